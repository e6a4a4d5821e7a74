"""Object Mode before a job reads or writes meshes.

In Edit Mode a mesh's data is the edit mesh's, written back into the mesh on leaving it (and on
saving): whatever a bake writes into the mesh meanwhile (lightmap UVs, colour attributes) would
be overwritten. Blender leaves Edit Mode the same way for its own mesh-wide operations.
"""

from __future__ import annotations


def leave_edit_mode(context) -> list[str]:
    """Object Mode for `context` when it is in another mode (the edit mesh written into the
    mesh, as Blender does on leaving): [a line saying so], or [] when it was already there."""
    import bpy

    if context.mode == "OBJECT" or context.view_layer.objects.active is None:
        return []
    mode = context.mode
    bpy.ops.object.mode_set(mode="OBJECT")
    return [f"left {mode.replace('_', ' ').title()} mode for Object Mode"]
