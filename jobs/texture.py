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
from .tiles import Tile, share

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
    describe(summary, scene, bakes, plan)
    stats, textured = summary.result, summary.sizes["textured_materials"]
    summary.message = (f"baked the albedo of {len(summary.lightmaps)} objects ({stats['texels']} "
                       f"texels, {stats['cells']} look-ups); colour attribute '{ATTRIBUTE}' on "
                       f"{len(summary.attributes)} objects; textures: {', '.join(textured) or 'none'}")
    summary.files = lightmap_files(summary, "albedo", previews=True)
    return summary


def texture_tile_job(context, settings: TextureBakeSettings, uv_name: str, uv_settings,
                     tile: Tile, resolution=None, render_overrides: dict | None = None
                     ) -> Steps[JobSummary]:
    """Tile K of N of `texture_bake_job` (jobs/tiles.py): the lightmaps of its share of the
    objects (by texel count, `share`; each object's albedo depends on its own texels only, so it
    comes out as the whole bake gives it) and, in tile 1, the camera's view. Nothing is written
    into Blender."""
    import bpy

    with lightmap_uvs(context, uv_name, uv_settings) as plan:
        scene = snapshot(context, SnapshotRequest(lightmap_uv=uv_name, textures=True,
                                                  world_render=False), resolution=resolution)
        targets, sizes = bake_targets(scene, plan, uv_settings)
        with_map = [k for k in targets
                    if scene.lightmap_uv is not None and scene.objects[k].has_lightmap_uv]
        if tile.count > len(targets):
            raise ValueError(f"--tile {tile.index}/{tile.count}: more tiles than the scene's "
                             f"{len(targets)} objects")
        weights = [(sizes[k] ** 2 if k in with_map else 0) + 3 * scene.objects[k].tri_count
                   for k in targets]
        mine = [targets[i] for i in share(weights, tile)]
        bakes = yield from scaled(
            texture_bake.texture_bake_steps(scene, mine, sizes, uv_settings.padding, settings),
            0.0, 0.6)
        image = None
        if tile.index == 1 and scene.camera is not None:
            image = yield from scaled(
                texture_bake.render_steps(scene, resolution, **(render_overrides or {})), 0.6, 0.4)
    summary = JobSummary(message="", scene=scene, render=image)
    for k, bake in bakes.items():
        info = scene.objects[k]
        if bake.lightmap is not None:
            summary.lightmaps[info.source_name] = (bake.lightmap, bake.lightmap_mask)
        obj = bpy.data.objects[info.source_name]
        if info.topology_matches_original:
            summary.attributes.append(info.source_name)
        elif obj.type != "MESH":  # as `write_bakes` says it
            summary.skipped.append(f"{info.source_name}: a {obj.type.lower()} object has no "
                                   "mesh to hold a colour attribute")
        else:
            summary.skipped.append(f"{info.source_name}: modifiers change its topology, so the "
                                   "colour attribute is not written (the lightmap is)")
    describe(summary, scene, bakes, plan)
    names = [scene.objects[k].source_name for k in with_map]
    summary.files = lightmap_files(summary, "albedo", previews=True, names=names)
    summary.extra["tile_objects"] = [scene.objects[k].source_name for k in mine]
    summary.extra["lightmap_order"] = names  # the whole bake's, for `merge`
    summary.message = (f"texture tile {tile.index} of {tile.count}: albedo of "
                       f"{len(summary.lightmaps)} objects ({summary.sizes['baked_texels']} texels)"
                       + ("; the camera view" if image is not None else ""))
    return summary


def describe(summary: JobSummary, scene, bakes: dict, plan: dict) -> None:
    """In place: the summary's result, sizes and metrics.json sections of the bakes."""
    stats = texture_bake.stats(bakes)
    textured = sorted({m.name for m in scene.read_materials if m.base_color_texture is not None})
    summary.result = stats
    summary.extra["lightmap_sizes"] = plan
    summary.sizes = {"objects": len(summary.lightmaps), "baked_texels": stats["texels"],
                     "look_ups": stats["cells"], "triangles": scene.triangle_count,
                     "textured_materials": textured}
    summary.extra["texels_per_cells_per_side"] = stats["texels_per_cells_per_side"]


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
    if values.get("tile") is not None:
        summary = yield from texture_tile_job(context, bake, uv_name, uv_settings, values["tile"],
                                              resolution=resolution, render_overrides=overrides)
    else:
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
    tiles="lightmaps",
)
