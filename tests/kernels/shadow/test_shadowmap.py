"""Shadow mapping against exact geometry: where shadows fall for sun, spot and point lights, acne
and its cures, peter-panning against tests/data/shadow_bias.json, and PCF.

Ground truth is analytic: a receiver is shadowed when its ray towards the light crosses a
rectangular occluder. Shadow-map results are checked with a sandwich: everything shadowed by the
occluder shrunk by a few texels must be shadowed, nothing outside the shadow of the occluder grown
by as much may be, so errors are confined to a band a stated number of texels wide."""

import dataclasses

import numpy as np
import pytest
from reference_data import reference

from classic_bake.kernels.geometry.raster import Projection
from classic_bake.kernels.geometry.scene import Light
from classic_bake.kernels.shadow.depth_maps import build_shadow_map, render_shadow_map_steps
from classic_bake.kernels.shadow.depth_test import depth_tolerance, light_visibility, shadow_visibility
from classic_bake.kernels.shadow.measures import acne_fraction, debug_image, peter_panning_gap
from classic_bake.kernels.shadow.shadowmap import ShadowMapSettings, ShadowView
from classic_bake.kernels.shadow.views import plan_shadow_map

BIAS_REFERENCE = reference("shadow_bias.json")


def _unit(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v)


def _light(kind, position=(0.0, 0.0, 0.0), direction=(0.0, 0.0, -1.0), spot_size=np.pi,
           cast_shadow=True):
    d = _unit(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    axis_y = _unit(np.cross(-d, helper))
    axis_x = np.cross(axis_y, -d)  # x = y cross z with local z = -direction
    return Light("test", kind, np.asarray(position, float), d, axis_x, axis_y,
                 intensity=np.ones(3), irradiance=np.ones(3), spot_size=spot_size,
                 cast_shadow=cast_shadow)


def _sun(zenith_deg, azimuth_deg=0.0):
    """A sun whose light travels down at `zenith_deg` from the vertical."""
    z, a = np.radians(zenith_deg), np.radians(azimuth_deg)
    return _light("SUN", direction=(np.sin(z) * np.cos(a), np.sin(z) * np.sin(a), -np.cos(z)))


def _quad(centre, u, v):
    """(2, 3, 3) float32: the rectangle centre +- u +- v, counter-clockwise around u x v."""
    c, u, v = (np.asarray(x, np.float64) for x in (centre, u, v))
    p = [c - u - v, c + u - v, c + u + v, c - u + v]
    return np.array([[p[0], p[1], p[2]], [p[0], p[2], p[3]]], np.float32)


def _rect_shadow(points, light, centre, u, v, grow=0.0):
    """(N,) bool: the segment from each point to the light crosses the rectangle centre + a u/|u|
    + b v/|v|, |a| <= |u| + grow, |b| <= |v| + grow (grow < 0 shrinks it)."""
    c, u, v = (np.asarray(x, np.float64) for x in (centre, u, v))
    n = np.cross(u, v)
    if light.kind == "SUN":
        ray, t_max = np.broadcast_to(-light.direction, points.shape), np.inf
    else:
        ray, t_max = light.position - points, 1.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = ((c - points) @ n) / (ray @ n)
    hit = points + t[:, None] * ray - c
    a = np.abs(hit @ _unit(u)) <= np.linalg.norm(u) + grow
    b = np.abs(hit @ _unit(v)) <= np.linalg.norm(v) + grow
    return (t > 0) & (t < t_max) & a & b


def _ground_grid(half, step, z=0.0):
    g = np.arange(-half, half + 1e-9, step)
    x, y = np.meshgrid(g, g)
    pts = np.column_stack([x.ravel(), y.ravel(), np.full(x.size, z)])
    return pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1))


# --------------------------------------------------------------------------------------------
# Where shadows fall
# --------------------------------------------------------------------------------------------


