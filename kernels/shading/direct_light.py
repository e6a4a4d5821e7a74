"""Direct light with shadow maps: the shadow mask of bake targets, and a camera render of it.

For receivers f (lightmap texels, mesh corners or camera pixels) and every light l:
    E_l(f)  unshadowed irradiance (`lights.direct_irradiance`, W/m^2)
    V_l(f)  the lecture's shadow-map test (`shadowmap.py`), in [0, 1] with PCF
    shadow mask  S(f) = sum_l Y(E_l) V_l / sum_l Y(E_l)   (Y: luminance; 0 where no light reaches)
    radiance     L(f) = emission + albedo / pi * sum_l E_l V_l
The mask is the fraction of the direct light that arrives, which for one light is V itself.
Area lights are treated as points at their centre (hard shadows); emissive meshes are not lights.

Map resolution is chosen from the receivers ("model no more than a scene needs"): a map texel no
as large as the receivers' own spacing where they are, clamped to [MIN_MAP, MAX_MAP].
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from ..bake.bake_targets import BakeTargets
from ..bake.camera_view import (
    EDGE_SAMPLES,
    background_and_fragments,
    blend_partial_cover,
    supersample_edges,
)
from ..geometry.bvh import BVH
from ..geometry.scene import Scene, interpolated_normals
from ..geometry.vec import bounds, row_norms
from ..measure.metrics import REC709_LUMINANCE
from ..progress import Steps, drain, scaled
from ..shadow.cutouts import Cutout
from ..shadow.depth_maps import render_shadow_map_steps
from ..shadow.depth_test import receivers_visibility
from ..shadow.shadowmap import Receivers, ShadowMap, ShadowMapSettings
from ..shadow.views import fit_sun, plan_shadow_map, potential_casters
from . import lights as light_units
from .alpha import alpha_materials, has_alpha, ray_coverage, surface_alpha
from .bump import relief_at, relief_shadowing, scene_normals, valid_reflection
from .highlight_spread import NormalFootprint, PixelSlopes, fragment_patches, normal_derivatives
from .material_maps import albedo_at, emission_at, hit_materials, metal_f0, translucent_colours
from .pixel_texture import cell_albedo
from .reflected_emitters import ray_offset, rays_needed, reflected_emitters
from .specular_layer import coat_layer, diffuse_factor, lamp_highlights, view_factors, view_tables

MIN_MAP = 256  # below this a map cannot place even a coarse shadow edge
MAX_MAP = 8192  # 256 MiB of float32 depth per face: the memory bound of one map
LUMINANCE = np.array(REC709_LUMINANCE)
# Map texels per receiver spacing at the receivers. One: a shadow edge then lands within about one
# receiver of where it truly is (half a texel diagonal), which the receivers could not show finer.
# On bench/shadowmap.py's sun, spot and point light one per spacing disagrees with Cycles on at
# most 0.1% of the texels (two per spacing: 0.05%), far under 0.5%, with 2x to 15x fewer map
# texels to draw.
TEXELS_PER_SPACING = 1.0
MAP_STEP = 16  # map sides are rounded up to a multiple of this: no power-of-two waste
DISTANCE_SAMPLES = 4096  # receivers sampled (evenly strided) for their distances to a light
DISTANCE_QUANTILE = 0.9  # perspective maps: texel <= spacing at this fraction of the receivers


@dataclass(frozen=True)
class DirectLightSettings:
    """| field      | default          | meaning                                               |
    |------------|------------------|-------------------------------------------------------|
    | shadow     | ShadowMapSettings| eps mode, bias, PCF; its `resolution` is used when     |
    |            |                  | `auto_resolution` is False                             |
    | auto_resolution | True        | pick each map's resolution from the receivers          |
    """

    shadow: ShadowMapSettings = ShadowMapSettings()
    auto_resolution: bool = True


def map_resolution(light, points: np.ndarray, spacing: float, sun_span: float | None = None) -> int:
    """Map texels (per side, per face) so that a texel is <= spacing / TEXELS_PER_SPACING at the
    receivers.

    A sun's map is `sun_span` m across (`views.fit_sun(...).span`: what the casters and the
    receivers make it cover); without it, the receivers' whole extent across the beam (an upper
    bound).
    """
    spacing = max(spacing, 1e-9)
    target = spacing / TEXELS_PER_SPACING
    pts = np.asarray(points, np.float64)
    if light.kind == "SUN":
        if sun_span is not None:
            extent = sun_span
        elif len(pts):
            d = np.asarray(light.direction, np.float64)
            lateral = pts - np.outer(pts @ d, d)
            extent = float(np.subtract(*bounds(lateral)[::-1]).max())
        else:
            extent = 1.0
        res = extent / target
    else:
        # A perspective texel grows with distance: size it for the farther receivers too, so that
        # it is no larger than their spacing at DISTANCE_QUANTILE of them.
        d = _distance_quantile(pts, light.position) if len(pts) else 1.0
        angle = light.spot_size if light.kind == "SPOT" and light.spot_size < np.radians(120) else (
            np.pi / 2)
        res = 2.0 * d * np.tan(0.5 * angle) / target
    return int(np.clip(MAP_STEP * np.ceil(res / MAP_STEP), MIN_MAP, MAX_MAP))


def _distance_quantile(points: np.ndarray, position) -> float:
    """The DISTANCE_QUANTILE-th distance (m) of an even stride of DISTANCE_SAMPLES receivers from
    `position`: an order statistic by partition (np.quantile sorts and interpolates, ~5x the time)."""
    sample = points[:: max(1, len(points) // DISTANCE_SAMPLES)]
    d = row_norms(sample - np.asarray(position, np.float64))
    k = min(len(d) - 1, int(np.ceil(DISTANCE_QUANTILE * (len(d) - 1))))
    return float(np.partition(d, k)[k])


def receiver_spacing(targets: BakeTargets, area_m2: float) -> float:
    """Typical distance between neighbouring receivers: sqrt(area / count)."""
    return float(np.sqrt(max(area_m2, 1e-12) / max(len(targets), 1)))


def median_spacing(spacings, counts) -> float:
    """The median receiver spacing (m) when counts[k] receivers share spacings[k]: np.median of
    the repeated values, without building them (a bake holds hundreds of thousands)."""
    spacings = np.asarray(spacings, np.float64)
    counts = np.asarray(counts, np.int64)
    total = int(counts.sum())
    if total == 0:
        return 1.0
    order = np.argsort(spacings)
    ends = np.cumsum(counts[order])  # receivers up to and including each sorted spacing
    low, high = (total - 1) // 2, total // 2  # the middle receiver(s), 0-based
    pick = spacings[order]
    return 0.5 * float(pick[np.searchsorted(ends, low, "right")] + pick[np.searchsorted(ends, high, "right")])


def light_visibility_steps(scene: Scene, receivers: Receivers, spacing: float,
                           settings: DirectLightSettings, out: np.ndarray) -> Steps[np.ndarray]:
    """Fill out (L, N) float32 with each light's shadow-map visibility at the receivers (points
    and geometric normals, `Receivers.of` or `of_parts`); yields progress, returns `out`."""
    maps = yield from shadow_maps_steps(scene, receivers, spacing, settings)
    return maps_visibility(maps, receivers, out)


def shadow_maps_steps(scene: Scene, receivers: Receivers, spacing: float,
                      settings: DirectLightSettings) -> Steps[list[ShadowMap | None]]:
    """Each light's shadow map, planned for and rendered over the receivers (points and
    geometric normals, prepared once for every light: `Receivers.of`), `spacing` m apart: yields
    progress, returns the list (None for a light that casts no shadow)."""
    lights = scene.lights
    # Culling and planning read the receivers only through their bounding box (the sun's fit
    # reads them all, the map size an even sample): its two corners stand in for them there.
    box = receivers.box if len(receivers) else np.zeros((0, 3))
    sample = receivers.sample(DISTANCE_SAMPLES)
    maps = []
    # Unlit surfaces (every ray but the camera's passes them), shadowless ones and objects Cycles
    # hides from shadow rays cast no shadow.
    unlit = scene.ray_hidden("shadow")
    for k, light in enumerate(lights):
        if not light.cast_shadow or scene.triangle_count == 0:
            maps.append(None)
            continue
        shadow = settings.shadow
        casting = potential_casters(scene.triangles, light, box)
        if unlit is not None:
            casting &= ~unlit
        if light.blockers is not None:  # shadow linking: only its blockers cast its shadows
            casting &= light.blockers[scene.object_ids]
        caster_ids = np.flatnonzero(casting)
        casters = scene.triangles[caster_ids]
        fit = fit_sun(casters, light, receivers) if light.kind == "SUN" else None
        if settings.auto_resolution:
            shadow = replace(shadow, resolution=map_resolution(
                light, sample, spacing, fit.span if fit is not None else None))
        shadow_map = plan_shadow_map(casters, light, shadow, box, fit)  # casters: culled above
        maps.append(drain(render_shadow_map_steps(shadow_map, casters, _cutout(scene, caster_ids))))
        yield (k + 1) / max(len(lights), 1)
    return maps


def _cutout(scene: Scene, caster_ids: np.ndarray) -> Cutout | None:
    """The alpha test of casters scene.triangles[caster_ids] (`shadow/cutouts.py`), or None when
    no caster has alpha."""
    if not has_alpha(scene):
        return None
    cut = alpha_materials(scene)[scene.material_ids[caster_ids]]
    return Cutout(cut, lambda tri, bary: surface_alpha(scene, caster_ids[tri], bary))


def maps_visibility(maps: list, receivers: Receivers, out: np.ndarray) -> np.ndarray:
    """Fill out (L, N) float32 with each light's visibility at the receivers (points and
    geometric normals, `Receivers.of`) read from its shadow map (`shadow_maps_steps`; None: 1)."""
    for k, shadow_map in enumerate(maps):
        if shadow_map is None:
            out[k] = 1.0
        else:
            receivers_visibility(shadow_map, receivers, out=out[k])
    return out


def irradiance_per_light(scene: Scene, points, normals, smooth=None, objects=None) -> np.ndarray:
    """(L, N, 3) unshadowed irradiance of each light at the receivers, W/m^2. smooth (N, 3):
    the normals before a relief tilted them to `normals`, whose facets then hide part of a low
    light from the diffuse base (`bump.bump_shadowing`, as Cycles weighs diffuse light).
    objects (N,): the receivers' objects (indices into `scene.objects`), for the lights' light
    linking; None: every light reaches every receiver."""
    weight = None if smooth is None else relief_shadowing(smooth, normals)
    out = np.zeros((len(scene.lights), len(points), 3))
    for k, light in enumerate(scene.lights):
        out[k] = light_units.direct_irradiance(light, points, normals, weight)
        reach = light_units.receiving(light, objects)
        if reach is not None:
            out[k] *= reach[:, None]
    return out


def lamps_lighting(scene: Scene, lobe: str) -> np.ndarray:
    """(L,) 1.0 for the scene's lights that light `lobe` ("diffuse" or "glossy": their ray
    visibility, `Light.hidden_from`), else 0.0."""
    return np.array([lobe not in light.hidden_from for light in scene.lights], np.float64)


def shadow_mask(irradiance: np.ndarray, visibility: np.ndarray) -> np.ndarray:
    """(N,) float32: fraction of the direct light (by luminance) that arrives; 0 where none could."""
    y = np.einsum("lnc,c->ln", irradiance, LUMINANCE)
    total = y.sum(0)
    arrived = (y * visibility).sum(0)
    return np.where(total > 0, arrived / np.where(total > 0, total, 1.0), 0.0).astype(np.float32)


def diffuse_weight(material, under_layer: bool = True) -> float:
    """The Principled BSDF's diffuse weight, (1 - metallic)(1 - transmission): how much of the
    base colour a surface reflects diffusely. A metal or a glass reflects nothing diffusely: its
    light leaves along specular paths, which a diffuse solver does not follow (Cycles' DIFFUSE
    bake of it is black too). `under_layer`: times the share the specular layer leaves the base
    seen along the normal, as a bake sees every texel (`specular_layer.diffuse_factor`; 1 at
    Specular IOR Level 0)."""
    weight = (1.0 - material.metallic) * (1.0 - material.transmission)
    return weight * diffuse_factor(material) if under_layer and weight > 0.0 else weight


def diffuse_at(scene: Scene, tri: np.ndarray, bary: np.ndarray, under_layer: bool = True,
               albedo: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) diffuse reflectance at barycentric points of triangles: the base colour
    (`albedo_at`, or `albedo` (N, 3) when given: a pixel's filtered one) times the
    `diffuse_weight` of the material at each point (metallic and roughness maps read there,
    `material_maps.hit_materials`: a painted metal trim reflects nothing diffusely where it is
    painted)."""
    weight = np.array([diffuse_weight(m, under_layer) for m in scene.materials], np.float64)
    mids = hit_materials(scene, tri, bary, scene.material_ids[tri])
    base = albedo_at(scene, tri, bary) if albedo is None else albedo
    return base * weight[mids][:, None]


