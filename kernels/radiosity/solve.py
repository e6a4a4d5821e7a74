"""Radiosity of a whole scene: patches, lights' first shot, form factors with BVH visibility, a
solver chosen by memory, adaptive refinement, and the solution evaluated anywhere on the surface.

Pipeline (`radiosity_steps`):

1. Patches: the scene's triangles cut into sub-triangles of about `patch_size` (`patches.py`;
   "auto" aims at `patch_budget` patches over the scene's area). Triangles that reflect nothing
   and emit nothing are left out of the exchange (`sources.exchanging_triangles`).
2. Plan (`planning.py`): "auto" settings, and the solver by memory. The hierarchical solver
   (`hierarchical.py`: its own linking and solve over the leaves of a hierarchy) takes scenes of
   more than AUTO_DENSE_PATCHES patches when its up-front memory bound fits the limit; else the
   matrix solvers (`patch_levels.py`) take the patches themselves.
3. Levels, one loop for every solver: patches across a lamp's hard shadow edge and patches in
   another surface's near field are split first (`refine.first_splits`); then each level takes
   its sources (`levels.level_light`: emission, the lights' and shot emitters' first shot, the
   world's light, `sources.py`), is solved, and splits where refinement asks
   (`refine.refine_splits`), up to `refine_levels` times and `max_patches` patches.
4. Result (`result.py`): B at the patches, fitted corner values, and the final gather's
   patch-level half (`final_gather.py`) when the settings ask for it.

Display: `RadiosityResult.exitance_at(tri, bary)` gives B anywhere on the surface. With
`final_gather` (the default) each receiver gets its exact direct light (lamps and emissive
triangles, with shadow rays) and the indirect part interpolated from the patches; without it, B
itself is interpolated smoothly inside objects (`patches.fitted_corner_values`, `interpolate`).
Outgoing radiance is B / pi, what Cycles' DIFFUSE bake (with colour) gives plus the emission.
`lightmap.bake_steps` evaluates lightmap texels and mesh corners, `view.render_steps` the scene
camera's view.

Materials: every surface is treated as Lambertian with the Principled BSDF's diffuse part, base
colour x (1 - metallic) x (1 - transmission) (textures sampled at the patch centre); the
specular paths of metals, glossy coats and glass are not modelled (listed in `ignored`), so a
chrome ball or a glass is black to the solution, as in Cycles' DIFFUSE bake.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ..geometry.bvh import BVH
from ..geometry.frames import RAY_OFFSET_REL
from ..geometry.scene import Scene
from ..progress import Steps, drain, scaled
from ..shading.alpha import alpha_aware, linked_shadows, shadow_aware
from ..shading.world_light import WORLD_SUN_NAME, world_lit, world_seen_by
from . import final_gather
from . import patches as patching
from .final_gather import FinalGather, PatchSolution
from .hierarchical import TreeLevels
from .lamps import LampShadows
from .levels import LevelLight, Levels, SolveContext, level_light
from .near_field import near_field
from .patch_levels import PatchLevels
from .planning import (
    clustering_pays,
    coarse_groups_pay,
    hierarchical_plan,
    patch_groups,
    resolve_auto,
)
from .refine import first_splits, refine_splits
from .result import RadiosityResult
from .settings import RadiositySettings
from .sheets import sheet_backs, with_sheet_backs
from .sources import (
    capped_materials,
    exchanging_triangles,
    gather_settings,
    layer_factors,
    patch_emission,
    shadow_edges,
    shot_emitters,
    with_idle,
    with_world_suns,
)


@dataclass(frozen=True, eq=False)
class Solved:
    """The last level the loop solved: its N patches, their light and B (N, 3) W/m^2, and every
    level's figures (`LevelSolution.stats`)."""

    patches: patching.Patches
    light: LevelLight
    radiosity: np.ndarray
    levels: list



