"""MikkTSpace and the lecture's tangent frames per face corner (kernels/normalmap/mikktspace.py,
lecture_frame.py) on meshes made here in NumPy; tests/blender/test_normalmap_tangents.py holds
them against Blender's own `calc_tangents`."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from classic_bake.kernels.normalmap.lecture_frame import frame_angles, lecture_frames
from classic_bake.kernels.normalmap.mikktspace import (
    _triangulate,
    bitangents,
    fast_acos,
    mikktspace_steps,
    mikktspace_tangents,
)


def grid(n=4, mirror=False):
    """An n x n quad grid over [-1, 1]^2 in z = 0 facing +z; UVs (x, y) / 2 + 1/2, or u mirrored
    about x = 0 (u = |x|). Returns the mesh's arrays as the bridge hands them over."""
    xs = np.linspace(-1.0, 1.0, n + 1)
    positions = np.array([(x, y, 0.0) for y in xs for x in xs])
    faces = [(j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i)
             for j in range(n) for i in range(n)]
    corner_verts = np.array(faces).ravel()
    p = positions[corner_verts]
    uv = np.stack([np.abs(p[:, 0]) if mirror else p[:, 0] / 2 + 0.5, p[:, 1] / 2 + 0.5], 1)
    normals = np.tile([0.0, 0.0, 1.0], (len(corner_verts), 1))
    starts = np.arange(0, len(corner_verts), 4)
    return positions, corner_verts, normals, uv, starts, np.full(len(faces), 4)


def uv_sphere(segments=8, rings=4):
    """Blender's UV sphere layout: pole triangle fans and quads, smooth normals, the u seam
    duplicated in UV, pole corners at the middle of their face's u range."""
    positions = [(0.0, 0.0, 1.0)]
    for r in range(1, rings):
        theta = np.pi * r / rings
        for k in range(segments):
            phi = 2 * np.pi * k / segments
            positions.append((np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)))
    positions.append((0.0, 0.0, -1.0))
    positions = np.array(positions)
    south = len(positions) - 1

    def ring_vertex(r, k):
        return 1 + (r - 1) * segments + k % segments

    corner_verts, uvs, sizes = [], [], []
    for k in range(segments):
        u0, u1 = k / segments, (k + 1) / segments
        # north fan
        corner_verts += [0, ring_vertex(1, k), ring_vertex(1, k + 1)]
        uvs += [((u0 + u1) / 2, 1.0), (u0, 1 - 1 / rings), (u1, 1 - 1 / rings)]
        sizes.append(3)
        for r in range(1, rings - 1):
            v0, v1 = 1 - r / rings, 1 - (r + 1) / rings
            corner_verts += [ring_vertex(r, k), ring_vertex(r + 1, k), ring_vertex(r + 1, k + 1),
                             ring_vertex(r, k + 1)]
            uvs += [(u0, v0), (u0, v1), (u1, v1), (u1, v0)]
            sizes.append(4)
        corner_verts += [south, ring_vertex(rings - 1, k + 1), ring_vertex(rings - 1, k)]
        uvs += [((u0 + u1) / 2, 0.0), (u1, 1 / rings), (u0, 1 / rings)]
        sizes.append(3)
    corner_verts = np.array(corner_verts)
    sizes = np.array(sizes)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    normals = positions[corner_verts]
    return positions, corner_verts, normals, np.array(uvs), starts, sizes


def assert_unit_and_perpendicular(frames, normals, atol=1e-5):
    assert np.all(np.isfinite(frames.tangents)) and np.all(np.abs(frames.signs) == 1.0)
    np.testing.assert_allclose(np.linalg.norm(frames.tangents, axis=1), 1.0, atol=atol)
    assert np.abs(np.einsum("ij,ij->i", frames.tangents, normals)).max() < atol


def test_plane_with_uv_along_xy_has_the_x_axis_as_tangent():
    mesh = grid()
    frames = mikktspace_tangents(*mesh)
    np.testing.assert_allclose(frames.tangents, np.tile([1.0, 0.0, 0.0], (len(mesh[1]), 1)), atol=1e-6)
    assert np.all(frames.signs == 1.0)
    np.testing.assert_allclose(bitangents(mesh[2], frames), np.tile([0.0, 1.0, 0.0], (len(mesh[1]), 1)),
                               atol=1e-6)
    assert frames.unassigned_corners == frames.degenerate_triangles == frames.groupless_triangles == 0


def test_mirrored_uvs_flip_the_sign_and_split_at_the_mirror_line():
    positions, corner_verts, normals, uv, starts, sizes = grid(mirror=True)
    frames = mikktspace_tangents(positions, corner_verts, normals, uv, starts, sizes)
    face_x = positions[corner_verts].reshape(-1, 4, 3)[:, :, 0].mean(axis=1)
    left = np.repeat(face_x < 0, 4)  # corners of faces where u = -x
    # u grows towards -x there: the tangent (dp/du) points along -x and the UV winding flips.
    np.testing.assert_allclose(frames.tangents[left], np.tile([-1.0, 0.0, 0.0], (left.sum(), 1)), atol=1e-6)
    np.testing.assert_allclose(frames.tangents[~left], np.tile([1.0, 0.0, 0.0], ((~left).sum(), 1)),
                               atol=1e-6)
    assert np.all(frames.signs[left] == -1.0) and np.all(frames.signs[~left] == 1.0)
    # b = sign (n x t) runs along +v on both sides.
    assert np.allclose(bitangents(normals, frames), [0.0, 1.0, 0.0], atol=1e-6)


