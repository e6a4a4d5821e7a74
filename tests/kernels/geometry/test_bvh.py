"""The BVH (kernels/geometry/bvh*.py): exact agreement with the brute force, watertightness, edge
cases.

The BVH and `intersect_all` share the triangle test, and the BVH never culls a node holding the
closest hit (see kernels/intersect.py), so the answers must be *identical*: same triangle, same
float32 t, u and v bit for bit. Hypothesis draws the scenes from a small pool of vertices so that
shared vertices and edges, duplicated and degenerate triangles and axis-parallel rays are common.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from classic_bake.bench import meshes
from classic_bake.kernels.geometry import bvh_traversal
from classic_bake.kernels.geometry.bvh import BVH, BVHSettings
from classic_bake.kernels.geometry.intersect import Hits, intersect_all, occluded_all

ONE_THREAD = BVHSettings(threads=1)

coordinate = st.one_of(
    st.integers(-3, 3).map(float),
    st.floats(-4.0, 4.0, allow_nan=False, width=32),
)
point = st.tuples(coordinate, coordinate, coordinate)
tree_settings = st.builds(
    BVHSettings,
    bins=st.integers(2, 16),
    leaf_size=st.integers(1, 6),
    width=st.sampled_from([2, 4, 8]),
    chunk_size=st.sampled_from([256, 1024]),
    threads=st.just(1),
    brute_force_below=st.sampled_from([0, 0, 8, 64]),
    frontier_rays=st.sampled_from([0, 4096]),  # the pool or the breadth-first frontier
)


@st.composite
def scenes(draw):
    """(triangles (T, 3, 3), origins (R, 3), directions (R, 3), t_min, t_max)."""
    pool = np.array(draw(st.lists(point, min_size=3, max_size=16)), np.float32)
    corners = draw(
        st.lists(st.tuples(*[st.integers(0, len(pool) - 1)] * 3), min_size=0, max_size=48)
    )
    tris = pool[np.array(corners, np.int64).reshape(-1, 3)] if corners else np.zeros((0, 3, 3))
    n_rays = draw(st.integers(1, 40))
    origins = np.array(draw(st.lists(point, min_size=n_rays, max_size=n_rays)), np.float32)
    # Aim at pool vertices (shared corners, edges' ends) or along random/axis directions.
    aims = draw(st.lists(st.integers(-4, len(pool) - 1), min_size=n_rays, max_size=n_rays))
    free = np.array(draw(st.lists(point, min_size=n_rays, max_size=n_rays)), np.float32)
    axis = np.eye(3, dtype=np.float32)[np.arange(n_rays) % 3] * np.float32(-1) ** np.arange(n_rays)[
        :, None
    ]
    aims = np.array(aims)
    dirs = np.where((aims >= 0)[:, None], pool[np.maximum(aims, 0)] - origins, free)
    dirs = np.where((aims == -1)[:, None], axis, dirs).astype(np.float32)
    t_min = draw(st.sampled_from([0.0, 0.0, 0.5]))
    t_max = draw(st.sampled_from([np.inf, np.inf, 2.0]))
    return tris.astype(np.float32), origins, dirs, t_min, t_max


def assert_same_hits(a: Hits, b: Hits) -> None:
    np.testing.assert_array_equal(a.tri, b.tri)
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.v, b.v)


@pytest.mark.slow
@settings(
    max_examples=250,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(scene=scenes(), config=tree_settings)
def test_bvh_equals_brute_force(scene, config):
    tris, o, d, t_min, t_max = scene
    bvh = BVH.build(tris, config)
    assert bvh.triangle_count == len(tris)
    assert_same_hits(bvh.intersect(o, d, t_min, t_max), intersect_all(tris, o, d, t_min, t_max))
    np.testing.assert_array_equal(
        bvh.occluded(o, d, t_min, t_max), occluded_all(tris, o, d, t_min, t_max)
    )


@pytest.mark.parametrize("frontier_rays", [0, 4096])
@pytest.mark.parametrize("width", [2, 4, 8])
def test_bvh_equals_brute_force_on_a_mesh(width, frontier_rays):
    tris = meshes.lumpy_sphere(4)  # 5120 triangles
    rng = np.random.default_rng(width)
    o = rng.uniform(-1.3, 1.3, (600, 3)).astype(np.float32)
    d = rng.normal(size=(600, 3)).astype(np.float32)
    t_max = rng.uniform(0.1, 3.0, 600).astype(np.float32)
    bvh = BVH.build(tris, BVHSettings(width=width, threads=1, chunk_size=256,
                                      frontier_rays=frontier_rays))
    ref = intersect_all(tris, o, d)
    assert 0.3 < (ref.tri >= 0).mean() < 0.9
    assert_same_hits(bvh.intersect(o, d), ref)
    np.testing.assert_array_equal(bvh.occluded(o, d, 0.0, t_max), occluded_all(tris, o, d, 0.0, t_max))


@pytest.mark.parametrize("pairs", [7, 100])
def test_frontier_rounds_split_into_bounded_parts(monkeypatch, pairs):
    """A breadth-first round of more than FRONTIER_PAIRS (ray, node) pairs runs in parts, the
    rest waiting: the same answers as brute force."""
    monkeypatch.setattr(bvh_traversal, "FRONTIER_PAIRS", pairs)
    tris = meshes.lumpy_sphere(4)
    rng = np.random.default_rng(3)
    o = rng.uniform(-1.3, 1.3, (3000, 3)).astype(np.float32)
    d = rng.normal(size=(3000, 3)).astype(np.float32)
    bvh = BVH.build(tris, BVHSettings(threads=1))
    assert_same_hits(bvh.intersect(o, d), intersect_all(tris, o, d))
    np.testing.assert_array_equal(bvh.occluded(o, d, 0.0, 0.7), occluded_all(tris, o, d, 0.0, 0.7))


@pytest.mark.parametrize("frontier_rays", [0, 4096])
@pytest.mark.parametrize("mesh", ["sphere", "two triangles"])
def test_occluded_passes_through_the_triangle_each_ray_skips(mesh, frontier_rays):
    """`BVH.occluded(skip=)`: each ray ignores one triangle (its own surface), on the tree's pool,
    its breadth-first frontier and a one-leaf scene's brute force alike: the same answers as
    testing every ray against all triangles but its own."""
    if mesh == "sphere":
        tris = meshes.lumpy_sphere(3)
    else:
        tris = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1], [1, 0, 1], [0, 1, 1]]],
                        np.float32)
    rng = np.random.default_rng(7)
    count = 400
    # Rays from just behind a random triangle's centre, out through it.
    own = rng.integers(0, len(tris), count)
    centre = tris[own].astype(np.float64).mean(axis=1)
    normal = np.cross(tris[own, 1] - tris[own, 0], tris[own, 2] - tris[own, 0]).astype(np.float64)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    o = (centre - 1e-4 * normal).astype(np.float32)
    d = normal + 0.5 * rng.normal(size=(count, 3))
    d = (d * np.sign(np.einsum("ij,ij->i", d, normal))[:, None]).astype(np.float32)  # outwards
    skip = np.where(rng.random(count) < 0.8, own, -1)  # some rays skip nothing
    bvh = BVH.build(tris, BVHSettings(threads=1, chunk_size=256, frontier_rays=frontier_rays))
    expected = np.zeros(count, bool)
    for k in np.unique(skip):
        rows = skip == k
        kept = tris if k < 0 else np.delete(tris, k, axis=0)
        expected[rows] = occluded_all(kept, o[rows], d[rows], 0.0, np.inf)
    got = bvh.occluded(o, d, 0.0, np.inf, skip=skip)
    np.testing.assert_array_equal(got, expected)
    assert got[skip < 0].all()  # without the skip each ray meets its own triangle first
    assert not np.array_equal(got, bvh.occluded(o, d, 0.0, np.inf))


@pytest.mark.slow
def test_watertight_icosphere_two_million_rays():
    """2,000,000 rays through the shared vertices and edges of a closed icosphere (5120 triangles):
    1M from inside it, 1M from outside aimed at the near side. Every ray crosses the surface at
    the aimed point, so every ray must hit, there (t = 1), on a triangle that owns that vertex or
    edge. (A line that only touches a convex surface at a silhouette vertex does not cross it;
    such tangent rays are not part of the watertightness claim and are not drawn here.)"""
    verts, faces = meshes.icosphere_indexed(4)
    v32 = verts.astype(np.float32)
    tris = v32[faces]
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    rng = np.random.default_rng(11)
    n = 1_000_000
    bvh = BVH.build(tris)
    for inside in (True, False):
        pick = rng.integers(0, len(edges), n)
        s = rng.uniform(0.0, 1.0, (n, 1)).astype(np.float32)
        s[: n // 4] = 0.0  # a quarter exactly through shared vertices
        a, b = v32[edges[pick, 0]], v32[edges[pick, 1]]
        target = a + s * (b - a)
        if inside:
            # Uniform in a ball of radius 0.9 (the icosphere's faces are >= 0.99 from the centre).
            ball = rng.normal(size=(n, 3))
            ball *= 0.9 * rng.uniform(0, 1, (n, 1)) ** (1 / 3) / np.linalg.norm(ball, axis=1)[:, None]
            o = ball.astype(np.float32)
        else:
            # From outside, on the target's side of the sphere: the aimed point is the first hit.
            o = (target * rng.uniform(1.5, 4.0, (n, 1)) + rng.normal(size=(n, 3)) * 0.05)
            o = o.astype(np.float32)
        hits = bvh.intersect(o, target - o)
        assert (hits.tri >= 0).all(), f"{(hits.tri < 0).sum()} misses"
        # A call of a few thousand rays walks the tree breadth-first: the same answers.
        few = slice(0, 4096)
        assert_same_hits(bvh.intersect(o[few], (target - o)[few]), Hits(
            t=hits.t[few], tri=hits.tri[few], u=hits.u[few], v=hits.v[few]))
        np.testing.assert_allclose(hits.t, 1.0, atol=1e-4)
        # The triangle owns the aimed vertex or edge: it contains corner a, and b unless s = 0.
        owner = faces[hits.tri]
        assert (owner == edges[pick, 0][:, None]).any(axis=1).all()
        on_edge = s[:, 0] > 0.0
        assert (owner[on_edge] == edges[pick[on_edge], 1][:, None]).any(axis=1).mean() > 0.999
        assert bvh.occluded(o, target - o).all()


def test_rays_parallel_to_triangles():
    floor = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]])
    tris = np.concatenate([floor + [i, j, 0] for i in range(6) for j in range(6)]).astype(
        np.float32
    )
    o = np.array([[-1, 0.5, 0.0], [-1, 0.5, 1e-3], [0.5, -1, 0.0], [-1, 0, 0]], np.float32)
    d = np.array([[1, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
    for config in (BVHSettings(threads=1), BVHSettings(threads=1, brute_force_below=100)):
        hits = BVH.build(tris, config).intersect(o, d)
        assert (hits.tri == -1).all() and not np.isnan(hits.t).any()


def test_rays_leaving_a_surface_skip_it_with_t_min():
    verts, faces = meshes.icosphere_indexed(3)
    tris = verts.astype(np.float32)[faces]
    bvh = BVH.build(tris, ONE_THREAD)
    rng = np.random.default_rng(2)
    face = rng.integers(0, len(tris), 2000)
    w = rng.dirichlet(np.ones(3), 2000).astype(np.float32)[:, :, None]
    o = (w * tris[face]).sum(axis=1)  # on the surface, within float32 rounding
    normal = np.cross(tris[face, 1] - tris[face, 0], tris[face, 2] - tris[face, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    # Outwards (the icosphere is convex): nothing beyond t_min.
    out = bvh.intersect(o, normal, t_min=1e-4)
    assert (out.tri == -1).all()
    assert not bvh.occluded(o, normal, t_min=1e-4).any()
    # Inwards: the far side, never the starting triangle.
    inward = bvh.intersect(o, -normal, t_min=1e-4)
    assert (inward.tri >= 0).all() and (inward.tri != face).all()
    assert (inward.t > 0.1).all()
    # Without t_min a ray starting on the surface may see its own triangle at t ~ 0 (or the one
    # next to it), never something behind it.
    near = bvh.intersect(o, -normal)
    assert ((near.t < 1e-5) | (near.tri == inward.tri)).all()


def test_empty_degenerate_and_single_triangle_scenes():
    o = np.array([[0.2, 0.2, 1.0], [5, 5, 5]], np.float32)
    d = np.array([[0, 0, -1], [1, 0, 0]], np.float32)
    empty = BVH.build(np.zeros((0, 3, 3)))
    assert empty.triangle_count == 0
    hits = empty.intersect(o, d)
    assert (hits.tri == -1).all() and np.isinf(hits.t).all()
    assert not empty.occluded(o, d).any()
    flat = BVH.build(np.zeros((5, 3, 3)))  # five zero-area triangles
    assert flat.triangle_count == 5 and (flat.intersect(o, d).tri == -1).all()
    one = BVH.build(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], np.float64))
    hits = one.intersect(o, d)
    np.testing.assert_array_equal(hits.tri, [0, -1])
    np.testing.assert_allclose([hits.t[0], hits.u[0], hits.v[0]], [1.0, 0.2, 0.2], rtol=1e-6)
    np.testing.assert_array_equal(one.occluded(o, d), [True, False])
    np.testing.assert_array_equal(one.occluded(o, d, t_max=0.5), [False, False])
    # No rays at all.
    assert len(one.intersect(np.zeros((0, 3)), np.zeros((0, 3)))) == 0
    assert one.occluded(np.zeros((0, 3)), np.zeros((0, 3))).shape == (0,)


def test_invalid_rays_and_limits():
    bvh = BVH.build(meshes.icosphere(2), ONE_THREAD)
    o = np.zeros((5, 3), np.float32)
    d = np.array([[0, 0, 0], [np.nan, 0, 1], [0, 0, 1], [0, 0, 1], [0, 0, 1]], np.float32)
    t_min = np.array([0, 0, 0, 2.0, 0.5], np.float32)
    t_max = np.array([9, 9, 9, 1.0, 0.5], np.float32)
    hits = bvh.intersect(o, d, t_min, t_max)
    assert list(hits.tri >= 0) == [False, False, True, False, False]
    with pytest.raises(ValueError):
        bvh.intersect(o, d, t_min=np.zeros(4))
    with pytest.raises(ValueError):
        bvh.intersect(o[:, :2], d[:, :2])


@pytest.mark.parametrize("field", [{"bins": 1}, {"leaf_size": 0}, {"width": 3}, {"chunk_size": 100},
                                   {"solo_chunk_size": 100}, {"threads": -1}])
def test_settings_out_of_range_are_refused(field):
    with pytest.raises(ValueError):
        BVHSettings(**field)


@pytest.mark.slow
def test_results_do_not_depend_on_chunks_or_threads():
    # Enough rays that every thread gets work (`bvh.THREAD_RAYS` per thread).
    tris = meshes.lumpy_sphere(3)
    rng = np.random.default_rng(4)
    o = rng.uniform(-1.2, 1.2, (70_000, 3))
    d = rng.normal(size=(70_000, 3))
    base = BVH.build(tris, BVHSettings(threads=1, chunk_size=256))
    ref = base.intersect(o, d)
    # The default pools: one thread (solo_chunk_size slots), several (chunk_size slots each).
    configs = (BVHSettings(threads=1), BVHSettings(threads=2, chunk_size=1000), BVHSettings(threads=3))
    for config in configs:
        assert_same_hits(BVH.build(tris, config).intersect(o, d), ref)
    assert_same_hits(base.intersect(o, d), ref)


@pytest.mark.slow
def test_out_buffers_and_progress():
    tris = meshes.lumpy_sphere(3)
    bvh = BVH.build(tris, BVHSettings(threads=2, chunk_size=256))
    rng = np.random.default_rng(6)
    o = rng.uniform(-1.2, 1.2, (70_000, 3))
    d = rng.normal(size=(70_000, 3))
    out = Hits(
        t=np.zeros(70_000, np.float32),
        tri=np.zeros(70_000, np.int32),
        u=np.ones(70_000, np.float32),
        v=np.ones(70_000, np.float32),
    )
    progress = list(bvh.intersect_steps(o, d, out=out))
    assert progress[-1] == 1.0 and all(0.0 <= p <= 1.0 for p in progress)
    assert_same_hits(out, bvh.intersect(o, d))
    assert bvh.intersect(o, d, out=out) is out
    blocked = np.ones(70_000, bool)
    assert bvh.occluded(o, d, out=blocked) is blocked
    np.testing.assert_array_equal(blocked, out.tri >= 0)
    # Closing the generator early stops the work without error.
    steps = bvh.occluded_steps(o, d)
    next(steps)
    steps.close()


def test_cornell_box_camera_rays_match_brute_force():
    tris = meshes.cornell_box()
    # The published camera, in Blender's frame: (x, y, z) -> (-x, z, y), mm -> m.
    eye = np.array([-0.278, -0.8, 0.273], np.float32)
    ys, xs = np.mgrid[-1:1:64j, -1:1:64j]
    tan = np.tan(np.radians(39.3077) / 2)
    d = np.stack([-xs.ravel() * tan, np.ones(xs.size), -ys.ravel() * tan], axis=1)
    o = np.tile(eye, (len(d), 1))
    ref = intersect_all(tris, o, d)
    assert (ref.tri >= 0).mean() > 0.85  # the box is open at the front
    # The box has 32 triangles: through the tree (pool, frontier) and as one brute-force leaf.
    for config in (BVHSettings(threads=1, frontier_rays=0), BVHSettings(threads=1),
                   BVHSettings(threads=1, brute_force_below=64)):
        assert_same_hits(BVH.build(tris, config).intersect(o, d), ref)