def radiosity_steps(scene: Scene, settings: RadiositySettings = RadiositySettings(),  # noqa: B008
                    bvh=None) -> Steps[RadiosityResult]:
    """Solve the scene's radiosity; yields progress in [0, 1], returns a `RadiosityResult`.

    bvh: a `kernels.geometry.bvh.BVH` over `scene.triangles` (built here when None)."""
    if scene.triangle_count == 0:
        raise ValueError("the scene has no triangles")
    t0 = time.perf_counter()
    # The world lights the patches only where Cycles shows it to diffuse rays.
    scene = with_world_suns(world_seen_by(scene, "diffuse"))
    flat = scene.triangles.reshape(-1, 3).astype(np.float64)
    scale = float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))
    size = settings.patch_size or patching.auto_patch_size(scene, settings.patch_budget)
    if bvh is None:
        bvh = BVH.build(scene.triangles)
    # Sheets whose back faces the scene take part with both sides (`sheets.py`).
    scene, back_of = with_sheet_backs(scene, sheet_backs(scene, bvh, RAY_OFFSET_REL * scale),
                                      RAY_OFFSET_REL * scale)
    if back_of is not None:
        bvh = BVH.build(scene.triangles)
    # Leaf cards and fences: visibility rays pass alpha surfaces with probability 1 - alpha.
    shadow_bvh = shadow_aware(bvh, scene, RAY_OFFSET_REL * scale, settings.seed)
    linked = linked_shadows(bvh, scene, RAY_OFFSET_REL * scale, settings.seed)
    bvh = alpha_aware(bvh, scene, RAY_OFFSET_REL * scale, settings.seed)
    # The lamps' and emitters' shadow rays: shadowless surfaces passed, each linked lamp its own.
    shadows = LampShadows(bvh if shadow_bvh is None else shadow_bvh, linked)
    exchanging = exchanging_triangles(scene)
    # The first patches: auto's test for clusters, the hierarchy's count, the other solvers' mesh.
    patches = patching.make_patches(scene, size, exchanging)
    groups = patch_groups(patches, size, settings)  # for auto's test; each level regroups
    plan = hierarchical_plan(scene, size, bvh, resolve_auto(scene, settings, hierarchical=True),
                             exchanging, patches, groups)
    levels: Levels
    if plan is not None:
        settings = plan.settings
        ctx = SolveContext(scene, settings, bvh, size, scale,
                           shot_emitters(scene, settings, bvh, RAY_OFFSET_REL * scale), shadows)
        levels = TreeLevels(scene, plan.roots, plan.depth, ctx.occluded, settings, scale,
                            plan.memory)
    else:
        settings = resolve_auto(scene, settings, hierarchical=False)
        coarse = None if clustering_pays(len(patches), groups, settings) else coarse_groups_pay(
            patches, size, settings)
        if coarse is not None:  # small objects by their six faces, not a matrix over them all
            groups = coarse.groups
        if settings.solver == "auto" and clustering_pays(len(patches), groups, settings):
            # Decided on the first patches, for every level: splits and light octaves add
            # groups, and a dense matrix over the patches they would hand on to costs O(N^2)
            # factors (shadows.blend at a 50-patch budget: 200 s of Gauss-Seidel against 0.7 s
            # clustered).
            settings = replace(settings, solver="clustered")
        ctx = SolveContext(scene, settings, bvh, size, scale,
                           shot_emitters(scene, settings, bvh, RAY_OFFSET_REL * scale), shadows)
        # Not grouped on the first patches, never grouped: split children (shadow edges, the
        # near field, refinement) are there to hold variation that a group's one value would
        # flatten (a wall 16 cm behind a plate, its 0.25 m children grouped: the light on it
        # flat where it falls off fourfold).
        levels = PatchLevels(ctx, patches, groups if settings.solver == "clustered" else None,
                             coarse=coarse)
    yield 0.02
    solved = yield from _level_steps(ctx, levels)
    light = solved.light
    patches, per_patch = with_idle(scene, solved.patches, exchanging, solved.radiosity,
                                   light.emitted, light.reflectance, light.direct, light.clear,
                                   light.world)
    # All N patches, idle ones joined.
    solution = PatchSolution(patches, *per_patch)
    stats = {"patch_size_m": size, "patches": len(patches),
             "idle_patches": len(patches) - len(solved.patches),
             "per_level": patches.level_counts(), **levels.stats(solved.levels)}
    result = replace(_result(ctx, solution, stats, t0), back_of=back_of)
    yield 1.0
    return result


