"""`texture`: every mesh's diffuse albedo, image and checker textures mapped through its UVs and
filtered over each texel, baked into lightmaps (an atlas per object over its lightmap UVs) and an
'Albedo' colour attribute, and the camera's view of it (render.exr)."""

from __future__ import annotations

from ..cli import Command, RunContext, command
from ..outputs import UsageError


def add_arguments(parser) -> None:
    parser.add_argument("--cells", type=int, default=0, metavar="N",
                        help="N x N filtered look-ups per lightmap texel (default 0: from each "
                             "texel's footprint in the texture)")
    parser.add_argument("--texture-filter", type=int, default=3, metavar="G",
                        help="camera view: G x G filtered look-ups over each pixel (default 3; "
                             "1: one look-up at the pixel centre, the lecture's mapping alone)")
    parser.add_argument("--adaptive", type=int, default=4, metavar="N",
                        help="camera view: N x N samples again in pixels at silhouettes "
                             "(default 4, 0: off)")
    parser.add_argument("--lightmap-size", type=int, default=256, metavar="TEXELS",
                        help="lightmap resolution of the largest object (default 256)")
    parser.add_argument("--padding", type=int, default=2, metavar="TEXELS", help="chart padding")
    parser.add_argument("--uv-name", default="Lightmap", help="lightmap UV layer (created if missing)")


def run(ctx: RunContext) -> None:
    from dataclasses import asdict

    import bpy

    from ...addon.jobs import run_to_end, texture_bake_job
    from ...kernels.bake.lightmap_uv import LightmapUVSettings
    from ...kernels.bake.texture_bake import TextureBakeSettings
    from ..bake_outputs import write_bake_outputs

    try:
        settings = TextureBakeSettings(samples_per_side=ctx.args.cells)
        uv = LightmapUVSettings(resolution=ctx.args.lightmap_size, padding=ctx.args.padding)
    except ValueError as exc:
        raise UsageError(f"texture: {exc}") from exc
    with ctx.phase("bake"):
        try:
            summary = run_to_end(texture_bake_job(
                bpy.context, settings, ctx.args.uv_name, uv, resolution=ctx.resolution,
                render_overrides={"texture_filter": ctx.args.texture_filter,
                                  "adaptive": ctx.args.adaptive}))
        except ValueError as exc:
            raise UsageError(str(exc)) from exc
    with ctx.phase("write"):
        write_bake_outputs(ctx, summary, "albedo", previews=True)
    scene, stats = summary["scene"], summary["stats"]
    textured = sorted({m.name for m in scene.materials if m.base_color_texture is not None})
    ctx.record.settings = {**asdict(settings), "texture_filter": ctx.args.texture_filter,
                           "adaptive": ctx.args.adaptive, "lightmap_size": uv.resolution,
                           "padding": uv.padding, "uv_name": ctx.args.uv_name}
    ctx.record.sizes = {"objects": len(summary["lightmaps"]), "baked_texels": stats["texels"],
                        "look_ups": stats["cells"], "triangles": scene.triangle_count,
                        "textured_materials": textured}
    ctx.record.extra["texels_per_cells_per_side"] = stats["texels_per_cells_per_side"]
    ctx.record.extra["skipped"] = summary["skipped"]
    ctx.say(f"baked the albedo of {len(summary['lightmaps'])} objects ({stats['texels']} texels, "
            f"{stats['cells']} look-ups); colour attribute 'Albedo' on "
            f"{len(summary['attributes'])} objects; textures: {', '.join(textured) or 'none'}")
    for why in summary["skipped"]:
        ctx.say(f"  skipped: {why}")


command(Command(name="texture", help="bake textured albedo into lightmaps and a colour attribute",
                run=run, add_arguments=add_arguments, is_technique=True))