def test_sphere_frames_are_unit_perpendicular_and_shared_at_welded_vertices():
    mesh = uv_sphere(12, 6)
    positions, corner_verts, normals, uv = mesh[:4]
    frames = mikktspace_tangents(*mesh)
    assert_unit_and_perpendicular(frames, normals)
    assert frames.unassigned_corners == 0 and frames.degenerate_triangles == 0
    # Corners of one vertex with one UV (off the seam and the poles) share one frame.
    key = np.concatenate([corner_verts[:, None].astype(float), uv], 1)
    _, group = np.unique(key, axis=0, return_inverse=True)
    for g in np.unique(group):
        members = np.nonzero(group == g)[0]
        assert np.abs(frames.tangents[members] - frames.tangents[members[0]]).max() < 1e-6
    # Away from the pole fans and the seam the tangent runs along the parallels: the two faces'
    # horizontal chords, projected into the normal's plane, tilt by opposite amounts. (Next to a
    # fan its apex at mid-u tilts it; on the seam only one side's chord counts.)
    mid = (np.abs(positions[corner_verts][:, 2]) < 0.8) & (uv[:, 0] > 0) & (uv[:, 0] < 1)
    assert np.abs(frames.tangents[mid, 2]).max() < 1e-5
    assert np.all(frames.signs == 1.0)


@settings(max_examples=25, deadline=None)
@given(axis=st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.1, 1)),
       angle=st.floats(-np.pi, np.pi))
def test_frames_turn_with_the_mesh(axis, angle):
    mesh = uv_sphere(8, 4)
    k = np.array(axis) / np.linalg.norm(axis)
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    rot = np.eye(3) + np.sin(angle) * kx + (1 - np.cos(angle)) * kx @ kx  # Rodrigues
    base = mikktspace_tangents(*mesh)
    turned = mikktspace_tangents(mesh[0] @ rot.T, mesh[1], mesh[2] @ rot.T, *mesh[3:])
    # float32 arithmetic throughout, as Blender's: 1e-5.
    np.testing.assert_allclose(turned.tangents, base.tangents @ rot.T, atol=1e-5)
    assert np.array_equal(turned.signs, base.signs)


def test_zero_area_uvs_and_collapsed_triangles_stay_finite_and_are_counted():
    positions, corner_verts, normals, uv, starts, sizes = uv_sphere(10, 5)
    uv = uv.copy()
    for f in range(0, len(sizes), 3):  # every third face: all its corners at one UV
        uv[starts[f]:starts[f] + sizes[f]] = uv[starts[f]]
    frames = mikktspace_tangents(positions, corner_verts, normals, uv, starts, sizes)
    assert frames.groupless_triangles > 0 and frames.unassigned_corners > 0
    assert np.all(np.isfinite(frames.tangents))
    np.testing.assert_allclose(np.linalg.norm(frames.tangents, axis=1), 1.0, atol=1e-5)
    # A triangle with two corners at one point: counted, and its corners take a good
    # triangle's frame at the same vertex.
    positions, corner_verts, normals, uv, starts, sizes = grid(3)
    positions = positions.copy()
    positions[5] = positions[6]  # vertex 5 moved onto vertex 6: quads around them collapse
    frames = mikktspace_tangents(positions, corner_verts, normals, uv, starts, sizes)
    assert frames.degenerate_triangles > 0
    assert np.all(np.isfinite(frames.tangents)) and np.all(np.abs(frames.signs) == 1)


def test_triangles_without_faces_ngons_and_progress():
    positions, corner_verts, normals, uv, starts, sizes = grid(2)
    tri = np.array([[0, 1, 2], [0, 2, 3]])
    tri_corners = (starts[:, None, None] + tri[None]).reshape(-1)
    frames = mikktspace_tangents(positions, corner_verts[tri_corners], normals[tri_corners],
                                 uv[tri_corners])
    np.testing.assert_allclose(frames.tangents, np.tile([1.0, 0.0, 0.0], (len(tri_corners), 1)),
                               atol=1e-6)
    with pytest.raises(ValueError):
        mikktspace_tangents(positions, np.arange(5), np.tile([0, 0, 1.0], (5, 1)), np.zeros((5, 2)),
                            np.array([0]), np.array([5]))
    steps = mikktspace_steps(positions, corner_verts, normals, uv, starts, sizes)
    seen = [p for p in steps]
    assert seen == sorted(seen) and seen[-1] == 1.0


