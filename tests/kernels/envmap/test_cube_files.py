"""Cube maps in other tools' layouts (kernels/envmap/cube_files.py): OpenEXR's standard cube against
ImfEnvmap's formulas (tests/data/openexr_cubemap.json), files written and read back with OpenEXR,
Blender's lat-long mapping, the labelled cross preview and the probe's JSON record."""

import json
import math

import numpy as np
import pytest
from reference_data import reference

from classic_bake.kernels.envmap import cube_files as cf
from classic_bake.kernels.envmap.cubemap import FACE_NAMES, direction_to_face, texel_directions
from classic_bake.kernels.envmap.prefilter import level_size
from classic_bake.kernels.progress import drain

SPEC = reference("openexr_cubemap.json")
AXIS = {"x": 0, "y": 1, "z": 2}
FRAMES = {"world": cf.WORLD_AXES, "y_up": cf.OPENEXR_Y_UP}


def _spec_pixel(face: str, p: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """ImfEnvmap's CubeMap::pixelPosition: in-face positions p (K, 2) -> image (x, y) (K,) each."""
    f = SPEC["face_order"].index(face)
    lo, hi = f * n, f * n + n - 1
    out = []
    for key, low_base in (("x", 0), ("y", lo)):
        expr = SPEC["pixelPosition"][face][key]  # e.g. "max-x"
        base = (low_base if expr[:3] == "min" else (n - 1 if key == "x" else hi))
        comp = p[:, AXIS[expr[4]]]
        out.append(base + comp if expr[3] == "+" else base - comp)
    return out[0], out[1]


def _spec_direction(face: str, pos: np.ndarray) -> np.ndarray:
    """ImfEnvmap's CubeMap::direction from pos in [-1, 1]^2 (K, 2) -> (K, 3) (|major| = 1)."""
    comps = []
    for expr in SPEC["direction"][face]:
        comps.append(np.full(len(pos), float(expr)) if expr.lstrip("-").isdigit()
                     else pos[:, AXIS[expr]])
    return np.stack(comps, axis=1)


def _spec_face_and_position(d: np.ndarray, n: int) -> tuple[str, np.ndarray]:
    """ImfEnvmap's CubeMap::faceAndPixelPosition of one direction (3,)."""
    ax, ay, az = np.abs(d)
    if ax >= ay and ax >= az:
        axis, minor = 0, (1, 2)
    elif ay >= az:
        axis, minor = 1, (0, 2)
    else:
        axis, minor = 2, (0, 1)
    m = abs(d[axis])
    face = ("+" if d[axis] > 0 else "-") + "XYZ"[axis]
    return face, np.array([(d[minor[0]] / m + 1) / 2 * (n - 1), (d[minor[1]] / m + 1) / 2 * (n - 1)])


def _direction_cube(n: int) -> np.ndarray:
    """(6, n, n, 3) float32 faces whose texels hold their own unit directions (world)."""
    return texel_directions(n).astype(np.float32)


def test_face_table_matches_the_spec_formulas():
    """Every stacked texel holds the direction ImfEnvmap's `direction` gives for the in-face position
    that `pixelPosition` puts there (cell centres: pos = 2 (p + 1/2) / N - 1)."""
    n = 6
    image = cf.openexr_cube_image(_direction_cube(n))
    assert image.shape == (6 * n, n, 3)
    px, py = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    p = np.stack([px.ravel(), py.ravel()], axis=1).astype(np.float64)
    for face in SPEC["face_order"]:
        x, y = _spec_pixel(face, p, n)
        d = _spec_direction(face, 2.0 * (p + 0.5) / n - 1.0)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        np.testing.assert_allclose(image[y.astype(int), x.astype(int)], d, atol=1e-6)


def test_spec_reader_finds_each_texel_by_direction():
    """A reader using ImfEnvmap's own faceAndPixelPosition + pixelPosition (edge-to-edge pixel
    positions) and rounding lands on the texel that holds that direction (half a texel at most)."""
    n = 5
    dirs = texel_directions(n).reshape(-1, 3)
    image = cf.openexr_cube_image(_direction_cube(n))
    for d in dirs:
        face, pif = _spec_face_and_position(d, n)
        x, y = _spec_pixel(face, np.round(pif)[None], n)
        np.testing.assert_allclose(image[int(y[0]), int(x[0])], d, atol=1e-6)


def test_lecture_example_and_every_face_centre():
    """r = (1, 0, 0) is the +x face's centre (1/2, 1/2) (lecture 13), in OpenGL's table and in the
    file; every face's centre texel (odd N) looks along its axis."""
    face, s, t = direction_to_face(np.array([[1.0, 0.0, 0.0]]))
    assert (FACE_NAMES[face[0]], s[0], t[0]) == ("+X", 0.5, 0.5)
    n = 5
    image = cf.openexr_cube_image(_direction_cube(n))
    for f, name in enumerate(SPEC["face_order"]):
        axis = np.zeros(3)
        axis[AXIS[name[1].lower()]] = 1.0 if name[0] == "+" else -1.0
        np.testing.assert_allclose(image[f * n + n // 2, n // 2], axis, atol=1e-7)
        # and the spec's faceAndPixelPosition puts the axis at the face centre (N - 1) / 2
        spec_face, pif = _spec_face_and_position(axis, n)
        assert spec_face == name and np.allclose(pif, (n - 1) / 2)


@pytest.mark.parametrize("name", FACE_NAMES)
def test_every_face_corner_matches_the_drawing(name):
    """The corner texels of each stacked face point at the cube vertices of ImfEnvmap.h's drawing."""
    n = 4
    image = cf.openexr_cube_image(_direction_cube(n))
    f = SPEC["face_order"].index(name)
    corners = [image[f * n, 0], image[f * n, n - 1], image[f * n + n - 1, 0],
               image[f * n + n - 1, n - 1]]  # TL, TR, BL, BR
    for texel, vertex in zip(corners, SPEC["drawing_corners"][name], strict=True):
        expected = np.array([1 if vertex & 1 else -1, 1 if vertex & 2 else -1,
                             1 if vertex & 4 else -1])
        np.testing.assert_array_equal(np.sign(texel), expected)


@pytest.mark.parametrize("frame", FRAMES)
def test_layout_round_trip_is_lossless(frame):
    rng = np.random.default_rng(3)
    faces = rng.random((6, 7, 7, 4)).astype(np.float32)
    image = cf.openexr_cube_image(faces, FRAMES[frame])
    assert np.array_equal(np.sort(image.ravel()), np.sort(faces.ravel()))  # a permutation
    assert np.array_equal(cf.faces_from_openexr_cube(image, FRAMES[frame]), faces)


def test_world_to_file_must_keep_texels_on_texels():
    with pytest.raises(ValueError):
        cf.openexr_cube_image(np.zeros((6, 2, 2, 3)), np.eye(3) * 0.5)


@pytest.mark.parametrize("frame", FRAMES)
def test_six_coloured_walls_written_and_read_with_openexr(tmp_path, frame):
    """A room of six coloured walls: each texel coloured by the wall it sees (largest |d_i|).
    The file, read with OpenEXR itself, is N x 6N with envmap = CUBE, and face f of the stack is
    the wall along the file's f-th axis (world: M^T of it)."""
    import OpenEXR

    colours = np.array([[1, 0, 0], [0, 1, 1], [0, 1, 0], [1, 0, 1], [0, 0, 1], [1, 1, 0]],
                       np.float32)
    n = 8
    dirs = texel_directions(n).reshape(-1, 3)
    wall, _s, _t = direction_to_face(dirs)
    faces = colours[wall].reshape(6, n, n, 3)
    path = tmp_path / "room.exr"
    m = FRAMES[frame]
    cf.write_openexr_cube(path, faces, world_to_file=m)
    with OpenEXR.File(str(path), separate_channels=True) as f:
        assert f.header()["envmap"] == OpenEXR.ENVMAP_CUBE
        rgb = np.stack([f.channels()[c].pixels for c in "RGB"], axis=-1)
    assert rgb.shape == (6 * n, n, 3)
    for k, name in enumerate(SPEC["face_order"]):
        file_axis = np.zeros(3)
        file_axis[AXIS[name[1].lower()]] = 1.0 if name[0] == "+" else -1.0
        world_face = direction_to_face((m.T @ file_axis)[None])[0][0]
        assert np.all(rgb[k * n:(k + 1) * n] == colours[world_face]), name
    assert cf.read_envmap_attribute(path) == "CUBE"
    assert np.array_equal(cf.read_openexr_cube(path, world_to_file=m), faces)


def test_stored_face_order():
    assert cf.stored_face_order() == FACE_NAMES
    assert cf.stored_face_order(cf.OPENEXR_Y_UP) == ("+Y", "-Y", "+Z", "-Z", "+X", "-X")


def test_reading_a_file_without_the_cube_attribute_fails(tmp_path):
    from classic_bake.kernels.measure.exr import write_exr

    path = tmp_path / "plain.exr"
    write_exr(path, np.zeros((12, 2, 3), np.float32))
    assert cf.read_envmap_attribute(path) is None
    with pytest.raises(ValueError):
        cf.read_openexr_cube(path)


# --- lat-long ---------------------------------------------------------------------------------

def test_equirect_matches_blenders_mapping():
    """Cycles' direction_to_equirectangular: u = 1/2 - atan2(y, x) / 2 pi, v from +Z's angle."""
    cases = {(1, 0, 0): (0.5, 0.5), (0, 1, 0): (0.25, 0.5), (0, -1, 0): (0.75, 0.5),
             (-1, 0, 0): (0.0, 0.5), (0, 0, 1): (0.5, 1.0), (0, 0, -1): (0.5, 0.0)}
    for d, (u0, v0) in cases.items():
        u, v = cf.direction_to_equirect(np.array(d, float))
        assert (float(u), float(v)) == pytest.approx((u0, v0), abs=1e-12), d
    rng = np.random.default_rng(4)
    d = rng.normal(size=(1000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    u, v = cf.direction_to_equirect(d)
    np.testing.assert_allclose(u, (0.5 - np.arctan2(d[:, 1], d[:, 0]) / (2 * np.pi)) % 1.0,
                               atol=1e-12)
    np.testing.assert_allclose(v, 1.0 - np.arccos(d[:, 2]) / np.pi, atol=1e-9)
    np.testing.assert_allclose(cf.equirect_to_direction(u, v), d, atol=1e-9)


def test_equirect_is_openexr_latlong_in_y_up_axes():
    """OpenEXR's LatLongMap (longitude atan2(x, z), latitude asin(y), x fraction lon / -2 pi + 1/2,
    y fraction lat / -pi + 1/2) of OPENEXR_Y_UP d gives Blender's (u, 1 - v) of d."""
    rng = np.random.default_rng(5)
    d = rng.normal(size=(1000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    e = d @ cf.OPENEXR_Y_UP.T  # file axes
    lon, lat = np.arctan2(e[:, 0], e[:, 2]), np.arcsin(e[:, 1])
    u, v = cf.direction_to_equirect(d)
    np.testing.assert_allclose((lon / (-2 * np.pi) + 0.5) % 1.0, u, atol=1e-9)
    np.testing.assert_allclose(lat / -np.pi + 0.5, 1.0 - v, atol=1e-9)


def _smooth(d: np.ndarray) -> np.ndarray:
    """(..., 3) directions -> (..., 3) a smooth positive environment (sky, a warm lobe, tint)."""
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    lobe = np.exp(4.0 * (0.6 * x + 0.48 * y + 0.64 * z - 1.0))
    return np.stack([1.0 + 0.5 * z + 2.0 * lobe, 0.8 + 0.3 * x * y + 1.5 * lobe,
                     0.6 + 0.4 * (x * x - y * y) + 0.2 * lobe], axis=-1).astype(np.float32)


def test_equirect_round_trip():
    """Analytic environment -> cube (64) -> lat-long (128 x 256) -> cube: both against the analytic
    values at their own sample points. Bilinear resampling error, measured ~2e-4 and ~4e-4 relative
    RMS; bound 2e-3."""
    n, h = 64, 128
    cube = _smooth(texel_directions(n))
    latlong = cf.equirect_image(cube, h, supersample=1)
    assert latlong.shape == (h, 2 * h, 3) and latlong.dtype == np.float32
    expected = _smooth(cf.equirect_directions(h)[:, :, 0])
    rel = np.sqrt(np.mean(((latlong - expected) / expected) ** 2))
    assert rel < 2e-3
    back = cf.cube_from_equirect(latlong, n)
    rel_back = np.sqrt(np.mean(((back - cube) / cube) ** 2))
    assert rel_back < 2e-3
    # supersampling averages sub-pixel look-ups: a constant stays exactly constant
    const = cf.equirect_image(np.full((6, 8, 8, 1), 0.25, np.float32), 16, supersample=3)
    assert np.all(const == np.float32(0.25))


def test_equirect_with_bordered_faces():
    """Bordered faces (one texel past each edge, as envmap.py renders them) give the same image
    away from seams and blend across them."""
    n, h = 32, 32
    from classic_bake.kernels.envmap.envmap import bordered_directions

    bordered = _smooth(bordered_directions(n, 1))
    plain = _smooth(texel_directions(n))
    a = cf.equirect_image(bordered, h, supersample=1, border=1)
    b = cf.equirect_image(plain, h, supersample=1)
    expected = _smooth(cf.equirect_directions(h)[:, :, 0])
    err_a = np.abs(a - expected).max()
    err_b = np.abs(b - expected).max()
    assert err_a <= err_b + 1e-6


def test_equirect_in_row_blocks_with_progress(monkeypatch):
    """Rows resampled in blocks give the same image as one block; progress rises to 1."""
    cube = _smooth(texel_directions(16))
    whole = cf.equirect_image(cube, 24, supersample=2)
    monkeypatch.setattr(cf, "EQUIRECT_BLOCK", 2 * 48 * 4)  # two rows of 48 pixels x 4 samples
    steps = cf.equirect_steps(cube, 24, supersample=2)
    seen = []
    blocks = drain(steps, seen.append)
    assert len(seen) == 12 and seen == sorted(seen) and seen[-1] == 1.0
    assert np.array_equal(blocks, whole)


def test_latlong_file_carries_the_attribute(tmp_path):
    path = tmp_path / "latlong.exr"
    image = np.ones((4, 8, 3), np.float32)
    cf.write_equirect_exr(path, image)
    assert cf.read_envmap_attribute(path) == "LATLONG"


# --- cross preview ----------------------------------------------------------------------------

def test_tone_map_values():
    s = cf.PreviewSettings()
    assert cf.tone_map_rgb8(np.array([0.0, 1.0, 1e9, -1.0, np.nan]), s).tolist() == \
        [0, 188, 255, 0, 0]  # reinhard 1 -> 0.5 -> sRGB 0.7354 -> 188
    clamp = cf.PreviewSettings(tone="clamp", exposure=1.0)
    assert cf.tone_map_rgb8(np.array([0.25, 0.5, 2.0]), clamp).tolist() == [188, 255, 255]
    with pytest.raises(ValueError):
        cf.PreviewSettings(tone="filmic")


def test_cross_layout_colours_seams_and_labels():
    n = 64
    colours = np.array([[1, 0, 0], [0, 1, 1], [0, 1, 0], [1, 0, 1], [0, 0, 1], [1, 1, 0]],
                       np.float32)
    faces = np.broadcast_to(colours[:, None, None, :], (6, n, n, 3))
    image = cf.cross_preview(faces)
    assert image.shape == (3 * n, 4 * n, 3) and image.dtype == np.uint8
    expected = cf.tone_map_rgb8(colours)
    for f, (row, col, *_axes) in enumerate(cf.CROSS_CELLS):
        cell = image[row * n:(row + 1) * n, col * n:(col + 1) * n]
        assert np.all(cell[n // 2:, :] == expected[f])             # below the label: the colour
        label = cf.label_mask(FACE_NAMES[f], 1)                     # scale 1 at n = 64
        drawn = cell[2:2 + label.shape[0], 2:2 + label.shape[1]]
        assert np.all(drawn[label] == 255)                          # glyph pixels white
        lit_top = np.flatnonzero(label[0])
        assert np.all(cell[1, 2 + lit_top] == 0)                    # a black outline above them
        assert np.all(cell[2 + label.shape[0] + 3:, :] == expected[f])
    empty = [(0, 0), (0, 2), (0, 3), (2, 0), (2, 2), (2, 3)]
    for row, col in empty:
        assert np.all(image[row * n:(row + 1) * n, col * n:(col + 1) * n] == cf.CROSS_BACKGROUND)
    # the labels differ: "+X" and "-X" masks are not the same picture
    assert not np.array_equal(cf.label_mask("+X"), cf.label_mask("-X"))


def test_cross_faces_meet_along_their_edges():
    """An environment that varies smoothly: texels on either side of each inner seam of the cross
    differ by about one texel's change, not by a face's."""
    n = 32
    faces = _smooth(texel_directions(n))
    image = cf.cross_preview(faces, cf.PreviewSettings(labels=False, tone="clamp",
                                                       exposure=-2.0)).astype(int)
    seams = [image[n:2 * n, n - 1] - image[n:2 * n, n],            # +Y | +X
             image[n:2 * n, 2 * n - 1] - image[n:2 * n, 2 * n],    # +X | -Y
             image[n:2 * n, 3 * n - 1] - image[n:2 * n, 3 * n],    # -Y | -X
             image[n - 1, n:2 * n] - image[n, n:2 * n],            # +Z over +X
             image[2 * n - 1, n:2 * n] - image[2 * n, n:2 * n]]    # +X over -Z
    inner = np.abs(image[n:2 * n, n + 10] - image[n:2 * n, n + 11]).max()
    for seam in seams:
        assert np.abs(seam).max() <= max(3, 2 * inner)


# --- the probe's record -----------------------------------------------------------------------

def test_probe_json():
    sh = np.arange(27, dtype=float).reshape(9, 3)
    record = cf.probe_json((1.0, 2.0, 3.0), (-1, -1, 0), (4, 4, 3), 64, FACE_NAMES, 6, sh)
    text = json.dumps(record)
    back = json.loads(text)
    assert back["position"] == [1.0, 2.0, 3.0]
    assert back["box"] == {"min": [-1.0, -1.0, 0.0], "max": [4.0, 4.0, 3.0]}
    assert back["face_order"] == list(FACE_NAMES)
    assert [m["roughness"] for m in back["mip_levels"]] == [0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
    assert [m["face_size"] for m in back["mip_levels"]] == [level_size(64, k) for k in range(6)]
    assert back["sh"]["coefficients"][8] == [24.0, 25.0, 26.0]
    assert cf.probe_json((0, 0, 0), None, None, 16)["box"] is None
    with pytest.raises(ValueError):
        cf.probe_json((0, 0, 0), None, None, 16, ("+X",) * 6)
    assert math.isclose(back["mip_levels"][1]["roughness"], 0.2)
