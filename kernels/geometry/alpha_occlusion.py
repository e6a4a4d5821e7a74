"""Any-hit occlusion through partly covered surfaces (alpha): transmittance of shadow rays.

A surface of coverage alpha in [0, 1] (a leaf card's texture: 0 in the holes, 1 on the leaf)
lets a ray through with weight 1 - alpha, as Cycles' transparent shadows do. Along a segment
the transmittance is the product over every surface it meets:

    T = prod_k (1 - alpha_k)        (0 as soon as it meets an opaque surface)

Found with the BVH's own queries, its internals untouched: one any-hit test (`BVH.occluded`)
settles the rays that meet nothing (T = 1, the common case, at the usual cost); the others walk
their hits front to back with closest-hit queries (`BVH.intersect`), each restarting just
beyond the last hit (`offset`), until they leave the segment, meet an opaque surface, or carry
less than `AnyHitSettings.opaque_below`.

`AlphaOccluder` puts this behind the BVH's `occluded` signature for kernels that take a
yes / no visibility query (radiosity): a ray is blocked with probability 1 - T, an unbiased
estimate of the transmittance in expectation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .bvh import BVH
from .intersect import Hits

# Coverage at hits: (tri (N,) int, u (N,), v (N,) barycentrics of corners 1 and 2) -> (N,) alpha
# in [0, 1]; 1 where a triangle is opaque.
Coverage = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
# Which triangles are opaque whatever their texture says: (tri (N,)) -> (N,) bool.
Opaque = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class AnyHitSettings:
    """| field        | range   | default | meaning                                              |
    |--------------|---------|---------|------------------------------------------------------|
    | max_layers   | >= 1    | 64      | alpha surfaces one ray walks through before it stops |
    |              |         |         | (the transmittance so far is kept): a bound on work  |
    | opaque_below | [0, 1)  | 1e-4    | a ray carrying less transmittance counts as blocked  |
    |              |         |         | (Cycles' shadow rays stop so at full absorption)     |
    """

    max_layers: int = 64
    opaque_below: float = 1e-4


def _queries(bvh, origins, directions, t_min, t_max):
    """The BVH's own queries (an `AlphaOccluder`'s, not its stochastic one), the rays as
    contiguous float64 (R, 3) and their segments as (R,) float64 copies the walk may move."""
    if isinstance(bvh, AlphaOccluder):
        bvh = bvh.bvh
    origins = np.ascontiguousarray(origins, np.float64)
    directions = np.ascontiguousarray(directions, np.float64)
    count = len(origins)
    t_lo = np.broadcast_to(np.asarray(t_min, np.float64), (count,)).copy()
    t_hi = np.broadcast_to(np.asarray(t_max, np.float64), (count,)).copy()
    return bvh, origins, directions, t_lo, t_hi


def transmittance(bvh: BVH, origins: np.ndarray, directions: np.ndarray, t_min, t_max,
                  coverage: Coverage, offset: float, opaque: Opaque | None = None,
                  skip: np.ndarray | None = None,
                  settings: AnyHitSettings = AnyHitSettings()) -> np.ndarray:  # noqa: B008
    """(R,) float64 in [0, 1]: the fraction of each ray's light that passes [t_min, t_max].

    | parameter  | shape / range       | unit / meaning                                         |
    |------------|---------------------|--------------------------------------------------------|
    | origins    | (R, 3)              | world, m                                               |
    | directions | (R, 3), nonzero     | world; t is in units of |direction|                    |
    | t_min/max  | scalar or (R,)      | the segment                                            |
    | coverage   | Coverage            | alpha at hits (`shading/alpha.py`'s `SceneAlpha`)      |
    | offset     | > 0                 | m: how far beyond a hit the next query starts (the     |
    |            |                     | scene's ray offset, `frames.RAY_OFFSET_REL` x its size)|
    | opaque     | Opaque or None      | triangles known opaque: no look-up there               |
    | skip       | (R,) int or None    | a triangle each ray passes through (-1: none)          |
    """
    bvh, origins, directions, t_lo, t_hi = _queries(bvh, origins, directions, t_min, t_max)
    count = len(origins)
    out = np.ones(count)
    if count == 0:
        return out
    # The rays that meet nothing keep T = 1 after the cheap any-hit test.
    rays = np.flatnonzero(bvh.occluded(origins, directions, t_lo, t_hi, skip=skip))
    step = offset / np.maximum(np.linalg.norm(directions, axis=1), 1e-30)  # (R,) in t units
    for _ in range(settings.max_layers):
        if rays.size == 0:
            break
        hits: Hits = bvh.intersect(origins[rays], directions[rays], t_lo[rays], t_hi[rays])
        met = hits.tri >= 0
        rays, tri = rays[met], hits.tri[met].astype(np.int64)
        u, v, t = hits.u[met], hits.v[met], hits.t[met].astype(np.float64)
        alpha = np.ones(len(rays))
        passed = np.zeros(len(rays), bool) if skip is None else tri == skip[rays]
        look = ~passed if opaque is None else ~passed & ~opaque(tri)
        if look.any():
            alpha[look] = np.clip(coverage(tri[look], u[look], v[look]), 0.0, 1.0)
        alpha[passed] = 0.0
        out[rays] *= 1.0 - alpha
        blocked = out[rays] < settings.opaque_below
        out[rays[blocked]] = 0.0
        t_lo[rays] = t + step[rays]
        rays = rays[~blocked]
    return out


@dataclass(frozen=True, eq=False)
class Layers:
    """The surfaces rays see through partly covered ones, front to back: K entries, each a hit
    (or a miss) of ray `ray[k]` seen with weight `weight[k]`.

    ray:    (K,) int64, the ray each entry belongs to (a ray's entries in the order met)
    weight: (K,) float64, the ray's transmittance before the surface times the surface's alpha
            (a miss: the transmittance left)
    hits:   Hits of K rows (tri -1 for a miss)
    """

    ray: np.ndarray
    weight: np.ndarray
    hits: Hits

    def first(self) -> np.ndarray:
        """(K,) bool: the entries that are their ray's first (what the ray meets first)."""
        out = np.zeros(len(self.ray), bool)
        out[np.unique(self.ray, return_index=True)[1]] = True
        return out

    def front_hits(self, count: int) -> Hits:
        """Hits of the `count` rays: each ray's first entry (a miss for a ray without one,
        which lost its light in holes past `AnyHitSettings.max_layers`)."""
        first = np.flatnonzero(self.first())
        rays = self.ray[first]
        hits = Hits(np.full(count, np.inf, np.float32), np.full(count, -1, np.int32),
                    np.zeros(count, np.float32), np.zeros(count, np.float32))
        for name in ("t", "tri", "u", "v"):
            getattr(hits, name)[rays] = getattr(self.hits, name)[first]
        return hits


def layered_hits(bvh: BVH, origins: np.ndarray, directions: np.ndarray, t_min, t_max,
                 coverage: Coverage, offset: float, opaque: Opaque | None = None,
                 settings: AnyHitSettings = AnyHitSettings()) -> Layers:  # noqa: B008
    """What each ray sees as Cycles blends partly covered surfaces: a surface of coverage a in
    front of what lies behind shows a S + (1 - a) T. Each ray yields one entry per surface of
    alpha > 0 it meets, weighted by the transmittance before it times its alpha, until an
    opaque surface, a miss (weighted by the transmittance left), or less than
    `settings.opaque_below` left; a ray past `settings.max_layers` surfaces loses the rest.
    Parameters as `transmittance`."""
    bvh, origins, directions, t_lo, t_hi = _queries(bvh, origins, directions, t_min, t_max)
    hits = bvh.intersect(origins, directions, t_lo, t_hi)
    step = offset / np.maximum(np.linalg.norm(directions, axis=1), 1e-30)  # (R,) in t units
    left = np.ones(len(origins))
    rays = np.arange(len(origins))
    parts = []  # (rays, weights, Hits) per layer
    for _ in range(settings.max_layers):
        tri = hits.tri.astype(np.int64)
        alpha = np.ones(len(rays))  # a miss ends the ray with the light left, as an opaque hit
        look = tri >= 0
        if opaque is not None and look.any():
            look[look] = ~opaque(tri[look])
        if look.any():
            alpha[look] = np.clip(coverage(tri[look], hits.u[look], hits.v[look]), 0.0, 1.0)
        seen = alpha > 0.0
        parts.append((rays[seen], left[rays[seen]] * alpha[seen],
                      Hits(hits.t[seen], hits.tri[seen], hits.u[seen], hits.v[seen])))
        left[rays] *= 1.0 - alpha
        on = left[rays] >= settings.opaque_below
        rays, t_next = rays[on], hits.t[on].astype(np.float64)
        if rays.size == 0:
            break
        t_lo[rays] = t_next + step[rays]
        hits = bvh.intersect(origins[rays], directions[rays], t_lo[rays], t_hi[rays])
    ray = np.concatenate([r for r, _, _ in parts])
    return Layers(ray=ray, weight=np.concatenate([w for _, w, _ in parts]),
                  hits=Hits(*(np.concatenate([getattr(h, f) for _, _, h in parts])
                              for f in ("t", "tri", "u", "v"))))


class AlphaOccluder:
    """A BVH whose `occluded` sees through alpha: a ray is blocked with probability 1 - T
    (`transmittance`), drawn from `rng`; the other queries are the BVH's own (closest hits see
    every surface as opaque)."""

    def __init__(self, bvh: BVH, coverage: Coverage, offset: float, opaque: Opaque | None = None,
                 rng: np.random.Generator | None = None,
                 settings: AnyHitSettings = AnyHitSettings()):  # noqa: B008
        self.bvh = bvh
        self.coverage = coverage
        self.offset = offset
        self.opaque = opaque
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.any_hit = settings  # not `settings`: that name is the BVH's own (read through)

    def transmittance(self, origins, directions, t_min=0.0, t_max=np.inf, skip=None) -> np.ndarray:
        """(R,) float64: `transmittance` of these rays."""
        return transmittance(self.bvh, origins, directions, t_min, t_max, self.coverage,
                             self.offset, self.opaque, skip, self.any_hit)

    def occluded(self, origins, directions, t_min=0.0, t_max=np.inf, out=None,
                 skip=None) -> np.ndarray:
        """(R,) bool: blocked with probability 1 - transmittance (`BVH.occluded`'s signature)."""
        t = self.transmittance(origins, directions, t_min, t_max, skip)
        blocked = self.rng.random(len(t)) >= t
        if out is not None:
            out[:] = blocked
            return out
        return blocked

    def __getattr__(self, name):
        return getattr(self.bvh, name)
