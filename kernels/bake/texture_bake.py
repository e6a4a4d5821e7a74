"""Texture mapping, baked: every object's diffuse albedo, its textures looked up through its UVs,
into the texels of its lightmap (an atlas over the lightmap UVs) and its mesh corners.

The lecture's texture mapping runs from a screen pixel to the surface to (s, t) in the texture; a
bake runs from a lightmap texel instead. Each texel belongs to one triangle (`bake_targets.py`),
and on that triangle both UV maps are affine, so the texel's square in lightmap UV maps to a
parallelogram in texture UV with the 2 x 2 Jacobian

    J = d(s, t) / d(u, v) = [T1 - T0, T2 - T0] [L1 - L0, L2 - L0]^-1

(L: the triangle's lightmap UVs, T: its texture UVs). Its sides, J's columns over the lightmap's
width and height, measured in texture texels (checker squares for the checker) are the texel's
FOOTPRINT. A texel that spans many texture texels is a minified texture: one look-up at its
centre aliases (a fine checker comes out as random squares instead of its grey mean).

What a converged Cycles bake stores (its DIFFUSE bake with only the colour pass) is the mean over
texel ∩ triangle: a box filter, its first sample at the centre and every later one jittered over
the texel, kept inside the triangle (`bake_targets` module docstring). The kernel takes that mean
over n x n sub-texel cells (cells outside the triangle dropped, as Cycles drops its samples), each
cell contributing the texture's mean over a texture-space box of the cell's area:

* checker: exact (`textures.checker_box`, separable square waves) for a box; a cell's footprint is
  a parallelogram, which a box of the same area and aspect stands for;
* image: the bilinear look-up at the cell's centre (sRGB images interpolated as stored, then
  decoded, as Cycles does), which is the cell's mean while the cell spans a fraction of a texel.

n comes from the footprint ("model no more than the scene needs"): 1 where the material has no
texture, or where the map is axis-aligned and the texture a checker (the box IS the footprint);
`SKEWED_CHECKER_SIDE` for a checker under a rotated or sheared map; for an image, enough cells
that each spans at most `CELL_TEXELS` image texels, capped at `max_samples_per_side` (beyond it
the image is under-filtered; `stats` counts the texels per n). Texels that straddle their
triangle's edge take at least `EDGE_CELLS` (the mean is over texel ∩ triangle).

The albedo is what the diffuse lobe reflects: base colour x (1 - metallic) x (1 - transmission)
x (1 - the specular layer's albedo along the normal) (`direct_light.diffuse_at`,
`specular_layer.py`), plus a translucent surface's colour (a diffuse-type closure too), the
quantity Cycles' Diffuse Color pass and colour-only DIFFUSE bake hold.
Mesh corners take the value at the corner itself (a colour-attribute bake samples the vertex).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.scene import Scene
from ..progress import Steps
from ..shading.direct_light import diffuse_at, diffuse_weight
from ..shading.material_maps import hit_materials, translucent_colours
from ..shading.textures import checker_box, sample_texture

# Image texels one sub-texel cell may span. A cell takes the bilinear look-up at its centre, and
# the filtered image is a ramp across each texel boundary, bent by the sRGB decode: a cell's
# mean is its centre value only while it spans a fraction of the ramp. env_room's tiled floor
# (a hard-edged 240 x 200 image) against Cycles' 256-sample colour bake, at 0.96 image texels a
# lightmap texel: relMSE 8.7e-3 with 1 x 1 cells, 1.4e-3 with 2 x 2, 2.7e-4 with 4 x 4 (this
# rule); at 3.9 texels, 4 x 4 cells leave 3.1e-3.
CELL_TEXELS = 0.25
# Cells per side under a rotated or sheared map for a checker: the same-area box stands for the
# cell's parallelogram, which it matches except where a square's edge crosses the cell; halving
# the cell halves that error band.
SKEWED_CHECKER_SIDE = 2
# A map counts as axis-aligned when the footprint's bounding box exceeds its area by at most this
# fraction (float32 UVs round at ~1e-7 of a unit).
AXIS_ALIGNED_REL = 1e-5
# Texels that straddle their triangle's edge take at least this many cells per side: the mean is
# over texel ∩ triangle (Cycles drops samples outside), and a texture often jumps at a chart's UV
# border (a checker's squares change at u = 0), so a box reaching past the edge would mix in the
# far side (the sample checker plane: relMSE 1.1e-2 with one box, 1.9e-5 with 4 x 4 cells).
EDGE_CELLS = 4
# Barycentric slack of a texel corner lying ON its triangle's edge (grid-aligned charts): inside.
CORNER_SLACK = 1e-9
# Lightmap UV triangles with |det| below this (uv units^2) are degenerate: their texels take the
# centre value, footprint 0 (no Jacobian exists).
DEGENERATE_UV_AREA = 1e-14


@dataclass(frozen=True)
class TextureBakeSettings:
    """| field                | range   | default | meaning                                     |
    |----------------------|---------|---------|---------------------------------------------|
    | samples_per_side     | >= 0    | 0       | n x n sub-texel cells per texel; 0: from    |
    |                      |         |         | each texel's footprint (module docstring)   |
    | max_samples_per_side | >= 1    | 8       | the cap on n when chosen from footprints    |
    """

    samples_per_side: int = 0
    max_samples_per_side: int = 8

    def __post_init__(self) -> None:
        if self.samples_per_side < 0 or self.max_samples_per_side < 1:
            raise ValueError("samples_per_side must be >= 0 (0: auto) and max_samples_per_side >= 1")


@dataclass(frozen=True, eq=False)
class ObjectTextureBake:
    """One object's baked albedo."""

    lightmap: np.ndarray | None  # (S, S, 3) float32 linear, row 0 top, dilated over the padding
    lightmap_mask: np.ndarray | None  # (S, S) bool: texels baked (before dilation)
    corners: np.ndarray  # (T * 3, 3) float32, per triangle corner, scene corner order
    cells: np.ndarray | None  # (N,) int n per baked texel (n x n cells)


