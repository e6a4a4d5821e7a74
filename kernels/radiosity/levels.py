"""One level of a solve: what every level shares (`SolveContext`), the light a level's patches start
from (`LevelLight`), what a solver makes of it (`LevelSolution`), and the patch sets the level
loop of `solve.py` splits and solves (`Levels`: the patches themselves for the matrix solvers,
`patch_levels.py`; the leaves of a hierarchy for the hierarchical solver, `hierarchical.py`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..geometry.frames import RAY_OFFSET_REL
from ..geometry.scene import Scene
from ..progress import Steps
from . import patches as patching
from .clusters import CLUSTER_AREA_SHARE
from .emitters import Emitters, clear_shafts
from .lamps import LampShadows
from .settings import RadiositySettings
from .sources import first_shot, patch_emission, patch_reflectance, shot_emission, world_shot


@dataclass(frozen=True, eq=False)
class SolveContext:
    """What every level of one solve shares."""

    scene: Scene  # as the solve lights it (`sources.with_world_suns`)
    settings: RadiositySettings  # "auto" resolved
    bvh: object  # kernels.geometry.bvh.BVH over scene.triangles
    size: float  # m, the patch size asked for
    scale: float  # m, the scene's bounding-box diagonal
    emitters: Emitters  # the emissive triangles that shoot first (`shot_emitters`)
    # What the lamps' and emitters' shadow rays meet (shadowless surfaces passed, each lamp under
    # shadow linking its own: `lamps.LampShadows`); None: `bvh`.
    shadows: LampShadows | None = None

    def occluded(self, origins, directions, t_min, t_max) -> np.ndarray:
        """The BVH's visibility query between surfaces: (R,) bool."""
        return self.bvh.occluded(origins, directions, t_min, t_max)

    @property
    def shadow_occluded(self) -> LampShadows:
        """The lights' shadow-ray query (origins, directions, t_min, t_max) -> (R,) bool, each
        lamp under shadow linking taking its own."""
        return LampShadows(self.bvh) if self.shadows is None else self.shadows


@dataclass(frozen=True, eq=False)
class LevelLight:
    """The light one level's N patches start from (`level_light`), W/m^2 unless said.

    reflectance (N, 3)  rho
    emitted     (N, 3)  pi L_e
    shot        (N, 3)  the part of `emitted` the shot emitters send in the first shot
    clear       (N, K)  bool: patch i sees shot emitter k whole (`emitters.clear_shafts`)
    direct      (N, 3)  the first shot's irradiance H (lamps and shot emitters)
    boundary    (N,)    bool: patches across a light's shadow boundary
    world       (N, 3)  the world's irradiance (`sources.world_shot`)
    """

    reflectance: np.ndarray
    emitted: np.ndarray
    shot: np.ndarray
    clear: np.ndarray
    direct: np.ndarray
    boundary: np.ndarray
    world: np.ndarray

    @property
    def sources(self) -> np.ndarray:
        """(N, 3) what the solver carries from: E - E_shot + rho (H + world)."""
        return self.emitted - self.shot + self.reflectance * (self.direct + self.world)


def level_light(ctx: SolveContext, patches: patching.Patches) -> LevelLight:
    """The light `patches` start from: their reflectance, emission, first shot and world light.
    Patches under `clusters.CLUSTER_AREA_SHARE` x the patch size squared test no shafts."""
    scene, settings = ctx.scene, ctx.settings
    rho = patch_reflectance(scene, patches)
    emitted = patch_emission(scene, patches)
    shot = shot_emission(scene, patches, ctx.emitters)
    clear = clear_shafts(patches, ctx.emitters, ctx.bvh, RAY_OFFSET_REL * ctx.scale,
                         CLUSTER_AREA_SHARE * ctx.size * ctx.size)
    direct, boundary = first_shot(scene, patches, ctx.shadow_occluded, settings, ctx.scale,
                                  ctx.emitters,
                                  clear)
    world = world_shot(scene, patches, ctx.bvh, settings, ctx.scale)
    return LevelLight(rho, emitted, shot, clear, direct, boundary, world)


@dataclass(frozen=True, eq=False)
class LevelSolution:
    """What a solver made of one level's light."""

    radiosity: np.ndarray  # (N, 3) B of the patches, W/m^2, without the shot emission
    stats: dict  # the solver's figures for this level


class Levels(Protocol):
    """The patch set the level loop splits and solves."""

    @property
    def count(self) -> int:
        """Patches now (the hierarchy: leaves)."""
        ...

    def untested(self) -> patching.Patches:
        """The patches no split test before the solve (shadow edges, near field) has seen yet."""
        ...

    def split_untested(self, mask: np.ndarray) -> None:
        """Split the `untested` patches `mask` (bool over them); their children are untested."""
        ...

    def patches(self) -> patching.Patches:
        """This level's patches."""
        ...

    def solve_steps(self, light: LevelLight) -> Steps[LevelSolution]:
        """Solve this level's patches lit by `light`; yields progress, returns the solution."""
        ...

    def refine(self, mask: np.ndarray) -> None:
        """Split this level's patches `mask` (bool over `patches()`) for the next level."""
        ...

    def stats(self, levels: list[dict]) -> dict:
        """The solve's figures ("solver", "memory_estimate", "method", "levels", ...) from every
        level's `LevelSolution.stats`."""
        ...
