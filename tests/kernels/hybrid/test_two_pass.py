"""The two-pass renderer (kernels/hybrid/two_pass.py) on a furnace: a closed box whose walls all
emit L_e and reflect rho diffusely holds L = L_e / (1 - rho) everywhere (the series
L_e (1 + rho + rho^2 + ...)). A mirror ball inside shows that same radiance. The Whitted tracer
alone stops after one diffuse bounce (L_e (1 + rho)); the hybrid carries every bounce through the
radiosity solution, at the camera's hits and behind the mirror alike."""

import numpy as np
import pytest
from scene_builder import build, grey, inward_box, persp_camera, uv_sphere

from classic_bake.kernels.geometry.scene import Material
from classic_bake.kernels.hybrid.two_pass import HybridSettings, hybrid_steps
from classic_bake.kernels.progress import drain
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import trace

RHO, EMISSION = 0.5, 1.0
FURNACE = EMISSION / (1.0 - RHO)
RESOLUTION = (24, 24)


def _furnace_with_mirror_ball():
    mirror = Material(name="mirror", base_color=np.ones(3, np.float32), metallic=1.0,
                      roughness=0.0, specular=0.0)
    ball = uv_sphere((1.0, 1.0, 1.0), 0.15, rings=12, segments=24)
    camera = persp_camera((1.0, 0.25, 1.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), np.radians(50.0),
                          RESOLUTION)
    return build([(inward_box(2.0), grey(RHO, EMISSION)), (ball, mirror)], camera=camera)


def _ball_pixels(scene, image):
    """Pixels whose centre sees the ball (a tighter disc than its silhouette)."""
    width, height = RESOLUTION
    y, x = np.mgrid[0:height, 0:width]
    # The ball's centre is on the optical axis at 0.75 m; its radius subtends atan(0.15 / 0.75).
    half = np.tan(np.radians(25.0))
    r = np.hypot((x + 0.5) / width - 0.5, (y + 0.5) / height - 0.5) * 2.0 * half
    return r < 0.7 * 0.15 / 0.75


@pytest.mark.slow
def test_the_mirror_shows_the_furnace_and_the_walls_keep_it():
    scene = _furnace_with_mirror_ball()
    settings = HybridSettings(radiosity=RadiositySettings(patch_budget=150, final_gather=False),
                              tracer=TracerSettings(max_depth=4, adaptive=0))
    result = drain(hybrid_steps(scene, settings, RESOLUTION))
    image = result.image.mean(axis=2)
    ball = _ball_pixels(scene, image)
    assert ball.sum() > 10 and (~ball).sum() > 300
    # The ball hides ~0.3% of what a wall point sees and reflects nothing diffusely in pass 1:
    # the walls lose at most a few per cent of the furnace value, no more.
    np.testing.assert_allclose(image[~ball].mean(), FURNACE, rtol=0.03)
    np.testing.assert_allclose(image[ball].mean(), FURNACE, rtol=0.04)
    # The tracer alone carries one bounce: L_e (1 + rho) on the walls.
    whitted = trace(scene, TracerSettings(max_depth=4, adaptive=0), resolution=RESOLUTION)
    alone = whitted.image.mean(axis=2)
    np.testing.assert_allclose(alone[~ball].mean(), EMISSION * (1.0 + RHO), rtol=0.05)
    assert result.seconds["radiosity"] > 0.0 and result.seconds["trace"] > 0.0


def test_a_scene_without_a_camera_is_refused():
    scene = build([(inward_box(2.0), grey(RHO, EMISSION))])
    with pytest.raises(ValueError, match="no camera"):
        drain(hybrid_steps(scene))
