"""Rays across a rough lobe (kernels/shading/glossy_lobe.py): GGX visible-normal sampling against
the distribution's closed form, and the stratified, position-hashed points."""

import numpy as np
import pytest

from classic_bake.kernels.shading.glossy_lobe import ggx_reflections, lobe_points, shadowing_weights
from classic_bake.kernels.shading.specular_layer import lobe_albedo


def _grid(n):
    """n x n stratified points of [0, 1)^2."""
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    return np.stack([(i.ravel() + 0.5) / n, (j.ravel() + 0.5) / n], axis=1)


@pytest.mark.parametrize("roughness", [0.3, 0.6])
def test_normal_incidence_draws_microfacets_as_ggx_distributes_them(roughness):
    """Seen head-on, visible normals are distributed as D(m) cos(theta_m), whose closed form
    is P(tan^2 theta_m <= x) = x / (alpha^2 + x); the reflected direction halves the angle back
    to the microfacet normal."""
    points = _grid(200)
    n = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    out = ggx_reflections(n, n.copy(), np.full(len(points), roughness), points)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0, atol=1e-9)
    half = out + n
    half /= np.linalg.norm(half, axis=1, keepdims=True)
    tan2 = (1.0 - half[:, 2] ** 2) / np.maximum(half[:, 2] ** 2, 1e-12)
    alpha2 = roughness**4
    for x in (0.25 * alpha2, alpha2, 4.0 * alpha2):
        assert np.mean(tan2 <= x) == pytest.approx(x / (alpha2 + x), abs=0.01)


def test_a_smooth_lobe_reflects_along_the_mirror_direction():
    rng = np.random.default_rng(3)
    wo = rng.normal(size=(50, 3))
    wo[:, 2] = np.abs(wo[:, 2]) + 0.2
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    n = np.tile([0.0, 0.0, 1.0], (50, 1))
    out = ggx_reflections(n, wo, np.full(50, 0.01), rng.random((50, 2)))
    mirror = 2.0 * wo[:, 2:] * n - wo
    np.testing.assert_allclose(out, mirror, atol=2e-3)


def test_lobe_points_are_stratified_per_hit_and_fixed_by_position():
    positions = np.array([[0.1, 2.0, -3.0], [5.0, 0.5, 1.0]])
    which, points = lobe_points(np.array([4, 2]), positions)
    assert which.tolist() == [0, 0, 0, 0, 1, 1]
    assert np.all((points >= 0.0) & (points < 1.0))
    # One point per quarter of u for the hit of four (a shifted stratification).
    assert sorted(np.floor(((points[:4, 0] - points[0, 0]) % 1.0) * 4).astype(int)) == [0, 1, 2, 3]
    _, again = lobe_points(np.array([2]), positions[1:])
    np.testing.assert_array_equal(again, points[4:])  # the same hit, alone, the same points


def test_a_pixels_sub_samples_share_one_stratified_set():
    """Four sub-samples of one pixel (one seed), two rays each: together the eight points of one
    lattice, one in each eighth of u; a second pixel's set is shifted differently."""
    seed = np.array([[12.0, 7.0, 0.0]])
    together = np.concatenate([lobe_points(np.array([2]), seed, np.array([k]), 4)[1]
                               for k in range(4)])
    _, whole = lobe_points(np.array([8]), seed)
    np.testing.assert_allclose(np.sort(together[:, 0]), np.sort(whole[:, 0]), atol=1e-12)
    shift = (together[:, 0] - together[0, 0]) % 1.0
    assert sorted(np.floor(shift * 8 + 1e-9).astype(int)) == list(range(8))
    _, other = lobe_points(np.array([8]), np.array([[13.0, 7.0, 0.0]]))
    assert not np.allclose(np.sort(other[:, 0]), np.sort(whole[:, 0]))


@pytest.mark.parametrize("roughness", [0.3, 0.6, 1.0])
def test_shadowing_weights_average_to_the_lobe_albedo(roughness):
    """Over the view's reflections about visible normals, G2 / G1(o) (0 below the surface)
    averages to the single-scattering albedo with F = 1, E(mu), that the specular tables
    integrate over half vectors (`lobe_albedo`): within 0.01 from 250,000 stratified rays (the
    table's bilinear reads are within 5e-3 of its integral, 7e-3 at mu = 0.1 and roughness 0.3),
    at views from grazing (mu = 0.1) to head-on. Each weight lies in [0, 1]."""
    points = _grid(500)
    n = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    rough = np.full(len(points), roughness)
    for mu in (0.1, 0.3, 0.6, 1.0):
        wo = np.tile([np.sqrt(1.0 - mu * mu), 0.0, mu], (len(points), 1))
        g = shadowing_weights(n, wo, ggx_reflections(n, wo, rough, points), rough)
        assert g.min() >= 0.0 and g.max() <= 1.0
        want, _ = lobe_albedo(np.array([mu]), np.array([roughness]))
        assert g.mean() == pytest.approx(want[0], abs=0.01)
    # Below the surface: no weight.
    down = np.tile([0.0, 0.6, -0.8], (len(points), 1))
    assert not shadowing_weights(n, wo, down, rough).any()
