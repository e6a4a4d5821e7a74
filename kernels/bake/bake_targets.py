"""Where a bake is evaluated: lightmap texel centres and mesh corners, as world points and normals.

A lightmap texel (i, j) (row 0 at the top) belongs to the triangle whose lightmap-UV footprint
covers its centre u = (j + 0.5) / W, v = 1 - (i + 0.5) / H (moved by Blender's `BAKE_SAMPLE_SHIFT`,
a few thousandths of a texel: `SAMPLE_SHIFT`), and is baked there. Texels no triangle
covers are "unbaked": `dilate` fills the padding ring around the charts from their baked
neighbours so bilinear lookups at chart edges never read black.

Texel filter. Cycles takes a bake's first sample at the texel centre and jitters every later one
uniformly over the texel, retrying until it lands inside the texel's own triangle (its
`bake_jitter_barycentric`): a converged Cycles texel is the mean over texel ∩ triangle, a box
filter. Where the baked function is linear across a texel that mean is the centre value; where it
jumps (a block standing on the floor, a hard shadow edge) the centre alone is off by the whole
step: 0 against Cycles' half-lit 0.15 in a texel the block's edge crosses. `box_filter` finds those
texels from the centre values (a second difference along a row or column of the image, relative
to the texels' level) and replaces each by the mean over k^2 sub-texel points of its triangle,
placed as n rooks (`rook_offsets`): no two share a row or a column of the texel, so the many
steps that run along a chart's axes (xatlas lays a rectangular face square to the texels: a
wall meeting the floor, a block's foot) are found to 1 / (2 k^2) of the texel, not 1 / (2 k).
Finding the covering triangle is rasterisation in UV space: the lightmap is an orthographic image
of the UV triangles, drawn by `raster.py` with its top-left rule (no texel claimed twice). Where
UV triangles overlap (a packer's sliver across other charts) the last triangle of the mesh wins,
as in Blender's bake, which writes every covered texel in triangle order without a depth test.

Lattice interpolation (irradiance caching on the lightmap's grid: Ward, Rubinstein and Clear
1988, with the cache points on a regular lattice). A bake is evaluated first at the texels of
even row and column, a quarter of them (`lattice_plan`). Every other texel lies halfway between
two or four of those; it takes their mean when (`lattice_fill`) all of them are baked, they lie on
the same flat piece of surface as the texel (the texel sits at their midpoint in the world too,
and their normals agree: no chart seam or fold between them), and their values differ by at most
`lattice_threshold` of their mean (no edge, shadow boundary or steep fall-off between them). The
rest are evaluated. What the lattice can miss is a feature that fits between two lattice texels
without touching either, narrower than two texels: the bake's resolution was too coarse for it
anyway.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..geometry.raster import SUBPIXEL_STEPS, Projection, rasterize
from ..geometry.scene import Scene, geometric_normals, interpolated_normals

# Barycentric coordinates are clamped to [0, 1] after solving: texel centres on a shared edge may
# land a rounding error outside the triangle the rasteriser gave them to.
BARY_CLAMP = (0.0, 1.0)
# Where in a texel Blender's bake takes its first sample, in texels from the centre along +u and
# +v: it rasterises the UV triangles moved by (-0.501, -0.502) texels onto pixel corners (its
# bake.cc, against texel centres landing exactly on pixel-aligned edges, its bug #18685), so
# texel (x, y), y counted from the bottom, is sampled at ((x + 0.501) / W, (y + 0.502) / H).
BAKE_SAMPLE_SHIFT = (0.001, 0.002)
# Ours: the rasteriser snaps vertices to 1 / SUBPIXEL_STEPS of a texel, which would round that
# shift away. Scaled until its smaller part is one step, (1/256, 2/256) texels, it keeps its
# direction and breaks every tie alike (an edge along it would need a slope of exactly 2).
SAMPLE_SHIFT = tuple(s / (min(BAKE_SAMPLE_SHIFT) * SUBPIXEL_STEPS) for s in BAKE_SAMPLE_SHIFT)
# Texels darker than this fraction of the object's brightest are compared as if this bright: their
# differences do not show, and relative to their own level they would flag every bit of noise.
EDGE_FLOOR_REL = 1e-3
# A texel is interpolated from its lattice neighbours only when it lies this close (relative to
# its distance from them) to their midpoint in the world: on one plane and chart the UV map is
# affine and the midpoint is exact up to rounding (~1e-7); across a seam it is off by metres and
# across a fold of angle a by about a / 4 (1e-2: folds above ~2 degrees are evaluated).
LATTICE_MIDPOINT_REL = 1e-2
# ... and when its normal and theirs are this parallel (cos 2.6 degrees): a crease between them
# bends the light's cosine, which the mean of the two sides does not follow.
LATTICE_NORMAL_COS = 0.999
# The texel filter's k^2 points (auto) where every edge is a ramp a few texels wide (area lights'
# penumbrae, contact shading): the ramp's mean over a texel is close to its 4 points' mean.
# Cornell box lightmaps (300 patches, rook points): relMSE 0.00227 unfiltered; 0.00159 with 4
# points, 0.00153 with 16 and 0.00148 with 36 for 0.02 and 0.07 s more (a 0.13 s bake).
SOFT_EDGE_SAMPLES = 2
# ... and where lamps cast hard shadows: a step through a texel, whose covered fraction k^2 rook
# points find to about 1 / (2 k^2). Defaults, 64-texel lightmaps, relMSE against 256-sample
# Cycles bakes with 16 / 36 / 64 points: shadows.blend (sun, spot and point lamp)
# 0.00073 / 0.00066 / 0.00065, raytrace.blend 3.1e-4 / 1.0e-4 / 3.3e-5, a lamp-lit room of
# default materials 0.00141 / 0.00102 / 0.00092; the bakes' seconds 0.06 / 0.07 / 0.09, 0.14 /
# 0.29 / 0.51, 0.09 / 0.12 / 0.18 (after a 0.3-1.4 s solve).
HARD_EDGE_SAMPLES = 6


@dataclass(frozen=True)
class TexelFilterSettings:
    """| field            | range | default | meaning                                          |
    |------------------|-------|---------|--------------------------------------------------|
    | samples_per_side | >= 0  | 0       | k: k^2 sub-texel points (`rook_offsets`)         |
    |                  |       |         | averaged in an edge texel                        |
    |                  |       |         | (1: centre values only, no filter; 0 auto:       |
    |                  |       |         | `resolved` by the bake, HARD_EDGE_SAMPLES where  |
    |                  |       |         | lamps cast hard shadows, else SOFT_EDGE_SAMPLES) |
    | edge_threshold   | > 0   | 0.5     | |left + right - 2 centre| over the three texels' |
    |                  |       |         | mean (or |neighbour - centre| over the two's     |
    |                  |       |         | mean at a chart border) that marks an edge texel |
    | lattice_threshold| >= 0  | 0.1     | largest (max - min) / mean of the lattice texels |
    |                  |       |         | a texel between them is interpolated from        |
    |                  |       |         | (module docstring; 0: every texel evaluated)     |
    """

    samples_per_side: int = 0
    edge_threshold: float = 0.5
    lattice_threshold: float = 0.1

    def __post_init__(self) -> None:
        if self.samples_per_side < 0 or not self.edge_threshold > 0.0:
            raise ValueError("samples_per_side must be >= 0 and edge_threshold > 0")
        if not self.lattice_threshold >= 0.0:
            raise ValueError("lattice_threshold must be >= 0")

    def resolved(self, hard_edges: bool) -> TexelFilterSettings:
        """These settings with auto's k x k chosen: HARD_EDGE_SAMPLES when the bake has hard
        shadow edges (steps that cross texels anywhere), else SOFT_EDGE_SAMPLES."""
        if self.samples_per_side:
            return self
        return replace(self, samples_per_side=HARD_EDGE_SAMPLES if hard_edges else SOFT_EDGE_SAMPLES)


@dataclass(frozen=True, eq=False)
class BakeTargets:
    """N points to evaluate a bake at, and where their values go back.

    points       (N, 3) float64  world, m
    normals      (N, 3) float64  interpolated shading normals, unit
    geo_normals  (N, 3) float64  face normals of the triangles, unit
    triangles    (N,) int64      scene triangle of each point
    bary         (N, 3) float64  barycentric weights of each point in its triangle
    Lightmaps: `mask` (H, W) bool marks the baked texels, `rows`/`cols` (N,) their indices.
    Corners: `corner_index` (N,) int64 = scene triangle * 3 + corner.
    """

    points: np.ndarray
    normals: np.ndarray
    geo_normals: np.ndarray
    triangles: np.ndarray
    bary: np.ndarray
    mask: np.ndarray | None = None
    rows: np.ndarray | None = None
    cols: np.ndarray | None = None
    corner_index: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.points.shape[0])

    def to_image(self, values: np.ndarray, fill: float = 0.0) -> np.ndarray:
        """Scatter (N, C) or (N,) values into an (H, W, C) float32 lightmap; unbaked texels = fill."""
        values = np.asarray(values, np.float32)
        if values.ndim == 1:
            values = values[:, None]
        height, width = self.mask.shape
        image = np.full((height, width, values.shape[1]), fill, np.float32)
        image[self.rows, self.cols] = values
        return image


def lightmap_targets(scene: Scene, object_index: int, resolution: int) -> BakeTargets:
    """The texels of object `object_index`'s square lightmap (`resolution`^2) that it covers."""
    if scene.lightmap_uv is None:
        raise ValueError("the scene snapshot has no lightmap UVs (request them by name)")
    sl = scene.object_slice(object_index)
    texels = uv_texels(scene.lightmap_uv[sl], resolution, resolution)
    return _targets(scene, sl.start + texels.triangles, texels.bary, mask=texels.mask,
                    rows=texels.rows, cols=texels.cols)


