"""What a probe gives the camera view besides the mirror look-up: rough reflections from the GGX
mip chain (by roughness, trilinear) and diffuse light from the SH9 irradiance.

Rough reflections. `prefilter.py` level k holds the surroundings averaged over the GGX lobe of
roughness k / (levels - 1) around each direction (the split-sum assumption n = v = r). A surface
of roughness rho reads the level coordinate x = the piecewise-linear inverse of that table
(rho (levels - 1) for the prefilter's levels), bilinearly on levels floor(x) and floor(x) + 1,
and blends the two by the fraction of x: trilinear filtering, as a reflection probe's sampler
does with its LOD. The view's weight for the lobe (the metal's Fresnel averaged over it) is the
tracer's; the lamps' highlights come from the tracer's direct light, not from the mips.

Diffuse light. A Lambertian surface of albedo a under irradiance E(n) reflects L = a E / pi; the
SH9 coefficients give E along the surface's normal (`sh_irradiance.irradiance`); the tracer
multiplies it by the diffuse part's albedo / pi (`lambert_radiance`).

Every level is given a one-texel border (`bordered_level`) so that bilinear look-ups blend across
the faces' edges as the captured map's rendered border does (`cubemap.sample_bordered`).
Faces are (6, M, M, C) float32 radiance, OpenGL face table of `cubemap.py`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cubemap import BORDER, bordered_directions, sample_bordered, sample_cubemap
from .prefilter import PrefilteredCube
from .sh_irradiance import irradiance


def bordered_level(faces: np.ndarray, border: int = BORDER) -> np.ndarray:
    """(6, M, M, C) -> (6, M + 2B, M + 2B, C) float32: the faces inside, and around them a border
    of B texels read from the neighbouring faces along the border texels' directions (the same
    90-degree camera's wider frustum, as `envmap.capture_steps` renders it)."""
    faces = np.asarray(faces, np.float32)
    size, channels = faces.shape[1], faces.shape[3]
    side = size + 2 * border
    out = np.empty((6, side, side, channels), np.float32)
    ring = np.ones((side, side), bool)
    ring[border:border + size, border:border + size] = False
    dirs = bordered_directions(size, border)[:, ring]                           # (6, R, 3)
    out[:, ring] = sample_cubemap(faces, dirs.reshape(-1, 3)).reshape(6, -1, channels)
    out[:, border:border + size, border:border + size] = faces
    return out


@dataclass(frozen=True)
class GlossyMips:
    """A prefiltered chain ready for look-ups: bordered levels and the roughness of each."""

    levels: tuple[np.ndarray, ...]  # (6, M_k + 2B, M_k + 2B, C) float32 radiance
    roughness: tuple[float, ...]    # per level, increasing (the prefilter's table)
    border: int = BORDER

    @classmethod
    def from_prefiltered(cls, cube: PrefilteredCube, level0: np.ndarray | None = None,
                         border: int = BORDER) -> GlossyMips:
        """From `prefilter.prefilter`'s chain; `level0`: an already bordered mirror level (the
        captured map's own faces, whose border was rendered) to use instead of padding level 0."""
        levels = [bordered_level(level, border) for level in cube.levels]
        if level0 is not None:
            levels[0] = np.asarray(level0, np.float32)
        return cls(tuple(levels), tuple(float(r) for r in cube.roughness), border)

    def level_coordinate(self, roughness: np.ndarray) -> np.ndarray:
        """(N,) roughness -> (N,) float64 level coordinate: the piecewise-linear inverse of the
        levels' roughness, clamped to [0, levels - 1]."""
        return np.interp(np.asarray(roughness, np.float64), self.roughness,
                         np.arange(len(self.roughness), dtype=np.float64))

    def lookup(self, directions: np.ndarray, roughness: np.ndarray) -> np.ndarray:
        """(N, 3) directions, (N,) roughness -> (N, C) float64 prefiltered radiance: bilinear on
        the two levels around each roughness, blended linearly between them."""
        x = self.level_coordinate(roughness)
        lo = np.minimum(np.floor(x).astype(np.int64), len(self.levels) - 1)
        frac = x - lo
        channels = self.levels[0].shape[3]
        out = np.zeros((len(x), channels))
        for k in np.unique(lo):
            rows = np.flatnonzero(lo == k)
            out[rows] = sample_bordered(self.levels[k], self.border, directions[rows])
            up = rows[frac[rows] > 0.0]
            if len(up) and k + 1 < len(self.levels):
                f = frac[up, None]
                upper = sample_bordered(self.levels[k + 1], self.border, directions[up])
                out[up] = out[up] * (1.0 - f) + upper * f
        return out


def lambert_radiance(sh: np.ndarray, normals: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """(9, C) SH9 radiance coefficients, (N, 3) unit normals, (N, C) albedo -> (N, C) float64
    radiance a Lambertian surface reflects under the band-limited irradiance: a E(n) / pi."""
    return np.asarray(albedo, np.float64) * irradiance(sh, normals) / np.pi
