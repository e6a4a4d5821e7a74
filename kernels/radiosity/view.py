"""The scene camera's view of the solution (`render_steps`): B / pi at the surface each pixel sees,
the back of surfaces seen from behind, and what the diffuse solution leaves out but Cycles draws
at the camera's first hit: the rough glossy lobes lit directly by the lamps and the world."""

from __future__ import annotations

import numpy as np

from ..bake.camera_view import (
    EDGE_SAMPLES,
    background_and_fragments,
    blend_partial_cover,
    supersample_edges,
)
from ..geometry.bvh import BVH
from ..geometry.scene import Scene, geometric_normals, interpolated_normals, triangle_emission
from ..progress import Steps
from ..shading import lights as light_units
from ..shading.alpha import ray_coverage
from ..shading.bump import relief_at, scene_normals, valid_reflection
from ..shading.highlight_spread import NormalFootprint, fragment_patches, normal_derivatives
from ..shading.material_maps import albedo_at, emission_detail, hit_materials, metal_f0
from ..shading.pixel_texture import cell_albedo
from ..shading.reflected_emitters import ray_offset, reflected_emitters
from ..shading.specular_layer import (
    MIRROR_ROUGHNESS,
    coat_layer,
    lamp_highlights,
    layer_f0,
    view_factors,
    view_tables,
)
from .final_gather import camera_enclosed
from .lamps import light_query, light_visibility, shadowed_irradiance
from .result import RadiosityResult
from .sources import with_world_suns


def render_steps(scene: Scene, result: RadiosityResult, resolution=None,
                 out: np.ndarray | None = None, edge_samples: int = EDGE_SAMPLES
                 ) -> Steps[np.ndarray]:
    """The scene camera's view of the solution: outgoing radiance B / pi at the surface each
    pixel centre sees (rasterised), the world colour elsewhere; a surface seen from behind shows
    its back (`RadiosityResult.back_radiance_at`); emission textures show texel by texel
    (`material_maps.emission_detail`). Edge pixels (silhouettes, folds, hard shadow
    edges: `camera_view.edge_pixels`) are then the mean of edge_samples x edge_samples rays
    through them (`camera_view.supersample_edges`), as Cycles' 1-px box filter averages a pixel
    (0 or 1: the centres only). Yields progress, returns (H, W, 3)."""
    image, f = background_and_fragments(scene, resolution, out)
    yield 0.3
    # As the solve lit it: a world map's suns are lamps there, and gone from its map (the solve
    # saw no world where Cycles hides it from diffuse rays; the glossy lobes still may).
    solved = result.gather is not None and "diffuse" not in scene.world_hidden_from
    lit = result.gather.scene if solved else with_world_suns(scene)
    # What the camera sees lies inside no solid when the camera does not: no enclosure probes.
    open_camera = result.gather is not None and not camera_enclosed(result.gather, scene.camera)

    slopes = None  # the pixel centres' normal derivatives, for the sub-pixel rays' too

    def shade(f, centres: bool = False) -> np.ndarray:
        nonlocal slopes
        values = np.empty((len(f), 3))
        # Cycles shades a surface on the side it is seen from; the solution is the front's.
        front, back = ~f.back, f.back
        if front.any():
            t, b = f.tri[front], f.bary[front]
            frame = _front_frame(scene, result, t, b, f.dirs[front])
            mids = hit_materials(scene, t, b, scene.material_ids[t])  # metallic / roughness maps
            known = result.gather.opened(np.ones(len(t), bool)) if open_camera else None
            shading_normals = frame[1]
            # the pixel centres' textures averaged over their pixels, as Cycles' box filter
            albedo = cell_albedo(scene, t, b, f.rows[front], f.cols[front],
                                 image.shape[:2]) if centres else None
            values[front] = _at_view(scene, t, mids, f.dirs[front], shading_normals,
                                     result.radiance_at(t, b, known=known, albedo=albedo))
            coat = coat_layer(scene.materials, mids,
                              np.einsum("ij,ij->i", shading_normals, f.dirs[front]))
            if coat is not None:  # what the coat lets through of the base's light
                values[front] *= coat.under
            if centres:
                slopes = normal_derivatives(shading_normals, f.rows[front], f.cols[front],
                                            scene.object_ids[t], image.shape[:2],
                                            relief_at(scene, t))
            footprint = None if slopes is None else NormalFootprint.of_pixels(
                slopes, f.rows[front], f.cols[front], f.cell,
                None if f.to_cell is None else f.to_cell[front],
                fragment_patches(scene, f, slopes.smooth.shape, front))
            values[front] += _lamp_highlights(lit, result, t, b, mids, f.points[front],
                                              f.dirs[front], frame, footprint)
            values[front] += reflected_emitters(lit, t, b, mids, f.points[front], f.dirs[front],
                                                *frame, footprint=footprint)
        if back.any():
            values[back] = result.back_radiance_at(scene, f.tri[back], f.bary[back])
        detail = emission_detail(scene, f.tri, f.bary)  # the patches emit triangles' means
        return values if detail is None else values + detail

    if len(f):
        image[f.rows, f.cols] = shade(f, centres=True)
    yield 0.6
    blends = ray_coverage(scene, "camera") is not None  # surfaces the camera sees through
    if (blends or edge_samples > 1) and len(f):
        # The gather's BVH holds the sheets' turned-over copies too (`sheets.py`) when the solve
        # made any: the camera's rays then need one over the scene's own triangles.
        own = result.gather is not None and result.back_of is None
        bvh = result.gather.bvh if own else BVH.build(scene.triangles)
        if blends:
            blend_partial_cover(scene, image, f, shade, bvh)
        if edge_samples > 1:
            supersample_edges(scene, image, f, shade, bvh, edge_samples)
    return image


