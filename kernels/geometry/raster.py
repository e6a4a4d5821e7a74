"""Triangle rasterisation into a depth buffer: the z-buffer of the lecture's shadow mapping.

Step 1 of the lecture's shadow mapping: "Put the viewer at the light position L, render the scene to
the z-buffer to create a shadow map: it contains the z-values of all points that can be seen from L"
(lecture 13, "4. Shadow Mapping"). This module is that z-buffer renderer, in pure NumPy.

Conventions
-----------
* View space: the viewer looks down its local -Z with +X right and +Y up (OpenGL's and Blender's
  camera convention); `look_at` builds the world -> view matrix.
* Image: (H, W), row 0 at the TOP (the project's image convention). Pixel (i, j) samples its centre:
  NDC x = -1 + 2 (j + 0.5) / W and y = 1 - 2 (i + 0.5) / H; NDC (-1, -1) is the bottom-left corner.
* Depth space: **linear view depth** d = -z_view in metres (the distance from the viewer's eye plane
  along its forward axis), float32, +inf where nothing was drawn. Not NDC z, because (1) the
  shadow test and its tolerance eps are then in metres, the unit of shadow_bias.json's world-space
  bias; (2) float32 keeps the same relative precision (2^-24) at every distance, whereas NDC z is
  hyperbolic in d and crowds its precision next to the near plane, so a tiny near plane costs
  nothing here; (3) on a cube face the view depth of a point p is |ma|, the major-axis component of
  p - eye in the OpenGL cube-map table, so the six faces agree on where they meet. Depth is
  interpolated exactly: 1/d is affine in screen space under perspective (d itself under
  orthographic projection); the interpolation plane is set up from unsnapped float64 vertices and
  evaluated at pixel centres.

Coverage
--------
Vertices are snapped to 1/256 pixel (SUBPIXEL_BITS) and edge functions are evaluated in exact int64
arithmetic at pixel centres, with the top-left fill rule of Direct3D 10 ("Rasterization Rules",
Microsoft docs): a centre exactly on an edge belongs to the triangle only when that edge is a top
edge (horizontal, the triangle below it) or a left edge. Since an edge shared by two triangles has
exactly negated integer edge functions and exactly one of its two orientations is top-left, a mesh
that tiles a region covers every pixel centre inside it exactly once: no cracks, no double coverage.

Clipping: triangles are clipped in homogeneous space against the near and far planes and against
side planes GUARD_PIXELS outside the viewport (Sutherland-Hodgman, one triangle into at most two per
plane). An intersection on an edge is always computed from the inside vertex towards the outside
one, so two triangles that share the edge get bit-identical new vertices, and clip-made edges on the
side planes lie outside every pixel centre. Degenerate (zero snapped area) and non-finite triangles
cover nothing.

Speed and memory
----------------
Triangles are set up (clipped, snapped, wound) in batches of TRIANGLE_CHUNK. Each pixel row of a
triangle's box is then solved for its span of covered centres in closed form from the three integer
edge functions (`_spans`), and only covered pixels are generated: no pixel is tested and rejected
(faster than testing power-of-two pixel windows per triangle for small and screen-sized triangles
alike, with the same bits; bench/shadowmap.py). Spans are solved MAX_SPANS pixel rows at a time
and turned into pixels CHUNK_FRAGMENTS at a time, so temporary memory is bounded independently of
the triangle count and the resolution: peaks (tracemalloc) above the buffer at 2048^2 of 26 MB
for two triangles covering every pixel, 35 MB for 100k and 27 MB for 1M small triangles.
Views of one size, near and far plane (a cube map's six faces) can be drawn in one batch
(`rasterize_views_steps`): each triangle carries its view's clip matrix and pixel offset, so the
set-up and the spans are paid once, not once per view.
The depth test is `np.minimum.at` on the flat float32 buffer: for 8M fragments into 2048^2 pixels
it is several times faster than a sort of packed (pixel, depth) keys.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..progress import Steps, drain
from .vec import cross3, max_of_three, min_of_three

ProjectionKind = Literal["PERSP", "ORTHO"]
CullMode = Literal["NONE", "BACK", "FRONT"]

SUBPIXEL_BITS = 8  # 1/256 pixel vertex snapping (as GPUs do): exact integer edge functions
SUBPIXEL_STEPS = 1 << SUBPIXEL_BITS  # positions a pixel is cut into
_ONE = SUBPIXEL_STEPS  # one pixel in fixed point
_HALF = _ONE // 2  # half a pixel: the pixel-centre offset in fixed point
GUARD_PIXELS = 2.0  # side clip planes this far outside the viewport: clip-made edges miss centres
CHUNK_FRAGMENTS = 1 << 19  # covered pixels generated per vectorised step: ~60 B each
MAX_SPANS = 1 << 17  # pixel rows of triangles solved at once: ~150 B each
TRIANGLE_CHUNK = 1 << 15  # triangles set up at once: ~1 kB each while clipping
MAX_RESOLUTION = 1 << 15  # px per side: keeps fixed-point edge products below 2^53, far from 2^63


# --------------------------------------------------------------------------------------------
# Projection
# --------------------------------------------------------------------------------------------


def look_at(eye: np.ndarray, forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """World -> view matrix (4, 4) float64 of a viewer at `eye` looking along `forward`.

    The view looks down -Z with +Y towards `up` (made orthogonal to `forward`) and
    +X = forward x up (right-handed). `forward` and `up` need not be unit, nor parallel.
    """
    f = np.asarray(forward, np.float64)
    f = f / np.linalg.norm(f)
    right = cross3(f, up)
    norm = np.linalg.norm(right)
    if norm == 0.0:
        raise ValueError("look_at: `up` is parallel to `forward`")
    right /= norm
    true_up = cross3(right, f)
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = right, true_up, -f
    view[:3, 3] = -view[:3, :3] @ np.asarray(eye, np.float64)
    return view


@dataclass(frozen=True, eq=False)
class Projection:
    """A perspective or orthographic viewer: what the shadow map is rendered from.

    | field  | range             | unit                                                         |
    |--------|-------------------|--------------------------------------------------------------|
    | kind   | "PERSP", "ORTHO"  | pinhole or parallel projection                               |
    | view   | rigid (4, 4)      | world -> view matrix, float64 (see `look_at`)                |
    | extent | left<right, b<top | image-plane rectangle: at distance 1 (PERSP), metres (ORTHO) |
    | near   | PERSP: (0, far)   | m, view depth of the near clip plane                         |
    | far    | > near            | m, view depth of the far clip plane                          |
    """

    kind: ProjectionKind
    view: np.ndarray  # (4, 4) float64, world -> view (looks down -Z, +Y up)
    extent: tuple[float, float, float, float]  # (left, right, bottom, top)
    near: float
    far: float

    def __post_init__(self) -> None:
        left, right, bottom, top = self.extent
        if not (right > left and top > bottom and self.far > self.near):
            raise ValueError(
                f"empty projection: extent {self.extent}, near/far {self.near}/{self.far}"
            )
        if self.kind == "PERSP" and self.near <= 0.0:
            raise ValueError("a perspective projection needs near > 0")

    @classmethod
    def perspective(
        cls, view: np.ndarray, fov: float, near: float, far: float, aspect: float = 1.0
    ) -> Projection:
        """Symmetric frustum: `fov` is the full vertical angle (rad), `aspect` = width / height."""
        top = float(np.tan(0.5 * fov))
        return cls("PERSP", np.asarray(view, np.float64), (-top * aspect, top * aspect, -top, top),
                   float(near), float(far))

    @classmethod
    def orthographic(
        cls, view: np.ndarray, extent: tuple[float, float, float, float], near: float, far: float
    ) -> Projection:
        """Parallel projection of the view-space box `extent` (m) x [near, far] (view depth, m)."""
        return cls("ORTHO", np.asarray(view, np.float64), tuple(float(e) for e in extent),
                   float(near), float(far))

    @property
    def clip_matrix(self) -> np.ndarray:
        """(4, 4) float64: world homogeneous point -> (xc, yc, d, w).

        NDC is (xc / w, yc / w) in [-1, 1]^2 over the image; d is the linear view depth (m); w = d
        for PERSP and w = 1 for ORTHO. Unlike OpenGL's projection matrix the third row carries the
        linear depth, not NDC z (see the module docstring for why).
        """
        left, right, bottom, top = self.extent
        sx, sy = 2.0 / (right - left), 2.0 / (top - bottom)
        ox, oy = (right + left) / (right - left), (top + bottom) / (top - bottom)
        if self.kind == "PERSP":  # xc = sx x_v - ox d, with d = -z_v and w = d
            proj = np.array([[sx, 0, ox, 0], [0, sy, oy, 0], [0, 0, -1, 0], [0, 0, -1, 0]], float)
        else:
            proj = np.array([[sx, 0, 0, -ox], [0, sy, 0, -oy], [0, 0, -1, 0], [0, 0, 0, 1]], float)
        return proj @ self.view


def _to_clip(points: np.ndarray, matrix: np.ndarray) -> np.ndarray:
    """(..., 3) world points -> (..., 4) float64 clip coordinates.

    Written elementwise (no BLAS) so that a vertex shared by two triangles maps to bit-identical
    coordinates wherever it sits in the array: the no-crack guarantee depends on it.
    """
    p = points.astype(np.float64, copy=False)
    x, y, z = p[..., 0], p[..., 1], p[..., 2]
    if matrix.ndim == 3:  # (T, 4, 4): one matrix per triangle of (T, 3, 3) points, same bits
        m = matrix[:, :, :, None]  # each entry (T, 1) against the (T, 3) corners
        rows = [m[:, r, 0] * x + m[:, r, 1] * y + m[:, r, 2] * z + m[:, r, 3] for r in range(4)]
    else:
        rows = [matrix[r, 0] * x + matrix[r, 1] * y + matrix[r, 2] * z + matrix[r, 3]
                for r in range(4)]
    return np.stack(rows, axis=-1)


def project_points(
    points: np.ndarray, projection: Projection, width: int, height: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where world points land in a (height, width) map of `projection`, and at what depth.

    Returns `col, row, depth`, each (N,) float64: continuous pixel coordinates (pixel (i, j) spans
    [j, j + 1) x [i, i + 1), so its centre is (j + 0.5, i + 0.5); row 0 at the top) and the linear
    view depth in metres, the quantity `rasterize` stores. Points behind a perspective eye
    (depth <= 0) get NaN coordinates. The depth stays float64 (the map stores it as float32).
    """
    clip = _to_clip(np.asarray(points, np.float64).reshape(-1, 3), projection.clip_matrix)
    depth = clip[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(clip[:, 3] > 0.0, clip[:, 3], np.nan)
        col = (clip[:, 0] / w + 1.0) * (0.5 * width)
        row = (1.0 - clip[:, 1] / w) * (0.5 * height)
    return col, row, depth


# --------------------------------------------------------------------------------------------
# Clipping (homogeneous space)
# --------------------------------------------------------------------------------------------


def _plane_distances(v: np.ndarray, plane: int, near: float, far: float, gx: float, gy: float):
    """Signed distance (>= 0 inside) of (..., 4) clip vertices to one of the six clip planes."""
    xc, yc, d, w = v[..., 0], v[..., 1], v[..., 2], v[..., 3]
    if plane == 0:
        return d - near
    if plane == 1:
        return far - d
    if plane == 2:
        return gx * w + xc
    if plane == 3:
        return gx * w - xc
    if plane == 4:
        return gy * w + yc
    return gy * w - yc


def _lerp_out(v_in: np.ndarray, v_out: np.ndarray, d_in: np.ndarray, d_out: np.ndarray):
    """Point where the edge from an inside vertex to an outside one crosses the plane.

    Always parameterised from the inside vertex: both triangles of a shared edge get the same bits.
    """
    t = (d_in / (d_in - d_out))[:, None]
    return v_in + t * (v_out - v_in)


def _clip_triangles(v: np.ndarray, ids: np.ndarray, projection: Projection, width: int,
                    height: int) -> tuple[np.ndarray, np.ndarray]:
    """Clip (T, 3, 4) clip-space triangles to the guard-banded frustum, keeping the winding."""
    gx = 1.0 + 2.0 * GUARD_PIXELS / width  # NDC half-width of the guard-banded viewport
    gy = 1.0 + 2.0 * GUARD_PIXELS / height
    near, far = projection.near, projection.far
    dist = np.stack([_plane_distances(v, k, near, far, gx, gy) for k in range(6)], axis=-1)
    inside = dist >= 0.0  # (T, 3, 6)
    all_in = inside.all(axis=(1, 2))
    all_out_one = (~inside).all(axis=1).any(axis=1)  # every vertex beyond one plane: invisible
    straddle = ~all_in & ~all_out_one
    if not straddle.any():
        return v[all_in], ids[all_in]
    kept_v, kept_ids = [v[all_in]], [ids[all_in]]
    cv, cid = v[straddle], ids[straddle]
    rot_keep = np.array([[0, 1, 2], [1, 2, 0], [2, 0, 1]])  # cyclic rotations keep the winding
    for plane in range(6):
        if len(cv) == 0:
            break
        d = _plane_distances(cv, plane, near, far, gx, gy)  # (n, 3)
        ins = d >= 0.0
        n_in = ins[:, 0].astype(np.int64) + ins[:, 1] + ins[:, 2]
        parts_v, parts_id = [cv[n_in == 3]], [cid[n_in == 3]]
        for count in (1, 2):
            sel = np.nonzero(n_in == count)[0]
            if len(sel) == 0:
                continue
            # Rotate so that the odd vertex (the lone inside one, or the lone outside one) is first.
            odd = np.argmax(ins[sel] if count == 1 else ~ins[sel], axis=1)
            order = rot_keep[odd]
            tv = cv[sel[:, None], order]  # (m, 3, 4)
            td = d[sel[:, None], order]  # (m, 3)
            a, b, c = tv[:, 0], tv[:, 1], tv[:, 2]
            if count == 1:  # a inside: one triangle (a, ab, ac)
                ab = _lerp_out(a, b, td[:, 0], td[:, 1])
                ac = _lerp_out(a, c, td[:, 0], td[:, 2])
                parts_v.append(np.stack([a, ab, ac], axis=1))
                parts_id.append(cid[sel])
            else:  # a outside, b and c inside: quad (b, c, ca, ab) as two triangles
                ca = _lerp_out(c, a, td[:, 2], td[:, 0])
                ab = _lerp_out(b, a, td[:, 1], td[:, 0])
                parts_v.append(np.stack([b, c, ca], axis=1))
                parts_v.append(np.stack([b, ca, ab], axis=1))
                parts_id.extend([cid[sel], cid[sel]])
        cv, cid = np.concatenate(parts_v), np.concatenate(parts_id)
    kept_v.append(cv)
    kept_ids.append(cid)
    return np.concatenate(kept_v), np.concatenate(kept_ids)


# --------------------------------------------------------------------------------------------
# Triangle setup
# --------------------------------------------------------------------------------------------


@dataclass
class _Setup:
    """Per-triangle rasterisation constants (T' screen triangles after clipping and culling)."""

    tri: np.ndarray  # (T',) int64, input triangle index
    edge_a: np.ndarray  # (T', 3) int64, E_k = a X + b Y + c over fixed-point pixel coordinates
    edge_b: np.ndarray  # (T', 3) int64
    edge_c: np.ndarray  # (T', 3) int64, includes the fill-rule bias
    plane: np.ndarray  # (T', 5) float64, attribute = p0 col + p1 row + p2 (pixel units), and
    #                    its range [p3, p4] over the vertices
    box: np.ndarray  # (T', 4) int64, inclusive pixel ranges (j0, j1, i0, i1)
    perspective: bool  # the attribute is 1 / depth (PERSP) or the depth itself (ORTHO)
    base: np.ndarray | None = None  # (T',) int64 first pixel of each one's view (views batched)


def _setup(tris: np.ndarray, first: int, projection: Projection, width: int, height: int,
           cull: CullMode, views: tuple[np.ndarray, np.ndarray] | None = None) -> _Setup:
    """Clip, project, snap, cull and wind (T, 3, 3) world triangles numbered from `first`.

    `views`: (clip matrices (V, 4, 4), view of each triangle (T,)) to draw triangles into several
    views of one size, near and far at once (`projection` gives those); `base` then holds each
    triangle's first pixel in the (V, H, W) buffer."""
    finite = np.isfinite(tris).all(axis=(1, 2))
    ids = np.nonzero(finite)[0].astype(np.int64) + first
    matrix = projection.clip_matrix if views is None else views[0][views[1][finite]]
    clip = _to_clip(tris[finite], matrix)  # (T, 3, 4) float64
    clip, ids = _clip_triangles(clip, ids, projection, width, height)
    # Screen space: col to the right, row downwards, in pixels (float64), then fixed point.
    w = clip[..., 3]
    col = (clip[..., 0] / w + 1.0) * (0.5 * width)
    row = (1.0 - clip[..., 1] / w) * (0.5 * height)
    attr = 1.0 / w if projection.kind == "PERSP" else clip[..., 2]  # affine in screen space
    fx = np.rint(col * _ONE).astype(np.int64)  # (T, 3) fixed point
    fy = np.rint(row * _ONE).astype(np.int64)
    ex1, ey1 = fx[:, 1] - fx[:, 0], fy[:, 1] - fy[:, 0]
    ex2, ey2 = fx[:, 2] - fx[:, 0], fy[:, 2] - fy[:, 0]
    area2 = ex1 * ey2 - ey1 * ex2  # twice the signed area, exact int64
    # area2 < 0: counter-clockwise as the viewer sees it (rows point down), i.e. front-facing.
    keep = area2 != 0
    if cull == "BACK":
        keep &= area2 < 0
    elif cull == "FRONT":
        keep &= area2 > 0
    flip = area2[keep] < 0
    fx, fy, col, row, attr, ids = fx[keep], fy[keep], col[keep], row[keep], attr[keep], ids[keep]
    # Wind every triangle so that area2 > 0: its interior is where all three edge functions are > 0.
    for arr in (fx, fy, col, row, attr):
        arr[flip, 1], arr[flip, 2] = arr[flip, 2].copy(), arr[flip, 1].copy()

    # Edge k runs from vertex k+1 to vertex k+2 (opposite vertex k):
    # E(p) = (bx - ax)(py - ay) - (by - ay)(px - ax) = A px + B py + C.
    ax_, ay_ = fx[:, [1, 2, 0]], fy[:, [1, 2, 0]]
    bx_, by_ = fx[:, [2, 0, 1]], fy[:, [2, 0, 1]]
    edge_a = ay_ - by_
    edge_b = bx_ - ax_
    edge_c = -(edge_a * ax_ + edge_b * ay_)
    # Top-left rule: a centre on an edge is inside only for a left edge (A > 0: the interior is to
    # its right) or a top edge (A == 0 and B > 0: horizontal with the interior below, rows down).
    top_left = (edge_a > 0) | ((edge_a == 0) & (edge_b > 0))
    edge_c = edge_c - (~top_left).astype(np.int64)  # integer E >= 1 for the other edges

    # Attribute plane from the unsnapped float64 vertices (exact depth at every pixel centre).
    e1c, e1r = col[:, 1] - col[:, 0], row[:, 1] - row[:, 0]
    e2c, e2r = col[:, 2] - col[:, 0], row[:, 2] - row[:, 0]
    det = e1c * e2r - e1r * e2c
    det = np.where(det == 0.0, 1.0, det)  # snapped area was nonzero; a zero here means a sliver
    da1, da2 = attr[:, 1] - attr[:, 0], attr[:, 2] - attr[:, 0]
    pc = (da1 * e2r - da2 * e1r) / det
    pr = (da2 * e1c - da1 * e2c) / det
    plane = np.stack([pc, pr, attr[:, 0] - pc * col[:, 0] - pr * row[:, 0],
                      min_of_three(attr), max_of_three(attr)], axis=1)

    # Pixel-centre bounding boxes: centre j + 1/2 in [min col, max col].
    j0 = -((-(min_of_three(fx) - _HALF)) // _ONE)
    j1 = (max_of_three(fx) - _HALF) // _ONE
    i0 = -((-(min_of_three(fy) - _HALF)) // _ONE)
    i1 = (max_of_three(fy) - _HALF) // _ONE
    box = np.stack([np.maximum(j0, 0), np.minimum(j1, width - 1),
                    np.maximum(i0, 0), np.minimum(i1, height - 1)], axis=1)
    ok = (box[:, 1] >= box[:, 0]) & (box[:, 3] >= box[:, 2])
    base = None if views is None else views[1][ids[ok] - first] * (width * height)
    return _Setup(ids[ok], edge_a[ok], edge_b[ok], edge_c[ok], plane[ok], box[ok],
                  projection.kind == "PERSP", base)


# --------------------------------------------------------------------------------------------
# Spans: the covered pixels of one triangle on one pixel row, solved from the edge functions
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Spans:
    """(P,) pixel rows of triangles, each with its covered columns lo .. lo + count - 1."""

    row: np.ndarray  # setup row (triangle) of each span, int64
    i: np.ndarray  # pixel row, int64
    lo: np.ndarray  # first covered pixel column, int64
    count: np.ndarray  # covered pixels, int64 >= 1

    def __getitem__(self, part: slice) -> _Spans:
        return _Spans(self.row[part], self.i[part], self.lo[part], self.count[part])


def _spans(s: _Setup, start: int, stop: int) -> _Spans:
    """The non-empty spans of setup rows start..stop-1, every pixel row of their boxes.

    A centre (j, i) is covered when E_k = A (j ONE + HALF) + B (i ONE + HALF) + C >= 0 for k = 0..2,
    i.e. A ONE j >= R with R = -(B py + C) - A HALF: an exact integer bound on j, from below when
    A > 0 (j >= ceil(R / (A ONE))), from above when A < 0 (j <= floor(R / (A ONE))), and all or
    nothing when A = 0 (R <= 0). Only covered pixels are generated afterwards: no candidate tests.
    """
    heights = s.box[start:stop, 3] - s.box[start:stop, 2] + 1
    row = np.repeat(np.arange(start, stop), heights)
    i = s.box[row, 2] + (np.arange(len(row)) - np.repeat(np.cumsum(heights) - heights, heights))
    py = i * _ONE + _HALF  # fixed-point centres
    lo = s.box[row, 0]
    hi = s.box[row, 1]
    for k in range(3):
        a = s.edge_a[row, k]
        r = -(s.edge_b[row, k] * py + s.edge_c[row, k]) - a * _HALF
        step = np.where(a == 0, 1, a * _ONE)
        lo = np.maximum(lo, np.where(a > 0, -((-r) // step), lo))
        # a < 0: an upper bound; a = 0: the whole row or none of it
        hi = np.minimum(hi, np.where(a < 0, r // step, np.where((a > 0) | (r <= 0), hi, -1)))
    count = hi - lo + 1
    keep = count > 0
    return _Spans(row[keep], i[keep], lo[keep], count[keep])


def _span_fragments(s: _Setup, sp: _Spans, width: int) -> Fragments:
    """Every pixel of the spans, with its depth from the triangle's attribute plane."""
    count = sp.count
    j = np.arange(int(count.sum())) + np.repeat(sp.lo - (np.cumsum(count) - count), count)
    plane = s.plane[sp.row]  # (P, 5)
    # (p0 (j + 1/2) + p2) + p1 (i + 1/2), in this order: every pixel gets the same bits whatever
    # the batching
    attr = np.repeat(plane[:, 0], count) * (j + 0.5)
    attr += np.repeat(plane[:, 2], count)
    attr += np.repeat(plane[:, 1] * (sp.i + 0.5), count)
    # A covered centre may lie up to 1/512 px outside the unsnapped triangle, where the plane of a
    # sliver (an edge-on caster) extrapolates wildly: clamp to the range of the vertices' values.
    np.maximum(attr, np.repeat(plane[:, 3], count), out=attr)
    np.minimum(attr, np.repeat(plane[:, 4], count), out=attr)
    depth = np.divide(1.0, attr, out=attr) if s.perspective else attr
    first_pixel = sp.i * width
    if s.base is not None:
        first_pixel += s.base[sp.row]
    j += np.repeat(first_pixel, count)  # now the flat pixel index
    return Fragments(j, depth, np.repeat(s.tri[sp.row], count))


@dataclass(frozen=True)
class Fragments:
    """Covered pixel centres of one chunk of triangles (F fragments)."""

    pixel: np.ndarray  # (F,) int64, flat index row * width + col (row 0 at the top)
    depth: np.ndarray  # (F,) float64, linear view depth, m
    triangle: np.ndarray  # (F,) int64, index into the input triangles


def iter_fragments(
    triangles: np.ndarray,
    projection: Projection,
    width: int,
    height: int,
    cull: CullMode = "NONE",
) -> Iterator[tuple[Fragments, float]]:
    """Rasterise (T, 3, 3) world triangles; yield (fragments of one chunk, progress in [0, 1]).

    Every covered pixel centre of every triangle is reported once per triangle (no depth test):
    `rasterize` reduces them to a z-buffer, `coverage_count` counts them.

    | parameter  | range                   | unit / meaning                                       |
    |------------|-------------------------|------------------------------------------------------|
    | triangles  | (T, 3, 3), any float    | m, world; non-finite triangles are skipped           |
    | projection | Projection              | the viewer                                           |
    | width      | [1, MAX_RESOLUTION]     | px                                                   |
    | height     | [1, MAX_RESOLUTION]     | px                                                   |
    | cull       | "NONE", "BACK", "FRONT" | drop triangles wound clockwise (BACK) or counter-    |
    |            |                         | clockwise (FRONT) as the viewer sees them            |
    """
    if not (1 <= width <= MAX_RESOLUTION and 1 <= height <= MAX_RESOLUTION):
        raise ValueError(f"resolution {width}x{height} outside [1, {MAX_RESOLUTION}]")
    tris = np.asarray(triangles)
    if tris.ndim != 3 or tris.shape[1:] != (3, 3):
        raise ValueError(f"triangles must be (T, 3, 3), got {tris.shape}")
    yield from _fragments(tris, projection, width, height, cull, None)


def _fragments(tris: np.ndarray, projection: Projection, width: int, height: int, cull: CullMode,
               views: tuple[np.ndarray, np.ndarray] | None) -> Iterator[tuple[Fragments, float]]:
    """`iter_fragments`, optionally into several views at once (see `_setup`)."""
    batches = range(0, len(tris), TRIANGLE_CHUNK)
    for b, first in enumerate(batches):
        part = slice(first, first + TRIANGLE_CHUNK)
        s = _setup(tris[part], first, projection, width, height, cull,
                   None if views is None else (views[0], views[1][part]))
        rows_end = np.cumsum(s.box[:, 3] - s.box[:, 2] + 1)  # pixel rows of triangles 0..t
        start = 0
        while start < len(rows_end):  # triangles with at most ~MAX_SPANS pixel rows in all
            before = rows_end[start - 1] if start else 0
            stop = max(start + 1, int(np.searchsorted(rows_end, before + MAX_SPANS, "right")))
            sp = _spans(s, start, stop)
            ends = np.cumsum(sp.count)
            a = 0
            while a < len(ends):  # spans with at most ~CHUNK_FRAGMENTS pixels in all
                z = max(a + 1, int(np.searchsorted(ends, (ends[a - 1] if a else 0) + CHUNK_FRAGMENTS,
                                                   "right")))
                yield _span_fragments(s, sp[a:z], width), (b + stop / len(rows_end)) / len(batches)
                a = z
            start = stop
    yield Fragments(np.zeros(0, np.int64), np.zeros(0), np.zeros(0, np.int64)), 1.0


# --------------------------------------------------------------------------------------------
# Z-buffer
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RasterResult:
    depth: np.ndarray  # (H, W) float32, linear view depth (m), +inf where empty
    triangle: np.ndarray | None  # (H, W) int64, nearest triangle index, -1 where empty


def rasterize_steps(
    triangles: np.ndarray,
    projection: Projection,
    depth_out: np.ndarray,
    triangle_out: np.ndarray | None = None,
    cull: CullMode = "NONE",
    clear: bool = True,
) -> Steps[RasterResult]:
    """Z-buffer (T, 3, 3) world triangles into caller-owned buffers; yields progress in [0, 1],
    returns the buffers as a `RasterResult`.

    `depth_out` (H, W) float32 receives the nearest linear view depth (m), +inf where nothing is
    drawn; `triangle_out` (H, W) int64, if given, the index of the triangle seen there (-1 where
    empty; among exactly equal depths the smallest index). With `clear=False` the buffers keep what
    they hold and the triangles are depth-tested against it (several draws into one z-buffer).
    """
    if depth_out.dtype != np.float32 or depth_out.ndim != 2:
        raise ValueError("depth_out must be an (H, W) float32 array")
    height, width = depth_out.shape
    flat = depth_out.reshape(-1)  # a view: fails loudly below if depth_out is not contiguous
    if not np.may_share_memory(flat, depth_out):
        raise ValueError("depth_out must be C-contiguous")
    ids = None
    if triangle_out is not None:
        if triangle_out.shape != depth_out.shape or triangle_out.dtype != np.int64:
            raise ValueError("triangle_out must be (H, W) int64 like depth_out")
        ids = triangle_out.reshape(-1)
        if not np.may_share_memory(ids, triangle_out):
            raise ValueError("triangle_out must be C-contiguous")
    if clear:
        flat.fill(np.inf)
        if ids is not None:
            ids.fill(-1)
    for frags, progress in iter_fragments(triangles, projection, width, height, cull):
        if len(frags.pixel):
            depth = frags.depth.astype(np.float32)
            if ids is None:
                np.minimum.at(flat, frags.pixel, depth)
            else:
                before = flat[frags.pixel]
                np.minimum.at(flat, frags.pixel, depth)
                win = depth == flat[frags.pixel]
                ids[frags.pixel[win & (depth < before)]] = np.iinfo(np.int64).max
                np.minimum.at(ids, frags.pixel[win], frags.triangle[win])
        yield progress
    return RasterResult(depth_out, triangle_out)


def rasterize_views_steps(triangles: np.ndarray, view_of: np.ndarray,
                          projections: tuple[Projection, ...], depth_out: np.ndarray
                          ) -> Steps[np.ndarray]:
    """Z-buffer (T, 3, 3) world triangles, triangle k into view view_of[k], into the (V, H, W)
    float32 `depth_out` (depth-tested against what it holds); yields progress in [0, 1], returns
    `depth_out`.

    One set-up and one pass of spans for all views (a cube map's faces: the same size,
    near and far, only the rotation differs) instead of one per view; every pixel gets the same
    bits as `rasterize_steps` of each view's own triangles would give it.
    """
    count, height, width = depth_out.shape
    if depth_out.dtype != np.float32 or len(projections) != count:
        raise ValueError("depth_out must be (V, H, W) float32 with one projection per view")
    first = projections[0]
    if any((p.kind, p.near, p.far) != (first.kind, first.near, first.far) for p in projections):
        raise ValueError("batched views must share their projection kind, near and far")
    flat = depth_out.reshape(-1)
    if not np.may_share_memory(flat, depth_out):
        raise ValueError("depth_out must be C-contiguous")
    matrices = np.stack([p.clip_matrix for p in projections])
    tris = np.asarray(triangles)
    view_of = np.asarray(view_of, np.int64)
    for frags, progress in _fragments(tris, first, width, height, "NONE", (matrices, view_of)):
        if len(frags.pixel):
            np.minimum.at(flat, frags.pixel, frags.depth.astype(np.float32))
        yield progress
    return depth_out


def rasterize(
    triangles: np.ndarray,
    projection: Projection,
    width: int,
    height: int,
    cull: CullMode = "NONE",
    with_triangle_ids: bool = False,
) -> RasterResult:
    """Z-buffer (T, 3, 3) world triangles; see `rasterize_steps` (this drains it)."""
    depth = np.empty((height, width), np.float32)
    tri = np.empty((height, width), np.int64) if with_triangle_ids else None
    return drain(rasterize_steps(triangles, projection, depth, tri, cull))


def coverage_count(
    triangles: np.ndarray, projection: Projection, width: int, height: int,
    cull: CullMode = "NONE",
) -> np.ndarray:
    """(H, W) int32: how many triangles cover each pixel centre (fill-rule and crack checks)."""
    count = np.zeros(width * height, np.int64)
    for frags, _ in iter_fragments(triangles, projection, width, height, cull):
        count += np.bincount(frags.pixel, minlength=width * height)
    return count.reshape(height, width).astype(np.int32)
