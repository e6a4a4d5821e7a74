"""Radiosity bake: the diffuse global illumination of emitters and lights into lightmaps, a
'Radiosity' corner colour attribute and the camera's view."""

import bpy

from ..addon.jobs import forward, radiosity_bake_job
from ..addon.settings import lightmap_uv_settings, radiosity_settings
from .job import JobOperator, ScenePoll


class CLASSICBAKE_OT_radiosity(ScenePoll, JobOperator, bpy.types.Operator):
    """Solve radiosity and bake outgoing radiance into lightmaps and a 'Radiosity' colour attribute"""

    bl_idname = "classic_bake.radiosity"
    bl_label = "Bake Radiosity"
    bl_options = {"REGISTER", "UNDO"}
    job_label = "Radiosity"
    needs = ("mesh",)

    def start(self, context):
        props = context.scene.classic_bake
        return self._job(context, radiosity_settings(props), props.lightmap_uv_name,
                         lightmap_uv_settings(props), props.radiosity_wire)

    def _job(self, context, settings, uv_name, uv_settings, wire):
        summary = yield from forward(radiosity_bake_job(context, settings, uv_name, uv_settings, wire=wire))
        stats = summary["result"].stats
        self.report({"INFO"}, f"Radiosity: {stats['patches']} patches ({stats['solver']}), "
                              f"lightmaps on {len(summary['images'])} objects, colour attribute "
                              f"'Radiosity' on {len(summary['attributes'])}")


CLASSES = (CLASSICBAKE_OT_radiosity,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
