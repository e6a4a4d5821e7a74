"""`shadowmap`: shadow-map masks baked into lightmaps and colour attributes, and the camera's view
of direct light with shadow-mapped shadows (render.exr)."""

from __future__ import annotations

from ..cli import Command, RunContext, command
from ..outputs import UsageError


def add_arguments(parser) -> None:
    parser.add_argument("--map-size", type=int, default=0, metavar="TEXELS",
                        help="shadow-map resolution (default 0: chosen per light from the receivers)")
    parser.add_argument("--eps", default="auto",
                        help="depth tolerance: 'auto' (from texel size and slope) or metres")
    parser.add_argument("--slope-bias", type=float, default=0.0, help="slope-scaled bias, texels")
    parser.add_argument("--normal-offset", type=float, default=0.0, help="normal offset, texels")
    parser.add_argument("--pcf", type=int, default=1, metavar="K", help="K x K PCF (odd, 1: off)")
    parser.add_argument("--lightmap-size", type=int, default=256, metavar="TEXELS",
                        help="lightmap resolution per object (default 256)")
    parser.add_argument("--padding", type=int, default=2, metavar="TEXELS", help="chart padding")
    parser.add_argument("--uv-name", default="Lightmap", help="lightmap UV layer (created if missing)")
    parser.add_argument("--target-error", type=float, default=None, metavar="REL_MSE",
                        help="pick the cheapest settings that reached this relative MSE on the "
                             "most similar scene `compare` measured")


def settings_from(args):
    from ...kernels.bake.lightmap_uv import LightmapUVSettings
    from ...kernels.shading.direct_light import DirectLightSettings
    from ...kernels.shadow.shadowmap import ShadowMapSettings

    try:
        if args.eps == "auto":
            eps_mode, eps = "auto", 0.0
        else:
            eps_mode, eps = "fixed", float(args.eps)
        shadow = ShadowMapSettings(resolution=args.map_size or 2048, eps_mode=eps_mode, eps=eps,
                                   slope_bias=args.slope_bias, normal_offset=args.normal_offset,
                                   pcf_size=args.pcf)
        uv = LightmapUVSettings(resolution=args.lightmap_size, padding=args.padding)
    except ValueError as exc:
        raise UsageError(f"shadowmap: {exc}") from exc
    return DirectLightSettings(shadow=shadow, auto_resolution=args.map_size == 0), uv


def run(ctx: RunContext) -> None:
    from dataclasses import asdict

    import bpy
    import numpy as np

    from ...addon import bridge
    from ...addon.jobs import run_to_end, shadow_bake_job
    from ..bake_outputs import write_bake_outputs
    from ..quality import apply_target

    if ctx.args.target_error is not None:
        apply_target(ctx, "shadowmap", bridge.snapshot(request=bridge.SnapshotRequest(
            textures=False, uv=False, world_render=False), resolution=ctx.resolution))
    settings, uv = settings_from(ctx.args)
    with ctx.phase("bake"):
        try:
            summary = run_to_end(shadow_bake_job(bpy.context, settings, ctx.args.uv_name, uv,
                                        resolution=ctx.resolution))
        except ValueError as exc:
            raise UsageError(str(exc)) from exc
    with ctx.phase("write"):
        write_bake_outputs(ctx, summary, "shadow")
    scene = summary["scene"]
    texels = {n: int(m.sum()) for n, (_, m) in summary["lightmaps"].items()}
    ctx.record.settings = {**asdict(settings.shadow), "auto_resolution": settings.auto_resolution,
                           "lightmap_size": uv.resolution, "padding": uv.padding,
                           "uv_name": ctx.args.uv_name}
    ctx.record.sizes = {"objects": len(summary["lightmaps"]), "lights": len(scene.lights),
                        "baked_texels": int(sum(texels.values())),
                        "triangles": scene.triangle_count}
    ctx.record.extra["skipped"] = summary["skipped"]
    lit = [float(np.mean(lm[m])) for lm, m in summary["lightmaps"].values() if m.any()]
    ctx.say(f"baked shadow masks of {len(texels)} objects ({sum(texels.values())} texels, "
            f"mean lit fraction {np.mean(lit):.3f}); colour attribute 'Shadow' on "
            f"{len(summary['attributes'])} objects")
    for why in summary["skipped"]:
        ctx.say(f"  skipped: {why}")


command(Command(name="shadowmap", help="bake shadow-map masks and render direct light with shadows",
                run=run, add_arguments=add_arguments, is_technique=True))
