"""The views of a light's shadow map: which ones, fitted to what (`plan_shadow_map`).

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

Triangles that cannot shadow any receiver need not enter the map at all (`potential_casters`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..envmap import cubemap
from ..geometry.raster import Projection, look_at
from ..geometry.scene import Light
from ..geometry.vec import bounds, bounds_of_parts, cross3, max_of_three, min_of_three, row_norms
from .shadowmap import Receivers, ShadowMap, ShadowMapSettings, ShadowView

SPOT_CUBE_ANGLE = np.radians(120.0)  # wider spot cones use the six-face cube map
DEPTH_MARGIN_REL = 1e-3  # of the depth range: keeps fitted near/far planes off the geometry
DEPTH_MARGIN_ABS = 1e-4  # m, the same for scenes of zero depth range
NEAR_REL = 1e-6  # PERSP near plane as a fraction of far: linear depth loses no precision for it
EDGE_ON_COS = 1e-3  # |cos| between a caster's normal and the light below this: seen edge-on
MIN_EXTENT_REL = 1e-6  # a fitted sun map is at least this fraction of the scene size across


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
    parts = receivers.positions if isinstance(receivers, Receivers) else (receivers,)
    r_lo, r_hi = bounds_of_parts(parts, basis)  # the receivers' box in light space, m
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