def test_sun_square_occluder_matches_geometry():
    """A 1 m square 1 m above a plane, sun at 30 degrees from the zenith. Misclassified receivers
    lie within 1 texel of the exact shadow edge (texels measured on the occluder's plane; in theory
    half a texel diagonal, 0.71); the shadow's area is within perimeter x 1 texel, and its centroid
    within half a texel (each edge snaps to texel centres) plus half the receiver spacing."""
    zenith = 30.0
    sun = _sun(zenith, 20.0)
    occ = ((0.2, -0.1, 1.0), (0.5, 0.0, 0.0), (0.0, 0.5, 0.0))
    tris = np.concatenate([_quad((0, 0, 0), (4, 0, 0), (0, 4, 0)), _quad(*occ)])
    pts, nrm = _ground_grid(2.5, 0.01)
    settings = ShadowMapSettings(resolution=512)
    smap = build_shadow_map(tris, sun, settings, pts)
    vis = shadow_visibility(smap, pts, nrm)
    texel = max(smap.views[0].texel_size)
    band = 1.0 * texel / np.cos(np.radians(zenith))  # a texel stretched onto the occluder plane
    shadowed = vis < 0.5
    assert np.all(shadowed[_rect_shadow(pts, sun, *occ, grow=-band)])
    assert not np.any(shadowed[~_rect_shadow(pts, sun, *occ, grow=band)])
    assert set(np.unique(vis)) == {0.0, 1.0}
    area = shadowed.sum() * 0.01**2
    assert abs(area - 1.0) <= 4.0 * texel / np.cos(np.radians(zenith))
    # the shadow moves along the light's travel: h tan(zenith) towards the azimuth
    azimuth = np.radians(20.0)
    shift = 1.0 * np.tan(np.radians(zenith)) * np.array([np.cos(azimuth), np.sin(azimuth)])
    centroid = pts[shadowed, :2].mean(axis=0)
    np.testing.assert_allclose(centroid, np.array(occ[0][:2]) + shift, atol=0.5 * band + 0.005)


def test_spot_square_occluder_matches_geometry():
    """A spot 4 m up, a 0.8 m square 2 m up: the shadow is the square magnified by 2 about the spot.
    Errors within 1 texel of the edge (texel footprint at the occluder, cone-edge stretch)."""
    spot = _light("SPOT", position=(0.1, 0.2, 4.0), direction=(0, 0, -1), spot_size=np.radians(70))
    occ = ((0.3, 0.0, 2.0), (0.4, 0.0, 0.0), (0.0, 0.4, 0.0))
    tris = np.concatenate([_quad((0, 0, 0), (4, 0, 0), (0, 4, 0)), _quad(*occ)])
    pts, nrm = _ground_grid(2.0, 0.01)
    settings = ShadowMapSettings(resolution=512)
    smap = build_shadow_map(tris, spot, settings, pts)
    assert smap.kind == "PERSP"
    vis = shadow_visibility(smap, pts, nrm)
    texel_at_occluder = max(smap.views[0].texel_size) * 2.0  # view depth 2 m
    band = 1.0 * texel_at_occluder / np.cos(np.radians(35.0))
    shadowed = vis < 0.5
    assert np.all(shadowed[_rect_shadow(pts, spot, *occ, grow=-band)])
    assert not np.any(shadowed[~_rect_shadow(pts, spot, *occ, grow=band)])
    assert abs(shadowed.sum() * 0.01**2 - 1.6**2) <= 4 * 1.6 * 2 * band  # ground band = 2 x band


def test_point_light_shadows_on_every_face():
    """A point light inside six separate walls, with occluders above it, below it and across the
    +X/+Y cube-face seam. Errors within 1 texel of each shadow edge."""
    light_pos = np.array([0.4, 0.7, 0.3])
    light = _light("POINT", position=light_pos)
    walls = []
    for axis in range(3):
        for sign in (1.0, -1.0):
            c, u, v = np.zeros(3), np.zeros(3), np.zeros(3)
            c[axis] = 3.0 * sign
            u[(axis + 1) % 3], v[(axis + 2) % 3] = 2.9, 2.9  # gaps at the corners: no creases
            walls.append((c, u, v, -sign * np.eye(3)[axis]))
    seam = _unit([1.0, 1.0, 0.0])
    occluders = [
        (light_pos + 0.8 * seam, 0.3 * _unit([-1.0, 1.0, 0.0]), np.array([0.0, 0.0, 0.3])),
        (light_pos + np.array([0.2, -0.1, 0.6]), np.array([0.25, 0, 0]), np.array([0, 0.25, 0])),
        (light_pos + np.array([-0.5, 0.1, -0.5]), np.array([0, 0.3, 0]), np.array([0.2, 0, 0.2])),
    ]
    tris = np.concatenate([_quad(c, u, v) for c, u, v, _ in walls] + [_quad(*o) for o in occluders])
    rng = np.random.default_rng(11)
    pts, nrm = [], []
    for c, u, v, n in walls:
        a, b = rng.uniform(-1, 1, (2, 8000))
        pts.append(c + a[:, None] * u + b[:, None] * v)
        nrm.append(np.tile(n, (8000, 1)))
    pts, nrm = np.concatenate(pts), np.concatenate(nrm)
    size = 256
    smap = build_shadow_map(tris, light, ShadowMapSettings(resolution=size), pts)
    assert smap.kind == "CUBE" and len(smap.views) == 6
    shadowed = shadow_visibility(smap, pts, nrm) < 0.5
    inner = np.zeros(len(pts), bool)
    outer = np.zeros(len(pts), bool)
    for c, u, v in occluders:
        reach = np.linalg.norm(c - light_pos) + np.linalg.norm(u) + np.linalg.norm(v)
        band = 1.0 * (2.0 / size) * reach  # 1 texel (unit-plane texel 2/S) at the occluder
        inner |= _rect_shadow(pts, light, c, u, v, grow=-band)
        outer |= _rect_shadow(pts, light, c, u, v, grow=band)
    assert inner.sum() > 2000  # every occluder casts a sizeable shadow
    assert np.all(shadowed[inner]) and not np.any(shadowed[~outer])
    faces_hit = {int(np.argmax(np.abs(p - light_pos))) for p in pts[inner]}
    assert faces_hit == {0, 1, 2}  # shadows seen through X, Y and Z faces


