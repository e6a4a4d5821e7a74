"""Texture lookups (kernels/textures.py): bilinear weights, wrap modes and the checkerboard, with
exact expected values worked out by hand."""

import numpy as np
import pytest

from classic_bake.kernels.geometry.scene import Texture
from classic_bake.kernels.shading import textures
from classic_bake.kernels.shading.textures import (
    checker,
    checker_box,
    sample_image,
    sample_texture,
    sample_texture_box,
    sample_tiles,
    srgb_to_linear,
)


def ramp(w=4, h=2):
    """Texel value = column index in R, row-from-bottom in G (row 0 of the array is the top)."""
    img = np.zeros((h, w, 4), np.float32)
    img[..., 0] = np.arange(w)[None, :]
    img[..., 1] = (h - 1 - np.arange(h))[:, None]
    img[..., 3] = 1
    return img


def test_texel_centres_return_the_texel():
    img = ramp()
    u = (np.arange(4) + 0.5) / 4
    v = np.full(4, 0.25)  # centre of the bottom row
    out = sample_image(img, np.stack([u, v], 1))
    np.testing.assert_allclose(out[:, 0], [0, 1, 2, 3])
    np.testing.assert_allclose(out[:, 1], 0)


def test_bilinear_is_linear_between_centres():
    img = ramp()
    out = sample_image(img, np.array([[0.5, 0.5], [0.3125, 0.5]]), extension="EXTEND")
    np.testing.assert_allclose(out[:, 0], [1.5, 0.75])  # halfway and a quarter way
    np.testing.assert_allclose(out[:, 1], [0.5, 0.5])


@pytest.mark.parametrize("mode, expected, alpha", [
    ("REPEAT", 2.25, 1.0),  # x = -0.75: 3/4 of texel -1 (wraps to 3) + 1/4 of texel 0
    ("EXTEND", 0.0, 1.0),   # texel -1 clamps to the edge texel 0
    ("CLIP", 0.0, 0.25),    # texel -1 is transparent black: only texel 0's quarter is left
    ("MIRROR", 0.0, 1.0),   # texel -1 mirrors to texel 0
])
def test_wrap_modes_left_of_the_image(mode, expected, alpha):
    out = sample_image(ramp(), np.array([[-0.0625, 0.25]]), extension=mode)
    assert out[0, 0] == pytest.approx(expected)
    assert out[0, 3] == pytest.approx(alpha)


def test_clip_is_transparent_outside_and_fades_at_the_border():
    img = np.ones((2, 2, 4), np.float32)
    out = sample_image(img, np.array([[1.5, 0.5], [0.0, 0.5], [0.25, 0.5]]), extension="CLIP")
    np.testing.assert_allclose(out[:, 3], [0.0, 0.5, 1.0])


def test_closest_interpolation():
    out = sample_image(ramp(), np.array([[0.49, 0.75], [0.51, 0.75]]), interpolation="CLOSEST")
    np.testing.assert_allclose(out[:, 0], [1, 2])
    np.testing.assert_allclose(out[:, 1], [1, 1])


def test_checker_parity_follows_cycles():
    # Scale 2: the top-left quadrant (u < 0.5, v > 0.5) is colour 1 (different parities).
    uv = np.array([[0.25, 0.75], [0.75, 0.75], [0.25, 0.25], [0.75, 0.25], [-0.25, 0.25]])
    c1, c2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    out = checker(uv, c1, c2, 2.0)
    np.testing.assert_array_equal(out[:, 0], [1, 0, 0, 1, 1])


def test_checker_in_three_dimensions_follows_cycles():
    """On Generated coordinates the checker is Cycles' 3-D one: colour 1 where the floors of
    x s, y s and z s sum to an odd number. z = 0 gives the (u, v) pattern; z = 0.5 at scale 4
    (a flat plane's Generated z) floors to 1 under Cycles' nudge and swaps the colours; an image
    reads x and y alone."""
    c1, c2 = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    uv = np.array([[0.1, 0.1], [0.1, 0.3], [0.3, 0.3], [0.6, 0.1]])
    flat = checker(uv, c1, c2, 4.0)
    np.testing.assert_array_equal(checker(np.c_[uv, np.zeros(4)], c1, c2, 4.0), flat)
    np.testing.assert_array_equal(checker(np.c_[uv, np.full(4, 0.5)], c1, c2, 4.0), flat[:, ::-1])
    np.testing.assert_array_equal(checker(np.array([[0.1, 0.1, 0.3]]), c1, c2, 4.0)[0], c1)
    image = Texture(kind="IMAGE", pixels=ramp(), extension="EXTEND")
    xyz = np.array([[0.125, 0.25, 0.9]])
    np.testing.assert_array_equal(sample_texture(image, xyz), sample_texture(image, xyz[:, :2]))


