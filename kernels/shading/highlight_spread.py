"""A lamp's highlight averaged over a pixel: the raster views' geometric specular antialiasing.

Cycles averages each pixel over the surface it covers, so a smooth lobe's highlight on a curved
or normal-mapped surface reaches the pixel as its mean over the normals the pixel sees. A view
that shades one point per pixel (or per sub-pixel cell) evaluates the lobe at one normal: where
the highlight is smaller than the pixel, that point meets its peak or misses it. An imported
helmet (normal-mapped metal of roughness 0.125-0.19) showed pixels 25x too bright.

The normal is taken as varying linearly across the pixel, n(x, y) = n + x dn/dx + y dn/dy for
x, y in [-1/2, 1/2] (`NormalFootprint`: the differences to the neighbouring pixel centres of the
same object). Its slopes then spread with the covariance J J^T / 12 (J = [dn/dx, dn/dy]), an
isotropic per-axis variance of (|dn/dx|^2 + |dn/dy|^2) / 24; convolving the lobe's slopes with
it widens GGX as Beckmann's slope variance alpha^2 / 2 widens, alpha'^2 = alpha^2 + (|dn/dx|^2
+ |dn/dy|^2) / 12 (`widened_roughness`; Kaplanyan et al. 2016, "Filtering distributions of
normals for shading antialiasing"). A lobe far narrower than that spread keeps GGX's sharp peak
and long tails, which no wider GGX matches: on a smooth surface it is evaluated at a grid of
normals across the footprint instead (`sub_sides`), each widened by what is left of the spread
within its sub-cell. A sub-pixel sample (an edge pixel's ray) stands for its cell of the pixel:
its footprint is the cell's, about the normal at the cell's centre.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.camera import Camera, camera_hit_derivatives
from ..geometry.frames import barycentric_gradients

# alpha^2 a pixel's normals add per squared unit of normal change across it: 1/12 (the variance
# of a uniform position in [-1/2, 1/2]) for the two axes' variance together, which is twice the
# isotropic per-axis variance, as alpha^2 is twice Beckmann's per-axis slope variance.
PIXEL_SLOPE_VARIANCE = 1.0 / 12.0
# Largest alpha^2 added (Kaplanyan's kappa, 0.18 there): a pixel across a crease or a normal
# map's seam differs from its neighbours by far more than its own normals spread, and would
# otherwise lose its highlight altogether.
SPREAD_CAP = 0.18
# alpha^2 a lamp sample adds per squared radian of its angular radius (`sample_roughness`): its
# disc moves the half vector within half that radius, a per-axis variance of (radius / 2)^2 / 4,
# and alpha^2 is twice it, as above. Against the dense integral of a 1 m lamp 2 m over a glossy
# floor (48 x 48 points, no widening), 4 x 4 samples' relMSE along a line through the highlight
# at roughness 0.1 / 0.2 / 0.3: 0.68 / 0.011 / 9e-5 as points, 0.26 / 0.0095 / 3.3e-5 widened by
# 1/8; 1/2 does better at 0.1 and worse from 0.2 on.
SAMPLE_SPREAD_SHARE = 1.0 / 8.0
# Lobes whose alpha^2 is under SUB_SPREAD_RATIO times the alpha^2 the footprint adds are
# evaluated at m x m normals across it, m the least that leaves each sub-cell's added alpha^2
# under 1 / SUB_SPREAD_RATIO of the lobe's, at least SUB_SIDE and at most MAX_SUB_SIDE. A 9 x 9
# pixel patch of a paraboloid under a highlight, against its pixels' means over 32 x 32 points
# each (relMSE over the patch, roughness 0.1 and 0.15, 0.05-0.1 of normal change per pixel):
# one widened lobe 0.02-0.26; 2 x 2 sub-normals 0.004-0.24; 3 x 3 3e-4-0.2; 4 x 4 5e-5-0.012. A
# lobe as wide as a quarter of the footprint's spread is within 0.002 with one.
SUB_SPREAD_RATIO = 4.0
SUB_SIDE = 4
MAX_SUB_SIDE = 8
# Radians a mirror's image may turn between the rays that sample it across a cell: above it, a
# bevel's smooth normals (36 degrees across a sixth of a pixel on an imported sword) showed an
# area lamp's image at its one ray's point and the pixel 500x Cycles' mean.
MIRROR_SWEEP_TURN = 0.05
# Pixels whose spread (|dn/dx|^2 + |dn/dy|^2) exceeds this are widened only, never swept nor
# their sub-samples' normals moved to their cells' centres: there the pixel is rarely a smooth
# surface's (a part one pixel wide differs from both of its neighbours), and normals it does not
# hold find highlights it does not show (an imported helmet's pixel of spread 0.27 became 60x
# too bright).
MAX_SWEPT_SPREAD = 0.04


@dataclass(frozen=True)
class TrianglePatch:
    """Where N samples lie on their triangles, and how that moves across their cells.

    bary     (N, 3)     barycentrics at the cell's centre
    dx, dy   (N, 3)     their change across the cell along the image's x and y (each sums to 0)
    corners  (N, 3, 3)  the triangles' corner normals, turned to the side the eye sees
    """

    bary: np.ndarray
    dx: np.ndarray
    dy: np.ndarray
    corners: np.ndarray

    def at(self, rows) -> TrianglePatch:
        """The patches of samples `rows`."""
        return TrianglePatch(self.bary[rows], self.dx[rows], self.dy[rows], self.corners[rows])

    def moved(self, by: np.ndarray, scale: float) -> TrianglePatch:
        """The patches moved by (N, 2) cells (x, y), their cells `scale` times as wide."""
        bary = self.bary + self.dx * by[:, :1] + self.dy * by[:, 1:]
        return TrianglePatch(bary, self.dx * scale, self.dy * scale, self.corners)

    def normals(self, ox: float = 0.0, oy: float = 0.0) -> np.ndarray:
        """(N, 3) the unit interpolated normals at (ox, oy) cells from the centres, held within
        the triangles (negative weights dropped): past its edges a smooth mesh's normal is its
        neighbours', which start where the triangle's end; extrapolated, a bevel a sixth of a
        pixel wide swept normals it never has into a lamp's highlight."""
        b = np.maximum(self.bary + ox * self.dx + oy * self.dy, 0.0)
        n = np.einsum("nk,nkc->nc", b, self.corners)
        return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)

    def slopes(self) -> tuple[np.ndarray, np.ndarray]:
        """(dn/dx, dn/dy) (N, 3) each: the unit normal's change across the cell at its centre."""
        raw = np.einsum("nk,nkc->nc", self.bary, self.corners)
        length = np.maximum(np.linalg.norm(raw, axis=1), 1e-12)[:, None]
        unit = raw / length
        out = []
        for db in (self.dx, self.dy):
            d_raw = np.einsum("nk,nkc->nc", db, self.corners)
            out.append((d_raw - unit * np.einsum("ij,ij->i", unit, d_raw)[:, None]) / length)
        return out[0], out[1]