def _icosphere(level):
    """(20 * 4^level, 3, 3) float64 triangles of a unit icosphere, counter-clockwise from outside."""
    t = (1 + 5**0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
         (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    tris = v[np.array(f)] / np.linalg.norm(v[0])
    for _ in range(level):
        a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
        ab, bc, ca = (m / np.linalg.norm(m, axis=1, keepdims=True) for m in (a + b, b + c, c + a))
        tris = np.concatenate([np.stack(t, 1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c),
                                                        (ab, bc, ca))])
    return tris


@pytest.mark.parametrize("pcf_size", [1, 3])
def test_curved_caster_on_ground(pcf_size):
    """A tessellated sphere above a plane under a sun, the realistic acne case: its lit facets
    (N.L > 0.05, truly lit: the sphere is convex) must not shadow themselves at all, its facets
    facing away are in attached shadow, and its cast shadow on the ground lies between the shadows
    of the inscribed and circumscribed spheres, up to one texel."""
    sun = _sun(40.0, 30.0)
    to_light = -sun.direction
    centre, radius = np.array([0.1, -0.2, 0.9]), 0.8
    sphere = _icosphere(3) * radius + centre
    tris = np.concatenate([sphere, _quad((0, 0, 0), (4, 0, 0), (0, 4, 0))]).astype(np.float32)
    rng = np.random.default_rng(13)
    pick = rng.integers(0, len(sphere), 20_000)
    u, v = rng.random((2, 20_000))
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    tri = sphere[pick]
    on_sphere = tri[:, 0] + u[:, None] * (tri[:, 1] - tri[:, 0]) + v[:, None] * (tri[:, 2] - tri[:, 0])
    facet_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    facet_n /= np.linalg.norm(facet_n, axis=1, keepdims=True)
    ground, ground_n = _ground_grid(2.5, 0.02)
    pts, nrm = np.concatenate([on_sphere, ground]), np.concatenate([facet_n, ground_n])
    smap = build_shadow_map(tris, sun, ShadowMapSettings(resolution=512, pcf_size=pcf_size), pts)
    vis = shadow_visibility(smap, pts, nrm)
    n_sph = len(on_sphere)
    nl = facet_n @ to_light
    assert np.all(vis[:n_sph][nl > 0.05] == 1.0)
    assert np.all(vis[:n_sph][nl < 0.0] == 0.0)
    # the ground: a ray towards the light passing within r of the centre hits a sphere of radius r
    rel = centre - ground
    miss = np.linalg.norm(np.cross(rel, to_light), axis=1)
    ahead = rel @ to_light > 0
    band = (pcf_size // 2 + 1) * max(smap.views[0].texel_size) / np.cos(np.radians(40.0))
    r_in = radius * np.abs((facet_n * (tri[:, 0] - centre)).sum(axis=1)).min() / radius
    g = vis[n_sph:]
    assert np.all(g[ahead & (miss < r_in - band)] == 0.0)
    assert np.all(g[~(ahead & (miss < radius + band))] == 1.0)


def test_wide_spot_uses_the_cube():
    tris = _quad((0, 0, 0), (1, 0, 0), (0, 1, 0))
    spot = _light("SPOT", position=(0, 0, 1), spot_size=np.radians(150))
    assert plan_shadow_map(tris, spot, ShadowMapSettings(resolution=16)).kind == "CUBE"


# --------------------------------------------------------------------------------------------
# Acne and its cures
# --------------------------------------------------------------------------------------------


def _tilted_plane(theta_deg, n=20_000, seed=5):
    """A plane whose normal makes theta with the direction to an overhead sun, and points on it."""
    t = np.radians(theta_deg)
    normal = np.array([np.sin(t), 0.0, np.cos(t)])
    u = np.array([np.cos(t), 0.0, -np.sin(t)])
    v = np.array([0.0, 1.0, 0.0])
    rng = np.random.default_rng(seed)
    a, b = rng.uniform(-1.8, 1.8, (2, n))
    pts = a[:, None] * u + b[:, None] * v
    return _quad((0, 0, 0), 2 * u, 2 * v), pts, np.tile(normal, (n, 1))


def test_zero_eps_shows_acne_and_the_cures_remove_it():
    tris, pts, nrm = _tilted_plane(60.0)
    sun = _sun(0.0)
    truth = np.ones(len(pts))  # nothing stands between the plane and the sun
    def acne(tol=0.5, **kw):
        vis = light_visibility(tris, pts, nrm, sun, ShadowMapSettings(resolution=256, **kw))
        assert np.all(np.isfinite(vis))
        return acne_fraction(vis, truth, tolerance=tol)
    assert acne(eps_mode="fixed", eps=0.0) > 0.2  # the lecture's test with eps = 0: self-shadowing
    assert acne(tol=1e-6) == 0.0  # auto eps: not even partially darkened
    assert acne(tol=1e-6, pcf_size=5) == 0.0  # auto scales with the PCF block
    assert acne(eps_mode="fixed", normal_offset=1.0) == 0.0  # one texel of normal offset
    assert acne(eps_mode="fixed", slope_bias=1.0) == 0.0  # a full texel of slope-scaled bias


@pytest.mark.parametrize("row", [r for r in BIAS_REFERENCE["example"]["rows"] if r["tan"] > 0])
def test_auto_eps_is_the_reference_minimum_bias(row):
    """shadow_bias.json's example: a 20 m wide orthographic map of 2048 texels; the minimum bias is
    half a texel diagonal times tan(theta)."""
    example = BIAS_REFERENCE["example"]
    half = example["ortho_width_m"] / 2
    view = ShadowView(Projection.orthographic(np.eye(4), (-half, half, -half, half), 0.0, 10.0),
                      np.empty((example["map_res"],) * 2, np.float32))
    assert view.texel_size[0] == example["texel_m"]
    depth = np.array([1.0])
    eps = depth_tolerance(view, ShadowMapSettings(), depth, np.array([row["tan"]]))
    precision = 2.0**-21  # DEPTH_PRECISION_REL at depth 1 m
    assert eps[0] - precision == pytest.approx(row["min_bias_world_m_diag_half_texel"], rel=2e-3)
    fixed = ShadowMapSettings(eps_mode="fixed", eps=0.01, slope_bias=2.0)
    eps = depth_tolerance(view, fixed, depth, np.array([row["tan"]]))
    assert eps[0] == pytest.approx(0.01 + 2.0 * example["texel_m"] * row["tan"], rel=1e-12)


@pytest.mark.parametrize("theta", [15.0, 45.0, 80.0])
def test_reference_minimum_bias_is_the_acne_threshold(theta):
    """A fixed eps just above half a texel diagonal x tan(theta) removes all acne; half of it
    does not (shadow_bias.json's rows)."""
    tris, pts, nrm = _tilted_plane(theta)
    sun = _sun(0.0)
    smap = build_shadow_map(tris, sun, ShadowMapSettings(resolution=256), pts)
    tw, th = smap.views[0].texel_size
    minimum = 0.5 * np.hypot(tw, th) * np.tan(np.radians(theta))
    truth = np.ones(len(pts))
    def acne(eps):
        s = ShadowMapSettings(resolution=256, eps_mode="fixed", eps=eps)
        return acne_fraction(shadow_visibility(dataclasses.replace(smap, settings=s), pts, nrm),
                             truth)
    assert acne(1.02 * minimum + 1e-6) == 0.0
    assert acne(0.5 * minimum) > 0.01


# --------------------------------------------------------------------------------------------
# Peter-panning
# --------------------------------------------------------------------------------------------


def _wall_scene(zenith):
    """A 1 m high wall on the ground at y = 0, lit from -y: its shadow starts at its base."""
    sun = _light("SUN", direction=(0.0, np.sin(np.radians(zenith)), -np.cos(np.radians(zenith))))
    wall = ((0.0, 0.0, 0.5), (1.0, 0.0, 0.0), (0.0, 0.0, 0.5))
    tris = np.concatenate([_quad((0, 0, 0), (3, 0, 0), (0, 3, 0)), _quad(*wall)])
    y = np.arange(0.0025, 0.9 * np.tan(np.radians(zenith)), 0.0025)
    x = np.linspace(-0.05, 0.05, 11)
    gx, gy = np.meshgrid(x, y)
    pts = np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])
    nrm = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    return sun, tris, pts, nrm, _rect_shadow(pts, sun, *wall)


