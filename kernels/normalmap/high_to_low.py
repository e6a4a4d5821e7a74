"""A detailed ("high") mesh's normals baked into a low-poly mesh's tangent-space normal map.

What Blender's bake does with "Selected to Active" for a NORMAL bake in tangent space, and what
every baker (xNormal, Substance, Marmoset) does in the same way:

1. **Texels.** Each texel of the low mesh's UV layout is baked at one point of the low surface
   (`kernels/bake/bake_targets.uv_texels`: the UV triangle that covers the texel's sample point,
   overlaps to the last triangle, Blender's sample shift).
2. **The cage ray.** From that point p with its interpolated low normal n (unit), the ray starts
   on the cage, c = p + e n (e the cage extrusion, metres), and runs inward along -n, for at most
   `max_ray` metres (Blender's Max Ray Distance; 0 there means unbounded, here: 2 e, as far
   inside the low surface as the cage lies outside). The closest hit on the high mesh counts;
   a hit on a triangle facing away from the ray's origin (its geometric normal along the ray) is
   a miss, as in Blender's bake (`cast_ray_highpoly` culls back faces after the closest hit).
3. **The high normal** at the hit: the high mesh's corner normals interpolated barycentrically
   and normalised (its smooth shading normal; a flat-shaded face's corners hold its face normal).
4. **Into the low tangent frame** at the texel: tangent t and normal n interpolated from the
   low triangle's corners without normalising, bitangent b = s (n x t) with s the sign of the
   interpolated corner signs, and the high normal N expressed in that frame by solving
   [t b n] x = N, x normalised (Blender's `RE_bake_normal_world_to_tangent`). This is the exact
   inverse of the Normal Map node, which decodes normalize(x t + y b + z n) with the same
   unnormalised t and n, so the map shades the low mesh with the high mesh's normals.
5. **Misses** (no hit, a back face, or beyond the ray's reach) take the flat normal (0, 0, 1)
   and are counted; the charts are padded and encoded as the height-made maps are
   (`dilate.pad_normals`, `encode.normals_to_rgb`).

Frames: MikkTSpace per corner of the low mesh (`mikktspace.py`, Blender's `calc_tangents`), in
the same space as the positions (world, metres). A transform with non-uniform scale is not
undone here (Blender converts to object space first); give world-space arrays of rigidly placed
or uniformly scaled objects.

Arrays: low and high corner arrays (T, 3, ...) float, world space, metres; maps (H, W, C),
row 0 at the top.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..bake.bake_targets import uv_texels
from ..geometry.bvh import BVH
from ..geometry.frames import tangent_frames
from ..geometry.scene import geometric_normals
from ..progress import Steps, scaled
from .dilate import FLAT, pad_normals
from .encode import normals_to_rgb
from .from_height import NormalMapSettings

# The automatic cage extrusion, as a share of the diagonal of the box around both meshes: deep
# enough for a sculpted relief of a few percent of the object's size (a displaced or smoothed
# version of the low mesh), shallow enough not to reach across thin parts to the far side.
AUTO_CAGE_REL = 0.05
# ... and at least this many times the largest gap between the two meshes' boxes along an axis:
# where the high mesh bulges out past the low one (a sphere over its low-poly cube's corners is
# inside, a subdivided cylinder's rim outside), the cage must still start outside it.
AUTO_CAGE_BOX_GAP = 1.5
# Shorter vectors than this have no direction (a frame that collapsed, a zero normal).
MIN_LENGTH = 1e-12
# A low frame [t b n] whose determinant is smaller than this (t along n: no tangent plane) is not
# inverted: the texel takes the high normal's components in the frame's orthonormalised version.
MIN_FRAME_DET = 1e-9


@dataclass(frozen=True)
class HighToLowSettings:
    """How a high mesh's normals are found from the low mesh's surface (the cage).

    | name    | range | default | unit | meaning                                           |
    |---------|-------|---------|------|---------------------------------------------------|
    | cage    | >= 0  | 0.0     | m    | how far outside the low surface, along its normal,|
    |         |       |         |      | each ray starts (Blender's Cage Extrusion); 0:    |
    |         |       |         |      | automatic, AUTO_CAGE_REL of the meshes' box       |
    |         |       |         |      | diagonal or AUTO_CAGE_BOX_GAP times their largest |
    |         |       |         |      | box gap, whichever is larger                      |
    | max_ray | >= 0  | 0.0     | m    | longest ray from the cage inward (Blender's Max   |
    |         |       |         |      | Ray Distance); 0: twice the cage, as deep inside  |
    |         |       |         |      | the low surface as the cage lies outside          |
    """

    cage: float = 0.0
    max_ray: float = 0.0

    def __post_init__(self):
        if not (self.cage >= 0.0 and self.max_ray >= 0.0):
            raise ValueError("cage and max_ray must not be negative")


@dataclass(frozen=True, eq=False)
class LowMesh:
    """The low-poly mesh the map is made for, per triangle corner (T triangles).

    | field     | shape            | meaning                                               |
    |-----------|------------------|-------------------------------------------------------|
    | uv        | (T, 3, 2) float  | the UV layer the map covers                           |
    | positions | (T, 3, 3) float  | corner positions, world, m                            |
    | normals   | (T, 3, 3) float  | corner normals, world, unit                           |
    | tangents  | (T, 3, 3) float  | MikkTSpace corner tangents on that UV layer, world    |
    | signs     | (T, 3) float     | bitangent signs, +1 or -1: b = sign (n x t)           |
    """

    uv: np.ndarray
    positions: np.ndarray
    normals: np.ndarray
    tangents: np.ndarray
    signs: np.ndarray


@dataclass(frozen=True, eq=False)
class HighMesh:
    """The detailed mesh whose normals are baked: triangles (H, 3, 3) world m and corner
    normals (H, 3, 3) world unit (its shading normals)."""

    triangles: np.ndarray
    normals: np.ndarray


@dataclass(frozen=True, eq=False)
class HighToLowMap:
    """A baked tangent-space normal map.

    | field       | shape / type        | meaning                                            |
    |-------------|---------------------|----------------------------------------------------|
    | normals     | (H, W, 3) float32   | unit tangent-space normals (OpenGL axes), padded   |
    | rgb         | (H, W, 3) float32   | colours in [0, 1] (settings' green convention)     |
    | mask        | (H, W) bool         | texels written: the charts and their padding       |
    | chart_texels| int                 | texels the low mesh's UV triangles cover           |
    | misses      | int                 | chart texels whose ray found no front face of the  |
    |             |                     | high mesh within reach (flat normal)               |
    | back_faces  | int                 | of those, rays whose closest hit was a back face   |
    | cage        | float, m            | the cage extrusion used (the automatic one solved) |
    | max_ray     | float, m            | the longest ray used                               |
    | settings    | NormalMapSettings   | size, green and padding used                       |
    """

    normals: np.ndarray
    rgb: np.ndarray
    mask: np.ndarray
    chart_texels: int
    misses: int
    back_faces: int
    cage: float
    max_ray: float
    settings: NormalMapSettings


def automatic_cage(low_positions: np.ndarray, high_triangles: np.ndarray) -> float:
    """The automatic cage extrusion, m (see `HighToLowSettings`): from the boxes of the low
    corners (T, 3, 3) and the high triangles (H, 3, 3)."""
    low = np.asarray(low_positions, np.float64).reshape(-1, 3)
    high = np.asarray(high_triangles, np.float64).reshape(-1, 3)
    lo = np.minimum(low.min(0), high.min(0))
    hi = np.maximum(low.max(0), high.max(0))
    gap = np.max(np.abs(np.concatenate([low.min(0) - high.min(0), low.max(0) - high.max(0)])))
    return float(max(AUTO_CAGE_REL * np.linalg.norm(hi - lo), AUTO_CAGE_BOX_GAP * gap))


def _normalize(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(length > MIN_LENGTH, v / np.maximum(length, MIN_LENGTH), 0.0)


def world_to_tangent(world: np.ndarray, normals: np.ndarray, tangents: np.ndarray,
                     signs: np.ndarray) -> np.ndarray:
    """(N, 3) float64 unit tangent-space normals of world normals (N, 3) in the frames of
    unnormalised interpolated normals and tangents (N, 3) with bitangent signs (N,): x solving
    [t b n] x = world, b = sign (n x t), normalised (the inverse of `mikktspace.tangent_to_object`
    and of Blender's Normal Map node). Frames that do not span space (t along n) are
    orthonormalised first."""
    n = np.asarray(normals, np.float64)
    t = np.asarray(tangents, np.float64)
    b = np.cross(n, t) * np.where(np.asarray(signs) < 0.0, -1.0, 1.0)[:, None]
    frame = np.stack([t, b, n], axis=2)  # (N, 3, 3): columns t, b, n
    det = np.linalg.det(frame)
    good = np.abs(det) > MIN_FRAME_DET
    out = np.empty_like(np.asarray(world, np.float64))
    if good.any():
        out[good] = np.linalg.solve(frame[good], np.asarray(world, np.float64)[good][..., None])[..., 0]
    if (~good).any():  # no tangent plane: any frame around n will do
        nb = _normalize(n[~good])
        t1, t2 = tangent_frames(nb)
        w = np.asarray(world, np.float64)[~good]
        out[~good] = np.stack([(w * t1).sum(1), (w * t2).sum(1), (w * nb).sum(1)], 1)
    out = _normalize(out)
    out[np.linalg.norm(out, axis=1) == 0.0] = FLAT
    return out


def high_to_low_steps(low: LowMesh, high: HighMesh,
                      map_settings: NormalMapSettings = NormalMapSettings(),  # noqa: B008
                      settings: HighToLowSettings = HighToLowSettings()  # noqa: B008
                      ) -> Steps[HighToLowMap]:
    """Bake `high`'s normals into `low`'s tangent-space map of map_settings.size^2 texels
    (module docstring); yields progress, returns a `HighToLowMap`."""
    size = int(map_settings.size)
    if size <= 0:
        raise ValueError("a high -> low bake needs a map size (size > 0)")
    cage = settings.cage or automatic_cage(low.positions, high.triangles)
    reach = settings.max_ray or 2.0 * cage
    texels = uv_texels(low.uv, size, size)
    yield 0.05
    tri, bary = texels.triangles, texels.bary  # (N,), (N, 3)
    point = np.einsum("nk,nkj->nj", bary, np.asarray(low.positions, np.float64)[tri])
    smooth = np.einsum("nk,nkj->nj", bary, np.asarray(low.normals, np.float64)[tri])
    tangent = np.einsum("nk,nkj->nj", bary, np.asarray(low.tangents, np.float64)[tri])
    sign = np.einsum("nk,nk->n", bary, np.asarray(low.signs, np.float64)[tri])
    direction = _normalize(smooth)
    flat = np.linalg.norm(direction, axis=1) == 0.0  # opposed corner normals: the face's own
    direction[flat] = geometric_normals(np.asarray(low.positions, np.float64)[tri[flat]])
    origin = point + cage * direction  # on the cage, m

    bvh = BVH.build(np.asarray(high.triangles, np.float64))
    yield 0.15
    hits = yield from scaled(bvh.intersect_steps(origin, -direction, 0.0, reach), 0.15, 0.8)
    found = hits.tri >= 0
    hit_tri = hits.tri[found].astype(np.int64)
    high_tris = np.asarray(high.triangles, np.float64)
    # The ray runs along -direction: a front face's normal points against it.
    along = np.einsum("nj,nj->n", geometric_normals(high_tris[hit_tri]), -direction[found])
    back = np.zeros(len(tri), bool)
    back[np.flatnonzero(found)[along >= 0.0]] = True  # the ray meets its back: a miss
    front = found & ~back
    hb = np.stack([1.0 - hits.u - hits.v, hits.u, hits.v], 1).astype(np.float64)[front]
    high_normal = _normalize(np.einsum(
        "nk,nkj->nj", hb, np.asarray(high.normals, np.float64)[hits.tri[front].astype(np.int64)]))

    local = np.broadcast_to(FLAT, (len(tri), 3)).astype(np.float64)
    local[front] = world_to_tangent(high_normal, smooth[front], tangent[front], sign[front])
    normals = np.broadcast_to(FLAT, (size, size, 3)).copy()
    normals[texels.rows, texels.cols] = local
    padded, filled = pad_normals(normals, texels.mask, map_settings.padding)
    yield 1.0
    return HighToLowMap(normals=padded, rgb=normals_to_rgb(padded, map_settings.green),
                        mask=filled, chart_texels=len(tri), misses=int((~front).sum()),
                        back_faces=int(back.sum()), cage=float(cage), max_ray=float(reach),
                        settings=map_settings)
