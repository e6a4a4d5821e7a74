"""Form factors between perfectly diffuse patches: closed forms, the exact point-to-polygon factor,
and two estimators of the patch-to-patch factor with visibility.

The radiosity equation B_i = E_i + rho_i * sum_j F_ij B_j needs F_ij, the fraction of the power
leaving patch i (uniformly, diffusely) that arrives at patch j:

    F_ij = 1/A_i  integral_Ai integral_Aj  V(x, y) cos(theta_i) cos(theta_j) / (pi s^2)  dA_j dA_i

The inner integral is the factor from a differential area at x to patch j, F_dA->j(x): the
projected solid angle of (the visible part of) j over pi. Three ways of getting it live here:

* Closed forms from Howell's catalogue (C-11, C-14, point and disk to coaxial disk): the ground
  truth of the tests, usable directly when a scene is one of those configurations.
* `point_to_polygon`: Lambert's contour formula (the unoccluded F_dA->j to a flat polygon, exact):
      F = 1/(2 pi) sum_k gamma_k  n . (R_{k+1} x R_k) / |R_{k+1} x R_k|
  R_k = V_k - x, gamma_k the angle between R_k and R_{k+1}, n the receiver's unit normal. The
  polygon is first clipped to the receiver's upper half-space (the formula only holds there).
* Two patch-to-patch estimators, both giving one row F_i* at a time (`FormFactorRows`):
  - method A, `HemicubeFormFactors` (Cohen & Greenberg 1985): hemicubes at n x n points of patch
    i; each pixel carries its delta form factor and looks through a caller-supplied
    `closest_hit`: the patch whose triangle the pixel's ray hits first receives the pixel's factor.
  - method B, `RayCastFormFactors`: the area average over n x n points x of patch i of
    point_to_polygon(x, j), times the visible fraction of j seen from x (rays to m x m stratified
    points of j through a caller-supplied `occluded`). Pairs that cannot be occluded (caller's
    word, or a quick plane/box test) use the closed form alone.
  The points on patch i are Gauss-Legendre nodes by default ("stratified", seeded jitter, is a
  setting): the area average of F_dA->j is smooth enough that a bare 4 x 4 Gauss rule is within
  1e-5 of Howell's C-11 and C-14 on unit squares, where 4 x 4 jittered strata are 1-4% off.

Near field. Adjacent patches sharing an edge are the classic failure of the point-to-point kernel
cos cos/(pi s^2), which is unbounded as s -> 0. Neither estimator evaluates it: method B
integrates the kernel over j analytically (the contour formula is bounded by 1 for every point,
including points next to the shared edge) and only averages the bounded result over patch i, over
the smaller patch of each pair (`RayCastFormFactors`); method A integrates over solid angle,
where the adjacent patch is a region of the hemicube, so nothing diverges, but its accuracy next
to a much smaller neighbour is limited by where its points sit (tests record -80% for a 1 x 1
floor beside a 0.01 high strip). Points exactly on j's plane (so on a shared edge, where the
contour integrand is 0/0) see j edge-on and get 0 (`PLANE_EPS`).

Conventions. Patches are `corners` (N, K, 3) float64, world space, metres: planar convex polygons
wound counter-clockwise around their front normal (Blender's order); a triangle among quads
repeats its last corner (zero-length edges contribute nothing). Patches are one-sided: a patch
seen from behind neither receives nor sends. Colours do not enter here.

Ray callbacks (method A and B), R rays per call:

    closest_hit(origins, directions, t_min, t_max) -> (t, tri)   # or an object with .t and .tri
    occluded(origins, directions, t_min, t_max) -> (R,) bool
        origins (R, 3) float64, world, m; directions (R, 3) float64, unit length;
        t_min float; t_max float or (R,) float64 (method B passes per-ray segment lengths);
        t (R,) float (inf on a miss); tri (R,) int (-1 on a miss); both sides of a triangle hit.

`kernels.geometry.bvh.BVH.intersect` fits `closest_hit` through a lambda returning its Hits.
`tests/support/radiosity_scenes.py` has a brute-force tracer with both callbacks for the tests.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np

# --- named constants -------------------------------------------------------------------------

# A point whose distance to a polygon's plane is below this fraction of its distance to the
# polygon's farthest corner sees the polygon edge-on: F = 0. This is the exact value on the plane
# and it also covers points on the polygon's edges and corners, where the contour integrand is 0/0;
# above it, |R_k x R_k+1| >= |edge| * distance stays far from float64 cancellation (1e-16).
PLANE_EPS = 1e-10
# An edge whose endpoints are seen within this sine (relative to |R_k||R_k+1|) of each other lies
# on a line through the point; off the polygon's plane that means gamma ~ 0 (a zero-length edge,
# padding, or the point on the edge's extension), so the edge contributes nothing.
COLLINEAR_EPS = 1e-14
# Ray end points are lifted off their surfaces along the normal by this fraction of the scene's
# bounding-box diagonal: above float32 rounding of coordinates (6e-8 relative), so a float32 BVH
# does not re-hit the surface a ray leaves, and far below any patch size worth meshing.
RAY_OFFSET_REL = 1e-5
# Shadow rays of method B stop this fraction of their length short of the target point, so the
# target's own surface is never its occluder even with ray_offset = 0 (float32 t rounding is 6e-8).
SHADOW_END_REL = 1e-6
# A patch is on one side of a triangle's plane when all its corners are within this fraction of
# the scene diagonal of that side (the quick unoccluded-pair test; a looser value only sends more
# pairs to the ray tests).
SIDE_EPS_REL = 1e-7
# Two patches whose areas differ by less than this fraction count as equal (rounding of areas of
# identical subdivided quads is ~1e-16): method B integrates such a pair over the lower index.
AREA_TIE_REL = 1e-9
# Default number of rays handed to one callback call: bounds temporary memory (~100 MB of
# (R, 3) float64 arrays and the callback's own buffers).
MAX_RAYS_PER_CALL = 1 << 18

TWO_PI = 2.0 * math.pi

ClosestHit = Callable[[np.ndarray, np.ndarray, float, Any], Any]
Occluded = Callable[[np.ndarray, np.ndarray, float, Any], np.ndarray]


# --- closed forms (Howell's catalogue; formulas in tests/data/form_factors.json) ---------


def parallel_rectangles(a, b, c):
    """Howell C-11: identical, directly opposed, parallel a x b rectangles at distance c.

    Arguments broadcast (metres, > 0). Returns F12 (float64 array or scalar), dimensionless.
    """
    x = np.asarray(a, np.float64) / np.asarray(c, np.float64)
    y = np.asarray(b, np.float64) / np.asarray(c, np.float64)
    x2, y2 = x * x, y * y
    sx, sy = np.sqrt(1.0 + x2), np.sqrt(1.0 + y2)
    bracket = (
        0.5 * np.log((1.0 + x2) * (1.0 + y2) / (1.0 + x2 + y2))
        + x * sy * np.arctan(x / sy)
        + y * sx * np.arctan(y / sx)
        - x * np.arctan(x)
        - y * np.arctan(y)
    )
    return 2.0 / (math.pi * x * y) * bracket


def perpendicular_rectangles(w, h, l):  # noqa: E741 - Howell's names
    """Howell C-14: from a w x l rectangle to a perpendicular h x l one sharing the edge l.

    Arguments broadcast (metres, > 0). Returns F12 (from the w x l rectangle), dimensionless. The
    logarithm's powers W^2 and H^2 are taken as products of logarithms (no overflow for long l).
    """
    l = np.asarray(l, np.float64)  # noqa: E741
    big_h = np.asarray(h, np.float64) / l
    big_w = np.asarray(w, np.float64) / l
    h2, w2 = big_h * big_h, big_w * big_w
    s = np.sqrt(h2 + w2)
    log_term = (
        np.log((1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2))
        + w2 * np.log(w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2)))
        + h2 * np.log(h2 * (1.0 + w2 + h2) / ((1.0 + h2) * (w2 + h2)))
    )
    bracket = (
        big_w * np.arctan(1.0 / big_w)
        + big_h * np.arctan(1.0 / big_h)
        - s * np.arctan(1.0 / s)
        + 0.25 * log_term
    )
    return bracket / (math.pi * big_w)


def element_to_disk(h, r, tilt=0.0):
    """Differential element on the axis of a disk of radius r at distance h, facing it.

    `tilt` (radians) turns the element's normal away from the axis; valid while the disk stays
    entirely above the element's horizon (tan(tilt) <= h / r). Returns cos(tilt) r^2/(r^2 + h^2).
    """
    h = np.asarray(h, np.float64)
    r = np.asarray(r, np.float64)
    return np.cos(tilt) * r * r / (r * r + h * h)


def disk_to_disk(r1, r2, h):
    """Coaxial parallel disks, radii r1 (from) and r2 (to), at distance h. Returns F12."""
    big_r1 = np.asarray(r1, np.float64) / np.asarray(h, np.float64)
    big_r2 = np.asarray(r2, np.float64) / np.asarray(h, np.float64)
    x = 1.0 + (1.0 + big_r2 * big_r2) / (big_r1 * big_r1)
    return 0.5 * (x - np.sqrt(x * x - 4.0 * (big_r2 / big_r1) ** 2))


# --- patch geometry ----------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PatchGeometry:
    """What the estimators need of (N, K, 3) patch corners.

    centres  (N, 3) float64  world, m: the corners' mean (the area centroid for parallelograms)
    normals  (N, 3) float64  world, unit: front normal (Newell's, counter-clockwise winding)
    areas    (N,)   float64  m^2
    scale    float           m: bounding-box diagonal of all corners (sets the ray offsets)
    """

    centres: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    scale: float


def patch_geometry(corners: np.ndarray) -> PatchGeometry:
    """Centres, unit normals, areas and overall scale of (N, K, 3) planar polygons."""
    v = _as_corners(corners)
    # Newell: the vector area is half the sum of V_k x V_k+1 (exact for planar polygons).
    vector_area = 0.5 * np.cross(v, np.roll(v, -1, axis=1)).sum(axis=1)  # (N, 3)
    areas = np.linalg.norm(vector_area, axis=1)
    if np.any(areas <= 0.0):
        raise ValueError(f"patches {np.flatnonzero(areas <= 0.0)[:8].tolist()} have zero area")
    flat = v.reshape(-1, 3)
    scale = float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))
    return PatchGeometry(v.mean(axis=1), vector_area / areas[:, None], areas, scale)


SampleRule = Literal["gauss", "stratified", "midpoint"]


def sample_patches(
    corners: np.ndarray,
    n: int,
    rule: SampleRule = "midpoint",
    rng: np.random.Generator | None = None,
    cells: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """(n cells)^2 quadrature points per patch in the bilinear (u, v) square, with area weights.

    | rule       | points in (u, v)                                 | weights                 |
    |------------|--------------------------------------------------|-------------------------|
    | gauss      | Gauss-Legendre nodes (exact for degree 2n - 1)   | Gauss weights x Jacobian|
    |            | in each of cells x cells sub-squares (composite) |                         |
    | stratified | one uniform point per cell of an m x m grid (rng)| Jacobian                |
    | midpoint   | cell centres of an m x m grid                    | Jacobian                |

    (m = n cells.)
    corners (N, K, 3). K <= 4: one bilinear map x(u, v) (a triangle repeats its last corner);
    K > 4 (convex): a fan of K triangles around the corners' mean, n x n points each. Returns
    points (N, S, 3) float64 and weights (N, S) float64, normalised to sum 1 per patch, so
    sum_s w_s f(x_s) estimates the area average of f over the patch.
    """
    v = _as_corners(corners)
    count, k = v.shape[:2]
    if k == 3 and rule == "midpoint":
        return triangle_midpoints(v, n * cells)
    if k == 3:
        quads = np.concatenate([v, v[:, 2:3]], axis=1)[:, None]  # (N, 1, 4, 3)
    elif k == 4:
        quads = v[:, None]
    else:  # fan around the corners' mean: (C, Vt, Vt+1, Vt+1), no slivers for regular polygons
        centre = np.broadcast_to(v.mean(axis=1, keepdims=True), v.shape)
        nxt = np.roll(v, -1, axis=1)
        quads = np.stack([centre, v, nxt, nxt], axis=2)
    pieces = quads.shape[1]
    m = n * cells
    if rule == "gauss":
        nodes, node_w = np.polynomial.legendre.leggauss(n)
        offsets = np.arange(cells, dtype=np.float64)[:, None]
        grid = ((offsets + 0.5 * (nodes + 1.0)) / cells).ravel()
        grid_w = np.tile(0.5 * node_w / cells, cells)
    else:
        _check_rule(rule)
        grid, grid_w = (np.arange(m, dtype=np.float64) + 0.5) / m, np.full(m, 1.0 / m)
    uu, vv = np.meshgrid(grid, grid, indexing="ij")
    shape = (count, pieces, m * m)
    u = np.broadcast_to(uu.ravel(), shape)
    w = np.broadcast_to(vv.ravel(), shape)
    if rule == "stratified":
        rng = rng if rng is not None else np.random.default_rng(0)
        u = u + (rng.random(shape) - 0.5) / m
        w = w + (rng.random(shape) - 0.5) / m
    u, w = u[..., None], w[..., None]
    q0, q1, q2, q3 = (quads[:, :, c][:, :, None] for c in range(4))  # (N, P, 1, 3)
    points = (1 - u) * (1 - w) * q0 + u * (1 - w) * q1 + u * w * q2 + (1 - u) * w * q3
    du = (1 - w) * (q1 - q0) + w * (q2 - q3)
    dv = (1 - u) * (q3 - q0) + u * (q2 - q1)
    jac = np.linalg.norm(np.cross(du, dv), axis=-1) * np.outer(grid_w, grid_w).ravel()
    jac = jac.reshape(count, -1)
    return points.reshape(count, -1, 3), jac / jac.sum(axis=1, keepdims=True)


def triangle_midpoints(triangles: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """The centroids of the m^2 equal triangles that cutting each side of each triangle (N, 3, 3)
    into m makes, weights 1 / m^2: points (N, m^2, 3), weights (N, m^2). Exact for linear
    functions at any m (m = 1: the centroid), unlike the bilinear square folded onto a triangle,
    whose cell centres crowd toward the repeated corner."""
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    up = (i + j <= m - 1).ravel()
    down = (i + j <= m - 2).ravel()
    a = np.concatenate([i.ravel()[up] + 1.0 / 3.0, i.ravel()[down] + 2.0 / 3.0]) / m
    b = np.concatenate([j.ravel()[up] + 1.0 / 3.0, j.ravel()[down] + 2.0 / 3.0]) / m
    bary = np.stack([1.0 - a - b, a, b], axis=1)  # (m^2, 3) weights of corners 0, 1, 2
    points = np.einsum("sk,nkc->nsc", bary, triangles)
    return points, np.full(points.shape[:2], 1.0 / (m * m))


def tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents (N, 3) completing unit normals (N, 3) to right-handed frames (t1, t2, n).

    Duff et al., "Building an Orthonormal Basis, Revisited" (JCGT 2017): branch-free, no
    singularity at n = -z.
    """
    x, y, z = normals[:, 0], normals[:, 1], normals[:, 2]
    sign = np.where(z >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z)
    b = x * y * a
    t1 = np.stack([1.0 + sign * x * x * a, sign * b, -sign * x], axis=1)
    t2 = np.stack([b, sign + y * y * a, -y], axis=1)
    return t1, t2


# --- the exact unoccluded point-to-polygon factor ---------------------------------------------


def point_to_polygon(
    points: np.ndarray,
    normals: np.ndarray,
    polygons: np.ndarray,
    polygon_normals: np.ndarray | None = None,
    *,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Exact unoccluded form factor from differential areas to flat polygons (Lambert / Nusselt).

    | argument        | shape           | meaning                                             |
    |-----------------|-----------------|-----------------------------------------------------|
    | points          | (..., 3)        | receiver positions x, world, m                      |
    | normals         | (..., 3)        | receiver unit normals                               |
    | polygons        | (..., K, 3)     | polygon corners, CCW around the front normal, m     |
    | polygon_normals | (..., 3) / None | unit front normals (None: Newell's from corners)    |
    | out             | (...) float64   | optional caller-owned result buffer                 |

    Leading shapes broadcast against each other. Returns F_dx->polygon in [0, 1] per pair: 0 when
    x is behind the polygon or within `PLANE_EPS` of its plane (edge-on, on an edge, on a corner),
    0 for a polygon entirely below x's horizon; polygons crossing the horizon are clipped to it
    (Sutherland-Hodgman, vectorised with a fixed 2K-corner output padded by repeated corners).
    """
    points = np.asarray(points, np.float64)
    normals = np.asarray(normals, np.float64)
    polygons = np.asarray(polygons, np.float64)
    if polygon_normals is None:
        vector_area = np.cross(polygons, np.roll(polygons, -1, axis=-2)).sum(axis=-2)
        length = np.linalg.norm(vector_area, axis=-1, keepdims=True)
        polygon_normals = np.divide(
            vector_area, length, out=np.zeros_like(vector_area), where=length > 0.0
        )
    polygon_normals = np.asarray(polygon_normals, np.float64)
    k = polygons.shape[-2]
    lead = np.broadcast_shapes(
        points.shape[:-1], normals.shape[:-1], polygons.shape[:-2], polygon_normals.shape[:-1]
    )
    x = np.broadcast_to(points, (*lead, 3)).reshape(-1, 3)
    n = np.broadcast_to(normals, (*lead, 3)).reshape(-1, 3)
    npoly = np.broadcast_to(polygon_normals, (*lead, 3)).reshape(-1, 3)
    rel = np.broadcast_to(polygons, (*lead, k, 3)).reshape(-1, k, 3) - x[:, None, :]  # (M, K, 3)

    result = np.zeros(x.shape[0], np.float64)
    # Front side, off the plane: distance of x in front of the polygon's plane vs its extent.
    distance = -np.einsum("mkc,mc->mk", rel, npoly).mean(axis=1)  # (M,)
    reach = np.sqrt(np.einsum("mkc,mkc->mk", rel, rel).max(axis=1))
    facing = distance > PLANE_EPS * reach
    height = np.einsum("mkc,mc->mk", rel, n)  # (M, K) above x's tangent plane
    whole = facing & np.all(height >= 0.0, axis=1)
    clipped = facing & ~whole & np.any(height > 0.0, axis=1)
    if whole.any():
        result[whole] = _contour_sum(rel[whole], n[whole])
    if clipped.any():
        result[clipped] = _contour_sum(_clip_above(rel[clipped], height[clipped]), n[clipped])
    np.maximum(result, 0.0, out=result)  # rounding can leave -1e-17 for grazing polygons
    result = result.reshape(lead)
    if out is not None:
        out[...] = result
        return out
    return result


def _contour_sum(rel: np.ndarray, n: np.ndarray) -> np.ndarray:
    """1/(2 pi) sum_k gamma_k n.(R_k+1 x R_k)/|R_k+1 x R_k| for (M, K, 3) corners relative to x."""
    nxt = np.roll(rel, -1, axis=1)
    c = np.cross(nxt, rel)  # (M, K, 3): positive n-component for a polygon facing x
    # Lengths through einsum: NumPy reduces a 3-long last axis row by row (3x slower).
    sine = np.sqrt(np.einsum("mkc,mkc->mk", c, c))
    cosine = np.einsum("mkc,mkc->mk", rel, nxt)
    gamma = np.arctan2(sine, cosine)
    length2 = np.einsum("mkc,mkc->mk", rel, rel)
    lengths = np.sqrt(length2 * np.roll(length2, -1, axis=1))
    regular = sine > COLLINEAR_EPS * lengths
    projected = np.einsum("mkc,mc->mk", c, n)
    ratio = np.divide(projected, sine, out=np.zeros_like(sine), where=regular)
    return (gamma * ratio).sum(axis=1) / TWO_PI


def _clip_above(rel: np.ndarray, height: np.ndarray) -> np.ndarray:
    """Clip (M, K, 3) polygons to height >= 0; returns (M, 2K, 3) with repeated-corner padding."""
    m, k = height.shape
    inside = height >= 0.0
    nxt_h = np.roll(height, -1, axis=1)
    crosses = inside != (nxt_h >= 0.0)
    denom = np.where(crosses, height - nxt_h, 1.0)  # nonzero where the signs differ
    t = np.where(crosses, height / denom, 0.0)[..., None]
    slots = np.empty((m, 2 * k, 3))
    slots[:, 0::2] = rel
    slots[:, 1::2] = rel + t * (np.roll(rel, -1, axis=1) - rel)
    valid = np.empty((m, 2 * k), bool)
    valid[:, 0::2] = inside
    valid[:, 1::2] = crosses
    # Fill each invalid slot with the previous valid corner (cyclically): zero-length edges.
    index = np.where(valid, np.arange(2 * k), -1)
    np.maximum.accumulate(index, axis=1, out=index)
    index = np.where(index < 0, index[:, -1:], index)
    return np.take_along_axis(slots, index[..., None], axis=1)


# --- rows: the interface the solvers consume ---------------------------------------------------


# One shadow-ray request of a generator estimator: (origins (R, 3), unit directions (R, 3),
# t_max (R,)) with t_min 0; the answer sent back is (R,) bool, True where something is hit.
RayRequest = tuple[np.ndarray, np.ndarray, np.ndarray]
RayRequests = Generator[RayRequest, np.ndarray, Any]
# Rays gathered from several rows into one ray-casting call: the BVH reaches its full rate from
# about 50k rays a call (a few thousand rays run at a third of it).
RAYS_PER_BATCH = 1 << 17


def _cast(occluded: Occluded, request: RayRequest, per_call: int) -> np.ndarray:
    origins, dirs, t_max = request
    blocked = np.zeros(len(origins), bool)
    for start in range(0, len(origins), per_call):
        part = slice(start, start + per_call)
        blocked[part] = np.asarray(occluded(origins[part], dirs[part], 0.0, t_max[part]), bool)
    return blocked


def answer_rays(steps: RayRequests, occluded: Occluded | None, per_call: int):
    """Run a ray-requesting generator to its end, answering with `occluded`; its return value."""
    try:
        request = next(steps)
        while True:
            request = steps.send(_cast(occluded, request, per_call))
    except StopIteration as stop:
        return stop.value


def answer_rays_together(steps: list, occluded: Occluded | None, per_call: int) -> list:
    """Run several ray-requesting generators side by side, their pending requests answered by
    one batch of `occluded` calls per round. Returns their return values."""
    results: list = [None] * len(steps)
    pending: dict[int, RayRequest] = {}
    for k, gen in enumerate(steps):
        try:
            pending[k] = next(gen)
        except StopIteration as stop:
            results[k] = stop.value
    while pending:
        keys = list(pending)
        sizes = np.cumsum([0] + [len(pending[k][0]) for k in keys])
        merged = tuple(np.concatenate([pending[k][part] for k in keys]) for part in range(3))
        blocked = _cast(occluded, merged, per_call)
        for n, k in enumerate(keys):
            try:
                pending[k] = steps[k].send(blocked[sizes[n] : sizes[n + 1]])
            except StopIteration as stop:
                results[k] = stop.value
                del pending[k]
    return results


class FormFactorRows(Protocol):
    """Anything that yields form factor rows F_i* on demand (methods A and B, a dense matrix)."""

    @property
    def areas(self) -> np.ndarray:  # (N,) float64, m^2
        ...

    def row(self, i: int, out: np.ndarray | None = None) -> np.ndarray:  # (N,) float64
        ...


@dataclass(frozen=True, eq=False)
class DenseRows:
    """A precomputed (N, N) matrix seen through the `FormFactorRows` interface."""

    matrix: np.ndarray  # (N, N) float64
    areas: np.ndarray  # (N,) float64, m^2

    def row(self, i: int, out: np.ndarray | None = None) -> np.ndarray:
        if out is None:
            return self.matrix[i].copy()
        out[...] = self.matrix[i]
        return out


def iter_matrix(rows: FormFactorRows, out: np.ndarray) -> Iterator[float]:
    """Fill caller-owned `out` (N, N) from `rows`, yielding progress in (0, 1]: row by row, or
    a batch of rows at a time where `rows` can share its ray casting between rows."""
    count = out.shape[0]
    batch = rows.rows_per_batch() if hasattr(rows, "rows") else 1
    for first in range(0, count, batch):
        last = min(first + batch, count)
        if batch > 1:
            rows.rows(range(first, last), out[first:last])
        else:
            rows.row(first, out=out[first])
        yield last / count


def form_factor_matrix(rows: FormFactorRows) -> np.ndarray:
    """The full (N, N) float64 matrix of `rows` (runs `iter_matrix` to the end)."""
    count = len(rows.areas)
    out = np.empty((count, count), np.float64)
    for _ in iter_matrix(rows, out):
        pass
    return out


def enforce_reciprocity(
    matrix: np.ndarray, areas: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """Average each pair's two estimates of exchanged power so that A_i F_ij = A_j F_ji exactly.

    matrix (N, N) float64, areas (N,) m^2. Estimated factors satisfy reciprocity only up to
    their sampling error, so a gathering solver (rows F_i*) and a shooting one (F_ji taken as
    F_ij A_i / A_j) solve slightly different systems; after this they solve the same one.
    Row sums move by half the mismatch. `out` may be `matrix` itself.
    """
    a = np.asarray(areas, np.float64)
    power = matrix * a[:, None]  # (N, N) A_i F_ij, m^2
    mean = 0.5 * (power + power.T)
    result = np.empty_like(matrix) if out is None else out
    np.divide(mean, a[:, None], out=result)
    return result


# --- method A: the ray-cast hemicube ----------------------------------------------------------


@dataclass(frozen=True)
class HemicubeSettings:
    """Method A, the hemicube (Cohen & Greenberg 1985), one ray per hemicube pixel centre.

    | field             | range          | default | meaning                                      |
    |-------------------|----------------|---------|----------------------------------------------|
    | resolution        | even, >= 2     | 64      | top-face pixels per side; each of the 4 side |
    |                   |                |         | faces is resolution x resolution/2 pixels    |
    | points_per_side   | >= 1           | 4       | hemicubes per patch: n x n points; 1 with    |
    |                   |                |         | "midpoint" is the patch centre of 1985       |
    | point_rule        | gauss /        | gauss   | where the points go and their weights        |
    |                   | stratified /   |         | (`sample_patches`)                           |
    |                   | midpoint       |         |                                              |
    | rotate            | bool           | True    | turn each hemicube by a random angle about   |
    |                   |                |         | the normal (decorrelates aliasing)           |
    | delta_rule        | exact/midpoint | exact   | pixel factors: exact (contour formula over   |
    |                   |                |         | the pixel, sums to 1) or the 1985 midpoint   |
    |                   |                |         | 1/(pi (x^2+y^2+1)^2) dA, z/(pi(..)^2) dA     |
    | seed              | int            | 0       | RNG seed; row i uses the stream (seed, i)    |
    | ray_offset        | >= 0, None     | None    | m; None: RAY_OFFSET_REL x scene diagonal     |
    | max_rays_per_call | >= 1           | 2^18    | rays per closest_hit call                    |

    Rays per patch: points_per_side^2 x 3 resolution^2 (4 x 4 x 12288 = 196 608 by default).
    """

    resolution: int = 64
    points_per_side: int = 4
    point_rule: SampleRule = "gauss"
    rotate: bool = True
    delta_rule: Literal["exact", "midpoint"] = "exact"
    seed: int = 0
    ray_offset: float | None = None
    max_rays_per_call: int = MAX_RAYS_PER_CALL

    def __post_init__(self) -> None:
        if self.resolution < 2 or self.resolution % 2:
            raise ValueError(f"hemicube resolution must be even and >= 2, got {self.resolution}")
        if self.points_per_side < 1:
            raise ValueError(f"points_per_side must be >= 1, got {self.points_per_side}")
        _check_rule(self.point_rule)
        if self.delta_rule not in ("exact", "midpoint"):
            raise ValueError(f"delta_rule must be 'exact' or 'midpoint', got {self.delta_rule!r}")
        if self.ray_offset is not None and not self.ray_offset >= 0.0:
            raise ValueError(f"ray_offset must be >= 0 m, got {self.ray_offset}")
        if self.max_rays_per_call < 1:
            raise ValueError(f"max_rays_per_call must be >= 1, got {self.max_rays_per_call}")


def hemicube_pixels(
    resolution: int, rule: Literal["exact", "midpoint"] = "exact"
) -> tuple[np.ndarray, np.ndarray]:
    """Pixel centre directions and delta form factors of a unit hemicube.

    The hemicube sits on the tangent plane (local +z is the normal): top face z = 1,
    -1 <= x, y <= 1, R x R pixels; side faces x = +-1 and y = +-1, 0 <= z <= 1, R x R/2 pixels each;
    pixel side 2/R. Returns directions (3 R^2, 3) float64 (unit, local frame) and deltas
    (3 R^2,) float64: top (index ix R + iy), then the faces x = +1, x = -1, y = +1, y = -1
    (index ia R/2 + iz, a the face's other axis).
    'midpoint': 1/(pi (x^2+y^2+1)^2) dA (top), z/(pi (y^2+z^2+1)^2) dA (sides), as in 1985; their
    sum approaches 1 as O(R^-2). 'exact': each pixel's own point-to-polygon factor; sums to 1.
    """
    r = resolution
    step = 2.0 / r
    across = -1.0 + step * (np.arange(r) + 0.5)  # (R,) pixel centres along a full side
    up = step * (np.arange(r // 2) + 0.5)  # (R/2,) pixel centres along z on a side face
    gx, gy = np.meshgrid(across, across, indexing="ij")
    top = np.stack([gx.ravel(), gy.ravel(), np.ones(r * r)], axis=1)
    ga, gz = np.meshgrid(across, up, indexing="ij")
    a, z = ga.ravel(), gz.ravel()
    one = np.ones_like(a)
    sides = [
        np.stack([one, a, z], axis=1),
        np.stack([-one, a, z], axis=1),
        np.stack([a, one, z], axis=1),
        np.stack([a, -one, z], axis=1),
    ]
    centres = np.concatenate([top, *sides])  # (3 R^2, 3) on the cube
    directions = centres / np.linalg.norm(centres, axis=1, keepdims=True)
    if rule == "midpoint":
        area = step * step
        top_delta = area / (math.pi * (gx.ravel() ** 2 + gy.ravel() ** 2 + 1.0) ** 2)
        side_delta = z * area / (math.pi * (a * a + z * z + 1.0) ** 2)
        return directions, np.concatenate([top_delta, np.tile(side_delta, 4)])
    # Exact: each pixel as a square polygon (corner offsets in the face's two in-plane axes).
    half = 0.5 * step
    offsets = np.array([[-half, -half], [half, -half], [half, half], [-half, half]])
    face_axes = [(0, 1), (1, 2), (1, 2), (0, 2), (0, 2)]  # in-plane axes: top, x+-, y+-
    polygons = np.repeat(centres[:, None, :], 4, axis=1)
    start = 0
    for face, (p, q) in enumerate(face_axes):
        stop = start + (r * r if face == 0 else r * r // 2)
        polygons[start:stop, :, p] += offsets[:, 0]
        polygons[start:stop, :, q] += offsets[:, 1]
        start = stop
    deltas = np.abs(_contour_sum(polygons, np.broadcast_to([0.0, 0.0, 1.0], (len(centres), 3))))
    return directions, deltas


def hemicube_gather(
    points: np.ndarray,
    normals: np.ndarray,
    weights: np.ndarray,
    closest_hit: ClosestHit,
    tri_patch: np.ndarray,
    target_normals: np.ndarray,
    settings: HemicubeSettings,
    rng: np.random.Generator | None,
    *,
    ray_offset: float,
    pixels: tuple[np.ndarray, np.ndarray] | None = None,
    skip: int = -1,
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Weighted hemicube form factors from P receiver points to N patches.

    points (P, 3), normals (P, 3) unit, weights (P,) summing to 1 (area-average weights);
    tri_patch (T,) int: the patch each triangle belongs to (-1: an occluder only); target_normals
    (N, 3): a pixel counts for the patch it hits only on that patch's front side; `skip`: a patch
    that never receives (the shooter itself). Returns (N,) float64 sum_p w_p sum_pixels delta.
    """
    tri_patch = np.asarray(tri_patch)
    count = target_normals.shape[0]
    result = np.zeros(count, np.float64) if out is None else out
    result[...] = 0.0
    local, deltas = pixels if pixels is not None else hemicube_pixels(
        settings.resolution, settings.delta_rule
    )
    t1, t2 = tangent_frames(normals)
    if rng is not None and settings.rotate:
        angle = rng.random(len(points)) * TWO_PI
        c, s = np.cos(angle)[:, None], np.sin(angle)[:, None]
        t1, t2 = c * t1 + s * t2, c * t2 - s * t1
    frames = np.stack([t1, t2, normals], axis=1)  # (P, 3, 3): rows are the local axes
    per_call = max(1, settings.max_rays_per_call // len(local))
    for start in range(0, len(points), per_call):
        sl = slice(start, start + per_call)
        dirs = np.einsum("dk,pkc->pdc", local, frames[sl]).reshape(-1, 3)  # world, unit
        origins = points[sl] + ray_offset * normals[sl]
        origins = np.repeat(origins, len(local), axis=0)
        _, tri = _unpack_hits(closest_hit(origins, dirs, 0.0, math.inf))
        patch = np.where(tri >= 0, tri_patch[np.maximum(tri, 0)], -1)
        hit = patch >= 0
        front = np.zeros_like(hit)
        front[hit] = np.einsum("rc,rc->r", dirs[hit], target_normals[patch[hit]]) < 0.0
        keep = front & (patch != skip)
        contribution = (weights[sl, None] * deltas[None, :]).ravel()
        result += np.bincount(patch[keep], weights=contribution[keep], minlength=count)
    return result


def hemicube_item_buffer(
    point: np.ndarray,
    normal: np.ndarray,
    closest_hit: ClosestHit,
    tri_patch: np.ndarray,
    resolution: int,
    *,
    ray_offset: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The patch each pixel of one hemicube sees (1985's item buffer), to inspect or dump as
    images when debugging a row; no rotation, so local x, y are `tangent_frames(normal)`.

    Returns top (R, R) int64, row 0 at local +y, columns from local x = -1 to +1; and sides
    (4, R/2, R) int64 for the faces x = +1, x = -1, y = +1, y = -1, row 0 at the top (z = 1),
    columns along the face's other axis from -1 to +1. -1: a miss or a triangle of no patch.
    """
    r = resolution
    local, _ = hemicube_pixels(r, "midpoint")
    n = np.asarray(normal, np.float64)[None]
    t1, t2 = tangent_frames(n)
    dirs = local @ np.concatenate([t1, t2, n])  # (3 R^2, 3) world
    origins = np.broadcast_to(np.asarray(point, np.float64) + ray_offset * n[0], dirs.shape)
    _, tri = _unpack_hits(closest_hit(np.ascontiguousarray(origins), dirs, 0.0, math.inf))
    tri_patch = np.asarray(tri_patch)
    ids = np.where(tri >= 0, tri_patch[np.maximum(tri, 0)], -1).astype(np.int64)
    top = ids[: r * r].reshape(r, r).T[::-1]
    sides = ids[r * r :].reshape(4, r, r // 2).transpose(0, 2, 1)[:, ::-1]
    return top, sides


class HemicubeFormFactors:
    """Method A: rows F_i* from hemicubes at n x n points of patch i (see the module doc).

    corners (N, K, 3) patches; closest_hit: the ray callback; tri_patch (T,) int, the patch of each
    triangle the callback can return (-1: occluder that is not a patch).
    """

    def __init__(
        self,
        corners: np.ndarray,
        closest_hit: ClosestHit,
        tri_patch: np.ndarray,
        settings: HemicubeSettings | None = None,
    ) -> None:
        self.corners = _as_corners(corners)
        self.geometry = patch_geometry(self.corners)
        self.closest_hit = closest_hit
        self.tri_patch = np.asarray(tri_patch, np.int64)
        self.settings = settings or HemicubeSettings()
        self.pixels = hemicube_pixels(self.settings.resolution, self.settings.delta_rule)
        offset = self.settings.ray_offset
        self.ray_offset = RAY_OFFSET_REL * self.geometry.scale if offset is None else offset

    @property
    def areas(self) -> np.ndarray:
        return self.geometry.areas

    def item_buffer(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """`hemicube_item_buffer` at the centre of patch i (debugging: what row i sees)."""
        g = self.geometry
        return hemicube_item_buffer(
            g.centres[i], g.normals[i], self.closest_hit, self.tri_patch,
            self.settings.resolution, ray_offset=self.ray_offset,
        )

    def row(self, i: int, out: np.ndarray | None = None) -> np.ndarray:
        s = self.settings
        rng = np.random.default_rng((s.seed, i))
        points, weights = sample_patches(
            self.corners[i : i + 1], s.points_per_side, s.point_rule, rng
        )
        normals = np.broadcast_to(self.geometry.normals[i], points[0].shape)
        return hemicube_gather(
            points[0], np.ascontiguousarray(normals), weights[0], self.closest_hit,
            self.tri_patch, self.geometry.normals, s, rng, ray_offset=self.ray_offset,
            pixels=self.pixels, skip=i, out=out,
        )


# --- method B: ray-cast point-to-polygon --------------------------------------------------------


@dataclass(frozen=True)
class RayCastSettings:
    """Method B: area average of the exact point-to-polygon factor times a visible fraction.

    | field                       | range      | default | meaning                               |
    |-----------------------------|------------|---------|---------------------------------------|
    | samples_per_side            | >= 1       | 4       | n: n x n points x on patch i          |
    | source_rule                 | gauss /    | gauss   | their placement and weights           |
    |                             | stratified |         | (`sample_patches`)                    |
    |                             | / midpoint |         |                                       |
    | visibility_samples_per_side | >= 1       | 3       | m: m x m points on patch j, one ray   |
    |                             |            |         | from each point of i to each of j     |
    | visibility_rule             | as above   | stratified | placement of the points on j       |
    | integrate_smaller           | bool       | True    | integrate each pair over its smaller  |
    |                             |            |         | patch, F_ij = A_j F_ji / A_i          |
    | near_field_cells            | >= 1       | 4       | near pairs: the unoccluded factor from|
    |                             |            |         | cells^2 sub-squares of n x n points   |
    | near_field_distance         | >= 0       | 1.0     | near: the patches' boxes closer than  |
    |                             |            |         | this x the integrating patch's size   |
    | quick_test                  | bool       | True    | prove pairs unoccluded by plane and   |
    |                             |            |         | box tests on the scene's triangles    |
    |                             |            |         | (cost O(T N) per row)                 |
    | seed                        | int        | 0       | RNG seed of the stratified points     |
    | ray_offset                  | >= 0, None | None    | m; None: RAY_OFFSET_REL x diagonal    |
    | max_rays_per_call           | >= 1       | 2^18    | rays per `occluded` call              |

    Estimator: F_ij = U_ij V_ij with U_ij = sum_s w_s F(x_s -> j), the unoccluded factor, and
    V_ij = sum_s w_s F(x_s -> j) v_s(j) / U_ij, the visible share; v_s(j) weights each ray to a
    point y of j by the point-to-point kernel cos_x cos_y / s^2 (and y's area weight), so it
    converges to the visible share of the projected solid angle (a plain count of rays would
    weight far parts of j too much). Near pairs take U_ij from the finer near-field rule (cheap:
    closed forms only) and V_ij from the n x n points. Rays per row: n^2 m^2 per pair that is not
    proven unoccluded.
    """

    samples_per_side: int = 4
    source_rule: SampleRule = "gauss"
    visibility_samples_per_side: int = 3
    visibility_rule: SampleRule = "stratified"
    integrate_smaller: bool = True
    near_field_cells: int = 4
    near_field_distance: float = 1.0
    quick_test: bool = True
    seed: int = 0
    ray_offset: float | None = None
    max_rays_per_call: int = MAX_RAYS_PER_CALL

    def __post_init__(self) -> None:
        if self.samples_per_side < 1 or self.visibility_samples_per_side < 1:
            raise ValueError("samples_per_side and visibility_samples_per_side must be >= 1")
        _check_rule(self.source_rule)
        _check_rule(self.visibility_rule)
        if self.near_field_cells < 1 or not self.near_field_distance >= 0.0:
            raise ValueError("near_field_cells must be >= 1 and near_field_distance >= 0")
        if self.ray_offset is not None and not self.ray_offset >= 0.0:
            raise ValueError(f"ray_offset must be >= 0 m, got {self.ray_offset}")
        if self.max_rays_per_call < 1:
            raise ValueError(f"max_rays_per_call must be >= 1, got {self.max_rays_per_call}")


def raycast_gather(
    points: np.ndarray,
    normals: np.ndarray,
    weights: np.ndarray,
    corners: np.ndarray,
    corner_normals: np.ndarray,
    occluded: Occluded | None,
    settings: RayCastSettings,
    rng: np.random.Generator | None,
    *,
    ray_offset: float,
    maybe_occluded: np.ndarray | None = None,
    target_samples: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Method B from weighted receiver points to N polygons; F_j = unoccluded_j x visible_j.

    (`raycast_gather_steps` is the same as a generator asking for its rays.)

    points (S, 3), normals (S, 3) or (3,) unit, weights (S,) summing to 1; corners (N, K, 3) and
    their unit normals (N, 3); occluded None: no rays (visible = 1); maybe_occluded (N,) bool:
    only these targets are ray-tested (None: every target with a nonzero factor);
    target_samples: visibility points of every polygon, (N, M, 3) and weights (N, M) (None:
    drawn here with `rng`). Returns unoccluded (N,) sum_s w_s F(x_s -> j) and visible (N,) in
    [0, 1], the F-weighted visible share (module doc, `RayCastSettings`).
    """
    steps = raycast_gather_steps(points, normals, weights, corners, corner_normals,
                                 occluded is not None, settings, rng, ray_offset=ray_offset,
                                 maybe_occluded=maybe_occluded, target_samples=target_samples)
    return answer_rays(steps, occluded, settings.max_rays_per_call)


def raycast_gather_steps(points, normals, weights, corners, corner_normals, trace: bool,
                         settings: RayCastSettings, rng, *, ray_offset: float,
                         maybe_occluded=None, target_samples=None) -> RayRequests:
    """`raycast_gather` as a generator asking for its shadow rays; `trace` False: none."""
    normals = np.broadcast_to(np.asarray(normals, np.float64), points.shape)
    # (S, N) exact unoccluded factors from each receiver point to every polygon.
    factors = point_to_polygon(
        points[:, None, :], normals[:, None, :], corners[None], corner_normals[None]
    )
    unoccluded = weights @ factors
    visible = np.ones(len(corners), np.float64)
    if not trace:
        return unoccluded, visible
    candidates = unoccluded > 0.0
    if maybe_occluded is not None:
        candidates &= maybe_occluded
    targets = np.flatnonzero(candidates)
    if targets.size:
        if target_samples is None:
            y, wy = sample_patches(
                corners[targets], settings.visibility_samples_per_side,
                settings.visibility_rule, rng,
            )
        else:
            y, wy = target_samples[0][targets], target_samples[1][targets]
        share = yield from _visible_fraction_steps(
            points, normals, y, wy, corner_normals[targets], ray_offset
        )
        visible[targets] = (weights @ (factors[:, targets] * share)) / unoccluded[targets]
    return unoccluded, visible


def disc_form(dist2: np.ndarray, cos_x: np.ndarray, cos_y: np.ndarray, area) -> np.ndarray:
    """(...) Wallace's disc approximation of the factor from a point x to a patch of `area` m^2
    whose centre is d away (Wallace, Elmquist and Haines 1989):
    A cos_x cos_y / (pi d^2 + A), exact for a disc seen head on, 0 where either faces away.
    dist2 = d^2; cos_x, cos_y: the cosines at x and at the patch, each times d (the dot
    products with the unnormalised direction), broadcastable together."""
    return np.divide(area * cos_x * cos_y, dist2 * (np.pi * dist2 + area),
                     out=np.zeros(np.broadcast_shapes(np.shape(dist2), np.shape(cos_x),
                                                      np.shape(cos_y), np.shape(area))),
                     where=(cos_x > 0.0) & (cos_y > 0.0))


def pair_kernel(between: np.ndarray, nx: np.ndarray, ny: np.ndarray) -> np.ndarray:
    """(...) the point-to-point kernel cos_x cos_y / d^2 of point pairs `between` (..., 3) = y - x
    apart (m), unit normals nx at x and ny at y broadcastable to it; 0 where either faces away."""
    dist2 = np.einsum("...c,...c->...", between, between)
    cos_x = np.einsum("...c,...c->...", between, nx)  # times d: d^4 below divides both out
    cos_y = -np.einsum("...c,...c->...", between, ny)
    return np.where((cos_x > 0.0) & (cos_y > 0.0),
                    cos_x * cos_y / np.maximum(dist2 * dist2, np.finfo(np.float64).tiny), 0.0)


def paired_share_steps(x, nx, y, ny, weight, ray_offset: float) -> RayRequests:
    """Generator asking for its shadow rays (see `RayRequest`); returns (L,) the visible share of
    L sets of point pairs: points x (L, S, 3) with unit normals nx, targets y (L, S, 3) with ny
    (normals broadcastable to the points), one ray per pair between copies lifted by
    `ray_offset` m along the normals. Each ray counts with the point-to-point kernel
    cos_x cos_y / d^2 times its weight (L, S), so a target behind either horizon carries no
    weight instead of counting as blocked; 1 where no pair of a set has weight."""
    kernel = pair_kernel(y - x, nx, ny) * weight  # (L, S)
    start = np.broadcast_to(x + ray_offset * nx, y.shape)
    seg = (y + ray_offset * ny - start).reshape(-1, 3)
    length = np.sqrt(np.einsum("ij,ij->i", seg, seg))
    rays = np.flatnonzero((kernel.ravel() > 0.0) & (length > 0.0))
    blocked = np.zeros(seg.shape[0], bool)
    if rays.size:
        blocked[rays] = yield (start.reshape(-1, 3)[rays], seg[rays] / length[rays, None],
                               length[rays] * (1.0 - SHADOW_END_REL))
    total = kernel.sum(axis=1)
    seen = np.where(blocked.reshape(kernel.shape), 0.0, kernel).sum(axis=1)
    return np.divide(seen, total, out=np.ones_like(total), where=total > 0.0)


def _visible_fraction_steps(x, nx, y, wy, nj, ray_offset: float) -> RayRequests:
    """Generator asking for its shadow rays (see `RayRequest`); returns the (S, J) kernel-weighted
    visible fraction of J polygons from S points x (normals nx); y (J, M, 3), wy (J, M): the
    polygons' visibility points and weights, nj (J, 3) normals."""
    # The kernel from the surface points themselves; the rays between lifted copies of them.
    tiny = np.finfo(np.float64).tiny
    between = y[None] - x[:, None, None, :]  # (S, J, M, 3)
    dist = np.maximum(np.sqrt(np.einsum("sjmc,sjmc->sjm", between, between)), tiny)
    cos_x = np.einsum("sjmc,sc->sjm", between, nx) / dist
    cos_y = -np.einsum("sjmc,jc->sjm", between, nj) / dist
    kernel = np.where((cos_x > 0.0) & (cos_y > 0.0), cos_x * cos_y / (dist * dist), 0.0)
    kernel *= wy[None]
    origin = x + ray_offset * nx  # (S, 3)
    seg = (y + ray_offset * nj[:, None, :])[None] - origin[:, None, None, :]  # (S, J, M, 3)
    length = np.sqrt(np.einsum("sjmc,sjmc->sjm", seg, seg))
    safe = np.maximum(length, tiny)
    rays = np.flatnonzero(kernel.ravel() > 0.0)
    blocked = np.zeros(kernel.size, bool)
    if rays.size:
        dirs = (seg / safe[..., None]).reshape(-1, 3)[rays]
        origins = np.broadcast_to(origin[:, None, None, :], seg.shape).reshape(-1, 3)[rays]
        blocked[rays] = yield origins, dirs, length.ravel()[rays] * (1.0 - SHADOW_END_REL)
    total = kernel.sum(axis=2)
    seen = np.where(blocked.reshape(kernel.shape), 0.0, kernel).sum(axis=2)
    return np.divide(seen, total, out=np.zeros_like(total), where=total > 0.0)


class RayCastFormFactors:
    """Method B rows F_i* (see `RayCastSettings` and the module doc).

    | argument         | meaning                                                            |
    |------------------|--------------------------------------------------------------------|
    | corners          | (N, K, 3) patches                                                  |
    | occluded         | ray callback; None: the caller states no pair is occluded (a       |
    |                  | convex room), every factor is the closed form alone                |
    | triangles        | (T, 3, 3) the occluding scene, for the quick unoccluded-pair test  |
    |                  | (None: every pair with a nonzero factor is ray-tested)             |
    | known_unoccluded | (N, N) bool, pairs the caller knows are unoccluded                 |

    Near field. The points x_s integrate F_dx->j(x) over patch i; that integrand is bounded but
    varies within about dist(x, j) of patch j, so next to j (a shared edge, a T-junction, a block
    standing on a floor) an n x n rule is coarse. Two remedies: each pair is integrated over its
    smaller patch, the other entry following by reciprocity (`integrate_smaller`: F_ij =
    A_j F_ji / A_i when A_j < A_i, equal areas over the lower index), and near pairs take their
    unoccluded factor from a composite rule of near_field_cells^2 sub-squares. Every pair is
    integrated once, over fixed points, so A_i F_ij = A_j F_ji holds exactly, occluded or not;
    row sums in a closed box are then 1 up to the quadrature error rather than to rounding.
    Two equally large slivers touching along their short sides stay the hardest case (C-14 with
    w = h = 1: l = 0.1 -0.23%, l = 0.01 -12%): keep patches near square when meshing.
    """

    def __init__(
        self,
        corners: np.ndarray,
        occluded: Occluded | None = None,
        *,
        triangles: np.ndarray | None = None,
        known_unoccluded: np.ndarray | None = None,
        settings: RayCastSettings | None = None,
    ) -> None:
        self.corners = _as_corners(corners)
        self.geometry = g = patch_geometry(self.corners)
        self.occluded = occluded
        self.settings = s = settings or RayCastSettings()
        self.known_unoccluded = known_unoccluded
        self.ray_offset = RAY_OFFSET_REL * g.scale if s.ray_offset is None else s.ray_offset
        # Every patch's points (N, S, 3) and visibility points (N, M, 3), with weights, drawn
        # once: a pair integrated over patch j from row i (reverse) or from row j itself uses
        # the same points and rays.
        self.points, self.weights = sample_patches(
            self.corners, s.samples_per_side, s.source_rule, np.random.default_rng([s.seed, 1])
        )
        self.visibility_points, self.visibility_weights = sample_patches(
            self.corners, s.visibility_samples_per_side, s.visibility_rule,
            np.random.default_rng([s.seed, 2]),
        )
        self._lo = self.corners.min(axis=1)  # (N, 3) boxes, m
        self._hi = self.corners.max(axis=1)
        self._size = np.linalg.norm(self._hi - self._lo, axis=1)  # (N,) box diagonals, m
        self._sides = None
        self._fine: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # near-field points per patch
        if occluded is not None and triangles is not None and s.quick_test:
            self._sides = _SideClassifier(self.corners, np.asarray(triangles, np.float64))

    @property
    def areas(self) -> np.ndarray:
        return self.geometry.areas

    def maybe_occluded(self, i: int) -> np.ndarray:
        """(N,) bool: the pairs (i, j) that need rays (all False without `occluded`)."""
        count = len(self.corners)
        if self.occluded is None:
            return np.zeros(count, bool)
        mask = np.ones(count, bool)
        if self._sides is not None:
            mask &= self._sides.maybe_occluded(i)
        if self.known_unoccluded is not None:
            mask &= ~np.asarray(self.known_unoccluded[i], bool)
        return mask

    def integrated_over_target(self, i: int) -> np.ndarray:
        """(N,) bool: the pairs of row i integrated over the target patch j (then reciprocity)."""
        areas = self.geometry.areas
        if not self.settings.integrate_smaller:
            return np.zeros(len(areas), bool)
        tie = np.abs(areas - areas[i]) <= AREA_TIE_REL * areas[i]
        return np.where(tie, np.arange(len(areas)) < i, areas < areas[i])

    def near(self, i: int) -> np.ndarray:
        """(N,) bool: pairs whose boxes are closer than near_field_distance x the size of the
        patch they are integrated over (both rows of a pair agree)."""
        gap = np.maximum(np.maximum(self._lo - self._hi[i], self._lo[i] - self._hi), 0.0)
        size = np.where(self.integrated_over_target(i), self._size, self._size[i])
        return np.linalg.norm(gap, axis=1) < self.settings.near_field_distance * size

    def row(self, i: int, out: np.ndarray | None = None) -> np.ndarray:
        return answer_rays(self._row_steps(i, out), self.occluded, self.settings.max_rays_per_call)

    def rows(self, indices, out: np.ndarray) -> None:
        """Rows `indices` into out (len(indices), N): their shadow rays go out together, a few
        large ray-casting calls instead of one small call per row (each call costs milliseconds
        of set-up in the BVH, whatever its size)."""
        answer_rays_together([self._row_steps(int(i), out[k]) for k, i in enumerate(indices)],
                             self.occluded, self.settings.max_rays_per_call)

    def rows_per_batch(self) -> int:
        """Rows whose rays make about RAYS_PER_BATCH rays (at least one)."""
        s = self.settings
        per_row = len(self.corners) * s.samples_per_side**2 * s.visibility_samples_per_side**2
        return max(1, RAYS_PER_BATCH // max(per_row, 1))

    def _row_steps(self, i: int, out: np.ndarray | None = None) -> RayRequests:
        g = self.geometry
        rays = self.maybe_occluded(i)
        reverse = self.integrated_over_target(i)
        near = self.near(i)
        near[i] = False
        result = np.zeros(len(g.areas), np.float64) if out is None else out
        forward = np.flatnonzero(~reverse)
        unoccluded, visible = yield from raycast_gather_steps(
            self.points[i], g.normals[i], self.weights[i], self.corners[forward],
            g.normals[forward], self.occluded is not None, self.settings, None,
            ray_offset=self.ray_offset, maybe_occluded=rays[forward],
            target_samples=(self.visibility_points[forward], self.visibility_weights[forward]),
        )
        refine = near[forward]
        if refine.any() and self.settings.near_field_cells > 1:
            points, weights = self._fine_points(np.array([i]))
            unoccluded[refine] = weights[0] @ point_to_polygon(
                points[0][:, None, :], g.normals[i], self.corners[forward[refine]][None],
                g.normals[forward[refine]][None],
            )
        result[...] = 0.0
        result[forward] = unoccluded * visible
        targets = np.flatnonzero(reverse)
        if targets.size:
            result[targets] = yield from self._reverse(i, targets, rays[targets], near[targets])
        result[i] = 0.0  # a flat patch does not see itself
        return result

    def _reverse(
        self, i: int, targets: np.ndarray, rays: np.ndarray, near: np.ndarray
    ) -> RayRequests:
        """(J,) F_ij = A_j F_ji / A_i, F_ji integrated over the points of each target j."""
        g = self.geometry
        y = self.points[targets]  # (J, S, 3)
        ny = np.broadcast_to(g.normals[targets][:, None, :], y.shape)  # (J, S, 3)
        factors = point_to_polygon(y, ny, self.corners[i], g.normals[i])  # (J, S)
        wy = self.weights[targets]
        unoccluded = np.einsum("js,js->j", wy, factors)
        visible = np.ones(len(targets))
        traced = rays & (unoccluded > 0.0)  # rays is all False without `occluded`
        if traced.any():
            share = (yield from _visible_fraction_steps(
                y[traced].reshape(-1, 3), ny[traced].reshape(-1, 3),
                self.visibility_points[i : i + 1], self.visibility_weights[i : i + 1],
                g.normals[i : i + 1], self.ray_offset,
            )).reshape(-1, y.shape[1])
            visible[traced] = np.einsum("js,js->j", wy[traced], factors[traced] * share)
            visible[traced] /= unoccluded[traced]
        if near.any() and self.settings.near_field_cells > 1:
            points, weights = self._fine_points(targets[near])  # (J', S', 3), (J', S')
            normals = np.broadcast_to(g.normals[targets[near]][:, None, :], points.shape)
            fine = point_to_polygon(points, normals, self.corners[i], g.normals[i])
            unoccluded[near] = np.einsum("js,js->j", weights, fine)
        return unoccluded * visible * g.areas[targets] / g.areas[i]

    def _fine_points(self, patches: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The near-field rule's points (J, S', 3) and weights (J, S') of some patches; the
        same for a patch whichever row asks (stratified: seeded by the patch index)."""
        s = self.settings
        corners = self.corners[patches]
        if s.source_rule != "stratified":
            return sample_patches(corners, s.samples_per_side, s.source_rule, None,
                                  s.near_field_cells)
        parts = []
        for k, p in enumerate(patches):
            if int(p) not in self._fine:  # drawn once per patch: rows ask for the same points
                self._fine[int(p)] = sample_patches(
                    corners[k : k + 1], s.samples_per_side, "stratified",
                    np.random.default_rng([s.seed, 3, int(p)]), s.near_field_cells)
            parts.append(self._fine[int(p)])
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


class _SideClassifier:
    """Quick conservative test: which pairs (i, j) no scene triangle can come between.

    A triangle blocks no segment from patch i to patch j (grazing aside) when both patches lie in
    the same closed half-space of its plane, or when its box misses the box of the two patches
    (every segment lies in their convex hull). Memory: two (T, N) bool arrays.
    """

    def __init__(self, corners: np.ndarray, triangles: np.ndarray) -> None:
        flat = np.concatenate([corners.reshape(-1, 3), triangles.reshape(-1, 3)])
        eps = SIDE_EPS_REL * float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))
        normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0.0)
        signed = np.einsum("tc,nkc->tnk", normal, corners) - np.einsum(
            "tc,tc->t", normal, triangles[:, 0]
        )[:, None, None]  # (T, N, K) m
        self.front = np.all(signed >= -eps, axis=2)  # (T, N)
        self.back = np.all(signed <= eps, axis=2)
        self.tri_lo = triangles.min(axis=1) - eps  # (T, 3)
        self.tri_hi = triangles.max(axis=1) + eps
        self.patch_lo = corners.min(axis=1)  # (N, 3)
        self.patch_hi = corners.max(axis=1)

    def maybe_occluded(self, i: int) -> np.ndarray:
        """(N,) bool: pairs (i, j) some triangle might block."""
        same_side = (self.front[:, i, None] & self.front) | (self.back[:, i, None] & self.back)
        lo = np.minimum(self.patch_lo[i], self.patch_lo)  # (N, 3) box of i and j
        hi = np.maximum(self.patch_hi[i], self.patch_hi)
        overlap = np.all(
            (self.tri_lo[:, None, :] <= hi[None]) & (self.tri_hi[:, None, :] >= lo[None]), axis=2
        )  # (T, N)
        return np.any(overlap & ~same_side, axis=0)


# --- helpers -------------------------------------------------------------------------------------


def _check_rule(rule: str) -> None:
    if rule not in ("gauss", "stratified", "midpoint"):
        raise ValueError(f"sampling rule must be gauss, stratified or midpoint, got {rule!r}")


def _as_corners(corners: np.ndarray) -> np.ndarray:
    v = np.asarray(corners, np.float64)
    if v.ndim != 3 or v.shape[2] != 3 or v.shape[1] < 3:
        raise ValueError(f"patch corners must be (N, K >= 3, 3), got {v.shape}")
    return v


def _unpack_hits(hits: Any) -> tuple[np.ndarray, np.ndarray]:
    """(t, tri) from a callback result: a (t, tri) pair or an object with .t and .tri."""
    if hasattr(hits, "tri"):
        return np.asarray(hits.t), np.asarray(hits.tri)
    t, tri = hits
    return np.asarray(t), np.asarray(tri)
