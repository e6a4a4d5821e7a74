"""Fuzzing the map kernels (issue 43): texture look-ups at random and far-away UVs, lightmap UVs
(xatlas) of random meshes, normal maps from random heights and strengths, cube-map look-ups and
prefiltering along random directions (the zero vector included), and the error metrics on random
images: no crash, nothing non-finite out, only ValueErrors with a message."""

from __future__ import annotations

import numpy as np
import pytest
from fuzz_inputs import all_finite, documented_error, fuzz, fuzz_slow, meshes
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings, lightmap_sizes, unwrap
from classic_bake.kernels.envmap.cubemap import direction_to_face, face_to_direction, sample_cubemap
from classic_bake.kernels.envmap.prefilter import PrefilterSettings, prefilter
from classic_bake.kernels.envmap.sh_irradiance import irradiance, sh_coefficients
from classic_bake.kernels.geometry.scene import Texture
from classic_bake.kernels.measure.metrics import MetricSettings, compare, psnr, rel_mse
from classic_bake.kernels.normalmap.from_height import NormalMapSettings, normal_map
from classic_bake.kernels.normalmap.heights import PROCEDURAL_HEIGHTS, ImageHeight, ProceduralHeight
from classic_bake.kernels.shading.textures import sample_texture

radiance = st.floats(0.0, 100.0, width=32)
uv_value = st.one_of(st.floats(-1e6, 1e6), st.floats(-2.0, 2.0))

# A NumPy RuntimeWarning (a division by zero, nan met) is where a nan would come from: fail on it.
pytestmark = pytest.mark.filterwarnings("error")


def images(max_side: int = 6, channels: int = 4):
    return hnp.arrays(np.float32, st.tuples(st.integers(1, max_side), st.integers(1, max_side),
                                            st.just(channels)), elements=radiance)


@fuzz
@given(pixels=images(), uv=hnp.arrays(np.float64, st.tuples(st.integers(1, 20), st.just(2)),
                                      elements=uv_value),
       extension=st.sampled_from(["REPEAT", "CLIP", "EXTEND", "MIRROR"]),
       interpolation=st.sampled_from(["LINEAR", "CLOSEST"]),
       encoding=st.sampled_from(["linear", "sRGB"]), checker=st.booleans(),
       scale=st.floats(0.0, 50.0))
def test_texture_lookups_are_finite(pixels, uv, extension, interpolation, encoding, checker,
                                    scale):
    texture = Texture("CHECKER", scale=scale) if checker else Texture(
        "IMAGE", pixels=pixels, extension=extension, interpolation=interpolation,
        encoding=encoding)
    rgb = sample_texture(texture, uv)
    assert rgb.shape == (len(uv), 3) and all_finite(rgb)
    assert rgb.min() >= 0.0


@fuzz_slow
@given(tris=meshes(min_triangles=1, max_triangles=16), resolution=st.sampled_from([16, 32, 64]),
       padding=st.integers(0, 4), scale=st.sampled_from([1.0, 1e-9, 1e6]))
def test_lightmap_uvs_of_random_meshes_lie_in_the_unit_square(tris, resolution, padding, scale):
    positions = tris.reshape(-1, 3).astype(np.float64) * scale
    faces = np.arange(len(positions)).reshape(-1, 3)
    with documented_error():  # many charts in a small atlas: "raise the resolution ..."
        result = unwrap(positions, faces, LightmapUVSettings(resolution=resolution,
                                                             padding=padding))
        check_unwrap(result, len(tris))


def check_unwrap(result, count):
    assert result.corner_uv.shape == (count, 3, 2) and all_finite(result.corner_uv)
    assert result.corner_uv.min() >= 0.0 and result.corner_uv.max() <= 1.0
    assert 0.0 <= result.utilization <= 1.0
    assert len(result.chart_ids) == count


@fuzz
@given(bad=st.sampled_from([np.nan, np.inf, -np.inf]))
def test_lightmap_uvs_refuse_non_finite_positions(bad):
    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float)
    positions[1, 2] = bad
    with documented_error():
        unwrap(positions, np.array([[0, 1, 2]]))
        raise AssertionError("non-finite positions were unwrapped")


@fuzz
@given(areas=st.lists(st.floats(0.0, 1e12), min_size=1, max_size=6),
       largest=st.sampled_from([16, 256, 4096]))
def test_lightmap_sizes_are_whole_and_bounded(areas, largest):
    with documented_error():
        sizes = lightmap_sizes(areas, largest)
        assert all(isinstance(s, int) and 1 <= s <= largest for s in sizes)


