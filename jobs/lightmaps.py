"""What every bake into lightmaps shares: the lightmap options, one texel density across the scene's
meshes, lightmap UV layers made where missing (and removed again if the job stops early), and the
write-back of lightmap images and corner colour attributes."""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, replace

import bpy
import numpy as np

from ..addon.bridge import mesh as bridge_mesh
from ..addon.bridge import write_back
from ..kernels.bake.lightmap_uv import LightmapUVSettings, lightmap_sizes
from ..kernels.geometry.scene import triangle_areas
from .file_names import unique_stems
from .record import JobSummary, Option


@dataclass(frozen=True)
class LightmapTarget:
    """| field   | default    | meaning                                                  |
    |---------|------------|----------------------------------------------------------|
    | uv_name | "Lightmap" | the lightmap UV layer (created where missing, never overwritten) |
    """

    uv_name: str = "Lightmap"


LIGHTMAP_OPTIONS = (
    Option("uv_name", LightmapTarget, "UV Layer", "Name of the lightmap UV layer (created where "
           "missing, never overwritten)", prop="lightmap_uv_name"),
    Option("lightmap_size", LightmapUVSettings, "Lightmap Size", "Texels along each side of the "
           "largest object's lightmap; the others keep its texel density", field="resolution",
           minimum=16, maximum=16384, soft_max=4096, prop="lightmap_resolution"),
    Option("padding", LightmapUVSettings, "Padding", "Texels kept free between UV charts",
           minimum=0, maximum=64, prop="lightmap_padding"),
)


def lightmap_settings(values: dict) -> tuple[str, LightmapUVSettings]:
    """(UV layer name, LightmapUVSettings) from option values."""
    name = str(values["uv_name"]).strip()
    if not name:
        raise ValueError("the lightmap UV layer name is empty")
    return name, LightmapUVSettings(resolution=int(values["lightmap_size"]),
                                    padding=int(values["padding"]))


def lightmap_record(uv_name: str, uv_settings: LightmapUVSettings) -> dict:
    """The lightmap options as metrics.json records them beside a technique's own settings."""
    return {"lightmap_size": uv_settings.resolution, "padding": uv_settings.padding,
            "uv_name": uv_name}


def mesh_objects(context, names=None):
    """Renderable mesh objects of the scene (optionally only `names`)."""
    return [o for o in context.scene.objects if o.type == "MESH" and not o.hide_render
            and (names is None or o.name in names)]


def object_areas(objects) -> list[float]:
    """World-space surface area (m^2) of each object's mesh, modifiers not applied."""
    areas = []
    for obj in objects:
        verts, _, _, _ = bridge_mesh.mesh_triangles(obj.data)
        world = bridge_mesh.mesh_positions(obj.data).astype(np.float64) @ np.array(
            obj.matrix_world)[:3, :3].T
        areas.append(float(triangle_areas(world[verts]).sum()))
    return areas


def lightmap_plan(objects, uv_settings) -> dict:
    """{object name: lightmap size} at one texel density (`uv_settings.resolution` is the size of
    the largest object's lightmap)."""
    sizes = lightmap_sizes(object_areas(objects), uv_settings.resolution)
    return {obj.name: size for obj, size in zip(objects, sizes, strict=True)}


def create_lightmap_uvs(objects, uv_name, uv_settings, plan):
    """Give each object lacking one a lightmap UV layer `uv_name` at its planned size; returns the
    objects that got one."""
    created = []
    for obj in objects:
        # A small lightmap may not hold every chart with its padding: the unwrap grows it, up to
        # 4x the largest object's size.
        settings = replace(uv_settings, resolution=plan[obj.name])
        made, summary = bridge_mesh.ensure_lightmap_uv(obj, uv_name, settings,
                                                       largest=4 * uv_settings.resolution)
        if made:
            plan[obj.name] = summary["resolution"]
            created.append(obj)
    return created


def _remove_uv_layers(objects, uv_name):
    for obj in objects:
        layer = obj.data.uv_layers.get(uv_name)
        if layer is not None:
            obj.data.uv_layers.remove(layer)


