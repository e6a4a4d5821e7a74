"""A rough metal's rays across its lobe under a world map (kernels/trace/tracer.py `_lobe_rays`,
`_lobe_sky_mean`; kernels/shading/glossy_lobe.py `shadowing_weights`, `lobe_mean`; the views
without glossy bounces, kernels/shading/reflected_emitters.py `_lobe_sky`), against the GGX BRDF
integrated over a hemisphere grid: what its reflection of a map should average to, pixel by
pixel, and with no more noise than the mean's."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scene_builder import build, floor_quad, grey, persp_camera, striped_sky

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.camera import camera_rays
from classic_bake.kernels.geometry.scene import Material, Texture
from classic_bake.kernels.shading.reflected_emitters import _lobe_sky
from classic_bake.kernels.shading.world_light import world_radiance
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import trace

RESOLUTION = (24, 16)
# The map: stripes (1.5 and 0.15) above the horizon, and a bright cap (radiance 6) over the
# top 30 degrees, the softbox a roughness-1 lobe reaches with its rays near the normal.
CAP = 6.0


def _sky(uniform: bool = False) -> np.ndarray:
    pixels = striped_sky()
    if uniform:
        return np.ones_like(pixels)
    pixels[: pixels.shape[0] // 6] = CAP  # rows within 30 degrees of the zenith
    return pixels


def _metal_floor(roughness: float, pixels: np.ndarray):
    """A white rough metal floor (F = 1 on every microfacet) 4 m wide under the map, seen
    obliquely (50 to 75 degrees from its normal)."""
    white = Material(name="metal", base_color=np.ones(3, np.float32), metallic=1.0,
                     roughness=roughness)
    cam = persp_camera((0.0, -2.0, 1.2), (0.0, 1.0, -0.55), (0.0, 0.0, 1.0), 0.6, RESOLUTION)
    scene = build([(floor_quad(0.0, -2.0, 2.0), white)], cam)
    rgba = np.concatenate([pixels, np.ones(pixels.shape[:2] + (1,), np.float32)], axis=2)
    return replace(scene, world_texture=Texture(kind="IMAGE", pixels=rgba, extension="REPEAT"))


def _brdf_means(scene, roughness: float, views: np.ndarray, grid: int = 384):
    """Per view wo (N, 3) (towards the eye, over a +z normal): the map's mean over the GGX
    BRDF x cosine, D(h) G2(v, l) / (4 cos_v), integrated on a hemisphere grid even in cos and
    azimuth (equal solid angles), F = 1; and the same with G1(v) for G2, the density of the view
    reflected about visible normals (what equal shares of the rays average to)."""
    cos_t = (np.arange(grid) + 0.5) / grid
    phi = (np.arange(2 * grid) + 0.5) / (2 * grid) * 2.0 * np.pi
    c, p = np.meshgrid(cos_t, phi, indexing="ij")
    s = np.sqrt(1.0 - c * c)
    dirs = np.stack([s * np.cos(p), s * np.sin(p), c], axis=-1).reshape(-1, 3)
    sky = world_radiance(scene, dirs)
    a2 = roughness**4

    def smith_lambda(mu):
        return 0.5 * (np.sqrt(1.0 + a2 * (1.0 - mu * mu) / (mu * mu)) - 1.0)

    shadowed, visible = [], []
    for v in views:
        h = dirs + v
        h /= np.linalg.norm(h, axis=1, keepdims=True)
        d = a2 / (np.pi * (h[:, 2] ** 2 * (a2 - 1.0) + 1.0) ** 2)
        lam_v, lam_l = smith_lambda(v[2]), smith_lambda(dirs[:, 2])
        for weights, out in ((d / (1.0 + lam_v + lam_l), shadowed), (d / (1.0 + lam_v), visible)):
            out.append(weights @ sky / weights.sum())
    return np.array(shadowed), np.array(visible)


@pytest.mark.parametrize("roughness, bound", [(0.5, 0.08), (1.0, 0.13)])
def test_a_rough_metal_floor_averages_the_map_over_its_brdf(roughness, bound):
    """Each pixel of the floor under stripes and a bright cap, over the same floor under a
    uniform map of 1 (the lobe's albedo): within `bound` (relative, rms over 40 pixels) of the
    map's mean over the BRDF, from 8 rays a pixel (the default; measured 0.054 and 0.095: the
    noise of the 64 directions the mean reads, on a map of 40:1 contrast). At roughness 1 the
    rays' equal shares (the view reflected about visible normals, unweighted) average to a mean
    up to 18% away, about twice as far from the pixels as the BRDF's."""
    settings = TracerSettings(max_depth=1, adaptive=0)
    lit = trace(_metal_floor(roughness, _sky()), settings).image
    albedo = trace(_metal_floor(roughness, _sky(uniform=True)), settings).image
    scene = _metal_floor(roughness, _sky())
    origins, dirs = camera_rays(scene.camera, *RESOLUTION)
    rows, cols = np.mgrid[0:RESOLUTION[1], 0:RESOLUTION[0]]
    on_floor = dirs[..., 2] < 0.0
    t = -origins[..., 2] / np.where(on_floor, dirs[..., 2], -1.0)
    point = origins + t[..., None] * dirs
    on_floor &= np.all(np.abs(point[..., :2]) < 1.9, axis=-1)
    pick = (rows % 3 == 1) & (cols % 3 == 1) & on_floor  # a sparse grid of pixels
    want, equal_shares = _brdf_means(scene, roughness, -dirs[pick])
    got = (lit / albedo)[pick]

    def rms(reference):
        return np.sqrt(np.mean((got / reference - 1.0) ** 2))

    assert rms(want) < bound
    if roughness == 1.0:
        assert np.abs(equal_shares / want - 1.0).max() > 0.15
        assert rms(equal_shares) > 1.5 * rms(want)


