"""Radiosity and ray tracing together: pass 1 solves the scene's radiosity (view-independent),
pass 2 traces the camera's view with mirrors and glass and reads every diffuse hit's light from
the solution (kernels/hybrid/two_pass.py), into the float image 'Classic Bake Hybrid'."""

from __future__ import annotations

from dataclasses import asdict

import bpy

from ..addon.bridge import write_back
from ..addon.bridge.request import SnapshotRequest
from ..addon.bridge.snapshot import snapshot
from ..kernels.hybrid.two_pass import HybridSettings, hybrid_steps, pass_one_settings
from ..kernels.progress import Steps, scaled
from ..kernels.radiosity.settings import RadiositySettings
from ..kernels.trace.settings import TracerSettings, auto_settings
from .record import JobSummary, OperatorSpec, Option, Technique

IMAGE_NAME = "Classic Bake Hybrid"

OPTIONS = (
    Option("patches", RadiositySettings, "Patches", "Pass 1: patches aimed at before refinement",
           field="patch_budget", minimum=1, soft_max=5000),
    Option("final_gather", RadiositySettings, "Final Gather", "Pass 1 read out with exact direct "
           "light and its shadows at every point the tracer meets (off: patches interpolated)"),
    Option("gather_rays", RadiositySettings, "Gather Rays", "Final gather: shadow rays per point "
           "to the emissive surfaces", minimum=1, soft_max=256),
    Option("depth", TracerSettings, "Depth", "Pass 2: mirror and glass bounces, counted as "
           "Cycles' Max Bounces; -1 chooses them from the scene", field="max_depth", auto=-1,
           minimum=-1, maximum=64),
    Option("supersample", TracerSettings, "Samples", "Pass 2: N x N samples in every pixel",
           minimum=1, maximum=16),
    Option("adaptive", TracerSettings, "Edge Samples", "Pass 2: N x N samples again in pixels at "
           "edges (0: off)", minimum=0, maximum=16),
)


def settings(values: dict, scene) -> HybridSettings:
    """HybridSettings from option values (depth -1: from the scene's mirrors and glass)."""
    solve = pass_one_settings(patch_budget=int(values["patches"]),
                              final_gather=bool(values["final_gather"]),
                              gather_rays=int(values["gather_rays"]))
    overrides = {"supersample": int(values["supersample"]), "adaptive": int(values["adaptive"])}
    if int(values["depth"]) >= 0:
        overrides["max_depth"] = int(values["depth"])
    tracer = auto_settings(scene, **overrides) if scene is not None else TracerSettings(
        **overrides)
    return HybridSettings(radiosity=solve, tracer=tracer)


def hybrid_job(scene, hybrid: HybridSettings, resolution=None) -> Steps[JobSummary]:
    """Both passes over a snapshot, then the view written into 'Classic Bake Hybrid'."""
    result = yield from scaled(hybrid_steps(scene, hybrid, resolution))
    image = write_back.write_image(IMAGE_NAME, result.image, image=bpy.data.images.get(IMAGE_NAME))
    height, width = result.image.shape[:2]
    stats = result.radiosity.stats
    return JobSummary(
        message=f"two passes into '{image.name}' ({width}x{height}): radiosity of "
                f"{stats['patches']} patches in {result.seconds['radiosity']:.2f} s, then "
                f"{result.trace_stats.camera_rays} camera and {result.trace_stats.secondary_rays} "
                f"mirror and glass rays in {result.seconds['trace']:.2f} s",
        scene=scene, render=result.image, images={IMAGE_NAME: image}, result=result,
        notes=list(result.radiosity.notes),
        settings={"radiosity": asdict(hybrid.radiosity), "tracer": asdict(hybrid.tracer)},
        sizes={"width": width, "height": height, "triangles": scene.triangle_count,
               "patches": stats["patches"]},
        extra={"seconds_per_pass": result.seconds, "trace_stats": result.trace_stats.as_dict()})


def start(context, values: dict, resolution=None) -> Steps[JobSummary]:
    scene = snapshot(context, SnapshotRequest(lightmap_uv=None, textures=True),
                     resolution=resolution)
    if scene.camera is None:
        raise ValueError("the scene has no camera to render from")
    return (yield from hybrid_job(scene, settings(values, scene), resolution))


def cycles_model(recorded: dict):
    from ..addon.cycles import models

    depth = int(recorded.get("tracer", {}).get("max_depth", 8))
    # Pass 1 lights the solve with the world unless its rays are off, as the radiosity bake does.
    world = int(recorded.get("radiosity", {}).get("world_rays", 0)) > 0
    return models.global_illumination(max(depth, 8), world_lighting=world)


RECORD = Technique(
    name="hybrid", label="Radiosity + Ray Tracing",
    help="the two-pass renderer: radiosity for diffuse light, then Whitted rays from the eye",
    options=OPTIONS, settings=settings, start=start, cycles_model=cycles_model,
    ladder=(("--patches", "100", "--adaptive", "0"), ("--patches", "400", "--adaptive", "0"),
            ("--patches", "400"), ("--patches", "1200", "--supersample", "2")),
    operator=OperatorSpec("classic_bake.hybrid", "Render Two Passes", "SHADING_RENDERED",
                          needs=("camera",), undo=False),
)
