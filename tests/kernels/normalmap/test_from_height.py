"""Height -> tangent-space normal map (kernels/normalmap/from_height.py, heights.py, encode.py)
against closed forms: flat heights, ramps, a sphere cap, the green conventions, wrap modes and
the stability figures."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from classic_bake.kernels.normalmap import encode
from classic_bake.kernels.normalmap.from_height import (
    NormalMapSettings,
    normal_map,
    normal_map_steps,
    slope_normals,
    texel_uvs,
)
from classic_bake.kernels.normalmap.heights import (
    PROCEDURAL_HEIGHTS,
    ImageHeight,
    ProceduralHeight,
    height_source,
)
from classic_bake.kernels.progress import drain


def unit_and_finite(n):
    return np.all(np.isfinite(n)) and np.allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-6)


@pytest.mark.parametrize("wrap", ["REPEAT", "CLAMP", "MIRROR"])
def test_flat_height_gives_flat_colour_everywhere(wrap):
    for source, size in ((ImageHeight(np.full((16, 24, 3), 0.3), wrap), 0),
                         (ProceduralHeight("ramp", slope=(0.0, 0.0)), 32)):
        result = normal_map(source, NormalMapSettings(size=size, strength=5.0))
        # Exactly (0.5, 0.5, 1.0): the flat normal (0, 0, 1) encoded.
        assert np.array_equal(result.rgb, np.broadcast_to([0.5, 0.5, 1.0], result.rgb.shape))
        assert np.array_equal(encode.to_uint8(result.rgb)[0, 0], [128, 128, 255])
        assert result.degenerate_texels == 0 and result.steep_texels == 0
    assert result.rgb.shape == (32, 32, 3)


@settings(max_examples=40, deadline=None)
@given(a=st.floats(-20, 20), b=st.floats(-20, 20), s=st.floats(0, 4))
def test_linear_ramp_gives_its_analytic_constant_normal(a, b, s):
    result = normal_map(ProceduralHeight("ramp", slope=(a, b)), NormalMapSettings(size=16, strength=s))
    expected = np.array([-s * a, -s * b, 1.0])
    expected /= np.linalg.norm(expected)
    # Central differences of a linear function are exact up to float64 rounding of the heights;
    # the result is stored as float32: 1e-6.
    np.testing.assert_allclose(result.normals.reshape(-1, 3), np.broadcast_to(expected, (256, 3)),
                               atol=1e-6)


def test_ramp_signs_follow_blenders_bump_node():
    # A height rising towards +u tilts the normal towards -u (red below 0.5); rising towards +v
    # tilts it towards -v (green below 0.5, OpenGL), as n - D grad h of Cycles' Bump node.
    up_u = normal_map(ProceduralHeight("ramp", slope=(1.0, 0.0)), NormalMapSettings(size=4))
    up_v = normal_map(ProceduralHeight("ramp", slope=(0.0, 1.0)), NormalMapSettings(size=4))
    assert np.all(up_u.rgb[..., 0] < 0.5) and np.allclose(up_u.rgb[..., 1], 0.5)
    assert np.all(up_v.rgb[..., 1] < 0.5) and np.allclose(up_v.rgb[..., 0], 0.5)


def test_image_ramp_is_exact_inside_and_wraps_at_its_border():
    width = 32
    ramp = np.tile((np.arange(width) + 0.5) / width, (8, 1))  # h = u at texel centres
    interior = slice(1, -1)
    slope_x = {}
    for wrap in ("REPEAT", "CLAMP", "MIRROR"):
        n = normal_map(ImageHeight(ramp, wrap), NormalMapSettings(size=0, strength=0.1)).normals
        expected = np.array([-0.1, 0.0, 1.0]) / np.hypot(0.1, 1.0)
        np.testing.assert_allclose(n[:, interior].reshape(-1, 3),
                                   np.broadcast_to(expected, (8 * (width - 2), 3)), atol=1e-6)
        slope_x[wrap] = -n[0, 0, 0] / n[0, 0, 2] / 0.1  # dh/du at the first column
    # CLAMP and MIRROR repeat the edge texel: half the slope; REPEAT meets the far end: a cliff.
    assert slope_x["CLAMP"] == pytest.approx(0.5, abs=1e-5)
    assert slope_x["MIRROR"] == pytest.approx(0.5, abs=1e-5)
    assert slope_x["REPEAT"] == pytest.approx((1.5 / width - (1 - 0.5 / width)) * width / 2, rel=1e-5)


def test_sphere_cap_gives_analytic_normals():
    radius, size = 0.4, 256
    result = normal_map(ProceduralHeight("sphere", radius=radius), NormalMapSettings(size=size))
    uv = texel_uvs(np.arange(size), np.arange(size), size, size)
    x, y = uv[..., 0] - 0.5, uv[..., 1] - 0.5
    r = np.hypot(x, y)
    inside = r < 0.8 * radius  # away from the rim, where the slope becomes infinite
    h = np.sqrt(np.maximum(radius**2 - r * r, 0.0))
    exact = np.stack([x, y, h], axis=-1) / radius  # the sphere's own normal, +z out
    angle = np.degrees(np.arccos(np.clip((result.normals * exact).sum(-1), -1, 1)))[inside]
    # Central differences one texel wide: second-order error, measured 0.019 degrees at most
    # (0.005 mean) at 256 texels; 0.05 degrees allowed.
    assert angle.max() < 0.05
    assert unit_and_finite(result.normals)


def test_directx_flips_green_only():
    source = ProceduralHeight("bricks")
    gl = normal_map(source, NormalMapSettings(size=64, green="OPENGL"))
    dx = normal_map(source, NormalMapSettings(size=64, green="DIRECTX"))
    np.testing.assert_array_equal(gl.normals, dx.normals)
    np.testing.assert_allclose(dx.rgb[..., 1], 1.0 - gl.rgb[..., 1], atol=1e-7)
    np.testing.assert_array_equal(dx.rgb[..., [0, 2]], gl.rgb[..., [0, 2]])
    np.testing.assert_allclose(encode.rgb_to_normals(dx.rgb, "DIRECTX"), gl.normals, atol=1e-6)


def test_steep_and_broken_heights_give_finite_unit_normals_and_counts():
    steep = normal_map(ProceduralHeight("checker", scale=8.0), NormalMapSettings(size=64, strength=1e9))
    assert unit_and_finite(steep.normals) and steep.steep_texels > 0
    assert steep.degenerate_texels == 0
    # Slopes at the edge of float64: still unit, still finite.
    n, bad = slope_normals(np.array([1e300, -1e308, 0.0]), np.array([1e300, 0.0, 0.0]), 1e8)
    assert not bad.any() and unit_and_finite(n)
    pixels = np.zeros((8, 8))
    pixels[3, 3] = np.nan
    pixels[5, 6] = np.inf
    broken = normal_map(ImageHeight(pixels), NormalMapSettings(size=0))
    assert unit_and_finite(broken.normals)
    assert broken.degenerate_texels > 0
    assert np.array_equal(broken.normals[3, 3], [0.0, 0.0, 1.0])


@pytest.mark.parametrize("name", PROCEDURAL_HEIGHTS)
def test_every_pattern_gives_unit_normals(name):
    result = normal_map(height_source(name), NormalMapSettings(size=48, strength=0.05))
    assert result.rgb.shape == (48, 48, 3) and result.rgb.dtype == np.float32
    assert unit_and_finite(result.normals)
    assert result.rgb.min() >= 0.0 and result.rgb.max() <= 1.0


@pytest.mark.parametrize("name", ["orange_peel", "bricks", "checker"])
def test_lecture_patterns_tile(name):
    source = ProceduralHeight(name, scale=2.0)
    uv = np.random.default_rng(3).random((500, 2))
    for shift in ((1.0, 0.0), (0.0, 1.0), (0.5, 0.5)):
        np.testing.assert_allclose(source.heights(uv + shift), source.heights(uv), atol=1e-9)
    h = source.heights(uv)
    assert h.min() >= 0.0 and h.max() <= 1.0 and h.std() > 0.05


def test_unknown_names_and_settings_are_refused():
    with pytest.raises(ValueError):
        ProceduralHeight("marble")
    with pytest.raises(ValueError):
        ImageHeight(np.zeros((2, 2)), "CLIP")
    with pytest.raises(ValueError):
        NormalMapSettings(green="METAL")
    with pytest.raises(ValueError):
        normal_map(ProceduralHeight("ramp"), NormalMapSettings(size=0))


def test_progress_is_monotone_and_ends_at_one():
    steps = normal_map_steps(ProceduralHeight("ramp"), NormalMapSettings(size=600))
    seen = []
    result = drain(steps, seen.append)
    assert len(seen) >= 3 and seen == sorted(seen) and seen[-1] == 1.0
    assert all(0.0 <= p <= 1.0 for p in seen)
    assert result.rgb.shape == (600, 600, 3)


@settings(max_examples=200, deadline=None)
@given(x=st.floats(-1, 1), y=st.floats(-1, 1), green=st.sampled_from(["OPENGL", "DIRECTX"]))
def test_encode_decode_round_trips(x, y, green):
    n = np.array([x, y, 1.0])
    n /= np.linalg.norm(n)
    rgb = encode.normals_to_rgb(n, green)
    # float32 colours: 1e-6; 8-bit: within half a code per channel, under 0.5 degrees.
    np.testing.assert_allclose(encode.rgb_to_normals(rgb, green), n, atol=1e-6)
    back = encode.rgb_to_normals(encode.to_uint8(rgb), green)
    assert np.degrees(np.arccos(min(1.0, float(back @ n)))) < 0.5
    assert encode.to_float(rgb).dtype == np.float32
    four = encode.with_alpha(encode.to_uint8(rgb[None]))
    assert four.shape == (1, 4) and four[0, 3] == 255


class Sampled:
    """An image height seen only through its `heights(uv)` (the general, interpolating path)."""

    resolution = None

    def __init__(self, image):
        self.image = image

    def heights(self, uv):
        return self.image.heights(uv)


@pytest.mark.parametrize("wrap", ["REPEAT", "CLAMP", "MIRROR"])
def test_image_at_its_own_size_reads_texels_as_the_sampled_path(wrap):
    pixels = np.random.default_rng(2).random((24, 40, 3)).astype(np.float32)
    image = ImageHeight(pixels, wrap)
    direct = normal_map(image, NormalMapSettings(size=0, strength=0.02))
    rows = np.arange(24)
    np.testing.assert_allclose(image.texel_heights(),
                               image.heights(texel_uvs(rows, np.arange(40), 40, 24).reshape(-1, 2)
                                             ).reshape(24, 40), atol=1e-6)
    # The general path needs a square size: compare on a square crop.
    square = ImageHeight(pixels[:24, :24], wrap)
    np.testing.assert_allclose(normal_map(square, NormalMapSettings(size=0, strength=0.02)).normals,
                               normal_map(Sampled(square), NormalMapSettings(size=24, strength=0.02)
                                          ).normals, atol=1e-5)
    assert direct.rgb.shape == (24, 40, 3)