@contextmanager
def lightmap_uvs(context, uv_name: str, uv_settings):
    """Every renderable mesh's lightmap size at one texel density ({name: texels}), with lightmap
    UV layers `uv_name` created for the meshes that lack one; those layers are removed again if
    the block stops early (an error, or the job closed by Esc), so the scene is left as it was."""
    objects, unusable = [], []
    for obj in mesh_objects(context):
        why = bridge_mesh.object_problem(obj)
        if why is None:
            objects.append(obj)
        else:  # the snapshot leaves it out too, and says so
            unusable.append(f"'{obj.name}' {why}")
    if not objects:
        raise ValueError("the scene has no mesh objects to bake" + (
            f": {'; '.join(unusable)}" if unusable else ""))
    plan = lightmap_plan(objects, uv_settings)
    created = create_lightmap_uvs(objects, uv_name, uv_settings, plan)
    try:
        yield plan
    except BaseException:
        _remove_uv_layers(created, uv_name)
        raise


def bake_targets(scene, plan: dict, uv_settings) -> tuple[list[int], dict]:
    """The objects a bake writes back (indices into scene.objects: every one but instances, which
    share their original's mesh) and each one's lightmap size from the plan."""
    targets = [k for k, o in enumerate(scene.objects) if not o.is_instance]
    return targets, {k: plan.get(scene.objects[k].source_name, uv_settings.resolution)
                     for k in targets}


def write_bakes(scene, bakes: dict, attribute: str, image_prefix: str, render_image,
                render_name: str, wire: bool = False) -> JobSummary:
    """Write per-object bakes (objects with .lightmap, .lightmap_mask, .corners) as lightmap images
    and CORNER colour attributes, and the camera render as an image. The summary's message is
    left for the technique to write."""
    summary = JobSummary(message="", scene=scene, render=render_image)
    for k, bake in bakes.items():
        info = scene.objects[k]
        obj = bpy.data.objects[info.source_name]
        if bake.lightmap is not None:
            name = f"{image_prefix} {info.source_name}"
            summary.images[info.source_name] = write_back.write_image(
                name, bake.lightmap, image=bpy.data.images.get(name))
            summary.lightmaps[info.source_name] = (bake.lightmap, bake.lightmap_mask)
        if info.topology_matches_original:
            write_back.write_corner_values(obj.data, scene, k, bake.corners, attribute)
            summary.attributes.append(info.source_name)
            if wire:
                write_back.wire_baked_display(obj, attribute=attribute)
        elif obj.type != "MESH":  # a curve, text, surface or metaball: no mesh to hold one
            summary.skipped.append(f"{info.source_name}: a {obj.type.lower()} object has no "
                                   "mesh to hold a colour attribute")
        else:
            summary.skipped.append(f"{info.source_name}: modifiers change its topology, so the "
                                   "colour attribute is not written (the lightmap is)")
    if render_image is not None:
        write_back.write_image(render_name, render_image, image=bpy.data.images.get(render_name))
    return summary


def lightmap_files(summary: JobSummary, suffix: str, previews: bool = False,
                   names: list[str] | None = None) -> dict:
    """The CLI's lightmap outputs: lightmaps/OBJECT_SUFFIX.exr (and .png with `previews`), each
    object's name made a safe file name unique among them (`unique_stems`: a hash suffix where
    cleaning changed the name), the extension never cut; metrics.json maps object -> file
    (`lightmap_files`). names: every object's name the whole bake writes, in its order, where the
    summary holds a share of them (a tile, jobs/tiles.py): the same files as the whole bake."""
    tail = f"_{suffix}.exr"
    stems = unique_stems(list(summary.lightmaps) if names is None else names, reserve=len(tail))
    files, where = {}, {}
    for name, (lightmap, _mask) in summary.lightmaps.items():
        files[f"lightmaps/{stems[name]}{tail}"] = lightmap
        where[name] = f"lightmaps/{stems[name]}{tail}"
        if previews:
            files[f"lightmaps/{stems[name]}_{suffix}.png"] = lightmap
    summary.extra["lightmap_files"] = where
    return files
