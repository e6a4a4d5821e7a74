"""Texture bake: every mesh's diffuse albedo, its textures mapped through its UVs, into lightmaps
(one atlas per object over its lightmap UVs), an 'Albedo' colour attribute and the camera's view."""

import bpy

from ..addon.jobs import forward, texture_bake_job
from ..addon.settings import lightmap_uv_settings, texture_settings
from .job import JobOperator, ScenePoll


class CLASSICBAKE_OT_texture(ScenePoll, JobOperator, bpy.types.Operator):
    """Bake each mesh's textured albedo into a lightmap atlas and an 'Albedo' colour attribute"""

    bl_idname = "classic_bake.texture"
    bl_label = "Bake Textures"
    bl_options = {"REGISTER", "UNDO"}
    job_label = "Texture mapping"
    needs = ("mesh",)

    def start(self, context):
        props = context.scene.classic_bake
        return self._job(context, texture_settings(props), props.lightmap_uv_name,
                         lightmap_uv_settings(props))

    def _job(self, context, settings, uv_name, uv_settings):
        summary = yield from forward(texture_bake_job(context, settings, uv_name, uv_settings))
        self.report({"INFO"}, f"Textures baked on {len(summary['images'])} objects "
                              f"({summary['stats']['cells']} look-ups), colour attribute 'Albedo' "
                              f"on {len(summary['attributes'])}")


CLASSES = (CLASSICBAKE_OT_texture,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
