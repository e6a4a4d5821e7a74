"""Step 2 of the lecture: the depth test of receivers against a shadow map, with its tolerance.

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

from dataclasses import dataclass

import numpy as np

from ..geometry import threads
from ..geometry.scene import Light
from .depth_maps import build_shadow_map
from .shadowmap import TINY, Receivers, ShadowMap, ShadowMapSettings, ShadowView, shared_depth

TAN_THETA_MAX = 20.0  # caps the slope terms at ~87 degrees, where N.L < 0.05 dims the light anyway
DEPTH_PRECISION_REL = 2.0**-21  # 8 half-ulps of float32: stored depth and float32 positions
RECEIVER_CHUNK = 1 << 16  # receivers per vectorised lookup step: ~20 MB of temporaries (per thread)
# Fewer receivers than this per thread are looked up on one: a thread's share must outweigh the
# GIL hand-offs of its NumPy calls. Even with larger shares a second thread gained little inside a
# whole light (after its raster), and sometimes lost: hence one thread by default.
MIN_THREAD_RECEIVERS = 1 << 15


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
# rows of three, and adding a (3,) vector to the points costs many times the matrix product itself.


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
    # for the same cores (with matmul, a second lookup thread gained nothing).
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
    shared = shared_depth(shadow_map)
    return shared if shared is not None else np.stack([v.depth for v in shadow_map.views])


def _stacked_veils(shadow_map: ShadowMap) -> tuple[np.ndarray, np.ndarray] | None:
    """(what the veils let through, the nearest veil's depth), each every view's (V x H x W,)
    float32 flat (`cutouts.py`); None when the map has no veil."""
    views = shadow_map.views
    if views[0].veil is None:
        return None
    return (np.stack([v.veil for v in views]).reshape(-1),
            np.stack([v.veil_depth for v in views]).reshape(-1))


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
                      n: np.ndarray, no_normal: np.ndarray | None, size: float,
                      veils: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """(N,) float32 visibility of receivers centre + p (see `_look_up`) with unit (or zero)
    normals n (3, N) float32 (`no_normal`: see there); `depth`: every view's map, flat
    (`_stacked_depth`); `size` m bounds every |world coordinate| of the receivers; `veils`: the
    map's partly covering casters (`_stacked_veils`), whose product a receiver farther than the
    nearest of them (by the same tolerance) takes, filtered as the depth test is."""
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

    def seen(at: np.ndarray) -> np.ndarray:
        """(N,) float32: the light the receivers get through texels `at` (N,): the lecture's
        case (b) "|z_f - M_p| <= eps" first, else "z_f <= M_p" (with eps >= 0 the two together
        are z_f - M_p <= eps), times the texel's veils where the receiver lies behind them."""
        lit = (z - depth[at] <= eps).astype(np.float32)
        if veils is not None:
            lit *= np.where(z - veils[1][at] > eps, veils[0][at], np.float32(1.0))
        return lit

    k = s.pcf_size
    if k == 1:
        vis = seen(index)
    else:
        base = index - i * width - j  # the receiver's view
        vis = np.zeros(len(eps), np.float32)
        for di in range(-(k // 2), k // 2 + 1):
            ii = base + np.clip(i + di, 0, height - 1) * width  # neighbours clamped to the map
            for dj in range(-(k // 2), k // 2 + 1):
                vis += seen(ii + np.clip(j + dj, 0, width - 1))
        vis /= np.float32(k * k)
    if inside is not None:
        vis[~inside] = 1.0
    if s.shadow_back_faces:
        vis[at.nl < 0.0] = 0.0  # attached shadow: the surface itself stands between f and the light
    return vis


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
    veils = _stacked_veils(shadow_map)
    pts, nrm, zero = receivers.local, receivers.normals, receivers.no_normal

    def look_up(a: int, b: int) -> None:
        out[a:b] = _visibility_chunk(shadow_map, depth, pts[:, a:b], receivers.centre, nrm[:, a:b],
                                     None if zero is None else zero[a:b], size, veils)

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
