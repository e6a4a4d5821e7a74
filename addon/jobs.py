"""Bake jobs shared by operators and the command line: snapshot, kernels, write-back.

Each job is a generator that yields progress in [0, 1] and changes Blender data only after its
last yield, except for lightmap UV layers it must create before the snapshot reads them: those are
removed again if the job is closed early (Esc, an error), so a cancelled job leaves the scene as
it was. The last value yielded is a summary dict.
"""

from __future__ import annotations

from contextlib import contextmanager

import bpy
import numpy as np

from . import bridge


def mesh_objects(context, names=None):
    """Renderable mesh objects of the scene (optionally only `names`)."""
    return [o for o in context.scene.objects if o.type == "MESH" and not o.hide_render
            and (names is None or o.name in names)]


def object_areas(objects) -> list[float]:
    """World-space surface area (m^2) of each object's mesh, modifiers not applied."""
    from ..kernels.geometry.scene import triangle_areas

    areas = []
    for obj in objects:
        verts, _, _, _ = bridge.mesh_triangles(obj.data)
        world = bridge.mesh_positions(obj.data).astype(np.float64) @ np.array(
            obj.matrix_world)[:3, :3].T
        areas.append(float(triangle_areas(world[verts]).sum()))
    return areas


def lightmap_plan(objects, uv_settings) -> dict:
    """{object name: lightmap size} at one texel density (`uv_settings.resolution` is the size of
    the largest object's lightmap)."""
    from ..kernels.bake.lightmap_uv import lightmap_sizes

    sizes = lightmap_sizes(object_areas(objects), uv_settings.resolution)
    return {obj.name: size for obj, size in zip(objects, sizes, strict=True)}


def create_lightmap_uvs(objects, uv_name, uv_settings, plan):
    from dataclasses import replace

    created = []
    for obj in objects:
        while True:  # a small lightmap may not hold every chart with its padding: grow it
            try:
                settings = replace(uv_settings, resolution=plan[obj.name])
                made, _ = bridge.ensure_lightmap_uv(obj, uv_name, settings)
                break
            except ValueError:
                if plan[obj.name] >= 4 * uv_settings.resolution:
                    raise
                plan[obj.name] *= 2
        if made:
            created.append(obj)
    return created


def _remove_uv_layers(objects, uv_name):
    for obj in objects:
        layer = obj.data.uv_layers.get(uv_name)
        if layer is not None:
            obj.data.uv_layers.remove(layer)


def forward(steps, start: float = 0.0, span: float = 1.0, is_result=lambda step: isinstance(step, dict)):
    """Re-yield a kernel generator's progress mapped onto [start, start + span]; `yield from`
    this returns the kernel's final value (the step for which `is_result` is true)."""
    result = None
    for step in steps:
        if is_result(step):
            result = step
        else:
            yield start + span * step
    return result


def run_to_end(job) -> dict:
    """Run a job generator to its end without reporting progress; returns its summary dict."""
    summary = None
    for step in job:
        if isinstance(step, dict):
            summary = step
    return summary


@contextmanager
def _lightmap_uvs(context, uv_name: str, uv_settings):
    """Every renderable mesh's lightmap size at one texel density ({name: texels}), with lightmap
    UV layers `uv_name` created for the meshes that lack one; those layers are removed again if
    the block stops early (an error, or the job closed by Esc), so the scene is left as it was."""
    objects = mesh_objects(context)
    if not objects:
        raise ValueError("the scene has no mesh objects to bake")
    plan = lightmap_plan(objects, uv_settings)
    created = create_lightmap_uvs(objects, uv_name, uv_settings, plan)
    try:
        yield plan
    except BaseException:
        _remove_uv_layers(created, uv_name)
        raise


def _bake_targets(scene, plan: dict, uv_settings) -> tuple[list[int], dict]:
    """The objects a bake writes back (indices into scene.objects: every one but instances, which
    share their original's mesh) and each one's lightmap size from the plan."""
    targets = [k for k, o in enumerate(scene.objects) if not o.is_instance]
    return targets, {k: plan.get(scene.objects[k].source_name, uv_settings.resolution)
                     for k in targets}


def _write_back(scene, bakes: dict, attribute: str, image_prefix: str, render_image,
                render_name: str, wire: bool = False) -> dict:
    """Write per-object bakes (objects with .lightmap, .lightmap_mask, .corners) as lightmap images
    and CORNER colour attributes, and the camera render as an image. Returns the summary."""
    summary = {"images": {}, "attributes": [], "render": render_image, "skipped": [],
               "lightmaps": {}, "scene": scene}
    for k, bake in bakes.items():
        info = scene.objects[k]
        obj = bpy.data.objects[info.source_name]
        if bake.lightmap is not None:
            name = f"{image_prefix} {info.source_name}"
            summary["images"][info.source_name] = bridge.write_image(
                name, bake.lightmap, image=bpy.data.images.get(name))
            summary["lightmaps"][info.source_name] = (bake.lightmap, bake.lightmap_mask)
        if info.topology_matches_original:
            bridge.write_corner_values(obj.data, scene, k, bake.corners, attribute)
            summary["attributes"].append(info.source_name)
            if wire:
                bridge.wire_baked_display(obj, attribute=attribute)
        elif obj.type != "MESH":  # a curve, text, surface or metaball: no mesh to hold one
            summary["skipped"].append(f"{info.source_name}: a {obj.type.lower()} object has no "
                                      "mesh to hold a colour attribute")
        else:
            summary["skipped"].append(f"{info.source_name}: modifiers change its topology, so the "
                                      "colour attribute is not written (the lightmap is)")
    if render_image is not None:
        bridge.write_image(render_name, render_image, image=bpy.data.images.get(render_name))
    return summary


