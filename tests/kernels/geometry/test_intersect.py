"""The watertight ray-triangle test and the brute-force reference (kernels/intersect.py).

Ground truth is analytic (planes and triangles with known hit points) or an independent float64
Moeller-Trumbore computation written here. Tolerances:
* distances: float32 storage and arithmetic keep |t - t64| <= 4e-6 * (|o| + t |d|) / |d|, i.e. a
  few float32 ulps of the larger of the origin's and the hit point's coordinates;
* barycentrics: within 4e-6 of the float64 values for well-shaped triangles.
"""

from __future__ import annotations

import numpy as np
import pytest

from classic_bake.bench import meshes
from classic_bake.kernels.geometry.intersect import (
    Hits,
    intersect_all,
    occluded_all,
    prepare_rays,
    prepare_triangles,
)

# Relative distance tolerance of float32 arithmetic (see the module docstring).
T_REL = 4e-6
# Barycentric tolerance for well-shaped triangles.
BARY_TOL = 4e-6

UNIT_TRI = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]], np.float32)


def moller_trumbore64(tris: np.ndarray, o: np.ndarray, d: np.ndarray):
    """Independent float64 reference: (t, u, v) of every ray against every triangle, NaN on miss."""
    tris = tris.astype(np.float64)
    o = o.astype(np.float64)[:, None, :]
    d = d.astype(np.float64)[:, None, :]
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("tk,rtk->rt", e1, p)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - v0
        u = np.einsum("rtk,rtk->rt", s, p) * inv
        q = np.cross(s, e1)
        v = np.einsum("rtk,rtk->rt", d, q) * inv
        t = np.einsum("tk,rtk->rt", e2, q) * inv
    hit = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0)
    nan = np.full_like(t, np.nan)
    return np.where(hit, t, nan), np.where(hit, u, nan), np.where(hit, v, nan)


def test_hit_point_distance_and_barycentrics_of_one_triangle():
    o = np.array([[0.25, 0.5, 2.0], [0.25, 0.5, -3.0]], np.float32)
    d = np.array([[0.0, 0.0, -2.0], [0.0, 0.0, 1.0]], np.float32)
    hits = intersect_all(UNIT_TRI, o, d)
    # t is in units of |direction|: 2 m at |d| = 2 is t = 1; the second ray travels 3 m.
    np.testing.assert_array_equal(hits.tri, [0, 0])
    np.testing.assert_allclose(hits.t, [1.0, 3.0], rtol=T_REL)
    # u weighs corner 1 (x), v corner 2 (y): the point (0.25, 0.5) has u = 0.25, v = 0.5.
    np.testing.assert_allclose(hits.u, [0.25, 0.25], atol=BARY_TOL)
    np.testing.assert_allclose(hits.v, [0.5, 0.5], atol=BARY_TOL)
    assert hits.t.dtype == np.float32 and hits.tri.dtype == np.int32


def test_matches_float64_moller_trumbore_on_random_triangles():
    rng = np.random.default_rng(3)
    tris = rng.uniform(-1, 1, (40, 3, 3)).astype(np.float32)
    o = rng.uniform(-2, 2, (1000, 3)).astype(np.float32)
    d = rng.normal(size=(1000, 3)).astype(np.float32)
    # Half the rays aim at random points of random triangles.
    w = rng.dirichlet(np.ones(3), 500)[:, :, None]
    d[:500] = (w * tris[rng.integers(0, 40, 500)]).sum(1) - o[:500]
    t64, u64, v64 = moller_trumbore64(tris, o, d)
    closest = np.where(np.isnan(t64), np.inf, t64)
    ref_tri = np.where(np.isfinite(closest.min(1)), closest.argmin(1), -1)
    hits = intersect_all(tris, o, d)
    # Rays that graze an edge within float32 rounding may differ; there must be very few.
    differ = hits.tri != ref_tri
    assert differ.mean() < 0.01
    same = (~differ) & (ref_tri >= 0)
    assert same.sum() > 400
    r = np.flatnonzero(same)
    t_ref = t64[r, ref_tri[r]]
    scale = (np.abs(o[r]).max(1) + t_ref * np.abs(d[r]).max(1)) / np.linalg.norm(d[r], axis=1)
    assert np.all(np.abs(hits.t[r] - t_ref) <= T_REL * scale)
    # Barycentrics rebuild the hit point on the triangle.
    tri = tris[hits.tri[r]].astype(np.float64)
    bu, bv = hits.u[r, None], hits.v[r, None]
    point = (1 - bu - bv) * tri[:, 0] + bu * tri[:, 1] + bv * tri[:, 2]
    along = o[r] + hits.t[r, None] * d[r]
    assert np.all(np.linalg.norm(point - along, axis=1) <= 1e-5 * (1 + np.abs(along).max(1)))


def test_closed_range_and_t_limits_per_ray():
    o = np.zeros((4, 3), np.float32) + [0.25, 0.25, 1.0]
    d = np.tile(np.float32([0, 0, -1]), (4, 1))
    # The hit is at t = 1 exactly: [t_min, t_max] is closed on both ends.
    t_min = np.array([0.0, 1.0, 1.0001, 0.0], np.float32)
    t_max = np.array([1.0, 5.0, 5.0, 0.9999], np.float32)
    hits = intersect_all(UNIT_TRI, o, d, t_min=t_min, t_max=t_max)
    np.testing.assert_array_equal(hits.tri, [0, 0, -1, -1])
    np.testing.assert_array_equal(occluded_all(UNIT_TRI, o, d, t_min, t_max), [1, 1, 0, 0])
    with pytest.raises(ValueError):
        intersect_all(UNIT_TRI, o, d, t_min=-1.0)