@dataclass(frozen=True)
class NormalFootprint:
    """How the shading normal changes across each sample's cell (N samples).

    dx, dy   (N, 3)  the change of the unit normal from the cell's centre to the next cell's
                     centre along the image's x and y (at a pixel centre, to the next pixel)
    shift    (N, 3)  from the sample's normal to its cell centre's (0: the samples are centres)
    smooth   (N,)    bool: the derivatives are a smooth surface's (no relief map, and the
                     spread of its pixel at most MAX_SWEPT_SPREAD or the sample's own
                     triangle's); elsewhere the lobe is only widened, about the sample's normal
    patch    the samples' own triangles across their cells (`TrianglePatch`; None: not known)
    own      (N,) bool: dx, dy are the own triangle's and no relief map moves its normals,
                     which the sweeps then take (`TrianglePatch.normals`) rather than the
                     linear extension
    plain    (N,) bool: no relief map moves the sample's normal (None: not known)
    """

    dx: np.ndarray
    dy: np.ndarray
    shift: np.ndarray
    smooth: np.ndarray
    patch: TrianglePatch | None = None
    own: np.ndarray | None = None
    plain: np.ndarray | None = None

    @classmethod
    def of_pixels(cls, slopes: PixelSlopes, rows: np.ndarray, cols: np.ndarray,
                  cell: float = 1.0, to_cell: np.ndarray | None = None,
                  patch: TrianglePatch | None = None) -> NormalFootprint:
        """The footprints of samples in pixels (rows, cols) (N,) whose cells are `cell` pixels
        wide, from the pixels' `slopes`; to_cell (N, 2): from each sample to its cell's centre,
        pixels (None: 0); patch: the samples' own triangles per pixel (`triangle_patches`),
        whose slopes are taken along each axis where larger than the pixel's (a sub-pixel ray
        on a bevel narrower than the pixel, whose normals turn within it)."""
        dx, dy = slopes.dx[rows, cols], slopes.dy[rows, cols]
        own, plain = None, slopes.smooth[rows, cols]
        if patch is not None:
            own_dx, own_dy = patch.slopes()
            # a relief map's normals are not the triangle's: its slopes widen, never sweep
            own = (_sq(own_dx) + _sq(own_dy) >= _sq(dx) + _sq(dy)) & plain
            dx, dy = (np.where((_sq(d) < _sq(o))[:, None], o, d)
                      for d, o in zip((dx, dy), (own_dx, own_dy), strict=True))
            moved = np.zeros((len(rows), 2)) if to_cell is None else to_cell
            patch = patch.moved(moved, cell)
        smooth = plain & ((_sq(dx) + _sq(dy) <= MAX_SWEPT_SPREAD)
                          | (False if own is None else own))
        shift = np.zeros_like(dx)
        if to_cell is not None:
            shift[smooth] = (dx * to_cell[:, :1] + dy * to_cell[:, 1:])[smooth]
        return cls(dx * cell, dy * cell, shift, smooth, patch, own, plain)

    def at(self, rows: np.ndarray) -> NormalFootprint:
        """The footprints of samples `rows`."""
        if self.patch is None:
            return NormalFootprint(self.dx[rows], self.dy[rows], self.shift[rows],
                                   self.smooth[rows])
        return NormalFootprint(self.dx[rows], self.dy[rows], self.shift[rows], self.smooth[rows],
                               self.patch.at(rows), self.own[rows], self.plain[rows])

    def own_triangles(self) -> NormalFootprint:
        """The footprints of the samples' own triangles alone (no change where not known),
        swept on the triangles where no relief map moves their normals."""
        if self.patch is None:
            return NormalFootprint(np.zeros_like(self.dx), np.zeros_like(self.dy),
                                   np.zeros_like(self.dx), self.smooth)
        dx, dy = self.patch.slopes()
        return NormalFootprint(dx, dy, np.zeros_like(dx), self.smooth, self.patch, self.plain,
                               self.plain)

    def centres(self, normals: np.ndarray) -> np.ndarray:
        """(N, 3) the unit normals (N, 3) of the samples moved to their cells' centres."""
        return self.normals_at(normals + self.shift, 0.0, 0.0)

    def normals_at(self, normals: np.ndarray, ox: float, oy: float) -> np.ndarray:
        """(N, 3) unit normals (ox, oy) cells from the samples' (N, 3) centre normals: along
        the footprint's slopes, or where they are the own triangle's, on the triangle."""
        n = normals + ox * self.dx + oy * self.dy
        n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        if self.own is not None and self.own.any():
            n[self.own] = self.patch.at(self.own).normals(ox, oy)
        return n

    @property
    def spread(self) -> np.ndarray:
        """(N,) |dn/dx|^2 + |dn/dy|^2."""
        return _sq(self.dx) + _sq(self.dy)


