"""The Principled specular layer's directional albedo (kernels/specular_layer.py)."""

import numpy as np
import pytest

from classic_bake.kernels.geometry.scene import Material
from classic_bake.kernels.shading.direct_light import diffuse_at, diffuse_weight
from classic_bake.kernels.shading.optics import fresnel_dielectric
from classic_bake.kernels.shading.specular_layer import (
    diffuse_factor,
    directional_albedo,
    energy_compensation,
    f82_curve,
    layer_f0,
    lobe_albedo,
    schlick_grazing_curve,
)

F0_GLASS = 0.04  # IOR 1.5 at the default level 0.5


def test_a_smooth_layer_reflects_its_fresnel_reflectance():
    """Roughness 0 is a mirror: E(mu) is the exact Fresnel reflectance at the view angle (the
    integrand is then a constant)."""
    for mu in (1.0, 0.8, 0.5, 0.2):
        np.testing.assert_allclose(directional_albedo(mu, 0.0, F0_GLASS),
                                   fresnel_dielectric(np.array([mu]), 1.0 / 1.5)[0], rtol=1e-9)


def test_albedo_matches_cycles_measured_darkening():
    """Cycles 5.2.3 darkens the base by 4.0% at roughness 0, 3.7% at 0.5 and 1.4% at 1 (ALBEDO
    bakes, IOR 1.5, level 0.5: addon/cycles/models.py, "albedo()"); tests/blender re-measures
    it through the bridge."""
    got = [directional_albedo(1.0, r, F0_GLASS) for r in (0.0, 0.5, 1.0)]
    np.testing.assert_allclose(got[:2], [0.040, 0.037], atol=5e-4)
    assert abs(got[2] - 0.014) < 5e-4


def test_the_level_scales_f0_and_zero_is_lambertian():
    assert layer_f0(1.5, 0.5) == pytest.approx(0.04)
    assert layer_f0(1.5, 1.0) == pytest.approx(0.08)
    assert layer_f0(1.5, 0.0) == 0.0 and layer_f0(3.0, 50.0) == 1.0
    lambertian = Material(name="l", specular=0.0, roughness=0.3)
    assert diffuse_factor(lambertian) == 1.0 and diffuse_weight(lambertian) == 1.0
    assert directional_albedo(1.0, 0.5, layer_f0(1.5, 1.0)) > directional_albedo(1.0, 0.5, 0.04)


@pytest.mark.parametrize("roughness", [0.0, 0.3, 0.6, 1.0])
def test_albedo_is_bounded_and_rises_towards_grazing(roughness):
    """0 < E <= 1; a near-total reflector (F0 -> 1) at roughness 0 reflects everything; Fresnel
    makes grazing views reflect more than head-on ones."""
    values = [directional_albedo(mu, roughness, F0_GLASS) for mu in (1.0, 0.7, 0.4, 0.15)]
    assert all(0.0 < v < 1.0 for v in values)
    assert values == sorted(values)
    assert directional_albedo(1.0, 0.0, 1.0 - 1e-12) == pytest.approx(1.0, abs=1e-5)


def test_the_texel_sees_the_base_under_the_layer_the_solver_without_it():
    """`diffuse_at` (what a bake shows) carries the layer; `under_layer=False` (the radiosity
    solver's reflectance, radiosity.patch_reflectance) does not; metals reflect nothing
    diffusely either way."""
    from scene_builder import build, quad

    layered = Material(name="p", base_color=np.full(3, 0.5, np.float32), specular=0.5,
                       roughness=0.5)
    metal = Material(name="m", base_color=np.full(3, 0.5, np.float32), metallic=1.0)
    scene = build([(quad([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), layered),
                   (quad([(0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]), metal)])
    tri, bary = np.array([0, 2]), np.full((2, 3), 1.0 / 3.0)
    factor = 1.0 - directional_albedo(1.0, 0.5, 0.04)
    np.testing.assert_allclose(diffuse_at(scene, tri, bary), [[0.5 * factor] * 3, [0.0] * 3])
    np.testing.assert_allclose(diffuse_at(scene, tri, bary, under_layer=False),
                               [[0.5] * 3, [0.0] * 3])


@pytest.mark.parametrize("tilt_deg", [0.0, 60.0, 80.0])
def test_the_camera_sees_the_base_darken_towards_grazing(tilt_deg):
    """The tracer's albedo view of a layered plane (roughness 0: E is Fresnel's reflectance)
    seen by an orthographic camera tilted `tilt_deg` from the normal: every pixel shows
    base x (1 - F(cos tilt)), as Cycles' Diffuse Color pass does (4% head-on, 10% at 60
    degrees, 39% at 80)."""
    from scene_builder import build, ortho_camera, quad

    from classic_bake.kernels.trace.settings import TracerSettings
    from classic_bake.kernels.trace.tracer import trace

    base = 0.6
    layered = Material(name="p", base_color=np.full(3, base, np.float32), specular=0.5,
                       roughness=0.0)
    t = np.radians(tilt_deg)
    forward = (0.0, -np.sin(t), -np.cos(t))
    camera = ortho_camera(np.array([0.0, 0.0, 0.0]) - 5.0 * np.array(forward), forward,
                          (0.0, 1.0, 0.0) if tilt_deg == 0.0 else (0.0, 0.0, 1.0), 0.5, (4, 4))
    scene = build([(quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)]), layered)],
                  camera=camera)
    image = trace(scene, TracerSettings(max_depth=0, output="albedo")).image
    expected = base * (1.0 - fresnel_dielectric(np.array([np.cos(t)]), 1.0 / 1.5)[0])
    np.testing.assert_allclose(image, expected, rtol=1e-3)


