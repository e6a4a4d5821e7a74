"""The solved scene: `RadiosityResult`, B anywhere on the surface."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..geometry.camera import Strata
from ..geometry.scene import Scene, triangle_emission
from . import final_gather
from . import patches as patching
from .final_gather import FinalGather
from .sources import MAX_REFLECTANCE


@dataclass(frozen=True, eq=False)
class RadiosityResult:
    """The solved scene.

    patches     `Patches` (N of them)
    radiosity   (N, 3) float64  B, W/m^2 (exitance; outgoing radiance is B / pi)
    emitted     (N, 3) float64  pi x emission radiance, W/m^2
    direct      (N, 3) float64  the lights' direct irradiance H (first shot), W/m^2
    reflectance (N, 3) float64  rho
    corner_b    (N, 3, 3)       B at each patch corner (`patches.fitted_corner_values`),
                                its reflected part under the specular layer (`layer_factors`)
    corner_e    (N, 3, 3)       the same for `emitted`
    stats       dict            patch counts per level, solver, memory estimate, seconds
    gather      FinalGather     what the final gather reads at receivers; None: interpolate B
    back_of     (T,) int64      the turned-over copy of each sheet triangle the solve added
                                (`sheets.py`), -1 for none; None: no copies
    """

    patches: patching.Patches
    radiosity: np.ndarray
    emitted: np.ndarray
    direct: np.ndarray
    reflectance: np.ndarray
    corner_b: np.ndarray
    corner_e: np.ndarray
    stats: dict = field(default_factory=dict)
    gather: FinalGather | None = None
    back_of: np.ndarray | None = None

    @property
    def notes(self) -> tuple[str, ...]:
        """What the solve took otherwise than the scene has it, one line each."""
        return tuple(f"material '{name}': a diffuse reflectance of 1 or more; the radiosity solve "
                     f"takes it at {MAX_REFLECTANCE} (the iteration needs some light kept back)"
                     for name in self.stats.get("capped_reflectance", ()))

    def exitance_at(self, tri: np.ndarray, bary: np.ndarray, reflected_only: bool = False,
                    interpolated: bool = False, known: final_gather.Visibility | None = None,
                    visibility_out: final_gather.Visibility | None = None,
                    strata: Strata | None = None, albedo: np.ndarray | None = None
                    ) -> np.ndarray:
        """(M, 3) B at points given as scene triangles (M,) and barycentrics (M, 3): the final
        gather's when the result has one (`final_gather.py`, which also takes `known` and fills
        `visibility_out`, `strata`: pixels' sub-samples that share out the emitters' points,
        and `albedo` (M, 3): the points' base colours, e.g. filtered over their pixels), else
        (or with `interpolated`) B interpolated from the patch corners.
        `reflected_only`: B minus the emission (what Cycles' DIFFUSE bake sees, times pi)."""
        if self.gather is not None and not interpolated:
            return final_gather.exitance(self.gather, tri, bary, reflected_only, known,
                                         visibility_out, strata, self._reflected, albedo)
        patch, local = patching.locate(self.patches, tri, bary)
        values = patching.interpolate(self.corner_b, patch, local)
        if reflected_only:
            values -= patching.interpolate(self.corner_e, patch, local)
        return values

    def _reflected(self, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """(M, 3) W/m^2: the solution's reflected exitance, interpolated (what a gather's
        bounce rays see on the surfaces they meet)."""
        return self.exitance_at(tri, bary, reflected_only=True, interpolated=True)

    def radiance_at(self, tri: np.ndarray, bary: np.ndarray, reflected_only: bool = False,
                    interpolated: bool = False, known: final_gather.Visibility | None = None,
                    visibility_out: final_gather.Visibility | None = None,
                    strata: Strata | None = None, albedo: np.ndarray | None = None
                    ) -> np.ndarray:
        """(M, 3) outgoing radiance B / pi, W/(m^2 sr) (see `exitance_at`)."""
        return self.exitance_at(tri, bary, reflected_only, interpolated, known,
                                visibility_out, strata, albedo) / np.pi

    def back_radiance_at(self, scene: Scene, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """(M, 3) outgoing radiance W/(m^2 sr) of the back side of surface points of `scene`
        (triangles, barycentrics): the emission and, with the final gather, the direct light
        that reaches the back and one bounce of this solution's light off the surfaces the back
        faces (`final_gather.back_exitance`). The solution itself is one-sided: without the
        gather a back side shows its emission only. A sheet's back that the solve gave a copy
        of its own (`back_of`) shows that copy's front."""
        tri = np.asarray(tri, np.int64)
        copy = self.back_of[tri] if self.back_of is not None else np.full(len(tri), -1)
        out = np.empty((len(tri), 3))
        sheets = copy >= 0  # a sheet's back: its copy's front, corners in reverse order
        if sheets.any():
            out[sheets] = self.radiance_at(copy[sheets], np.asarray(bary)[sheets][:, ::-1])
        rest = ~sheets
        if not rest.any():
            return out
        if self.gather is not None:
            out[rest] = final_gather.back_exitance(
                self.gather, tri[rest], np.asarray(bary)[rest], self._reflected) / np.pi
        else:
            out[rest] = triangle_emission(scene)[tri[rest]]
        return out
