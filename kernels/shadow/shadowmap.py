"""Shadow mapping: the lecture's two-pass z-buffer shadow test, with the usual cures for its flaws.

The lecture (lecture 13, "4. Shadow Mapping"; L. Williams, "Casting curved shadows on curved
surfaces", SIGGRAPH 1978):
  1. Put the viewer at the light position L and render the scene into a z-buffer: the shadow map M.
  2. For each receiver point f, with depth z_f seen from L at map pixel p: f is lit when
     |z_f - M_p| <= eps ("test case (b) first": the tolerance against self-shadowing) or
     z_f <= M_p; otherwise f is shadowed.

Depth is the linear view depth in metres (see `raster.py`), so eps is a world distance.

Per light kind (`scene.Light`):
* SUN: orthographic, along `direction`. The frustum is fitted to what can matter ("model no more
  than needed"): laterally, the receivers' bounds (the receivers extruded towards the light)
  intersected with the bounds of the casters inside that prism; in depth, from the nearest such
  caster to the farthest receiver. Texels are square: the longer side gets `resolution` texels.
* SPOT: perspective from `position` along `direction` over the full cone angle `spot_size`. A cone
  wider than SPOT_CUBE_ANGLE is mapped with the six cube faces instead (a single perspective map
  would spend its texels on the rim).
* POINT (and AREA, approximated by a point at its centre: hard shadows): six 90-degree faces in the
  OpenGL cube-map convention of `cubemap.py`; each face stores the view depth |ma| of the table.
The light's `radius` / area is ignored: shadow maps give hard shadows.

Tolerance (bias). With texel(f) the side and h(f) the half diagonal of a texel's footprint at f
(ORTHO: in metres; PERSP: at f's view depth d, a texel's footprint there being at most d times its
size on the unit image plane), theta the angle between f's normal and the direction to the light,
and a k x k PCF block:

    fixed: eps(f) = eps + slope_bias * texel(f) * tan(theta)
    auto:  eps(f) = fixed eps(f) + k * h(f) * tan(theta) + DEPTH_PRECISION_REL * (|z_f| + |f|_inf)

The fixed form is Direct3D's depth bias "DepthBias + SlopeScaledDepthBias * MaxDepthSlope" in world
units (MaxDepthSlope = texel * tan(theta), the depth change across one texel; OpenGL's
glPolygonOffset(factor, units) is the same idea). The auto term is the minimum bias of
tests/data/shadow_bias.json: a planar receiver may sit anywhere in its texel, up to half
a texel diagonal from the centre where M was sampled, where its plane's depth differs by at most
h * tan(theta) (k * h for the farthest texel of a k x k PCF block); plus float32 precision (the
reference's r_min is 2^-24 relative; the position term covers float32 receivers and vertices).
tan(theta) is capped at TAN_THETA_MAX.
Normal offset (D. Holbert, "Normal Offset Shadows", GDC 2011): f moves normal_offset texels along
its normal (turned towards the light) before it is projected. One texel removes the acne of planar
receivers at any angle: the moved point stands texel / cos(theta) in front of its plane along the
light, more than the h * tan(theta) by which the plane varies within a texel.
Percentage-closer filtering (Reeves, Salesin and Cook 1987): the lecture's test on the k x k texels
around p, averaged; the neighbours are clamped to the map (to the face, for cube maps).

Receivers outside every map (beyond a fitted sun frustum, outside a spot cone, behind a spot) are
reported lit: no caster was recorded for them; the spot cone's own falloff is the shading's job.
Receivers whose normal faces away from the light (N.L < 0) are in their attached shadow and get 0
(`shadow_back_faces`): testing them would only trade acne for light leaking through thin walls
near the terminator, where tan(theta) and so the tolerance grow without bound. Pass geometric
(face) normals: smooth shading normals can under-state a facet's slope.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..envmap import cubemap
from ..geometry import threads
from ..geometry.raster import Projection, look_at, rasterize_steps, rasterize_views_steps
from ..geometry.scene import Light
from ..geometry.vec import bounds, cross3, max_of_three, min_of_three, row_norms

EpsMode = Literal["fixed", "auto"]
MapKind = Literal["ORTHO", "PERSP", "CUBE"]

TAN_THETA_MAX = 20.0  # caps the slope terms at ~87 degrees, where N.L < 0.05 dims the light anyway
DEPTH_PRECISION_REL = 2.0**-21  # 8 half-ulps of float32: stored depth and float32 positions
SPOT_CUBE_ANGLE = np.radians(120.0)  # wider spot cones use the six-face cube map
DEPTH_MARGIN_REL = 1e-3  # of the depth range: keeps fitted near/far planes off the geometry
DEPTH_MARGIN_ABS = 1e-4  # m, the same for scenes of zero depth range
NEAR_REL = 1e-6  # PERSP near plane as a fraction of far: linear depth loses no precision for it
EDGE_ON_COS = 1e-3  # |cos| between a caster's normal and the light below this: seen edge-on
MIN_EXTENT_REL = 1e-6  # a fitted sun map is at least this fraction of the scene size across
TINY = np.float32(1e-30)  # guards divisions by cos(theta) = 0: far below any real cosine, and
#                          the quotient is capped at TAN_THETA_MAX anyway
UNIT_LENGTH2_TOL = 1e-6  # |n|^2 this close to 1 is unit for the tolerance's slopes: a relative
#                          error of 5e-7 in cos(theta), below float32 rounding of the products
RECEIVER_CHUNK = 1 << 16  # receivers per vectorised lookup step: ~20 MB of temporaries (per thread)
# Fewer receivers than this per thread are looked up on one: a thread's share must outweigh the
# GIL hand-offs of its NumPy calls. On this 2-core machine, 255k receivers: 2 threads gained 1.3-2.7
# ms per light on a map looked up again and again, nothing with 32k-receiver shares, and inside a
# whole light (after its raster, 15 runs each, interleaved) the median got 0.5-1.2 ms worse: hence
# one thread by default.
MIN_THREAD_RECEIVERS = 1 << 15


@dataclass(frozen=True)
class ShadowMapSettings:
    """How the shadow map is made and read.

    | field         | range           | default | unit / meaning                                  |
    |---------------|-----------------|---------|-------------------------------------------------|
    | resolution    | [8, 16384]      | 2048    | texels along the map's longer side (per face)   |
    | eps_mode      | "fixed", "auto" | "auto"  | auto adds the minimum bias of shadow_bias.json  |
    | eps           | [0, inf)        | 0.0     | m, the lecture's constant tolerance             |
    | slope_bias    | [0, inf)        | 0.0     | texels of depth slope added (Direct3D's slope-  |
    |               |                 |         | scaled depth bias, in world units)              |
    | normal_offset | [0, inf)        | 0.0     | texels: receivers move along their normal       |
    | pcf_size      | odd, [1, 15]    | 1       | k: k x k percentage-closer filtering (1: off)   |
    | shadow_back_  | bool            | True    | receivers whose normal faces away from the light|
    |   faces       |                 |         | (N.L < 0) are shadowed, as N.L shading and      |
    |               |                 |         | Cycles' SHADOW bake have it; False: tested      |
    | threads       | >= 0            | 1       | lookup threads; 0: one per CPU core (see        |
    |               |                 |         | MIN_THREAD_RECEIVERS for when they pay)         |
    """

    resolution: int = 2048
    eps_mode: EpsMode = "auto"
    eps: float = 0.0
    slope_bias: float = 0.0
    normal_offset: float = 0.0
    pcf_size: int = 1
    shadow_back_faces: bool = True
    threads: int = 1

    def __post_init__(self) -> None:
        if not 8 <= self.resolution <= 16384:
            raise ValueError(f"resolution {self.resolution} outside [8, 16384]")
        if self.eps_mode not in ("fixed", "auto"):
            raise ValueError(f"eps_mode must be 'fixed' or 'auto', got {self.eps_mode!r}")
        if min(self.eps, self.slope_bias, self.normal_offset) < 0.0:
            raise ValueError("eps, slope_bias and normal_offset must be >= 0")
        if self.pcf_size < 1 or self.pcf_size % 2 == 0 or self.pcf_size > 15:
            raise ValueError(f"pcf_size must be odd in [1, 15], got {self.pcf_size}")
        if self.threads < 0:
            raise ValueError(f"threads must be >= 0, got {self.threads}")

    @property
    def thread_count(self) -> int:
        return self.threads or os.cpu_count() or 1


@dataclass(frozen=True, eq=False)
class ShadowView:
    """One rendered view of the light: its projection and its z-buffer."""

    projection: Projection
    depth: np.ndarray  # (H, W) float32, linear view depth from the light (m), +inf: nothing

    @property
    def texel_size(self) -> tuple[float, float]:
        """Texel (width, height): metres (ORTHO) or on the image plane at distance 1 (PERSP)."""
        left, right, bottom, top = self.projection.extent
        height, width = self.depth.shape
        return (right - left) / width, (top - bottom) / height


@dataclass(frozen=True, eq=False)
class ShadowMap:
    """The shadow map of one light: one view (SUN, SPOT) or six cube faces (CUBE, face order)."""

    kind: MapKind
    views: tuple[ShadowView, ...]
    light_position: np.ndarray  # (3,) float64, world m (the sun: its map's eye)
    light_direction: np.ndarray  # (3,) float64, world unit: where the light points
    settings: ShadowMapSettings


# --------------------------------------------------------------------------------------------
# Planning: which views, fitted to what
# --------------------------------------------------------------------------------------------


def _frame(light: Light) -> tuple[np.ndarray, np.ndarray]:
    """(forward, up) unit float64 of the light: up is axis_y made orthogonal to forward."""
    forward = np.asarray(light.direction, np.float64)
    forward = forward / np.linalg.norm(forward)
    up = np.asarray(light.axis_y, np.float64)
    up = up - forward * (up @ forward)
    if np.linalg.norm(up) < 1e-6:  # a broken axis_y: any perpendicular will do
        up = cross3(forward, [1.0, 0.0, 0.0] if abs(forward[0]) < 0.9 else [0.0, 1.0, 0.0])
    return forward, up / np.linalg.norm(up)


def _margin(lo: float, hi: float) -> float:
    return DEPTH_MARGIN_REL * max(hi - lo, 0.0) + DEPTH_MARGIN_ABS


def _nearest_in_prism(tris: np.ndarray, rect: tuple[float, float, float, float]) -> float:
    """Smallest light-space depth of (T, 3, 3) light-space triangles inside the prism over `rect`.

    A lower bound, per triangle the larger of its nearest vertex and its plane's minimum over the
    rectangle's corners (depth is affine over the rectangle): a huge ground plane seen slantwise
    contributes the depth it has above the receivers, not the depth of its far corners.
    """
    nearest = min_of_three(tris[..., 2])
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])  # (T, 3) light space
    slanted = np.abs(n[:, 2]) > EDGE_ON_COS * row_norms(n)
    if slanted.any():
        x0, x1, y0, y1 = rect
        corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]])  # (4, 2)
        v0, ns = tris[slanted, 0], n[slanted]
        # plane: n . (p - v0) = 0  ->  depth = v0_z - (n_x (x - v0_x) + n_y (y - v0_y)) / n_z
        dx = corners[None, :, 0] - v0[:, 0:1]
        dy = corners[None, :, 1] - v0[:, 1:2]
        plane = v0[:, 2:3] - (ns[:, 0:1] * dx + ns[:, 1:2] * dy) / ns[:, 2:3]  # (T', 4)
        lowest = np.minimum(np.minimum(plane[:, 0], plane[:, 1]), np.minimum(plane[:, 2], plane[:, 3]))
        nearest[slanted] = np.maximum(nearest[slanted], lowest)
    return float(nearest.min())


@dataclass(frozen=True)
class SunFit:
    """A sun map's frustum in light space (x right, y up, depth along the light), metres."""

    basis: np.ndarray  # (3, 3) rows: light-space x, y, depth in world coordinates
    x0: float
    x1: float
    y0: float
    y1: float
    d0: float  # nearest caster that matters
    d1: float  # farthest receiver
    scene_size: float

    @property
    def span(self) -> float:
        """The fitted map's longer side, m."""
        return max(self.x1 - self.x0, self.y1 - self.y0, 0.0)


