"""Radiosity: diffuse patches, form factors, a solver, colour bleeding; the view-independent
solution baked into lightmaps ("Radiosity <object>") and a 'Radiosity' corner colour attribute
(outgoing radiance B / pi), and the camera's view of it."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

from ..addon.bridge.request import SnapshotRequest
from ..addon.bridge.snapshot import snapshot
from ..kernels.progress import Steps, scaled
from ..kernels.radiosity.lightmap import bake_steps, gather_groups
from ..kernels.radiosity.planning import (
    AUTO_MATRIX_NEAR_SPLITS,
    AUTO_NEAR_SPLITS,
    AUTO_SHADOW_SPLITS,
)
from ..kernels.radiosity.settings import RadiositySettings
from ..kernels.radiosity.solve import radiosity_steps
from ..kernels.radiosity.view import render_steps
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
from .tiles import PREPARE, SOLUTION, TILE_FOLDER, Tile, load_solution, save_solution, share

ATTRIBUTE = "Radiosity"
IMAGE_PREFIX = "Radiosity"
RENDER_IMAGE = "Classic Bake Radiosity"


@dataclass(frozen=True)
class RadiosityDisplay:
    """| field | default | meaning                                                        |
    |-------|---------|----------------------------------------------------------------|
    | wire  | False   | wire the 'Radiosity' attribute into the materials (Emission)   |
    """

    wire: bool = False


def radiosity_bake_job(context, settings: RadiositySettings, uv_name: str, uv_settings, *,
                       render: bool = True, resolution=None, wire: bool = False
                       ) -> Steps[JobSummary]:
    """Solve the scene's radiosity and bake B / pi into a lightmap image and a CORNER colour
    attribute per mesh, and (render=True) the camera's view of the solution. `wire` makes the
    materials show the attribute (Emission). `summary.result` is the RadiosityResult."""
    with lightmap_uvs(context, uv_name, uv_settings) as plan:
        scene = snapshot(context, SnapshotRequest(lightmap_uv=uv_name, textures=True),
                         resolution=resolution)
        result = yield from scaled(radiosity_steps(scene, settings), 0.0, 0.85)
        targets, sizes = bake_targets(scene, plan, uv_settings)
        bakes = yield from scaled(
            bake_steps(scene, result, targets, sizes, uv_settings.padding), 0.85, 0.1)
        image = None
        if render and scene.camera is not None:
            image = yield from scaled(render_steps(scene, result, resolution), 0.95, 0.05)
    # --- write back: everything computed ---------------------------------------------------------
    summary = write_bakes(scene, bakes, ATTRIBUTE, IMAGE_PREFIX, image, RENDER_IMAGE, wire=wire)
    describe(summary, scene, result, bakes, plan)
    summary.message = (f"radiosity: {result.stats['patches']} patches (levels "
                       f"{result.stats['per_level']}), {result.stats['solver']} with "
                       f"{result.stats['method']} form factors in {result.stats['seconds']:.2f} s; "
                       f"lightmaps on {len(summary.lightmaps)} objects, colour attribute "
                       f"'{ATTRIBUTE}' on {len(summary.attributes)}")
    summary.files = lightmap_files(summary, "radiosity")
    return summary


def describe(summary: JobSummary, scene, result, bakes: dict, plan: dict) -> None:
    """In place: the summary's result, sizes and metrics.json sections of a solve and its bakes."""
    summary.result = result
    summary.notes.extend(result.notes)
    summary.extra["lightmap_sizes"] = plan
    stats = result.stats
    filtered = sum(b.filtered_texels for b in bakes.values())
    summary.sizes = {
        "patches": stats["patches"],
        "patches_per_level": {str(k): v for k, v in stats["per_level"].items()},
        "refinement_levels": len(stats["levels"]) - 1,
        "triangles": scene.triangle_count, "lights": len(scene.lights),
        "baked_texels": int(sum(int(m.sum()) for _, m in summary.lightmaps.values())),
        "filtered_texels": int(filtered),  # averaged over sub-texel points
        "memory_estimate_bytes": stats["memory_estimate"]["total"],
    }
    summary.extra["radiosity"] = {
        "solver": stats["solver"], "method": stats["method"], "patch_size_m": stats["patch_size_m"],
        # What "auto" (0 and -1 in settings) chose for this scene.
        "samples_per_side": stats["samples_per_side"], "refine_levels": stats["refine_levels"],
        "shadow_splits": stats["shadow_splits"], "memory_estimate": stats["memory_estimate"],
        "levels": [{k: v for k, v in level.items() if k != "memory_estimate"}
                   for level in stats["levels"]],
        "final_gather": stats.get("final_gather"),  # None when switched off
        "world": stats.get("world"),  # sky rays per patch, suns taken from the world's map
        # where auto coarsened the groups of a scene of many parts to fit the memory limit
        "coarse_groups": stats.get("coarse_groups"),
    }


