"""Kernel settings dataclasses made from Blender properties: one function per kernel, one place."""

from ..kernels.lightmap_uv import LightmapUVSettings
from ..kernels.tracer import TracerSettings, auto_settings


def lightmap_uv_settings(props) -> LightmapUVSettings:
    """`scene.classic_bake` -> LightmapUVSettings."""
    return LightmapUVSettings(resolution=props.lightmap_resolution, padding=props.lightmap_padding)


def tracer_settings(props, scene) -> TracerSettings:
    """`scene.classic_bake` + the kernel scene -> TracerSettings (depth -1: from the scene)."""
    overrides = {"supersample": props.trace_supersample, "adaptive": props.trace_adaptive}
    if props.trace_depth >= 0:
        overrides["max_depth"] = props.trace_depth
    return auto_settings(scene, **overrides)
