"""Lightmap UVs from xatlas for the selected meshes (or all), never overwriting a UV layer."""

import bpy
from bpy.props import BoolProperty

from ..addon import bridge
from ..addon.settings import lightmap_uv_settings
from .job import JobOperator, ScenePoll


def _targets(context, all_objects: bool):
    objects = context.scene.objects if all_objects else context.selected_objects
    seen, out = set(), []
    for obj in objects:
        # One unwrap per mesh datablock: objects sharing a mesh share its UV layers.
        if obj.type == "MESH" and not obj.hide_render and obj.data.name_full not in seen:
            seen.add(obj.data.name_full)
            out.append(obj)
    return out


def unwrap_job(targets, name: str, settings, report):
    """Unwrap `targets` one per step (yielding progress), then write every UV layer at the end."""
    results = []
    for k, obj in enumerate(targets):
        loop_uv, summary = bridge.lightmap_loop_uv(obj, settings)
        results.append((obj, loop_uv, summary))
        yield (k + 1) / (len(targets) + 1)
    # Everything computed: only now touch the meshes (a cancel above changed nothing).
    split = 0
    for obj, loop_uv, summary in results:
        bridge.write_uv_layer(obj.data, name, loop_uv)
        split += summary["split_polygons"]
    message = f"Lightmap UVs '{name}' on {len(results)} meshes"
    if split:
        message += f" ({split} polygons split across charts)"
    report({"WARNING"} if split else {"INFO"}, message)


class CLASSICBAKE_OT_lightmap_uv(ScenePoll, JobOperator, bpy.types.Operator):
    """Unwrap and pack meshes into a new lightmap UV layer (xatlas); existing layers are kept"""

    bl_idname = "classic_bake.lightmap_uv"
    bl_label = "Create Lightmap UVs"
    bl_options = {"REGISTER", "UNDO"}
    job_label = "Lightmap UVs"
    needs = ("mesh",)

    all_objects: BoolProperty(
        name="All Objects", description="Unwrap every mesh in the scene, not only the selection",
        default=False)

    def start(self, context):
        settings = lightmap_uv_settings(context.scene.classic_bake)
        name = context.scene.classic_bake.lightmap_uv_name.strip()
        if not name:
            raise ValueError("Lightmap UV layer name is empty")
        targets = [o for o in _targets(context, self.all_objects) if name not in o.data.uv_layers]
        if not targets:
            return self._nothing_to_do(name)
        return unwrap_job(targets, name, settings, self.report)

    def _nothing_to_do(self, name):
        self.report({"INFO"}, f"Every target mesh already has a '{name}' UV layer")
        yield 1.0


CLASSES = (CLASSICBAKE_OT_lightmap_uv,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