def test_quads_split_along_the_shorter_uv_diagonal():
    pos = np.zeros((8, 3), np.float32)
    pos[:4] = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    pos[4:] = pos[:4]
    uv = np.array([(0, 0), (1, 0), (1, 1), (0, 1),  # square: a tie in UV, a tie in 3D -> 0-2
                   (0, 0), (2, 0), (1, 1), (0, 1)], np.float32)  # |uv2 - uv0| < |uv3 - uv1|
    uv[4:] = [(0, 0), (3, 0), (3, 1), (0.5, 1)]  # d02^2 = 10, d13^2 = 7.25: 1-3
    face, fv = _triangulate(pos, uv, np.array([0, 4]), np.array([4, 4]))
    assert face.tolist() == [0, 0, 1, 1]
    assert fv.tolist() == [[0, 1, 2], [0, 2, 3], [0, 1, 3], [1, 2, 3]]


def test_fast_acos_is_cycles_approximation():
    x = np.linspace(-1, 1, 20001, dtype=np.float32)
    # Cycles states 4.5e-5 rad at most.
    assert np.abs(fast_acos(x) - np.arccos(x.astype(np.float64))).max() < 4.6e-5


def test_lecture_frame_equals_mikktspace_on_a_plane_and_differs_on_a_coarse_sphere():
    mesh = grid(4, mirror=True)
    mikk = mikktspace_tangents(*mesh)
    lecture = lecture_frames(*mesh)
    assert np.array_equal(lecture.signs, mikk.signs)
    angle = frame_angles(mesh[2], mikk.tangents, mikk.signs, lecture.tangents, lecture.signs)
    assert angle.max() < 1e-3
    sphere = uv_sphere(6, 4)
    mikk = mikktspace_tangents(*sphere)
    lecture = lecture_frames(*sphere)
    assert_unit_and_perpendicular(lecture, sphere[2])
    angle = frame_angles(sphere[2], mikk.tangents, mikk.signs, lecture.tangents, lecture.signs)
    assert np.all(np.isfinite(angle)) and angle.max() > 1.0 and angle.max() < 90.0
    # The same frame: 0 degrees; the opposite handedness: 180.
    same = frame_angles(sphere[2], mikk.tangents, mikk.signs, mikk.tangents, mikk.signs)
    flipped = frame_angles(sphere[2], mikk.tangents, mikk.signs, mikk.tangents, -mikk.signs)
    assert same.max() < 1e-3 and np.allclose(flipped, 180.0)


def test_lecture_frame_counts_zero_area_uv_corners():
    positions, corner_verts, normals, uv, starts, sizes = grid(2)
    uv = uv.copy()
    uv[:4] = uv[0]
    lecture = lecture_frames(positions, corner_verts, normals, uv, starts, sizes)
    assert lecture.degenerate_frames == 4
    assert_unit_and_perpendicular(lecture, normals)


def test_vectorised_groups_equal_mikktspaces_flood_fill():
    from classic_bake.kernels.normalmap import mikktspace as mk

    positions, corner_verts, normals, uv, starts, sizes = uv_sphere(10, 6)
    uv = np.random.default_rng(5).random(uv.shape)  # random windings: many groups per vertex
    uv[::7] = uv[1::7][: len(uv[::7])]  # and some shared UVs
    pos = positions[corner_verts].astype(np.float32)
    keys = np.concatenate([pos.view(np.uint32), normals.astype(np.float32).view(np.uint32),
                           uv.astype(np.float32).view(np.uint32)], axis=1)
    weld = mk._weld(keys)
    face, fv = mk._triangulate(pos, uv.astype(np.float32), starts, sizes)
    verts = weld[starts[face][:, None] + fv]
    neighbour = mk._neighbours(verts)
    orient = np.random.default_rng(6).random(len(verts)) < 0.5
    flood, flood_orient = mk._groups(verts, neighbour, orient.copy(), np.zeros(len(verts), bool))
    fast, fast_orient = mk._groups_connected(verts, neighbour, orient)
    # The same partition of corners (group ids may differ), and the same orientation per group.
    pairs = np.unique(np.stack([flood.ravel(), fast.ravel()], 1), axis=0)
    assert len(pairs) == len(np.unique(flood)) == len(np.unique(fast))
    assert np.array_equal(flood_orient[pairs[:, 0]], fast_orient[pairs[:, 1]])


def test_tangent_space_normals_go_to_object_space_as_the_normal_map_node_reads_them():
    from classic_bake.kernels.normalmap.mikktspace import tangent_to_object

    mesh = grid(4, mirror=True)
    frames = mikktspace_tangents(*mesh)
    count = len(mesh[1])
    # flat -> the corner normal; +x -> the tangent; +y -> along +v (world +y) on both sides.
    flat = tangent_to_object(np.tile([0.0, 0.0, 1.0], (count, 1)), mesh[2], frames.tangents, frames.signs)
    along_y = tangent_to_object(np.tile([0.0, 1.0, 0.0], (count, 1)), mesh[2], frames.tangents,
                                frames.signs)
    np.testing.assert_allclose(flat, mesh[2], atol=1e-12)
    np.testing.assert_allclose(along_y, np.tile([0.0, 1.0, 0.0], (count, 1)), atol=1e-6)
