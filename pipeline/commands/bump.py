"""`bump`: the camera's view shaded flat, Gouraud, Phong or with bump and normal maps (the
lecture's comparison), traced with shadows (render.exr + render.png; modes/MODE.exr with
--all-modes)."""

from __future__ import annotations

from ..cli import Command, RunContext, command
from ..outputs import UsageError


def add_arguments(parser) -> None:
    from ...kernels.shading.bump import SHADING_MODES

    parser.add_argument("--shading", choices=SHADING_MODES, default="bump",
                        help="normals for shading: flat, gouraud (light at the vertices), phong "
                             "(interpolated normals) or bump (perturbed by the materials' height "
                             "and normal maps; the default)")
    parser.add_argument("--all-modes", action="store_true",
                        help="also render every shading mode into modes/MODE.exr and .png")
    parser.add_argument("--adaptive", type=int, default=4, metavar="N",
                        help="N x N samples again in pixels at edges (default 4, 0: off)")


def run(ctx: RunContext) -> None:
    import time
    from dataclasses import asdict

    from ...addon.bridge import SnapshotRequest, snapshot
    from ...kernels.geometry.bvh import BVH
    from ...kernels.measure.exr import write_exr
    from ...kernels.shading.bump import SHADING_MODES, has_bump
    from ...kernels.trace.settings import auto_settings
    from ...kernels.trace.tracer import trace
    from ..images import write_preview_png

    with ctx.phase("snapshot"):
        scene = snapshot(request=SnapshotRequest(lightmap_uv=None), resolution=ctx.resolution)
    if scene.camera is None:
        raise UsageError("the scene has no camera to render from")
    bumped = [m.name for m in scene.materials if has_bump(m)]
    with ctx.phase("bvh"):
        bvh = BVH.build(scene.triangles)
    modes = SHADING_MODES if ctx.args.all_modes else (ctx.args.shading,)
    seconds, image = {}, None
    for mode in modes:
        settings = auto_settings(scene, shading=mode, adaptive=ctx.args.adaptive)
        start = time.perf_counter()
        with ctx.phase(f"render_{mode}"):
            result = trace(scene, settings, bvh=bvh, resolution=ctx.resolution)
        seconds[mode] = time.perf_counter() - start
        if ctx.args.all_modes:
            write_exr(ctx.output(f"modes/{mode}.exr"), result.image)
            write_preview_png(ctx.output(f"modes/{mode}.png"), result.image)
        if mode == ctx.args.shading:
            image, chosen = result.image, settings
    ctx.write_render(image)
    write_preview_png(ctx.output("render.png"), image)
    ctx.record.settings = asdict(chosen)
    ctx.record.sizes = {"width": image.shape[1], "height": image.shape[0],
                        "triangles": scene.triangle_count, "bumped_materials": bumped}
    ctx.record.extra["seconds_per_mode"] = seconds
    ctx.say(f"shaded {ctx.args.shading} ({', '.join(f'{m} {s:.2f} s' for m, s in seconds.items())}); "
            + (f"bump and normal maps on {', '.join(bumped)}" if bumped
               else "no material has a Bump or Normal Map node"))


command(Command(name="bump", help="flat, Gouraud, Phong and bump-mapped shading of the camera view",
                run=run, add_arguments=add_arguments, is_technique=True))
