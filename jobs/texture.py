"""Texture mapping: every mesh's diffuse albedo, its image and checker textures mapped through its
UVs and filtered over each texel, baked into lightmaps ("Texture <object>"), an 'Albedo' corner
colour attribute, and the camera's view of the albedo."""

from __future__ import annotations

from ..addon.bridge.request import SnapshotRequest
from ..addon.bridge.snapshot import snapshot
from ..kernels.bake import texture_bake
from ..kernels.bake.texture_bake import TextureBakeSettings
from ..kernels.progress import Steps, scaled
from ..kernels.trace.settings import TracerSettings
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

ATTRIBUTE = "Albedo"
IMAGE_PREFIX = "Texture"
RENDER_IMAGE = "Classic Bake Texture"


def texture_bake_job(context, settings: TextureBakeSettings, uv_name: str, uv_settings, *,
                     render: bool = True, resolution=None, render_overrides: dict | None = None
                     ) -> Steps[JobSummary]:
    """Bake every mesh's albedo into a lightmap and a CORNER colour attribute, and (render=True)
    the camera's view of the albedo (`render_overrides`: TracerSettings fields of that view)."""
    with lightmap_uvs(context, uv_name, uv_settings) as plan:
        # Albedo sees no light: a world shader is not worth rendering (`world_render`).
        scene = snapshot(context, SnapshotRequest(lightmap_uv=uv_name, textures=True,
                                                  world_render=False), resolution=resolution)
        targets, sizes = bake_targets(scene, plan, uv_settings)
        bakes = yield from scaled(
            texture_bake.texture_bake_steps(scene, targets, sizes, uv_settings.padding, settings),
            0.0, 0.6)
        image = None
        if render and scene.camera is not None:
            image = yield from scaled(
                texture_bake.render_steps(scene, resolution, **(render_overrides or {})), 0.6, 0.4)
    # --- write back: everything computed ---------------------------------------------------------
    summary = write_bakes(scene, bakes, ATTRIBUTE, IMAGE_PREFIX, image, RENDER_IMAGE)
    stats = texture_bake.stats(bakes)
    textured = sorted({m.name for m in scene.materials if m.base_color_texture is not None})
    summary.result = stats
    summary.extra["lightmap_sizes"] = plan
    summary.sizes = {"objects": len(summary.lightmaps), "baked_texels": stats["texels"],
                     "look_ups": stats["cells"], "triangles": scene.triangle_count,
                     "textured_materials": textured}
    summary.extra["texels_per_cells_per_side"] = stats["texels_per_cells_per_side"]
    summary.message = (f"baked the albedo of {len(summary.lightmaps)} objects ({stats['texels']} "
                       f"texels, {stats['cells']} look-ups); colour attribute '{ATTRIBUTE}' on "
                       f"{len(summary.attributes)} objects; textures: {', '.join(textured) or 'none'}")
    summary.files = lightmap_files(summary, "albedo", previews=True)
    return summary


OPTIONS = (
    Option("cells", TextureBakeSettings, "Cells per Side", "N x N filtered look-ups per lightmap "
           "texel (0: from each texel's footprint in the texture)", field="samples_per_side",
           minimum=0, maximum=16, prop="texture_samples"),
    Option("texture_filter", TracerSettings, "View Filter", "Camera view: G x G filtered look-ups "
           "over each pixel (1: one look-up at the pixel centre, the lecture's mapping alone)",
           minimum=1, maximum=16),
    Option("adaptive", TracerSettings, "Edge Samples", "Camera view: N x N samples again in "
           "pixels at silhouettes (0: off)", minimum=0, maximum=16),
)


def settings(values: dict, scene=None) -> TextureBakeSettings:
    return TextureBakeSettings(samples_per_side=int(values["cells"]))


def start(context, values: dict, resolution=None) -> Steps[JobSummary]:
    uv_name, uv_settings = lightmap_settings(values)
    overrides = {"texture_filter": int(values["texture_filter"]), "adaptive": int(values["adaptive"])}
    bake = settings(values)
    summary = yield from texture_bake_job(context, bake, uv_name, uv_settings,
                                          resolution=resolution, render_overrides=overrides)
    summary.settings = {"samples_per_side": bake.samples_per_side,
                        "max_samples_per_side": bake.max_samples_per_side, **overrides,
                        **lightmap_record(uv_name, uv_settings)}
    return summary


def cycles_model(recorded: dict):
    from ..addon.cycles import models

    return models.albedo()  # Cycles' Diffuse Color pass


RECORD = Technique(
    name="texture", label="Texture Mapping",
    help="bake textured albedo into lightmaps and a colour attribute",
    options=OPTIONS, settings=settings, start=start, cycles_model=cycles_model, shared=LIGHTMAP_OPTIONS,
    # A centre look-up per texel and pixel (the lecture's mapping alone), then the filters.
    ladder=(("--cells", "1", "--texture-filter", "1", "--adaptive", "0"),
            ("--texture-filter", "1"), (), ("--texture-filter", "6")),
    operator=OperatorSpec("classic_bake.texture", "Bake Textures", "TEXTURE", needs=("mesh",)),
)
