"""`lightmap-uv`: give every mesh a lightmap UV layer from xatlas (existing layers are kept)."""

from __future__ import annotations

from ..cli import Command, RunContext, command
from ..outputs import UsageError

DEFAULT_LAYER = "Lightmap"


def add_arguments(parser) -> None:
    parser.add_argument("--lightmap-size", type=int, default=512, metavar="TEXELS",
                        help="lightmap resolution the charts are packed for (default 512)")
    parser.add_argument("--padding", type=int, default=2, metavar="TEXELS",
                        help="texels between charts (default 2)")
    parser.add_argument("--uv-name", default=DEFAULT_LAYER, help="UV layer name (default Lightmap)")


def run(ctx: RunContext) -> None:
    import bpy

    from ...addon.bridge import ensure_lightmap_uv
    from ...kernels.bake.lightmap_uv import LightmapUVSettings

    args = ctx.args
    try:
        settings = LightmapUVSettings(resolution=args.lightmap_size, padding=args.padding)
    except ValueError as exc:
        raise UsageError(str(exc)) from exc
    ctx.record.settings = {"lightmap_size": settings.resolution, "padding": settings.padding,
                           "uv_name": args.uv_name}
    report = {}
    with ctx.phase("unwrap"):
        for obj in bpy.context.scene.objects:
            if obj.type != "MESH" or obj.hide_render:
                continue
            created, summary = ensure_lightmap_uv(obj, args.uv_name, settings)
            report[obj.name] = {"created": created, **summary}
            ctx.say(f"  {obj.name}: " + ("unwrapped, " + ", ".join(
                f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in summary.items())
                if created else f"kept its '{args.uv_name}' layer"))
    ctx.record.sizes = {"objects": len(report),
                        "created": sum(1 for r in report.values() if r["created"])}
    ctx.staging.write_json("lightmap_uv.json", report)


command(Command(name="lightmap-uv", help="create xatlas lightmap UVs on meshes that lack them",
                run=run, add_arguments=add_arguments))
