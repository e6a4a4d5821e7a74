"""Planning a solve before it runs: the "auto" settings, memory estimates, and the solver that runs
(the hierarchical solver when its up-front memory bound fits, the clustered one where grouping
the patches of fine meshes pays, else Gauss-Seidel when the dense matrix fits, else progressive
refinement)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..geometry.scene import Scene
from ..shading.direct_light import diffuse_at
from ..shading.world_light import sky_ray_bytes, world_lit
from . import clusters
from . import patches as patching
from .hierarchical import FACING_COUNT_PAIRS, facing_roots, hierarchy_roots, memory_bound
from .lamps import shadowing_lamps
from .settings import RadiositySettings

# The quick unoccluded-pair test of method B keeps (T, N) bool tables and a (T, N, 3) float64
# temporary; it is used only while that stays under this many bytes.
QUICK_TEST_BYTES = 256 << 20
# ... and only on scenes of at most this many triangles: it costs ~36 ns per triangle and pair
# (every triangle's planes and box against the pair's), where the rays it may save cost a few
# us per pair. Gauss-Seidel, the same solution with and without it: Cornell box (38 triangles,
# 512 patches) 5.95 -> 5.42 s; shadows.blend (1234 triangles, 2236 patches) 37.9 -> 238 s;
# the Cornell box with two 2200-triangle balls (492 patches) 7.1 -> 51 s.
QUICK_TEST_TRIANGLES = 100
# Bytes per (point, patch) element of the ray-cast row temporaries (factors, clipped polygons,
# visibility kernels; measured order of magnitude, for the up-front estimate).
ROW_BYTES_PER_ELEMENT = 400
# samples_per_side "auto" takes one point per patch (its centre) for the hierarchical solver when
# no surface reflects more than this, else 2 x 2. One point's form factors miss a closed box's row
# sum by ~0.1-0.3%, which the solution multiplies by rho / (1 - rho): furnace (closed cube,
# hierarchical, 60 and 400 patch budgets) mean error 0.47-0.82% at rho 0.8 with one point, 2.1%
# at 0.9, 4.8% at 0.95 (2 x 2 points: 0.12-0.22%, 0.55%, 1.2%). At 0.8 one point keeps the issue's
# 1% furnace bound and costs a quarter of the rays (Cornell box, 600 patches: solve 0.38 s against
# 1.0 s, the same error against Cycles). The matrix solvers keep 2 x 2: their rows do not refine
# the near field, and one point misses the row sums by ~0.8% (furnace 1.3% at rho 0.6).
AUTO_ONE_POINT_RHO = 0.8
# Shadow-edge splits before the solve with the final gather. The gather gives every receiver its
# own direct light, but a patch lit on one part and shadowed on the other still sends its mean
# to its neighbours: under a ball over a ground whose 2.8 m patches straddle the ball's shadow,
# the bounce light came out 8% too bright. shadows.blend against a 256-sample Cycles bake:
# 50-patch budget (hierarchical) relMSE 0.0076 -> 0.0014; defaults 0.0021 -> 0.0010, 2.2 -> 3.5 s.
# Area lamps too (a small one casts a step): a generated room lit by a 0.5 m area lamp, a 0.25 m
# sphere on its floor, defaults against a 1024-sample Cycles bake: relMSE 0.0128 -> 0.0016 (the
# sphere's underside had been 20x too bright), 8.4 -> 9.8 s.
AUTO_SHADOW_SPLITS = 2
# Near-field splits before the solve with the final gather (`near_field.py`): the gather places
# each receiver's light but not a source patch's own variation, which a surface close to it sees.
# Defaults against 1024-sample Cycles bakes (texel relMSE as measured, the references' own noise
# 3-4e-4 included; solve + bake seconds): one pass took a generated room with a box 16 cm from a
# wall from 0.0072 to 0.0030 (7.2 -> 10.2 s), one with a ball on the floor under an area lamp
# from 0.0016 to 0.00095, the Cornell box from 0.0017 to 0.0013. A second pass, with room for it
# (AUTO_MAX_PATCHES): 0.0030 -> 0.00097 (the floor under a ball and the ball's underside, whose
# contact one pass left 10x too bright), 0.00098 -> 0.00069, 0.00127 -> 0.00111, shadows.blend
# 0.00020 -> 0.00016, for 1.3-2.1x the seconds. The matrix solvers take one pass: their factors
# cost O(N^2).
AUTO_NEAR_SPLITS = 2
AUTO_MATRIX_NEAR_SPLITS = 1
# Patches the splits and refinement may reach (max_patches 0). The hierarchy's links grow about
# as leaves x roots: the rooms above at 5712 and 4290 leaves made 2.8M and 2.0M links (peak
# memory 740 MB with Blender's own), 2.5-4x under their bound. The matrix solvers' O(N^2)
# factors keep them at the cap they had.
AUTO_MAX_PATCHES = 6000
AUTO_MATRIX_MAX_PATCHES = 3000
# Coarse groups' grid widths tried, each twice the last from the patch size, before auto hands
# more than AUTO_MATRIX_MAX_PATCHES patches to progressive refinement, which casts a row of rays
# per shot and shoots each patch many times: an imported airliner (354 objects, 41k triangles and
# as many patches) made 2778 coarse groups at the patch size, 8% over the memory limit, and ran
# progressive refinement for over 20 minutes; at twice the width, 2241 groups. Small objects
# of one cell are then pooled: 3000 scattered 10 cm cubes make six groups each, at any width.
COARSE_CELL_DOUBLINGS = 4


def resolve_auto(scene: Scene, settings: RadiositySettings, hierarchical: bool
                 ) -> RadiositySettings:
    """`settings` with its "auto" fields chosen for `scene` and the solver that runs:
    samples_per_side from the largest reflectance of any triangle (base colour and textures at
    the centroid, AUTO_ONE_POINT_RHO; 2 unless `hierarchical`),
    refine_levels from the final gather (which gathers direct light and its shadows at every
    receiver, so the patches carry only smooth indirect light: a refinement level costs a second
    link-and-solve for ~15% less error on the Cornell box, where twice the patches give ~40%),
    shadow_splits from the final gather and the lamps (AUTO_SHADOW_SPLITS where a lamp of any
    kind casts shadows: `shadow_edges`), near_splits from the final gather and the solver
    (AUTO_NEAR_SPLITS, AUTO_MATRIX_NEAR_SPLITS: `near_field`), max_patches from the solver
    (AUTO_MAX_PATCHES, AUTO_MATRIX_MAX_PATCHES)."""
    changes = {}
    if settings.samples_per_side == 0:
        count = scene.triangle_count
        rho = diffuse_at(scene, np.arange(count), np.full((count, 3), 1.0 / 3.0),
                         under_layer=False)
        one = hierarchical and float(np.max(rho, initial=0.0)) <= AUTO_ONE_POINT_RHO
        changes["samples_per_side"] = 1 if one else 2
    if settings.refine_levels == -1:
        changes["refine_levels"] = 0 if settings.final_gather else 1
    if settings.shadow_splits == -1:
        shadowed = settings.final_gather and shadowing_lamps(scene)
        changes["shadow_splits"] = AUTO_SHADOW_SPLITS if shadowed else 0
    if settings.near_splits == -1:
        passes = AUTO_NEAR_SPLITS if hierarchical else AUTO_MATRIX_NEAR_SPLITS
        changes["near_splits"] = passes if settings.final_gather else 0
    if settings.max_patches == 0:
        changes["max_patches"] = AUTO_MAX_PATCHES if hierarchical else AUTO_MATRIX_MAX_PATCHES
    return replace(settings, **changes) if changes else settings


def memory_estimate(patch_count: int, triangle_count: int, settings: RadiositySettings,
                    solver: str, group_count: int = 0, world_lit: bool = False) -> dict:
    """Bytes each part of a solve needs, and their sum ("total").

    dense_f: N^2 x 8 (Gauss-Seidel only; the clustered solver: G^2 x 8 over `group_count`
    groups, and its (points, groups) factor table); rows: the per-row temporaries of the estimator;
    row_cache: progressive refinement's cached rows; quick_test: method B's pair tables;
    bvh: about 200 bytes per triangle (nodes, leaves, prepared triangles); patches: ~400 B each;
    world_rays: the sky rays' chunk when the world lights the scene (`world_lit`).
    """
    n, t = patch_count, triangle_count
    s = settings.samples_per_side ** 2
    parts = {
        "dense_f": n * n * 8 if solver == "gauss_seidel" else 0,
        "groups": clustered_bytes(group_count) if solver == "clustered" else 0,
        "rows": ROW_BYTES_PER_ELEMENT * s * n * (4 if settings.method == "raycast" else 1),
        "row_cache": min(n * n * 8, settings.dense_memory_limit) if solver == "progressive" else 0,
        "quick_test": quick_test_bytes(n, t) if quick_test_pays(n, t) else 0,
        "bvh": 200 * (t + (n if settings.method == "hemicube" else 0)),
        "patches": 400 * n,
        "world_rays": sky_ray_bytes(n, settings.world_rays) if world_lit else 0,
    }
    if settings.method == "hemicube":
        parts["rows"] += 3 * settings.hemicube_resolution ** 2 * s * 64
    parts["total"] = int(sum(parts.values()))
    return parts


def clustered_bytes(group_count: int) -> int:
    """The clustered solver's G x G factors and its (receiver points, groups) table."""
    return group_count * group_count * 8 * (1 + max(clusters.CLUSTER_POINTS, 4))


