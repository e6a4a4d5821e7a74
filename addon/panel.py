"""The "Classic Bake" tab of the 3D viewport's sidebar: a section per technique record, drawn from
its options, with its button. Operators are named by their bl_idname string, so this module never
imports `operators` (dependency direction: operators -> addon)."""

import bpy

from ..jobs.techniques import TECHNIQUES


class _SidebarPanel:
    """Where every Classic Bake panel lives: the 3D viewport's sidebar, tab "Classic Bake"."""

    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Classic Bake"


class _TechniquePanel(_SidebarPanel):
    """A section under the main panel."""

    bl_parent_id = "CLASSICBAKE_PT_main"


class CLASSICBAKE_PT_main(_SidebarPanel, bpy.types.Panel):
    bl_label = "Classic Bake"

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        meshes = sum(1 for o in scene.objects if o.type == "MESH")
        lights = sum(1 for o in scene.objects if o.type == "LIGHT")
        layout.label(text=f"{meshes} meshes, {lights} lights", icon="SCENE_DATA")


def technique_panel(technique) -> type:
    """The sidebar section of one technique: its own options, then its button. The shared
    lightmap options are drawn once, in the Lightmap UVs section."""
    names = [o.prop_name(technique.prefix) for o in
             (technique.all_options() if technique.name == "lightmap-uv" else technique.options)]

    def draw(self, context):
        layout = self.layout
        props = context.scene.classic_bake
        layout.use_property_split = True
        for name in names:
            layout.prop(props, name)
        layout.operator(technique.operator.idname, icon=technique.operator.icon)

    return type(f"CLASSICBAKE_PT_{technique.prefix}", (_TechniquePanel, bpy.types.Panel),
                {"bl_label": technique.label, "draw": draw})


class CLASSICBAKE_PT_compare(_TechniquePanel, bpy.types.Panel):
    bl_label = "Compare with Cycles"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        props = context.scene.classic_bake
        layout.use_property_split = True
        layout.prop(props, "compare_technique")
        layout.prop(props, "compare_samples")
        layout.operator("classic_bake.compare", icon="IMAGE_REFERENCE")
        if props.compare_rel_mse >= 0.0:
            box = layout.box()
            box.label(text=f"Relative MSE {props.compare_rel_mse:.3g}")
            if props.compare_flip >= 0.0:
                box.label(text=f"HDR-FLIP {props.compare_flip:.3f}")
            box.label(text=f"Kernel {props.compare_kernel_seconds:.2f} s, "
                           f"Cycles {props.compare_cycles_seconds:.2f} s")
            box.label(text="Error image: 'Classic Bake Error'", icon="IMAGE_DATA")


CLASSES = (CLASSICBAKE_PT_main, *(technique_panel(t) for t in TECHNIQUES), CLASSICBAKE_PT_compare)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