# --- the camera view ------------------------------------------------------------------------------


def render_steps(scene: Scene, settings: DirectLightSettings, resolution=None,
                 out: np.ndarray | None = None, edge_samples: int = EDGE_SAMPLES
                 ) -> Steps[np.ndarray]:
    """The camera's view of direct light with shadow-mapped shadows: the lecture's step 2, with
    the eye's own z-buffer giving the fragments f. Edge pixels (silhouettes, folds, shadow edges:
    `camera_view.edge_pixels`) are then the mean of edge_samples x edge_samples rays through them,
    as Cycles' 1-px box filter averages a pixel (0 or 1: the centres only). Yields progress,
    returns the (H, W, 3) image."""
    image, f = background_and_fragments(scene, resolution, out)
    camera = scene.camera
    width = image.shape[1]
    yield 0.2
    if len(f) == 0:
        return image
    # Pixel footprint at the receivers: the image plane's texel at distance t (PERSP) or in m.
    texel = (camera.plane_max[0] - camera.plane_min[0]) / width
    spacing = texel * (float(np.median(f.depth)) if camera.kind == "PERSP" else 1.0)
    receivers = _seen_receivers(f)  # plans the maps and reads them at the pixel centres
    maps = yield from scaled(shadow_maps_steps(scene, receivers, spacing, settings), 0.2, 0.6)
    rays = rays_needed(scene, area_lamps=False)  # the glossy lobes' rays to the sky, emitters
    blends = ray_coverage(scene, "camera") is not None  # surfaces the camera sees through
    bvh = BVH.build(scene.triangles) if rays or blends or edge_samples > 1 else None
    mirror = (bvh, ray_offset(scene)) if rays else None
    normals = _view_normals(scene, f)
    slopes = normal_derivatives(normals.glossy, f.rows, f.cols, scene.object_ids[f.tri],
                                image.shape[:2], relief_at(scene, f.tri))
    image[f.rows, f.cols] = _shade(scene, maps, f, receivers, mirror, slopes, normals)
    yield 0.8
    # The maps planned for the pixel centres serve the surfaces behind partly covered ones and
    # the sub-pixel rays too.
    def shade(g):
        return _shade(scene, maps, g, mirror=mirror, slopes=slopes)
    if blends:
        blend_partial_cover(scene, image, f, shade, bvh)
    if edge_samples > 1:
        supersample_edges(scene, image, f, shade, bvh, edge_samples)
    return image


