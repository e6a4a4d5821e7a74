"""`envmap`: cube maps rendered from the centre of each mirror, and the camera's view with the
mirrors shaded from their maps (render.exr + render.png, cube/OBJECT.exr face strips)."""

from __future__ import annotations

from ..cli import Command, RunContext, command
from ..outputs import UsageError


def add_arguments(parser) -> None:
    parser.add_argument("--face-size", type=int, default=0, metavar="TEXELS",
                        help="texels per cube face side (default 0: from each object's size on "
                             "screen)")
    parser.add_argument("--face-samples", type=int, default=1, metavar="N",
                        help="N x N rays per face texel, averaged (default 1)")
    parser.add_argument("--objects", nargs="+", default=[], metavar="NAME",
                        help="objects to map (default: every mirror, i.e. smooth metal)")
    parser.add_argument("--parallax-steps", type=int, default=None, metavar="K",
                        help="refinements of the search along each reflected ray for the surface "
                             "it meets (default 4; 0: the lecture's look-up along r alone)")
    parser.add_argument("--face-depth", type=int, default=-1,
                        help="ray-tree depth of the face renders (default -1: from the scene)")
    parser.add_argument("--adaptive", type=int, default=4, metavar="N",
                        help="N x N camera samples again in pixels at edges (default 4, 0: off)")


def settings_from(scene, args):
    from ...kernels.envmap.envmap import EnvMapSettings
    from ...kernels.trace.settings import auto_settings

    try:
        steps = {} if args.parallax_steps is None else {"parallax_steps": args.parallax_steps}
        settings = EnvMapSettings(face_size=args.face_size, face_supersample=args.face_samples,
                                  objects=tuple(args.objects), face_depth=args.face_depth, **steps)
        return settings, auto_settings(scene, adaptive=args.adaptive)
    except ValueError as exc:
        raise UsageError(f"envmap: {exc}") from exc


def run(ctx: RunContext) -> None:
    from dataclasses import asdict

    from ...addon.bridge import SnapshotRequest, snapshot
    from ...kernels.envmap.envmap import render_steps, strip_image
    from ...kernels.geometry.bvh import BVH
    from ...kernels.measure.exr import write_exr
    from ...kernels.progress import drain
    from ..images import write_preview_png
    from ..outputs import safe_name

    with ctx.phase("snapshot"):
        scene = snapshot(request=SnapshotRequest(lightmap_uv=None), resolution=ctx.resolution)
    if scene.camera is None:
        raise UsageError("the scene has no camera to render from")
    settings, tracer = settings_from(scene, ctx.args)
    with ctx.phase("bvh"):
        bvh = BVH.build(scene.triangles)
    with ctx.phase("envmap"):
        try:
            result = drain(render_steps(scene, settings, tracer, bvh=bvh, resolution=ctx.resolution))
        except ValueError as exc:
            raise UsageError(str(exc)) from exc
    ctx.write_render(result.image)
    write_preview_png(ctx.output("render.png"), result.image)
    maps = {}
    for env in result.maps:
        name = scene.objects[env.object_index].source_name
        write_exr(ctx.output(f"cube/{safe_name(name)}.exr"), strip_image(env))
        write_preview_png(ctx.output(f"cube/{safe_name(name)}.png"), strip_image(env))
        maps[name] = {"face_size": env.size, "centre": [float(c) for c in env.centre]}
    width, height = result.image.shape[1], result.image.shape[0]
    ctx.record.settings = {**asdict(settings), "tracer": asdict(tracer)}
    ctx.record.sizes = {"width": width, "height": height, "triangles": scene.triangle_count,
                        "maps": maps, "face_rays": result.face_rays}
    # Not "seconds": metrics.json keeps that key for the phases and the total.
    ctx.record.extra["stage_seconds"] = result.seconds
    ctx.record.extra["stats"] = result.trace.stats.as_dict()
    listed = ", ".join(f"{n} ({m['face_size']} texels per face)" for n, m in maps.items())
    ctx.say(f"cube maps of {listed}: {result.face_rays} face rays in {result.seconds['capture']:.2f} s; "
            f"camera view {width}x{height} in {result.seconds['render']:.2f} s")


command(Command(name="envmap", help="environment (cube) mapping of the scene's mirrors",
                run=run, add_arguments=add_arguments, is_technique=True))
