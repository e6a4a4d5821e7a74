"""Lightmap UVs from xatlas: each mesh unwrapped and packed into a new UV layer at one texel
density, never overwriting a layer that exists."""

from __future__ import annotations

from ..addon.bridge import mesh as bridge_mesh
from ..kernels.progress import Steps
from .lightmaps import LIGHTMAP_OPTIONS, lightmap_settings
from .record import JobSummary, OperatorSpec, Technique


def unwrap_targets(objects):
    """The renderable meshes among `objects`, one per mesh datablock (objects sharing a mesh share
    its UV layers)."""
    seen, out = set(), []
    for obj in objects:
        if obj.type == "MESH" and not obj.hide_render and obj.data.name_full not in seen:
            seen.add(obj.data.name_full)
            out.append(obj)
    return out


def unwrap_job(targets, name: str, settings) -> Steps[JobSummary]:
    """Unwrap `targets` one per step, then write every UV layer at the end (closed before its end,
    it has changed nothing). Meshes that already have layer `name` keep it."""
    todo = [o for o in targets if name not in o.data.uv_layers]
    results = []
    for k, obj in enumerate(todo):
        loop_uv, summary = bridge_mesh.lightmap_loop_uv(obj, settings)
        results.append((obj, loop_uv, summary))
        yield (k + 1) / (len(todo) + 1)
    # --- write back: everything computed ---------------------------------------------------------
    report = {o.name: {"created": False} for o in targets if o not in todo}
    split = 0
    for obj, loop_uv, summary in results:
        bridge_mesh.write_uv_layer(obj.data, name, loop_uv)
        report[obj.name] = {"created": True, **summary}
        split += summary["split_polygons"]
    if results:
        message = f"lightmap UVs '{name}' on {len(results)} meshes"
        if split:
            message += f" ({split} polygons split across charts)"
    else:
        message = f"every target mesh already has a '{name}' UV layer"
    return JobSummary(message=message, files={"lightmap_uv.json": report},
                      sizes={"objects": len(report), "created": len(results)},
                      extra={"split_polygons": split})


def settings(values: dict, scene=None):
    return lightmap_settings(values)


def start(context, values: dict, resolution=None, all_objects: bool = True) -> Steps[JobSummary]:
    name, uv_settings = lightmap_settings(values)
    objects = context.scene.objects if all_objects else context.selected_objects
    summary = yield from unwrap_job(unwrap_targets(objects), name, uv_settings)
    summary.settings = {"lightmap_size": uv_settings.resolution, "padding": uv_settings.padding,
                        "uv_name": name}
    return summary


RECORD = Technique(
    name="lightmap-uv", label="Lightmap UVs",
    help="create xatlas lightmap UVs on meshes that lack them",
    options=(), settings=settings, start=start, shared=LIGHTMAP_OPTIONS, renders=False,
    operator=OperatorSpec("classic_bake.lightmap_uv", "Create Lightmap UVs", "UV", needs=("mesh",)),
)