def _at_view(scene: Scene, tri: np.ndarray, mids: np.ndarray, dirs: np.ndarray,
             normals: np.ndarray, radiance: np.ndarray) -> np.ndarray:
    """(M, 3) radiance (M, 3) W/(m^2 sr) of surface points (triangles, their materials mids
    (M,): `material_maps.hit_materials`) as a camera looking along dirs (M, 3) sees it: the
    reflected part, which the texels show under the specular layer along the normal
    (`layer_factors`), rescaled to the layer at the view angle about the glossy normals (M, 3)
    (`specular_layer.view_factors`), as Cycles' diffuse lobe darkens towards grazing. The
    layer's own highlights are not drawn."""
    tables = view_tables(scene.materials)
    if not (tables < 1.0).any():  # no layer anywhere
        return radiance
    ratio = view_factors(tables, mids, np.einsum("ij,ij->i", normals, dirs)) / tables[mids, -1]
    emitted = triangle_emission(scene)[tri]
    return emitted + (radiance - emitted) * ratio[:, None]


def _front_frame(scene: Scene, result: RadiosityResult, tri: np.ndarray, bary: np.ndarray,
                 dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray, object, float]:
    """What the view's glossy terms need of front-facing surface points (triangles,
    barycentrics) seen along dirs (M, 3): their face normals (M, 3), the normals their glossy
    lobes turn about (interpolated, then bump and normal maps: `bump.scene_normals`, bent until
    the view's reflection leaves the surface: `bump.valid_reflection`, as Cycles' glossy
    closures and the tracer's) (M, 3), the BVH for their rays (the gather's, else built) and
    the rays' offset off surfaces, m."""
    geometric = geometric_normals(scene.triangles[tri])
    normals = valid_reflection(geometric, -dirs, scene_normals(
        scene, tri, bary, interpolated_normals(scene, tri, bary, geometric)))
    if result.gather is not None:
        return geometric, normals, result.gather.bvh, result.gather.offset
    return geometric, normals, BVH.build(scene.triangles), ray_offset(scene)