@pytest.mark.parametrize("roughness, level", [(0.5, 0.5), (0.0, 1.0)])
def test_a_layer_reflects_its_surroundings(roughness, level):
    """A black plane under a specular layer seen 60 degrees off its normal, under a world of
    radiance 2 all round: each pixel shows the layer's albedo at that view times the world,
    E(0.5) x 2, through the rays across its lobe (rough, 0.5: over a black base the lobe takes
    all `lobe_rays`) or one mirror-direction ray (smooth at level 1: Fresnel's reflectance at the
    doubled F0, 0.08)."""
    from scene_builder import build, ortho_camera, quad

    from classic_bake.kernels.trace.settings import TracerSettings
    from classic_bake.kernels.trace.tracer import trace

    black = Material(name="b", base_color=np.zeros(3, np.float32), specular=level,
                     roughness=roughness)
    t = np.radians(60.0)
    forward = np.array([0.0, np.sin(t), -np.cos(t)])
    camera = ortho_camera(-3.0 * forward, forward, (0, 0, 1), 0.4, (4, 4))
    scene = build([(quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)]), black)],
                  camera=camera, world=(2.0, 2.0, 2.0))
    image = trace(scene, TracerSettings(max_depth=1, adaptive=0)).image
    expected = 2.0 * directional_albedo(0.5, roughness, layer_f0(1.5, level))
    np.testing.assert_allclose(image, expected, rtol=2e-3)


@pytest.mark.parametrize("metallic", [0.0, 0.5])
def test_the_tracers_highlight_is_the_layers_share(metallic):
    """A black plane under a rough layer (roughness 0.3), a sun 45 degrees off its normal, the
    camera in the mirror direction: the tracer draws the analytic GGX highlight
    (`mirror_highlight`) of each lobe times its share: the layer's (F0 0.04) 1 - metallic, the
    metal's (F0 = the black base colour: Schlick's grazing term alone) metallic."""
    from scene_builder import build, mirror_highlight, mirror_view, quad

    from classic_bake.kernels.geometry.scene import Light
    from classic_bake.kernels.trace.settings import TracerSettings
    from classic_bake.kernels.trace.tracer import trace

    black = Material(name="b", base_color=np.zeros(3, np.float32), specular=0.5, roughness=0.3,
                     metallic=metallic)
    cam, sun_dir = mirror_view(45.0)
    sun = Light(name="Sun", kind="SUN", position=np.zeros(3),
                direction=sun_dir / np.linalg.norm(sun_dir), axis_x=np.array([1.0, 0, 0]),
                axis_y=np.array([0, 1.0, 0]), irradiance=np.full(3, 3.0))
    scene = build([(quad([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)]), black)], camera=cam,
                  lights=[sun])
    image = trace(scene, TracerSettings(max_depth=1, adaptive=0)).image
    expected = ((1.0 - metallic) * mirror_highlight(0.3, 0.04, 3.0, 45.0)
                + metallic * mirror_highlight(0.3, 0.0, 3.0, 45.0))
    np.testing.assert_allclose(image, expected, rtol=1e-6)


def test_schlicks_grazing_term_over_a_lobe():
    """Roughness 0: exactly (1 - mu)^5. Rougher, the lobe's microfacets face the view less
    obliquely, so at grazing views the term is smaller (a wide lobe keeps a metal's tint):
    roughness 0.5 at mu 0.1 gives well under half of the mirror's 0.59."""
    mu = np.array([1.0, 0.5, 0.3, 0.1])
    np.testing.assert_allclose(schlick_grazing_curve(mu, 0.0), (1.0 - mu) ** 5, atol=1e-12)
    wide = schlick_grazing_curve(mu, 0.5)
    assert wide[-1] < 0.5 * (1.0 - mu[-1]) ** 5
    assert np.all(np.diff(wide) > 0.0)  # still rising towards grazing


def test_the_f82_term_over_a_lobe():
    """The F82-tint model's term over a GGX lobe: roughness 0 exactly mu (1 - mu)^6; rougher,
    its peak (at 82 degrees for a mirror) spreads, lower, over the views."""
    mu = np.linspace(0.02, 1.0, 50)
    np.testing.assert_allclose(f82_curve(mu, 0.0), mu * (1.0 - mu) ** 6, atol=1e-12)
    wide = f82_curve(mu, 0.6)
    assert wide.max() < (mu * (1.0 - mu) ** 6).max()
    assert np.all(wide >= 0.0) and wide[-1] < 1e-3  # head on: nearly nothing


