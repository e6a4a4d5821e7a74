"""Kernel settings dataclasses made from Blender properties: one function per kernel, one place."""

from ..kernels.lightmap_uv import LightmapUVSettings


def lightmap_uv_settings(props) -> LightmapUVSettings:
    """`scene.classic_bake` -> LightmapUVSettings."""
    return LightmapUVSettings(resolution=props.lightmap_resolution, padding=props.lightmap_padding)