@dataclass(frozen=True, eq=False)
class UVTexels:
    """The texels of a (H, W) map that UV triangles cover, and where in them each is baked.

    mask       (H, W) bool     covered texels
    rows, cols (N,) int64      their indices, row 0 at the top
    triangles  (N,) int64      the UV triangle (index into the input) each is baked on
    bary       (N, 3) float64  barycentric weights of the texel's sample point in it
    """

    mask: np.ndarray
    rows: np.ndarray
    cols: np.ndarray
    triangles: np.ndarray
    bary: np.ndarray


def uv_texels(uv_triangles: np.ndarray, width: int, height: int) -> UVTexels:
    """Which UV triangle (T, 3, 2) each texel of a (height, width) map is baked on, sampled where
    Blender's bake samples (`SAMPLE_SHIFT`), overlaps going to the last triangle as in Blender."""
    uv = np.asarray(uv_triangles, np.float64)  # (T, 3, 2)
    # Sampled where Blender's bake samples: the triangles moved back by the shift, so the
    # rasteriser's texel centres meet them at centre + shift (and an edge through a centre,
    # common on grid meshes, gives the texel to the triangle Cycles bakes it from).
    shift = np.array(SAMPLE_SHIFT) / np.array([width, height])  # uv units
    tris_uv = np.concatenate([uv - shift, -np.ones(uv.shape[:2] + (1,))], axis=2)  # depth 1
    projection = Projection.orthographic(np.eye(4), (0.0, 1.0, 0.0, 1.0), 0.5, 1.5)
    # Drawn in reverse: the rasteriser gives a tie to the lowest id, Blender's bake to the last
    # triangle it draws (each overwrites the texels it covers), so overlaps go where it puts them.
    raster = rasterize(tris_uv[::-1].astype(np.float32), projection, width, height,
                       with_triangle_ids=True)
    mask = raster.triangle >= 0  # (H, W)
    rows, cols = np.nonzero(mask)
    tri_local = len(uv) - 1 - raster.triangle[rows, cols].astype(np.int64)
    centre = np.stack([(cols + 0.5) / width, 1.0 - (rows + 0.5) / height], 1) + shift
    bary = _barycentric_2d(uv[tri_local], centre)
    return UVTexels(mask=mask, rows=rows, cols=cols, triangles=tri_local, bary=bary)


