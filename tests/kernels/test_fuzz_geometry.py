"""Fuzzing the geometry kernels (issue 43): the BVH's intersect, occluded and shaft tests, the
rasteriser and camera rays on random meshes (duplicated, degenerate and non-finite triangles) and
rays (zero-length and axis-parallel directions): no crash, finite answers, misses where the
documents say so, and only ValueErrors with a message."""

from __future__ import annotations

import numpy as np
import pytest
from fuzz_inputs import all_finite, cameras, documented_error, fuzz, meshes, rays
from hypothesis import given
from hypothesis import strategies as st

from classic_bake.kernels.geometry.bvh import BVH, BVHSettings
from classic_bake.kernels.geometry.camera import camera_rays
from classic_bake.kernels.geometry.intersect import intersect_all, occluded_all
from classic_bake.kernels.geometry.raster import Projection, look_at, rasterize_steps
from classic_bake.kernels.geometry.scene import geometric_normals, triangle_areas
from classic_bake.kernels.progress import drain

ONE_THREAD = BVHSettings(threads=1, brute_force_below=0)
# Non-finite corners the snapshot could meet (the bridge refuses them, the kernels must not hang).
POISON = st.sampled_from([np.nan, np.inf, -np.inf])

# A NumPy RuntimeWarning (a division by zero, nan met) is where a nan would come from: fail on it.
pytestmark = pytest.mark.filterwarnings("error")


@fuzz
@given(tris=meshes(), ray=rays(), poison=st.one_of(st.none(), POISON),
       t_max=st.sampled_from([np.inf, 2.0, 0.0]), frontier_rays=st.sampled_from([0, 4096]))
def test_bvh_intersect_and_occluded_answer_finitely(tris, ray, poison, t_max, frontier_rays):
    """On the pool (frontier_rays 0) and the breadth-first frontier alike."""
    if poison is not None and len(tris):
        tris = tris.copy()
        tris[0, 0, 0] = poison  # left out of the tree: never hit
    origins, dirs = ray
    bvh = BVH.build(tris, BVHSettings(threads=1, brute_force_below=0, frontier_rays=frontier_rays))
    hits = bvh.intersect(origins, dirs, 0.0, t_max)
    seen = hits.tri >= 0
    assert all_finite(hits.t[seen], hits.u[seen], hits.v[seen])
    assert np.all(hits.t[~seen] == np.inf)
    assert np.all((hits.t[seen] >= 0.0) & (hits.t[seen] <= t_max))
    assert np.all((hits.u[seen] >= 0) & (hits.v[seen] >= 0) & (hits.u[seen] + hits.v[seen] <= 1 + 1e-6))
    zero = ~np.any(dirs != 0.0, axis=1)
    assert not seen[zero].any(), "a zero-length ray hit something"
    if poison is not None and len(tris):
        assert not (hits.tri == 0).any(), "a triangle with a non-finite corner was hit"
    blocked = bvh.occluded(origins, dirs, 0.0, t_max)
    np.testing.assert_array_equal(blocked, seen)
    brute = intersect_all(tris, origins, dirs, 0.0, t_max)
    np.testing.assert_array_equal(brute.tri, hits.tri)
    np.testing.assert_array_equal(occluded_all(tris, origins, dirs, 0.0, t_max), seen)


@fuzz
@given(tris=meshes(), ray=rays(), poison=POISON)
def test_rays_with_non_finite_origins_or_directions_miss(tris, ray, poison):
    origins, dirs = ray
    origins, dirs = origins.copy(), dirs.copy()
    origins[0, 1] = poison
    dirs[-1, 2] = poison
    hits = BVH.build(tris, ONE_THREAD).intersect(origins, dirs)
    assert hits.tri[0] == -1 and hits.tri[-1] == -1


@fuzz
@given(tris=meshes(max_triangles=12), slack=st.floats(0.0, 0.1))
def test_convex_clear_answers_for_random_boxes(tris, slack):
    bvh = BVH.build(tris, ONE_THREAD)
    # Two axis boxes as half-spaces: [-1, 1]^3 and [2, 3]^3.
    normals = np.tile(np.concatenate([np.eye(3), -np.eye(3)])[None], (2, 1, 1))
    offsets = np.array([[1, 1, 1, 1, 1, 1], [3, 3, 3, -2, -2, -2]], float)
    corners = np.array([[[x, y, z] for x in a for y in a for z in a] for a in ([-1, 1], [2, 3])],
                       float)
    clear = bvh.convex_clear(normals, offsets, corners, slack)
    assert clear.shape == (2,) and clear.dtype == bool


@fuzz
@given(tris=meshes())
def test_areas_and_normals_are_finite(tris):
    assert all_finite(triangle_areas(tris), geometric_normals(tris))


@fuzz
@given(tris=meshes(), eye=st.tuples(*[st.floats(-3, 3)] * 3), persp=st.booleans(),
       size=st.tuples(st.integers(1, 9), st.integers(1, 9)), cull=st.sampled_from(
           ["NONE", "BACK", "FRONT"]))
def test_rasteriser_depths_are_inside_the_frustum(tris, eye, persp, size, cull):
    eye = np.array(eye) + np.array([0.0, -5.0, 0.5])
    view = look_at(eye, np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    near, far = (0.1, 20.0) if persp else (0.0, 20.0)
    extent = (-1.0, 1.0, -0.8, 0.8) if persp else (-3.0, 3.0, -2.0, 2.0)
    projection = Projection("PERSP" if persp else "ORTHO", view, extent, near, far)
    depth = np.empty(size[::-1], np.float32)
    ids = np.empty(size[::-1], np.int64)
    drain(rasterize_steps(tris, projection, depth, ids, cull))
    drawn = ids >= 0
    assert np.all(np.isinf(depth[~drawn]))
    assert np.all((depth[drawn] >= near - 1e-4) & (depth[drawn] <= far + 1e-3))
    assert np.all(ids[drawn] < len(tris))


@fuzz
@given(near=st.floats(-1, 1), far=st.floats(-1, 1), width=st.floats(-1, 1))
def test_empty_projections_are_refused_with_a_message(near, far, width):
    view = np.eye(4)
    with documented_error():
        Projection("ORTHO", view, (0.0, width, 0.0, 1.0), near, far)


@fuzz
@given(camera=cameras(), size=st.tuples(st.integers(1, 7), st.integers(1, 7)))
def test_camera_rays_are_finite_and_unit(camera, size):
    origins, dirs = camera_rays(camera, *size)
    assert origins.shape == dirs.shape == (size[1], size[0], 3)
    assert all_finite(origins, dirs)
    np.testing.assert_allclose(np.linalg.norm(dirs, axis=-1), 1.0, atol=1e-6)
