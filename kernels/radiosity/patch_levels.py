"""The matrix solvers' levels: the patches themselves, their form factors one row at a time
(`form_factors`: ray-cast or hemicube) and B = E + rho F B solved in RGB (`solvers.py`):
Gauss-Seidel on the dense matrix when it fits `dense_memory_limit`, else progressive refinement
(one row per shot, never N x N), or the clustered solver over groups of patches (`clusters.py`).
"""

from __future__ import annotations

import time

import numpy as np

from ..geometry.bvh import BVH
from ..geometry.frames import RAY_OFFSET_REL
from ..geometry.scene import Scene
from ..progress import Steps, scaled
from ..shading.world_light import world_lit
from . import clusters
from . import patches as patching
from .form_factors.hemicube import HemicubeFormFactors, HemicubeSettings
from .form_factors.raycast import RayCastFormFactors, RayCastSettings
from .form_factors.rows import enforce_reciprocity, iter_matrix
from .levels import LevelLight, LevelSolution, SolveContext
from .planning import CoarseGroups, choose_solver, memory_estimate, patch_groups, quick_test_pays
from .settings import RadiositySettings
from .solvers import GaussSeidelSettings, GaussSeidelSolver, ProgressiveSettings, ProgressiveSolver


class PatchLevels:
    """`levels.Levels` of the matrix solvers: the patches, split in place level by level.

    groups: the first patches' `planning.patch_groups` (None where no solver uses groups);
    coarse: how coarse ones were made where auto chose them (`planning.coarse_groups_pay`),
    None for groups at the patch size; split
    children, known lit or shadowed once the lamps have shot, are grouped apart
    (`clusters.light_bucket`)."""

    def __init__(self, ctx: SolveContext, patches: patching.Patches,
                 groups: clusters.Groups | None, coarse: CoarseGroups | None = None) -> None:
        self.ctx = ctx
        self.current = patches
        self.groups = groups
        self.coarse = coarse
        self.fresh = np.ones(len(patches), bool)  # the patches no shadow-edge test has seen

    @property
    def count(self) -> int:
        return len(self.current)

    def untested(self) -> patching.Patches:
        return self.current.subset(self.fresh)

    def split_untested(self, mask: np.ndarray) -> None:
        full = np.zeros(len(self.current), bool)
        full[self.fresh] = mask
        self.current, self.fresh = patching.split_children(self.ctx.scene, self.current, full)

    def patches(self) -> patching.Patches:
        return self.current

    def refine(self, mask: np.ndarray) -> None:
        self.current = patching.split(self.ctx.scene, self.current, mask)

    def solve_steps(self, light: LevelLight) -> Steps[LevelSolution]:
        ctx, patches = self.ctx, self.current
        if self.groups is not None and (patches.level > 0).any():
            # Without split children these are the first patches and their groups as they were.
            self.groups = (patch_groups(patches, ctx.size, ctx.settings, light.direct)
                           if self.coarse is None else
                           self.coarse.regrouped(patches, ctx.settings, light.direct))
        stats: dict = {"patches": len(patches), "per_level": patches.level_counts()}
        b = yield from _solve_level(ctx, patches, light, self.groups, stats)
        return LevelSolution(b, stats)

    def stats(self, levels: list[dict]) -> dict:
        last = levels[-1]
        out = {"levels": levels, "solver": last["solver"],
               "memory_estimate": last["memory_estimate"], "method": self.ctx.settings.method}
        if self.coarse is not None:  # how far auto coarsened the groups to fit the memory limit
            out["coarse_groups"] = {"cell_m": self.coarse.cell, "pooled": self.coarse.pooled}
        return out