def test_both_faces_hit_and_rays_behind_miss():
    o = np.array([[0.2, 0.2, 1.0], [0.2, 0.2, -1.0], [0.2, 0.2, 1.0]], np.float32)
    d = np.array([[0, 0, -1], [0, 0, 1], [0, 0, 1]], np.float32)
    np.testing.assert_array_equal(intersect_all(UNIT_TRI, o, d).tri, [0, 0, -1])


def test_parallel_rays_miss_without_nan():
    # In the triangle's plane (through its interior) and above it, parallel to it.
    o = np.array([[-1.0, 0.25, 0.0], [-1.0, 0.25, 0.5], [0.25, -1.0, 0.0]], np.float32)
    d = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], np.float32)
    with np.errstate(all="raise"):
        hits = intersect_all(UNIT_TRI, o, d)
    np.testing.assert_array_equal(hits.tri, [-1, -1, -1])
    assert not np.isnan(hits.t).any()


def test_degenerate_triangles_are_ignored_never_nan():
    tris = np.array(
        [
            [[0, 0, 0], [1, 0, 0], [2, 0, 0]],  # collinear
            [[0, 0, 0], [0, 0, 0], [0, 1, 0]],  # repeated corner
            [[0.5, 0.5, 0], [0.5, 0.5, 0], [0.5, 0.5, 0]],  # a point
            [[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]],  # not finite
        ],
        np.float32,
    )
    prepared = prepare_triangles(tris)
    assert not prepared.valid.any()
    rng = np.random.default_rng(0)
    o = rng.uniform(-1, 2, (500, 3)).astype(np.float32)
    # Aim at the degenerate triangles' points and edges.
    targets = np.concatenate([tris[:3].reshape(-1, 3), [[0.5, 0.0, 0.0], [0.0, 0.5, 0.0]]])
    d = (targets[rng.integers(0, len(targets), 500)] - o).astype(np.float32)
    hits = intersect_all(tris, o, d)
    assert (hits.tri == -1).all() and np.isinf(hits.t).all()
    assert not np.isnan(hits.u).any()


def test_invalid_rays_miss():
    o = np.array([[0.2, 0.2, 1.0], [0.2, 0.2, 1.0], [np.nan, 0.2, 1.0], [0.2, 0.2, 1.0]])
    d = np.array([[0, 0, 0], [0, 0, np.inf], [0, 0, -1], [0, 0, -1]])
    rays = prepare_rays(o, d)
    np.testing.assert_array_equal(rays.valid, [False, False, False, True])
    np.testing.assert_array_equal(intersect_all(UNIT_TRI, o, d).tri, [-1, -1, -1, 0])


def test_ties_go_to_the_lower_triangle_index():
    tris = np.concatenate([UNIT_TRI, UNIT_TRI[:, ::-1], UNIT_TRI]).astype(np.float32)
    hits = intersect_all(tris, [[0.2, 0.3, 1.0]], [[0, 0, -1.0]])
    assert hits.tri[0] == 0
    # Reversed winding, same point: same distance, mirrored barycentrics.
    alone = intersect_all(tris[1:2], [[0.2, 0.3, 1.0]], [[0, 0, -1.0]])
    assert alone.t[0] == hits.t[0]


def test_rays_through_shared_vertices_and_edges_never_miss():
    """Watertightness, brute force: every ray from inside a closed icosphere through a vertex or
    an edge point hits. (test_bvh.py repeats this at millions of rays through the BVH.)"""
    verts, faces = meshes.icosphere_indexed(2)
    tris = verts.astype(np.float32)[faces]
    rng = np.random.default_rng(5)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    s = rng.uniform(0, 1, (len(edges), 1)).astype(np.float32)
    v32 = verts.astype(np.float32)
    edge_points = v32[edges[:, 0]] + s * (v32[edges[:, 1]] - v32[edges[:, 0]])
    targets = np.concatenate([v32, edge_points, v32[edges[:, 0]] * np.float32(0.5)
                              + v32[edges[:, 1]] * np.float32(0.5)])
    for origin in ([0, 0, 0], [0.1, -0.2, 0.05], [0.3, 0.3, -0.3]):
        o = np.tile(np.float32(origin), (len(targets), 1))
        hits = intersect_all(tris, o, targets - o)
        assert (hits.tri >= 0).all()
        # The hit is at the aimed point: t = 1 within float32 rounding.
        np.testing.assert_allclose(hits.t, 1.0, atol=1e-5)


def test_every_hit_lies_in_its_padded_box():
    tris = meshes.lumpy_sphere(2)
    prepared = prepare_triangles(tris)
    lo, hi = prepared.boxes
    assert np.all(lo.T <= tris.min(axis=1)) and np.all(hi.T >= tris.max(axis=1))
    assert np.all(hi - lo > 0)


def test_empty_inputs():
    empty = np.zeros((0, 3, 3), np.float32)
    hits = intersect_all(empty, [[0, 0, 0]], [[1, 0, 0]])
    assert hits.tri[0] == -1 and np.isinf(hits.t[0])
    assert len(intersect_all(UNIT_TRI, np.zeros((0, 3)), np.zeros((0, 3)))) == 0
    assert not occluded_all(empty, [[0, 0, 0]], [[1, 0, 0]])[0]
    assert len(Hits.empty(3)) == 3
