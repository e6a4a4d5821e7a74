"""Shadow mapping: a depth map from each light, the lecture's depth test with a tolerance eps;
masks baked into lightmaps ("Shadow <object>") and a 'Shadow' colour attribute, and the camera's
view of direct light with shadow-mapped shadows."""

from __future__ import annotations

from dataclasses import asdict

import numpy as np

from ..addon.bridge.request import SnapshotRequest
from ..addon.bridge.snapshot import snapshot
from ..kernels.progress import Steps, scaled
from ..kernels.shading import direct_light
from ..kernels.shading.direct_light import DirectLightSettings
from ..kernels.shadow.shadowmap import ShadowMapSettings
from .lightmaps import (
    LIGHTMAP_OPTIONS,
    bake_targets,
    lightmap_files,
    lightmap_record,
    lightmap_settings,
    lightmap_uvs,
    write_bakes,
)
from .record import JobSummary, OperatorSpec, Option, Technique

ATTRIBUTE = "Shadow"
IMAGE_PREFIX = "Shadow"
RENDER_IMAGE = "Classic Bake Shadows"


def shadow_bake_job(context, settings: DirectLightSettings, uv_name: str, uv_settings, *,
                    render: bool = True, resolution=None) -> Steps[JobSummary]:
    """Bake the shadow-map mask of every mesh into a lightmap image and a corner colour attribute,
    and (render=True) the camera's view of direct light with shadows."""
    with lightmap_uvs(context, uv_name, uv_settings) as plan:
        # The world shows only as the view's background (shadow masks ignore it).
        scene = snapshot(context, SnapshotRequest(lightmap_uv=uv_name, textures=render,
                                                  world_render=render), resolution=resolution)
        if not scene.lights:
            raise ValueError("the scene has no lights: nothing casts a shadow")
        targets, sizes = bake_targets(scene, plan, uv_settings)
        results = yield from scaled(
            direct_light.shadow_bake_steps(scene, targets, sizes, uv_settings.padding, settings),
            0.0, 0.8)
        image = None
        if render and scene.camera is not None:
            image = yield from scaled(direct_light.render_steps(scene, settings, resolution), 0.8, 0.2)
    # --- write back: everything computed ---------------------------------------------------------
    summary = write_bakes(scene, results, ATTRIBUTE, IMAGE_PREFIX, image, RENDER_IMAGE)
    summary.extra["per_light"] = {scene.objects[k].source_name: bake.per_light_lightmaps
                                  for k, bake in results.items() if bake.lightmap is not None}
    texels = {n: int(m.sum()) for n, (_, m) in summary.lightmaps.items()}
    lit = [float(np.mean(lm[m])) for lm, m in summary.lightmaps.values() if m.any()]
    summary.sizes = {"objects": len(summary.lightmaps), "lights": len(scene.lights),
                     "baked_texels": int(sum(texels.values())), "triangles": scene.triangle_count}
    summary.message = (f"baked shadow masks of {len(texels)} objects ({sum(texels.values())} "
                       f"texels, mean lit fraction {np.mean(lit) if lit else 0.0:.3f}); colour "
                       f"attribute '{ATTRIBUTE}' on {len(summary.attributes)} objects")
    summary.files = lightmap_files(summary, "shadow")
    return summary


OPTIONS = (
    Option("map_size", ShadowMapSettings, "Map Size", "Shadow-map texels per side; 0 chooses it "
           "per light from the receivers' texel size", field="resolution", auto=0, minimum=0,
           maximum=16384, prop="shadow_map_size"),
    Option("eps_mode", ShadowMapSettings, "Tolerance Mode", "auto: the depth tolerance from texel "
           "size and slope; fixed: the tolerance below",
           choices=(("auto", "Automatic", "From texel size and slope"),
                    ("fixed", "Fixed", "The tolerance below, in metres"))),
    Option("eps", ShadowMapSettings, "Tolerance", "The lecture's depth tolerance against "
           "self-shadowing, metres (with the fixed mode)", minimum=0.0, soft_max=0.5,
           prop="shadow_eps"),
    Option("slope_bias", ShadowMapSettings, "Slope Bias", "Slope-scaled bias, texels",
           minimum=0.0, soft_max=8.0),
    Option("normal_offset", ShadowMapSettings, "Normal Offset", "Receivers moved along their "
           "normal before the test, texels", minimum=0.0, soft_max=8.0),
    Option("pcf", ShadowMapSettings, "PCF", "K x K percentage-closer filtering (odd; 1: hard)",
           field="pcf_size", minimum=1, maximum=15, prop="shadow_pcf"),
)


def settings(values: dict, scene=None) -> DirectLightSettings:
    size = int(values["map_size"])
    shadow = ShadowMapSettings(resolution=size or ShadowMapSettings.resolution,
                               eps_mode=str(values["eps_mode"]), eps=float(values["eps"]),
                               slope_bias=float(values["slope_bias"]),
                               normal_offset=float(values["normal_offset"]),
                               pcf_size=int(values["pcf"]))
    return DirectLightSettings(shadow=shadow, auto_resolution=size == 0)


def start(context, values: dict, resolution=None) -> Steps[JobSummary]:
    uv_name, uv_settings = lightmap_settings(values)
    light = settings(values)
    summary = yield from shadow_bake_job(context, light, uv_name, uv_settings, resolution=resolution)
    summary.settings = {**asdict(light.shadow), "auto_resolution": light.auto_resolution,
                        **lightmap_record(uv_name, uv_settings)}
    return summary


def cycles_model(recorded: dict):
    from ..addon.cycles import models

    return models.direct()


RECORD = Technique(
    name="shadowmap", label="Shadow Mapping",
    help="bake shadow-map masks and render direct light with shadows",
    options=OPTIONS, settings=settings, start=start, cycles_model=cycles_model, shared=LIGHTMAP_OPTIONS,
    ladder=(("--map-size", "512"), ("--map-size", "0"), ("--map-size", "2048"), ("--pcf", "3")),
    operator=OperatorSpec("classic_bake.shadowmap", "Bake Shadow Maps", "LIGHT_SUN",
                          needs=("light", "mesh")),
)