def _rows(scene: Scene, patches: patching.Patches, bvh, settings: RadiositySettings):
    corners = patches.corners
    if settings.method == "hemicube":
        patch_bvh = BVH.build(corners.astype(np.float32))
        hemi = HemicubeSettings(resolution=settings.hemicube_resolution,
                                points_per_side=settings.samples_per_side, seed=settings.seed)
        return HemicubeFormFactors(
            corners, lambda o, d, t0, t1: patch_bvh.intersect(o, d, t0, t1),
            np.arange(len(patches)), hemi)
    ray = RayCastSettings(samples_per_side=settings.samples_per_side,
                          visibility_samples_per_side=settings.visibility_samples_per_side,
                          seed=settings.seed)
    quick = quick_test_pays(len(patches), scene.triangle_count)
    return RayCastFormFactors(
        corners, lambda o, d, t0, t1: bvh.occluded(o, d, t0, t1),
        triangles=scene.triangles if quick else None, settings=ray)


def _solve_level(ctx: SolveContext, patches: patching.Patches, light: LevelLight,
                 groups: clusters.Groups | None, stats: dict) -> Steps[np.ndarray]:
    """Form factors and solve of one level's patches (`patch_groups` of them: `groups`); yields
    progress, returns B (N, 3) without the shot emission. stats: receives the level's figures."""
    scene, settings, bvh = ctx.scene, ctx.settings, ctx.bvh
    count = len(patches)
    rho, sources = light.reflectance, light.sources
    solver = choose_solver(count, settings, groups)
    stats["solver"] = solver
    stats["memory_estimate"] = memory_estimate(count, scene.triangle_count, settings, solver,
                                               groups.count if groups is not None else 0,
                                               world_lit(scene))
    start = time.perf_counter()
    if solver == "clustered":
        b, solution = yield from _solve_clustered(patches, groups, rho, sources, bvh, settings,
                                                  stats, RAY_OFFSET_REL * ctx.scale)
    elif solver == "gauss_seidel":
        rows = _rows(scene, patches, bvh, settings)
        matrix = np.empty((count, count))
        yield from scaled(iter_matrix(rows, matrix), 0.0, 0.9)
        if settings.method == "hemicube":  # estimated rows: make the pairs agree
            enforce_reciprocity(matrix, patches.areas, out=matrix)
        stats["form_factor_seconds"] = time.perf_counter() - start
        gs = GaussSeidelSolver(matrix, sources, rho,
                               GaussSeidelSettings(tolerance=settings.tolerance))
        yield from scaled(gs.run(), 0.9, 0.1)
        solution = gs.solution()
        b = solution.radiosity
    else:
        rows = _rows(scene, patches, bvh, settings)
        # Keep as many rows as the memory limit allows: a patch is shot again and again when
        # rho is high, and a row costs O(N) form factors with rays.
        cache = int(min(count, settings.dense_memory_limit // (8 * count)))
        prog = ProgressiveSolver(rows, sources, rho, patches.areas,
                                 ProgressiveSettings(tolerance=settings.tolerance,
                                                     row_cache=cache,
                                                     max_shots=settings.max_shots or 1_000_000))
        for p in prog.run():
            yield max(p, prog.shots / settings.max_shots) if settings.max_shots else p
        solution = prog.solution()
        b = solution.radiosity
    stats["solve_seconds"] = time.perf_counter() - start
    stats["iterations"] = solution.iterations
    stats["converged"] = bool(solution.converged)
    stats["solver_error"] = float(solution.error)
    return b


def _solve_clustered(patches, groups, rho, sources, bvh, settings, stats, offset: float):
    """Generator: `_solve_level`'s clustered solver (`clusters.py`, shadow rays lifted `offset`
    m); yields progress, returns (B per patch (N, 3), the solution over the groups)."""
    start = time.perf_counter()
    factors = yield from scaled(clusters.factor_steps(
        patches, groups, settings.samples_per_side, offset,
        lambda o, d, t0, t1: bvh.occluded(o, d, t0, t1), np.random.default_rng(settings.seed)),
        0.0, 0.9)
    stats["form_factor_seconds"] = time.perf_counter() - start
    stats["groups"] = groups.count
    stats["clustered_patches"] = int(groups.sizes[~groups.lone].sum())
    return (yield from scaled(clusters.solve_steps(patches, groups, sources, rho, factors,
                                                   settings.tolerance), 0.9, 0.1))