def quick_test_bytes(patch_count: int, triangle_count: int) -> int:
    """Method B's quick unoccluded-pair test: two (T, N) bool tables and a (T, N, 3) float64."""
    return triangle_count * patch_count * (2 + 24)


def quick_test_pays(patch_count: int, triangle_count: int) -> bool:
    """Whether method B runs its quick unoccluded-pair test (QUICK_TEST_TRIANGLES,
    QUICK_TEST_BYTES)."""
    return (triangle_count <= QUICK_TEST_TRIANGLES
            and quick_test_bytes(patch_count, triangle_count) <= QUICK_TEST_BYTES)


# auto hands scenes of more patches than this to the hierarchical solver. Measured (Cornell box,
# ~300 patches, refinement on): against Cycles' DIFFUSE bake its mean texel error was 9.1% in
# 6.7 s of test time, Gauss-Seidel's 10.2% in 18.6 s; at 96 patches Gauss-Seidel takes 0.6 s.
AUTO_DENSE_PATCHES = 200


def choose_solver(patch_count: int, settings: RadiositySettings,
                  groups: clusters.Groups | None = None) -> str:
    """The solver "auto" runs over `patch_count` patches (the hierarchical solver aside, which
    `hierarchical_plan` chooses first): the clustered solver when `groups`
    (`clusters.group_patches`) has at most AUTO_MAX_GROUP_SHARE as many unknowns and fits the
    memory limit; else Gauss-Seidel when the dense matrix fits it, else progressive."""
    if settings.solver != "auto":
        return settings.solver
    if clustering_pays(patch_count, groups, settings):
        return "clustered"
    return "gauss_seidel" if patch_count ** 2 * 8 <= settings.dense_memory_limit else "progressive"


