"""Cube-map convention: the OpenGL table of tests/data/cubemap_gl.json, its inverse, the
per-face cameras (checked by rendering faces with kernels/raster.py) and the bilinear lookup."""

import re

import numpy as np
import pytest
from reference_data import reference

from classic_bake.kernels.envmap import cubemap
from classic_bake.kernels.geometry.raster import rasterize

REFERENCE = reference("cubemap_gl.json")
AXIS = {"x": 0, "y": 1, "z": 2}


def _parse_direction(key: str) -> np.ndarray:
    """'+X' -> (1, 0, 0); '(0.3,-1,0.6)' -> (0.3, -1, 0.6); '(1,1,1)/tie->X' -> (1, 1, 1)."""
    if key[0] in "+-" and len(key) == 2:
        d = np.zeros(3)
        d[AXIS[key[1].lower()]] = 1.0 if key[0] == "+" else -1.0
        return d
    return np.array([float(v) for v in re.match(r"\(([^)]*)\)", key).group(1).split(",")])


@pytest.mark.parametrize("key", list(REFERENCE["examples"]))
def test_reference_examples(key):
    expected = REFERENCE["examples"][key]
    face, s, t = cubemap.direction_to_face(_parse_direction(key)[None])
    assert cubemap.FACE_NAMES[face[0]] == expected["face"]
    assert s[0] == pytest.approx(expected["s"], abs=1e-12)
    assert t[0] == pytest.approx(expected["t"], abs=1e-12)


def test_table_formula_on_random_directions():
    """sc, tc and ma read from the JSON table text, then s and t from its formula."""
    rng = np.random.default_rng(1)
    r = rng.normal(size=(5000, 3))
    face, s, t = cubemap.direction_to_face(r)
    for f, name in enumerate(cubemap.FACE_NAMES):
        sel = face == f
        assert sel.any()
        terms = dict(re.findall(r"(sc|tc|ma)=([+-]?r[xyz])", REFERENCE["table"][name]))
        def comp(expr, rows=r[sel]):
            sign = -1.0 if expr.startswith("-") else 1.0
            return sign * rows[:, AXIS[expr[-1]]]
        ma = np.abs(comp(terms["ma"]))
        # the face's major axis is the largest magnitude, with the face's sign
        assert np.all(ma >= np.abs(r[sel]).max(axis=1))
        assert np.all(np.sign(r[sel, AXIS[terms["ma"][-1]]]) == (1 if name[0] == "+" else -1))
        np.testing.assert_allclose(s[sel], (comp(terms["sc"]) / ma + 1) / 2, atol=1e-15)
        np.testing.assert_allclose(t[sel], (comp(terms["tc"]) / ma + 1) / 2, atol=1e-15)


def test_round_trips():
    rng = np.random.default_rng(2)
    d = rng.normal(size=(100_000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    face, s, t = cubemap.direction_to_face(d * rng.uniform(0.1, 10.0, (len(d), 1)))
    assert np.all((s >= 0) & (s <= 1) & (t >= 0) & (t <= 1))
    back = cubemap.face_to_direction(face, s, t)
    assert np.abs(back - d).max() < 1e-6  # the brief's tolerance; measured ~1e-15
    # and (face, s, t) -> direction -> (face, s, t), away from the face edges (ties)
    f0 = rng.integers(0, 6, 10_000)
    s0, t0 = rng.uniform(0.001, 0.999, (2, 10_000))
    f1, s1, t1 = cubemap.direction_to_face(cubemap.face_to_direction(f0, s0, t0))
    np.testing.assert_array_equal(f1, f0)
    assert max(np.abs(s1 - s0).max(), np.abs(t1 - t0).max()) < 1e-12


def test_zero_direction_is_defined():
    face, s, t = cubemap.direction_to_face(np.zeros((1, 3)))
    assert (face[0], s[0], t[0]) == (0, 0.5, 0.5)


@pytest.mark.parametrize("f", range(6))
def test_face_camera_matches_reference(f):
    check = REFERENCE["render_to_face_lookAt_check"][cubemap.FACE_NAMES[f]]
    forward, up, right = cubemap.face_camera(f)
    np.testing.assert_array_equal(forward, check["lookAt_forward"])
    np.testing.assert_array_equal(up, check["up"])
    np.testing.assert_array_equal(right + 0.0, np.array(check["screen_right"]) + 0.0)
    np.testing.assert_array_equal(np.cross(forward, up), right)  # a right-handed camera
    # s grows to the screen's right and t upwards, as the reference states
    probes = (forward, forward + 0.1 * right, forward + 0.1 * up)
    (_, s0, t0), (_, s_r, _), (_, _, t_u) = (cubemap.direction_to_face(v[None]) for v in probes)
    assert check["s_increases_with_screen_right"] and s_r[0] > s0[0]
    assert check["t_increases_with_screen_up"] and t_u[0] > t0[0]


def _box(lo, hi):
    """(12, 3, 3) triangles of an axis-aligned box."""
    c = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                  for z in (lo[2], hi[2])])
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = [[c[a], c[b], c[cc]] for a, b, cc, _ in quads]
    tris += [[c[a], c[cc], c[d]] for a, _, cc, d in quads]
    return np.array(tris, np.float32)


