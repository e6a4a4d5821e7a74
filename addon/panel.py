"""The "Classic Bake" tab of the 3D viewport's sidebar. Operators are named by their bl_idname
string, so this module never imports `operators` (dependency direction: operators -> addon)."""

import bpy


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


class CLASSICBAKE_PT_lightmap_uv(_TechniquePanel, bpy.types.Panel):
    bl_label = "Lightmap UVs"

    def draw(self, context):
        layout = self.layout
        props = context.scene.classic_bake
        layout.use_property_split = True
        layout.prop(props, "lightmap_uv_name")
        layout.prop(props, "lightmap_resolution")
        layout.prop(props, "lightmap_padding")
        layout.operator("classic_bake.lightmap_uv", icon="UV")


class CLASSICBAKE_PT_texture(_TechniquePanel, bpy.types.Panel):
    bl_label = "Texture Mapping"

    def draw(self, context):
        layout = self.layout
        props = context.scene.classic_bake
        layout.use_property_split = True
        layout.prop(props, "texture_samples")
        layout.operator("classic_bake.texture", icon="TEXTURE")


class CLASSICBAKE_PT_trace(_TechniquePanel, bpy.types.Panel):
    bl_label = "Ray Tracing"

    def draw(self, context):
        layout = self.layout
        props = context.scene.classic_bake
        layout.use_property_split = True
        layout.prop(props, "trace_depth")
        layout.prop(props, "trace_supersample")
        layout.prop(props, "trace_adaptive")
        layout.operator("classic_bake.trace", icon="RENDER_STILL")


class CLASSICBAKE_PT_envmap(_TechniquePanel, bpy.types.Panel):
    bl_label = "Environment Mapping"

    def draw(self, context):
        layout = self.layout
        props = context.scene.classic_bake
        layout.use_property_split = True
        layout.prop(props, "envmap_face_size")
        layout.prop(props, "envmap_face_samples")
        layout.prop(props, "envmap_parallax_steps")
        layout.prop(props, "envmap_selected_only")
        layout.operator("classic_bake.envmap", icon="MAT_SPHERE_SKY")


class CLASSICBAKE_PT_bump(_TechniquePanel, bpy.types.Panel):
    bl_label = "Bump Mapping"

    def draw(self, context):
        layout = self.layout
        props = context.scene.classic_bake
        layout.use_property_split = True
        layout.prop(props, "bump_shading")
        layout.operator("classic_bake.shading", icon="MOD_NORMALEDIT")


class CLASSICBAKE_PT_shadowmap(_TechniquePanel, bpy.types.Panel):
    bl_label = "Shadow Mapping"

    def draw(self, context):
        layout = self.layout
        props = context.scene.classic_bake
        layout.use_property_split = True
        layout.prop(props, "shadow_map_size")
        layout.prop(props, "shadow_eps_auto")
        row = layout.row()
        row.enabled = not props.shadow_eps_auto
        row.prop(props, "shadow_eps")
        layout.prop(props, "shadow_pcf")
        layout.operator("classic_bake.shadowmap", icon="LIGHT_SUN")


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


class CLASSICBAKE_PT_radiosity(_TechniquePanel, bpy.types.Panel):
    bl_label = "Radiosity"

    def draw(self, context):
        layout = self.layout
        props = context.scene.classic_bake
        layout.use_property_split = True
        layout.prop(props, "radiosity_method")
        layout.prop(props, "radiosity_solver")
        layout.prop(props, "radiosity_patches")
        layout.prop(props, "radiosity_refine")
        layout.prop(props, "radiosity_shadow_splits")
        layout.prop(props, "radiosity_final_gather")
        row = layout.row()
        row.enabled = props.radiosity_final_gather
        row.prop(props, "radiosity_gather_rays")
        layout.prop(props, "radiosity_world_rays")
        layout.prop(props, "radiosity_wire")
        layout.operator("classic_bake.radiosity", icon="LIGHT_AREA")


CLASSES = (CLASSICBAKE_PT_main, CLASSICBAKE_PT_lightmap_uv, CLASSICBAKE_PT_texture,
           CLASSICBAKE_PT_trace,
           CLASSICBAKE_PT_envmap, CLASSICBAKE_PT_bump, CLASSICBAKE_PT_shadowmap,
           CLASSICBAKE_PT_radiosity, CLASSICBAKE_PT_compare)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