def edge_texels(targets: BakeTargets, values: np.ndarray, threshold: float) -> np.ndarray:
    """(N,) bool: texels of lightmap `targets` whose centre value (N, C) or (N,) departs from a
    straight line through their neighbours along a row or a column (`TexelFilterSettings`)."""
    level = np.asarray(values, np.float64).reshape(len(targets), -1).mean(axis=1)
    image = np.zeros(targets.mask.shape)
    image[targets.rows, targets.cols] = level
    floor = EDGE_FLOOR_REL * max(float(level.max(initial=0.0)), 1e-300)
    mask = targets.mask
    edge = np.zeros_like(mask)
    for axis in (0, 1):
        before, after = _shifted(image, 1, axis), _shifted(image, -1, axis)
        has_before, has_after = _shifted(mask, 1, axis), _shifted(mask, -1, axis)
        both = mask & has_before & has_after
        mean3 = np.maximum((before + after + image) / 3.0, floor)
        edge |= both & (np.abs(before + after - 2.0 * image) > threshold * mean3)
        for other, has in ((before, has_before), (after, has_after)):
            one = mask & has & ~both
            edge |= one & (np.abs(other - image) > threshold * np.maximum((other + image) / 2.0, floor))
    return edge[targets.rows, targets.cols]


@dataclass(frozen=True, eq=False)
class LatticePlan:
    """Which texels of a lightmap a bake evaluates first, and what the others lie between.

    first    (L,) int64     positions into the targets: texels of even row and column
    rest     (R,) int64     the other texels
    sources  (R, 4) int64   positions of the (up to four, repeated) lattice texels around each of
                            `rest`, -1 where one is not baked or falls outside the image
    affine   (R,) bool      all sources exist, and the texel is their midpoint on one flat piece
                            of surface (LATTICE_MIDPOINT_REL, LATTICE_NORMAL_COS)
    """

    first: np.ndarray
    rest: np.ndarray
    sources: np.ndarray
    affine: np.ndarray