def _fit_sun(tris: np.ndarray, receivers: np.ndarray | Receivers, light: Light) -> SunFit:
    forward, up = _frame(light)
    right = cross3(forward, up)
    basis = np.stack([right, up, forward])  # rows: light-space x, y, depth
    verts = tris.reshape(-1, 3).astype(np.float64) @ basis.T  # (3T, 3) light space, m
    if isinstance(receivers, Receivers):  # light space of (3, N) columns: contiguous reductions
        recv = basis @ receivers.positions
        r_lo, r_hi = recv.min(axis=1), recv.max(axis=1)
    else:
        r_lo, r_hi = bounds(receivers @ basis.T)  # (N, 3) light space, m
    if len(verts):
        v_lo, v_hi = bounds(verts)
        scene_size = float((np.maximum(r_hi, v_hi) - np.minimum(r_lo, v_lo)).max())
    else:
        scene_size = 0.0
    # Casters that can shadow a receiver: inside the receivers' prism extruded towards the light.
    corners = verts.reshape(-1, 3, 3)
    lo, hi = min_of_three(corners), max_of_three(corners)  # (T, 3)
    relevant = ((hi[:, 0] >= r_lo[0]) & (lo[:, 0] <= r_hi[0]) & (hi[:, 1] >= r_lo[1])
                & (lo[:, 1] <= r_hi[1]) & (lo[:, 2] <= r_hi[2]))
    if relevant.any():
        c_lo, c_hi = bounds(lo[relevant])[0], bounds(hi[relevant])[1]
        x0, x1 = max(r_lo[0], c_lo[0]), min(r_hi[0], c_hi[0])
        y0, y1 = max(r_lo[1], c_lo[1]), min(r_hi[1], c_hi[1])
        d0 = _nearest_in_prism(corners[relevant], (x0, x1, y0, y1))
    else:  # nothing can shadow: an empty map over the receivers
        x0, x1, y0, y1, d0 = r_lo[0], r_hi[0], r_lo[1], r_hi[1], r_lo[2]
    return SunFit(basis, x0, x1, y0, y1, d0, max(r_hi[2], d0), scene_size)


