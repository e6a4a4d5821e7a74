"""Patch geometry and quadrature points on patches: `patch_geometry`, `sample_patches`,
`triangle_midpoints`. Patches are (N, K, 3) corners, world m (conventions: `form_factors`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np


@dataclass(frozen=True, eq=False)
class PatchGeometry:
    """What the estimators need of (N, K, 3) patch corners.

    centres  (N, 3) float64  world, m: the corners' mean (the area centroid for parallelograms)
    normals  (N, 3) float64  world, unit: front normal (Newell's, counter-clockwise winding)
    areas    (N,)   float64  m^2
    scale    float           m: bounding-box diagonal of all corners (sets the ray offsets)
    """

    centres: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    scale: float


def patch_geometry(corners: np.ndarray) -> PatchGeometry:
    """Centres, unit normals, areas and overall scale of (N, K, 3) planar polygons."""
    v = as_corners(corners)
    # Newell: the vector area is half the sum of V_k x V_k+1 (exact for planar polygons).
    vector_area = 0.5 * np.cross(v, np.roll(v, -1, axis=1)).sum(axis=1)  # (N, 3)
    areas = np.linalg.norm(vector_area, axis=1)
    if np.any(areas <= 0.0):
        raise ValueError(f"patches {np.flatnonzero(areas <= 0.0)[:8].tolist()} have zero area")
    flat = v.reshape(-1, 3)
    scale = float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))
    return PatchGeometry(v.mean(axis=1), vector_area / areas[:, None], areas, scale)


SampleRule = Literal["gauss", "stratified", "midpoint"]


def sample_patches(
    corners: np.ndarray,
    n: int,
    rule: SampleRule = "midpoint",
    rng: np.random.Generator | None = None,
    cells: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """(n cells)^2 quadrature points per patch in the bilinear (u, v) square, with area weights.

    | rule       | points in (u, v)                                 | weights                 |
    |------------|--------------------------------------------------|-------------------------|
    | gauss      | Gauss-Legendre nodes (exact for degree 2n - 1)   | Gauss weights x Jacobian|
    |            | in each of cells x cells sub-squares (composite) |                         |
    | stratified | one uniform point per cell of an m x m grid (rng)| Jacobian                |
    | midpoint   | cell centres of an m x m grid                    | Jacobian                |

    (m = n cells.)
    corners (N, K, 3). K <= 4: one bilinear map x(u, v) (a triangle repeats its last corner);
    K > 4 (convex): a fan of K triangles around the corners' mean, n x n points each. Returns
    points (N, S, 3) float64 and weights (N, S) float64, normalised to sum 1 per patch, so
    sum_s w_s f(x_s) estimates the area average of f over the patch.
    """
    v = as_corners(corners)
    count, k = v.shape[:2]
    if k == 3 and rule == "midpoint":
        return triangle_midpoints(v, n * cells)
    if k == 3:
        quads = np.concatenate([v, v[:, 2:3]], axis=1)[:, None]  # (N, 1, 4, 3)
    elif k == 4:
        quads = v[:, None]
    else:  # fan around the corners' mean: (C, Vt, Vt+1, Vt+1), no slivers for regular polygons
        centre = np.broadcast_to(v.mean(axis=1, keepdims=True), v.shape)
        nxt = np.roll(v, -1, axis=1)
        quads = np.stack([centre, v, nxt, nxt], axis=2)
    pieces = quads.shape[1]
    m = n * cells
    if rule == "gauss":
        nodes, node_w = np.polynomial.legendre.leggauss(n)
        offsets = np.arange(cells, dtype=np.float64)[:, None]
        grid = ((offsets + 0.5 * (nodes + 1.0)) / cells).ravel()
        grid_w = np.tile(0.5 * node_w / cells, cells)
    else:
        check_rule(rule)
        grid, grid_w = (np.arange(m, dtype=np.float64) + 0.5) / m, np.full(m, 1.0 / m)
    uu, vv = np.meshgrid(grid, grid, indexing="ij")
    shape = (count, pieces, m * m)
    u = np.broadcast_to(uu.ravel(), shape)
    w = np.broadcast_to(vv.ravel(), shape)
    if rule == "stratified":
        rng = rng if rng is not None else np.random.default_rng(0)
        u = u + (rng.random(shape) - 0.5) / m
        w = w + (rng.random(shape) - 0.5) / m
    u, w = u[..., None], w[..., None]
    q0, q1, q2, q3 = (quads[:, :, c][:, :, None] for c in range(4))  # (N, P, 1, 3)
    points = (1 - u) * (1 - w) * q0 + u * (1 - w) * q1 + u * w * q2 + (1 - u) * w * q3
    du = (1 - w) * (q1 - q0) + w * (q2 - q3)
    dv = (1 - u) * (q3 - q0) + u * (q2 - q1)
    jac = np.linalg.norm(np.cross(du, dv), axis=-1) * np.outer(grid_w, grid_w).ravel()
    jac = jac.reshape(count, -1)
    return points.reshape(count, -1, 3), jac / jac.sum(axis=1, keepdims=True)


def triangle_midpoints(triangles: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """The centroids of the m^2 equal triangles that cutting each side of each triangle (N, 3, 3)
    into m makes, weights 1 / m^2: points (N, m^2, 3), weights (N, m^2). Exact for linear
    functions at any m (m = 1: the centroid), unlike the bilinear square folded onto a triangle,
    whose cell centres crowd toward the repeated corner."""
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    up = (i + j <= m - 1).ravel()
    down = (i + j <= m - 2).ravel()
    a = np.concatenate([i.ravel()[up] + 1.0 / 3.0, i.ravel()[down] + 2.0 / 3.0]) / m
    b = np.concatenate([j.ravel()[up] + 1.0 / 3.0, j.ravel()[down] + 2.0 / 3.0]) / m
    bary = np.stack([1.0 - a - b, a, b], axis=1)  # (m^2, 3) weights of corners 0, 1, 2
    points = np.einsum("sk,nkc->nsc", bary, triangles)
    return points, np.full(points.shape[:2], 1.0 / (m * m))


def check_rule(rule: str) -> None:
    if rule not in ("gauss", "stratified", "midpoint"):
        raise ValueError(f"sampling rule must be gauss, stratified or midpoint, got {rule!r}")


def as_corners(corners: np.ndarray) -> np.ndarray:
    v = np.asarray(corners, np.float64)
    if v.ndim != 3 or v.shape[2] != 3 or v.shape[1] < 3:
        raise ValueError(f"patch corners must be (N, K >= 3, 3), got {v.shape}")
    return v
