"""Ray tracing: the lecture's backward (Whitted) tracer from the eye through pixel centres, with
shadow rays, mirrors and refraction to a depth chosen from the scene, into a float image."""

from __future__ import annotations

from dataclasses import asdict

import bpy

from ..addon.bridge import write_back
from ..addon.bridge.request import SnapshotRequest
from ..addon.bridge.snapshot import snapshot
from ..kernels.progress import Steps, scaled
from ..kernels.trace.settings import TracerSettings, auto_settings
from ..kernels.trace.tracer import trace_steps
from .record import JobSummary, OperatorSpec, Option, Technique
from .tiles import Tile, row_range

IMAGE_NAME = "Classic Bake Trace"


def traced(scene, settings: TracerSettings, name: str, resolution=None) -> Steps[tuple]:
    """Trace the camera's view, then write it into the float image `name`: (image, TraceResult).
    Closed before its end, it has changed nothing."""
    result = yield from scaled(trace_steps(scene, settings, resolution=resolution))
    return write_back.write_image(name, result.image, image=bpy.data.images.get(name)), result


def trace_job(scene, settings: TracerSettings, resolution=None) -> Steps[JobSummary]:
    """Trace the camera's view of a snapshot into the image 'Classic Bake Trace'."""
    image, result = yield from traced(scene, settings, IMAGE_NAME, resolution)
    s = result.stats
    height, width = result.image.shape[:2]
    return JobSummary(
        message=f"traced {width}x{height} into '{image.name}': {s.camera_rays} camera, "
                f"{s.secondary_rays} secondary, {s.shadow_rays} shadow rays; {s.pruned_branches} "
                f"branches pruned by weight, {s.edge_pixels} edge pixels supersampled",
        scene=scene, render=result.image, images={IMAGE_NAME: image}, result=result,
        settings=asdict(settings),
        sizes={"width": width, "height": height, "triangles": scene.triangle_count,
               "lights": len(scene.lights)},
        extra={"stats": s.as_dict()})


def trace_tile_job(scene, settings: TracerSettings, tile: Tile, resolution=None
                   ) -> Steps[JobSummary]:
    """Tile K of N of `trace_job` (jobs/tiles.py): its share of the camera view's rows
    (`row_range`), each pixel as the whole view traces it; `render` holds those rows. Nothing is
    written into Blender."""
    width, height = resolution or scene.camera.resolution
    rows = row_range(height, tile)
    result = yield from scaled(trace_steps(scene, settings, resolution=(width, height), rows=rows))
    s = result.stats
    return JobSummary(
        message=f"traced rows {rows[0]}..{rows[1] - 1} of {width}x{height} (tile {tile.index} of "
                f"{tile.count}): {s.camera_rays} camera, {s.secondary_rays} secondary, "
                f"{s.shadow_rays} shadow rays",
        scene=scene, render=result.image, result=result, settings=asdict(settings),
        sizes={"width": width, "height": height, "triangles": scene.triangle_count,
               "lights": len(scene.lights)},
        extra={"stats": s.as_dict(), "tile_rows": list(rows)})


def camera_snapshot(context, resolution=None):
    """The scene as the camera techniques read it (no lightmap UVs), or ValueError without a camera."""
    scene = snapshot(context, SnapshotRequest(lightmap_uv=None), resolution=resolution)
    if scene.camera is None:
        raise ValueError("the scene has no camera to render from")
    return scene


TRACE_OPTIONS = (
    Option("depth", TracerSettings, "Depth", "Mirror and glass bounces, counted as Cycles' Max "
           "Bounces; -1 chooses them from the scene's mirrors and glass", field="max_depth",
           auto=-1, minimum=-1, maximum=64),
    Option("supersample", TracerSettings, "Samples", "N x N samples in every pixel (1: pixel "
           "centres)", minimum=1, maximum=16),
    Option("adaptive", TracerSettings, "Edge Samples", "N x N samples again in pixels at edges "
           "(0: off)", minimum=0, maximum=16),
    Option("min_weight", TracerSettings, "Minimum Weight", "Branches whose weight falls below "
           "this are not traced", minimum=0.0, maximum=1.0),
    Option("offset_scale", TracerSettings, "Ray Offset", "Secondary rays start this fraction of "
           "the scene's size off the surface", minimum=0.0, maximum=1e-2),
)


def tracer_settings(values: dict, scene, **fixed) -> TracerSettings:
    """TracerSettings from trace option values (depth -1: from the scene's materials)."""
    overrides = {"supersample": int(values["supersample"]), "adaptive": int(values["adaptive"]),
                 "min_weight": float(values["min_weight"]),
                 "offset_scale": float(values["offset_scale"]), **fixed}
    if int(values["depth"]) >= 0:
        overrides["max_depth"] = int(values["depth"])
    return auto_settings(scene, **overrides)


def start(context, values: dict, resolution=None) -> Steps[JobSummary]:
    scene = camera_snapshot(context, resolution)
    if values.get("tile") is not None:
        return (yield from trace_tile_job(scene, tracer_settings(values, scene), values["tile"],
                                          resolution))
    return (yield from trace_job(scene, tracer_settings(values, scene), resolution))


def cycles_model(recorded: dict):
    from ..addon.cycles import models

    return models.whitted(int(recorded.get("max_depth", 8)))


RECORD = Technique(
    name="trace", label="Ray Tracing", help="Whitted ray tracing of the scene camera's view",
    options=TRACE_OPTIONS, settings=tracer_settings, start=start, cycles_model=cycles_model,
    ladder=(("--adaptive", "0"), ("--adaptive", "2"), ("--adaptive", "4"),
            ("--supersample", "2", "--adaptive", "4")), tiles="rows",
    operator=OperatorSpec("classic_bake.trace", "Trace Camera View", "RENDER_STILL",
                          needs=("camera",), undo=False),
)
