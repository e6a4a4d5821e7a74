"""The two-pass renderer (kernels/hybrid/two_pass.py) on a furnace: a closed box whose walls all
emit L_e and reflect rho diffusely holds L = L_e / (1 - rho) everywhere (the series
L_e (1 + rho + rho^2 + ...)). A mirror ball inside shows that same radiance. The Whitted tracer
alone stops after one diffuse bounce (L_e (1 + rho)); the hybrid carries every bounce through the
radiosity solution, at the camera's hits and behind the mirror alike."""

import numpy as np
import pytest
from scene_builder import build, grey, inward_box, persp_camera, quad, tessellated_box, uv_sphere

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.camera import camera_rays
from classic_bake.kernels.geometry.scene import Material
from classic_bake.kernels.hybrid.two_pass import (
    HybridSettings,
    diffuse_lookup,
    hybrid_steps,
    pass_one_settings,
)
from classic_bake.kernels.progress import drain
from classic_bake.kernels.radiosity.final_gather import camera_enclosed
from classic_bake.kernels.radiosity.patches import locate
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.radiosity.solve import radiosity_steps
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


def _room_with_a_block(camera_at):
    """A grey room with an emissive square under its ceiling and a closed block standing on its
    floor (outward normals; the floor runs on under it, so floor points there need probes),
    seen from `camera_at` towards the block."""
    room = tessellated_box(1)
    lamp = quad([[0.4, 0.4, 0.99], [0.4, 0.6, 0.99], [0.6, 0.6, 0.99], [0.6, 0.4, 0.99]])
    block = (0.35 + 0.3 * inward_box(1.0)) * np.array([1.0, 1.0, 0.5]) + np.array(
        [0.0, 0.0, -0.175])
    block = block[:, ::-1]  # outward
    camera = persp_camera(camera_at, np.array([0.5, 0.5, 0.1]) - camera_at, (0.0, 0.0, 1.0),
                          np.radians(60.0), (16, 16))
    return build([(room, grey(0.6)), (lamp, grey(0.0, emission=20.0, name="lamp")),
                  (block, grey(0.5, name="block"))], camera=camera)


def test_what_the_camera_sees_is_looked_up_without_enclosure_probes():
    """Points the camera reaches lie inside no solid: the look-up that skips their probes gives
    what the probes would (the floor under the block, which they find inside, is out of view)."""
    scene = _room_with_a_block(np.array([0.9, 0.1, 0.8]))
    bvh = BVH.build(scene.triangles)
    solution = drain(radiosity_steps(scene, pass_one_settings(patch_budget=60), bvh))
    origins, dirs = (a.reshape(-1, 3) for a in camera_rays(scene.camera))
    hits = bvh.intersect(origins, dirs)
    seen = np.flatnonzero(hits.tri >= 0)
    tri = np.asarray(hits.tri[seen], np.int64)
    u, v = hits.u[seen].astype(np.float64), hits.v[seen].astype(np.float64)
    bary = np.stack([1.0 - u - v, u, v], axis=1)
    front = np.einsum("ij,ij->i", solution.gather.triangle_normals[tri], dirs[seen]) < 0.0
    assert front.all() and "block" in {scene.materials[m].name for m in scene.material_ids[tri]}
    # Some of them lie under the block's top (a back face from below): those the gather probes.
    patch, _ = locate(solution.gather.patches, tri, bary)
    assert (~solution.gather.open_above[patch]).sum() >= 10
    lookup = diffuse_lookup(scene, solution)
    probed = lookup(tri, bary, dirs[seen], front, np.zeros(len(tri), bool))
    skipped = lookup(tri, bary, dirs[seen], front, np.ones(len(tri), bool))
    np.testing.assert_array_equal(skipped, probed)
    assert probed.max() > 0.0


def test_a_camera_inside_a_solid_keeps_the_probes():
    """A camera inside the closed block (facing its wall's back) is enclosed; one in the room is
    not, so only the latter's views skip the probes."""
    for at, expected in (((0.45, 0.45, 0.1), True), ((0.9, 0.1, 0.8), False)):
        scene = _room_with_a_block(np.array(at))
        solution = drain(radiosity_steps(scene, pass_one_settings(patch_budget=30),
                                         BVH.build(scene.triangles)))
        assert camera_enclosed(solution.gather, scene.camera) is expected


def _flags_seen_through(glass_part):
    """The camera-side flags the tracer gives the look-up at the front of the back wall of a
    grey room, seen through `glass_part` (smooth glass) in front of the camera."""
    glass = Material(name="glass", base_color=np.ones(3, np.float32), transmission=1.0,
                     roughness=0.0, ior=1.5)
    camera = persp_camera((1.0, 0.3, 1.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), np.radians(40.0),
                          (16, 16))
    scene = build([(inward_box(2.0), grey(0.5, name="room")), (glass_part, glass)], camera=camera)
    flags = []

    def lookup(tri, bary, dirs, front, camera_side, strata=None):
        wall = front & (scene.object_ids[tri] == 0)
        flags.append(camera_side[wall])
        return np.zeros((len(tri), 3))

    trace(scene, TracerSettings(max_depth=4, adaptive=0), diffuse=lookup)
    return np.concatenate(flags)


def test_points_seen_through_closed_glass_are_on_the_camera_side():
    """A ray that refracts into a closed glass ball and out through its back faces is outside
    every solid again: the room's walls seen through the ball are on the camera's side (no
    enclosure probes). Through an open sheet of glass (one face: entered, never left) the tracer
    cannot tell, and the points keep their probes."""
    through_ball = _flags_seen_through(uv_sphere((1.0, 0.8, 1.0), 0.3, rings=12, segments=24))
    assert through_ball.size > 200 and through_ball.all()
    sheet = quad([[0.6, 0.6, 0.6], [1.4, 0.6, 0.6], [1.4, 0.6, 1.4], [0.6, 0.6, 1.4]])  # faces -y
    through_sheet = _flags_seen_through(sheet)
    assert (~through_sheet).sum() > 50 and through_sheet.sum() > 50