@dataclass(frozen=True)
class PixelSlopes:
    """How the shading normal changes across each pixel of an image (H, W).

    dx, dy  (H, W, 3)  dn/dx, dn/dy: the change to the next pixel's centre along x and y
    smooth  (H, W)     bool: the pixel's surface carries no relief map, whose texels' normals
                       a pixel's neighbours sample, not its surface's derivatives
    """

    dx: np.ndarray
    dy: np.ndarray
    smooth: np.ndarray


def normal_derivatives(normals: np.ndarray, rows: np.ndarray, cols: np.ndarray, ids: np.ndarray,
                       shape: tuple[int, int], relief: np.ndarray | None = None) -> PixelSlopes:
    """`PixelSlopes` of an image of `shape` (H, W) from the unit normals (N, 3) seen at the pixel
    centres (rows, cols) (N,) of objects ids (N,), relief (N,) bool where a bump or normal map
    moved them: along each axis the smaller of the differences to the two neighbours of the
    same object (0 with none). The smaller: a pixel beside a crease or another part of the
    object differs from that neighbour by far more than across its own surface."""
    height, width = shape
    image = np.zeros((height, width, 3))
    owner = np.full((height, width), -1, np.int64)
    image[rows, cols] = normals
    owner[rows, cols] = ids
    out = []
    for axis in (1, 0):  # x runs along the columns, y down the rows
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        lo, hi = tuple(lo), tuple(hi)
        pair = (owner[lo] == owner[hi]) & (owner[lo] >= 0)
        step = image[hi] - image[lo]
        length = np.where(pair, np.sum(step * step, axis=-1), np.inf)
        best = np.zeros((height, width, 3))
        least = np.full((height, width), np.inf)
        for side in (lo, hi):  # each difference belongs to both pixels of its pair
            smaller = length < least[side]
            least[side] = np.where(smaller, length, least[side])
            best[side] = np.where(smaller[..., None], step, best[side])
        out.append(best)
    smooth = np.ones((height, width), bool)
    if relief is not None:
        smooth[rows, cols] = ~np.asarray(relief, bool)
    return PixelSlopes(out[0], out[1], smooth)