def _seen_receivers(f) -> Receivers:
    """Fragments f as shadow-map receivers, their geometric normals turned to the side the eye
    sees (seen from behind: shade the side we see)."""
    geo = f.geometric.copy()
    geo[f.back] *= -1
    return Receivers.of(f.points, geo)


class ViewNormals(NamedTuple):
    """The normals fragments are shaded with, each (M, 3), turned to the side the eye sees."""

    geometric: np.ndarray  # the faces'
    smooth: np.ndarray  # interpolated
    mapped: np.ndarray  # interpolated, then bump and normal maps
    glossy: np.ndarray  # mapped, bent until the view's reflection leaves the surface
    relief: bool  # any bump or normal map changed `mapped`


def _view_normals(scene: Scene, f) -> ViewNormals:
    """`ViewNormals` of fragments f. A mapped normal tilted away from the eye keeps its tilt for
    the diffuse base (as Cycles' diffuse closures do); the glossy lobes turn about it bent until
    the view's reflection leaves the surface (`bump.valid_reflection`), as the tracer's do."""
    side = np.where(f.back, -1.0, 1.0)[:, None]
    smooth = interpolated_normals(scene, f.tri, f.bary)
    mapped = scene_normals(scene, f.tri, f.bary, smooth)
    relief = mapped is not smooth
    geometric = f.geometric * side
    mapped = mapped * side
    return ViewNormals(geometric, smooth * side, mapped, valid_reflection(geometric, -f.dirs, mapped),
                       relief)


