"""Watertight ray-triangle intersection, vectorised, and a brute-force reference.

The test is Woop, Benthin and Wald, "Watertight Ray/Triangle Intersection" (JCGT 2013): each ray
gets a frame in which it runs along +z' from the origin; every triangle corner is moved into that
frame *once*, the same way for every triangle that shares it, and the ray hits the triangle when the
origin lies inside its 2D projection. The three 2D edge functions of a shared edge are computed from
the same corner coordinates by the same float operations, so the two triangles of an edge see
exactly opposite values: a ray through an edge or a vertex of a closed mesh hits at least one of its
triangles, never none. A rounded 2D edge function is either exactly signed or zero; zeros are
recomputed in float64, where the products of float32 numbers are exact.

Two more rules make the answer of any acceleration structure equal to the brute force, bit for bit:

* every triangle has a padded box (`PreparedTriangles.boxes`); a hit counts only where the ray
  crosses that box, and its distance is clamped into the box's slab interval. A BVH node's box
  contains its triangles' boxes, the slab test is monotone in the box planes, so a node holding a hit
  at distance t always tests as entered at or before t and left at or after t, and is never culled;
* ties (two triangles at the same distance, e.g. a ray through their shared edge) go to the lower
  triangle index.

Conventions: rays are origin + t * direction, t in units of |direction|, accepted on
[t_min, t_max] (closed). Barycentrics: `u` weighs corner 1, `v` corner 2, corner 0 gets 1 - u - v.
All arithmetic is float32 except the zero-edge fallback; float32 keeps distances within a relative
error of about 1e-6 of the float64 answer (tests/kernels/test_intersect.py states the bound it
checks).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

# Padding of triangle boxes, as a fraction of the scene's largest |coordinate|: room for the float32
# rounding of the corners moved into the ray frame (a few ulps of |corner - origin|), so an edge hit
# is never rejected by its own box for origins up to ~2^13 scene sizes away.
BOX_PAD_REL = 2.0**-16
# Smallest box padding, m: keeps boxes open when every coordinate is zero.
BOX_PAD_ABS = 1.0e-30
# A direction component smaller than this fraction of the largest one is replaced (sign kept) before
# its reciprocal is taken: the slab test then never forms 0 * inf = NaN, and the slab it describes
# still holds every hit closer than 2^40 times the box padding.
DIR_TINY_REL = 2.0**-40
# Rays processed at once by the brute-force reference: (rays x triangles) pairs per block.
BRUTE_FORCE_PAIRS = 1 << 20

INT32_MAX = np.iinfo(np.int32).max


@dataclass
class Hits:
    """Closest hits of R rays (filled with the miss values where a ray hits nothing).

    t:   (R,) float32, distance in units of |direction| (inf where missed)
    tri: (R,) int32, triangle index into the build input (-1 where missed)
    u:   (R,) float32, barycentric weight of corner 1 (0 where missed)
    v:   (R,) float32, barycentric weight of corner 2 (corner 0 gets 1 - u - v)
    """

    t: np.ndarray
    tri: np.ndarray
    u: np.ndarray
    v: np.ndarray

    @classmethod
    def empty(cls, count: int) -> Hits:
        """`count` misses."""
        return cls(
            t=np.full(count, np.inf, np.float32),
            tri=np.full(count, -1, np.int32),
            u=np.zeros(count, np.float32),
            v=np.zeros(count, np.float32),
        )

    def __len__(self) -> int:
        return int(self.t.shape[0])

    @property
    def hit(self) -> np.ndarray:
        """(R,) bool: whether each ray hit something."""
        return self.tri >= 0


@dataclass(frozen=True, eq=False)
class PreparedTriangles:
    """Triangles in the form every query reads.

    vertices: (T, 3, 3) float32, world, m: the input, rounded to float32 once
    boxes:    (2, 3, T) float32, world, m: padded lower (0) and upper (1) corners per axis
    valid:    (T,) bool: finite corners and non-zero area (the others never hit)
    """

    vertices: np.ndarray
    boxes: np.ndarray
    valid: np.ndarray

    @property
    def count(self) -> int:
        return int(self.vertices.shape[0])


def prepare_triangles(triangles: np.ndarray) -> PreparedTriangles:
    """Round (T, 3, 3) world-space triangles to float32 and give each a padded box."""
    tris = np.ascontiguousarray(np.asarray(triangles, np.float32).reshape(-1, 3, 3))
    with np.errstate(invalid="ignore", over="ignore"):
        t64 = tris.astype(np.float64)
        cross = np.cross(t64[:, 1] - t64[:, 0], t64[:, 2] - t64[:, 0])
        area2 = np.einsum("ij,ij->i", cross, cross)
        valid = np.isfinite(tris).all(axis=(1, 2)) & (area2 > 0.0) & np.isfinite(area2)
    finite = tris[valid]
    scale = float(np.abs(finite).max()) if finite.size else 0.0
    pad = np.float32(max(BOX_PAD_REL * scale, BOX_PAD_ABS))
    lo = tris.min(axis=1)  # (T, 3)
    hi = tris.max(axis=1)
    # Round the padded planes outwards: the box must contain the unpadded one exactly.
    lo = np.nextafter(lo - pad, np.float32(-np.inf))
    hi = np.nextafter(hi + pad, np.float32(np.inf))
    boxes = np.ascontiguousarray(np.stack([lo.T, hi.T]))  # (2, 3, T)
    boxes[:, :, ~valid] = np.nan
    return PreparedTriangles(vertices=tris, boxes=boxes, valid=valid)


@dataclass(frozen=True, eq=False)
class Rays:
    """R rays in the form the tests read: one (12, R) float32 table and two per-ray arrays.

    table rows 0..2  origin:   world, m
               3..5  inv_dir:  1 / direction, near-zero components replaced (slab test)
               6..8  origin_k: the origin's components in ray-frame order (kx, ky, kz)
               9..11 shear:    Woop's (Sx, Sy, Sz): d[kx]/d[kz], d[ky]/d[kz], 1/d[kz]
    kz:    (R,) int8, the ray frame's z axis: the largest |direction| component
    valid: (R,) bool, finite origin and finite, non-zero direction (the others never hit)
    """

    table: np.ndarray
    kz: np.ndarray
    valid: np.ndarray

    origin = property(lambda self: self.table[0:3])
    inv_dir = property(lambda self: self.table[3:6])
    origin_k = property(lambda self: self.table[6:9])
    shear = property(lambda self: self.table[9:12])

    @property
    def count(self) -> int:
        return int(self.kz.shape[0])


def prepare_rays(
    origins: np.ndarray, directions: np.ndarray, out: np.ndarray | None = None
) -> Rays:
    """Per-ray constants of the watertight test and the slab test, from (R, 3) arrays.

    out: an optional (12, R) float32 array (rows may be a view) that becomes `Rays.table`.
    """
    o = np.asarray(origins, np.float32).reshape(-1, 3)
    d = np.asarray(directions, np.float32).reshape(-1, 3)
    count = o.shape[0]
    table = np.empty((12, count), np.float32) if out is None else out
    table[0:3] = o.T
    dx, dy, dz = d.T.copy()
    ox, oy, oz = table[0], table[1], table[2]
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        ax, ay, az = np.abs(dx), np.abs(dy), np.abs(dz)
        # The largest |component| (the first of equals), as np.argmax would pick it.
        x_top = (ax >= ay) & (ax >= az)
        y_top = ~x_top & (ay >= az)
        z_top = ~(x_top | y_top)
        kz = np.where(x_top, 0, np.where(y_top, 1, 2)).astype(np.int8)
        dmax = np.maximum(np.maximum(ax, ay), az)
        omax = np.maximum(np.maximum(np.abs(ox), np.abs(oy)), np.abs(oz))  # NaN stays NaN
        valid = np.isfinite(omax) & np.isfinite(dmax) & (dmax > 0.0)

        def frame(vx, vy, vz, out):
            """Components in ray-frame order: kz = x -> (y, z, x), y -> (z, x, y), z -> (x, y, z)."""
            np.copyto(out[0], np.where(x_top, vy, np.where(y_top, vz, vx)))
            np.copyto(out[1], np.where(x_top, vz, np.where(y_top, vx, vy)))
            np.copyto(out[2], np.where(x_top, vx, np.where(y_top, vy, vz)))

        frame(ox, oy, oz, table[6:9])
        shear = table[9:12]
        frame(dx, dy, dz, shear)
        shear[2] = np.where(valid, shear[2], np.float32(1.0))
        shear[0] /= shear[2]
        shear[1] /= shear[2]
        np.divide(np.float32(1.0), shear[2], out=shear[2])
        tiny = np.where(valid, dmax, np.float32(1.0)) * np.float32(DIR_TINY_REL)
        for axis, (dc, ac) in enumerate(((dx, ax), (dy, ay), (dz, az))):
            safe = np.where(ac < tiny, np.copysign(tiny, dc), dc)
            np.divide(np.float32(1.0), safe, out=table[3 + axis])
    del z_top
    if not valid.all():
        table[:, ~valid] = 0.0
        table[3:6, ~valid] = 1.0
    return Rays(table=table, kz=kz, valid=valid)


def ray_frame_corners(
    corners: np.ndarray, origin_k: np.ndarray, shear: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Move triangle corners into the ray frame (Woop's translate, permute and shear).

    corners:  (3, 3, ...) float32, [corner, axis in ray-frame order (kx, ky, kz), ...]
    origin_k: (3, ...) float32, the ray origin in ray-frame order, broadcast against corners[0]
    shear:    (3, ...) float32, (Sx, Sy, Sz), broadcast likewise
    Returns X, Y (3, ...) float32 (2D positions, ray at the origin) and the kz differences
    A_kz (3, ...) float32 (still to be scaled by Sz for distances).
    """
    a = corners - origin_k  # (3 corners, 3 axes, ...): corner - origin, ray-frame order
    az = a[:, 2]
    x = a[:, 0] - shear[0] * az
    y = a[:, 1] - shear[1] * az
    return x, y, az