@pytest.mark.parametrize("zenith", [30.0, 60.0])
def test_peter_panning_gap_follows_the_reference(zenith):
    """A fixed eps detaches the shadow from the wall by eps x sin(phi) (shadow_bias.json's
    peter_panning_gap_vertical_wall); measured within 2 texels plus the receiver spacing."""
    sun, tris, pts, nrm, truth = _wall_scene(zenith)
    truth_vis = np.where(truth, 0.0, 1.0)
    smap = build_shadow_map(tris, sun, ShadowMapSettings(resolution=512), pts)
    texel = max(smap.views[0].texel_size)
    rows = [r for r in BIAS_REFERENCE["peter_panning_gap_vertical_wall"]
            if r["phi_deg"] == zenith and r["bias_m"] >= 0.02]
    gaps = []
    for row in rows:
        s = ShadowMapSettings(resolution=512, eps_mode="fixed", eps=row["bias_m"])
        vis = shadow_visibility(dataclasses.replace(smap, settings=s), pts, nrm)
        gaps.append(peter_panning_gap(pts, vis, truth_vis))
        assert gaps[-1] == pytest.approx(row["gap_m"], abs=2 * texel + 0.0025)
    auto = peter_panning_gap(pts, shadow_visibility(smap, pts, nrm), truth_vis)
    assert auto <= 2 * texel + 0.0025
    assert auto < gaps[0] < gaps[1] < gaps[2]  # the gap grows with eps