def _shade(scene: Scene, maps: list, f, receivers: Receivers | None = None,
           mirror: tuple | None = None, slopes: PixelSlopes | None = None,
           view_normals: ViewNormals | None = None) -> np.ndarray:
    """(M, 3) radiance of fragments f (`Fragments`; `receivers`: `_seen_receivers(f)` and
    view_normals: `_view_normals(scene, f)`, when the caller has them): emission plus each
    light's diffuse light times its shadow-map visibility (`maps`, `shadow_maps_steps`) and the
    rough lobes' highlights, each averaged over its pixel's normals where slopes gives their
    change (`highlight_spread.normal_derivatives`); with `mirror` (the scene's BVH, the rays'
    offset m), what the glossy lobes show of the sky and of emissive surfaces
    (`reflected_emitters`: Cycles' direct model lights them from the world too)."""
    tri, bary, points, d = f.tri, f.bary, f.points, f.dirs
    geometric, smooth, normals, glossy, relief = (
        view_normals if view_normals is not None else _view_normals(scene, f))
    if receivers is None:
        receivers = _seen_receivers(f)
    vis = maps_visibility(maps, receivers, np.ones((len(scene.lights), len(points)), np.float32))
    objects = scene.object_ids[tri]
    e_diffuse = irradiance_per_light(scene, points, normals, objects=objects)
    e = e_diffuse  # the lobes'
    bent = np.flatnonzero(np.any(glossy != normals, axis=1))
    if bent.size:
        e = e_diffuse.copy()
        e[:, bent] = irradiance_per_light(scene, points[bent], glossy[bent], objects=objects[bent])
    if relief:  # the diffuse base's on the relief's tilted points
        tilted = np.flatnonzero(np.einsum("ij,ij->i", smooth, normals) < 1.0)
        e_diffuse = e_diffuse.copy()
        e_diffuse[:, tilted] = irradiance_per_light(scene, points[tilted], normals[tilted],
                                                    smooth[tilted], objects[tilted])
    # Each lamp's light where its ray visibility lets it: the diffuse base's, the lobes'.
    e_diffuse = e_diffuse * lamps_lighting(scene, "diffuse")[:, None, None]
    e = e * lamps_lighting(scene, "glossy")[:, None, None]
    # What reflects diffusely toward the eye: no metal or glass, and the base under the specular
    # layer darkened at this view (`specular_layer.py`), as Cycles' diffuse lobe.
    mids = hit_materials(scene, tri, bary, scene.material_ids[tri])  # metallic / roughness maps
    weight = np.array([diffuse_weight(m, under_layer=False) for m in scene.materials])[mids]
    weight = weight * view_factors(view_tables(scene.materials), mids,
                                   np.einsum("ij,ij->i", glossy, d))
    if slopes is not None and f.cell == 1.0 and f.to_cell is None:  # pixel centres' rays
        base = cell_albedo(scene, tri, bary, f.rows, f.cols, slopes.smooth.shape)
    else:  # a sub-pixel ray's cell: the texture at its point
        base = albedo_at(scene, tri, bary)
    albedo = base * weight[:, None]
    f0 = metal_f0(scene, tri, base)
    emission = emission_at(scene, tri, bary)
    # The rough lobes' highlights (a layer's, a metal's), as Cycles' direct-light render draws
    # them (lights as points).
    shine = np.zeros_like(points)
    footprint = None if slopes is None else NormalFootprint.of_pixels(
        slopes, f.rows, f.cols, f.cell, f.to_cell, fragment_patches(scene, f, slopes.smooth.shape))
    for k, light in enumerate(scene.lights):
        to_light, _ = light_units.light_vectors(light, points)
        shine += lamp_highlights(scene.materials, mids, glossy, -d, to_light, e[k],
                                 f0, footprint) * vis[k, :, None]
    if mirror is not None:
        shine += reflected_emitters(scene, tri, bary, mids, points, d, geometric, glossy,
                                    *mirror, area_lamps=False, footprint=footprint)
    diffuse = emission + albedo / np.pi * np.einsum("lnc,ln->nc", e_diffuse, vis)
    # A translucent surface passes the light on its back (colour / pi), its shadow test taken
    # on that side (a receiver facing away from a light is in its shadow).
    translucent = translucent_colours(scene.materials)[mids]
    lit_behind = np.flatnonzero(translucent.max(axis=1) > 0.0)
    if lit_behind.size:
        back = Receivers.of(points[lit_behind], -geometric[lit_behind])
        vis_back = maps_visibility(maps, back, np.ones((len(scene.lights), len(lit_behind)),
                                                       np.float32))
        e_back = irradiance_per_light(scene, points[lit_behind], -normals[lit_behind],
                                      objects=objects[lit_behind])
        e_back *= lamps_lighting(scene, "diffuse")[:, None, None]
        diffuse[lit_behind] += translucent[lit_behind] / np.pi * np.einsum(
            "lnc,ln->nc", e_back, vis_back)
    coat = coat_layer(scene.materials, mids, np.einsum("ij,ij->i", glossy, d))
    # what a coat lets through of the base's light (its own and the lobes' are in `shine`)
    return (diffuse if coat is None else diffuse * coat.under) + shine