def triangle_patches(camera: Camera, shape: tuple[int, int], rows: np.ndarray,
                     cols: np.ndarray, corners: np.ndarray, corner_normals: np.ndarray,
                     bary: np.ndarray, side: np.ndarray) -> TrianglePatch:
    """The `TrianglePatch` of pixels: samples in pixels (rows, cols) (N,) of an image of
    `shape` (H, W) at barycentrics bary (N, 3) of triangles of (N, 3, 3) world corners and
    (N, 3, 3) corner normals, turned by side (N,) +-1 to the side the eye sees; the
    barycentrics' change per pixel along x and y. The camera ray's hit on the triangle's plane
    moves by dp (`camera_hit_derivatives`, the tracer's ray differentials; 0 edge-on), the
    barycentrics by their in-plane gradients . dp."""
    height, width = shape
    v = np.asarray(corners, np.float64)
    p = np.einsum("nk,nkc->nc", bary, v)
    normal = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    dp, _ = camera_hit_derivatives(camera, width, height, cols + 0.5, rows + 0.5, None, p,
                                   normal)
    grad = barycentric_gradients(v)  # (N, 2, 3)
    b1, b2 = (np.einsum("kij,ij->ki", dp, grad[:, c]) for c in (0, 1))  # (2, N) each
    moves = np.stack([-b1 - b2, b1, b2], axis=-1)  # (2, N, 3): along x, along y
    turned = corner_normals.astype(np.float64) * np.asarray(side, np.float64)[:, None, None]
    return TrianglePatch(np.asarray(bary, np.float64), moves[0], moves[1], turned)