def shadow_bake_job(context, settings, uv_name: str, uv_settings, attribute: str = "Shadow",
                    image_prefix: str = "Shadow", render: bool = True, resolution=None):
    """Bake the shadow-map mask of every mesh into a lightmap image and a corner colour attribute,
    and (render=True) the camera's view of direct light with shadows. Yields progress, then a
    summary {"images": {...}, "attributes": [...], "render": image or None, "skipped": [...]}."""
    from ..kernels.progress import scaled
    from ..kernels.shading import direct_light

    with _lightmap_uvs(context, uv_name, uv_settings) as plan:
        # The world shows only as the view's background (shadow masks ignore it).
        scene = bridge.snapshot(context, bridge.SnapshotRequest(lightmap_uv=uv_name, textures=render,
                                                                world_render=render),
                                resolution=resolution)
        if not scene.lights:
            raise ValueError("the scene has no lights: nothing casts a shadow")
        targets, sizes = _bake_targets(scene, plan, uv_settings)
        results = yield from scaled(
            direct_light.shadow_bake_steps(scene, targets, sizes, uv_settings.padding, settings),
            0.0, 0.8)
        image = None
        if render and scene.camera is not None:
            image = yield from scaled(direct_light.render_steps(scene, settings, resolution), 0.8, 0.2)
    # --- write back: everything computed ---------------------------------------------------------
    summary = _write_back(scene, results, attribute, image_prefix, image, "Classic Bake Shadows")
    summary["per_light"] = {scene.objects[k].source_name: bake.per_light_lightmaps
                            for k, bake in results.items() if bake.lightmap is not None}
    yield summary


def radiosity_bake_job(context, settings, uv_name: str, uv_settings, attribute: str = "Radiosity",
                       image_prefix: str = "Radiosity", render: bool = True, resolution=None,
                       wire: bool = False):
    """Solve the scene's radiosity and bake its outgoing radiance B / pi into a lightmap image
    ("Radiosity <object>") and a CORNER colour attribute (`attribute`) per mesh, and (render=True)
    the camera's view of the solution. `wire` makes materials show the attribute (Emission).
    Yields progress, then a summary {"images", "attributes", "render", "skipped", "lightmaps",
    "result", "scene"}."""
    from ..kernels.progress import scaled
    from ..kernels.radiosity.lightmap import bake_steps
    from ..kernels.radiosity.solve import radiosity_steps
    from ..kernels.radiosity.view import render_steps

    with _lightmap_uvs(context, uv_name, uv_settings) as plan:
        scene = bridge.snapshot(context, bridge.SnapshotRequest(lightmap_uv=uv_name, textures=True),
                                resolution=resolution)
        result = yield from scaled(radiosity_steps(scene, settings), 0.0, 0.85)
        targets, sizes = _bake_targets(scene, plan, uv_settings)
        bakes = yield from scaled(
            bake_steps(scene, result, targets, sizes, uv_settings.padding), 0.85, 0.1)
        image = None
        if render and scene.camera is not None:
            image = yield from scaled(render_steps(scene, result, resolution), 0.95, 0.05)
    # --- write back: everything computed ---------------------------------------------------------
    summary = _write_back(scene, bakes, attribute, image_prefix, image, "Classic Bake Radiosity",
                          wire=wire)
    summary.update(result=result, lightmap_sizes=plan,
                   filtered_texels=sum(b.filtered_texels for b in bakes.values()))
    yield summary


def texture_bake_job(context, settings, uv_name: str, uv_settings, attribute: str = "Albedo",
                     image_prefix: str = "Texture", render: bool = True, resolution=None,
                     render_overrides: dict | None = None):
    """Bake every mesh's diffuse albedo, its textures mapped through its UVs and filtered over
    each texel (`kernels/texture_bake.py`), into a lightmap image ("Texture <object>") and a
    CORNER colour attribute (`attribute`), and (render=True) the camera's view of the albedo.
    Yields progress, then a summary {"images", "attributes", "render", "skipped", "lightmaps",
    "scene", "stats"}."""
    from ..kernels.bake import texture_bake
    from ..kernels.progress import scaled

    with _lightmap_uvs(context, uv_name, uv_settings) as plan:
        # Albedo sees no light: a world shader is not worth rendering (`world_render`).
        scene = bridge.snapshot(context, bridge.SnapshotRequest(lightmap_uv=uv_name, textures=True,
                                                                world_render=False),
                                resolution=resolution)
        targets, sizes = _bake_targets(scene, plan, uv_settings)
        bakes = yield from scaled(
            texture_bake.texture_bake_steps(scene, targets, sizes, uv_settings.padding, settings),
            0.0, 0.6)
        image = None
        if render and scene.camera is not None:
            image = yield from scaled(
                texture_bake.render_steps(scene, resolution, **(render_overrides or {})), 0.6, 0.4)
    # --- write back: everything computed ---------------------------------------------------------
    summary = _write_back(scene, bakes, attribute, image_prefix, image, "Classic Bake Texture")
    summary.update(stats=texture_bake.stats(bakes), lightmap_sizes=plan)
    yield summary