# --- baking the shadow mask -----------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ObjectShadowBake:
    """One object's baked shadow mask."""

    lightmap: np.ndarray | None  # (S, S, 1) float32, row 0 top, dilated over the padding
    lightmap_mask: np.ndarray | None  # (S, S) bool: texels baked (before dilation)
    corners: np.ndarray  # (T * 3,) float32, per triangle corner, scene corner order
    per_light_lightmaps: np.ndarray | None  # (L, S, S) float32 visibility per light


def shadow_bake_steps(scene: Scene, objects, lightmap_sizes: dict, padding: int,
                      settings: DirectLightSettings) -> Steps[dict[int, ObjectShadowBake]]:
    """Shadow masks of `objects` (indices into scene.objects) on their lightmap texels (when the
    scene carries lightmap UVs; `lightmap_sizes` {object index: texels per side}) and corners.
    Yields progress, returns {object index: ObjectShadowBake}.
    """
    from ..bake.bake_targets import corner_targets, dilate, lightmap_targets
    from ..geometry.scene import triangle_areas

    # Every receiver of every object at once: one shadow map per light serves them all, at the
    # resolution the median receiver spacing asks for (a small object with a dense lightmap does
    # not set the map size for the whole scene).
    areas = triangle_areas(scene.triangles)
    sets = []  # (object, kind, targets)
    for k in objects:
        if scene.lightmap_uv is not None and scene.objects[k].has_lightmap_uv:
            sets.append((k, "lightmap", lightmap_targets(scene, k, lightmap_sizes[k])))
        sets.append((k, "corners", corner_targets(scene, k)))
        yield 0.1 * (len(sets) / (2 * max(len(objects), 1)))
    # The parts are read in place: concatenating them cost more than preparing them.
    receivers = Receivers.of_parts([t.points for _, _, t in sets], [t.geo_normals for _, _, t in sets])
    spacing = median_spacing([receiver_spacing(t, float(areas[scene.object_slice(k)].sum()))
                              for k, _, t in sets], [len(t) for _, _, t in sets])
    vis = np.ones((len(scene.lights), len(receivers)), np.float32)
    yield from scaled(light_visibility_steps(scene, receivers, spacing, settings, vis), 0.1, 0.85)
    results, start = {}, 0
    parts: dict = {}
    for k, kind, t in sets:
        stop = start + len(t)
        lit = irradiance_per_light(scene, t.points, t.normals, objects=np.full(len(t.points), k))
        lit *= lamps_lighting(scene, "diffuse")[:, None, None]
        mask = shadow_mask(lit, vis[:, start:stop])
        parts.setdefault(k, {})[kind] = (t, mask, vis[:, start:stop])
        start = stop
    for k in objects:
        out = parts[k]
        lightmap = mask_image = per_light = None
        if "lightmap" in out:
            targets, m, v = out["lightmap"]
            mask_image = targets.mask
            lightmap = dilate(targets.to_image(m), targets.mask, padding)
            per_light = np.stack([targets.to_image(row)[..., 0] for row in v]) if len(v) else None
        results[k] = ObjectShadowBake(lightmap=lightmap, lightmap_mask=mask_image,
                                      corners=out["corners"][1], per_light_lightmaps=per_light)
    return results
