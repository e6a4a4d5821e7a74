"""The environment-mapped view's probe look-ups against Cycles (kernels/envmap/probe_lookup.py):
a rough metal ball reading the GGX mips by its roughness, a diffuse ball lit by the SH9
irradiance. env_room's ball is made rough or diffuse in place; the error is the relative MSE over
the ball's pixels against the mean of two Cycles renders of 128 samples (two seeds, whose
difference gives the reference's own noise)."""

import bpy
import numpy as np
import pytest

from classic_bake.addon import bridge

RESOLUTION = (96, 72)
BALL = "MirrorSphere"
SAMPLES = 128


def _ball_pixels(snap) -> np.ndarray:
    """(H, W) bool: pixels whose centre ray first meets the ball."""
    from classic_bake.kernels.geometry.bvh import BVH
    from classic_bake.kernels.geometry.camera import camera_rays

    o, d = camera_rays(snap.camera, *RESOLUTION)
    hits = BVH.build(snap.triangles).intersect(o.reshape(-1, 3), d.reshape(-1, 3))
    ball = next(k for k, obj in enumerate(snap.objects) if obj.source_name == BALL)
    first = np.where(hits.tri >= 0, snap.object_ids[np.maximum(hits.tri, 0)], -1)
    return (first == ball).reshape(RESOLUTION[1], RESOLUTION[0])


def _set_ball(**inputs) -> None:
    node = bpy.data.materials["Chrome"].node_tree.nodes["Principled BSDF"]
    for name, value in inputs.items():
        node.inputs[name].default_value = value


def _cycles(model) -> tuple[np.ndarray, float, np.ndarray]:
    """(mean of two seeds' renders, relMSE between them over the ball, ball mask)."""
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.measure.metrics import rel_mse

    a, _ = cr.render_camera(bpy.context.scene, model, SAMPLES, resolution=RESOLUTION, seed=0)
    b, _ = cr.render_camera(bpy.context.scene, model, SAMPLES, resolution=RESOLUTION, seed=7)
    ball = _ball_pixels(bridge.snapshot(resolution=RESOLUTION))
    return 0.5 * (a + b), rel_mse(a[ball][:, None], b[ball][:, None]), ball


def _ball_error(image, reference, ball) -> float:
    from classic_bake.kernels.measure.metrics import rel_mse

    return rel_mse(image[ball][:, None], reference[ball][:, None])


@pytest.mark.slow
def test_rough_metal_reads_the_mips_closer_to_cycles_than_the_sharp_look_up(open_sample):
    """Roughness 0.4, Cycles' `whitted` model (its glossy rays see the directly lit room).
    Measured: relMSE 0.039 with the mips, 0.161 with the sharp look-up (roughness 0.3: 0.061
    and 0.161; reference noise between the two seeds ~0.007, of their mean half that)."""
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.envmap import envmap
    from classic_bake.kernels.trace.settings import auto_settings

    open_sample("env_room")
    _set_ball(Roughness=0.4)
    snap = bridge.snapshot(resolution=RESOLUTION)
    tracer = auto_settings(snap, adaptive=0)
    views = {mips: envmap.render(snap, envmap.EnvMapSettings(objects=(BALL,), rough_mips=mips),
                                 tracer, resolution=RESOLUTION).image for mips in (0, 6)}
    reference, noise, ball = _cycles(cr.whitted(tracer.max_depth))
    errors = {mips: _ball_error(image, reference, ball) for mips, image in views.items()}
    print(f"ball pixels {ball.sum()}, reference noise {noise:.3g}: relMSE sharp "
          f"{errors[0]:.3g}, mips {errors[6]:.3g}")
    assert ball.sum() > 200
    assert errors[6] < 0.08
    assert errors[6] < errors[0] / 2


@pytest.mark.slow
def test_diffuse_ball_lit_by_the_sh_is_close_to_cycles_one_bounce(open_sample):
    """A white-ish Lambertian ball (base 0.8, no specular layer). The view lights it directly
    (the tracer) plus albedo / pi x the SH9 irradiance of the faces, which hold the directly lit
    room: Cycles with one diffuse bounce (`radiosity(1)`) computes that light. Measured: relMSE
    0.024 with the SH (mean 6% bright), 0.35 without (the direct light alone); against Cycles'
    full diffuse interreflection (32 bounces) 0.10 and 0.47."""
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.envmap import envmap
    from classic_bake.kernels.trace.settings import auto_settings

    open_sample("env_room")
    _set_ball(Metallic=0.0, Roughness=0.5, **{"Base Color": (0.8, 0.8, 0.8, 1.0)})
    snap = bridge.snapshot(resolution=RESOLUTION)
    tracer = auto_settings(snap, adaptive=0)
    views = {sh: envmap.render(snap, envmap.EnvMapSettings(objects=(BALL,), diffuse_sh=sh),
                               tracer, resolution=RESOLUTION).image for sh in (False, True)}
    reference, noise, ball = _cycles(cr.radiosity(1))
    errors = {sh: _ball_error(image, reference, ball) for sh, image in views.items()}
    print(f"ball pixels {ball.sum()}, reference noise {noise:.3g}: relMSE direct only "
          f"{errors[False]:.3g}, with the SH {errors[True]:.3g}")
    assert errors[True] < 0.05
    assert errors[True] < errors[False] / 5
    # Away from the ball (and the edge samples next to it) the view is unchanged.
    near = ball.copy()
    for axis in (0, 1):
        near |= np.roll(ball, 1, axis) | np.roll(ball, -1, axis)
    np.testing.assert_allclose(views[True][~near], views[False][~near], rtol=1e-5, atol=1e-6)