def lattice_plan(targets: BakeTargets) -> LatticePlan:
    """The lattice of lightmap `targets` (module docstring): evaluate `first`, then `lattice_fill`."""
    height, width = targets.mask.shape
    rows, cols = targets.rows, targets.cols
    on = (rows % 2 == 0) & (cols % 2 == 0)
    first, rest = np.flatnonzero(on), np.flatnonzero(~on)
    index = np.full((height + 1, width + 1), -1, np.int64)  # one row and column of -1 past the end
    index[rows, cols] = np.arange(len(targets))
    r, c = rows[rest], cols[rest]
    # Odd coordinates take the lattice lines on both sides, even ones their own line twice.
    r0, r1, c0, c1 = r - r % 2, r + r % 2, c - c % 2, c + c % 2
    sources = np.stack([index[r0, c0], index[r0, c1], index[r1, c0], index[r1, c1]], axis=1)
    affine = (sources >= 0).all(axis=1)
    got = np.flatnonzero(affine)
    src = sources[got]
    points, here = targets.points[src], targets.points[rest[got]][:, None]  # (G, 4, 3), (G, 1, 3)
    span = np.linalg.norm(points - here, axis=2).max(axis=1)
    off = np.linalg.norm(points.mean(axis=1) - here[:, 0], axis=1)
    cos = np.einsum("gkj,gj->gk", targets.normals[src], targets.normals[rest[got]]).min(axis=1)
    affine[got] = (off <= LATTICE_MIDPOINT_REL * span) & (cos >= LATTICE_NORMAL_COS)
    return LatticePlan(first, rest, sources, affine)


