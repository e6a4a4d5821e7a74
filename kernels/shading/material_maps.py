"""Material maps beyond the base colour: emission, metallic and roughness read from textures.

Real assets (glTF, FBX, texture libraries) drive a Principled BSDF's Emission Color, Metallic and
Roughness with image textures (glTF packs metallic in the blue and roughness in the green channel
of one image). The kernels model the base colour per texel everywhere; these three are resolved
here once per snapshot, so that every kernel reads them as it reads a constant material:

* emission: per hit where a camera view sees the surface (`emission_at`, texel-exact), and per
  triangle as a light (`Scene.triangle_radiance`: the texture's mean over the triangle, what the
  tracer's mesh lights and radiosity's sources emit); triangles whose mean is black emit nothing
  and cost no shadow rays;
* metallic and roughness: rounded to the multiples of `METALLIC_STEP` / `ROUGHNESS_STEP` and the
  map's extremes, each pair the maps can give a variant of the material with those
  constants (`Scene.map_variants`). A ray hit takes
  the variant of the maps' values at the hit (`hit_materials`: the tracer, so a low-poly asset's
  painted metal trim is metal where it is painted); a triangle carries the variant of their
  mean over it (`resolve_material_maps`), what kernels shading per triangle or texel read
  (each material's variant count is listed in `Scene.ignored`).

Coordinates are the texture's own: the active UVs, or Generated (`Texture.coordinates`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..geometry.scene import MapVariants, Material, Scene, Texture, triangle_emission
from .textures import sample_texture, srgb_to_linear

# Metallic and roughness per triangle are rounded to multiples of these steps before triangles
# are grouped into material variants: finer than a glTF texture's 8-bit steps would make a
# variant per triangle; 1/16 in roughness moves a GGX highlight's width by under 7% at roughness
# 0.5. The map's extremes are levels too: on the grid alone a uniform metallic of 0.3115 (a
# battery's map of 1 times its metallicFactor) rounds to 0.25, its diffuse 9% too bright.
METALLIC_STEP = 1.0 / 8.0
ROUGHNESS_STEP = 1.0 / 16.0
# Sub-triangles per side when a triangle's mean is taken: enough to average a texture over a
# triangle that spans up to about MAX_SIDE^2 / 2 texels; a smaller one gets fewer.
MAX_SIDE = 12


def corner_coords(scene: Scene, tri: np.ndarray, texture: Texture) -> np.ndarray:
    """(N, 3, 3) float64 per-corner coordinates of triangles `tri` that `texture` reads: (u, v, 0)
    on the active UVs, Generated, or a colour attribute's colours."""
    if texture.coordinates == "GENERATED" and scene.generated is not None:
        return scene.generated[tri].astype(np.float64)
    if texture.coordinates == "ATTRIBUTE":
        if scene.corner_colors is None:
            return np.zeros((len(tri), 3, 3))
        return scene.corner_colors[tri].astype(np.float64)
    out = np.zeros((len(tri), 3, 3))
    out[..., :2] = scene.uv[tri]
    return out


def lattice_points(n: int) -> np.ndarray:
    """(n^2, 3) barycentric centroids of the n^2 equal sub-triangles of a triangle."""
    points = []
    for i in range(n):
        for j in range(n - i):
            points.append((i + 1.0 / 3.0, j + 1.0 / 3.0))  # an upright sub-triangle
            if i + j < n - 1:
                points.append((i + 2.0 / 3.0, j + 2.0 / 3.0))  # the inverted one beside it
    st = np.array(points) / n
    return np.column_stack([1.0 - st.sum(axis=1), st])


def texels_covered(texture: Texture, coords: np.ndarray) -> np.ndarray:
    """(N,) about how many texels (checker squares) a triangle's coordinates (N, 3, 3) cover."""
    e1, e2 = coords[:, 1, :2] - coords[:, 0, :2], coords[:, 2, :2] - coords[:, 0, :2]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    if texture.kind == "CHECKER":
        return area * texture.scale ** 2
    if texture.kind == "ATTRIBUTE":  # linear across the triangle: its centroid holds its mean
        return np.ones(len(coords))
    height, width = texture.pixels.shape[:2]
    return area * width * height