def test_failure_measures_on_hand_made_cases():
    pts = np.column_stack([np.linspace(0.0, 1.0, 11), np.zeros(11), np.zeros(11)])
    truth = np.where(pts[:, 0] < 0.55, 0.0, 1.0)  # shadowed from x = 0 to 0.5
    vis = truth.copy()
    assert peter_panning_gap(pts, vis, truth) == 0.0
    vis[:3] = 1.0  # the first three shadowed points leak: the shadow starts at x = 0.3
    assert peter_panning_gap(pts, vis, truth) == pytest.approx(0.3)
    assert peter_panning_gap(pts, np.ones(11), truth) == np.inf
    vis = truth.copy()
    vis[[6, 8]] = 0.25  # two of five lit points darkened
    assert acne_fraction(vis, truth) == pytest.approx(0.4)
    assert acne_fraction(vis, truth, mask=pts[:, 0] > 0.85) == 0.0


# --------------------------------------------------------------------------------------------
# PCF, robustness, plumbing
# --------------------------------------------------------------------------------------------


def test_pcf_gives_fractions_at_the_edge_only():
    sun = _sun(30.0, 20.0)
    occ = ((0.2, -0.1, 1.0), (0.5, 0.0, 0.0), (0.0, 0.5, 0.0))
    tris = np.concatenate([_quad((0, 0, 0), (4, 0, 0), (0, 4, 0)), _quad(*occ)])
    pts, nrm = _ground_grid(1.6, 0.01)
    k = 5
    smap = build_shadow_map(tris, sun, ShadowMapSettings(resolution=256, pcf_size=k), pts)
    vis = shadow_visibility(smap, pts, nrm)
    assert vis.dtype == np.float32 and np.all(np.isfinite(vis))
    assert np.all((vis >= 0) & (vis <= 1))
    np.testing.assert_allclose(vis * k * k, np.round(vis * k * k), atol=1e-4)  # multiples of 1/k^2
    partial = (vis > 0) & (vis < 1)
    assert partial.sum() > 100
    band = (k // 2 + 1.5) * max(smap.views[0].texel_size) / np.cos(np.radians(30.0))
    inner = _rect_shadow(pts, sun, *occ, grow=-band)
    outer = _rect_shadow(pts, sun, *occ, grow=band)
    assert np.all(vis[inner] == 0.0) and np.all(vis[~outer] == 1.0)
    # filtering keeps the shadow's area
    assert abs((1 - vis).sum() * 0.01**2 - 1.0) < 0.03


def test_odd_receivers_give_finite_visibility():
    tris = np.concatenate([_quad((0, 0, 0), (2, 0, 0), (0, 2, 0)),
                           _quad((0, 0, 1), (0.3, 0, 0), (0, 0.3, 0))])
    pts = np.array([[0, 0, 0], [0, 0, 3], [0, 0, 5], [50, 50, 0], [0.1, 0, 0], [1e6, 0, 0],
                    [0, 0, -2]], float)
    nrm = np.array([[0, 0, 1], [0, 0, 0], [1, 0, 0], [0, 0, -1], [0, 0, 0], [0, 1, 0], [0, 0, 1]],
                   float)
    lights = [_light("POINT", position=(0, 0, 3)),
              _light("SPOT", position=(0, 0, 3), spot_size=np.radians(40)),
              _sun(10.0), _light("AREA", position=(0, 0, 3))]
    for light in lights:
        for s in (ShadowMapSettings(resolution=32),
                  ShadowMapSettings(resolution=32, pcf_size=3, normal_offset=1.0, slope_bias=1.0)):
            vis = light_visibility(tris, pts, nrm, light, s)
            assert np.all(np.isfinite(vis)) and np.all((vis >= 0) & (vis <= 1)), light.kind
            assert vis[0] == 0.0 and vis[4] == 0.0, light.kind  # under the small square
    assert light_visibility(tris, pts, nrm, _light("POINT", cast_shadow=False)).min() == 1.0
    assert light_visibility(tris[:0], pts, nrm, lights[0]).min() == 1.0
    assert light_visibility(tris, pts[:0], nrm[:0], lights[0]).shape == (0,)


def test_sun_map_models_no_more_than_needed():
    """Receivers in a 2 m patch of a 200 m ground: the map covers the patch, not the ground; a
    pillar outside the receivers' prism changes nothing; the far plane stops behind the receivers.
    """
    sun = _sun(25.0, 40.0)
    ground = _quad((0, 0, 0), (100, 0, 0), (0, 100, 0))
    box = _quad((0.3, 0.2, 0.8), (0.2, 0, 0), (0, 0.2, 0))
    pillar = _quad((40, 0, 10), (0.5, 0, 0), (0, 0, 10))
    pts, _ = _ground_grid(1.0, 0.1)
    settings = ShadowMapSettings(resolution=128)
    a = plan_shadow_map(np.concatenate([ground, box]), sun, settings, pts).views[0]
    b = plan_shadow_map(np.concatenate([ground, box, pillar]), sun, settings, pts).views[0]
    left, right, bottom, top = a.projection.extent
    assert right - left < 2.9 and top - bottom < 2.9  # the patch is 2 m wide, 2.83 m diagonally
    assert b.projection.extent == a.projection.extent and b.projection.far == a.projection.far
    # depth: from just before the box top to just behind the lowest receiver
    down = sun.direction
    depths = np.concatenate([pts, box.reshape(-1, 3)]) @ down
    assert a.projection.far - a.projection.near < (depths.max() - depths.min()) * 1.01 + 1e-3


def test_progress_and_debug_image():
    tris = np.concatenate([_quad((0, 0, 0), (3, 0, 0), (0, 3, 0)),
                           _quad((0, 0, 1), (0.3, 0, 0), (0, 0.3, 0))])
    light = _light("POINT", position=(0.1, 0.2, 2.0))
    smap = plan_shadow_map(tris, light, ShadowMapSettings(resolution=16))
    progress = list(render_shadow_map_steps(smap, tris))
    assert progress == sorted(progress) and progress[-1] == 1.0
    image = debug_image(smap)
    assert image.shape == (16, 96, 1) and image.dtype == np.float32
    assert image.min() == 0.0 and image.max() == 1.0
    assert np.all(image[:, 16 * 5 : 16 * 6] < 1.0)  # -Z face: all ground


def test_cube_faces_draw_only_what_reaches_them_and_miss_nothing():
    """Each cube face rasterises only the triangles that reach into its frustum, all six faces in
    one batch: the depth buffers equal those drawn from every triangle, face by face (random
    triangles all around the light); so do faces that do not share one array (drawn one by one)."""
    from dataclasses import replace

    from classic_bake.kernels.geometry.raster import rasterize
    from classic_bake.kernels.shadow.shadowmap import ShadowView

    rng = np.random.default_rng(7)
    centres = rng.normal(size=(300, 1, 3)) * 2.0
    tris = (centres + rng.normal(size=(300, 3, 3)) * 0.3).astype(np.float32)
    light = _light("POINT", position=(0.05, -0.1, 0.2))
    smap = plan_shadow_map(tris, light, ShadowMapSettings(resolution=64))
    apart = replace(smap, views=tuple(ShadowView(v.projection, v.depth.copy()) for v in smap.views))
    list(render_shadow_map_steps(smap, tris))
    list(render_shadow_map_steps(apart, tris))
    for view, alone in zip(smap.views, apart.views, strict=True):
        full = rasterize(tris, view.projection, 64, 64).depth
        assert np.array_equal(view.depth, full)
        assert np.array_equal(alone.depth, full)
        assert np.isfinite(full).any()  # every face sees something


def test_prepared_receivers_plan_and_look_up_as_the_arrays_do():
    """Receivers prepared once (columns, unit normals, bounds) give the sun the same fit and every
    light the same visibility as the (N, 3) arrays, and their box corners plan the same maps."""
    from classic_bake.kernels.shadow.depth_test import receivers_visibility
    from classic_bake.kernels.shadow.shadowmap import Receivers
    from classic_bake.kernels.shadow.views import fit_sun

    tris = np.concatenate([_quad((-2, -2, 0), (4, 0, 0), (0, 4, 0)),
                           _quad((-0.3, -0.2, 0.9), (0.5, 0, 0), (0, 0.6, 0.1))])
    pts, nrm = _ground_grid(1.5, 0.05)
    nrm = nrm * 3.0  # any length
    nrm[::7] = 0.0  # unknown normals
    prepared = Receivers.of(pts, nrm)
    assert np.array_equal(prepared.box, np.stack([pts.min(axis=0), pts.max(axis=0)]))
    sun = _sun(30.0, 20.0)
    a, b = fit_sun(tris, sun, prepared), fit_sun(tris, sun, pts)
    assert np.array_equal(a.basis, b.basis)
    assert [a.x0, a.x1, a.y0, a.y1, a.d0, a.d1] == pytest.approx([b.x0, b.x1, b.y0, b.y1, b.d0, b.d1],
                                                                abs=1e-12)
    for light in (sun, _light("SPOT", position=(0.2, 0.1, 3.0)), _light("POINT", position=(0, 0, 2))):
        smap = build_shadow_map(tris, light, ShadowMapSettings(resolution=128), pts)
        boxed = plan_shadow_map(tris, light, ShadowMapSettings(resolution=128), prepared.box,
                                fit_sun(tris, light, prepared) if light.kind == "SUN" else None)
        assert boxed.views[0].projection.far == smap.views[0].projection.far
        vis = shadow_visibility(smap, pts, nrm)
        assert np.array_equal(receivers_visibility(smap, prepared), vis)
        assert 0.0 < vis.mean() < 1.0  # a shadow falls


def test_receivers_from_parts_are_the_concatenated_receivers():
    """Parts read in place (a bake's objects, with an empty one among them) give the columns,
    normals, box and plan sample of their concatenation bit for bit; the sun's fit to them too."""
    from classic_bake.kernels.geometry.vec import COLUMN_BLOCK
    from classic_bake.kernels.shadow.shadowmap import Receivers
    from classic_bake.kernels.shadow.views import fit_sun

    rng = np.random.default_rng(11)
    sizes = (COLUMN_BLOCK + 5, 0, 37, 2 * COLUMN_BLOCK)  # parts across the conversion steps
    points = [rng.normal(size=(n, 3)) * [4.0, 2.0, 1.0] + [1.0, -3.0, 2.0] for n in sizes]
    normals = [rng.normal(size=(n, 3)) for n in sizes]
    normals[3][::5] = 0.0  # unknown normals
    parts = Receivers.of_parts(points, normals)
    whole = Receivers.of(np.concatenate(points), np.concatenate(normals))
    for name in ("local", "centre", "normals", "no_normal", "lo", "hi"):
        assert np.array_equal(getattr(parts, name), getattr(whole, name)), name
    for count in (1, 100, 4096, 10**6):
        assert np.array_equal(parts.sample(count), np.concatenate(points)[:: max(1, len(whole) // count)])
    tris = _quad((-2, -2, 3), (4, 0, 0), (0, 4, 0))
    sun = _sun(25.0, 40.0)
    a, b = fit_sun(tris, sun, parts), fit_sun(tris, sun, np.concatenate(points))
    assert [a.x0, a.x1, a.y0, a.y1, a.d0, a.d1] == pytest.approx([b.x0, b.x1, b.y0, b.y1, b.d0, b.d1],
                                                                abs=1e-12)
    with pytest.raises(ValueError, match="one normal per point"):
        Receivers.of_parts(points, normals[:3] + [normals[3][1:]])


def test_prepared_normals_are_unit_or_zero():
    """Receivers.of rescales normals of any length to unit, keeps unit normals bit for bit (they
    are not rescaled) and zero normals zero (flagged as unknown)."""
    from classic_bake.kernels.shadow.shadowmap import Receivers

    rng = np.random.default_rng(5)
    unit = rng.normal(size=(50, 3))
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    prepared = Receivers.of(np.zeros((50, 3)), unit)
    assert prepared.no_normal is None
    assert np.array_equal(prepared.normals, unit.T.astype(np.float32))
    scaled = unit * rng.uniform(0.1, 10.0, size=(50, 1))
    scaled[3] = 0.0
    prepared = Receivers.of(np.zeros((50, 3)), scaled)
    length = np.linalg.norm(prepared.normals.astype(np.float64), axis=0)
    assert length[3] == 0.0 and prepared.no_normal[3] and prepared.no_normal.sum() == 1
    assert np.delete(length, 3) == pytest.approx(1.0, abs=1e-6)


def test_threaded_lookup_matches_one_thread():
    """The lookup split over threads (equal shares of the receivers, any chunking) gives the same
    visibility as one thread, bit for bit, on every kind of map."""
    from classic_bake.kernels.shadow import depth_test as shadowmap

    tris = np.concatenate([_quad((-2, -2, 0), (4, 0, 0), (0, 4, 0)),
                           _quad((-0.3, -0.2, 0.9), (0.5, 0, 0), (0, 0.6, 0.1))])
    pts, nrm = _ground_grid(1.5, 0.01)  # 90k receivers: shares of more than MIN_THREAD_RECEIVERS
    assert len(pts) >= 2 * shadowmap.MIN_THREAD_RECEIVERS
    for light in (_sun(30.0, 20.0), _light("SPOT", position=(0.2, 0.1, 3.0)),
                  _light("POINT", position=(0, 0, 2))):
        one = build_shadow_map(tris, light, ShadowMapSettings(resolution=128, threads=1), pts)
        vis = shadow_visibility(one, pts, nrm)
        for threads, chunk in ((2, 1 << 16), (3, 1 << 12)):
            many = dataclasses.replace(one, settings=ShadowMapSettings(resolution=128, threads=threads))
            shadowmap_chunk = shadowmap.RECEIVER_CHUNK
            try:
                shadowmap.RECEIVER_CHUNK = chunk
                assert np.array_equal(shadow_visibility(many, pts, nrm), vis)
            finally:
                shadowmap.RECEIVER_CHUNK = shadowmap_chunk
        assert 0.0 < vis.mean() < 1.0
    with pytest.raises(ValueError, match="threads"):
        ShadowMapSettings(threads=-1)


@pytest.mark.parametrize("kind, pcf", [("SUN", 1), ("POINT", 1), ("SUN", 5)])
def test_partly_covering_casters_let_their_share_through(kind, pcf):
    """Two stacked veils (constant alpha 0.3 and 0.5) over a ground: the ground under both gets
    (1 - 0.3)(1 - 0.5) = 0.35 of the light, under the upper one alone 0.7, beside them 1; an
    opaque card (alpha 1) still casts a full shadow, and one of alpha 0 none. A cube map (a point
    lamp) as a sun's single view; PCF filters the veils as it does the depth test (the receivers
    lie texels away from any edge, so the figures hold)."""
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.shadow.cutouts import Cutout

    ground = _quad((0, 0, 0), (4, 0, 0), (0, 4, 0))
    upper = _quad((0, 0, 2.0), (1, 0, 0), (0, 1, 0))  # x in [-1, 1]
    lower = _quad((-0.5, 0, 1.0), (0.5, 0, 0), (0, 1, 0))  # x in [-1, 0]
    card = _quad((2.5, 0, 1.0), (0.5, 0, 0), (0, 1, 0))  # x in [2, 3]
    ghost = _quad((-2.5, 0, 1.0), (0.5, 0, 0), (0, 1, 0))  # x in [-3, -2]
    tris = np.concatenate([ground, upper, lower, card, ghost])
    alpha = np.repeat([1.0, 0.3, 0.5, 1.0, 0.0], 2)
    cut = Cutout(np.repeat([False, True, True, True, True], 2), lambda tri, bary: alpha[tri])
    light = (_light("SUN", direction=(0.0, 0.0, -1.0)) if kind == "SUN"
             else _light("POINT", position=(0.0, 0.0, 40.0)))
    points = np.array([[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0], [1.5, 0.0, 0.0], [2.5, 0.0, 0.0],
                       [-2.5, 0.0, 0.0]])
    settings = ShadowMapSettings(resolution=256, pcf_size=pcf)
    smap = plan_shadow_map(tris, light, settings, points)
    smap = drain(render_shadow_map_steps(smap, tris, cut))
    vis = shadow_visibility(smap, points, np.tile([0.0, 0.0, 1.0], (len(points), 1)))
    np.testing.assert_allclose(vis, [0.35, 0.7, 1.0, 0.0, 1.0], atol=1e-6)
