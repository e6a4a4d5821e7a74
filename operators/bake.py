"""One operator per technique record (jobs/techniques.py): it reads the technique's options from
`scene.classic_bake`, runs the record's job on both paths (operators/job.py) and reports its line.

Every technique's job writes Blender data (at least an image), so every operator is undoable: one
finished bake is one undo step. An operator that wrote data without UNDO would leave that data out
of the undo history, and the next Ctrl+Z would take it away together with the step before.
"""

from __future__ import annotations

import importlib

import bpy
from bpy.props import BoolProperty

from ..jobs.record import Technique
from ..jobs.techniques import TECHNIQUES
from .job import JobOperator, ScenePoll


def written_attribute(technique: Technique) -> str:
    """The colour attribute a technique's job writes (its job module's `ATTRIBUTE`), or ""."""
    return getattr(importlib.import_module(technique.start.__module__), "ATTRIBUTE", "")


def operator_class(technique: Technique) -> type:
    """The `bpy.types.Operator` subclass of a technique (bl_idname from its record)."""
    spec = technique.operator

    def start(self, context):
        values = technique.values_from_props(context.scene.classic_bake)
        if technique.name == "lightmap-uv":  # unwraps the selection unless told otherwise
            return technique.start(context, values, all_objects=self.all_objects)
        return technique.start(context, values)

    namespace = {
        "__doc__": technique.help[0].upper() + technique.help[1:],
        "bl_idname": spec.idname, "bl_label": spec.label,
        "bl_options": {"REGISTER", "UNDO"},
        "job_label": technique.label, "needs": spec.needs, "start": start,
        "attribute": written_attribute(technique),
    }
    if technique.name == "lightmap-uv":
        namespace["__annotations__"] = {"all_objects": BoolProperty(
            name="All Objects", description="Unwrap every mesh in the scene, not only the selection",
            default=False)}
    suffix = spec.idname.split(".")[1]
    return type(f"CLASSICBAKE_OT_{suffix}", (ScenePoll, JobOperator, bpy.types.Operator), namespace)


CLASSES = tuple(operator_class(t) for t in TECHNIQUES)


# Registered in order, unregistered in reverse.
register, unregister = bpy.utils.register_classes_factory(CLASSES)