def test_the_lobe_albedo_table_is_the_integral_sampled_another_way():
    """E(mu) of a GGX lobe with F = 1 (`lobe_albedo`) against a Monte Carlo estimate over
    uniformly sampled outgoing directions (2^21, seeded): within 1% (roughness 1 seen head on
    keeps only 0.31 of the light in one scattering)."""
    rng = np.random.default_rng(7)
    n = 1 << 21
    z, phi = rng.random(n), 2.0 * np.pi * rng.random(n)
    out = np.stack([np.sqrt(1.0 - z * z) * np.cos(phi), np.sqrt(1.0 - z * z) * np.sin(phi), z], 1)
    for roughness, mu in ((0.5, 1.0), (0.75, 0.5), (1.0, 1.0), (1.0, 0.2)):
        a2 = roughness ** 4
        view = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
        h = out + view
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        d = a2 / (np.pi * (h[:, 2] ** 2 * (a2 - 1.0) + 1.0) ** 2)

        def lam(c, a2=a2):
            return 0.5 * (np.sqrt(1.0 + a2 * (1.0 - c * c) / (c * c)) - 1.0)

        brute = np.mean(d / (1.0 + lam(mu) + lam(z)) / (4.0 * mu)) * 2.0 * np.pi
        e, _ = lobe_albedo(np.array([mu]), np.array([roughness]))
        np.testing.assert_allclose(e[0], brute, rtol=1e-2)


@pytest.mark.parametrize("roughness", [0.2, 0.5, 0.8, 1.0])
def test_a_white_lobe_with_its_lost_light_restored_keeps_all_of_it(roughness):
    """The white furnace: a lobe of F = 1 reflects all it receives once the light scattered more
    than once is restored, E(mu) x energy_compensation = 1 at every view (within the tables'
    interpolation, 3e-3); a darker F0 keeps less than that but more than single scattering."""
    mu = np.linspace(0.05, 1.0, 12)
    r = np.full(mu.shape, roughness)
    e, _ = lobe_albedo(mu, r)
    np.testing.assert_allclose(e * energy_compensation(mu, r, np.ones((12, 3)))[:, 0], 1.0,
                               atol=3e-3)
    grey = energy_compensation(mu, r, np.full((12, 3), 0.5))[:, 0]
    assert np.all(grey >= 1.0) and np.all(e * grey < 1.0)


def test_a_tinted_smooth_layer_reflects_cycles_generalised_fresnel():
    """A smooth layer's albedo is the dielectric Fresnel F(mu); tinted by t, Cycles reflects
    t F0 + (1 - t F0) (F - F0) / (1 - F0): t F0 head on, 1 at grazing, F for a white tint."""
    from classic_bake.kernels.shading.specular_layer import tinted_albedo

    mu = np.linspace(0.0, 1.0, 11)
    ior = 1.5
    f = fresnel_dielectric(mu, 1.0 / ior)
    f0 = np.full(mu.shape, ((ior - 1.0) / (ior + 1.0)) ** 2)
    tint = np.tile([1.0, 0.3, 0.0], (mu.size, 1))
    expected = tint * f0[:, None] + (1.0 - tint * f0[:, None]) * ((f - f0) / (1.0 - f0))[:, None]
    got = tinted_albedo(f, f0, tint)
    np.testing.assert_allclose(got, expected, atol=1e-12)
    np.testing.assert_allclose(got[:, 0], f, atol=1e-12)
    np.testing.assert_allclose(got[-1], [0.04, 0.3 * 0.04, 0.0], atol=1e-12)
    np.testing.assert_allclose(got[0], 1.0, atol=1e-12)


def test_a_tinted_layer_reflects_between_nothing_and_its_untinted_albedo():
    """A tint of at most 1 takes light away: the tinted albedo lies in [0, E]. The closed form
    takes the lobe's albedo with F = 1 as 1; a rough layer of IOR 1000 (F0 0.996) and a black
    tint, as an imported house came, gave E - 249 (1 - E), far below 0, and its base drew 1.6x
    Cycles' light (the house, lamp-lit, relMSE 0.12; 2.2e-3 kept within [0, E])."""
    from classic_bake.kernels.shading.specular_layer import tinted_albedo

    e = np.array([0.6, 0.9, 0.99])
    f0 = np.full(3, layer_f0(1000.0, 0.5))
    assert f0[0] == pytest.approx(0.996, abs=1e-3)
    black = tinted_albedo(e, f0, np.zeros(3))
    assert black.min() >= 0.0
    assert (black <= e[:, None] + 1e-12).all()
    np.testing.assert_allclose(tinted_albedo(e, f0, np.ones(3)), np.repeat(e[:, None], 3, 1))
    # an ordinary layer is untouched: IOR 1.5, tint 0.5, the closed form itself
    e15, f15 = np.array([0.08]), np.array([layer_f0(1.5, 0.5)])
    expected = 0.08 - 0.5 * f15[0] * (1 - 0.08) / (1 - f15[0])
    np.testing.assert_allclose(tinted_albedo(e15, f15, 0.5)[:, 0], [expected])
