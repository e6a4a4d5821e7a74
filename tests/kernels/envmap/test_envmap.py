"""Environment (cube) mapping (kernels/envmap.py): the faces, the seamless lookup, the mirror
shading, and the technique's failure mode (parallax) against true reflection rays."""

import numpy as np
import pytest
from envmap_rooms import coloured_room, emissive, room
from scene_builder import build, ortho_camera, persp_camera, quad, uv_sphere

from classic_bake.kernels.envmap import cubemap, envmap
from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.scene import Light, Material
from classic_bake.kernels.measure.metrics import rel_mse
from classic_bake.kernels.progress import drain
from classic_bake.kernels.trace.emitters import point_light
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import Tracer, trace

CHROME = Material(name="chrome", base_color=np.array([0.9, 0.7, 0.5], np.float32), metallic=1.0,
                  roughness=0.0)
GREY = Material(name="grey", base_color=np.full(3, 0.7, np.float32), specular=0.0)


def test_bordered_directions_inside_the_border_are_the_cube_map_texels():
    size = 8
    inner = envmap.bordered_directions(size, 1)[:, 1:-1, 1:-1]
    np.testing.assert_allclose(inner, cubemap.texel_directions(size), atol=1e-12)


def test_lookup_at_texel_centres_returns_the_texel():
    rng = np.random.default_rng(1)
    size = 6
    faces = rng.random((6, size + 2, size + 2, 3)).astype(np.float32)
    dirs = cubemap.texel_directions(size).reshape(-1, 3)
    got = envmap.sample_bordered(faces, 1, dirs)
    np.testing.assert_allclose(got, faces[:, 1:-1, 1:-1].reshape(-1, 3), atol=1e-6)


def test_the_border_removes_the_seams():
    # A smooth environment, L(d) = a . d + b per channel, stored in the faces at their texel
    # directions. Bilinear interpolation errs by O(1 / S^2) inside a face; clamping at the seams
    # (cubemap.sample_cubemap) errs by half a texel's change, O(1 / S), next to every edge.
    size = 32
    a = np.array([[0.5, -0.3, 0.2], [0.1, 0.4, -0.6], [-0.2, 0.2, 0.7]])
    b = np.array([1.0, 1.0, 1.0])

    def env(d):
        return d @ a.T + b

    bordered = env(envmap.bordered_directions(size)).astype(np.float32)
    plain = bordered[:, 1:-1, 1:-1]
    rng = np.random.default_rng(2)
    # Directions within half a texel of a seam: one minor component near +-|major|.
    major = rng.integers(0, 3, 4000)
    d = rng.uniform(-1, 1, (4000, 3))
    d[np.arange(4000), major] = np.sign(rng.uniform(-1, 1, 4000))
    minor = (major + 1) % 3
    d[np.arange(4000), minor] = np.sign(d[np.arange(4000), minor]) * rng.uniform(1 - 1 / size, 1, 4000)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    seam_err = np.abs(envmap.sample_bordered(bordered, 1, d) - env(d)).max()
    clamp_err = np.abs(cubemap.sample_cubemap(plain, d) - env(d)).max()
    # Everywhere: random directions over the sphere.
    u = rng.normal(size=(20000, 3))
    everywhere = np.abs(envmap.sample_bordered(bordered, 1, u) - env(u / np.linalg.norm(
        u, axis=1, keepdims=True))).max()
    assert seam_err < 2e-3 and everywhere < 2e-3
    assert clamp_err > 10 * seam_err


def lit_room_with_sphere(half=2.0, radius=0.3, light=(0.7, -0.4, 1.2)):
    parts = [(room(half), GREY), (uv_sphere((0, 0, 0), radius, 16, 32), CHROME)]
    return build(parts, lights=[point_light("P", light, np.full(3, 30.0))])