def test_checker_box_in_three_dimensions_is_the_mean_over_the_box():
    c1, c2 = np.array([0.9, 0.2, 0.1]), np.array([0.1, 0.3, 0.8])
    lo, hi = np.array([0.05, 0.3, 0.2]), np.array([0.7, 0.45, 0.95])
    n = 81
    axes = [lo[c] + (np.arange(n) + 0.5) / n * (hi[c] - lo[c]) for c in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    dense = checker(grid, c1, c2, 3.0).mean(axis=0)
    box = checker_box(lo[None], hi[None], c1, c2, 3.0)[0]
    np.testing.assert_allclose(box, dense, atol=0.03)


def test_sample_texture_dispatches_on_kind():
    tex = Texture(kind="IMAGE", pixels=ramp(), extension="EXTEND")
    assert sample_texture(tex, np.array([[0.125, 0.25]])).shape == (1, 3)
    chk = Texture(kind="CHECKER", color1=np.ones(3, np.float32), color2=np.zeros(3, np.float32), scale=1)
    assert sample_texture(chk, np.array([[0.5, 0.5]]))[0, 0] == 0.0


@pytest.mark.parametrize("lo, hi, scale", [
    ((0.1, 0.2), (0.13, 0.21), 2.0),  # inside one square
    ((0.2, 0.3), (0.9, 0.4), 2.0),  # across one edge
    ((-1.3, 0.7), (2.9, 5.2), 3.0),  # many squares, negative coordinates
    ((0.25, 0.25), (0.25, 0.75), 2.0),  # zero width: a line
])
def test_checker_box_is_the_mean_of_the_checker_over_the_box(lo, hi, scale):
    c1, c2 = np.array([0.9, 0.2, 0.1]), np.array([0.1, 0.3, 0.8])
    n = 801  # midpoint rule: error ~ squares crossed / n
    u = lo[0] + (np.arange(n) + 0.5) / n * (hi[0] - lo[0])
    v = lo[1] + (np.arange(n) + 0.5) / n * (hi[1] - lo[1])
    uu, vv = np.meshgrid(u, v)
    dense = checker(np.stack([uu.ravel(), vv.ravel()], 1), c1, c2, scale).mean(axis=0)
    box = checker_box(np.array([lo]), np.array([hi]), c1, c2, scale)[0]
    np.testing.assert_allclose(box, dense, atol=0.02)


def random_image(height=64, width=64, encoding="linear", seed=3):
    rng = np.random.default_rng(seed)
    pixels = np.ones((height, width, 4), np.float32)
    pixels[..., :3] = rng.random((height, width, 3), np.float32)
    return Texture(kind="IMAGE", pixels=pixels, encoding=encoding)


@pytest.mark.parametrize("band", [512, 6])
@pytest.mark.parametrize("encoding", ["linear", "sRGB"])
def test_an_image_box_of_2k_texels_on_the_grid_is_the_mean_of_its_texels(encoding, band,
                                                                         monkeypatch):
    # A box of 16 x 16 texels whose corners are texel corners: the mip level of 16-texel means
    # holds its mean exactly (of the decoded colours, as Cycles averages what it looks up),
    # whether the first level is built in one band of rows or in several.
    monkeypatch.setattr(textures, "PYRAMID_BAND", band)
    tex = random_image(encoding=encoding)
    lo, hi = np.array([[16 / 64, 32 / 64]]), np.array([[32 / 64, 48 / 64]])
    linear = tex.pixels[..., :3] if encoding == "linear" else srgb_to_linear(tex.pixels[..., :3])
    # Columns 16..31; v from 32/64 to 48/64 is rows 64 - 48 .. 64 - 32 (row 0 is the top).
    expected = linear[16:32, 16:32].reshape(-1, 3).mean(axis=0)
    np.testing.assert_allclose(sample_texture_box(tex, lo, hi)[0], expected, rtol=1e-5)


def test_an_image_box_of_a_texel_or_less_is_read_at_its_centre():
    tex = random_image()
    rng = np.random.default_rng(5)
    lo = rng.random((200, 2))
    hi = lo + rng.uniform(0.0, 1.0 / 64, (200, 2))  # at most a texel wide
    np.testing.assert_array_equal(sample_texture_box(tex, lo, hi),
                                  sample_texture(tex, 0.5 * (lo + hi)).astype(np.float64))


def test_wider_image_boxes_approach_the_mean_of_their_texels():
    # Boxes 2.5 - 40 texels wide anywhere (not on any grid), texels uniform in [0, 1]: the
    # trilinear read against the exact mean of the texels they cover, median error 0.0075; the
    # centre alone 0.14.
    tex = random_image(128, 128)
    rng = np.random.default_rng(9)
    errors_mip, errors_centre = [], []
    for _ in range(60):
        size = rng.uniform(2.5, 40.0)
        x0, y0 = rng.uniform(0, 128 - size, 2)
        lo = np.array([[x0 / 128, y0 / 128]])
        hi = lo + size / 128
        rows = slice(128 - int(round(y0 + size)), 128 - int(round(y0)))
        cols = slice(int(round(x0)), int(round(x0 + size)))
        exact = tex.pixels[rows, cols, :3].reshape(-1, 3).mean(axis=0)
        errors_mip.append(np.abs(sample_texture_box(tex, lo, hi)[0] - exact).mean())
        errors_centre.append(np.abs(sample_texture(tex, 0.5 * (lo + hi))[0] - exact).mean())
    assert np.median(errors_mip) < 0.02
    assert np.median(errors_mip) < 0.2 * np.median(errors_centre)


def flat(rgb, size=4):
    return np.broadcast_to(np.array([*rgb, 1.0], np.float32), (size, size, 4)).copy()


def test_udim_tiles_follow_cycles_integer_parts_and_missing_tiles_are_magenta():
    tiles = {1001: flat((1, 0, 0)), 1002: flat((0, 1, 0)), 1011: flat((0, 0, 1))}
    uv = np.array([[0.5, 0.5], [1.5, 0.25], [0.25, 1.75], [2.5, 0.5], [-0.5, 0.5], [10.5, 0.5],
                   [0.5, -0.25]])
    got = sample_tiles(tiles, uv)
    # The integer parts truncate towards zero (Cycles' int cast): u = -0.5 and v = -0.25 read
    # tile 1001 through its extension; tile 1003 is absent and u = 10.5 has no tile: magenta.
    expected = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 0, 0), (1, 0, 1), (1, 0, 0)]
    np.testing.assert_array_equal(got[:, :3], expected)
    assert (got[:, 3] == 1).all()
    # CLIP acts within the tile: u = -0.5 is outside tile 1001's [0, 1] and reads black.
    np.testing.assert_array_equal(sample_tiles(tiles, uv[4:5], "CLIP"), [[0, 0, 0, 0]])


