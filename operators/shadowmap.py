"""Shadow-map bake: masks into lightmaps and a colour attribute, and the camera's direct light."""

import bpy

from ..addon.jobs import forward, shadow_bake_job
from ..addon.settings import direct_light_settings, lightmap_uv_settings
from .job import JobOperator, ScenePoll


class CLASSICBAKE_OT_shadowmap(ScenePoll, JobOperator, bpy.types.Operator):
    """Bake shadow-map shadows of every light into lightmaps and a 'Shadow' colour attribute"""

    bl_idname = "classic_bake.shadowmap"
    bl_label = "Bake Shadow Maps"
    bl_options = {"REGISTER", "UNDO"}
    job_label = "Shadow maps"
    needs = ("light", "mesh")

    def start(self, context):
        props = context.scene.classic_bake
        return self._job(context, direct_light_settings(props), props.lightmap_uv_name,
                         lightmap_uv_settings(props))

    def _job(self, context, settings, uv_name, uv_settings):
        summary = yield from forward(shadow_bake_job(context, settings, uv_name, uv_settings))
        self.report({"INFO"}, f"Shadow masks on {len(summary['images'])} objects, colour "
                              f"attribute 'Shadow' on {len(summary['attributes'])}")


CLASSES = (CLASSICBAKE_OT_shadowmap,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
