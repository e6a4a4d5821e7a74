"""Shaft culling: which receiver and emitter triangles see each other whole, decided without rays.

Every segment from a point of triangle A to a point of triangle B lies in the convex hull of
their six corners (the "shaft" of Haines and Wallace, "Shaft culling for efficient ray-cast
radiosity", 1994). If no scene triangle enters that hull, every point of A sees all of B, so the
visible share of B from anywhere on A is exactly 1 and no shadow ray needs to be cast. The final
gather asks this per (patch, emissive triangle) pair once per solution; a texel in a clear patch
then costs its exact unoccluded point-to-polygon factor and nothing else.

The hull's face planes are found by enumeration: a face of the hull of two convex polygons is one
of the polygons, or holds an edge of one and a corner of the other (its intersection with either
polygon's plane is an edge or a corner of that polygon). So the candidates are A's plane, B's
plane and the 18 planes through an edge of one and a corner of the other; a candidate is kept,
facing outwards, when all six corners lie on one side of it. Any kept plane is a supporting plane
of the hull, so a triangle wholly outside one of them is outside the hull, and so is a triangle
whose own plane has all six corners on one side (`BVH.convex_clear`). The test is conservative:
a triangle that only a hull edge's cross product would separate counts as entering, which costs
rays, never a wrong answer.

The same test with the prism swept from a patch along its normal (`open_above`) tells which
patches no back face hangs over: the final gather's enclosure probe (a ray along the normal that
meets a back face) cannot find them enclosed, so it is not cast.
"""

from __future__ import annotations

import numpy as np

from . import threads

# Planes through three corners closer to collinear than this (|cross| relative to the squared
# longest edge) are skipped: a sliver's plane is meaningless, and the hull keeps its other faces.
DEGENERATE_REL = 1e-12
# Corners may sit this far (fraction of the pair's extent) on the wrong side of a candidate plane
# and it still counts as supporting: float rounding of coplanar corners (1e-16 relative) with a
# wide margin, far below any geometry that could block a ray.
SUPPORT_REL = 1e-9
# Regions handed to a thread at a time (a few ms of plane tests each).
THREAD_PAIRS = 1024
# Edges (start corner, end corner) of a triangle.
_EDGES = ((0, 1), (1, 2), (2, 0))


def hull_planes(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Supporting planes of the convex hull of triangles a (P, 3, 3) and b (P, 3, 3), world m.

    Returns normals (P, K, 3) unit and offsets (P, K) m, K <= 20: every corner of the pair
    satisfies n . x <= d. Candidates that are degenerate or support nothing are dropped, or
    where a pair has fewer planes than K, padded with a zero normal and d = +inf (bounding
    nothing)."""
    a = np.asarray(a, np.float64)
    b = np.asarray(b, np.float64)
    corners = np.concatenate([a, b], axis=1)  # (P, 6, 3)
    # Candidate planes as point triples: each triangle's own plane, then edge x opposite corner.
    triples = [(0, 1, 2), (3, 4, 5)]
    triples += [(3 * s + i, 3 * s + j, 3 * (1 - s) + k)
                for s in (0, 1) for i, j in _EDGES for k in range(3)]
    idx = np.array(triples)  # (20, 3)
    p0, p1, p2 = (corners[:, idx[:, c]] for c in range(3))  # (P, 20, 3)
    normal = np.cross(p1 - p0, p2 - p0)
    extent = np.ptp(corners, axis=1).max(axis=1)[:, None]  # (P, 1) m
    length = np.linalg.norm(normal, axis=2)
    usable = length > DEGENERATE_REL * np.maximum(extent, 1e-300) ** 2
    normal = np.divide(normal, length[..., None], out=np.zeros_like(normal),
                       where=usable[..., None])
    offset = np.einsum("pkc,pkc->pk", normal, p0)
    side = np.einsum("pkc,pvc->pkv", normal, corners) - offset[..., None]  # (P, 20, 6)
    tol = SUPPORT_REL * extent
    below = (side <= tol[..., None]).all(axis=2)
    above = (side >= -tol[..., None]).all(axis=2)
    flip = above & ~below
    normal[flip] *= -1.0
    offset[flip] *= -1.0
    supporting = usable & (below | above)
    normal[~supporting] = 0.0
    offset[~supporting] = np.inf
    # Supporting planes first, then only as many columns as the pair with the most needs (a
    # hull of two triangles has about 8 faces): the culling tests cost per column.
    order = np.argsort(~supporting, axis=1, kind="stable")
    keep = max(1, int(supporting.sum(axis=1).max(initial=1)))
    order = order[:, :keep]
    return (np.take_along_axis(normal, order[:, :, None], axis=1),
            np.take_along_axis(offset, order, axis=1))


def clear_pairs(a: np.ndarray, b: np.ndarray, bvh, slack: float) -> np.ndarray:
    """(P,) bool: no triangle of `bvh` enters the shaft between triangles a[p] and b[p]
    (P, 3, 3), world m, by more than `slack` m (the rays' own offset off surfaces: the pair's
    own triangles and their coplanar neighbours lie on the shaft's faces)."""
    if len(a) == 0:
        return np.zeros(0, bool)
    out = np.empty(len(a), bool)

    def work(lo: int, hi: int) -> None:
        normals, offsets = hull_planes(a[lo:hi], b[lo:hi])
        out[lo:hi] = bvh.convex_clear(normals, offsets, np.concatenate([a[lo:hi], b[lo:hi]], axis=1),
                                      slack)

    threads.for_ranges(work, len(a), THREAD_PAIRS, min_rows=THREAD_PAIRS // 4)
    return out


def open_above(tris: np.ndarray, normals: np.ndarray, height: float, bvh, slack: float
               ) -> np.ndarray:
    """(P,) bool: no triangle of `bvh` that faces away from triangle tris[p] (P, 3, 3) (front
    normal along normals[p] (P, 3), unit) enters the prism swept from it along its normal for
    `height` m (the scene's extent: nothing lies beyond), by more than `slack` m."""
    tris = np.asarray(tris, np.float64)
    count = len(tris)
    if count == 0:
        return np.zeros(0, bool)
    n = np.asarray(normals, np.float64)
    base = np.einsum("pc,pc->p", n, tris[:, 0])
    planes = [-n, n]  # in front of the base, below the cap
    offsets = [-base, base + height]
    for i, j in _EDGES:  # the side walls through each edge, parallel to the normal, outwards
        side = np.cross(tris[:, j] - tris[:, i], n)
        side /= np.maximum(np.linalg.norm(side, axis=1), 1e-300)[:, None]
        planes.append(side)
        offsets.append(np.einsum("pc,pc->p", side, tris[:, i]))
    planes, offsets = np.stack(planes, axis=1), np.stack(offsets, axis=1)
    corners = np.concatenate([tris, tris + height * n[:, None, :]], axis=1)
    out = np.empty(count, bool)

    def work(lo: int, hi: int) -> None:
        out[lo:hi] = bvh.convex_clear(planes[lo:hi], offsets[lo:hi], corners[lo:hi], slack,
                                      facing=n[lo:hi])

    threads.for_ranges(work, count, THREAD_PAIRS, min_rows=THREAD_PAIRS // 4)
    return out
