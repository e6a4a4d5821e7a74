"""A texture's mean over the image cell a sample stands for: the pixel's box filter applied to
the base colour, for the tracer's hits (seen directly, or through mirrors and lenses by ray
differentials) and the raster views' pixel centres (`cell_albedo`).

A cell is cut into g x g sub-cells whose corners are carried onto the hit triangle's plane; the
texture's mean over each sub-cell's box in texture space (`textures.sample_texture_box`) is
averaged: exact for a planar, evenly lit cell, at the price of look-ups instead of rays.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.camera import GRAZING_COS, Camera, camera_ray_lines
from ..geometry.scene import Scene
from .material_maps import albedo_at
from .textures import sample_texture_box

# Hits filtered at a time: the (corners, hits) float64 temporaries of a 3 x 3 grid stay ~1 MB, in
# cache. A 640 x 480 view filtered in one go (300k hits, 38 MB temporaries) ran 30% slower.
FILTER_CHUNK = 8192
# Sub-cells per side the raster views filter a pixel's texture over, as the tracer's default
# `texture_filter`.
VIEW_GRID = 3


@dataclass(frozen=True, eq=False)
class Footprint:
    """The image cell each camera ray samples: for filtering the textures it sees directly."""

    camera: Camera
    width: int  # image pixels
    height: int
    x: np.ndarray  # (N,) float64 cell centre, pixels from the image's left edge
    y: np.ndarray  # (N,) float64 cell centre, pixels from the image's top edge
    cell: float  # cell side, pixels (1 / n for n x n supersampling)
    grid: int  # g: g x g texture samples over the cell


def filtered_albedo(scene: Scene, tri: np.ndarray, centre: np.ndarray, fp: Footprint,
                     rays: np.ndarray) -> np.ndarray:
    """`_filtered_albedo` in chunks of FILTER_CHUNK hits."""
    return _in_chunks(len(tri), lambda part: _filtered_albedo(scene, tri[part], centre[part], fp,
                                                               rays[part]))


def _in_chunks(count: int, colours) -> np.ndarray:
    """(count, 3): colours(part) for the slices of FILTER_CHUNK hits."""
    out = np.empty((count, 3))
    for start in range(0, count, FILTER_CHUNK):
        part = slice(start, start + FILTER_CHUNK)
        out[part] = colours(part)
    return out


def _filtered_albedo(scene: Scene, tri: np.ndarray, centre: np.ndarray, fp: Footprint,
                     rays: np.ndarray) -> np.ndarray:
    """Base colour (M, 3) averaged over the image cells of camera rays `rays` that hit `tri` at
    barycentrics `centre` (M, 3).

    The cell is cut into g x g sub-cells; the camera rays through their corners are carried onto
    the hit triangle's plane, whose barycentrics (extrapolated past the triangle's edges, where its
    texture coordinates continue linearly) give each sub-cell's corners in texture space (UV, or
    Generated: `Scene.texture_coords`). Each sub-cell then contributes the texture's mean over
    their bounding box (`sample_texture_box`: exact for the checker at any minification; a
    Generated box around a slanted face is larger than the face's footprint in it). The
    pixel's box filter applied to the texture: exact for a planar, evenly lit cell, at the
    price of look-ups instead of rays.

    The corner rays cost a few scalar operations each: a camera ray's line o + s d is affine in the
    image position (`camera_ray_lines`), so its plane hit is a ratio of affine functions, whose
    coefficients are dot products taken once per hit.
    """
    v = scene.triangles[tri].astype(np.float64)  # (M, 3, 3) world m
    e1, e2 = v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]
    n = np.cross(e1, e2)
    d11 = np.einsum("ij,ij->i", e1, e1)
    d12 = np.einsum("ij,ij->i", e1, e2)
    d22 = np.einsum("ij,ij->i", e2, e2)
    det = d11 * d22 - d12 * d12  # > 0: the BVH never returns a degenerate triangle
    n_len = np.sqrt(np.einsum("ij,ij->i", n, n))
    o, d, o_x, o_y, d_x, d_y = camera_ray_lines(fp.camera, fp.width, fp.height, fp.x[rays],
                                                fp.y[rays])
    rel = o - v[:, 0]
    # For a corner at (dx, dy) pixels from the cell centre, with a . b of per-hit vectors:
    #   line:  o' = o + dx o_x + dy o_y,  d' = d + dx d_x + dy d_y
    #   plane: s = n.(v0 - o') / n.d',  q = o' + s d' - v0,  (b1, b2) from q.e1 and q.e2.
    # Every corner of the g x g sub-cells at once: (K, 1) offsets against (M,) hits, K = (g+1)^2.
    g = fp.grid
    steps = (np.arange(g + 1) / g - 0.5) * fp.cell
    dy, dx = (a.reshape(-1, 1) for a in np.meshgrid(steps, steps, indexing="ij"))  # rows, columns

    def along(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """w . (o' - v0) and w . d' at every corner: (K, M) each."""
        at_o = np.einsum("ij,ij->i", rel, w) + dx * (w @ o_x) + dy * (w @ o_y)
        at_d = np.einsum("ij,ij->i", d, w) + dx * (w @ d_x) + dy * (w @ d_y)
        return at_o, at_d

    rn, dn = along(n)
    speed = np.sqrt(np.einsum("ij,ij->i", d, d))
    # Edge-on (|cos| below GRAZING_COS, with |d'| ~ |d| across a pixel) or behind: the ray's own
    # hit point.
    ok = np.abs(dn) > GRAZING_COS * n_len * speed
    s = -rn / np.where(ok, dn, 1.0)
    ok &= s > 0.0
    s = np.where(ok, s, 0.0)
    q = [r0 + s * w0 for r0, w0 in (along(e1), along(e2))]
    b1 = (d22 * q[0] - d12 * q[1]) / det
    b2 = (d11 * q[1] - d12 * q[0]) / det
    bary = (np.where(ok, 1.0 - b1 - b2, centre[:, 0]), np.where(ok, b1, centre[:, 1]),
            np.where(ok, b2, centre[:, 2]))
    return _cell_means(scene, tri, bary, g)


def footprint_albedo(scene: Scene, tri: np.ndarray, centre: np.ndarray, dp: np.ndarray,
                     grad: np.ndarray, cell: float, grid: int) -> np.ndarray:
    """`_footprint_albedo` in chunks of FILTER_CHUNK hits."""
    return _in_chunks(len(tri), lambda part: _footprint_albedo(
        scene, tri[part], centre[part], dp[:, part], grad[part], cell, grid))


def _footprint_albedo(scene: Scene, tri: np.ndarray, centre: np.ndarray, dp: np.ndarray,
                      grad: np.ndarray, cell: float, grid: int) -> np.ndarray:
    """Base colour (M, 3) averaged over image cells seen at hits on `tri` at barycentrics
    `centre` (M, 3) whose positions move by dp (2, M, 3) m per pixel across the image (ray
    differentials, `differentials.py`: a mirror's or a lens's view of the surface); grad (M, 2, 3)
    the gradients of the barycentrics b1, b2 in each triangle's plane
    (`differentials.TriangleFrames`).

    The cell (side `cell` pixels) maps to the parallelogram dp spans in the triangle's plane; it
    is cut into grid x grid sub-cells whose texture-space boxes are averaged, as
    `_filtered_albedo` does with the camera's exact corner rays.
    """
    # the barycentric change per pixel, x and y: (2, M) each
    db1, db2 = (np.einsum("kij,ij->ki", dp, grad[:, c]) for c in (0, 1))
    steps = (np.arange(grid + 1) / grid - 0.5) * cell
    dy, dx = (a.reshape(-1, 1) for a in np.meshgrid(steps, steps, indexing="ij"))
    b1 = centre[:, 1] + dx * db1[0] + dy * db1[1]  # (K, M) at the sub-cells' corners
    b2 = centre[:, 2] + dx * db2[0] + dy * db2[1]
    return _cell_means(scene, tri, (1.0 - b1 - b2, b1, b2), grid)


def _cell_means(scene: Scene, tri: np.ndarray, bary: tuple[np.ndarray, np.ndarray, np.ndarray],
                g: int) -> np.ndarray:
    """Base colour (M, 3): the mean over g x g sub-cells of the texture's mean over each
    sub-cell's texture-space box, from barycentrics (K, M) each at its (g+1)^2 corners (row-major,
    rows of g + 1) on the hit triangles tri (M,)."""
    # Past a texture seam (`Scene.texture_seams`) the extrapolated coordinates run into another
    # island of the atlas (an imported battery's label showed its white lettering along a seam
    # the pixel straddled): corners there are held on the seam, and each sub-cell counts by its
    # share of corners on this side (the part past it is another triangle's, not this one's).
    b = np.stack(bary)  # (3, K, M)
    cut = (b < 0.0) & scene.texture_seams[tri].T[:, None, :]
    share = None
    if cut.any():
        b = np.where(cut, 0.0, b)
        b = b / b.sum(axis=0)  # >= 1: only negative weights were dropped
        bary = (b[0], b[1], b[2])
        inside = (~cut.any(axis=0)).reshape(g + 1, g + 1, -1).astype(np.float64)
        share = (inside[:-1, :-1] + inside[:-1, 1:] + inside[1:, :-1] + inside[1:, 1:]) / 4.0
    corner_uv = scene.texture_coords[tri]  # (M, 3, 3): (u, v, 0) or Generated
    lo = np.zeros((3, g, g, len(tri)))  # each sub-cell's box in texture space, [axis, row, column]
    hi = np.zeros((3, g, g, len(tri)))
    for axis in range(3):
        c = corner_uv[:, :, axis]
        if not c.any():  # UV's z: 0 everywhere
            continue
        uv = (bary[0] * c[:, 0] + bary[1] * c[:, 1] + bary[2] * c[:, 2]).reshape(g + 1, g + 1, -1)
        a, b = uv[:-1], uv[1:]  # the sub-cells' upper and lower corner rows
        lo[axis] = np.minimum(np.minimum(a[:, :-1], a[:, 1:]), np.minimum(b[:, :-1], b[:, 1:]))
        hi[axis] = np.maximum(np.maximum(a[:, :-1], a[:, 1:]), np.maximum(b[:, :-1], b[:, 1:]))
    lo = lo.reshape(3, -1).T  # (g*g*M, 3), sub-cell-major
    hi = hi.reshape(3, -1).T
    mats = np.tile(scene.material_ids[tri], g * g)
    kinds = np.unique(mats)
    if kinds.size == 1:  # one textured material: no row selection
        acc = sample_texture_box(scene.materials[kinds[0]].base_color_texture, lo, hi)
    else:
        acc = np.empty((len(lo), 3))
        for m in kinds:
            rows = mats == m
            acc[rows] = sample_texture_box(scene.materials[m].base_color_texture, lo[rows],
                                           hi[rows])
    acc = acc.reshape(g * g, len(tri), 3)
    if share is None:
        return acc.mean(axis=0)
    share = share.reshape(g * g, -1)
    total = share.sum(axis=0)
    share = np.where(total > 0.0, share, 1.0)  # no corner on this side: all sub-cells alike
    return np.einsum("sm,smc->mc", share, acc) / share.sum(axis=0)[:, None]


def cell_albedo(scene: Scene, tri: np.ndarray, bary: np.ndarray, rows: np.ndarray,
                cols: np.ndarray, shape: tuple[int, int], grid: int = VIEW_GRID) -> np.ndarray:
    """(N, 3) the base colour of camera samples at barycentrics bary (N, 3) of triangles tri
    (N,), each seen at the centre of its pixel (rows, cols) (N,) of an image of `shape` (H, W):
    a texture's mean over the pixel (`filtered_albedo`, grid x grid sub-cells), the colour
    itself where the material has none."""
    out = albedo_at(scene, tri, bary)
    if scene.camera is None:
        return out
    textured = np.array([m.base_color_texture is not None for m in scene.materials], bool)
    at = np.flatnonzero(textured[scene.material_ids[tri]])
    if at.size:
        height, width = shape
        fp = Footprint(scene.camera, width, height, cols[at] + 0.5, rows[at] + 0.5, 1.0, grid)
        out[at] = filtered_albedo(scene, tri[at], bary[at], fp, np.arange(at.size))
    return out
