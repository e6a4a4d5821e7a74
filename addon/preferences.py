"""Add-on preferences, keyed by the extension's package name."""

import bpy
from bpy.props import BoolProperty, FloatProperty, IntProperty, StringProperty

# "classic_bake" when run from a checkout, "bl_ext.<repo>.classic_bake" when installed.
ADDON_PACKAGE = __package__.rpartition(".")[0]


class CLASSICBAKE_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_PACKAGE

    tick_budget_ms: FloatProperty(
        name="Work per UI Tick", description="Milliseconds of baking between interface updates "
        "while a bake runs interactively (smaller: smoother interface, slower bake)",
        default=50.0, min=5.0, max=1000.0, subtype="NONE")
    save_images: BoolProperty(
        name="Save Images", description="After each bake, also write its images as OpenEXR files "
        "into the output folder (otherwise they live in the .blend until saved)", default=False)
    output_dir: StringProperty(
        name="Output Folder", description="Where baked images are saved ('//' is the .blend's "
        "folder; an unsaved file uses Blender's temporary folder)",
        default="//classic_bake", subtype="DIR_PATH", options={"PATH_SUPPORTS_BLEND_RELATIVE"})
    threads: IntProperty(
        name="Threads", description="Cores the bakes may use (0: every core of the machine); "
        "fewer keep the machine responsive for other work", default=0, min=0, max=1024)

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "tick_budget_ms")
        layout.prop(self, "save_images")
        row = layout.row()
        row.active = self.save_images
        row.prop(self, "output_dir")
        layout.prop(self, "threads")


def get(context=None):
    """These preferences, or None when the add-on is not enabled (e.g. in a bare script)."""
    context = context or bpy.context
    addon = context.preferences.addons.get(ADDON_PACKAGE)
    return addon.preferences if addon else None


CLASSES = (CLASSICBAKE_AP_preferences,)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