def radiosity_tile_job(context, settings: RadiositySettings, uv_name: str, uv_settings, tile: Tile,
                       out: Path, resolution=None) -> Steps[JobSummary]:
    """A part of `radiosity_bake_job` (jobs/tiles.py). `--tile prepare` solves, saves the
    solution into OUT/tiles/prepare/ and renders the camera's view; tile K of N reads that solution
    and bakes the lightmaps of its share of the objects: of the runs of objects the bake gathers
    together (`gather_groups`), by texel count, so each comes out exactly as the whole bake gives
    it (`kernels/radiosity/lightmap.py`). Nothing is written into Blender."""
    with lightmap_uvs(context, uv_name, uv_settings) as plan:
        scene = snapshot(context, SnapshotRequest(lightmap_uv=uv_name, textures=True),
                         resolution=resolution)
        targets, sizes = bake_targets(scene, plan, uv_settings)
        if tile.prepare:
            result = yield from scaled(radiosity_steps(scene, settings), 0.0, 0.85)
            image = None
            if scene.camera is not None:
                image = yield from scaled(render_steps(scene, result, resolution), 0.85, 0.15)
            bakes, mine = {}, []
        else:
            result = load_solution(out / TILE_FOLDER / PREPARE / SOLUTION)
            image = None
            with_map = [k for k in targets
                        if scene.lightmap_uv is not None and scene.objects[k].has_lightmap_uv]
            groups = gather_groups(scene, targets, sizes)
            weights = [sum((sizes[k] ** 2 if k in with_map else 0)
                           + 3 * scene.objects[k].tri_count for k in run) for run in groups]
            runs = [groups[i] for i in share(weights, tile)]
            mine = [k for k in targets if any(k in run for run in runs)]
            bakes = yield from bake_steps(scene, result, mine, sizes, uv_settings.padding,
                                          groups=runs)
    summary = JobSummary(message="", scene=scene, render=image)
    for k, bake in bakes.items():
        if bake.lightmap is not None:
            summary.lightmaps[scene.objects[k].source_name] = (bake.lightmap, bake.lightmap_mask)
    describe(summary, scene, result, bakes, plan)
    if tile.prepare:
        summary.files = {SOLUTION: lambda path: save_solution(path, result)}
        summary.message = (f"radiosity {tile.name}: {result.stats['patches']} patches solved in "
                           f"{result.stats['seconds']:.2f} s and saved for the tiles")
    else:
        names = [scene.objects[k].source_name for k in with_map]
        summary.files = lightmap_files(summary, "radiosity", names=names)
        summary.extra["tile_objects"] = [scene.objects[k].source_name for k in mine]
        summary.extra["lightmap_order"] = names  # the whole bake's, for `merge`
        summary.message = (f"radiosity tile {tile.index} of {tile.count}: lightmaps of "
                           f"{len(summary.lightmaps)} objects, "
                           f"{summary.sizes['baked_texels']} texels")
    return summary


SOLVER_CHOICES = (
    ("auto", "Automatic", "Clustered when grouping fine meshes cuts the unknowns fourfold; else "
     "Gauss-Seidel up to 200 patches; above, hierarchical when its memory bound fits (refinement "
     "capped to fit), else Gauss-Seidel or progressive refinement"),
    ("gauss_seidel", "Gauss-Seidel", "Gathering on the dense form factor matrix"),
    ("progressive", "Progressive", "Shooting, one row at a time, never N x N"),
    ("hierarchical", "Hierarchical", "Patches gather from a hierarchy of sources, coarse where the "
     "form factor is small (links, not N x N)"),
    ("clustered", "Clustered", "Small patches of fine meshes solved as groups by object, place and "
     "facing (ray-cast factors)"),
)