def clustering_pays(patch_count: int, groups: clusters.Groups | None,
                    settings: RadiositySettings) -> bool:
    """Whether grouping the patches (`clusters.group_patches`) pays: at most AUTO_MAX_GROUP_SHARE
    as many unknowns, within the memory limit, with ray-cast factors."""
    return (settings.clusters and settings.method == "raycast" and groups is not None
            and groups.count <= clusters.AUTO_MAX_GROUP_SHARE * patch_count
            and clustered_bytes(groups.count) <= settings.dense_memory_limit)


def patch_groups(patches: patching.Patches, size: float, settings: RadiositySettings,
                 direct: np.ndarray | None = None, coarse: bool = False,
                 pooled: bool = False) -> clusters.Groups | None:
    """`clusters.group_patches` where auto or the clustered solver may use them, else None."""
    if settings.method == "raycast" and settings.solver in ("auto", "clustered"):
        return clusters.group_patches(patches, size, direct, coarse, pooled)
    return None


@dataclass(frozen=True, eq=False)
class CoarseGroups:
    """Coarse groups (`clusters.group_patches(coarse=True)`) over a grid `cell` m wide, `pooled`
    or not: every level regroups its patches so (`patch_levels.PatchLevels`)."""

    groups: clusters.Groups
    cell: float
    pooled: bool = False

    def regrouped(self, patches: patching.Patches, settings: RadiositySettings,
                  direct: np.ndarray | None) -> clusters.Groups | None:
        return patch_groups(patches, self.cell, settings, direct, True, self.pooled)


def coarse_groups_pay(patches: patching.Patches, size: float, settings: RadiositySettings
                      ) -> CoarseGroups | None:
    """The coarse groups (`clusters.SMALL_OBJECT_SHARE`) when auto, left with a matrix solver over
    more than AUTO_MATRIX_MAX_PATCHES patches, would cluster them (`clustering_pays`): over the
    narrowest grid of `size` m doubled up to COARSE_CELL_DOUBLINGS times that does, then the
    same with small objects pooled by cell; else None."""
    if settings.solver != "auto" or len(patches) <= AUTO_MATRIX_MAX_PATCHES:
        return None
    for pooled in (False, True):
        cell = size
        for _ in range(COARSE_CELL_DOUBLINGS + 1):
            groups = patch_groups(patches, cell, settings, coarse=True, pooled=pooled)
            if clustering_pays(len(patches), groups, settings):
                return CoarseGroups(groups, cell, pooled)
            cell *= 2.0
    return None


def split_levels(settings: RadiositySettings) -> int:
    """Levels of leaf splits the hierarchy may make below its first leaves (refinement, and the
    shadow-edge and near-field splits, which share passes), for its memory bound."""
    return max(settings.refine_levels, 0) + max(settings.shadow_splits, settings.near_splits, 0)


