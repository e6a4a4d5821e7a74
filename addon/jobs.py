"""Bake jobs shared by operators and the command line: snapshot, kernels, write-back.

Each job is a generator that yields progress in [0, 1] and changes Blender data only after its
last yield, except for lightmap UV layers it must create before the snapshot reads them: those are
removed again if the job is closed early (Esc, an error), so a cancelled job leaves the scene as
it was. The last value yielded is a summary dict.
"""

from __future__ import annotations

import bpy
import numpy as np

from . import bridge


def mesh_objects(context, names=None):
    """Renderable mesh objects of the scene (optionally only `names`)."""
    return [o for o in context.scene.objects if o.type == "MESH" and not o.hide_render
            and (names is None or o.name in names)]


def _create_lightmap_uvs(objects, uv_name, uv_settings):
    created = []
    for obj in objects:
        made, _ = bridge.ensure_lightmap_uv(obj, uv_name, uv_settings)
        if made:
            created.append(obj)
    return created


def _remove_uv_layers(objects, uv_name):
    for obj in objects:
        layer = obj.data.uv_layers.get(uv_name)
        if layer is not None:
            obj.data.uv_layers.remove(layer)


def shadow_bake_job(context, settings, uv_name: str, uv_settings, attribute: str = "Shadow",
                    image_prefix: str = "Shadow", render: bool = True, resolution=None):
    """Bake the shadow-map mask of every mesh into a lightmap image and a corner colour attribute,
    and (render=True) the camera's view of direct light with shadows. Yields progress, then a
    summary {"images": {...}, "attributes": [...], "render": image or None, "skipped": [...]}."""
    from ..kernels import direct_light

    objects = mesh_objects(context)
    if not objects:
        raise ValueError("the scene has no mesh objects to bake")
    created = _create_lightmap_uvs(objects, uv_name, uv_settings)
    try:
        scene = bridge.snapshot(context, bridge.SnapshotRequest(lightmap_uv=uv_name, textures=render),
                                resolution=resolution)
        if not scene.lights:
            raise ValueError("the scene has no lights: nothing casts a shadow")
        targets = [k for k, o in enumerate(scene.objects) if not o.is_instance]
        results = None
        for step in direct_light.shadow_bake_steps(scene, targets, uv_settings.resolution,
                                                   uv_settings.padding, settings):
            if isinstance(step, dict):
                results = step
            else:
                yield 0.8 * step
        image = None
        if render and scene.camera is not None:
            for step in direct_light.render_steps(scene, settings, resolution):
                if isinstance(step, np.ndarray):
                    image = step
                else:
                    yield 0.8 + 0.2 * step
    except BaseException:
        _remove_uv_layers(created, uv_name)
        raise
    # --- write back: everything computed ---------------------------------------------------------
    summary = {"images": {}, "attributes": [], "render": None, "skipped": [],
               "lightmaps": {}, "per_light": {}, "scene": scene}
    for k, bake in results.items():
        info = scene.objects[k]
        obj = bpy.data.objects[info.source_name]
        if bake.lightmap is not None:
            name = f"{image_prefix} {info.source_name}"
            summary["images"][info.source_name] = bridge.write_image(
                name, bake.lightmap, image=bpy.data.images.get(name))
            summary["lightmaps"][info.source_name] = (bake.lightmap, bake.lightmap_mask)
            summary["per_light"][info.source_name] = bake.per_light_lightmaps
        if info.topology_matches_original:
            bridge.write_corner_values(obj.data, scene, k, bake.corners, attribute)
            summary["attributes"].append(info.source_name)
        else:
            summary["skipped"].append(f"{info.source_name}: modifiers change its topology, so the "
                                      "colour attribute is not written (the lightmap is)")
    if image is not None:
        summary["render"] = image
        name = "Classic Bake Shadows"
        bridge.write_image(name, image, image=bpy.data.images.get(name))
    yield summary
