"""Kernel settings dataclasses made from Blender properties: one function per kernel, one place."""

from ..kernels.bake.lightmap_uv import LightmapUVSettings
from ..kernels.trace.settings import TracerSettings, auto_settings


def lightmap_uv_settings(props) -> LightmapUVSettings:
    """`scene.classic_bake` -> LightmapUVSettings."""
    return LightmapUVSettings(resolution=props.lightmap_resolution, padding=props.lightmap_padding)


def tracer_settings(props, scene) -> TracerSettings:
    """`scene.classic_bake` + the kernel scene -> TracerSettings (depth -1: from the scene)."""
    overrides = {"supersample": props.trace_supersample, "adaptive": props.trace_adaptive}
    if props.trace_depth >= 0:
        overrides["max_depth"] = props.trace_depth
    return auto_settings(scene, **overrides)


def shading_settings(props, scene) -> TracerSettings:
    """`scene.classic_bake` + the kernel scene -> TracerSettings with the Bump Mapping panel's
    shading mode (flat, Gouraud, Phong or bump)."""
    from dataclasses import replace

    return replace(tracer_settings(props, scene), shading=props.bump_shading.lower())


def direct_light_settings(props):
    """`scene.classic_bake` -> DirectLightSettings (shadow maps)."""
    from ..kernels.shading.direct_light import DirectLightSettings
    from ..kernels.shadow.shadowmap import ShadowMapSettings

    pcf = props.shadow_pcf if props.shadow_pcf % 2 else props.shadow_pcf + 1
    shadow = ShadowMapSettings(resolution=props.shadow_map_size or 2048,
                               eps_mode="auto" if props.shadow_eps_auto else "fixed",
                               eps=props.shadow_eps, pcf_size=pcf)
    return DirectLightSettings(shadow=shadow, auto_resolution=props.shadow_map_size == 0)


def radiosity_settings(props):
    """`scene.classic_bake` -> RadiositySettings."""
    from ..kernels.radiosity.settings import RadiositySettings

    return RadiositySettings(method=props.radiosity_method, solver=props.radiosity_solver,
                             patch_budget=props.radiosity_patches,
                             refine_levels=props.radiosity_refine,
                             shadow_splits=props.radiosity_shadow_splits,
                             final_gather=props.radiosity_final_gather,
                             gather_rays=props.radiosity_gather_rays,
                             world_rays=props.radiosity_world_rays)


def envmap_settings(props, selected: list[str]):
    """`scene.classic_bake` + the selected mesh names -> EnvMapSettings (every mirror unless
    "Selected Only" is on)."""
    from ..kernels.envmap.envmap import EnvMapSettings

    objects = tuple(selected) if props.envmap_selected_only else ()
    if props.envmap_selected_only and not objects:
        raise ValueError("Select the objects to environment-map (or turn off Selected Only)")
    return EnvMapSettings(face_size=props.envmap_face_size,
                          face_supersample=props.envmap_face_samples, objects=objects,
                          parallax_steps=props.envmap_parallax_steps)


def texture_settings(props):
    """`scene.classic_bake` -> TextureBakeSettings."""
    from ..kernels.bake.texture_bake import TextureBakeSettings

    return TextureBakeSettings(samples_per_side=props.texture_samples)