def _level_steps(ctx: SolveContext, levels: Levels) -> Steps[Solved]:
    """The level loop every solver shares: shadow-edge and near-field splits before the first
    solve, then solve and refine up to `refine_levels` times; yields progress in [0.02, 0.98]."""
    scene, settings, scale = ctx.scene, ctx.settings, ctx.scale
    # Patches across a lamp's hard shadow edge (`shadow_splits`) and patches that a surface faces
    # closer than their own size (`near_splits`) split before the first solve; each pass tests
    # the children of the last.
    for split in range(max(settings.shadow_splits, settings.near_splits)):
        room = (settings.max_patches - levels.count) // 3  # a split adds three patches
        if room <= 0:  # a dense mesh's triangles alone fill the budget: nothing may split
            break
        tested = levels.untested()
        wanted = np.zeros(len(tested), bool)
        if split < settings.shadow_splits:
            wanted |= shadow_edges(scene, tested, ctx.shadow_occluded, settings, scale)
        if split < settings.near_splits:
            wanted |= near_field(tested, ctx.occluded, scale)
        mask = first_splits(wanted, patch_emission(scene, tested), tested.areas, room)
        if not mask.any():
            break
        levels.split_untested(mask)
    count = settings.refine_levels + 1
    records = []
    for level in range(count):
        patches = levels.patches()
        light = level_light(ctx, patches)
        solution = yield from scaled(levels.solve_steps(light), 0.02 + 0.96 * level / count,
                                     0.96 / count)
        b = solution.radiosity + light.shot
        records.append(solution.stats)
        if level == count - 1:
            break
        mask = refine_splits(patches, b, light.emitted, light.reflectance, light.direct,
                             light.boundary, settings, scale)
        if not mask.any():
            break
        levels.refine(mask)
    return Solved(patches, light, b, records)


def _result(ctx: SolveContext, solution: PatchSolution, stats: dict, t0: float
            ) -> RadiosityResult:
    """The solved scene, with the final gather prepared when the settings ask for it."""
    scene, settings = ctx.scene, ctx.settings
    patches, b, emitted = solution.patches, solution.radiosity, solution.emitted
    # What the patches show: their reflected light under the specular layer (`patch_reflectance`).
    shown = emitted + (b - emitted) * layer_factors(scene)[scene.material_ids[patches.parent]][:, None]
    # One fit for both (their corner groups and CG iterations shared; channels are independent).
    corners = patching.fitted_corner_values(patches, np.hstack([shown, emitted]),
                                            settings.smooth_angle, ctx.scale)
    corner_b, corner_e = corners[..., :3], corners[..., 3:]
    # What "auto" chose, for metrics.json.
    stats.update(samples_per_side=settings.samples_per_side, refine_levels=settings.refine_levels,
                 shadow_splits=settings.shadow_splits, near_splits=settings.near_splits)
    # The world as a light: its rays per patch (0: black or off) and the suns taken from its map.
    lit_by_world = settings.world_rays if world_lit(scene) else 0
    stats["capped_reflectance"] = capped_materials(scene, patches, solution.reflectance)
    stats["world"] = {"rays_per_patch": int(lit_by_world),
                      "map_suns": sum(light.name.startswith(WORLD_SUN_NAME)
                                      for light in scene.lights)}
    gather = _prepare_gather(ctx, solution, stats)
    stats["seconds"] = time.perf_counter() - t0
    return RadiosityResult(patches=patches, radiosity=b, emitted=emitted, direct=solution.direct,
                           reflectance=solution.reflectance, corner_b=corner_b, corner_e=corner_e,
                           stats=stats, gather=gather)


def _prepare_gather(ctx: SolveContext, solution: PatchSolution, stats: dict
                    ) -> FinalGather | None:
    """The final gather's patch-level half, when the settings ask for it (stats: its figures)."""
    settings = ctx.settings
    if not settings.final_gather:
        return None
    start = time.perf_counter()
    gather = final_gather.prepare(ctx.scene, solution, ctx.emitters, ctx.bvh, settings.smooth_angle,
                                  settings.area_light_samples_per_side, gather_settings(settings),
                                  ctx.shadows)
    stats["final_gather"] = {**gather.stats, "prepare_seconds": time.perf_counter() - start}
    return gather


def solve_radiosity(scene: Scene, settings: RadiositySettings = RadiositySettings(),  # noqa: B008
                    bvh=None) -> RadiosityResult:
    """`radiosity_steps` run to the end."""
    return drain(radiosity_steps(scene, settings, bvh))
