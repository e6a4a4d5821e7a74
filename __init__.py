"""Classic Bake: the classic mapping and global-shading techniques, baked with NumPy kernels.

The repository root is the Blender extension (id `classic_bake`). Importing this package does not
import Blender: `kernels/` is usable on its own, and `python -m classic_bake` imports `bpy` only
when a command needs it. Blender calls `register()`; dependency direction is
operators -> addon -> kernels, and this function is the one place that ties them together.
"""

_cli_handle = None


def register() -> None:
    import bpy

    from . import addon, operators
    from .pipeline import cli

    addon.register()
    operators.register()
    global _cli_handle
    # `blender -b -c classic_bake info scene.blend ...`: the same commands as `python -m`.
    _cli_handle = bpy.utils.register_cli_command("classic_bake", cli.blender_command)


def unregister() -> None:
    import bpy

    from . import addon, operators

    global _cli_handle
    if _cli_handle is not None:
        bpy.utils.unregister_cli_command(_cli_handle)
        _cli_handle = None
    operators.unregister()
    addon.unregister()