def test_capture_holds_what_rays_from_the_centre_see_with_the_object_hidden():
    scene = lit_room_with_sphere(radius=0.3)
    settings = TracerSettings(max_depth=0, adaptive=0)
    size = 16
    env = drain(envmap.capture_steps(scene, 1, size, settings))
    assert isinstance(env, envmap.EnvironmentMap) and env.size == size
    np.testing.assert_allclose(env.centre, 0.0, atol=1e-6)
    # The same directions traced in the whole scene from just outside the sphere (radius 0.3, its
    # vertices on it): what the eye at the centre sees when only the sphere is invisible to it.
    # Equal at every texel centre (bilinear weight 1), which also fixes each face's orientation.
    dirs = cubemap.texel_directions(size).reshape(-1, 3)
    tracer = Tracer(scene, BVH.build(scene.triangles), settings)
    expected = tracer.radiance(0.301 * dirs, dirs)
    np.testing.assert_allclose(env.lookup(dirs), expected, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(env.face_images().reshape(-1, 3), expected, rtol=1e-5, atol=1e-7)
    # The sphere still casts its shadow on the wall behind it: some texels are darker than in a
    # room that never had the sphere, and none are brighter.
    without = build([(room(2.0), GREY)], lights=scene.lights)
    bare = Tracer(without, BVH.build(without.triangles), settings).radiance(0.301 * dirs, dirs)
    assert np.all(expected <= bare + 1e-7) and np.sum(expected[:, 0] < 0.5 * bare[:, 0]) >= 3


def test_faces_captured_apart_equal_the_cube_captured_whole():
    # What a tile of an envmap run captures (jobs/envmap.py): any faces, each texel traced as the
    # whole cube traces it, so the parts stacked are the cube bit for bit (supersampled, with an
    # emitter's seen emission too).
    scene = build([(room(2.0), GREY), (uv_sphere((0, 0, 0), 0.3, 8, 16), CHROME),
                   (quad([(-0.3, -0.3, 1.9), (-0.3, 0.3, 1.9), (0.3, 0.3, 1.9), (0.3, -0.3, 1.9)]),
                    emissive(np.full(3, 5.0)))],
                  lights=[point_light("P", (0.7, -0.4, 1.2), np.full(3, 30.0))])
    settings = TracerSettings(max_depth=2, adaptive=0)
    whole = drain(envmap.capture_steps(scene, 1, 8, settings, supersample=2, edge_samples=3))
    parts = [drain(envmap.capture_faces_steps(scene, 1, 8, settings, 2, faces=faces,
                                              edge_samples=3))
             for faces in ((0, 1, 2, 3), (4,), (5,))]
    stacked = envmap.CapturedFaces(1, parts[0].centre, tuple(range(6)),
                                   np.concatenate([p.radiance for p in parts]),
                                   np.concatenate([p.inverse_distance for p in parts]),
                                   np.concatenate([p.emission for p in parts]),
                                   np.concatenate([p.rays for p in parts])).environment_map()
    assert whole.emission is not None and whole.rays > 4 * 6 * 10 * 10  # edges traced again
    for field in ("faces", "inverse_distance", "emission", "centre", "rays"):
        assert np.array_equal(getattr(stacked, field), getattr(whole, field)), field
    with pytest.raises(ValueError, match="six faces in order"):
        parts[0].environment_map()


def test_env_mapped_mirror_equals_traced_mirror_in_a_uniform_room():
    # A uniformly glowing room is the same from every point: no parallax, so the map is exact and
    # the environment-mapped sphere must match true reflection rays pixel for pixel, Fresnel
    # (Schlick, tinted by the metal's colour) included.
    parts = [(room(2.0), emissive(np.full(3, 1.0))), (uv_sphere((0, 0, 0), 0.5, 24, 48), CHROME)]
    cam = ortho_camera((0, -1.5, 0.2), (0, 1, -0.1), (0, 0, 1), 1.2, (24, 24))
    scene = build(parts, cam)
    tracer_settings = TracerSettings(max_depth=1, adaptive=0)
    exact = trace(scene, tracer_settings).image
    mapped = envmap.render(scene, envmap.EnvMapSettings(face_size=8), tracer_settings).image
    np.testing.assert_allclose(mapped, exact, rtol=1e-5, atol=1e-6)
    sphere = exact[..., 2] < 0.9  # the tinted reflection (blue 0.5 at normal incidence)
    assert sphere.sum() > 100


def test_env_mapped_mirror_shows_an_area_lamp_as_a_traced_mirror_does():
    """The glowing room with an area lamp of radiance 20 hanging under its ceiling: Cycles' lamps
    are visible to glossy rays, so the traced mirror shows it, and the environment-mapped one adds
    it exactly (not from the map, whose texels would smear it): the two agree pixel for pixel,
    and the lamp shows (pixels far above the room's reflected 1)."""
    lamp = Light(name="Panel", kind="AREA", position=np.array([0.0, 0.0, 1.9]),
                 direction=np.array([0.0, 0.0, -1.0]), axis_x=np.array([1.0, 0.0, 0.0]),
                 axis_y=np.array([0.0, 1.0, 0.0]), radiance=np.full(3, 20.0), size_x=1.0,
                 size_y=1.0)
    parts = [(room(2.0), emissive(np.full(3, 1.0))), (uv_sphere((0, 0, 0), 0.5, 24, 48), CHROME)]
    cam = ortho_camera((0, -1.5, 0.2), (0, 1, -0.1), (0, 0, 1), 1.2, (24, 24))
    scene = build(parts, cam, [lamp])
    tracer_settings = TracerSettings(max_depth=1, adaptive=0)
    exact = trace(scene, tracer_settings).image
    mapped = envmap.render(scene, envmap.EnvMapSettings(face_size=8), tracer_settings).image
    np.testing.assert_allclose(mapped, exact, rtol=1e-5, atol=1e-6)
    assert (exact[..., 0] > 5.0).sum() >= 4


def _panel(height=1.9, radiance=20.0):
    return Light(name="Panel", kind="AREA", position=np.array([0.0, 0.0, height]),
                 direction=np.array([0.0, 0.0, -1.0]), axis_x=np.array([1.0, 0.0, 0.0]),
                 axis_y=np.array([0.0, 1.0, 0.0]), radiance=np.full(3, radiance), size_x=1.0,
                 size_y=1.0)


def test_edge_texels_are_traced_again_and_the_rest_kept():
    """The edge pass of the capture, under a point lamp (no shared lamp samples), faces of 24
    texels: a texel whose 4-neighbours see another object or a contrast (the sphere's shadow,
    the room's corners, the lamp's falloff) becomes the mean of 3 x 3 sub-samples, as a uniform
    3 x 3 capture has it; every other texel keeps its centre, as a 1 x 1 capture has it. Against
    an 8 x 8 capture, the edges' error is the uniform 3 x 3's with two thirds of its rays
    (measured: relMSE 1 x 1 3.1e-3, + edges 1.09e-4, 3 x 3 1.09e-4; 56% of the texels edges,
    at 12 texels 89%, at 32 36%)."""
    scene = lit_room_with_sphere()
    settings = TracerSettings(max_depth=0, adaptive=0)
    size = 24

    def capture(n, a):
        return drain(envmap.capture_steps(scene, 1, size, settings, supersample=n, edge_samples=a))

    def error(env):
        return rel_mse(env.face_images().reshape(-1, size, 3),
                       fine.face_images().reshape(-1, size, 3))

    centres, edges, uniform, fine = capture(1, 1), capture(1, 3), capture(3, 1), capture(8, 1)
    again = np.any(edges.faces != centres.faces, axis=-1)  # (a texel's mean may equal its centre)
    side = size + 2 * envmap.BORDER
    edge_rays = edges.rays - 6 * side * side
    assert edge_rays % 9 == 0 and edge_rays >= 9 * again.sum() and uniform.rays == 9 * 6 * side ** 2
    np.testing.assert_allclose(edges.faces[again], uniform.faces[again], rtol=1e-5, atol=1e-6)
    assert 0.2 < again.mean() < 0.8 and edges.rays < 0.75 * uniform.rays
    assert error(edges) < 0.1 * error(centres) and error(edges) < 1.1 * error(uniform)


def test_face_sub_samples_share_the_area_lamps_samples():
    """A room under an area lamp, faces of 8 texels: the 2 x 2 sub-samples of a texel share out
    the lamp's 4 x 4 shadow samples (each takes a quarter, weighted 4) instead of each casting
    all 16. The same light in expectation: against the capture where every sub-sample casts all
    of them (3 x 3 sub-samples, which do not divide 16), the faces' mean within 1% and the median
    texel within 5% (measured: 0.3% and 1.1%)."""
    scene = build([(room(2.0), GREY), (uv_sphere((0, 0, 0), 0.3, 8, 16), CHROME)],
                  lights=[_panel()])
    settings = TracerSettings(max_depth=0, adaptive=0, area_samples=4)
    shared = drain(envmap.capture_steps(scene, 1, 8, settings, supersample=2)).face_images()
    every = drain(envmap.capture_steps(scene, 1, 8, settings, supersample=3)).face_images()
    assert shared.mean() == pytest.approx(every.mean(), rel=0.01)
    assert np.median(np.abs(shared / np.maximum(every, 1e-6) - 1.0)) < 0.05


def test_env_mapped_mirror_needs_no_ray_depth():
    # The look-up is not a ray: with depth 0 the mirror still shows its lit surroundings. The
    # tracer's rays one bounce past the limit see only what shines, and the room only reflects.
    parts = [(room(2.0), GREY), (uv_sphere((0, 0, 0), 0.5, 24, 48), CHROME)]
    cam = ortho_camera((0, -1.5, 0), (0, 1, 0), (0, 0, 1), 0.4, (4, 4))
    scene = build(parts, cam, [point_light("P", (0.0, -1.2, 1.5), np.full(3, 200.0))])
    flat = TracerSettings(max_depth=0, adaptive=0)
    assert trace(scene, flat).image.max() == 0.0  # the walls it sees in the mirror are unlit
    mapped = envmap.render(scene, envmap.EnvMapSettings(face_size=8), flat).image
    assert mapped.min() > 0.05


def parallax_error(half: float, steps: int, radius: float = 0.3) -> float:
    """Mean |mapped - traced| over the sphere's pixels in a room of coloured walls."""
    parts = coloured_room(half) + [(uv_sphere((0, 0, 0), radius, 32, 64), CHROME)]
    # Orthographic rays start on the camera's plane: put it inside the room, before the sphere.
    cam = ortho_camera((0, -(radius + half) / 2, 0.1), (0, 1, -0.25), (0, 0, 1), 2.2 * radius,
                       (48, 48))
    scene = build(parts, cam)
    settings = TracerSettings(max_depth=1, adaptive=0)
    exact = trace(scene, settings).image
    mapped = envmap.render(scene, envmap.EnvMapSettings(face_size=128, parallax_steps=steps),
                           settings).image
    sphere = exact.max(axis=2) < 0.95  # the metal's tint darkens every reflection
    return float(np.abs(mapped - exact)[sphere].mean())


def test_parallax_shrinks_as_the_environment_recedes():
    # The failure mode of the lecture's look-up: the map is exact only at the sphere's centre, and
    # a point on its surface sees the room's edges shifted by about its distance from the centre
    # (radius / half-size).
    errors = [parallax_error(half, steps=0) for half in (0.45, 0.9, 1.8, 3.6)]
    assert all(later < earlier for earlier, later in zip(errors, errors[1:], strict=False))
    assert errors[0] > 0.05  # a close room: edges visibly misplaced
    assert errors[-1] < errors[0] / 4


def test_distance_steps_correct_the_parallax_of_a_close_room():
    lecture, corrected = parallax_error(0.45, steps=0), parallax_error(0.45, steps=4)
    assert corrected < lecture / 3


def test_parallax_search_finds_a_sphere_around_the_centre():
    # Everything the map holds lies on a sphere of radius R about its centre: the ray from p meets
    # it where |p - c + t r| = R, found here by bisection; the search lands there.
    size, radius = 32, 2.0
    centre = np.array([0.1, -0.2, 0.3])
    a = np.array([[0.5, -0.3, 0.2], [0.1, 0.4, -0.6], [-0.2, 0.2, 0.7]])
    dirs = envmap.bordered_directions(size)
    env = envmap.EnvironmentMap(object_index=0, centre=centre, faces=(dirs @ a.T + 1).astype(
        np.float32), inverse_distance=np.full(dirs.shape[:3] + (1,), 1 / radius, np.float32))
    rng = np.random.default_rng(3)
    o = rng.normal(size=(500, 3)) * 0.3
    r = rng.normal(size=(500, 3))
    r /= np.linalg.norm(r, axis=1, keepdims=True)
    lo, hi = np.zeros(500), np.full(500, 2 * radius)
    for _ in range(60):  # |o + t r| grows with t past the closest point; o is inside the sphere
        mid = 0.5 * (lo + hi)
        outside = np.linalg.norm(o + mid[:, None] * r, axis=1) > radius
        hi, lo = np.where(outside, mid, hi), np.where(outside, lo, mid)
    hit = o + lo[:, None] * r
    expected = env.lookup(hit)
    for steps in (4, 8):
        np.testing.assert_allclose(env.reflected(centre + o, r, steps), expected, atol=1e-4)
    assert np.abs(env.reflected(centre + o, r, 0) - expected).max() > 0.05  # the lecture's


def test_auto_face_size_follows_the_object_on_screen():
    parts = [(room(3.0), GREY), (uv_sphere((0, 0, 0), 0.5, 16, 32), CHROME)]
    sizes = []
    for width in (160, 320, 640):
        cam = persp_camera((0, -2.5, 0), (0, 1, 0), (0, 0, 1), np.radians(50), (width, width))
        sizes.append(envmap.auto_face_size(build(parts, cam), 1))
    assert sizes[0] < sizes[1] < sizes[2]
    assert abs(sizes[2] / sizes[1] - 2.0) < 0.2  # twice the pixels across: twice the texels
    far = build(parts, persp_camera((0, -10, 0), (0, 1, 0), (0, 0, 1), np.radians(50), (640, 640)))
    assert envmap.auto_face_size(far, 1) < sizes[2]  # smaller on screen: fewer texels
    assert envmap.auto_face_size(build(parts), 1) == 128  # no camera
    # A flat mirror filling a small view: one texel per pixel would be 1024 texels a face; the
    # six faces stay within four times the view's pixels.
    wall = [(quad([(-5, 1, -5), (5, 1, -5), (5, 1, 5), (-5, 1, 5)]), CHROME)]
    near = build(wall, persp_camera((0, 0, 0), (0, 1, 0), (0, 0, 1), np.radians(50), (160, 120)))
    size = envmap.auto_face_size(near, 0)
    assert 6 * size**2 <= envmap.VIEW_TEXEL_SHARE * 160 * 120 and size >= 64
    for s in sizes:
        assert envmap.MIN_FACE_SIZE <= s <= envmap.MAX_FACE_SIZE and s % 8 == 0


def test_mirror_objects_and_clear_errors():
    scene = lit_room_with_sphere()
    assert envmap.mirror_objects(scene) == [1]
    assert envmap.resolve_objects(scene, ["obj0"], 0.1) == [0]
    with pytest.raises(ValueError, match="no mesh object named"):
        envmap.resolve_objects(scene, ["nope"], 0.1)
    dull = build([(room(2.0), GREY)], ortho_camera((0, 0, 0), (0, 1, 0), (0, 0, 1), 1.0))
    with pytest.raises(ValueError, match="nothing to environment-map"):
        envmap.render(dull)
    with pytest.raises(ValueError, match="face_size"):
        envmap.EnvMapSettings(face_size=4)
    with pytest.raises(ValueError, match="face_supersample"):
        envmap.EnvMapSettings(face_supersample=0)
    with pytest.raises(ValueError, match="face_edge_samples"):
        envmap.EnvMapSettings(face_edge_samples=9)
    with pytest.raises(ValueError, match="face_supersample"):
        envmap.EnvMapSettings(face_supersample=9)
    with pytest.raises(ValueError, match="parallax_steps"):
        envmap.EnvMapSettings(parallax_steps=-1)
