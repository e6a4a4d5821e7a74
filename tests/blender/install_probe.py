"""Run by test_install.py in a fresh Blender process whose user resources are an empty folder:
install the extension zip, enable, disable, re-enable, and print what was registered as JSON."""

import importlib
import json
import pkgutil
import sys

import bpy

MODULE = "bl_ext.user_default.classic_bake"


def expected_classes():
    """Every class named in a `CLASSES` tuple of the installed package."""
    package = importlib.import_module(MODULE)
    names = []
    for info in pkgutil.walk_packages(package.__path__, MODULE + "."):
        if ".kernels" in info.name or ".pipeline" in info.name or info.name.endswith("__main__"):
            continue  # no Blender classes there (and kernels must import without bpy)
        module = importlib.import_module(info.name)
        names += [cls for cls in getattr(module, "CLASSES", ())]
    return names


def state(classes):
    return {
        "registered": sorted(c.__name__ for c in classes if c.is_registered),
        "leaked_types": sorted(n for n in dir(bpy.types) if n.startswith("CLASSICBAKE")),
        "scene_property": hasattr(bpy.types.Scene, "classic_bake"),
        "operators": sorted(dir(bpy.ops.classic_bake)),
        "enabled": MODULE in bpy.context.preferences.addons,
    }


report = {"before": sorted(n for n in dir(bpy.types) if n.startswith("CLASSICBAKE"))}
result = bpy.ops.extensions.package_install_files(
    filepath=sys.argv[-1], repo="user_default", enable_on_install=True)
report["install"] = sorted(result)
classes = expected_classes()
report["expected"] = sorted(c.__name__ for c in classes)
report["enabled"] = state(classes)
import OpenEXR  # noqa: E402, F401
import xatlas  # noqa: E402  (the bundled wheel must import)

report["wheel_paths"] = [xatlas.__file__]
bpy.ops.preferences.addon_disable(module=MODULE)
report["disabled"] = state(classes)
bpy.ops.preferences.addon_enable(module=MODULE)
report["reenabled"] = state(classes)
print("PROBE" + json.dumps(report))