OPTIONS = (
    Option("method", RadiositySettings, "Form Factors", "How form factors between patches are "
           "estimated", choices=(("raycast", "Ray-Cast", "Exact point-to-polygon factors, "
                                  "visibility by shadow rays"),
                                 ("hemicube", "Hemicube", "Hemicubes at points of each patch "
                                  "(Cohen & Greenberg)"))),
    Option("solver", RadiositySettings, "Solver", "How the radiosity system is solved",
           choices=SOLVER_CHOICES),
    Option("patches", RadiositySettings, "Patches", "Patches aimed at before refinement (sets the "
           "patch size)", field="patch_budget", minimum=1, soft_max=5000),
    Option("patch_size", RadiositySettings, "Patch Size", "Longest patch edge in metres (0: from "
           "Patches)", minimum=0.0, soft_max=10.0),
    Option("refine", RadiositySettings, "Refinement", "Adaptive refinement levels (patches split "
           "where the solution varies strongly or a shadow boundary crosses); -1: auto, none with "
           "the final gather, one level without it", field="refine_levels", minimum=-1, maximum=4),
    Option("shadow_splits", RadiositySettings, "Shadow Splits", "Times patches across a point, "
           f"spot or sun lamp's shadow edge are split before the solve; -1: auto, "
           f"{AUTO_SHADOW_SPLITS} with the final gather when such a lamp casts shadows, else 0",
           minimum=-1, maximum=4),
    Option("near_splits", RadiositySettings, "Near Splits", "Times patches that another surface "
           "faces nearer than their own size are split before the solve (a box by a wall); -1: "
           f"auto, {AUTO_NEAR_SPLITS} with the final gather ({AUTO_MATRIX_NEAR_SPLITS} for the "
           "matrix solvers), else 0", minimum=-1, maximum=4),
    Option("final_gather", RadiositySettings, "Final Gather", "Read the solution out with exact "
           "direct light (and its shadows) at every texel, pixel and corner; the patches carry "
           "only the indirect light"),
    Option("gather_rays", RadiositySettings, "Gather Rays", "Final gather: shadow rays per "
           "receiver to the emissive surfaces (more: smoother penumbrae)", minimum=1,
           soft_max=256),
    Option("world_rays", RadiositySettings, "World Rays", "Rays per patch that find its share of "
           "open sky, which the world's colour lights as Cycles does (0: the world lights no "
           "surface)", minimum=0, soft_max=1024),
    Option("wire", RadiosityDisplay, "Show in Materials", "Wire the 'Radiosity' attribute into the "
           "materials (Emission) so viewport and renders show the bake"),
)


def settings(values: dict, scene=None) -> RadiositySettings:
    return RadiositySettings(method=str(values["method"]), solver=str(values["solver"]),
                             patch_budget=int(values["patches"]),
                             patch_size=float(values["patch_size"]),
                             refine_levels=int(values["refine"]),
                             shadow_splits=int(values["shadow_splits"]),
                             near_splits=int(values["near_splits"]),
                             final_gather=bool(values["final_gather"]),
                             gather_rays=int(values["gather_rays"]),
                             world_rays=int(values["world_rays"]))


def start(context, values: dict, resolution=None) -> Steps[JobSummary]:
    uv_name, uv_settings = lightmap_settings(values)
    solve = settings(values)
    if values.get("tile") is not None:
        summary = yield from radiosity_tile_job(context, solve, uv_name, uv_settings,
                                                values["tile"], Path(values["out_dir"]),
                                                resolution=resolution)
    else:
        summary = yield from radiosity_bake_job(context, solve, uv_name, uv_settings,
                                                resolution=resolution, wire=bool(values["wire"]))
    summary.settings = {**asdict(solve), **lightmap_record(uv_name, uv_settings)}
    return summary


def cycles_model(recorded: dict):
    from ..addon.cycles import models

    # The world lights the solve unless its rays are off (kernels/shading/world_light.py).
    return models.radiosity(world_lighting=int(recorded.get("world_rays", 0)) > 0)


RECORD = Technique(
    name="radiosity", label="Radiosity",
    help="solve radiosity; bake lightmaps, colour attributes and render the camera's view",
    options=OPTIONS, settings=settings, start=start, cycles_model=cycles_model, shared=LIGHTMAP_OPTIONS,
    ladder=((),), tiles="lightmaps", tile_prepare=True,
    operator=OperatorSpec("classic_bake.radiosity", "Bake Radiosity", "LIGHT_AREA",
                          needs=("mesh",)),
)
