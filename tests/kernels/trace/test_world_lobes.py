"""The world's map averaged over GGX lobes (kernels/trace/world_lobes.py), against Monte Carlo
over the same lobe (the split-sum kernel: n = v = r) on a map of sharp stripes."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scene_builder import build, floor_quad, grey, striped_sky

from classic_bake.kernels.geometry.scene import Texture
from classic_bake.kernels.shading.world_light import world_radiance
from classic_bake.kernels.trace.world_lobes import WorldLobes


def _striped_sky():
    """A scene whose world is an equirectangular map (128 x 256): stripes of radiance 1.5 and
    0.15, 8 texels (5.6 degrees) wide, above the horizon; 0.15 below."""
    stripes = striped_sky()
    pixels = np.concatenate([stripes, np.ones(stripes.shape[:2] + (1,), np.float32)], axis=2)
    scene = build([(floor_quad(), grey(0.5))], world=(0.5, 0.5, 0.5))
    return replace(scene, world_texture=Texture(kind="IMAGE", pixels=pixels, extension="REPEAT"))


def _lobe_mean(scene, r: np.ndarray, roughness: float, rng, count: int = 200_000) -> np.ndarray:
    """The map's mean over the GGX lobe about r, weighted D(h) (r . l) dOmega(l): half vectors
    drawn from D(h) (n . h) about n = r, mirrored to l (pdf D / 4 with n = v), weighted r . l."""
    alpha = roughness * roughness
    u1, u2 = rng.random(count), rng.random(count)
    cos_t = np.sqrt((1.0 - u1) / (1.0 + (alpha * alpha - 1.0) * u1))
    sin_t, phi = np.sqrt(1.0 - cos_t * cos_t), 2.0 * np.pi * u2
    t = np.cross(r, [0.0, 0.0, 1.0] if abs(r[2]) < 0.9 else [1.0, 0.0, 0.0])
    t /= np.linalg.norm(t)
    b = np.cross(r, t)
    h = (sin_t * np.cos(phi))[:, None] * t + (sin_t * np.sin(phi))[:, None] * b + cos_t[:, None] * r
    l_dir = 2.0 * (h @ r)[:, None] * h - r
    w = np.maximum(l_dir @ r, 0.0)
    return (world_radiance(scene, l_dir) * w[:, None]).sum(axis=0) / w.sum()


@pytest.mark.parametrize("roughness, bound", [(0.1, 0.12), (0.3, 0.07), (0.45, 0.03), (0.9, 0.02)])
def test_the_lobe_mean_of_a_striped_sky_matches_monte_carlo(roughness, bound):
    """Six random directions 11-57 degrees up, over the stripes: each look-up within `bound`
    (relative) of a 200k-sample Monte Carlo mean over its lobe; the map read along the direction
    alone (a mirror's look-up) misses it by over three times the bound from roughness 0.3."""
    scene = _striped_sky()
    lobes = WorldLobes(scene)
    rng = np.random.default_rng(3)
    up, around = rng.uniform(0.2, 1.0, 6), rng.uniform(0.0, 2.0 * np.pi, 6)  # over the stripes
    dirs = np.stack([np.cos(up) * np.cos(around), np.cos(up) * np.sin(around), np.sin(up)], axis=1)
    got = lobes.radiance(dirs, np.full(len(dirs), roughness))
    want = np.array([_lobe_mean(scene, d, roughness, rng) for d in dirs])
    np.testing.assert_allclose(got, want, rtol=bound)
    if roughness >= 0.3:
        assert np.abs(world_radiance(scene, dirs) / want - 1.0).max() > 3.0 * bound


def test_a_uniform_sky_is_the_same_through_any_lobe():
    """A map of one colour: every lobe's mean is that colour (the prefilter's weights are
    normalised), and no look-up is needed to build nothing (an empty call returns (0, 3))."""
    scene = _striped_sky()
    pixels = np.ones_like(scene.world_texture.pixels)
    pixels[..., :3] = (0.2, 0.5, 1.0)
    scene = replace(scene, world_texture=replace(scene.world_texture, pixels=pixels))
    lobes = WorldLobes(scene)
    assert lobes.radiance(np.zeros((0, 3)), np.zeros(0)).shape == (0, 3)
    dirs = np.eye(3)
    got = lobes.radiance(np.concatenate([dirs, -dirs]), np.linspace(0.1, 1.0, 6))
    np.testing.assert_allclose(got, np.tile([0.2, 0.5, 1.0], (6, 1)), rtol=1e-4)