def fit_sun(triangles: np.ndarray, light: Light, receivers: np.ndarray | Receivers) -> SunFit:
    """The frustum `plan_shadow_map` fits a sun's map to, for these casters and receivers ((N, 3)
    world m, or prepared)."""
    tris = np.asarray(triangles, np.float32).reshape(-1, 3, 3)
    if not isinstance(receivers, Receivers):
        receivers = np.asarray(receivers, np.float64).reshape(-1, 3)
    return _fit_sun(tris, receivers, light)


def _plan_sun(tris: np.ndarray, receivers: np.ndarray, light: Light,
              settings: ShadowMapSettings, fit: SunFit | None) -> ShadowMap:
    fit = fit or _fit_sun(tris, receivers, light)
    forward, up = _frame(light)
    basis, x0, x1, y0, y1, d0, d1 = fit.basis, fit.x0, fit.x1, fit.y0, fit.y1, fit.d0, fit.d1
    scene_size = fit.scene_size
    # Square texels: the longer side gets `resolution` texels minus a border for the PCF block and
    # the normal offset, plus one texel.
    pad = settings.pcf_size // 2 + int(np.ceil(settings.normal_offset)) + 1
    span = max(x1 - x0, y1 - y0, MIN_EXTENT_REL * scene_size, 1e-9)
    texel = span / (settings.resolution - 2 * pad)
    width = min(settings.resolution, int(np.ceil(max(x1 - x0, 0.0) / texel - 1e-9)) + 2 * pad)
    height = min(settings.resolution, int(np.ceil(max(y1 - y0, 0.0) / texel - 1e-9)) + 2 * pad)
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    half_w, half_h = 0.5 * width * texel, 0.5 * height * texel
    margin = _margin(d0, d1)
    eye_depth = d0 - 2.0 * margin  # the eye sits just before the nearest caster: small depths
    eye = basis.T @ np.array([cx, cy, eye_depth])
    projection = Projection.orthographic(
        look_at(eye, forward, up), (-half_w, half_w, -half_h, half_h), margin,
        d1 - eye_depth + margin,
    )
    view = ShadowView(projection, np.full((height, width), np.inf, np.float32))
    return ShadowMap("ORTHO", (view,), eye, forward, settings)


def _far_from(position: np.ndarray, tris: np.ndarray, receivers: np.ndarray) -> float:
    """Farthest receiver (or vertex, without receivers) from the light, m, with a margin."""
    pts = receivers if len(receivers) else tris.reshape(-1, 3).astype(np.float64)
    if len(pts) == 0:
        return 1.0 + _margin(0.0, 1.0)
    # The farthest corner of the points' box: at most its diagonal beyond the farthest point (the
    # far plane only bounds the depth range), and O(N) column passes instead of N norms.
    lo, hi = bounds(pts)
    far = float(np.linalg.norm(np.maximum(np.abs(lo - position), np.abs(hi - position))))
    return far + _margin(0.0, far)