def test_rendered_faces_match_the_lookup():
    """Render the inside of a rotated, off-centre box on every face; texel (i, j) must see, at
    depth |ma|, the wall hit along texel_directions[f, i, j]: the image orientation matches (s, t).
    The box is rotated so that every face sees several walls (a flipped image would not match)."""
    size = 48
    angle, axis = 0.6, np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k  # Rodrigues, local -> world
    lo, hi = np.array([-1.0, -1.5, -0.7]), np.array([1.3, 0.9, 1.6])
    tris = (_box(lo, hi).astype(np.float64) @ rot.T).astype(np.float32)
    eye = rot @ np.array([0.3, -0.2, 0.1])
    dirs = cubemap.texel_directions(size)  # (6, S, S, 3) world
    local_dirs, local_eye = dirs @ rot, rot.T @ eye
    with np.errstate(divide="ignore"):  # exit distance from inside the box: nearest slab wall
        t_hit = np.where(local_dirs > 0, (hi - local_eye) / local_dirs,
                         (lo - local_eye) / local_dirs).min(axis=-1)
    for f in range(6):
        depth = rasterize(tris, cubemap.face_projection(f, eye, 0.01, 10.0), size, size).depth
        expected = np.abs((t_hit[f, ..., None] * dirs[f])[..., cubemap._AXIS[f]])
        assert np.abs(expected - expected[::-1]).max() > 0.05  # the check can see a flip
        assert np.abs(expected - expected[:, ::-1]).max() > 0.05
        np.testing.assert_allclose(depth, expected, rtol=1e-5)


def test_texel_directions_match_the_lookup():
    size = 8
    dirs = cubemap.texel_directions(size).reshape(-1, 3)
    face, s, t = cubemap.direction_to_face(dirs)
    jj, ii = np.meshgrid(np.arange(size), np.arange(size))
    np.testing.assert_array_equal(face, np.repeat(np.arange(6), size * size))
    np.testing.assert_allclose(s, np.tile((jj.ravel() + 0.5) / size, 6), atol=1e-12)
    np.testing.assert_allclose(t, np.tile(1 - (ii.ravel() + 0.5) / size, 6), atol=1e-12)


def test_bilinear_lookup():
    """A face holding an affine function of (s, t) is reproduced exactly between texel centres;
    beyond the outermost centres the lookup clamps within the face (the stated seam rule)."""
    size = 16
    jj, ii = np.meshgrid(np.arange(size), np.arange(size))
    s_c, t_c = (jj + 0.5) / size, 1 - (ii + 0.5) / size
    cube = np.stack([np.stack([s_c + 2 * t_c + 10 * f, np.full_like(s_c, f)], -1)
                     for f in range(6)])
    cube = cube.astype(np.float32)
    rng = np.random.default_rng(3)
    f = rng.integers(0, 6, 2000)
    s, t = rng.uniform(0.5 / size, 1 - 0.5 / size, (2, 2000))
    value = cubemap.sample_cubemap(cube, cubemap.face_to_direction(f, s, t))
    assert value.dtype == np.float32 and value.shape == (2000, 2)
    np.testing.assert_allclose(value[:, 0], s + 2 * t + 10 * f, atol=2e-5)
    np.testing.assert_array_equal(value[:, 1], f)
    # clamped: within half a texel of an edge the edge texel's value holds
    near_edges = cubemap.face_to_direction([2, 2], [0.01, 0.2], [0.5, 0.999])
    edge = cubemap.sample_cubemap(cube, near_edges)
    first, last = 0.5 / size, 1 - 0.5 / size  # outermost texel centres
    np.testing.assert_allclose(edge[:, 0], [first + 2 * 0.5 + 20, 0.2 + 2 * last + 20], atol=2e-5)
    out = np.empty((2000, 2), np.float32)
    assert cubemap.sample_cubemap(cube, cubemap.face_to_direction(f, s, t), out=out) is out
