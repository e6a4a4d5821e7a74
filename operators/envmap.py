"""Environment (cube) mapping of the scene's mirrors, and the camera's view shaded with the maps."""

import bpy

from ..addon import bridge
from ..addon.settings import envmap_settings, tracer_settings
from .job import JobOperator, ScenePoll

IMAGE_NAME = "Classic Bake Environment"
CUBE_PREFIX = "Classic Bake Cube "  # + object name: the six faces side by side


def envmap_job(scene, settings, tracer, report):
    """Capture the maps and render the view (yielding progress), then write the images: a cancel
    before the end changes nothing."""
    from ..kernels.envmap.envmap import render_steps, strip_image

    result = yield from render_steps(scene, settings, tracer)
    image = bridge.write_image(IMAGE_NAME, result.image, image=bpy.data.images.get(IMAGE_NAME))
    for env in result.maps:
        name = CUBE_PREFIX + scene.objects[env.object_index].source_name
        bridge.write_image(name, strip_image(env), image=bpy.data.images.get(name))
    sizes = ", ".join(f"{scene.objects[m.object_index].source_name} {m.size}" for m in result.maps)
    report({"INFO"}, f"Rendered '{image.name}' with cube maps of {sizes} texels per face "
                     f"({result.face_rays} face rays)")


class CLASSICBAKE_OT_envmap(ScenePoll, JobOperator, bpy.types.Operator):
    """Render a cube map from the centre of every mirror (the object hidden), then the camera's view
    with the mirrors reading their maps along the reflected ray"""

    bl_idname = "classic_bake.envmap"
    bl_label = "Environment Map Mirrors"
    bl_options = {"REGISTER"}
    job_label = "Environment mapping"
    needs = ("camera", "mesh")

    def start(self, context):
        scene = bridge.snapshot(context)
        if scene.camera is None:
            raise ValueError("The scene needs a camera")
        props = context.scene.classic_bake
        selected = [o.name for o in context.selected_objects if o.type == "MESH"]
        return envmap_job(scene, envmap_settings(props, selected),
                          tracer_settings(props, scene), self.report)


CLASSES = (CLASSICBAKE_OT_envmap,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