def plan_shadow_map(
    triangles: np.ndarray,
    light: Light,
    settings: ShadowMapSettings | None = None,
    receivers: np.ndarray | None = None,
    sun_fit: SunFit | None = None,
) -> ShadowMap:
    """Choose and fit the views of `light`'s shadow map; their depth buffers start at +inf.

    `receivers` (N, 3) world m are the points that will be looked up: the sun's map is fitted to
    them and every map's far plane stops behind them. Without them, the whole scene is covered.
    `sun_fit`: `fit_sun` of the same triangles, light and receivers, when the caller has it;
    with it, only the receivers' bounding box matters (its two corners may stand in for them).
    """
    settings = settings or ShadowMapSettings()
    tris = np.asarray(triangles, np.float32).reshape(-1, 3, 3)
    if receivers is None or len(receivers) == 0:
        recv = tris.reshape(-1, 3).astype(np.float64)
    else:
        recv = np.asarray(receivers, np.float64).reshape(-1, 3)
    if len(recv) == 0:
        recv = np.zeros((1, 3))
    if light.kind == "SUN":
        return _plan_sun(tris, recv, light, settings, sun_fit)
    position = np.asarray(light.position, np.float64)
    forward, up = _frame(light)
    far = _far_from(position, tris, recv)
    near = NEAR_REL * far
    res = settings.resolution
    if light.kind == "SPOT" and light.spot_size <= SPOT_CUBE_ANGLE:
        projection = Projection.perspective(look_at(position, forward, up), light.spot_size,
                                            near, far)
        view = ShadowView(projection, np.full((res, res), np.inf, np.float32))
        return ShadowMap("PERSP", (view,), position, forward, settings)
    if light.kind not in ("POINT", "SPOT", "AREA"):
        raise ValueError(f"unknown light kind {light.kind!r}")
    faces = np.full((6, res, res), np.inf, np.float32)  # one array: lookups gather across faces
    views = tuple(ShadowView(cubemap.face_projection(f, position, near, far), faces[f])
                  for f in range(6))
    return ShadowMap("CUBE", views, position, forward, settings)


def render_shadow_map_steps(shadow_map: ShadowMap, triangles: np.ndarray) -> Iterator[float]:
    """Step 1 of the lecture: z-buffer (T, 3, 3) world triangles into every view; yield progress.

    Draws into the planned buffers as they are (a fresh plan holds +inf): rendering more
    triangles into the same map depth-tests them against what is there."""
    # The planned buffers start at +inf: no second clearing pass over the map.
    if shadow_map.kind != "CUBE":
        yield from rasterize_steps(triangles, shadow_map.views[0].projection,
                                   shadow_map.views[0].depth, clear=False)
        return
    reach = _reaches_faces(triangles, shadow_map.light_position)  # (6, T): a face draws these
    stacked = _shared_depth(shadow_map)  # planned maps: the faces share one (6, H, W) array
    if stacked is not None:
        # All faces in one batch: one set-up and one pass of spans (point light of the
        # bench: 3 faces drawn, 14 -> 10.5 ms, bit for bit the same maps).
        face, tri = np.nonzero(reach)
        yield from rasterize_views_steps(triangles[tri], face,
                                         tuple(v.projection for v in shadow_map.views), stacked)
        return
    for k, view in enumerate(shadow_map.views):
        for progress in rasterize_steps(triangles[reach[k]], view.projection, view.depth,
                                        clear=False):
            yield (k + progress) / len(shadow_map.views)


def _reaches_faces(triangles: np.ndarray, position: np.ndarray) -> np.ndarray:
    """(6, T) bool: triangles not wholly outside one side plane of each cube face's frustum.

    Inside a face's 90-degree frustum the major component ma = F . d is at least |U . d| and
    |V . d| (d = p - L); a triangle whose three vertices all break the same one of these four
    half-spaces (or all lie behind the eye) covers no texel of the face, and the rasteriser would
    only clip it away.
    """
    d = np.asarray(triangles, np.float64) - position  # (T, 3, 3) from the light, m
    ma = d @ cubemap.FACE_FORWARD.T  # (T, 3, 6): per vertex, per face
    sc = d @ cubemap.FACE_U.T
    tc = d @ cubemap.FACE_V.T
    outside = min_of_three(ma <= 0.0)  # (T, 6): all three corners (the minimum of booleans)
    for side in (ma - sc, ma + sc, ma - tc, ma + tc):
        outside |= min_of_three(side < 0.0)
    return ~outside.T


# A receiver this close to a triangle's plane (relative to the scene's size) counts as on it, so
# it cannot be shadowed by that plane: the floor's own texels do not keep the floor in its map.
CASTER_PLANE_EPS = 1e-6


def potential_casters(triangles: np.ndarray, light: Light, receivers: np.ndarray) -> np.ndarray:
    """(T,) bool: triangles that may shadow some receiver; the others need not enter the map.

    A triangle only blocks light towards points on the far side of its plane from the light. If
    all eight corners of the receivers' bounding box lie on the light's side of the plane (or on
    it), no receiver can be behind it: culling it changes no visibility, only the work. Exact,
    conservative (a box corner may be behind while no receiver is) and O(T).
    """
    tris = np.asarray(triangles, np.float64)
    if len(tris) == 0:
        return np.zeros(0, bool)
    pts = np.asarray(receivers, np.float64).reshape(-1, 3)
    lo, hi = bounds(pts)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])  # (8, 3)
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    length = row_norms(n)
    keep = length > 0.0
    n = n / np.where(length > 0.0, length, 1.0)[:, None]
    if light.kind == "SUN":
        toward = np.broadcast_to(-np.asarray(light.direction, np.float64), n.shape)
    else:
        toward = np.asarray(light.position, np.float64) - tris[:, 0]
    # Orient each plane normal towards the light; a plane through the light blocks nothing.
    side = np.einsum("ij,ij->i", n, toward)
    n = n * np.sign(side)[:, None]
    keep &= side != 0.0
    scale = max(float(np.abs(np.concatenate([lo, hi])).max()), 1.0)
    behind = (corners @ n.T) - np.einsum("ij,ij->i", n, tris[:, 0])[None, :]  # (8, T)
    return keep & np.any(behind < -CASTER_PLANE_EPS * scale, axis=0)