def triangle_means(scene: Scene, tri: np.ndarray, texture: Texture) -> np.ndarray:
    """(N, 3) float64 mean of `texture` over each triangle of `tri`: the value at the centroids of
    n^2 sub-triangles, n from the texels the triangle covers (1 to MAX_SIDE)."""
    coords = corner_coords(scene, tri, texture)
    side = np.clip(np.ceil(np.sqrt(2.0 * texels_covered(texture, coords))), 1, MAX_SIDE).astype(int)
    out = np.empty((len(tri), 3))
    for n in np.unique(side):
        rows = np.flatnonzero(side == n)
        bary = lattice_points(int(n))  # (K, 3)
        points = np.einsum("kc,ncj->nkj", bary, coords[rows]).reshape(-1, 3)
        values = sample_texture(texture, points).reshape(len(rows), len(bary), 3)
        out[rows] = values.mean(axis=1)
    return out


def material_values(scene: Scene, tri: np.ndarray, bary: np.ndarray,
                    texture_of: Callable[[Material], Texture | None],
                    constant_of: Callable[[Material], np.ndarray]) -> np.ndarray:
    """(N, 3) float64 one material socket at barycentric points (N, 3) of triangles `tri`: each
    material's texture (`texture_of`) looked up through its own coordinates, else its constant."""
    mids = scene.material_ids[tri]
    out = np.zeros((len(tri), 3))
    for m in np.unique(mids):
        rows = mids == m
        mat = scene.materials[m]
        texture = texture_of(mat)
        if texture is None:
            out[rows] = constant_of(mat)
            continue
        coords = corner_coords(scene, tri[rows], texture)
        out[rows] = sample_texture(texture, np.einsum("nc,ncj->nj", bary[rows], coords))
    return out