def hierarchical_memory(scene: Scene, roots: patching.Patches, depth: int, bvh,
                        settings: RadiositySettings, facing: tuple[int, int] | None = None
                        ) -> dict:
    """The hierarchical solver's memory (bytes by part, "total") over `hierarchy_roots`' roots
    and depth, bounded before it links. facing: `facing_roots(roots)` when the caller has it;
    when counted here or given, the result keeps it as "facing" (pairs, most)."""
    def memory(facing=None) -> dict:
        bound = memory_bound(len(roots), depth, settings.link_epsilon,
                             settings.samples_per_side, split_levels(settings),
                             settings.max_patches, facing)
        out = {"links": bound["links"], "patches": bound["elements"], "work": bound["work"],
               "bvh": 200 * scene.triangle_count, "bvh_queries": bvh.settings.query_bytes,
               "world_rays": sky_ray_bytes(settings.max_patches, settings.world_rays)
               if world_lit(scene) else 0}
        out["total"] = int(sum(out.values()))
        out["link_bound"] = bound["link_bound"]
        if facing is not None:
            out["facing"] = tuple(facing)
        return out

    if facing is not None:
        return memory(facing)
    found = memory()
    if found["total"] > settings.hierarchy_memory_limit and len(roots) ** 2 <= FACING_COUNT_PAIRS:
        # Many roots (a room of many small triangles): count the root pairs that can exchange
        # light at all, which only then costs more than a few ms (0.4 s at 3k roots).
        found = memory(facing_roots(roots))
    return found


@dataclass(frozen=True, eq=False)
class HierarchyPlan:
    """What the hierarchical solver runs with (`hierarchical_plan`)."""

    settings: RadiositySettings  # "auto" resolved; max_patches lowered to fit the memory limit
    roots: patching.Patches  # `hierarchy_roots`' roots
    depth: int  # levels of elements below the roots
    memory: dict  # bytes by part and "total" (`hierarchical_memory`), bounded before linking


def hierarchical_plan(scene: Scene, size: float, bvh, settings: RadiositySettings,
                      exchanging: np.ndarray, patches: patching.Patches,
                      groups: clusters.Groups | None) -> HierarchyPlan | None:
    """The hierarchical solver's plan when it is the one to run, else None. auto picks it for all
    but small scenes (more than AUTO_DENSE_PATCHES patches) when its bound fits
    `hierarchy_memory_limit` and factors are ray-cast; where only refinement breaks the bound, auto
    lowers `max_patches` (the refined leaves' cap) until it fits (`capped_refinement`) rather
    than hand the scene to a matrix solver. exchanging: `exchanging_triangles`; patches: theirs
    at `size`, what the other solvers would start from; groups: their `patch_groups`."""
    if settings.solver not in ("hierarchical", "auto"):
        return None
    if settings.solver == "auto" and settings.method != "raycast":
        return None
    if settings.solver == "auto":
        # Finely tessellated meshes: their patches solved as groups (`clusters.py`) are far
        # fewer unknowns than the hierarchy's leaves, one or more per triangle.
        if clustering_pays(len(patches), groups, settings):
            return None
    roots, depth, wanted = hierarchy_roots(scene, size, settings.max_depth, exchanging,
                                           wanted=len(patches))
    memory = hierarchical_memory(scene, roots, depth, bvh, settings)
    if settings.solver == "auto" and memory["total"] > settings.hierarchy_memory_limit:
        settings, memory = capped_refinement(scene, roots, depth, bvh, settings, memory)
    if settings.solver == "auto" and (wanted <= AUTO_DENSE_PATCHES
                                      or memory["total"] > settings.hierarchy_memory_limit):
        return None
    return HierarchyPlan(settings, roots, depth, memory)


def capped_refinement(scene: Scene, roots: patching.Patches, depth: int, bvh,
                      settings: RadiositySettings, memory: dict) -> tuple[RadiositySettings, dict]:
    """`settings` with the largest `max_patches` (refined leaves) whose hierarchical bound fits
    `hierarchy_memory_limit`, and that bound; `settings` and `memory` as they are when refinement
    is off or the unrefined leaves alone break it. The fallback would be Gauss-Seidel over the
    refined patches' dense matrix, O(N^2) ray-cast factors: shadows.blend with refine_levels 2
    took 671 s there against 10 s hierarchical."""
    first = len(roots) * 4**depth
    if split_levels(settings) < 1 or settings.max_patches <= first:
        return settings, memory

    facing = memory.get("facing")  # counted by the bound that broke the limit, if at all

    def bound(cap: int) -> dict:
        return hierarchical_memory(scene, roots, depth, bvh, replace(settings, max_patches=cap),
                                   facing)

    low, high = first, settings.max_patches  # bound(low) may fit, bound(high) does not
    if bound(low)["total"] > settings.hierarchy_memory_limit:
        return settings, memory
    while high - low > max(1, first // 100):  # the bound grows with the cap: bisect
        mid = (low + high) // 2
        if bound(mid)["total"] <= settings.hierarchy_memory_limit:
            low = mid
        else:
            high = mid
    return replace(settings, max_patches=low), bound(low)