def build_shadow_map(
    triangles: np.ndarray,
    light: Light,
    settings: ShadowMapSettings | None = None,
    receivers: np.ndarray | None = None,
) -> ShadowMap:
    """Plan and render `light`'s shadow map of (T, 3, 3) world triangles (see `plan_shadow_map`).

    With `receivers` given, triangles that cannot shadow any of them are left out first
    (`potential_casters`): a floor under everything is never drawn into its own map.
    """
    if receivers is not None and len(receivers):
        triangles = triangles[potential_casters(triangles, light, receivers)]
    shadow_map = plan_shadow_map(triangles, light, settings, receivers)
    for _ in render_shadow_map_steps(shadow_map, triangles):
        pass
    return shadow_map


# --------------------------------------------------------------------------------------------
# Lookup: step 2 of the lecture
# --------------------------------------------------------------------------------------------


def _texel_sides(view: ShadowView) -> tuple[float, float]:
    """(texel side, half texel diagonal) of a view: metres (ORTHO) or at view depth 1 (PERSP)."""
    tw, th = view.texel_size
    return max(tw, th), 0.5 * float(np.hypot(tw, th))


def depth_tolerance(
    view: ShadowView,
    settings: ShadowMapSettings,
    depth: np.ndarray,
    tan_theta: np.ndarray,
    position_size: np.ndarray | float | None = None,
) -> np.ndarray:
    """The lecture's eps for receivers at view `depth` (N,) m with slopes `tan_theta` (N,).

    (N,) metres, the formulas of the module docstring, in the dtype of `tan_theta`;
    `position_size` (N,) or scalar m, the receivers' largest |world coordinate| (or a bound on it),
    feeds the float32-position part of the precision term (omitted when None).
    """
    texel, half_diag = _texel_sides(view)
    if view.projection.kind == "PERSP":  # a texel's footprint grows with the view depth
        slope_depth = tan_theta * np.abs(depth)
    else:
        slope_depth = tan_theta
    auto = settings.eps_mode == "auto"
    # One product for both slope terms (the automatic one: PCF's reach of half texel diagonals);
    # a constant eps of 0, the default, costs no pass.
    eps = (settings.slope_bias * texel + (settings.pcf_size * half_diag if auto else 0.0)) * slope_depth
    if settings.eps:
        eps += settings.eps
    if auto:
        scale = np.abs(depth)
        if position_size is not None:
            scale = scale + position_size
        eps += DEPTH_PRECISION_REL * scale
    return eps


# The lookup works on columns: (3, N) arrays of x, y, z rows. On (N, 3) arrays NumPy loops over
# rows of three, and adding a (3,) vector to 65,536 points took 1.8 ms against 0.1 ms for the
# matrix product itself; each column operation costs ~20 us per 65,536 receivers.


@dataclass(frozen=True)
class _Lookup:
    """Where receivers meet a shadow map: every array (N,), receivers in their given order."""

    col: np.ndarray  # float32 continuous texel column in the receiver's view
    row: np.ndarray  # continuous texel row (row 0 at the top)
    depth: np.ndarray  # float32 linear view depth z_f, m
    ahead: np.ndarray | None  # bool, in front of a perspective view's eye (None: ORTHO, cube)
    face: np.ndarray | None  # int64 cube face per receiver (CUBE), None for a single view
    nl: np.ndarray  # float32 signed cos(theta): normal . unit direction to the light
    slope: np.ndarray  # float32 depth slope standing in for tan(theta), capped at TAN_THETA_MAX


def _tan_from_cos(cos_t: np.ndarray) -> np.ndarray:
    """tan(theta) from |cos(theta)| (N,), capped at TAN_THETA_MAX (also where cos = 0)."""
    sin_t = np.sqrt(np.maximum(1.0 - cos_t * cos_t, 0.0))
    # sin <= 1, so sin / max(cos, 1 / cap) <= the cap unless cos is below 1 / cap: one min does
    return np.minimum(sin_t / np.maximum(cos_t, TINY), TAN_THETA_MAX)


def _perspective_slope(along: np.ndarray, r_dot_a: np.ndarray, cos_t: np.ndarray) -> np.ndarray:
    """The depth slope that replaces tan(theta) in a perspective map, (N,).

    The map stores depth along the view axis a, not along the ray r, so within one texel a plane's
    stored depth changes by (half diagonal x d) x |n_perp| (r . a) / |n . r|, with n_perp the part of
    the normal across the axis (|n_perp|^2 = 1 - (n . a)^2 = 1 - along^2). On the axis (r = a) this
    is tan(theta); off the axis it is not zero even for a surface facing the light, which is where a
    tilted spot showed acne without it. cos_t = |n . r|.
    """
    n_perp = np.sqrt(np.maximum(1.0 - along * along, 0.0))
    return np.minimum(n_perp * r_dot_a / np.maximum(cos_t, TINY), TAN_THETA_MAX)


def _pixel_rows(view: ShadowView) -> np.ndarray:
    """(3, 4) float64: world point (x, y, z, 1) -> (col w, row w, w) of `view`'s map, w = depth
    (PERSP) or 1 (ORTHO), folding `project_points`' NDC-to-texel step into the clip matrix."""
    height, width = view.depth.shape
    clip = view.projection.clip_matrix
    w = clip[3]
    return np.stack([0.5 * width * (clip[0] + w), 0.5 * height * (w - clip[1]), clip[2]])