def albedo_at(scene: Scene, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """Base colour (N, 3) at barycentric points of triangles, textures sampled through their
    coordinates (UVs or Generated)."""
    return material_values(scene, tri, bary, lambda m: m.base_color_texture,
                           lambda m: m.base_color)


def metal_f0(scene: Scene, tri: np.ndarray, base: np.ndarray) -> np.ndarray:
    """(N, 3) a metal's reflectance at normal incidence at points of triangles `tri`: their base
    colour `base` (`albedo_at`), or their material's `metal_color` where it has one."""
    tints = [(k, m.metal_color) for k, m in enumerate(scene.materials) if m.metal_color is not None]
    if not tints:
        return base
    out = np.array(base, np.float64, copy=True)
    mids = scene.material_ids[tri]
    for k, tint in tints:
        out[mids == k] = tint
    return out


def emission_at(scene: Scene, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(N, 3) float64 emitted radiance W/(m^2 sr) at barycentric points (N, 3) of triangles
    `tri`: the material's constant, or its emission texture looked up there."""
    return material_values(scene, tri, bary, lambda m: m.emission_texture, lambda m: m.emission)


def emission_detail(scene: Scene, tri: np.ndarray, bary: np.ndarray) -> np.ndarray | None:
    """(N, 3) what emission textures show at barycentric points (N, 3) of triangles `tri` beyond
    their triangles' means (`emission_at` less `triangle_emission`), W/(m^2 sr): what a camera
    view or a bake adds to values that carry each triangle's mean (radiosity's patches); on an
    unlit surface, which emits nothing into the scene, its whole emission. None when no
    material has an emission texture or glows unlit."""
    if not any(m.emission_texture is not None or (m.camera_only and m.is_emissive)
               for m in scene.materials):
        return None
    return emission_at(scene, tri, bary) - triangle_emission(scene)[tri]


def resolve_material_maps(scene: Scene) -> Scene:
    """The scene with its materials' emission, metallic and roughness textures resolved per
    triangle, and the metallic / roughness variants ray hits choose among (`hit_materials`)
    listed in `Scene.map_variants` (module docstring); the same scene when no material has
    such a texture."""
    textured = [k for k, m in enumerate(scene.materials)
                if m.emission_texture is not None or m.metallic_texture is not None
                or m.roughness_texture is not None]
    if not textured or scene.triangle_count == 0:
        return scene
    materials = list(scene.materials)
    material_ids = scene.material_ids.copy()
    radiance = None
    notes = list(scene.ignored)
    families = []
    for k in textured:
        mat = scene.materials[k]
        tri = np.flatnonzero(scene.material_ids == k)
        if mat.emission_texture is not None:
            if radiance is None:
                radiance = np.array([np.asarray(m.emission, np.float64) for m in materials]
                                    ).reshape(-1, 3)[scene.material_ids]
            radiance[tri] = np.maximum(triangle_means(scene, tri, mat.emission_texture), 0.0)
        if (mat.metallic_texture is None and mat.roughness_texture is None) or len(tri) == 0:
            continue
        metal_levels = _levels(scene, tri, mat.metallic_texture, mat.metallic, METALLIC_STEP)
        rough_levels = _levels(scene, tri, mat.roughness_texture, mat.roughness, ROUGHNESS_STEP)
        ids = np.empty((len(metal_levels), len(rough_levels)), np.int32)
        for n, (i, j) in enumerate(np.ndindex(ids.shape)):
            variant = replace(mat, metallic=float(metal_levels[i]),
                              roughness=float(rough_levels[j]),
                              metallic_texture=None, roughness_texture=None)
            if n == 0:
                materials[k] = variant
                ids[i, j] = k
            else:
                materials.append(replace(variant, name=f"{mat.name} ({n})"))
                ids[i, j] = len(materials) - 1
        metal = _level_index(_means(scene, tri, mat.metallic_texture), metal_levels, len(tri))
        rough = _level_index(_means(scene, tri, mat.roughness_texture), rough_levels, len(tri))
        material_ids[tri] = ids[metal, rough]
        families.append(MapVariants(mat, metal_levels, rough_levels, ids))
        notes.append(f"material '{mat.name}': metallic / roughness textures read at each ray hit "
                     f"of a traced view, per triangle elsewhere ({ids.size} variants, steps "
                     f"{METALLIC_STEP:g} / {ROUGHNESS_STEP:g} and the maps' extremes)")
    return replace(scene, materials=tuple(materials), material_ids=material_ids,
                   triangle_radiance=radiance, ignored=tuple(notes), map_variants=tuple(families))


def hit_materials(scene: Scene, tri: np.ndarray, bary: np.ndarray,
                  materials: np.ndarray) -> np.ndarray:
    """(N,) int32 the material of each hit, at barycentric points (N, 3) of triangles `tri`: where
    the triangle's material (`materials`, (N,)) has metallic / roughness maps, the variant of
    the maps' quantised values at the hit itself (`Scene.map_variants`); else unchanged."""
    if not scene.map_variants:
        return materials
    family = scene.variant_family[materials]
    out = materials.copy()
    for f in np.unique(family[family >= 0]):
        rows = np.flatnonzero(family == f)
        mv = scene.map_variants[f]

        def at_hits(texture, rows=rows):
            if texture is None:
                return None
            coords = corner_coords(scene, tri[rows], texture)
            return sample_texture(texture, np.einsum("nc,ncj->nj", bary[rows], coords))[:, 0]

        metal = _level_index(at_hits(mv.source.metallic_texture), mv.metallic, len(rows))
        rough = _level_index(at_hits(mv.source.roughness_texture), mv.roughness, len(rows))
        out[rows] = mv.ids[metal, rough]
    return out


def _means(scene: Scene, tri: np.ndarray, texture: Texture | None) -> np.ndarray | None:
    """(N,) a map's first channel's mean over each triangle of `tri`; None without a map."""
    return None if texture is None else triangle_means(scene, tri, texture)[:, 0]


def _level_index(values: np.ndarray | None, levels: np.ndarray, count: int) -> np.ndarray:
    """(count,) int64 indices into `levels` (ascending, `_levels`) of the nearest level to each
    of `values` (count,); zeros where there are no values (no map: one level, the constant)."""
    if values is None or len(levels) == 1:
        return np.zeros(count, np.int64)
    return np.searchsorted((levels[1:] + levels[:-1]) * 0.5, np.clip(values, 0.0, 1.0))


def _levels(scene: Scene, tri: np.ndarray, texture: Texture | None, constant: float,
            step: float) -> np.ndarray:
    """The values a map's look-ups on triangles `tri` are rounded to: its lowest and highest
    possible values (`_value_bounds`) and the multiples of `step` between them, so a map of one
    value or of two (a metal mask times glTF's metallicFactor) keeps them exactly; the
    material's constant alone when there is no map."""
    if texture is None:
        return np.array([float(constant)])
    lo, hi = np.clip(_value_bounds(scene, tri, texture), 0.0, 1.0)
    inner = np.arange(np.floor(lo / step) + 1, np.ceil(hi / step)) * step
    return np.unique(np.concatenate([[lo], inner[(inner > lo) & (inner < hi)], [hi]]))


def _value_bounds(scene: Scene, tri: np.ndarray, texture: Texture) -> tuple[float, float]:
    """(lowest, highest) value of a texture's first output channel anywhere: from its texels'
    (all tiles', decoded) per-channel extremes, a checker's two colours or the triangles' corner
    colours, through its node chain (bounds of a weighted sum: each weight at the end of the
    range that makes its term smallest or largest)."""
    if texture.kind == "CHECKER":
        corners = np.stack([texture.color1, texture.color2])
        corners = np.column_stack([corners, np.ones(2)])
    elif texture.kind == "ATTRIBUTE":
        colours = (scene.corner_colors[tri].reshape(-1, 3) if scene.corner_colors is not None
                   else np.zeros((1, 3)))
        corners = np.column_stack([colours, np.ones(len(colours))])
    else:
        images = texture.udim.values() if texture.udim is not None else [texture.pixels]
        flat = [p.reshape(-1, p.shape[-1]) for p in images]  # extremes in the stored precision
        corners = np.stack([np.min([f.min(axis=0) for f in flat], axis=0),
                            np.max([f.max(axis=0) for f in flat], axis=0)]).astype(np.float64)
        if corners.shape[1] == 3:
            corners = np.column_stack([corners, np.ones(2)])
        if texture.encoding == "sRGB":
            corners[:, :3] = srgb_to_linear(corners[:, :3])
        if texture.extension == "CLIP":  # transparent black outside the image
            corners[0] = np.minimum(corners[0], 0.0)
    lo4, hi4 = corners.min(axis=0), corners.max(axis=0)
    if texture.weights is None:
        lo, hi = lo4[0], hi4[0]
    else:
        w = np.asarray(texture.weights, np.float64)
        lo, hi = np.minimum(w * lo4, w * hi4).sum(), np.maximum(w * lo4, w * hi4).sum()
    ends = sorted((lo * texture.gain[0] + texture.offset[0], hi * texture.gain[0] + texture.offset[0]))
    if texture.clamp:
        ends = [min(max(e, 0.0), 1.0) for e in ends]
    return float(ends[0]), float(ends[1])


def material_with_maps(material: Material) -> bool:
    """True when `material` has a texture that `resolve_material_maps` resolves."""
    return (material.emission_texture is not None or material.metallic_texture is not None
            or material.roughness_texture is not None)


def translucent_colours(materials) -> np.ndarray:
    """(M, 3) each material's translucency (`Material.translucent`: a Translucent BSDF's colour
    x weight; 0 for most), indexed by material id."""
    return np.array([m.translucent for m in materials], np.float64).reshape(-1, 3)
