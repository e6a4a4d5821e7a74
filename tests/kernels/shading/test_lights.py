"""Light unit conversions and direct irradiance (kernels/lights.py).

Ground truth: the inverse-square and cosine laws, and the Cycles measurements recorded in
tests/data/cycles_facts.md and kernels/lights.py (tests/blender/test_light_units.py re-measures
them against Cycles itself).
"""

import numpy as np
import pytest

from classic_bake.kernels.geometry.scene import Light
from classic_bake.kernels.shading import lights

UP = np.array([0.0, 0.0, 1.0])


def make_light(kind, **kw):
    base = dict(name="L", kind=kind, position=np.array([0.0, 0.0, 2.0]),
                direction=np.array([0.0, 0.0, -1.0]), axis_x=np.array([1.0, 0.0, 0.0]),
                axis_y=np.array([0.0, 1.0, 0.0]))
    base.update(kw)
    return Light(**base)


def test_point_light_inverse_square_and_cosine():
    light = make_light("POINT", intensity=lights.point_intensity(100.0, np.ones(3)))
    points = np.array([[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    e = lights.direct_irradiance(light, points, np.tile(UP, (2, 1)))
    i = 100.0 / (4 * np.pi)
    np.testing.assert_allclose(e[:, 0], [i / 4.0, i / 8.0 * (2.0 / np.sqrt(8.0))], rtol=1e-12)


def test_point_light_radius_softens_as_measured_in_cycles():
    # Cycles (5.2.3): a sphere light of radius r at distance d gives E = I / (d^2 + r^2) head-on.
    light = make_light("POINT", intensity=lights.point_intensity(100.0, np.ones(3)), radius=0.5)
    e = lights.direct_irradiance(light, np.zeros((1, 3)), UP[None])
    assert e[0, 0] == pytest.approx(100.0 / (4 * np.pi) / (4.0 + 0.25), rel=1e-12)


def test_back_facing_receivers_get_nothing():
    light = make_light("POINT", intensity=np.ones(3))
    e = lights.direct_irradiance(light, np.zeros((1, 3)), -UP[None])
    assert np.all(e == 0.0)


def test_sun_strength_is_irradiance_on_a_facing_surface():
    d = np.array([0.0, -np.sin(np.radians(60)), -np.cos(np.radians(60))])
    light = make_light("SUN", direction=d, irradiance=lights.sun_irradiance(3.0, np.ones(3)))
    e = lights.direct_irradiance(light, np.zeros((1, 3)), UP[None])
    assert e[0, 0] == pytest.approx(3.0 * 0.5, rel=1e-12)


@pytest.mark.parametrize(
    "angle_deg, measured",
    # Cycles 5.2.3, spot 60 deg, blend 0.5: received / unblended point value (tests/blender re-checks).
    [(0.0, 1.0), (16.70, 1.0), (21.80, 0.98674), (25.41, 0.58379), (28.81, 0.06252), (33.02, 0.0)],
)
def test_spot_falloff_matches_cycles_measurements(angle_deg, measured):
    f = lights.spot_falloff(np.cos(np.radians(angle_deg)), np.radians(60.0), 0.5)
    assert f == pytest.approx(measured, abs=2e-3)


def test_spot_without_blend_is_a_hard_cone():
    f = lights.spot_falloff(np.cos(np.radians([29.9, 30.1])), np.radians(60.0), 0.0)
    np.testing.assert_array_equal(f, [1.0, 0.0])


def test_area_radiance_normalize():
    # normalize on: P spread over the area; off: as if the area were 1 m^2 (measured in Cycles).
    on = lights.area_radiance(100.0, np.ones(3), 4.0, True)
    off = lights.area_radiance(100.0, np.ones(3), 4.0, False)
    assert on[0] == pytest.approx(100.0 / (4.0 * np.pi))
    assert off[0] == pytest.approx(100.0 / np.pi)
    assert lights.area_of_shape("DISK", 2.0, 2.0) == pytest.approx(np.pi)


@pytest.mark.parametrize("shape", ["SQUARE", "DISK"])
def test_small_area_light_far_away_acts_as_a_point(shape):
    # A 0.1 m emitter 10 m away: E ~ L A cos / d^2 within the stratification error (< 0.1%).
    area = lights.area_of_shape(shape, 0.1, 0.1)
    radiance = lights.area_radiance(1.0, np.ones(3), area, True)
    light = make_light("AREA", position=np.array([0.0, 0.0, 10.0]), radiance=radiance, shape=shape,
                       size_x=0.1, size_y=0.1)
    e = lights.direct_irradiance(light, np.zeros((1, 3)), UP[None])
    assert e[0, 0] == pytest.approx(radiance[0] * area / 100.0, rel=1e-3)


def test_area_light_matches_the_closed_form_for_a_disk():
    # Irradiance on the axis of a Lambertian disk of radius R at height h: E = pi L R^2 / (R^2 + h^2)
    # (the element-to-coaxial-disk form factor of tests/data/form_factors.json, times pi L).
    radius, h = 1.0, 1.0
    light = make_light("AREA", position=np.array([0.0, 0.0, h]), radiance=np.ones(3), shape="DISK",
                       size_x=2 * radius, size_y=2 * radius)
    e = lights.direct_irradiance(light, np.zeros((1, 3)), UP[None])
    # The 16x16 stratified grid keeps ~200 cells inside the disk: 2% is its measured bound at h = R.
    assert e[0, 0] == pytest.approx(np.pi * 0.5, rel=0.02)


def test_a_direction_weight_is_taken_along_each_direction_the_light_comes_from():
    """A relief's shadowing weighs the light per direction: over a square lamp centred above the
    receiver, a weight of 1 on its +x half and 0 on its -x half leaves half the irradiance (the
    centre's direction alone would keep all of it or none); a sun's or a point's single
    direction takes the weight there."""
    square = make_light("AREA", position=np.array([0.0, 0.0, 1.0]), radiance=np.ones(3),
                        size_x=1.0, size_y=1.0)
    at, up = np.zeros((1, 3)), UP[None]
    whole = lights.direct_irradiance(square, at, up)
    half = lights.direct_irradiance(square, at, up, lambda d: (d[:, 0] > 0.0).astype(float))
    np.testing.assert_allclose(half, 0.5 * whole, rtol=1e-12)
    point = make_light("POINT", intensity=np.ones(3))
    dimmed = lights.direct_irradiance(point, at, up, lambda d: np.full(len(d), 0.25))
    np.testing.assert_allclose(dimmed, 0.25 * lights.direct_irradiance(point, at, up))