def _look_up(shadow_map: ShadowMap, p: np.ndarray, centre: np.ndarray, n: np.ndarray,
              no_normal: np.ndarray | None) -> _Lookup:
    """Project receivers at centre + p (p: (3, N) float32, m; centre (3,) float64, world m) with
    unit (or zero) normals n (3, N) float32 into their view. `no_normal` (N,) bool marks the zero
    normals (None: there are none); they get no slope.

    All in float32 (7 digits are plenty for a tolerance, and each pass costs half as much as in
    float64): positions are relative to the receivers' centre, so rounding them is relative to
    the receivers' extent, not to their distance from the world origin, and the depth tolerance's
    precision term (DEPTH_PRECISION_REL of |z| plus the largest |coordinate|) covers it.
    One pass over all receivers whatever the kind: a cube map's face comes from the OpenGL table in
    closed form (sc, tc and ma are signed components of p - L), so receivers are never sorted.
    """
    look = _look_up_cube if shadow_map.kind == "CUBE" else _look_up_view
    return look(shadow_map, p, centre, n, no_normal)


def _look_up_cube(shadow_map: ShadowMap, p: np.ndarray, centre: np.ndarray, n: np.ndarray,
                  no_normal: np.ndarray | None) -> _Lookup:
    """`_look_up` for the six faces of a cube map: texel coordinates move by ~1e-4 texel."""
    light = (shadow_map.light_position - centre).astype(np.float32)
    x, y, z = p - light[:, None]  # from the light, m
    ax, ay, az = np.abs(x), np.abs(y), np.abs(z)
    x_wins = (ax >= ay) & (ax >= az)  # ties as cubemap.direction_to_face: X, then Y, then Z
    y_wins = ~x_wins & (ay >= az)
    z_wins = ~(x_wins | y_wins)
    neg = (x_wins & (x < 0.0)) | (y_wins & (y < 0.0)) | (z_wins & (z < 0.0))
    face = 2 * (y_wins + 2 * z_wins) + neg  # int64: 2 x axis + (major component < 0)
    sign = np.float32(1.0) - np.float32(2.0) * neg  # of the major component
    ma = np.maximum(np.maximum(ax, ay), az)  # |ma|: the face's view depth
    # The table's (sc, tc): +-X: (-+z, -y); +-Y: (x, +-z); +-Z: (+-x, -y).
    sc = np.where(x_wins, -sign * z, np.where(y_wins, x, sign * x))
    tc = np.where(y_wins, sign * z, -y)
    height, width = shadow_map.views[0].depth.shape
    inv = 1.0 / np.maximum(ma, TINY)  # the light's own position lands at a face's centre
    # its face was chosen for it: s = 1 or t = 0 is the last texel, not outside
    col = np.minimum((sc * inv + 1.0) * np.float32(0.5 * width), np.float32(width - 0.5))
    row = np.minimum((1.0 - tc * inv) * np.float32(0.5 * height), np.float32(height - 0.5))
    inv_dist = 1.0 / np.maximum(np.sqrt(x * x + y * y + z * z), TINY)
    nl = -(n[0] * x + n[1] * y + n[2] * z) * inv_dist  # to_light = -(p - L) / |p - L|
    along = np.where(x_wins, n[0], np.where(y_wins, n[1], n[2]))  # n . face axis, up to sign
    slope = _perspective_slope(along, ma * inv_dist, np.abs(nl))
    if no_normal is not None:
        slope[no_normal] = 0.0
    return _Lookup(col, row, ma, None, face, nl, slope)


def _look_up_view(shadow_map: ShadowMap, p: np.ndarray, centre: np.ndarray, n: np.ndarray,
                  no_normal: np.ndarray | None) -> _Lookup:
    """`_look_up` for a single orthographic or perspective view."""
    view = shadow_map.views[0]
    rows = _pixel_rows(view)  # (3, 4) float64, world (x, y, z, 1) -> (col, row, depth) x w
    offset = (rows[:, :3] @ centre + rows[:, 3]).astype(np.float32)  # the centre's image
    # einsum, not matmul: BLAS would start threads of its own, which fight the lookup's threads
    # for the same cores (2 lookup threads: no gain with matmul, 1.4-2.7 ms per light with einsum).
    col, row, depth = np.einsum("ij,jn->in", rows[:, :3].astype(np.float32), p) + offset[:, None]
    if shadow_map.kind == "ORTHO":
        nl = -np.einsum("j,jn->n", shadow_map.light_direction.astype(np.float32), n)
        slope = _tan_from_cos(np.abs(nl))
        ahead = None
    else:
        ahead = depth > 0.0  # behind the spot: outside its map
        inv = 1.0 / np.where(ahead, depth, np.float32(1.0))
        col *= inv
        row *= inv
        light = (shadow_map.light_position - centre).astype(np.float32)
        tx, ty, tz = light[:, None] - p
        inv_dist = 1.0 / np.maximum(np.sqrt(tx * tx + ty * ty + tz * tz), TINY)
        nl = (n[0] * tx + n[1] * ty + n[2] * tz) * inv_dist
        axis = (-view.projection.view[2, :3]).astype(np.float32)  # world direction of view -Z
        slope = _perspective_slope(np.einsum("j,jn->n", axis, n), np.abs(depth) * inv_dist,
                                   np.abs(nl))
    if no_normal is not None:
        slope[no_normal] = 0.0
    return _Lookup(col, row, depth, ahead, None, nl, slope)


def _stacked_depth(shadow_map: ShadowMap) -> np.ndarray:
    """(V, H, W) float32 depth of every view, without a copy when the views share one array."""
    if len(shadow_map.views) == 1:
        return shadow_map.views[0].depth[None]
    shared = _shared_depth(shadow_map)
    return shared if shared is not None else np.stack([v.depth for v in shadow_map.views])


def _shared_depth(shadow_map: ShadowMap) -> np.ndarray | None:
    """The (V, H, W) array whose slices the views' depth buffers are (a planned cube map), or
    None."""
    first = shadow_map.views[0].depth
    base = first.base
    if base is None or base.shape != (len(shadow_map.views), *first.shape):
        return None
    return base if all(np.shares_memory(v.depth, base) for v in shadow_map.views) else None