def _lamp_highlights(scene: Scene, result: RadiosityResult, tri: np.ndarray, bary: np.ndarray,
                     mids: np.ndarray, points: np.ndarray, dirs: np.ndarray, frame: tuple,
                     footprint: NormalFootprint | None = None) -> np.ndarray:
    """(M, 3) radiance W/(m^2 sr) the lamps' light leaves toward a camera looking along dirs
    (M, 3) by the rough glossy lobes (specular layers, metals) of surface points (triangles,
    barycentrics, materials (M,), world points (M, 3)): each lamp's shadowed irradiance (an
    area lamp's grid point by point, `_area_lamp_points`) times the GGX lobes
    (`specular_layer.lamp_highlights`), as Cycles lights the glossy lobes directly at the
    camera's first hit. Emissive meshes draw none. frame: `_front_frame` of the points;
    footprint: how their normals change across their pixels (`lamp_highlights`)."""
    out = np.zeros((len(tri), 3))
    shiny = [(m.roughness >= MIRROR_ROUGHNESS and (m.metallic > 0.0 or m.transmission > 0.0 or (
        layer_f0(m.ior, m.specular) > 0.0)))
        or (m.coat > 0.0 and m.coat_roughness >= MIRROR_ROUGHNESS) for m in scene.materials]
    if not scene.lights or not any(shiny) or not len(tri):
        return out
    geometric, normals, bvh, offset = frame
    gather = result.gather
    samples = gather.area_samples_per_side if gather is not None else 4
    # The lamps' shadow rays as the solve cast them (shadowless surfaces, shadow linking)
    occluded = gather.shadow_occluded() if gather is not None else bvh.occluded
    objects = scene.object_ids[tri]  # for the lamps' light linking
    base = metal_f0(scene, tri, albedo_at(scene, tri, bary))
    for light in (light for light in scene.lights if light.lights_glossy):
        if light.kind == "AREA":  # its highlight spread over the emitter, point by point
            reach = light_units.receiving(light, objects)
            for to_light, e, spread in _area_lamp_points(light, points, normals,
                                                         points + offset * geometric,
                                                         light_query(occluded, light), samples):
                e = e if reach is None else e * reach[:, None]
                out += lamp_highlights(scene.materials, mids, normals, -dirs, to_light, e, base,
                                       footprint, spread)
            continue
        e, _ = shadowed_irradiance(light, points, normals, points + offset * geometric,
                                   occluded, samples, objects=objects)
        to_light, _ = light_units.light_vectors(light, points)
        out += lamp_highlights(scene.materials, mids, normals, -dirs, to_light, e, base,
                               footprint)
    return out


def _area_lamp_points(light, points: np.ndarray, normals: np.ndarray, origins: np.ndarray,
                      occluded, samples: int):
    """Yields (unit directions (M, 3) to one of the area lamp's n x n grid points, the shadowed
    irradiance W/m^2 (M, 3) that point brings, the angular radius (M,) rad of the grid cell it
    stands for): the lamp's `direct_irradiance` split over its grid points in proportion to
    cos_receiver cos_lamp / d^2, each times its own shadow ray's visibility from `origins`. A
    glossy lobe lit this way draws the emitter's whole extent, not a highlight aimed at its
    centre."""
    targets = light_units.area_light_samples(light, samples)  # (K, 3)
    total = light_units.direct_irradiance(light, points, normals)  # (M, 3)
    delta = targets[:, None, :] - points[None, :, :]  # (K, M, 3)
    dist = np.linalg.norm(delta, axis=2)
    to = delta / np.maximum(dist, 1e-300)[..., None]
    cos_r = np.clip(np.einsum("mj,kmj->km", normals, to), 0.0, None)
    cos_l = np.clip(-to @ np.asarray(light.direction, np.float64), 0.0, None)
    weight = cos_r * cos_l / np.maximum(dist, 1e-300) ** 2  # (K, M)
    share = np.divide(weight, weight.sum(axis=0), out=np.zeros_like(weight),
                      where=weight.sum(axis=0) > 0.0)
    visible = np.ones_like(share)
    if occluded is not None and light.cast_shadow and len(points):
        visible = light_visibility(light, origins, occluded, samples, per_target=True)
    da = light_units.area_of_shape(light.shape, light.size_x, light.size_y) / len(targets)
    for k in range(len(targets)):
        yield (to[k], total * (share[k] * visible[k])[:, None],
               light_units.sample_radius(da, cos_l[k], dist[k]))