def lattice_fill(plan: LatticePlan, first_values: np.ndarray, threshold: float,
                 out: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Every texel's value (N, C) from the lattice's, first_values (L, C): the lattice texels
    themselves, the mean of their sources where `plan.affine` and the sources' (max - min) is at
    most `threshold` of their mean in every channel (EDGE_FLOOR_REL of the brightest as a floor);
    zero elsewhere. Returns the values and the positions (into the targets) still to evaluate."""
    first_values = np.asarray(first_values, np.float64)
    if first_values.ndim == 1:
        first_values = first_values[:, None]
    count = len(plan.first) + len(plan.rest)
    if out is None:
        out = np.zeros((count, first_values.shape[1]))
    out[...] = 0.0
    out[plan.first] = first_values
    got = np.flatnonzero(plan.affine)
    vals = out[plan.sources[got]]  # (G, 4, C): only lattice texels are read, all set above
    mean = vals.mean(axis=1)
    floor = EDGE_FLOOR_REL * max(float(first_values.max(initial=0.0)), 1e-300)
    smooth = (np.ptp(vals, axis=1) <= threshold * np.maximum(mean, floor)).all(axis=1)
    out[plan.rest[got[smooth]]] = mean[smooth]
    todo = np.ones(len(plan.rest), bool)
    todo[got[smooth]] = False
    return out, plan.rest[todo]


def _shifted(a: np.ndarray, step: int, axis: int) -> np.ndarray:
    """a[i - step] along `axis` (2-D), zero (False) where that falls outside the image."""
    out = np.zeros_like(a)
    size = a.shape[axis]
    src, dst = [slice(None)] * 2, [slice(None)] * 2
    src[axis] = slice(max(-step, 0), size - max(step, 0))
    dst[axis] = slice(max(step, 0), size - max(-step, 0))
    out[tuple(dst)] = a[tuple(src)]
    return out


def grid_offsets(k: int) -> tuple[np.ndarray, np.ndarray]:
    """(k^2,) and (k^2,) offsets across and down a texel, 0..1 from its top-left corner: the
    centres of a k x k grid of equal cells (a texture bake's cells tile the texel)."""
    offset = (np.arange(k) + 0.5) / k
    du, dv = np.meshgrid(offset, offset)
    return du.ravel(), dv.ravel()


def rook_offsets(k: int) -> tuple[np.ndarray, np.ndarray]:
    """(k^2,) and (k^2,) offsets across and down a texel for n = k^2 points, 0..1 from its top-left
    corner: the Hammersley set (i + 1/2) / n against the base-2 radical inverse of i, its values
    replaced by their ranks so that both columns are evenly spaced for any n. No two points
    share a column or a row (n rooks), so a step along either axis, such as the line where a
    wall meets the floor in an xatlas chart, is found to 1 / (2n) of the texel, where a k x k
    grid finds it to 1 / (2k) only; for n = 2^m every k x k cell holds one point as well (a
    (0, m, 2)-net)."""
    n = k * k
    i = np.arange(n)
    radical, bit, rest = np.zeros(n), 0.5, i.copy()
    while rest.any():
        radical += bit * (rest & 1)
        rest >>= 1
        bit *= 0.5
    rank = np.empty(n)
    rank[np.argsort(radical, kind="stable")] = i
    return (i + 0.5) / n, (rank + 0.5) / n


def subtexel_points(scene: Scene, targets: BakeTargets, which: np.ndarray, k: int,
                    pattern=grid_offsets) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """k^2 points over each lightmap texel `which` (M,) indexes, placed by `pattern` (k ->
    offsets across and down the texel: `grid_offsets`, `rook_offsets`), kept where they lie in
    the texel's own triangle (as Cycles keeps its jittered samples). Returns owner (P,) int64
    positions into `which`, triangles (P,) int64 and barycentrics (P, 3) float64."""
    height, width = targets.mask.shape
    tri = targets.triangles[which]
    uv = scene.lightmap_uv[tri].astype(np.float64)  # (M, 3, 2)
    du, dv = pattern(k)
    u = (targets.cols[which][:, None] + du) / width  # (M, k^2)
    v = 1.0 - (targets.rows[which][:, None] + dv) / height
    points = np.stack([u, v], axis=-1).reshape(-1, 2)
    bary = _barycentric_2d(np.repeat(uv, k * k, axis=0), points, clamp=False).reshape(-1, k * k, 3)
    inside = (bary >= 0.0).all(axis=-1)
    owner = np.broadcast_to(np.arange(len(which))[:, None], inside.shape)[inside]
    return owner.astype(np.int64), tri[owner], bary[inside]


@dataclass(frozen=True, eq=False)
class FilterSamples:
    """The sub-texel points of a lightmap's edge texels (`filter_samples`).

    which      (M,) int64    edge texels, positions into the targets
    owner      (P,) int64    each point's position into `which`
    triangles  (P,) int64    scene triangle of each point
    bary       (P, 3)        barycentric weights of each point in its triangle
    """

    which: np.ndarray
    owner: np.ndarray
    triangles: np.ndarray
    bary: np.ndarray


def filter_samples(scene: Scene, targets: BakeTargets, values: np.ndarray,
                   settings: TexelFilterSettings = TexelFilterSettings()  # noqa: B008
                   ) -> FilterSamples:
    """Where `box_filter` evaluates the bake again for lightmap `targets` with centre values
    (N, C): k x k points in every edge texel (`edge_texels`), none when k = 1."""
    none = np.zeros(0, np.int64)
    settings = settings.resolved(hard_edges=False)  # a caller that knows of none: auto is soft
    if settings.samples_per_side <= 1 or len(targets) == 0:
        return FilterSamples(none, none, none, np.zeros((0, 3)))
    which = np.flatnonzero(edge_texels(targets, values, settings.edge_threshold))
    if which.size == 0:
        return FilterSamples(which, none, none, np.zeros((0, 3)))
    return FilterSamples(which, *subtexel_points(scene, targets, which, settings.samples_per_side,
                                                 rook_offsets))


def apply_box_filter(values: np.ndarray, samples: FilterSamples, sampled: np.ndarray
                     ) -> tuple[np.ndarray, int]:
    """Centre values (N, C) with each edge texel replaced by the mean of the bake at its points,
    sampled (P, C). Returns the values and how many texels were replaced."""
    values = np.array(values, copy=True)
    if samples.which.size == 0:
        return values, 0
    which = samples.which
    sums = np.zeros((len(which),) + values.shape[1:])
    np.add.at(sums, samples.owner, sampled)
    counts = np.bincount(samples.owner, minlength=len(which))
    got = counts > 0  # a triangle thinner than the sub-texel spacing keeps its centre value
    values[which[got]] = sums[got] / counts[got].reshape((-1,) + (1,) * (values.ndim - 1))
    return values, int(got.sum())


def box_filter(scene: Scene, targets: BakeTargets, values: np.ndarray, evaluate,
               settings: TexelFilterSettings = TexelFilterSettings()  # noqa: B008
               ) -> tuple[np.ndarray, int]:
    """Centre values (N, C) of lightmap `targets` with every edge texel (`edge_texels`) replaced by
    its mean over texel ∩ triangle (module docstring). evaluate(triangles (P,), bary (P, 3)) ->
    (P, C) is the bake itself. Returns the values and how many texels were filtered.
    (`filter_samples` and `apply_box_filter` are its two halves, for a bake that evaluates many
    lightmaps' points at once.)"""
    samples = filter_samples(scene, targets, values, settings)
    if samples.which.size == 0:
        return np.array(values, copy=True), 0
    return apply_box_filter(values, samples, evaluate(samples.triangles, samples.bary))


def corner_targets(scene: Scene, object_index: int) -> BakeTargets:
    """Every triangle corner of object `object_index` (for corner-domain colour attributes)."""
    sl = scene.object_slice(object_index)
    tri = np.repeat(np.arange(sl.start, sl.stop, dtype=np.int64), 3)
    bary = np.tile(np.eye(3), (sl.stop - sl.start, 1))
    corners = np.arange(sl.start * 3, sl.stop * 3, dtype=np.int64)
    return _targets(scene, tri, bary, corner_index=corners)


def _barycentric_2d(tri: np.ndarray, p: np.ndarray, clamp: bool = True) -> np.ndarray:
    """Barycentric weights (N, 3) of 2-D points p (N, 2) in triangles (N, 3, 2); clamped into the
    triangle (BARY_CLAMP) unless `clamp` is False. Degenerate triangles: their centroid (clamped)
    or NaN (unclamped, which no `>= 0` test accepts)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    v0, v1, v2 = b - a, c - a, p - a
    d00 = np.einsum("ij,ij->i", v0, v0)
    d01 = np.einsum("ij,ij->i", v0, v1)
    d11 = np.einsum("ij,ij->i", v1, v1)
    d20 = np.einsum("ij,ij->i", v2, v0)
    d21 = np.einsum("ij,ij->i", v2, v1)
    denom = d00 * d11 - d01 * d01
    safe = np.where(np.abs(denom) > 0, denom, 1.0)
    fallback = 1.0 / 3.0 if clamp else np.nan
    v = np.where(np.abs(denom) > 0, (d11 * d20 - d01 * d21) / safe, fallback)
    w = np.where(np.abs(denom) > 0, (d00 * d21 - d01 * d20) / safe, fallback)
    if not clamp:
        return np.stack([1.0 - v - w, v, w], 1)
    bary = np.clip(np.stack([1.0 - v - w, v, w], 1), *BARY_CLAMP)
    return bary / bary.sum(1, keepdims=True)


def _targets(scene: Scene, tri: np.ndarray, bary: np.ndarray, **where) -> BakeTargets:
    corners = scene.triangles[tri].astype(np.float64)  # (N, 3, 3)
    points = np.einsum("nc,ncj->nj", bary, corners)
    geo = geometric_normals(scene.triangles[tri])
    normals = interpolated_normals(scene, tri, bary, geo)
    return BakeTargets(points=points, normals=normals, geo_normals=geo, triangles=tri, bary=bary,
                       **where)


def dilate(image: np.ndarray, mask: np.ndarray, texels: int, out: np.ndarray | None = None) -> np.ndarray:
    """Grow baked texels `texels` rings outward: each unbaked texel next to baked ones takes their
    mean (8-neighbourhood), ring by ring. image (H, W, C); mask (H, W) bool. Returns (H, W, C)."""
    out = np.array(image, np.float32, copy=True) if out is None else out
    if out is not image:
        out[...] = image
    filled = mask.copy()
    height, width = mask.shape
    for _ in range(texels):
        acc = np.zeros_like(out)
        count = np.zeros((height, width), np.float32)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dx == 0 and dy == 0:
                    continue
                src = (slice(max(dy, 0), height + min(dy, 0)), slice(max(dx, 0), width + min(dx, 0)))
                dst = (slice(max(-dy, 0), height + min(-dy, 0)), slice(max(-dx, 0), width + min(-dx, 0)))
                acc[dst] += out[src] * filled[src][..., None]
                count[dst] += filled[src]
        grow = ~filled & (count > 0)
        if not grow.any():
            break
        out[grow] = acc[grow] / count[grow][:, None]
        filled |= grow
    return out