def _texels(at: _Lookup, height: int, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """(column, row) int64 texel of each receiver, clamped into the map, and whether it lies in the
    view (None: all do, cube faces)."""
    if at.face is not None:  # 0 <= col, row < size by construction (truncation is the floor)
        return at.col.astype(np.int64), at.row.astype(np.int64), None
    # Out of the map in either direction in one test: a negative texel is a huge unsigned one.
    j = np.floor(at.col).astype(np.int64).view(np.uint64)
    i = np.floor(at.row).astype(np.int64).view(np.uint64)
    inside = (j < width) & (i < height)
    if at.ahead is not None:
        inside &= at.ahead
    # Receivers outside the map are lit (no caster was recorded); indices clamped into the map
    # keep the gathers in bounds and `inside` overrides what they read.
    j = np.minimum(j, width - 1).view(np.int64)
    i = np.minimum(i, height - 1).view(np.int64)
    return j, i, inside


def _visibility_chunk(shadow_map: ShadowMap, depth: np.ndarray, p: np.ndarray, centre: np.ndarray,
                      n: np.ndarray, no_normal: np.ndarray | None, size: float) -> np.ndarray:
    """(N,) float32 visibility of receivers centre + p (see `_look_up`) with unit (or zero)
    normals n (3, N) float32 (`no_normal`: see there); `depth`: every view's map, flat
    (`_stacked_depth`); `size` m bounds every |world coordinate| of the receivers."""
    s = shadow_map.settings
    view = shadow_map.views[0]  # every view of a map has the same size and texel (cube faces)
    height, width = view.depth.shape
    texel, _ = _texel_sides(view)
    if s.normal_offset > 0.0:  # move towards the light side of the surface, texel-sized
        at = _look_up(shadow_map, p, centre, n, no_normal)
        footprint = texel * (np.abs(at.depth) if view.projection.kind == "PERSP" else np.float32(1.0))
        side = np.where(at.nl < 0.0, np.float32(-1.0), np.float32(1.0))
        p = p + n * (footprint * s.normal_offset * side)
        size += texel * s.normal_offset * (float(np.abs(at.depth).max(initial=0.0))
                                           if view.projection.kind == "PERSP" else 1.0)
    at = _look_up(shadow_map, p, centre, n, no_normal)  # a moved receiver may change cube face
    z = at.depth  # float32: the map's precision, covered by eps' precision term
    eps = depth_tolerance(view, s, z, at.slope, np.float32(size))
    j, i, inside = _texels(at, height, width)
    index = i * width + j
    if at.face is not None:
        index += at.face * (height * width)
    k = s.pcf_size
    if k == 1:
        # The lecture: case (b) "|z_f - M_p| <= eps" first, else "z_f <= M_p"; with eps >= 0 the
        # two together are z_f - M_p <= eps.
        lit = z - depth[index] <= eps
        if inside is not None:
            lit |= ~inside
        vis = lit.astype(np.float32)
    else:
        base = index - i * width - j  # the receiver's view
        lit = np.zeros(len(eps), np.float32)
        for di in range(-(k // 2), k // 2 + 1):
            ii = base + np.clip(i + di, 0, height - 1) * width  # neighbours clamped to the map
            for dj in range(-(k // 2), k // 2 + 1):
                lit += z - depth[ii + np.clip(j + dj, 0, width - 1)] <= eps
        vis = lit / np.float32(k * k)
        if inside is not None:
            vis[~inside] = 1.0
    if s.shadow_back_faces:
        vis[at.nl < 0.0] = 0.0  # attached shadow: the surface itself stands between f and the light
    return vis


@dataclass(frozen=True, eq=False)
class Receivers:
    """Receivers prepared once for any number of lights: columns, unit normals and bounds.

    The lookup works on (3, N) float32 columns relative to the receivers' centre (see
    `_look_up`); transposing, centring, normalising and bounding 255k receivers costs ~2 ms, paid
    once per bake instead of once per light.
    """

    positions: np.ndarray  # (3, N) float64, world m (planning)
    local: np.ndarray  # (3, N) float32, world position - centre, m (the lookup)
    centre: np.ndarray  # (3,) float64, the bounding box's centre, world m
    normals: np.ndarray  # (3, N) float32, world unit; zero where unknown
    no_normal: np.ndarray | None  # (N,) bool, the zero normals; None when there are none
    lo: np.ndarray  # (3,) float64, bounding box, world m
    hi: np.ndarray  # (3,) float64

    @classmethod
    def of(cls, points: np.ndarray, normals: np.ndarray) -> Receivers:
        """From (N, 3) world points (m) and normals (any length; zero: unknown)."""
        points = np.asarray(points).reshape(-1, 3)
        normals = np.asarray(normals).reshape(-1, 3)
        pts = np.empty((3, len(points)), np.float64)
        np.copyto(pts, points.T)  # into a fresh C array: faster than astype(order="C")
        if pts.shape[1]:
            lo, hi = pts.min(axis=1), pts.max(axis=1)  # contiguous rows: fast reductions
        else:
            lo = hi = np.zeros(3)
        centre = 0.5 * (lo + hi)
        local = np.empty(pts.shape, np.float32)
        np.subtract(pts, centre[:, None], out=local, casting="same_kind")
        nrm = np.empty((3, len(normals)), np.float32)
        np.copyto(nrm, normals.T, casting="same_kind")
        length2 = nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]
        shortest = float(length2.min(initial=1.0))
        zero = length2 == 0.0 if shortest == 0.0 else None
        # Bake targets pass unit normals: rescaling them would change nothing but cost 0.5 ms.
        longest = float(length2.max(initial=1.0))
        if not 1.0 - UNIT_LENGTH2_TOL <= shortest <= longest <= 1.0 + UNIT_LENGTH2_TOL:
            nrm *= 1.0 / np.sqrt(np.maximum(length2, TINY))  # zero normals stay zero
        return cls(pts, local, centre, nrm, zero, lo, hi)

    def __len__(self) -> int:
        return self.local.shape[1]

    @property
    def box(self) -> np.ndarray:
        """(2, 3) float64: the bounding box's two corners (stand-ins for culling and planning)."""
        return np.stack([self.lo, self.hi])

    @property
    def size(self) -> float:
        """Largest |world coordinate| of any receiver, m."""
        return float(max(np.abs(self.lo).max(), np.abs(self.hi).max()))


def receivers_visibility(shadow_map: ShadowMap, receivers: Receivers,
                         out: np.ndarray | None = None) -> np.ndarray:
    """`shadow_visibility` of prepared receivers: (N,) float32 in [0, 1]."""
    if out is None:
        out = np.empty(len(receivers), np.float32)
    if len(receivers) == 0:
        return out
    # The float32-position precision term takes the largest |coordinate| of all the receivers
    # (at most 2^-21 of the scene's size more tolerance than each receiver's own).
    size = receivers.size
    depth = _stacked_depth(shadow_map).reshape(-1)  # every view's map, flat, gathered per chunk
    pts, nrm, zero = receivers.local, receivers.normals, receivers.no_normal

    def look_up(a: int, b: int) -> None:
        out[a:b] = _visibility_chunk(shadow_map, depth, pts[:, a:b], receivers.centre, nrm[:, a:b],
                                     None if zero is None else zero[a:b], size)

    threads.for_ranges(look_up, len(receivers), RECEIVER_CHUNK,
                       shadow_map.settings.thread_count, MIN_THREAD_RECEIVERS)
    return out


def shadow_visibility(
    shadow_map: ShadowMap,
    points: np.ndarray,
    normals: np.ndarray,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Step 2 of the lecture: (N,) float32 light visibility in [0, 1] of receivers (1 = lit).

    `points` (N, 3) world m and their `normals` (N, 3) world (any length; zero: unknown, which
    drops the slope terms). PCF gives fractions k'/k^2. `out` (N,) float32 may be caller-owned.
    Several lights over the same receivers: prepare them once (`Receivers.of`) and call
    `receivers_visibility`.
    """
    return receivers_visibility(shadow_map, Receivers.of(points, normals), out)


def light_visibility(
    triangles: np.ndarray,
    points: np.ndarray,
    normals: np.ndarray,
    light: Light,
    settings: ShadowMapSettings | None = None,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Both steps: (N,) float32 visibility of receivers (N, 3) from `light` past (T, 3, 3) casters.

    | parameter | shape / range       | unit / meaning                                          |
    |-----------|---------------------|---------------------------------------------------------|
    | triangles | (T, 3, 3) float32   | m, world: the casters (receivers' own surfaces included)|
    | points    | (N, 3) float        | m, world: the receivers f                               |
    | normals   | (N, 3) float        | world: receiver normals (slope bias, normal offset)     |
    | light     | scene.Light         | SUN, SPOT, POINT (AREA: a point at its centre)          |
    | settings  | ShadowMapSettings   | default ShadowMapSettings()                             |
    | out       | (N,) float32        | optional caller-owned result                            |
    """
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    if out is None:
        out = np.empty(len(pts), np.float32)
    if not light.cast_shadow or len(pts) == 0 or len(triangles) == 0:
        out[...] = 1.0
        return out
    shadow_map = build_shadow_map(triangles, light, settings, pts)
    return shadow_visibility(shadow_map, pts, normals, out)


# --------------------------------------------------------------------------------------------
# Debugging and failure measures
# --------------------------------------------------------------------------------------------


def debug_image(shadow_map: ShadowMap) -> np.ndarray:
    """(H, W, 1) float32 picture of the map: depth scaled to [0, 1] over its finite texels,
    1 where nothing was drawn; a cube map is its six faces side by side in face order."""
    depth = np.concatenate([v.depth for v in shadow_map.views], axis=1).astype(np.float64)
    finite = np.isfinite(depth)
    image = np.ones_like(depth)
    if finite.any():
        lo, hi = depth[finite].min(), depth[finite].max()
        image[finite] = (depth[finite] - lo) / (hi - lo) if hi > lo else 0.0
    return image[..., None].astype(np.float32)


def acne_fraction(
    visibility: np.ndarray, truth: np.ndarray, tolerance: float = 0.5,
    mask: np.ndarray | None = None,
) -> float:
    """Fraction of truly lit receivers (truth >= 0.5) reported darker than truth - tolerance.

    tolerance 0.5 counts receivers a binary test calls shadowed; a small tolerance counts any
    darkening (then exclude the PCF penumbra with `mask`, (N,) bool of receivers to consider).
    """
    lit = np.asarray(truth) >= 0.5
    if mask is not None:
        lit &= np.asarray(mask, bool)
    if not lit.any():
        return 0.0
    wrong = np.asarray(visibility)[lit] < np.asarray(truth)[lit] - tolerance
    return float(wrong.mean())


def peter_panning_gap(
    points: np.ndarray, visibility: np.ndarray, truth: np.ndarray, threshold: float = 0.5
) -> float:
    """How far a shadow comes loose from its caster, m (0: attached; inf: shadow gone).

    Leaked receivers are truly shadowed (truth < threshold) but reported lit; the gap is the largest
    distance from a leaked receiver to the nearest receiver shadowed in both, i.e. the width of the
    lit strip between a caster's contact and where its shadow starts (plus up to a texel of edge
    quantisation). Brute force, O(leaked x shadowed): meant for test- and sweep-sized point sets.
    """
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    vis, tru = np.asarray(visibility), np.asarray(truth)
    leaked = pts[(tru < threshold) & (vis >= threshold)]
    held = pts[(tru < threshold) & (vis < threshold)]
    if len(leaked) == 0:
        return 0.0
    if len(held) == 0:
        return float("inf")
    gap = 0.0
    step = max(1, (1 << 22) // len(held))  # ~4M distances (32 MB) at a time
    for a in range(0, len(leaked), step):
        d2 = ((leaked[a : a + step, None, :] - held[None, :, :]) ** 2).sum(axis=2)
        gap = max(gap, float(np.sqrt(d2.min(axis=1).max())))
    return gap
