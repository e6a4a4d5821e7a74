"""Ray differentials against finite differences of traced rays, and the textures they filter."""

from dataclasses import replace

import numpy as np
import pytest
from scene_builder import build, ortho_camera, persp_camera, quad, uv_sphere

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.camera import pixel_rays, plane_transfer
from classic_bake.kernels.geometry.scene import Light, Material, Texture
from classic_bake.kernels.measure.metrics import rel_mse
from classic_bake.kernels.shading.optics import reflect, refract
from classic_bake.kernels.shading.pixel_texture import Footprint
from classic_bake.kernels.trace import differentials as rd
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.surface import surface_at
from classic_bake.kernels.trace.tracer import Tracer, trace

CENTRE = np.array([0.0, 0.0, 1.0])
RADIUS = 1.0
# Finite-difference step, pixels: a small share of the rays cross a facet's edge (facets ~0.8
# pixel), and the hits' float32 rounding (~4e-7 m at 6 m) is ~4e-4 of the difference.
STEP = 1e-2


def smooth_sphere_scene(camera, glass: bool):
    """A sphere (normals interpolated from the true sphere's) inside a far sphere that every ray
    leaving it meets."""
    ball = Material(name="ball", base_color=np.ones(3, np.float32), specular=0.0,
                    metallic=0.0 if glass else 1.0, transmission=1.0 if glass else 0.0,
                    roughness=0.0, ior=1.5)
    backdrop = uv_sphere((0.0, 0.0, 0.0), 30.0, rings=24, segments=48, inward=True)
    scene = build([(uv_sphere(CENTRE, RADIUS, rings=96, segments=192), ball),
                   (backdrop, Material(name="backdrop", specular=0.0))], camera)
    corners = scene.triangles.astype(np.float64)
    normals = np.where(scene.object_ids[:, None, None] == 0,
                       (corners - CENTRE) / RADIUS, scene.normals)
    return replace(scene, normals=normals.astype(np.float32))


def follow(scene, bvh, x, y, bounces, glass):
    """Positions (N, 3) of each ray's hits, from the camera through `bounces` specular events,
    with the derivatives (2, N, 3) the differentials carry to each."""
    cam = scene.camera
    width, height = cam.resolution
    fp = Footprint(cam, width, height, x, y, 1.0, 1)
    tracer = Tracer(scene, bvh, TracerSettings())
    frames = rd.TriangleFrames(scene)
    o, d = pixel_rays(cam, width, height, x, y)
    points, derivatives = [], []
    dp = dd = None
    for depth in range(bounces + 1):
        hits = bvh.intersect(o, d)
        assert (hits.tri >= 0).all()
        h = surface_at(scene, tracer.tri_normals, o, d, hits, "smooth")
        if depth == 0:
            dp, dd = rd.camera_derivatives(fp, np.arange(len(x)), d, h.p, h.ng)
        else:
            dp = plane_transfer(dp, dd, d, hits.t.astype(np.float64), h.ng)
        points.append(h.p)
        derivatives.append(dp)
        if depth == bounces:
            break
        dn = rd.normal_derivatives(frames, hits.tri, h.ns, h.normal_length,
                                   np.where(h.front, 1.0, -1.0), dp)
        if glass:
            eta = np.where(h.front, 1.0 / 1.5, 1.5)
            new_d, tir = refract(d, h.ns, eta)
            assert not tir.any()
            dd = rd.refracted(d, h.ns, eta, new_d, dd, dn)
            o = h.p - h.ng * 1e-5
        else:
            new_d = reflect(d, h.ns)
            dd = rd.reflected(d, h.ns, dd, dn)
            o = h.p + h.ng * 1e-5
        d = new_d
    return points, derivatives


@pytest.mark.parametrize("glass", [False, True])
@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_differentials_match_finite_differences_through_a_curved_surface(glass, kind):
    # Rays through a sphere (glass: in and out again; mirror: off it to the far sphere): the
    # carried derivative of every hit against central differences of rays STEP pixels apart.
    # The hits lie on the facets while the normals are interpolated, as in the tracer.
    make = persp_camera if kind == "PERSP" else ortho_camera
    cam = make((0.0, -6.0, 1.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0),
               np.radians(30.0) if kind == "PERSP" else 3.0, (64, 64))
    scene = smooth_sphere_scene(cam, glass)
    bvh = BVH.build(scene.triangles)
    rng = np.random.default_rng(7)
    # Pixels whose rays meet the sphere well inside its outline (no grazing rays).
    x = 32.0 + rng.uniform(-7.0, 7.0, 40)
    y = 32.0 + rng.uniform(-7.0, 7.0, 40)
    bounces = 2 if glass else 1
    points, derivatives = follow(scene, bvh, x, y, bounces, glass)
    for axis in (0, 1):
        shift = np.array([STEP, 0.0]) if axis == 0 else np.array([0.0, STEP])
        ahead, _ = follow(scene, bvh, x + shift[0], y + shift[1], bounces, glass)
        behind, _ = follow(scene, bvh, x - shift[0], y - shift[1], bounces, glass)
        for depth in range(bounces + 1):
            numeric = (ahead[depth] - behind[depth]) / (2.0 * STEP)
            carried = derivatives[depth][axis]
            error = np.linalg.norm(carried - numeric, axis=1)
            # measured medians 1e-4 - 6e-4 (the few rays that cross a facet's edge: up to 6%)
            assert np.median(error / np.linalg.norm(numeric, axis=1)) < 2e-3, (axis, depth)


