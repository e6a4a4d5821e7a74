"""Bump mapping: the camera's view shaded with the chosen normals (flat, Gouraud, Phong, bump)."""

import bpy

from ..addon import bridge
from ..addon.settings import shading_settings
from .job import JobOperator, ScenePoll
from .trace import traced_image

IMAGE_NAME = "Classic Bake Shading"


def shading_job(scene, settings, report):
    """Trace with the settings' shading mode (yielding progress), then write the image: a cancel
    before the end changes nothing."""
    from ..kernels.shading.bump import has_bump

    image, _ = yield from traced_image(scene, settings, IMAGE_NAME)
    bumped = [m.name for m in scene.materials if has_bump(m)]
    report({"INFO"}, f"Shaded '{image.name}' ({settings.shading}); bump and normal maps on "
                     f"{', '.join(bumped) if bumped else 'no material'}")


class CLASSICBAKE_OT_shading(ScenePoll, JobOperator, bpy.types.Operator):
    """Render the camera's view with flat, Gouraud, Phong or bump-mapped shading, to compare them"""

    bl_idname = "classic_bake.shading"
    bl_label = "Render Shading"
    bl_options = {"REGISTER"}
    job_label = "Shading"
    needs = ("camera",)

    def start(self, context):
        scene = bridge.snapshot(context)
        if scene.camera is None:
            raise ValueError("The scene needs a camera")
        return shading_job(scene, shading_settings(context.scene.classic_bake, scene), self.report)


CLASSES = (CLASSICBAKE_OT_shading,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
