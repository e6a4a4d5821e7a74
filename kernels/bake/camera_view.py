"""What the camera sees, by z-buffer: the fragments f of the lecture's step 2.

The scene is rasterised from the camera (`raster.py`, top-left rule) with triangle ids; each covered
pixel's centre ray is then intersected with its triangle's plane in float64, giving the exact point
and barycentrics that the shading at that pixel uses. Shared by every kernel that renders the camera
view of a baked or computed result (direct light with shadow maps, radiosity).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.alpha_occlusion import layered_hits
from ..geometry.camera import camera_rays, camera_reach, pixel_rays
from ..geometry.raster import Projection, rasterize
from ..geometry.scene import Camera, Scene, geometric_normals
from ..measure.metrics import REC709_LUMINANCE

# Relative luminance contrast between neighbouring pixels that marks an edge for supersampling;
# 1/16 is about the smallest step visible in an 8-bit display of the result.
EDGE_CONTRAST = 1.0 / 16.0
# Added to the luminance sum in the contrast test so that near-black pixels do not all count as edges.
CONTRAST_FLOOR = 1e-2
# Rays per side through each edge pixel of a camera view (`supersample_edges`): 3 x 3 takes a
# silhouette's coverage to 1/9 of a pixel (`pixel_patterns`).
EDGE_SAMPLES = 3


@dataclass(frozen=True, eq=False)
class Fragments:
    """Covered pixels (N of them) and the surface point each pixel centre sees.

    rows, cols (N,) int   pixel indices, row 0 top
    tri        (N,) int64 scene triangle
    bary       (N, 3)     barycentric weights of the point in its triangle
    points     (N, 3)     world, m
    dirs       (N, 3)     unit view directions (camera to point)
    depth      (N,)       distance along the ray from its origin, m
    geometric  (N, 3)     unit front normals of the triangles seen
    back       (N,) bool  the triangle is seen from behind (its front faces away)
    cell       float      side of each sample's cell, pixels (1 at the centres, 1/n for n x n
                          sub-samples): the share of the pixel's surface a sample stands for
    to_cell    (N, 2)     from each sample to its cell's centre, pixels (x right, y down); None:
                          the samples are the centres
    """

    rows: np.ndarray
    cols: np.ndarray
    tri: np.ndarray
    bary: np.ndarray
    points: np.ndarray
    dirs: np.ndarray
    depth: np.ndarray
    geometric: np.ndarray
    back: np.ndarray
    cell: float = 1.0
    to_cell: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.rows.shape[0])


def camera_projection(camera: Camera) -> Projection:
    """The kernel camera as a rasteriser projection (same image plane, clip range)."""
    view = np.linalg.inv(camera.matrix_world)
    extent = (camera.plane_min[0], camera.plane_max[0], camera.plane_min[1], camera.plane_max[1])
    if camera.kind == "ORTHO":
        return Projection.orthographic(view, extent, camera.clip_start, camera.clip_end)
    return Projection("PERSP", view, tuple(float(e) for e in extent), max(camera.clip_start, 1e-6),
                      camera.clip_end)


def ray_triangle_bary(origins, dirs, tris) -> tuple[np.ndarray, np.ndarray]:
    """Barycentrics (N, 3) and distance (N,) where each ray meets its own triangle's plane
    (Moller-Trumbore without the inside test: the rasteriser already chose the triangle)."""
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    e1, e2 = b - a, c - a
    pvec = np.cross(dirs, e2)
    det = np.einsum("ij,ij->i", e1, pvec)
    inv = np.where(np.abs(det) > 1e-300, 1.0 / np.where(det == 0, 1.0, det), 0.0)
    tvec = origins - a
    u = np.einsum("ij,ij->i", tvec, pvec) * inv
    qvec = np.cross(tvec, e1)
    v = np.einsum("ij,ij->i", dirs, qvec) * inv
    t = np.einsum("ij,ij->i", e2, qvec) * inv
    bary = np.clip(np.stack([1 - u - v, u, v], 1), 0.0, 1.0)
    return bary / np.maximum(bary.sum(1, keepdims=True), 1e-12), t


def camera_fragments(scene: Scene, resolution=None) -> Fragments:
    """Rasterise the camera view of `scene` at `resolution` (W, H; default the camera's)."""
    camera = scene.camera
    if camera is None:
        raise ValueError("the scene has no camera")
    width, height = resolution or camera.resolution
    raster = rasterize(scene.triangles, camera_projection(camera), width, height,
                       with_triangle_ids=True)
    rows, cols = np.nonzero(raster.triangle >= 0)
    tri = raster.triangle[rows, cols].astype(np.int64)
    origins, dirs = camera_rays(camera, width, height)
    o, d = origins[rows, cols], dirs[rows, cols]
    bary, t = ray_triangle_bary(o, d, scene.triangles[tri].astype(np.float64))
    geometric = geometric_normals(scene.triangles[tri])
    return Fragments(rows=rows, cols=cols, tri=tri, bary=bary, points=o + d * t[:, None], dirs=d,
                     depth=t, geometric=geometric,
                     back=np.einsum("ij,ij->i", geometric, d) > 0.0)


def background_and_fragments(scene: Scene, resolution=None, out: np.ndarray | None = None
                             ) -> tuple[np.ndarray, Fragments]:
    """The start of every camera render: an (H, W, 3) float32 image (or `out`) filled with the
    world colour, which escaping pixel rays see, and the fragments to shade."""
    if scene.camera is None:
        raise ValueError("the scene has no camera")
    from ..shading.world_light import world_radiance, world_seen_by

    width, height = resolution or scene.camera.resolution
    image = np.empty((height, width, 3), np.float32) if out is None else out
    world = world_seen_by(scene, "camera")  # black where Cycles hides it from the camera
    if world.world_texture is None:
        image[...] = world.world_color
    else:  # the world's map along each pixel's ray
        _, dirs = camera_rays(scene.camera, width, height)
        image[...] = world_radiance(world, dirs.reshape(-1, 3)).reshape(height, width, 3)
    return image, camera_fragments(scene, (width, height))


def edge_pixels(image: np.ndarray, ids: np.ndarray, chroma: np.ndarray | None = None) -> np.ndarray:
    """(H, W) bool: pixels whose 4-neighbours see another object/material (ids (H, W), -1 for
    none) or a visible luminance contrast (EDGE_CONTRAST) in image (H, W, 3). Where chroma
    (H, W) bool marks either pixel of a pair, a contrast in any one channel counts too (colours
    of equal luminance meet there: vertex colours of neighbouring faces)."""
    lum = image @ np.array(REC709_LUMINANCE)
    mark = np.zeros(ids.shape, bool)
    for axis in (0, 1):
        a = [slice(None)] * 2
        b = [slice(None)] * 2
        a[axis] = slice(1, None)
        b[axis] = slice(None, -1)
        differ = ids[tuple(a)] != ids[tuple(b)]
        la, lb = lum[tuple(a)], lum[tuple(b)]
        differ |= np.abs(la - lb) > EDGE_CONTRAST * (la + lb + CONTRAST_FLOOR)
        if chroma is not None:
            ca, cb = image[tuple(a)], image[tuple(b)]
            channel = (np.abs(ca - cb) > EDGE_CONTRAST * (ca + cb + CONTRAST_FLOOR)).any(axis=-1)
            differ |= (chroma[tuple(a)] | chroma[tuple(b)]) & channel
        mark[tuple(a)] |= differ
        mark[tuple(b)] |= differ
    return mark


def stratified_offsets(n: int) -> np.ndarray:
    """(n^2, 2) offsets in [0, 1)^2: the centres of an n x n grid of cells."""
    g = (np.arange(n) + 0.5) / n
    gx, gy = np.meshgrid(g, g, indexing="xy")
    return np.stack([gx.ravel(), gy.ravel()], 1)


def pixel_patterns(n: int, pixels: np.ndarray) -> np.ndarray:
    """(n^2, P, 2) offsets in [0, 1)^2: [k, p] is sample k (in cell k of an n x n grid, row by row
    as `stratified_offsets`) in pixel pixels[p] (P,) int (the image's flat indices).

    Every pixel's n^2 samples take one cell each, and no two share a column or a row of the
    n^2 x n^2 grid of finer cells, so an edge along the pixel grid is resolved to 1/n^2 of a pixel,
    not 1/n. Cell centres alone give every pixel along a straight edge the same rounding: a
    glowing ceiling panel's near side, covering 82% of a row of pixels, showed as 67% (3 x 3), its
    far side's 89% as 100%, and the room's view came out 1.4% darker than Cycles'. n a power of
    two: the Hammersley points (x = (i + 1/2) / n^2, y the bits of i reversed), a (0, 2h, 2)-net
    in base 2 (one point in every box of area 1/n^2 whose sides are powers of two); other n: the
    "n-rooks" pattern of multi-jittered sampling. Each pixel's pattern is scrambled by a hash of
    its index (the net's bits XOR-ed, a digital shift that keeps the net; the rooks' sub-columns
    and sub-rows permuted), so that one pattern does not round the same way in every pixel along
    a slanted edge: what is left is noise, as in Cycles' pixel sampling (an edge along the rows
    meets every pixel's n^2 fine rows alike and rounds to the same 1/n^2). n = 1: the pixel
    centre."""
    pixels = np.asarray(pixels, np.uint64)
    if n == 1:
        return np.full((1, len(pixels), 2), 0.5)
    m = n * n
    cx, cy = np.arange(m) % n, np.arange(m) // n  # each sample's cell
    if n & (n - 1) == 0:
        h = n.bit_length() - 1  # bits per cell coordinate; a fine index has 2h bits
        shift_x = _pixel_hash(pixels, 1) & np.uint64(m - 1)
        shift_y = _pixel_hash(pixels, 2) & np.uint64(m - 1)
        # The point i of the pixel's net in cell (cx, cy): x's top h bits are i's top h bits
        # XOR the shift's, y's top h bits are i's low h bits reversed XOR the shift's.
        high = cx.astype(np.uint64)[:, None] ^ (shift_x >> np.uint64(h))  # (m, P)
        low = _reversed_bits(cy.astype(np.uint64)[:, None] ^ (shift_y >> np.uint64(h)), h)
        i = (high << np.uint64(h)) | low
        fine_x, fine_y = i ^ shift_x, _reversed_bits(i, 2 * h) ^ shift_y
    else:
        # Per pixel, a permutation of the sub-columns within each column and of the sub-rows
        # within each row: fine column cx n + P(cy), fine row cy n + Q(cx).
        keys = _pixel_hash(pixels[:, None], np.arange(1, 2 * n + 1, dtype=np.uint64)[None])
        sub_column = np.argsort(keys[:, :n], axis=1)[:, cy].T  # (m, P)
        sub_row = np.argsort(keys[:, n:], axis=1)[:, cx].T
        fine_x, fine_y = (cx * n)[:, None] + sub_column, (cy * n)[:, None] + sub_row
    return (np.stack([fine_x, fine_y], 2).astype(np.float64) + 0.5) / m


def _pixel_hash(pixels: np.ndarray, salt) -> np.ndarray:
    """A 64-bit mix (splitmix64's finaliser) of pixel indices and a salt, uint64."""
    with np.errstate(over="ignore"):
        z = (np.asarray(pixels, np.uint64) + np.uint64(0x9E3779B97F4A7C15) * np.asarray(
            salt, np.uint64))
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


def _reversed_bits(values: np.ndarray, bits: int) -> np.ndarray:
    """The low `bits` bits of `values` (uint64) in reverse order."""
    values = np.asarray(values, np.uint64)
    out = np.zeros_like(values)
    for b in range(bits):
        out |= ((values >> np.uint64(b)) & np.uint64(1)) << np.uint64(bits - 1 - b)
    return out


def blend_partial_cover(scene: Scene, image: np.ndarray, fragments: Fragments, shade, bvh
                        ) -> int:
    """In place: every pixel of `image` (H, W, 3) whose centre sees a partly covered surface
    first (alpha below 1: a leaf card, a fence, a glass-like blend; `shading/alpha.py`) shows
    what Cycles blends there, a S + (1 - a) T through each such surface to the first opaque one
    or the world (`alpha_occlusion.layered_hits`), where the z-buffer kept the front surface
    alone. shade(Fragments) -> (M, 3) and `bvh` (over scene.triangles) as in
    `supersample_edges`; `fragments` the covered pixels. Returns the number of pixels blended."""
    from ..shading.alpha import ray_coverage

    cover = ray_coverage(scene, "camera")
    if cover is None or not len(fragments):
        return 0
    sel = np.flatnonzero(~cover.opaque(fragments.tri))
    if sel.size == 0:
        return 0
    rows, cols = fragments.rows[sel], fragments.cols[sel]
    d = fragments.dirs[sel]
    o = fragments.points[sel] - d * fragments.depth[sel, None]
    image[rows, cols] = seen_along(scene, o, d, shade, bvh, cover, rows, cols)
    return int(sel.size)


def seen_along(scene: Scene, o: np.ndarray, d: np.ndarray, shade, bvh, cover, rows: np.ndarray,
               cols: np.ndarray, cell: float = 1.0, to_cell: np.ndarray | None = None
               ) -> np.ndarray:
    """(N, 3) what camera rays o + t d (N, 3 each, d unit) through pixels (rows, cols) see:
    the surface each meets first shaded by shade(Fragments) (of `cell`, the side in pixels of
    each ray's share of its pixel, and to_cell (N, 2), from each ray to its share's centre), the
    world's colour where it escapes; through partly covered surfaces their blend
    (`layered_hits`) when `cover` (the camera's coverage, `ray_coverage`) is given."""
    from ..shading.reflected_emitters import ray_offset
    from ..shading.world_light import world_radiance, world_seen_by

    reach = camera_reach(scene.camera, d)  # the far clip plane, as the z-buffer's
    if cover is None:
        hits = bvh.intersect(o, d, 0.0, reach)
        ray, weight = np.arange(len(o)), np.ones(len(o))
    else:
        layers = layered_hits(bvh, o, d, 0.0, reach, cover, ray_offset(scene), cover.opaque)
        hits, ray, weight = layers.hits, layers.ray, layers.weight
    tri = np.asarray(hits.tri, np.int64)
    hit = tri >= 0
    value = np.empty((len(ray), 3))
    world = world_seen_by(scene, "camera")
    if world.world_texture is None:
        value[~hit] = world.world_color
    else:
        value[~hit] = world_radiance(world, d[ray[~hit]])
    if hit.any():
        t, r = tri[hit], ray[hit]
        u, v = hits.u[hit].astype(np.float64), hits.v[hit].astype(np.float64)
        depth = hits.t[hit].astype(np.float64)
        geometric = geometric_normals(scene.triangles[t])
        value[hit] = shade(Fragments(
            rows=rows[r], cols=cols[r], tri=t, bary=np.stack([1.0 - u - v, u, v], 1),
            points=o[r] + d[r] * depth[:, None], dirs=d[r], depth=depth, geometric=geometric,
            back=np.einsum("ij,ij->i", geometric, d[r]) > 0.0, cell=cell,
            to_cell=None if to_cell is None else to_cell[r]))
    out = np.zeros((len(o), 3))
    for c in range(3):  # each ray's layers summed
        out[:, c] = np.bincount(ray, weight * value[:, c], minlength=len(o))
    return out


def supersample_edges(scene: Scene, image: np.ndarray, fragments: Fragments, shade, bvh,
                      samples: int = EDGE_SAMPLES) -> int:
    """In place: every edge pixel of `image` (H, W, 3) shaded at its centre (`fragments`, the
    covered pixels; `edge_pixels` of the image and of the objects the centres see) becomes the
    mean of `samples` x `samples` stratified rays through it (`pixel_patterns`), the box filter
    Cycles' 1-px BOX pixel filter is (the pixel centres alone alias silhouettes, folds and hard
    shadow edges). A ray that hits a triangle of `bvh` (built over scene.triangles) is shaded by
    shade(Fragments) -> (M, 3); one that escapes sees the world (its map along the ray, else its
    colour); one that meets partly covered surfaces their blend (`seen_along`). Returns the
    number of pixels supersampled."""
    from ..shading.alpha import ray_coverage

    height, width = image.shape[:2]
    ids = np.full((height, width), -1, np.int64)
    ids[fragments.rows, fragments.cols] = scene.object_ids[fragments.tri]
    rows, cols = np.nonzero(edge_pixels(image, ids))
    if rows.size == 0 or samples < 2:
        return 0
    flat = rows * width + cols
    offsets = pixel_patterns(samples, flat).reshape(-1, 2)  # sample-major, as the tiles below
    # Every sub-pixel ray of every edge pixel in one BVH call and one shading call: `shade` may
    # cost a few ms per call besides its points (the radiosity view's final gather).
    sub_rows = np.tile(rows, samples * samples)
    sub_cols = np.tile(cols, samples * samples)
    o, d = pixel_rays(scene.camera, width, height, sub_cols + offsets[:, 0],
                      sub_rows + offsets[:, 1])
    # Each ray stands for its cell of the pixel's n x n grid (`pixel_patterns`)
    centres = np.repeat(stratified_offsets(samples), rows.size, axis=0)
    value = seen_along(scene, o, d, shade, bvh, ray_coverage(scene, "camera"), sub_rows, sub_cols,
                       1.0 / samples, centres - offsets)
    image[rows, cols] = value.reshape(samples * samples, rows.size, 3).mean(axis=0)
    return int(rows.size)
