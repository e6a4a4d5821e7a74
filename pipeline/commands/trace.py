"""`trace`: Whitted ray tracing of the scene camera's view (render.exr + render.png)."""

from __future__ import annotations

from ..cli import Command, RunContext, command
from ..outputs import UsageError


def add_arguments(parser) -> None:
    parser.add_argument("--depth", type=int, default=None,
                        help="ray-tree depth (default: chosen from the scene's materials)")
    parser.add_argument("--supersample", type=int, default=1, metavar="N",
                        help="N x N samples in every pixel (default 1: pixel centres)")
    parser.add_argument("--adaptive", type=int, default=4, metavar="N",
                        help="N x N samples again in pixels at edges (default 4, 0: off)")
    parser.add_argument("--min-weight", type=float, default=None,
                        help="stop branches whose weight falls below this (default 1e-2)")
    parser.add_argument("--offset-scale", type=float, default=None,
                        help="ray offset as a fraction of the scene size (default 1e-5)")
    parser.add_argument("--target-error", type=float, default=None, metavar="REL_MSE",
                        help="pick the cheapest settings that reached this relative MSE on the "
                             "most similar scene `compare` measured (overrides the options above)")


def tracer_settings(scene, args):
    from ...kernels.trace.settings import auto_settings

    overrides = {"supersample": args.supersample, "adaptive": args.adaptive}
    if args.min_weight is not None:
        overrides["min_weight"] = args.min_weight
    if args.depth is not None:
        overrides["max_depth"] = args.depth
    if args.offset_scale is not None:
        overrides["offset_scale"] = args.offset_scale
    try:
        return auto_settings(scene, **overrides)
    except ValueError as exc:
        raise UsageError(str(exc)) from exc


def run(ctx: RunContext) -> None:
    from dataclasses import asdict

    from ...addon.bridge import SnapshotRequest, snapshot
    from ...kernels.geometry.bvh import BVH
    from ...kernels.progress import drain
    from ...kernels.trace.tracer import trace_steps
    from ..images import write_preview_png
    from ..quality import apply_target

    with ctx.phase("snapshot"):
        scene = snapshot(request=SnapshotRequest(lightmap_uv=None), resolution=ctx.resolution)
    if scene.camera is None:
        raise UsageError("the scene has no camera to trace from")
    apply_target(ctx, "trace", scene)
    settings = tracer_settings(scene, ctx.args)
    with ctx.phase("bvh"):
        bvh = BVH.build(scene.triangles)
    with ctx.phase("trace"):
        result = drain(trace_steps(scene, settings, bvh=bvh, resolution=ctx.resolution))
    ctx.write_render(result.image)
    write_preview_png(ctx.output("render.png"), result.image)
    width, height = result.image.shape[1], result.image.shape[0]
    ctx.record.settings = asdict(settings)
    ctx.record.sizes = {"width": width, "height": height, "triangles": scene.triangle_count,
                        "lights": len(scene.lights)}
    ctx.record.extra["stats"] = result.stats.as_dict()
    s = result.stats
    ctx.say(f"traced {width}x{height}: {s.camera_rays} camera, {s.secondary_rays} secondary, "
            f"{s.shadow_rays} shadow rays; {s.pruned_branches} branches pruned by weight, "
            f"{s.edge_pixels} edge pixels supersampled")


command(Command(name="trace", help="Whitted ray tracing of the scene camera's view", run=run,
                add_arguments=add_arguments, is_technique=True))