def fragment_patches(scene, f, shape: tuple[int, int], at=slice(None)) -> TrianglePatch:
    """`triangle_patches` of the scene's camera at fragments f (`camera_view.Fragments`: tri,
    bary, rows, cols, back) of an image of `shape` (H, W), those `at` (an index or mask)."""
    tri = f.tri[at]
    return triangle_patches(scene.camera, shape, f.rows[at], f.cols[at], scene.triangles[tri],
                            scene.normals[tri], f.bary[at], np.where(f.back[at], -1.0, 1.0))


def _sq(v: np.ndarray) -> np.ndarray:
    """(N,) squared lengths of rows v (N, 3)."""
    return np.einsum("ij,ij->i", v, v)


def widened_roughness(roughness: np.ndarray, spread: np.ndarray | None) -> np.ndarray:
    """(N,) Blender roughness whose alpha^2 (roughness^4) is widened by a footprint's spread (N,)
    (`NormalFootprint.spread`): alpha'^2 = alpha^2 + min(spread x PIXEL_SLOPE_VARIANCE,
    SPREAD_CAP). roughness itself without one."""
    if spread is None:
        return roughness
    return _widened(roughness, np.minimum(np.asarray(spread, np.float64) * PIXEL_SLOPE_VARIANCE,
                                          SPREAD_CAP))


def sample_roughness(roughness: np.ndarray, spread: np.ndarray | None) -> np.ndarray:
    """(N,) Blender roughness of lobes of `roughness` (N,) lit by lamp samples of angular radius
    `spread` (N,) rad seen from the surface (`lights.sample_radius`); roughness itself
    without one.

    An area lamp is n x n points, each standing for its cell: a lobe much narrower than the
    cells drew every point's own highlight, a grid of spots where Cycles reflects the whole
    lamp. Each point's lobe convolved with its disc, alpha'^2 = alpha^2 + SAMPLE_SPREAD_SHARE
    spread^2, joins them into the lamp's reflection."""
    if spread is None:
        return roughness
    return _widened(roughness, SAMPLE_SPREAD_SHARE * np.square(np.asarray(spread, np.float64)))


def _widened(roughness: np.ndarray, added: np.ndarray) -> np.ndarray:
    """(N,) Blender roughness whose alpha^2 (roughness^4) is `added` (N,) more."""
    return (np.asarray(roughness, np.float64) ** 4 + added) ** 0.25


def sub_sides(alpha2: np.ndarray, footprint: NormalFootprint) -> np.ndarray:
    """(N,) int: the sides m of the grids of sub-normals lobes of alpha^2 (N,) take over their
    footprints, 1 for the lobes the widening alone serves."""
    added = footprint.spread * PIXEL_SLOPE_VARIANCE
    narrow = (alpha2 < SUB_SPREAD_RATIO * added) & footprint.smooth
    need = np.ceil(np.sqrt(SUB_SPREAD_RATIO * added / np.maximum(alpha2, 1e-300)))
    return np.where(narrow, np.clip(need, SUB_SIDE, MAX_SUB_SIDE), 1).astype(np.int64)


def mirror_sides(footprint: NormalFootprint) -> np.ndarray:
    """(N,) int: the sides m of the grids of normals a mirror's rays take across each sample's
    own triangle's footprint (`NormalFootprint.own_triangles`): its mirror image turns by twice
    the normal, so m x m rays keep each within MIRROR_SWEEP_TURN of its neighbours (1: the one
    ray), at most MAX_SUB_SIDE."""
    turn = 2.0 * np.sqrt(footprint.own_triangles().spread)
    return np.clip(np.ceil(turn / MIRROR_SWEEP_TURN), 1, MAX_SUB_SIDE).astype(np.int64)


def sub_normals(normals: np.ndarray, footprint: NormalFootprint, side: int):
    """Yields side^2 unit normals (N, 3) each: `normals` (the cells' centres') moved across
    their footprints to the centres of a side x side grid of sub-cells
    (`NormalFootprint.normals_at`)."""
    offsets = (np.arange(side) + 0.5) / side - 0.5
    for oy in offsets:
        for ox in offsets:
            yield footprint.normals_at(normals, ox, oy)