def test_udim_tile_reads_its_texels_at_the_tile_local_uvs():
    img = ramp()
    tiles = {1001: flat((9, 9, 9), 2), 1012: img}
    uv = np.array([[0.3, 0.6], [0.9, 0.1]])
    np.testing.assert_allclose(sample_tiles(tiles, uv + [1.0, 1.0]), sample_image(img, uv), atol=1e-6)


def test_udim_texture_boxes_read_each_tile_and_its_pyramid():
    checker_tile = np.zeros((8, 8, 4), np.float32)
    checker_tile[..., 3] = 1
    checker_tile[::2, ::2, 0] = checker_tile[1::2, 1::2, 0] = 1.0  # mean red 0.5
    tex = Texture(kind="IMAGE", pixels=checker_tile, udim={1001: flat((0, 0, 1), 8),
                                                          1002: checker_tile})
    centre = np.array([[0.5, 0.5], [1.5, 0.5], [2.5, 0.5]])
    half = np.full((3, 2), 0.5)  # whole tiles: the pyramid's last level
    got = sample_texture_box(tex, centre - half, centre + half)
    np.testing.assert_allclose(got, [(0, 0, 1), (0.5, 0, 0), (1, 0, 1)], atol=1e-6)
    np.testing.assert_allclose(sample_texture(tex, centre), sample_tiles(tex.udim, centre)[:, :3])


def test_a_textures_mean_runs_its_node_chain_over_the_decoded_texels():
    from classic_bake.kernels.shading.textures import MEAN_TEXELS, srgb_to_linear, texture_mean

    rng = np.random.default_rng(3)
    pixels = rng.uniform(0, 1, (512, 512, 4)).astype(np.float32)
    assert pixels.shape[0] * pixels.shape[1] > MEAN_TEXELS  # a subset is read
    alpha_x2 = Texture("IMAGE", pixels=pixels, weights=np.array([0, 0, 0, 1.0], np.float32),
                       gain=np.full(3, 2.0, np.float32), offset=np.full(3, 0.1, np.float32))
    np.testing.assert_allclose(texture_mean(alpha_x2), 2.0 * pixels[..., 3].mean() + 0.1,
                               rtol=1e-2)
    srgb = Texture("IMAGE", pixels=pixels, encoding="sRGB")
    np.testing.assert_allclose(texture_mean(srgb),
                               srgb_to_linear(pixels[..., :3]).reshape(-1, 3).mean(axis=0),
                               rtol=1e-2)
    checker = Texture("CHECKER", color1=np.array([1.0, 0.5, 0.0], np.float32),
                      color2=np.zeros(3, np.float32))
    np.testing.assert_allclose(texture_mean(checker), [0.5, 0.25, 0.0])
    assert texture_mean(Texture("ATTRIBUTE")) is None
