"""Sheen lobes (kernels/shading/sheen.py): the microfiber LTC integrates to its fitted albedo,
its table is read as Cycles reads it, and Ashikhmin's velvet follows its closed form."""

import numpy as np
import pytest

from classic_bake.kernels.shading.sheen import SHEEN_LTC, ltc_table, microfiber, microfiber_albedo, velvet


def _hemisphere(count):
    """Midpoint directions over the upper hemisphere (z up) and their solid angles."""
    theta = (np.arange(count) + 0.5) / count * np.pi / 2
    phi = (np.arange(4 * count) + 0.5) / (4 * count) * 2 * np.pi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    dirs = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    d_omega = (np.sin(t) * (np.pi / 2 / count) * (2 * np.pi / (4 * count))).ravel()
    return dirs, d_omega


@pytest.mark.parametrize("mu_v, roughness", [
    (0.15, 0.2), (0.15, 0.5), (0.5, 0.5), (0.95, 0.5), (0.15, 1.0), (0.5, 1.0), (0.95, 1.0),
])  # a smooth sheen (0.2) reflects almost nothing unless seen at grazing angles
def test_the_microfiber_lobe_integrates_to_its_albedo(mu_v, roughness):
    # The transformed clamped cosine is a normalised distribution: over the hemisphere,
    # f cos integrates to R(mu_v, r) (midpoint rule, 256 x 1024 directions).
    dirs, d_omega = _hemisphere(256)
    n = np.tile([0.0, 0.0, 1.0], (len(dirs), 1))
    eye = np.tile([np.sqrt(1 - mu_v**2), 0.0, mu_v], (len(dirs), 1))
    rough = np.full(len(dirs), roughness)
    total = np.sum(microfiber(n, dirs, eye, rough) * d_omega)
    albedo = microfiber_albedo(np.array([mu_v]), np.array([roughness]))[0]
    assert albedo > 0.01
    assert total == pytest.approx(albedo, rel=2e-3)


def test_the_table_is_read_at_its_entries_and_between_them():
    # Row = roughness, column = mu_v, both over [0, 1] in 31 steps (Cycles' 2-D look-up).
    mu, r = np.array([3 / 31, 3.5 / 31, 1.0]), np.array([20 / 31, 20 / 31, 1.0])
    got = ltc_table(2, mu, r)
    assert got[0] == pytest.approx(SHEEN_LTC[2, 20, 3])
    assert got[1] == pytest.approx((SHEEN_LTC[2, 20, 3] + SHEEN_LTC[2, 20, 4]) / 2)
    assert got[2] == pytest.approx(SHEEN_LTC[2, 31, 31])


def test_sheen_is_brightest_at_grazing_views():
    mu = np.linspace(0.05, 1.0, 20)
    albedo = microfiber_albedo(mu, np.full(20, 0.5))
    assert np.all(np.diff(albedo) < 0) and albedo[0] > 5 * albedo[-1]


def test_velvet_matches_its_closed_form_and_vanishes_below_the_horizon():
    sigma = 0.5
    n = np.array([[0.0, 0.0, 1.0]] * 3)
    eye = np.array([[0.6, 0.0, 0.8]] * 3)
    light = np.array([[-0.6, 0.0, 0.8], [0.0, 0.6, 0.8], [0.0, 0.8, -0.6]])
    got = velvet(n, light, eye, np.full(3, sigma))
    h = (light[0] + eye[0]) / np.linalg.norm(light[0] + eye[0])  # the normal itself: no value
    assert h[2] == pytest.approx(1.0) and got[0] == 0.0
    h = (light[1] + eye[1]) / np.linalg.norm(light[1] + eye[1])
    cos_h, cos_hv = h[2], h @ eye[1]
    sin2 = 1 - cos_h**2
    d = np.exp(-(cos_h**2 / sin2) / sigma**2) / (np.pi * sigma**2 * sin2**2)
    g = min(1.0, 2 * cos_h / cos_hv * 0.8)
    assert got[1] == pytest.approx(d * g / (4 * 0.8), rel=1e-9)
    assert got[2] == 0.0


def test_a_layered_sheen_dims_what_lies_under_it_by_its_albedo_and_an_added_one_does_not():
    from classic_bake.kernels.shading.sheen import Fabric

    mu = np.array([0.15, 0.15, 0.9])
    fabric = Fabric(color=np.array([[1.0, 0.5, 0.2], [1.0, 0.5, 0.2], [0.0, 0.0, 0.0]]),
                    roughness=np.full(3, 0.5), velvet=np.zeros(3, bool),
                    layer=np.array([True, False, True]))
    albedo = microfiber_albedo(mu[:1], np.array([0.5]))[0]
    np.testing.assert_allclose(fabric.under(mu), [1.0 - albedo, 1.0, 1.0])  # max channel: 1.0
    np.testing.assert_array_equal(fabric.present, [True, True, False])
    n = np.tile([0.0, 0.0, 1.0], (3, 1))
    eye = np.array([[np.sqrt(1 - 0.15**2), 0.0, 0.15]] * 3)
    light = np.array([[0.0, 0.6, 0.8]] * 3)
    got = fabric.brdf_cos(np.arange(3), n, light, eye)
    expected = microfiber(n, light, eye, np.full(3, 0.5))[:, None] * fabric.color
    np.testing.assert_allclose(got, expected)
