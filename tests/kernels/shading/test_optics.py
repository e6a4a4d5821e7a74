"""Reflection, refraction and Fresnel (kernels/optics.py) against
tests/data/fresnel_snell.json (exact Fresnel, Snell, critical and Brewster angles)."""


import numpy as np
import pytest
from reference_data import reference

from classic_bake.kernels.shading.optics import (
    F82_COS,
    critical_angle,
    f82_factor,
    fresnel_dielectric,
    fresnel_f82,
    fresnel_schlick,
    reflect,
    refract,
)

REF = reference("fresnel_snell.json")


@pytest.mark.parametrize("n", [1.33, 1.4, 1.5, 1.52, 2.42])
def test_normal_incidence_and_critical_angle(n):
    assert fresnel_dielectric(np.array([1.0]), 1.0 / n)[0] == pytest.approx(REF[f"R0 n={n}"], abs=1e-12)
    assert np.degrees(critical_angle(n)) == pytest.approx(REF[f"critical angle deg n={n}"], abs=1e-9)


@pytest.mark.parametrize("row", REF["table_n1.5"], ids=lambda r: f"{r['theta_i_deg']}deg")
def test_fresnel_table_both_directions(row):
    cos_i = np.array([np.cos(np.radians(row["theta_i_deg"]))])
    assert fresnel_dielectric(cos_i, 1 / 1.5)[0] == pytest.approx(row["air->glass1.5: R"], abs=1e-6)
    assert fresnel_dielectric(cos_i, 1.5)[0] == pytest.approx(row["glass1.5->air: R"], abs=1e-6)
    assert fresnel_schlick(cos_i, np.full(3, 0.04))[0, 0] == pytest.approx(row["Schlick"], abs=1e-6)


def test_brewster_angle_has_no_p_reflection():
    rp, rs, r = REF["Brewster n=1.5: Rp, Rs, R_unpolarized"]
    cos_b = np.array([np.cos(np.radians(REF["Brewster deg n=1.5 (air->n)"]))])
    assert fresnel_dielectric(cos_b, 1 / 1.5)[0] == pytest.approx(r, abs=1e-9)


def test_snell_refraction_and_reflection_examples():
    ex = REF["refract 45deg air->1.5 (GLSL refract, eta=1/1.5)"]
    d = np.array([ex["I"]])
    n = np.array([[0.0, 1.0, 0.0]])
    t, tir = refract(d, n, 1 / 1.5)
    np.testing.assert_allclose(t[0], ex["T"], atol=1e-12)
    assert not tir[0]
    np.testing.assert_allclose(reflect(d, n)[0], REF["reflect 45deg"]["R"], atol=1e-12)


def test_total_internal_reflection_beyond_the_critical_angle():
    crit = critical_angle(1.5)
    angles = np.array([crit - 1e-3, crit + 1e-3])
    d = np.stack([np.sin(angles), -np.cos(angles), np.zeros(2)], 1)
    t, tir = refract(d, np.tile([0.0, 1.0, 0.0], (2, 1)), 1.5)
    np.testing.assert_array_equal(tir, [False, True])
    np.testing.assert_allclose(np.linalg.norm(t[0]), 1.0)
    np.testing.assert_array_equal(t[1], 0.0)
    np.testing.assert_array_equal(fresnel_dielectric(np.cos(angles), 1.5)[1], 1.0)


def test_refraction_is_reversible():
    rng = np.random.default_rng(5)
    d = rng.normal(size=(1000, 3))
    d[:, 1] = -np.abs(d[:, 1])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    n = np.tile([0.0, 1.0, 0.0], (1000, 1))
    t, tir = refract(d, n, 1 / 1.5)
    assert not tir.any()
    back, tir_back = refract(-t, n * -1, 1.5)
    assert not tir_back.any()
    np.testing.assert_allclose(back, -d, atol=1e-12)


def test_the_f82_tint_scales_schlicks_curve_at_82_degrees_alone():
    """The F82-tint Fresnel (a Metallic BSDF's Edge Tint, a Principled metal's Specular Tint):
    F0 at normal incidence, tint x Schlick's value at cos = 1/7, 1 at grazing, and Schlick's curve
    itself for a white tint."""
    f0 = np.array([[0.9, 0.6, 0.3]])
    tint = np.array([[0.695, 0.726, 0.77]])  # Blender's default Edge Tint
    b = f82_factor(f0, tint)
    cos = np.array([1.0, F82_COS, 0.0])
    f = fresnel_f82(cos, np.repeat(f0, 3, 0), np.repeat(b, 3, 0))
    schlick = fresnel_schlick(cos, f0[0])
    np.testing.assert_allclose(f[0], f0[0], rtol=1e-12)
    np.testing.assert_allclose(f[1], tint[0] * schlick[1], rtol=1e-12)
    np.testing.assert_allclose(f[2], 1.0, rtol=1e-12)
    np.testing.assert_allclose(fresnel_f82(cos, np.repeat(f0, 3, 0), np.zeros((3, 3))), schlick)
    assert np.all(f82_factor(f0, np.ones((1, 3))) == 0.0)