@fuzz
@given(heights=hnp.arrays(np.float64, st.tuples(st.integers(1, 6), st.integers(1, 6)),
                          elements=st.floats(-1e3, 1e3)),
       wrap=st.sampled_from(["REPEAT", "CLAMP", "MIRROR"]),
       strength=st.one_of(st.floats(0.0, 1e6), st.sampled_from([np.nan, np.inf])),
       size=st.integers(0, 9), green=st.sampled_from(["OPENGL", "DIRECTX"]))
def test_normal_maps_from_random_heights_are_unit(heights, wrap, strength, size, green):
    with documented_error():
        result = normal_map(ImageHeight(heights, wrap),
                            NormalMapSettings(size=size, strength=strength, green=green))
        assert all_finite(result.normals, result.rgb)
        np.testing.assert_allclose(np.linalg.norm(result.normals, axis=-1), 1.0, atol=1e-5)
        assert result.rgb.min() >= 0.0 and result.rgb.max() <= 1.0


@fuzz
@given(name=st.sampled_from(sorted(PROCEDURAL_HEIGHTS)), scale=st.floats(0.01, 40.0),
       size=st.integers(1, 12), strength=st.floats(0.0, 100.0))
def test_normal_maps_of_procedural_heights_are_unit(name, scale, size, strength):
    with documented_error():
        result = normal_map(ProceduralHeight(name, scale=scale),
                            NormalMapSettings(size=size, strength=strength))
        assert all_finite(result.normals, result.rgb)


directions = hnp.arrays(np.float64, st.tuples(st.integers(1, 24), st.just(3)),
                        elements=st.one_of(st.floats(-1e3, 1e3), st.just(0.0)))


@fuzz
@given(dirs=directions, size=st.integers(1, 6))
def test_cube_map_lookups_along_random_directions(dirs, size):
    rng = np.random.default_rng(size)
    cube = rng.random((6, size, size, 3)).astype(np.float32)
    face, s, t = direction_to_face(dirs)
    assert np.all((face >= 0) & (face < 6)) and all_finite(s, t)
    assert np.all((s >= 0) & (s <= 1) & (t >= 0) & (t <= 1))
    back = face_to_direction(face, s, t)
    assert all_finite(back)
    values = sample_cubemap(cube, dirs)
    assert values.shape == (len(dirs), 3) and all_finite(values)
    assert values.min() >= 0.0 and values.max() <= 1.0


@fuzz_slow
@given(size=st.sampled_from([2, 4, 8]), seed=st.integers(0, 9), dirs=directions)
def test_prefiltered_cubes_and_irradiance_are_finite(size, seed, dirs):
    faces = (np.random.default_rng(seed).random((6, size, size, 3)) * 10).astype(np.float32)
    cube = prefilter(faces, PrefilterSettings())
    for level in cube.levels:
        assert all_finite(level)
    sh = sh_coefficients(faces)
    norm = np.linalg.norm(dirs, axis=1, keepdims=True)
    unit = np.where(norm > 0, dirs / np.where(norm > 0, norm, 1.0), [0.0, 0.0, 1.0])
    assert all_finite(sh, irradiance(sh, unit))


@fuzz
@given(shape=st.tuples(st.integers(1, 6), st.integers(1, 6), st.sampled_from([1, 3])),
       seed=st.integers(0, 99), masked=st.booleans(), poison=st.booleans(),
       peak=st.one_of(st.none(), st.floats(0.1, 10.0)))
def test_metrics_on_random_images(shape, seed, masked, poison, peak):
    rng = np.random.default_rng(seed)
    test, reference = (rng.random(shape) * rng.choice([0.0, 1.0, 100.0])).astype(np.float32), \
        rng.random(shape).astype(np.float32)
    mask = rng.random(shape[:2]) < 0.5 if masked else None
    if poison:
        test[0, 0, 0] = np.nan
    with documented_error():
        m = compare(test, reference, mask, MetricSettings(psnr_peak=peak))
        values = [v for v in m.to_dict().values() if isinstance(v, float)]
        assert all_finite(values)
        assert all_finite(rel_mse(test, reference, mask), psnr(test, reference, mask))


@pytest.mark.parametrize("bad", [np.nan, np.inf, 0.0, -1.0])
def test_metric_settings_refuse_non_finite_values(bad):
    for field in ("rel_mse_eps", "psnr_peak", "flip_ppd"):
        with documented_error():
            MetricSettings(**{field: bad})
            raise AssertionError(f"{field} {bad} accepted")
    with documented_error():
        rel_mse(np.ones((2, 2)), np.ones((2, 2)), eps=bad)
        raise AssertionError(f"eps {bad} accepted")


@pytest.mark.parametrize("bad", [np.nan, np.inf, -1.0])
def test_normal_map_settings_refuse_non_finite_strength(bad):
    with documented_error():
        NormalMapSettings(strength=bad)
        raise AssertionError(f"strength {bad} accepted")