def _lightmap_inverse(scene: Scene, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[L1 - L0, L2 - L0]^-1 (M, 2, 2) of scene triangles' lightmap UVs (what turns a lightmap-uv
    offset into barycentric weights b1, b2), and (M,) bool where it does not exist (zeros)."""
    lm = scene.lightmap_uv[triangles].astype(np.float64)  # (M, 3, 2)
    el = np.stack([lm[:, 1] - lm[:, 0], lm[:, 2] - lm[:, 0]], axis=2)  # columns: edges, (M, 2, 2)
    det = el[:, 0, 0] * el[:, 1, 1] - el[:, 0, 1] * el[:, 1, 0]
    degenerate = np.abs(det) < DEGENERATE_UV_AREA
    safe = np.where(degenerate, 1.0, det)
    inverse = np.stack([np.stack([el[:, 1, 1], -el[:, 0, 1]], 1),
                        np.stack([-el[:, 1, 0], el[:, 0, 0]], 1)], 1) / safe[:, None, None]
    inverse[degenerate] = 0.0
    return inverse, degenerate


def texel_jacobians(scene: Scene, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """J (M, 3, 2) = d(texture coordinates) / d(lightmap uv) of scene triangles (M,) (rows: the
    coordinates of `Scene.texture_coords`, u, v, 0 or Generated x, y, z), and (M,) bool where the
    lightmap UV triangle is degenerate (J = 0 there)."""
    tex = scene.texture_coords[triangles]
    et = np.stack([tex[:, 1] - tex[:, 0], tex[:, 2] - tex[:, 0]], axis=2)
    inverse, degenerate = _lightmap_inverse(scene, triangles)
    return np.einsum("mij,mjk->mik", et, inverse), degenerate


def straddling(scene: Scene, targets) -> np.ndarray:
    """(N,) bool: lightmap texels of `targets` not wholly inside their own triangle (a corner of
    the texel's square lies outside it: chart borders and the edges between triangles)."""
    height, width = targets.mask.shape
    inverse, _ = _lightmap_inverse(scene, targets.triangles)
    origin = scene.lightmap_uv[targets.triangles, 0].astype(np.float64)  # (N, 2) L0
    out = np.zeros(len(targets), bool)
    for du, dv in ((0, 0), (1, 0), (0, 1), (1, 1)):
        corner = np.stack([(targets.cols + du) / width, 1.0 - (targets.rows + dv) / height], 1)
        b12 = np.einsum("nij,nj->ni", inverse, corner - origin)
        out |= (b12 < -CORNER_SLACK).any(axis=1) | (b12.sum(axis=1) > 1.0 + CORNER_SLACK)
    return out


def texture_units(scene: Scene, triangles: np.ndarray) -> np.ndarray:
    """(M, 3) texture units per coordinate unit along each texture axis for each triangle's
    material: an image's width and height in texels (it ignores the third), a checker's scale in
    squares, 0 without a texture or for a colour attribute."""
    units = np.zeros((len(triangles), 3))
    mids = scene.material_ids[triangles]
    for m in np.unique(mids):
        texture = scene.materials[m].base_color_texture
        if texture is None:
            continue
        rows = mids == m
        if texture.kind == "CHECKER":
            units[rows] = texture.scale
        elif texture.kind == "ATTRIBUTE":  # smooth: one sample a texel reads it
            continue
        else:
            height, width = texture.pixels.shape[:2]
            units[rows] = (width, height, 0)
    return units


def footprint_box(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For parallelograms of sides a, b (M, 3) in texture space, over the two axes each spreads
    along most: (the bounding box's area, the parallelogram's area) (M,) each, and (M,) bool
    where it also spreads along the third beyond AXIS_ALIGNED_REL (a face slanted in Generated
    space, whose bounding box is larger than it; UV footprints never are: their third
    coordinate is 0)."""
    extent = np.abs(a) + np.abs(b)
    order = np.argsort(extent, axis=1, kind="stable")
    keep = np.sort(order[:, 1:], axis=1)
    least = np.take_along_axis(extent, order[:, :1], axis=1)[:, 0]
    slanted = least > AXIS_ALIGNED_REL * extent.max(axis=1, initial=0.0)
    a2, b2 = np.take_along_axis(a, keep, axis=1), np.take_along_axis(b, keep, axis=1)
    box = np.take_along_axis(extent, keep, axis=1).prod(axis=1)
    return box, np.abs(a2[:, 0] * b2[:, 1] - a2[:, 1] * b2[:, 0]), slanted


def cells_per_side(scene: Scene, triangles: np.ndarray, jac: np.ndarray, size: tuple[int, int],
                   settings: TextureBakeSettings, edge: np.ndarray | None = None) -> np.ndarray:
    """(M,) n for texels of triangles (M,) with Jacobians jac (M, 3, 2) in a lightmap of size
    (W, H) texels (module docstring); `edge` (M,) bool marks texels that straddle their
    triangle (`straddling`), which take at least `EDGE_CELLS` where textured."""
    if settings.samples_per_side > 0:
        return np.full(len(triangles), settings.samples_per_side, np.int64)
    width, height = size
    units = texture_units(scene, triangles)  # (M, 3)
    # The footprint's two sides in texture units: J's columns over one texel.
    side_u = jac[:, :, 0] / width * units
    side_v = jac[:, :, 1] / height * units
    footprint = np.maximum(np.linalg.norm(side_u, axis=1), np.linalg.norm(side_v, axis=1))
    n = np.clip(np.ceil(footprint / CELL_TEXELS), 1, settings.max_samples_per_side).astype(np.int64)
    mids = scene.material_ids[triangles]
    checker = np.array([m.base_color_texture is not None and m.base_color_texture.kind == "CHECKER"
                        for m in scene.materials], bool)[mids]
    # Axis-aligned (a rectangle, quarter turns and mirrors included): the footprint's bounding
    # box has the footprint's own area.
    box, area, slanted = footprint_box(jac[:, :, 0], jac[:, :, 1])
    skewed = slanted | (box > (1.0 + AXIS_ALIGNED_REL) * area)
    # A checker's boxes are exact at any size: under an axis-aligned map the box IS the
    # footprint, under a skewed one a few cells narrow the band where box and footprint differ.
    n[checker] = np.where(skewed[checker], min(SKEWED_CHECKER_SIDE, settings.max_samples_per_side), 1)
    textured = units.max(axis=1) > 0.0
    if edge is not None:  # the mean is over texel ∩ triangle: cells drop the far side
        grow = edge & textured
        n[grow] = np.maximum(n[grow], min(EDGE_CELLS, settings.max_samples_per_side))
    n[~textured] = 1  # no texture: nothing varies within the triangle
    return n


def _texture_uv(scene: Scene, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(P, 3) texture coordinates (`Scene.texture_coords`) at barycentrics bary (P, 3) of
    triangles tri (P,)."""
    return np.einsum("pc,pcj->pj", bary, scene.texture_coords[tri])


def _cell_albedo(scene: Scene, tri: np.ndarray, bary: np.ndarray, uv: np.ndarray, half: np.ndarray
                 ) -> np.ndarray:
    """(P, 3) diffuse albedo at cells of triangles tri (P,) centred at barycentrics bary (P, 3),
    texture coordinates uv (P, 3): the base colour's mean over a texture-space box of half
    extents `half` (P, 3) around it (checker: exact; image: bilinear at the centre) times the
    diffuse weight of the material at the centre (metallic maps read there)."""
    out = np.empty((len(tri), 3))
    mids = scene.material_ids[tri]
    weight = np.array([diffuse_weight(m) for m in scene.materials])
    for m in np.unique(mids):
        rows = np.flatnonzero(mids == m)
        mat = scene.materials[m]
        texture = mat.base_color_texture
        if texture is None:
            out[rows] = mat.base_color
            continue
        if texture.kind == "CHECKER":
            out[rows] = checker_box(uv[rows] - half[rows], uv[rows] + half[rows], texture.color1,
                                    texture.color2, texture.scale)
        else:
            out[rows] = sample_texture(texture, uv[rows])
    # A translucent surface's colour counts too, as in Cycles' Diffuse Color pass.
    translucent = translucent_colours(scene.materials)[mids]
    return out * weight[hit_materials(scene, tri, bary, mids)][:, None] + translucent


def _cell_half_extents(jac: np.ndarray, n: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """(M, 3) half extents in texture space of the box standing for one of a texel's n x n
    cells: the cell's parallelogram's bounding box, shrunk to the parallelogram's area (same
    aspect) over the two axes it spreads along most (`footprint_box`)."""
    width, height = size
    a = jac[:, :, 0] / (width * n[:, None])  # the cell's sides in texture space, (M, 3)
    b = jac[:, :, 1] / (height * n[:, None])
    half = 0.5 * (np.abs(a) + np.abs(b))
    box, area, _ = footprint_box(a, b)
    shrink = np.sqrt(np.divide(area, box, out=np.ones_like(area), where=box > 0.0))
    return half * shrink[:, None]


def texel_albedo(scene: Scene, targets, settings: TextureBakeSettings = TextureBakeSettings()  # noqa: B008
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) diffuse albedo of lightmap `targets` (`bake_targets.lightmap_targets`), each texel
    the mean over texel ∩ triangle of its n x n cells, and n (N,)."""
    from .bake_targets import SAMPLE_SHIFT, subtexel_points

    height, width = targets.mask.shape
    size = (width, height)
    tri = targets.triangles
    jac, degenerate = texel_jacobians(scene, tri)
    edge = straddling(scene, targets) if settings.samples_per_side == 0 else None
    n = cells_per_side(scene, tri, jac, size, settings, edge)
    n[degenerate] = 1
    half = _cell_half_extents(jac, n, size)
    values = np.empty((len(tri), 3))
    single = n == 1  # and below, slivers thinner than the cell spacing, which keep no cell
    for k in np.unique(n[n > 1]):
        which = np.flatnonzero(n == k)
        owner, cell_tri, bary = subtexel_points(scene, targets, which, int(k))
        cells = _cell_albedo(scene, cell_tri, bary, _texture_uv(scene, cell_tri, bary),
                             half[which[owner]])
        sums = np.zeros((len(which), 3))
        np.add.at(sums, owner, cells)
        counts = np.bincount(owner, minlength=len(which))
        kept = counts > 0
        values[which[kept]] = sums[kept] / counts[kept, None]
        single[which[~kept]] = True
    # One cell: the whole texel's box around its centre (the targets' points sit where Blender
    # takes its first sample, `SAMPLE_SHIFT` texels off; J carries them back).
    rows = np.flatnonzero(single)
    shift = np.array(SAMPLE_SHIFT) / np.array(size, np.float64)  # lightmap uv
    centre = _texture_uv(scene, tri[rows], targets.bary[rows]) - jac[rows] @ shift
    values[rows] = _cell_albedo(scene, tri[rows], targets.bary[rows], centre, half[rows])
    return values, n


def texture_bake_steps(scene: Scene, objects, lightmap_sizes: dict, padding: int,
                       settings: TextureBakeSettings = TextureBakeSettings()  # noqa: B008
                       ) -> Steps[dict[int, ObjectTextureBake]]:
    """The diffuse albedo of `objects` (indices into scene.objects) on their lightmap texels (when
    the scene carries lightmap UVs; sizes {object index: texels per side}) and at their mesh
    corners. Yields progress, returns {object index: ObjectTextureBake}."""
    from .bake_targets import corner_targets, dilate, lightmap_targets

    out = {}
    for i, k in enumerate(objects):
        lightmap = mask = cells = None
        if scene.lightmap_uv is not None and scene.objects[k].has_lightmap_uv:
            targets = lightmap_targets(scene, k, lightmap_sizes[k])
            values, cells = texel_albedo(scene, targets, settings)
            mask = targets.mask
            lightmap = dilate(targets.to_image(values), mask, padding)
        corners = corner_targets(scene, k)
        corner_values = diffuse_at(scene, corners.triangles, corners.bary).astype(np.float32)
        out[k] = ObjectTextureBake(lightmap, mask, corner_values, cells)
        yield (i + 1) / max(len(objects), 1)
    return out


def stats(bakes: dict) -> dict:
    """Figures for metrics.json: texels baked, cells looked up, texels per n."""
    cells = [b.cells for b in bakes.values() if b.cells is not None]
    n = np.concatenate(cells) if cells else np.zeros(0, np.int64)
    values, counts = np.unique(n, return_counts=True)
    return {"texels": int(n.size), "cells": int((n * n).sum()),
            "texels_per_cells_per_side": {int(v): int(c) for v, c in zip(values, counts, strict=True)}}


def render_settings(**overrides):
    """The tracer settings of texture mapping's camera view: camera rays only (depth 0), each
    returning the diffuse albedo it sees, its textures averaged over the pixel (`tracer.py`,
    output "albedo": Cycles' Diffuse Color pass), silhouettes supersampled."""
    from ..trace.settings import TracerSettings

    return TracerSettings(**{"max_depth": 0, "output": "albedo", **overrides})


def render_steps(scene: Scene, resolution=None, bvh=None, out: np.ndarray | None = None,
                 **overrides) -> Steps[np.ndarray]:
    """The scene camera's view of the albedo (`render_settings`). Yields progress, returns
    (H, W, 3) float32, 0 where no surface is seen."""
    from ..trace.tracer import trace_steps

    result = yield from trace_steps(scene, render_settings(**overrides), bvh=bvh,
                                    resolution=resolution, out=out)
    return result.image
