"""Fuzzing the techniques' kernels (issue 43) on random small scenes: the Whitted tracer, shadow
maps, radiosity (closed and open scenes) and the texture bake's camera view, with random meshes
(degenerate triangles included), materials, lights, cameras and settings. Each must finish with
finite, non-negative radiance or refuse with a ValueError that says why."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from fuzz_inputs import (
    all_finite,
    documented_error,
    fuzz,
    fuzz_slow,
    lights,
    materials,
    meshes,
    point,
    scenes,
)
from hypothesis import given
from hypothesis import strategies as st
from scene_builder import build, grey, inward_box

from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings
from classic_bake.kernels.bake.texture_bake import TextureBakeSettings
from classic_bake.kernels.bake.texture_bake import render_steps as albedo_view_steps
from classic_bake.kernels.envmap.envmap import EnvMapSettings
from classic_bake.kernels.envmap.prefilter import PrefilterSettings
from classic_bake.kernels.measure.metrics import MetricSettings
from classic_bake.kernels.normalmap.from_height import NormalMapSettings
from classic_bake.kernels.progress import drain
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.radiosity.solve import solve_radiosity
from classic_bake.kernels.shadow.depth_test import light_visibility
from classic_bake.kernels.shadow.shadowmap import ShadowMapSettings
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import trace

# A NumPy RuntimeWarning (a division by zero, nan met) is where a nan would come from: fail on it.
pytestmark = pytest.mark.filterwarnings("error")

SETTINGS = [TracerSettings, ShadowMapSettings, RadiositySettings, NormalMapSettings,
            LightmapUVSettings, PrefilterSettings, EnvMapSettings, TextureBakeSettings,
            MetricSettings]


@pytest.mark.parametrize("kind", SETTINGS, ids=lambda k: k.__name__)
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_settings_refuse_non_finite_floats(kind, bad):
    """Every float field of every kernel's settings: nan and inf are refused with a message (the
    command line refuses them first; a script calling the kernels meets these)."""
    for field in dataclasses.fields(kind):
        if isinstance(field.default, float):
            with documented_error():
                kind(**{field.name: bad})
                raise AssertionError(f"{kind.__name__}.{field.name} = {bad} accepted")


tracer_settings = st.builds(
    TracerSettings,
    max_depth=st.integers(0, 4),
    supersample=st.integers(1, 2),
    adaptive=st.integers(0, 2),
    min_weight=st.sampled_from([0.0, 0.01, 1.0]),
    offset_scale=st.sampled_from([0.0, 1e-5, 1e-2]),
    area_samples=st.integers(1, 3),
    shading=st.sampled_from(["flat", "gouraud", "phong", "bump"]),
    texture_filter=st.integers(1, 3),
    output=st.sampled_from(["radiance", "albedo"]),
)


@fuzz_slow
@given(scene=scenes(), config=tracer_settings)
def test_tracer_on_random_scenes_gives_finite_radiance(scene, config):
    image = trace(scene, config).image
    assert image.shape == (4, 6, 3)
    assert all_finite(image) and image.min() >= 0.0


@fuzz_slow
@given(scene=scenes())
def test_albedo_view_of_random_scenes_lies_in_0_1(scene):
    image = drain(albedo_view_steps(scene))
    assert all_finite(image) and image.min() >= 0.0 and image.max() <= 1.0 + 1e-6


shadow_settings = st.builds(
    ShadowMapSettings,
    resolution=st.sampled_from([8, 16, 32]),
    eps_mode=st.sampled_from(["fixed", "auto"]),
    eps=st.sampled_from([0.0, 1e-3, 0.5]),
    slope_bias=st.sampled_from([0.0, 1.0]),
    normal_offset=st.sampled_from([0.0, 1.0]),
    pcf_size=st.sampled_from([1, 3, 5]),
    shadow_back_faces=st.booleans(),
)


@fuzz
@given(tris=meshes(), light=lights(), config=shadow_settings,
       receivers=st.lists(st.tuples(point, point), min_size=1, max_size=12))
def test_shadow_visibility_is_a_fraction(tris, light, config, receivers):
    points = np.array([r[0] for r in receivers], float)
    normals = np.array([r[1] for r in receivers], float)  # any length, zero included
    vis = light_visibility(tris, points, normals, light, config)
    assert vis.shape == (len(points),) and all_finite(vis)
    assert vis.min() >= 0.0 and vis.max() <= 1.0


@fuzz
@given(bad=st.sampled_from([np.nan, np.inf, -1.0]),
       field=st.sampled_from(["eps", "slope_bias", "normal_offset"]))
def test_shadow_settings_refuse_non_finite_biases(bad, field):
    with documented_error():
        ShadowMapSettings(**{field: bad})
        raise AssertionError(f"{field} = {bad} accepted")


radiosity_settings = st.builds(
    RadiositySettings,
    solver=st.sampled_from(["auto", "gauss_seidel", "progressive", "hierarchical", "clustered"]),
    patch_budget=st.integers(8, 60),
    refine_levels=st.integers(-1, 1),
    final_gather=st.booleans(),
)


@st.composite
def radiosity_scenes(draw):
    """A closed box (an emitting floor or a lamp inside) with random clutter, or an open scene."""
    clutter = draw(meshes(min_triangles=1, max_triangles=8)) * 0.3 + 0.5
    parts = [(clutter, draw(materials()))]
    if draw(st.booleans()):
        parts.append((inward_box(), grey(draw(st.floats(0.0, 0.95)),
                                         emission=draw(st.sampled_from([0.0, 1.0])))))
    return build(parts, lights=draw(st.lists(lights(), max_size=1)),
                 world=(draw(st.sampled_from([0.0, 0.5])),) * 3)


@fuzz_slow
@given(scene=radiosity_scenes(), config=radiosity_settings)
def test_radiosity_on_random_scenes_is_finite(scene, config):
    with documented_error():
        result = solve_radiosity(scene, config)
        assert all_finite(result.radiosity, result.corner_b, result.emitted, result.direct)
        assert result.radiosity.min() >= 0.0
