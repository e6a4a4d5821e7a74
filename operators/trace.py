"""Whitted ray tracing of the scene camera into a float image."""

import bpy

from ..addon import bridge
from ..addon.settings import tracer_settings
from .job import JobOperator, ScenePoll

IMAGE_NAME = "Classic Bake Trace"


def traced_image(scene, settings, name: str):
    """Trace the camera's view (yielding progress), then write it into the float image `name`;
    returns (image, TraceResult). A cancel before the end changes nothing."""
    from ..kernels.trace.tracer import trace_steps

    result = yield from trace_steps(scene, settings)
    return bridge.write_image(name, result.image, image=bpy.data.images.get(name)), result


def trace_job(scene, settings, report):
    """Trace (yielding progress), then write the image: a cancel before the end changes nothing."""
    image, result = yield from traced_image(scene, settings, IMAGE_NAME)
    s = result.stats
    report({"INFO"}, f"Traced '{image.name}': {s.camera_rays + s.secondary_rays} rays, "
                     f"{s.shadow_rays} shadow rays, {s.pruned_branches} branches pruned")


class CLASSICBAKE_OT_trace(ScenePoll, JobOperator, bpy.types.Operator):
    """Ray trace the scene camera's view (Whitted: shadows, mirrors, glass) into a float image"""

    bl_idname = "classic_bake.trace"
    bl_label = "Trace Camera View"
    bl_options = {"REGISTER"}
    job_label = "Ray tracing"
    needs = ("camera",)

    def start(self, context):
        scene = bridge.snapshot(context)
        if scene.camera is None:
            raise ValueError("The scene needs a camera")
        return trace_job(scene, tracer_settings(context.scene.classic_bake, scene), self.report)


CLASSES = (CLASSICBAKE_OT_trace,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