def edge_functions(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Woop's U, V, W: twice the signed areas of the origin with each edge, in the ray frame.

    U (edge 1-2) weighs corner 0, V (edge 2-0) corner 1, W (edge 0-1) corner 2. x, y: (3, ...).
    """
    u = x[2] * y[1] - y[2] * x[1]
    v = x[0] * y[2] - y[0] * x[2]
    w = x[1] * y[0] - y[1] * x[0]
    return u, v, w


def inside(u: np.ndarray, v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Whether the edge functions do not disagree in sign (NaN never counts as inside)."""
    lo = np.minimum(np.minimum(u, v), w)
    hi = np.maximum(np.maximum(u, v), w)
    return (lo >= 0.0) | (hi <= 0.0)


def raw_distance(
    u: np.ndarray, v: np.ndarray, w: np.ndarray, az: np.ndarray, sz: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Woop's determinant U + V + W and the distance T / det (inf or NaN where det = 0).

    u, v, w: float32 edge functions; az: (3, ...) kz differences of the corners; sz: Woop's Sz.
    Elementwise, so it gives the same bits on full arrays and on gathered candidates.
    """
    det = u + v + w
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        t = (u * (sz * az[0]) + v * (sz * az[1]) + w * (sz * az[2])) / det
    return det, t


def finish_candidates(
    u: np.ndarray,
    v: np.ndarray,
    w: np.ndarray,
    az: np.ndarray,
    sz: np.ndarray,
    box: np.ndarray,
    origin: np.ndarray,
    inv_dir: np.ndarray,
    t_min: np.ndarray,
    recheck: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Distances and barycentrics of K candidate (ray, triangle) pairs that passed `inside`.

    u, v, w: (K,) float32 edge functions; az: (3, K) kz differences; sz: (K,) Woop's Sz;
    box: (2, 3, K) the triangles' padded boxes; origin, inv_dir: (3, K); t_min: (K,).
    recheck(index) returns the ray-frame corners x, y (3, n) of candidates `index`: the pairs with
    a zero edge function, whose signs are recomputed exactly in float64.
    Returns (ok, t, u, v), each (K,). A pair is rejected where det = 0, the distance T / det is
    not finite or below t_min, the exact edge signs disagree, or the ray misses the triangle's
    box. t is clamped into the box's slab interval (so a BVH node holding the triangle is entered
    no later and left no earlier), then checked against t_min again.
    """
    det, t = raw_distance(u, v, w, az, sz)
    ok = (det != 0.0) & np.isfinite(t) & (t >= t_min)
    zero = ok & ((u == 0.0) | (v == 0.0) | (w == 0.0))
    if zero.any():
        # Products of float32 numbers are exact in float64: these signs are exact.
        index = np.flatnonzero(zero)
        x, y = recheck(index)
        ok[index] = inside(*edge_functions(x.astype(np.float64), y.astype(np.float64)))
    near, far = slab(box, origin, inv_dir)
    ok &= near <= far
    # Clamp into the box; adding +0 turns -0.0 into +0.0 (callers order hits by t's bits).
    t = np.minimum(np.maximum(t, near), far) + np.float32(0.0)
    ok &= t >= t_min
    with np.errstate(divide="ignore", invalid="ignore"):
        return ok, t, v / det, w / det


def slab(box: np.ndarray, origin: np.ndarray, inv_dir: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Entry and exit distances of rays through axis-aligned boxes (NaN boxes are never entered).

    box: (2, 3, ...) float32 lower/upper corners; origin, inv_dir: (3, ...) broadcast against box[0].
    Returns (near, far), each box[0, 0]'s broadcast shape; the ray crosses the box where near <= far.
    Monotone in the planes: a box containing another gets near <= and far >= the other's.
    """
    t = (box - origin) * inv_dir  # (2, 3, ...)
    lo = np.minimum(t[0], t[1])
    hi = np.maximum(t[0], t[1])
    near = np.maximum(np.maximum(lo[0], lo[1]), lo[2])
    far = np.minimum(np.minimum(hi[0], hi[1]), hi[2])
    return near, far


def _as_ray_array(value, count: int, name: str) -> np.ndarray:
    """A scalar or (R,) array of distances as an (R,) float32 array."""
    arr = np.asarray(value, np.float32)
    if arr.ndim == 0:
        return np.full(count, arr, np.float32)
    if arr.shape != (count,):
        raise ValueError(f"{name} must be a scalar or have shape ({count},), got {arr.shape}")
    return arr


def ray_limits(t_min, t_max, count: int) -> tuple[np.ndarray, np.ndarray]:
    """(t_min, t_max) as (R,) float32 arrays; t_min must be >= 0."""
    # Adding +0 turns -0.0 into +0.0: distances are compared through their bits downstream.
    lo = _as_ray_array(t_min, count, "t_min") + np.float32(0.0)
    hi = _as_ray_array(t_max, count, "t_max") + np.float32(0.0)
    if np.any(lo < 0.0) or np.isnan(lo).any():
        raise ValueError("t_min must be >= 0")
    return lo, hi


def corners_in_ray_order(vertices: np.ndarray, kz: np.ndarray) -> np.ndarray:
    """Corners of K pairs in ray-frame axis order (kx, ky, kz).

    vertices: (K, 3, 3) float32 [pair, corner, axis]; kz: (K,) each pair's ray-frame z axis.
    Returns (3, 3, K) float32 [corner, ray-frame axis, pair].
    """
    k = np.arange(vertices.shape[0])
    kz = kz.astype(np.intp)
    axes = ((kz + 1) % 3, (kz + 2) % 3, kz)
    return np.stack([np.stack([vertices[k, c, a] for a in axes]) for c in range(3)])


def _pairs(
    prepared: PreparedTriangles,
    rays: Rays,
    ray_idx: np.ndarray,
    tri_idx: np.ndarray,
    t_min: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Test K (ray, triangle) pairs. Returns (ray_idx, tri_idx, t, u, v) of the pairs that hit."""
    kz = rays.kz[ray_idx]
    corners = corners_in_ray_order(prepared.vertices[tri_idx], kz)  # (3, 3, K)
    shear = rays.shear[:, ray_idx]
    x, y, az = ray_frame_corners(corners, rays.origin_k[:, ray_idx], shear)
    u, v, w = edge_functions(x, y)
    _, t_raw = raw_distance(u, v, w, az, shear[2])
    cand = np.flatnonzero(inside(u, v, w) & (t_raw >= t_min[ray_idx]))
    ray_c = ray_idx[cand]
    tri_c = tri_idx[cand]
    ok, t, bu, bv = finish_candidates(
        u[cand],
        v[cand],
        w[cand],
        az[:, cand],
        shear[2, cand],
        prepared.boxes[:, :, tri_c],
        rays.origin[:, ray_c],
        rays.inv_dir[:, ray_c],
        t_min[ray_c],
        lambda i: (x[:, cand[i]], y[:, cand[i]]),
    )
    return ray_c[ok], tri_c[ok], t[ok], bu[ok], bv[ok]


def _brute_force_pairs(
    prepared: PreparedTriangles, origins: np.ndarray, directions: np.ndarray, t_min, t_max
):
    """Yield the hits (ray, tri, t, u, v) of every ray against every valid triangle, in blocks."""
    rays = prepare_rays(origins, directions)
    lo, hi = ray_limits(t_min, t_max, rays.count)
    tris = np.flatnonzero(prepared.valid)
    live = np.flatnonzero(rays.valid & (lo <= hi))
    if tris.size == 0 or live.size == 0:
        return rays.count, lo, hi, []
    block = max(1, BRUTE_FORCE_PAIRS // tris.size)
    found = []
    for start in range(0, live.size, block):
        r = live[start : start + block]
        ray_idx = np.repeat(r, tris.size)
        tri_idx = np.tile(tris, r.size)
        hit = _pairs(prepared, rays, ray_idx, tri_idx, lo)
        keep = hit[2] <= hi[hit[0]]
        found.append(tuple(a[keep] for a in hit))
    return rays.count, lo, hi, found


def intersect_all(
    triangles: np.ndarray | PreparedTriangles,
    origins: np.ndarray,
    directions: np.ndarray,
    t_min=0.0,
    t_max=np.inf,
) -> Hits:
    """Brute-force closest hits: every ray against every triangle (the reference for the BVH).

    The closest hit on [t_min, t_max] wins; equal distances go to the lower triangle index.
    """
    prepared = triangles if isinstance(triangles, PreparedTriangles) else prepare_triangles(triangles)
    count, _, _, found = _brute_force_pairs(prepared, origins, directions, t_min, t_max)
    hits = Hits.empty(count)
    if not found:
        return hits
    ray, tri, t, u, v = (np.concatenate(parts) for parts in zip(*found, strict=True))
    if ray.size == 0:
        return hits
    # Lexicographic (ray, t, tri): the first entry of each ray is its closest hit.
    order = np.lexsort((tri, t, ray))
    ray, tri, t, u, v = ray[order], tri[order], t[order], u[order], v[order]
    first = np.r_[True, ray[1:] != ray[:-1]]
    r = ray[first]
    hits.t[r] = t[first]
    hits.tri[r] = tri[first]
    hits.u[r] = u[first]
    hits.v[r] = v[first]
    return hits


def occluded_all(
    triangles: np.ndarray | PreparedTriangles,
    origins: np.ndarray,
    directions: np.ndarray,
    t_min=0.0,
    t_max=np.inf,
) -> np.ndarray:
    """Brute-force occlusion: (R,) bool, whether any triangle is hit on [t_min, t_max]."""
    prepared = triangles if isinstance(triangles, PreparedTriangles) else prepare_triangles(triangles)
    count, _, _, found = _brute_force_pairs(prepared, origins, directions, t_min, t_max)
    result = np.zeros(count, bool)
    for ray, *_ in found:
        result[ray] = True
    return result