def checker_seen_in(mirror: str):
    """A checker floor finer than the pixels seen in a mirror (a flat one tilted 45 degrees, all
    the camera sees; or a ball) by a perspective camera, lit by a low sun."""
    tex = Texture(kind="CHECKER", color1=np.array([0.8, 0.1, 0.1], np.float32),
                  color2=np.array([0.1, 0.7, 0.2], np.float32), scale=6.0)
    floor = Material(name="checker", base_color=np.ones(3, np.float32), specular=0.0,
                     base_color_texture=tex)
    chrome = Material(name="chrome", base_color=np.ones(3, np.float32), metallic=1.0,
                      roughness=0.0, specular=0.0)
    ground = quad([(-40, -40, 0), (40, -40, 0), (40, 40, 0), (-40, 40, 0)])
    # Low, from behind the camera: under the leaning mirror the floor is lit too.
    low = np.array([0.0, 1.0, -0.2]) / np.hypot(1.0, 0.2)
    sun = Light(name="Sun", kind="SUN", position=np.zeros(3), direction=low,
                axis_x=np.array([1.0, 0.0, 0.0]), axis_y=np.array([0.0, 1.0, 0.0]),
                irradiance=np.full(3, 3.0))
    if mirror == "flat":  # sends the camera's rays straight down onto the floor
        cam = persp_camera((0.0, -8.0, 2.5), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), np.radians(30.0),
                           (48, 36))
        glass = quad([(-4, -2.5, 5), (4, -2.5, 5), (4, 2.5, 0), (-4, 2.5, 0)])
        return build([(glass, chrome), (ground, floor)], cam, [sun])
    cam = persp_camera((0.0, -6.0, 1.5), (0.0, 1.0, -0.1), (0.0, 0.0, 1.0), np.radians(30.0),
                       (48, 36))
    centre, radius = np.array([0.0, 0.0, 1.2]), 1.2
    scene = build([(uv_sphere(centre, radius, rings=96, segments=192), chrome), (ground, floor)],
                  cam, [sun])
    corners = scene.triangles.astype(np.float64)
    normals = np.where(scene.object_ids[:, None, None] == 0, (corners - centre) / radius,
                       scene.normals)
    return replace(scene, normals=normals.astype(np.float32))


def mirror_pixels(scene) -> np.ndarray:
    """(H, W) bool: pixels whose four corners' rays all meet the mirror (object 0)."""
    width, height = scene.camera.resolution
    bvh = BVH.build(scene.triangles)
    row, col = np.divmod(np.arange(width * height), width)
    inside = np.ones(width * height, bool)
    for dx in (0.0, 1.0):
        for dy in (0.0, 1.0):
            o, d = pixel_rays(scene.camera, width, height, col + dx, row + dy)
            tri = bvh.intersect(o, d).tri
            inside &= (tri >= 0) & (scene.object_ids[np.maximum(tri, 0)] == 0)
    return inside.reshape(height, width)


@pytest.mark.parametrize("mirror", ["flat", "ball"])
def test_a_checker_seen_in_a_mirror_is_filtered_like_supersampling(mirror):
    # Inside the mirror's outline, the filtered pixel centres against 16 x 16 point samples a
    # pixel (256 rays): the ray differentials' footprint, a parallelogram to first order, is the
    # pixel's exact image in a flat mirror and close to it in the ball. Point-sampled centres alias.
    scene = checker_seen_in(mirror)
    mask = mirror_pixels(scene)
    assert mask.mean() > (0.9 if mirror == "flat" else 0.2)
    reference = trace(scene, TracerSettings(max_depth=1, supersample=16, adaptive=0,
                                            texture_filter=1)).image
    filtered = trace(scene, TracerSettings(max_depth=1, adaptive=0)).image
    point = trace(scene, TracerSettings(max_depth=1, adaptive=0, texture_filter=1)).image
    point_error = rel_mse(point, reference, mask)
    filtered_error = rel_mse(filtered, reference, mask)
    assert point_error > 0.05  # measured 0.067 (flat), 0.070 (ball)
    assert filtered_error < (5e-4 if mirror == "flat" else 2.5e-3)  # 1.5e-4, 9.9e-4
