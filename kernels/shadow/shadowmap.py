"""Shadow mapping: the lecture's two-pass z-buffer shadow test, with the usual cures for its flaws.

The lecture (lecture 13, "4. Shadow Mapping"; L. Williams, "Casting curved shadows on curved
surfaces", SIGGRAPH 1978):
  1. Put the viewer at the light position L and render the scene into a z-buffer: the shadow map M.
  2. For each receiver point f, with depth z_f seen from L at map pixel p: f is lit when
     |z_f - M_p| <= eps ("test case (b) first": the tolerance against self-shadowing) or
     z_f <= M_p; otherwise f is shadowed.

Depth is the linear view depth in metres (see `raster.py`), so eps is a world distance.

This module holds the settings and the data: a map's views and depth buffers, and receivers
prepared once for any number of lights. Choosing and fitting the views per light kind is
`views.py`, rendering step 1 into them `depth_maps.py`, step 2 (the depth test with its
tolerance, normal offset and percentage-closer filtering) `depth_test.py`, and the pictures and
failure measures (acne, peter-panning) `measures.py`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..geometry.raster import Projection
from ..geometry.threads import core_count
from ..geometry.vec import COLUMN_BLOCK, bounds_of_parts

EpsMode = Literal["fixed", "auto"]
MapKind = Literal["ORTHO", "PERSP", "CUBE"]

TINY = np.float32(1e-30)  # guards divisions by cos(theta) = 0: far below any real cosine, and
#                          the quotient is capped at TAN_THETA_MAX anyway
UNIT_LENGTH2_TOL = 1e-6  # |n|^2 this close to 1 is unit for the tolerance's slopes: a relative
#                          error of 5e-7 in cos(theta), below float32 rounding of the products


@dataclass(frozen=True)
class ShadowMapSettings:
    """How the shadow map is made and read.

    | field         | range           | default | unit / meaning                                  |
    |---------------|-----------------|---------|-------------------------------------------------|
    | resolution    | [8, 16384]      | 2048    | texels along the map's longer side (per face)   |
    | eps_mode      | "fixed", "auto" | "auto"  | auto adds the minimum bias of shadow_bias.json  |
    | eps           | [0, inf)        | 0.0     | m, the lecture's constant tolerance             |
    | slope_bias    | [0, inf)        | 0.0     | texels of depth slope added (Direct3D's slope-  |
    |               |                 |         | scaled depth bias, in world units)              |
    | normal_offset | [0, inf)        | 0.0     | texels: receivers move along their normal       |
    | pcf_size      | odd, [1, 15]    | 1       | k: k x k percentage-closer filtering (1: off)   |
    | shadow_back_  | bool            | True    | receivers whose normal faces away from the light|
    |   faces       |                 |         | (N.L < 0) are shadowed, as N.L shading and      |
    |               |                 |         | Cycles' SHADOW bake have it; False: tested      |
    | threads       | >= 0            | 1       | lookup threads; 0: one per CPU core (see        |
    |               |                 |         | depth_test.MIN_THREAD_RECEIVERS: when they pay) |
    """

    resolution: int = 2048
    eps_mode: EpsMode = "auto"
    eps: float = 0.0
    slope_bias: float = 0.0
    normal_offset: float = 0.0
    pcf_size: int = 1
    shadow_back_faces: bool = True
    threads: int = 1

    def __post_init__(self) -> None:
        if not 8 <= self.resolution <= 16384:
            raise ValueError(f"resolution {self.resolution} outside [8, 16384]")
        if self.eps_mode not in ("fixed", "auto"):
            raise ValueError(f"eps_mode must be 'fixed' or 'auto', got {self.eps_mode!r}")
        biases = (self.eps, self.slope_bias, self.normal_offset)
        if not all(math.isfinite(b) and b >= 0.0 for b in biases):  # nan passed a "< 0" test
            raise ValueError(f"eps, slope_bias and normal_offset must be finite and >= 0, got "
                             f"{biases}")
        if self.pcf_size < 1 or self.pcf_size % 2 == 0 or self.pcf_size > 15:
            raise ValueError(f"pcf_size must be odd in [1, 15], got {self.pcf_size}")
        if self.threads < 0:
            raise ValueError(f"threads must be >= 0, got {self.threads}")

    @property
    def thread_count(self) -> int:
        return self.threads or core_count()


@dataclass(frozen=True, eq=False)
class ShadowView:
    """One rendered view of the light: its projection and its z-buffer."""

    projection: Projection
    depth: np.ndarray  # (H, W) float32, linear view depth from the light (m), +inf: nothing
    # Partly covering casters (0 < alpha < 1: a tinted window, a leaf's soft edge), where the
    # view has them (`cutouts.py`): what they let through, the product of their 1 - alpha
    # (H, W) float32, and the depth of the nearest (H, W) float32 m, +inf: none.
    veil: np.ndarray | None = None
    veil_depth: np.ndarray | None = None

    @property
    def texel_size(self) -> tuple[float, float]:
        """Texel (width, height): metres (ORTHO) or on the image plane at distance 1 (PERSP)."""
        left, right, bottom, top = self.projection.extent
        height, width = self.depth.shape
        return (right - left) / width, (top - bottom) / height


@dataclass(frozen=True, eq=False)
class ShadowMap:
    """The shadow map of one light: one view (SUN, SPOT) or six cube faces (CUBE, face order)."""

    kind: MapKind
    views: tuple[ShadowView, ...]
    light_position: np.ndarray  # (3,) float64, world m (the sun: its map's eye)
    light_direction: np.ndarray  # (3,) float64, world unit: where the light points
    settings: ShadowMapSettings


@dataclass(frozen=True, eq=False)
class Receivers:
    """Receivers prepared once for any number of lights: columns, unit normals and bounds.

    The lookup works on (3, N) float32 columns relative to the receivers' centre (see
    `depth_test._look_up`); transposing, centring, normalising and bounding them is paid once per
    bake instead of once per light. A bake's receivers come in parts (an object's lightmap
    texels, its corners): `of_parts` reads them in place, as if concatenated, without the copy.
    """

    positions: tuple[np.ndarray, ...]  # (N_k, 3) world m, the parts as given (not copied)
    local: np.ndarray  # (3, N) float32, world position - centre, m
    centre: np.ndarray  # (3,) float64, the bounding box's centre, world m
    normals: np.ndarray  # (3, N) float32, world unit; zero where unknown
    no_normal: np.ndarray | None  # (N,) bool, the zero normals; None when there are none
    lo: np.ndarray  # (3,) float64, bounding box, world m
    hi: np.ndarray  # (3,) float64

    @classmethod
    def of(cls, points: np.ndarray, normals: np.ndarray) -> Receivers:
        """From (N, 3) world points (m) and normals (any length; zero: unknown)."""
        return cls.of_parts((points,), (normals,))

    @classmethod
    def of_parts(cls, points: Sequence[np.ndarray], normals: Sequence[np.ndarray]) -> Receivers:
        """From parts of (N_k, 3) world points (m) and their normals (any length; zero: unknown),
        in order: the receivers of `of(concatenated points, concatenated normals)`."""
        points = tuple(np.asarray(p).reshape(-1, 3) for p in points)
        normals = tuple(np.asarray(n).reshape(-1, 3) for n in normals)
        if [len(p) for p in points] != [len(n) for n in normals]:
            raise ValueError("every part needs one normal per point")
        count = sum(len(p) for p in points)
        # The box first: the centre precedes `local`.
        lo, hi = bounds_of_parts(points) if count else (np.zeros(3), np.zeros(3))
        centre = 0.5 * (lo + hi)
        local = np.empty((3, count), np.float32)
        nrm = np.empty((3, count), np.float32)
        shortest = longest = 1.0
        first = 0
        for part, part_normals in zip(points, normals, strict=True):
            # A cache-sized block at a time: no (3, N) float64 copy or (N,) temporaries.
            for a in range(0, len(part), COLUMN_BLOCK):
                b = min(a + COLUMN_BLOCK, len(part))
                cols = slice(first + a, first + b)
                np.subtract(part[a:b].T, centre[:, None], out=local[:, cols], casting="same_kind")
                np.copyto(nrm[:, cols], part_normals[a:b].T, casting="same_kind")
                length2 = np.einsum("ij,ij->j", nrm[:, cols], nrm[:, cols])
                shortest = min(shortest, float(length2.min()))
                longest = max(longest, float(length2.max()))
            first += len(part)
        # Bake targets pass unit normals: rescaling them would change nothing but cost 0.5 ms.
        zero = None
        if not 1.0 - UNIT_LENGTH2_TOL <= shortest <= longest <= 1.0 + UNIT_LENGTH2_TOL:
            length2 = np.einsum("ij,ij->j", nrm, nrm)
            zero = length2 == 0.0 if shortest == 0.0 else None
            nrm *= 1.0 / np.sqrt(np.maximum(length2, TINY))  # zero normals stay zero
        return cls(points, local, centre, nrm, zero, lo, hi)

    def sample(self, count: int) -> np.ndarray:
        """(M, 3) float64 world m: every max(1, N // count)-th receiver from the first, the rows
        `np.concatenate(positions)[::step]` would give (an even stride for planning)."""
        step = max(1, len(self) // max(count, 1))
        picks, start = [], 0
        for part in self.positions:
            picks.append(np.asarray(part[(-start) % step :: step], np.float64))
            start += len(part)
        return np.concatenate(picks) if picks else np.zeros((0, 3))

    def __len__(self) -> int:
        return self.local.shape[1]

    @property
    def box(self) -> np.ndarray:
        """(2, 3) float64: the bounding box's two corners (stand-ins for culling and planning)."""
        return np.stack([self.lo, self.hi])

    @property
    def size(self) -> float:
        """Largest |world coordinate| of any receiver, m."""
        return float(max(np.abs(self.lo).max(), np.abs(self.hi).max()))


def shared_depth(shadow_map: ShadowMap) -> np.ndarray | None:
    """The (V, H, W) array whose slices the views' depth buffers are (a planned cube map), or
    None."""
    first = shadow_map.views[0].depth
    base = first.base
    if base is None or base.shape != (len(shadow_map.views), *first.shape):
        return None
    return base if all(np.shares_memory(v.depth, base) for v in shadow_map.views) else None
