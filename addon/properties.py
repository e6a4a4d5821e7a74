"""Per-scene settings (`scene.classic_bake`), edited in the sidebar and read by `settings.py`."""

import bpy
from bpy.props import IntProperty, PointerProperty, StringProperty


class CLASSICBAKE_PG_settings(bpy.types.PropertyGroup):
    lightmap_resolution: IntProperty(
        name="Lightmap Size", description="Texels along each side of a lightmap",
        default=512, min=16, max=16384, soft_max=4096)
    lightmap_padding: IntProperty(
        name="Padding", description="Texels kept free between UV charts", default=2, min=0, max=64)
    lightmap_uv_name: StringProperty(
        name="UV Layer", description="Name of the lightmap UV layer (created where missing, "
        "never overwritten)", default="Lightmap")


    trace_depth: IntProperty(
        name="Depth", description="Ray-tree depth; -1 chooses it from the scene's mirrors and glass",
        default=-1, min=-1, max=64)
    trace_supersample: IntProperty(
        name="Samples", description="N x N samples in every pixel (1: pixel centres)",
        default=1, min=1, max=16)
    trace_adaptive: IntProperty(
        name="Edge Samples", description="N x N samples again in pixels at edges (0: off)",
        default=4, min=0, max=16)


CLASSES = (CLASSICBAKE_PG_settings,)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.classic_bake = PointerProperty(type=CLASSICBAKE_PG_settings)


def unregister() -> None:
    del bpy.types.Scene.classic_bake
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
