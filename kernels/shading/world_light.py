"""World light: the background (a colour or an equirectangular map) as a source at infinity,
for the radiosity solve.

Cycles lights every diffuse surface with its world: radiance L_w from each direction that meets no
geometry. A surface point x with normal n receives from it

    H_w(x) = L_w * integral over escaping w of cos(theta) dw = pi L_w s(x),

s(x) in [0, 1] the cosine-weighted share of its hemisphere open to the sky: 1 on an open floor, 1/2
at the foot of an endless wall, 0 inside a closed room. In an open scene s is 1 minus the patch's
row sum of form factors, but the backs of one-sided surfaces block the sky as well and carry no
factor, so s is found with rays, which meet faces from either side.

Estimator (Malley's method): points spread evenly over the unit disc, lifted onto the hemisphere,
are directions with density cos(theta) / pi, so the share of such rays that escape is s itself,
with no weights. Each patch casts `rays` of them from points spread over its triangle, the disc
points stratified on an m x m grid (jittered, a random rotation per patch), so a patch's s
carries little noise: under a plate (0.1 m patches, against 16384 rays each) 16, 64 and 256 rays
give s to 0.057, 0.024 and 0.0077 rms. Where the sky shows through an opening only, a patch that
saw it in part casts again with the rays its share needs (`world_irradiance`). Under a map, the
irradiance is the map's on an open surface, E(n) = integral of L max(n . w, 0) dw (tabulated over
normals once, `MappedWorld`), less pi times the mean radiance the blocked rays would have brought
from the map along their own directions: a control variate, so an open patch carries no noise
from the map's detail, and a shaded one only the noise of what is hidden. Rays start
a hair behind the surface and pass through its own triangle (`BVH.occluded(skip=)`), so a face
lying flat on another, a box's base on the floor, meets it at once as in Cycles, whose rays start
on the surface (lifted in front, they slipped past the floor into the sky below it).

A map's sun is the exception: a spot thousands of times brighter than its sky, which cosine rays
would find on a few patches only (blotches where Cycles, sampling the map by its brightness,
casts a sharp shadow). `extract_suns` takes such spots out of the map as sun lamps
(`radiosity.with_world_suns`), lit with shadow rays like any sun.

The solver carries H_w like the lamps' first shot (rho H_w is a source of every patch), and it
bounces on from there; the final gather treats it as indirect light, interpolated from the
patches (the sky's share changes on the scale of the geometry, as indirect light does), so no
receiver casts rays at the sky. What is left out: the sky's contact darkening finer than a patch,
and the backs of one-sided surfaces (their patches face one way).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..envmap.cubemap import BORDER, sample_bordered
from ..envmap.cubemap import texel_directions as cube_directions
from ..envmap.probe_lookup import bordered_level
from ..geometry.frames import RAY_OFFSET_REL, tangent_frames
from ..geometry.scene import Light, Scene, Texture
from ..measure.metrics import REC709_LUMINANCE
from .textures import sample_texture

# Rays per patch by default: s to 0.024 rms under a plate (module docstring), 0.1 s per 1.5k
# patches.
WORLD_RAYS = 64
# Relative rms noise of the sky's share aimed for where a patch sees it in part, and the rays a
# patch may cast for it (`world_irradiance`). A generated room lit by the sun and sky through a
# window (its walls see the sky in 2-10% of their view): texel relMSE against a 1024-sample Cycles
# bake 0.035 with 64 rays a patch, 0.0028 with 1024 everywhere.
WORLD_NOISE = 0.1
WORLD_MAX_RAYS = 1024
# A map texel this many times brighter than the map's mean luminance is part of a sun: a spot so
# small and bright that cosine rays would find it on a few patches only (a clear-sky HDRI's sun is
# 10^3-10^5 times its sky), so it is lit as a sun lamp instead (`extract_suns`).
SUN_CONTRAST = 50.0
# Bright texels within this angle of a sun's brightest texel belong to it (its disc and halo).
SUN_RADIUS = np.radians(5.0)
# Suns taken from one map at most (the brightest first); the rest stay in the map.
MAX_SUNS = 4
# The name every sun taken from a map starts with (then its rank).
WORLD_SUN_NAME = "world sun"
# A map's irradiance on an unoccluded surface, E(n) = integral of L(w) max(n . w, 0) dw, the map
# convolved with a cosine lobe: tabulated over normals on a cube of IRRADIANCE_FACE texels a side
# (3.75 degrees; E changes smoothly on that scale) by quadrature over an equirectangular grid of
# IRRADIANCE_GRID texels (rows, columns: 1.4 degrees), each the sum of IRRADIANCE_SUPERSAMPLE^2
# point samples of the map (a photographed map's detail is finer). `MappedWorld.irradiance`. On
# a photographed studio map (1560 x 780) against the full map's quadrature, 40 normals: within
# 0.4% (0.05% mean; 16-texel faces 0.7%, point samples alone 1%), built in ~1 s.
IRRADIANCE_FACE = 24
IRRADIANCE_GRID = (128, 256)
IRRADIANCE_SUPERSAMPLE = 4
# Grid texels per block of the quadrature: (6 F^2 normals x this) float64 weights, 50 MB.
IRRADIANCE_BLOCK = 4096
# Rays handed to the BVH at once (it reaches its full rate from about 50k): bounds the chunk's
# temporaries (`RAY_BYTES`).
RAYS_PER_CALL = 1 << 18
# Bytes a sky ray holds while its chunk is traced: origin, direction, point and disc coordinates
# (float64 triples and scalars), its skip id, answer and the BVH's copies and queues. Measured
# (tracemalloc peak of 20k patches, one full chunk): 580-680 B per ray at 16-256 rays per patch.
RAY_BYTES = 768


def sky_ray_bytes(patch_count: int, rays: int) -> int:
    """Peak bytes of `world_irradiance` over patch_count patches at `rays` each (one chunk, of
    the most rays a patch may cast again where it sees the sky in part)."""
    if rays <= 0:
        return 0
    k = max(_refined_rays(cosine_ray_count(rays)), default=cosine_ray_count(rays))
    return min(patch_count * k, max(RAYS_PER_CALL // k, 1) * k) * RAY_BYTES


def _refined_rays(k: int) -> list[int]:
    """The ray counts a patch that cast k and saw the sky in part may cast again with."""
    return [m for m in (4 * k, 16 * k) if m <= WORLD_MAX_RAYS]


def equirect_uv(dirs: np.ndarray) -> np.ndarray:
    """(N, 2) image UVs (v = 0 at the bottom row) of unit world directions (N, 3) on an
    equirectangular map, as Cycles' Environment Texture reads it (`direction_to_equirectangular`):
    u = 1/2 - atan2(y, x) / (2 pi) (+x at the centre, +y a quarter to the left), v = 1 -
    acos(z) / pi (+z at the top)."""
    d = np.asarray(dirs, np.float64)
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    u = 0.5 - np.arctan2(d[:, 1], d[:, 0]) / (2.0 * np.pi)
    v = 1.0 - np.arccos(np.clip(d[:, 2], -1.0, 1.0)) / np.pi
    return np.stack([u, v], axis=1)


def world_seen_by(scene: Scene, kind: str) -> Scene:
    """`scene` as rays of `kind` ("camera", "diffuse", "glossy", "transmission") see its world:
    black where Cycles hides the world from them (`Scene.world_hidden_from`), the camera's own
    map for camera rays where it has one (`Scene.camera_world`), else itself."""
    if kind not in scene.world_hidden_from:
        if kind == "camera" and scene.camera_world is not None:
            return replace(scene, world_texture=scene.camera_world, world_transform=None)
        return scene
    return replace(scene, world_color=np.zeros(3, np.float32), world_texture=None,
                   world_transform=None)


def world_lit(scene: Scene) -> bool:
    """Whether the world sends any light (a map's mean, `world_color`, is above 0 somewhere)."""
    return bool((np.asarray(scene.world_color) > 0.0).any())


def world_source(scene: Scene):
    """The world as `world_irradiance` takes it: the (3,) colour of a uniform world, else its map
    (`MappedWorld`)."""
    if scene.world_texture is None:
        return scene.world_color
    return MappedWorld(scene)


class MappedWorld:
    """A world map as `world_irradiance` takes it: called with (M, 3) unit directions, the
    radiance (M, 3) W/(m^2 sr) along them (`world_radiance`); `irradiance(normals)`, what a
    surface facing each normal receives from the whole map, W/m^2, so that rays need only find
    what the scene hides of it."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self._table: np.ndarray | None = None  # (6, F + 2B, F + 2B, 3) bordered cube of E(n)

    def __call__(self, dirs: np.ndarray) -> np.ndarray:
        return world_radiance(self.scene, dirs)

    def irradiance(self, normals: np.ndarray) -> np.ndarray:
        """(N, 3) unit normals -> (N, 3) float64 W/m^2: E(n) = integral of L(w) max(n . w, 0) dw
        over the whole map (no occlusion), bilinear in a cube table built on the first call
        (IRRADIANCE_FACE, IRRADIANCE_GRID): a quadrature over the grid's texels, each the power
        per unit area its point samples bring (radiance times solid angle, summed)."""
        if self._table is None:
            rows, cols = IRRADIANCE_GRID
            k = IRRADIANCE_SUPERSAMPLE
            fine, fine_omega = texel_directions(rows * k, cols * k)
            power = (world_radiance(self.scene, fine.reshape(-1, 3))
                     * fine_omega.reshape(-1, 1)).reshape(rows, k, cols, k, 3).sum(axis=(1, 3))
            dirs, _ = texel_directions(rows, cols)                              # (R, C, 3)
            dirs, power = dirs.reshape(-1, 3), power.reshape(-1, 3)             # power W/m^2
            normals_ = cube_directions(IRRADIANCE_FACE).reshape(-1, 3)          # (6 F^2, 3)
            table = np.zeros((len(normals_), 3))
            for a in range(0, len(dirs), IRRADIANCE_BLOCK):
                block = slice(a, a + IRRADIANCE_BLOCK)
                table += np.maximum(normals_ @ dirs[block].T, 0.0) @ power[block]
            self._table = bordered_level(table.reshape(6, IRRADIANCE_FACE, IRRADIANCE_FACE, 3))
        return sample_bordered(self._table, BORDER, np.asarray(normals, np.float64)
                               ).astype(np.float64)


def world_radiance(scene: Scene, dirs: np.ndarray) -> np.ndarray:
    """(N, 3) float64 radiance W/(m^2 sr) the world sends along -dirs, for unit directions (N, 3)
    away from the scene: its equirectangular map (`Scene.world_texture`, read along
    normalize(A d + t) where a Mapping node turns it, `Scene.world_transform`) where it has one,
    else the uniform `world_color`."""
    if scene.world_texture is None:
        return np.broadcast_to(np.asarray(scene.world_color, np.float64), (len(dirs), 3)).copy()
    dirs = np.asarray(dirs, np.float64)
    if scene.world_transform is not None:  # a Mapping node: A d + t, normalised by the look-up
        dirs = dirs @ scene.world_transform[:, :3].T + scene.world_transform[:, 3]
    return sample_texture(scene.world_texture, equirect_uv(dirs)).astype(np.float64)


def horizon_sky(scene: Scene, dirs: np.ndarray) -> np.ndarray:
    """(N, 3) `world_radiance` along unit directions dirs (N, 3), a map's above the horizon only
    (+Z up; 0 below, where the ground a scene stands on hides it), a uniform world's everywhere:
    what a rough lobe's rays are measured against (`glossy_lobe.lobe_mean`, the tracer's and
    `reflected_emitters`' control variate). Under the horizon a map's ground, often as bright
    as its sky, is what a scene's own ground blocks."""
    sky = world_radiance(scene, dirs)
    return sky if scene.world_texture is None else sky * (dirs[:, 2:3] > 0.0)


def texel_directions(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """(H, W, 3) unit map directions of an equirectangular map's texel centres (row 0 at the top,
    `equirect_uv`'s inverse) and (H, W) their solid angles, sr (they sum to 4 pi)."""
    rows, cols = np.mgrid[0:height, 0:width]
    dirs = _texel_directions(rows.ravel(), cols.ravel(), height, width).reshape(height, width, 3)
    return dirs, np.broadcast_to(_row_solid_angles(height, width)[:, None], (height, width)).copy()


def _row_solid_angles(height: int, width: int) -> np.ndarray:
    """(H,) the solid angle, sr, of one texel in each row of an equirectangular map (row 0 at
    the top): the band between the row's two latitudes over 2 pi / W of longitude."""
    v = 1.0 - (np.arange(height) + 0.5) / height  # image v of each row, 1 at the top
    return (2.0 * np.pi / width) * (np.cos(np.pi * (1.0 - v - 0.5 / height))
                                    - np.cos(np.pi * (1.0 - v + 0.5 / height)))


def _texel_directions(rows: np.ndarray, cols: np.ndarray, height: int, width: int) -> np.ndarray:
    """(N, 3) unit map directions of texels (rows, cols) (N,) of an H x W equirectangular map."""
    theta = (rows + 0.5) / height * np.pi  # from +z: v = 1 - theta / pi
    phi = (0.5 - (cols + 0.5) / width) * 2.0 * np.pi  # atan2(y, x): u = 1/2 - phi / (2 pi)
    return np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1)


def extract_suns(texture: Texture, transform: np.ndarray | None = None,
                 max_suns: int = MAX_SUNS) -> tuple[tuple[Light, ...], Texture]:
    """The suns of an equirectangular world map (radiance, linear), and the map without them.

    A texel SUN_CONTRAST times brighter than the map's mean luminance belongs to a sun; the
    brightest such texel and every bright one within SUN_RADIUS of it make one, up to `max_suns`.
    Each becomes a SUN `Light` (parallel, hard) of irradiance sum L dOmega over its texels (RGB,
    W/m^2 on a surface facing it) from their energy-weighted mean direction, and its texels are
    set to 0 in the returned map, so the sky rays carry the rest and the light is counted once.
    transform: the map's (3, 4) `Scene.world_transform` (read along normalize(A d + t)): the
    suns' world directions are A^-1 m (a translation t, which no direction inverts, keeps them
    in the map). A map with no texel that bright is returned as it is, with no sun."""
    pixels = np.asarray(texture.pixels)
    height, width = pixels.shape[:2]
    # Directions of the bright texels only (a 4k map is 8M texels, of which a sun holds a few
    # hundred).
    row_omega = _row_solid_angles(height, width)
    luminance = pixels[..., :3] @ np.asarray(REC709_LUMINANCE, np.float32)  # (H, W) float32
    mean = float(luminance.astype(np.float64).sum(axis=1) @ row_omega / (4.0 * np.pi))
    rows, cols = np.nonzero(luminance > SUN_CONTRAST * max(mean, 1e-300))
    if rows.size == 0 or (transform is not None and np.any(transform[:, 3] != 0.0)):
        return (), texture
    dirs = _texel_directions(rows, cols, height, width)
    rgb = pixels[rows, cols, :3].astype(np.float64)  # (B, 3) the bright texels
    omega = row_omega[rows]
    energy = luminance[rows, cols].astype(np.float64) * omega
    inverse = np.eye(3) if transform is None else np.linalg.inv(transform[:, :3])
    residual = pixels.astype(np.float32, copy=True)
    left = np.ones(rows.size, bool)
    suns = []
    while left.any() and len(suns) < max_suns:
        peak = int(np.argmax(np.where(left, energy, -1.0)))
        member = left & (dirs @ dirs[peak] >= np.cos(SUN_RADIUS))
        m = (dirs[member] * energy[member][:, None]).sum(axis=0)
        d = inverse @ (m / np.linalg.norm(m))
        d /= np.linalg.norm(d)
        irradiance = (rgb[member] * omega[member][:, None]).sum(axis=0)
        axis_x = np.cross([0.0, 0.0, 1.0], d) if abs(d[2]) < 0.9 else np.cross([1.0, 0.0, 0.0], d)
        axis_x /= np.linalg.norm(axis_x)
        suns.append(Light(name=f"{WORLD_SUN_NAME} {len(suns) + 1}", kind="SUN",
                          position=np.zeros(3),
                          direction=-d, axis_x=axis_x, axis_y=np.cross(-d, axis_x),
                          irradiance=irradiance))
        residual[rows[member], cols[member], :3] = 0.0
        left &= ~member
    return tuple(suns), replace(texture, pixels=residual)


def cosine_ray_count(rays: int) -> int:
    """The rays `cosine_directions` casts for `rays` asked: the next square, m x m strata."""
    m = int(np.ceil(np.sqrt(max(rays, 1))))
    return m * m


def cosine_directions(normals: np.ndarray, rays: int, rng: np.random.Generator) -> np.ndarray:
    """(P, k, 3) unit directions, cosine-distributed about each unit normal (P, 3), one in each
    of m x m strata of the unit square (k = m^2 = `cosine_ray_count(rays)`): Malley's method,
    disc points u1 -> radius sqrt(u1) (even over the disc), u2 -> angle, lifted onto the
    hemisphere; per normal a random rotation, so neighbouring receivers' strata do not line up.
    pi times the mean radiance along them estimates the irradiance."""
    k, p = cosine_ray_count(rays), len(normals)
    m = math.isqrt(k)
    u1 = (np.arange(k) // m + rng.random((p, k))) / m
    u2 = (np.arange(k) % m + rng.random((p, k))) / m + rng.random((p, 1))
    t1, t2 = tangent_frames(normals)
    return cosine_lift((t1[:, None], t2[:, None], normals[:, None]), u1, u2)


def cosine_lift(frame: tuple, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """(..., 3) unit directions cosine-distributed about the normals of `frame` (tangent,
    bitangent, normal: unit (..., 3) each, broadcast against the points) at points (u1, u2)
    (...) of the unit square: Malley's method, u1 -> radius sqrt(u1) (even over the disc), u2
    -> angle 2 pi u2, lifted onto the hemisphere."""
    t1, t2, n = frame
    radius, angle = np.sqrt(u1), 2.0 * np.pi * u2
    return ((radius * np.cos(angle))[..., None] * t1 + (radius * np.sin(angle))[..., None] * t2
            + np.sqrt(np.maximum(1.0 - u1, 0.0))[..., None] * n)


def _sky_rays(corners: np.ndarray, normals: np.ndarray, parents: np.ndarray, occluded,
              scale: float, rays: int, rng: np.random.Generator):
    """Yields (slice of patches, their ray directions (P, k, 3), escaped (P, k) bool): `rays`
    cosine-distributed rays per patch (module docstring), a chunk of patches at a time. corners
    (N, 3, 3): the rays leave from points spread over each triangle, just behind it (passing
    through its own triangle, `parents`); (N, 3): from those points, lifted in front of their
    surface (a receiver on a mesh edge would see its neighbour's plane from behind; a face lying
    on another is not seen, so no contact needs finding there)."""
    count = len(corners)
    parents = np.asarray(parents, np.int64)
    k = cosine_ray_count(rays)
    offset = RAY_OFFSET_REL * scale
    per_call = max(1, RAYS_PER_CALL // k)
    for a in range(0, count, per_call):
        c, n = corners[a:a + per_call], normals[a:a + per_call]
        p = len(c)
        dirs = cosine_directions(n, rays, rng)
        if c.ndim == 2:  # receivers: every ray from the point itself
            points = np.broadcast_to(c[:, None], (p, k, 3))
        else:  # uniform points of each triangle (the square root folds the square onto it)
            r1, r2 = np.sqrt(rng.random((p, k, 1))), rng.random((p, k, 1))
            points = ((1.0 - r1) * c[:, None, 0] + r1 * (1.0 - r2) * c[:, None, 1]
                      + r1 * r2 * c[:, None, 2])
        # Patches' rays start just BEHIND the surface and pass through its own triangle: a face
        # lying flat on another (a box's base on the floor) meets that one at once, as Cycles'
        # rays, which start on the surface, do; lifted in front of it they would slip past.
        side = 1.0 if c.ndim == 2 else -1.0
        origins = points + side * offset * n[:, None]
        skip = None if c.ndim == 2 else np.repeat(parents[a:a + p], k)
        hit = occluded(np.ascontiguousarray(origins.reshape(-1, 3)),
                       np.ascontiguousarray(dirs.reshape(-1, 3)), 0.0, np.inf, skip=skip)
        yield slice(a, a + p), dirs, ~np.asarray(hit, bool).reshape(p, k)


def sky_factors(corners: np.ndarray, normals: np.ndarray, parents: np.ndarray, occluded,
                scale: float, rays: int, rng: np.random.Generator) -> np.ndarray:
    """(N,) s in [0, 1]: the cosine-weighted share of each patch's hemisphere that meets no
    geometry (module docstring).

    | parameter | shape / range     | unit    | meaning                                         |
    |-----------|-------------------|---------|-------------------------------------------------|
    | corners   | (N, 3, 3)         | m world | the patches' triangles                          |
    | normals   | (N, 3) unit       |         | their front normals (the hemisphere's pole)     |
    | parents   | (N,) int          |         | each patch's scene triangle, which its rays     |
    |           |                   |         | pass through                                    |
    | occluded  | callable          |         | (origins, dirs, t_min, t_max, skip=) -> (R,)    |
    |           |                   |         | bool: the BVH's any-hit query (`BVH.occluded`)  |
    | scale     | > 0               | m       | the scene's extent: rays start RAY_OFFSET_REL x |
    |           |                   |         | scale off the surface                           |
    | rays      | >= 1 (WORLD_RAYS) |         | rays per patch, rounded up to a square m x m    |
    | rng       |                   |         | jitter, rotations and points                    |
    """
    return _world_estimate(np.ones(3), np.asarray(corners, np.float64),
                           np.asarray(normals, np.float64), parents, occluded, scale, rays,
                           rng)[1]


def _world_estimate(world, corners: np.ndarray, normals: np.ndarray, parents: np.ndarray,
                    occluded, scale: float, rays: int, rng: np.random.Generator
                    ) -> tuple[np.ndarray, np.ndarray]:
    """((N, 3) each patch's irradiance from the world, W/m^2; (N,) the share s of its rays that
    escape), from `rays` rays each (`_sky_rays`): pi x the mean radiance its escaping rays bring;
    with a world that knows its unoccluded irradiance E(n) (`MappedWorld`), E(n) less pi x the
    mean its blocked rays would have brought (the same expectation, and no noise where nothing
    blocks the sky: a map's detail no longer shows as patch-to-patch blotches)."""
    out = np.zeros((len(corners), 3))
    share = np.zeros(len(corners))
    uniform = not callable(world)
    whole = getattr(world, "irradiance", None)
    for rows, dirs, escaped in _sky_rays(corners, normals, parents, occluded, scale, rays, rng):
        share[rows] = escaped.mean(axis=1)
        if uniform:
            out[rows] = np.pi * share[rows, None] * np.asarray(world, np.float64)
            continue
        if whole is None:
            seen = np.zeros(escaped.shape + (3,))
            seen[escaped] = world(dirs[escaped])
            out[rows] = np.pi * seen.mean(axis=1)
            continue
        hidden = np.zeros(escaped.shape + (3,))
        hidden[~escaped] = world(dirs[~escaped])
        out[rows] = np.maximum(whole(normals[rows]) - np.pi * hidden.mean(axis=1), 0.0)
    return out, share


def world_irradiance(world, corners: np.ndarray, normals: np.ndarray, parents: np.ndarray,
                     occluded, scale: float, rays: int, rng: np.random.Generator,
                     budget: int | None = None) -> np.ndarray:
    """(N, 3) W/m^2: the world's irradiance on each patch, pi times the mean radiance of its
    cosine-distributed rays that escape (0 for those that meet geometry): pi L_w s for a uniform
    world. world: its radiance, a (3,) colour W/(m^2 sr) or a callable (M, 3) directions ->
    (M, 3) radiance (a map's `MappedWorld`, whose `irradiance` makes the estimate its open
    irradiance less what the blocked rays hide, `_world_estimate`); the rest as `sky_factors`, except that
    corners may also be points (N, 3), each ray leaving from its point (receivers rather than
    patches). Zero, with no ray cast, for a black colour or rays = 0.

    Where the sky shows through an opening, `rays` find it on a few rays only: a wall of a room
    lit through a window sees the sky in ~2-10% of its view, s from 64 rays then carries 30-70%
    noise, and patch-to-patch blotches. Patches whose first `rays` found the sky in part (0 < s
    < 1, or none where other patches found it) are cast again with the rays a binomial s needs
    for WORLD_NOISE relative noise, 4x or 16x `rays` (within WORLD_MAX_RAYS), and take that
    estimate alone (the first decided only how many). `budget`: the most rays those second casts
    take in all (None: no limit): over it, the patches cast 4x `rays` only, the noisiest
    first, as many as it pays for (a mesh of tens of thousands of tiny patches, each seeing
    sky in part, would cast millions; the gather's corners average neighbours' noise there)."""
    corners = np.asarray(corners, np.float64)
    normals = np.asarray(normals, np.float64)
    parents = np.asarray(parents, np.int64)
    count = len(corners)
    if rays <= 0 or count == 0 or (not callable(world) and not (np.asarray(world) > 0.0).any()):
        return np.zeros((count, 3))
    out, share = _world_estimate(world, corners, normals, parents, occluded, scale, rays, rng)
    if not (share > 0.0).any():  # nothing sees the sky: a closed room
        return out
    k = cosine_ray_count(rays)
    wanted = (1.0 - share) / (np.maximum(share, 1.0 / k) * WORLD_NOISE**2)
    steps = _refined_rays(k)
    refine = (share < 1.0) & (wanted > k)
    if steps and refine.any():
        again = np.where(wanted > steps[0], steps[-1], steps[0])
        if budget is not None and again[refine].sum() > budget:
            again[:] = steps[0]
            noisiest = np.flatnonzero(refine)[np.argsort(-wanted[refine], kind="stable")]
            refine[noisiest[budget // steps[0]:]] = False
        for m in steps:
            rows = np.flatnonzero(refine & (again == m))
            if rows.size:
                out[rows] = _world_estimate(world, corners[rows], normals[rows], parents[rows],
                                            occluded, scale, m, rng)[0]
    return out