def test_sub_samples_see_as_much_of_a_walled_sky_as_whole_pixels():
    """The floor under a uniform map of 1, a dark wall 4 m high behind it hiding a third of its
    lobes' sky: 4 x 4 sub-samples a pixel (each its part of the pixel's lattice, 4 rays) within
    2% of whole pixels of 64 rays (measured 0.697 and 0.697; a part with no ray above the floor
    keeping its mirror ray, which meets the wall, gave 0.576)."""
    floor = _metal_floor(1.0, _sky(uniform=True))
    wall = np.array([[[-9.0, 1.6, 0.0], [9.0, 1.6, 0.0], [9.0, 1.6, 4.0]],
                     [[-9.0, 1.6, 0.0], [9.0, 1.6, 4.0], [-9.0, 1.6, 4.0]]])
    scene = replace(build([(floor_quad(0.0, -2.0, 2.0), floor.materials[1]), (wall, grey(0.05))],
                          floor.camera), world_texture=floor.world_texture)
    whole = trace(scene, TracerSettings(max_depth=1, adaptive=0, lobe_rays=64)).image[10:]
    parts = trace(scene, TracerSettings(max_depth=1, adaptive=0, supersample=4)).image[10:]
    assert whole.mean() < 0.8  # the wall hides some of it
    assert parts.mean() == pytest.approx(whole.mean(), rel=0.02)


def test_the_views_without_glossy_bounces_average_the_map_over_the_brdf_less_what_is_hidden():
    """The radiosity and shadow-map views' rough lobes (`reflected_emitters._lobe_sky`, 8 rays,
    64 directions for the mean): at 60 points of an open roughness-1 floor seen from a camera,
    within 0.13 rms of the map's mean over the BRDF (as the tracer's); under a wall that blocks
    the half of the sky behind the points, darker by the sky it hides and never negative."""
    scene = _metal_floor(1.0, _sky())
    rng = np.random.default_rng(5)
    points = np.column_stack([rng.uniform(-1.5, 1.5, (60, 2)), np.zeros(60)])
    eye = np.array([0.0, -3.0, 1.5])
    wo = eye - points
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    up = np.tile([0.0, 0.0, 1.0], (60, 1))
    rough, weight = np.ones(60), np.ones((60, 3))
    open_sky = _lobe_sky(scene, BVH.build(scene.triangles), points + 1e-4 * up, wo, up, up,
                         rough, weight)
    want, _ = _brdf_means(scene, 1.0, wo)
    assert np.sqrt(np.mean((open_sky / want - 1.0) ** 2)) < 0.13
    # A wall 4 m high just behind the points (y = 1.6): the reflected half of the lobe hidden.
    wall = np.array([[[-9.0, 1.6, 0.0], [9.0, 1.6, 0.0], [9.0, 1.6, 4.0]],
                     [[-9.0, 1.6, 0.0], [9.0, 1.6, 4.0], [-9.0, 1.6, 4.0]]])
    walled = _lobe_sky(scene, BVH.build(np.concatenate([scene.triangles, wall])),
                       points + 1e-4 * up, wo, up, up, rough, weight)
    assert np.all(walled >= -1e-9)
    assert np.mean(walled) < 0.8 * np.mean(open_sky)
