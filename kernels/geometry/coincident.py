"""Coincident opposite faces: two triangles in one plane facing away from each other.

A box resting on a floor puts its bottom face in the floor's plane, facing down against the
floor's up. A ray crossing there meets both at the same distance, and a closest-hit query returns
one of them (the BVH's tie goes to the lower triangle index), so a walk that counts the surfaces
it crosses (`radiosity.final_gather.enclosed`) would miss the other. `CoincidentFaces` answers,
for a hit on one face, whether an opposite face lies under the hit point.

It also says which faces have a solid behind them (their object reaches behind their plane: the
box's bottom, its sides rising above the floor). A sheet modelled double-sided, two opposite
faces in one plane and nothing behind either, is no solid to leave: a walk crosses it as two
surfaces that cancel.

Planes are matched on a grid: unit normals to NORMAL_GRID, offsets to the caller's tolerance
(the ray offset: surfaces closer than it are one surface to every ray).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Unit normals are compared to this grid: two faces whose normals differ by less are one plane's.
NORMAL_GRID = 1e-4
# Vertices of an object read at a time when finding how far it reaches behind a face.
SUPPORT_CHUNK = 1 << 16
# Barycentric slack of the point-in-triangle test (a hit on the shared edge of two triangles
# belongs to both).
BARY_SLACK = 1e-9


@dataclass(frozen=True, eq=False)
class CoincidentFaces:
    """triangles (T, 3, 3) world m; group (T,) the plane of each triangle, opposite (T,) the plane
    of its opposite (-n, -d); order (T,) triangles sorted by group, starts (G + 1,) where each
    group begins in `order`; solid (T,) bool: the triangle's object reaches behind its plane
    (`_reach_behind`; asked only of triangles whose opposite plane holds faces)."""

    triangles: np.ndarray
    group: np.ndarray
    opposite: np.ndarray
    order: np.ndarray
    starts: np.ndarray
    solid: np.ndarray

    @classmethod
    def find(cls, triangles: np.ndarray, normals: np.ndarray, objects: np.ndarray,
             tolerance: float) -> CoincidentFaces:
        """triangles (T, 3, 3) world m, their unit normals (T, 3), objects (T,) int the object of
        each; tolerance m (> 0): plane offsets closer than this match, and an object reaching
        less than this behind a face is no solid there."""
        tris = np.asarray(triangles, np.float64)
        n = np.asarray(normals, np.float64)
        d = np.einsum("ij,ij->i", n, tris[:, 0]) if len(tris) else np.zeros(0)
        key = np.column_stack([np.round(n / NORMAL_GRID), np.round(d / tolerance)]).astype(np.int64)
        keys = np.concatenate([key, -key])  # each plane, then its opposite
        _, inverse = np.unique(keys, axis=0, return_inverse=True)
        inverse = inverse.ravel()
        group, opposite = inverse[:len(tris)], inverse[len(tris):]
        order = np.argsort(group, kind="stable")
        starts = np.searchsorted(group[order], np.arange(int(inverse.max(initial=-1)) + 2))
        # Which faces have a solid behind them, asked only of those in a plane whose opposite
        # holds faces (the only ones a pair can hold).
        solid = np.zeros(len(tris), bool)
        candidates = np.flatnonzero(np.isin(group, opposite))
        solid[candidates] = _reach_behind(tris, n, d, np.asarray(objects), candidates) > tolerance
        return cls(tris, group, opposite, order, starts, solid)

    def covered(self, tri: np.ndarray, points: np.ndarray, solid: bool = False) -> np.ndarray:
        """(R,) bool: an opposite face of triangle tri[r] lies under points[r] (R, 3) (on tri[r]);
        with `solid`, one with a solid behind it."""
        out = np.zeros(len(tri), bool)
        planes = self.opposite[tri]
        paired = np.flatnonzero(self.starts[planes + 1] > self.starts[planes])  # most hit none
        for plane in np.unique(planes[paired]):
            members = self.order[self.starts[plane]:self.starts[plane + 1]]
            if solid:
                members = members[self.solid[members]]
            rows = paired[planes[paired] == plane]
            out[rows] = _inside_any(points[rows], self.triangles[members])
        return out


def _reach_behind(triangles: np.ndarray, normals: np.ndarray, offsets: np.ndarray,
                  objects: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(len(rows),) m: how far behind the plane of each triangle of `rows` its object reaches,
    offsets[r] - min over the object's vertices v of normals[r] . v (0 for a flat object)."""
    out = np.zeros(len(rows))
    owner = objects[rows]
    for obj in np.unique(owner):
        mine = rows[owner == obj]
        vertices = triangles[objects == obj].reshape(-1, 3)
        lowest = np.full(len(mine), np.inf)
        for start in range(0, len(vertices), SUPPORT_CHUNK):
            heights = normals[mine] @ vertices[start:start + SUPPORT_CHUNK].T  # (P, chunk)
            lowest = np.minimum(lowest, heights.min(axis=1))
        out[owner == obj] = offsets[mine] - lowest
    return out


def _inside_any(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """(R,) bool: points (R, 3), lying in the triangles' plane, inside any of triangles (M, 3, 3)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]  # (M, 3)
    e1, e2 = b - a, c - a
    p = points[:, None, :] - a[None]  # (R, M, 3)
    d11, d12, d22 = (np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e1, e2),
                     np.einsum("ij,ij->i", e2, e2))
    p1, p2 = np.einsum("rmj,mj->rm", p, e1), np.einsum("rmj,mj->rm", p, e2)
    det = d11 * d22 - d12 * d12
    safe = np.where(det > 0.0, det, 1.0)
    u = (d22 * p1 - d12 * p2) / safe
    v = (d11 * p2 - d12 * p1) / safe
    inside = (u >= -BARY_SLACK) & (v >= -BARY_SLACK) & (u + v <= 1.0 + BARY_SLACK) & (det > 0.0)
    return inside.any(axis=1)
