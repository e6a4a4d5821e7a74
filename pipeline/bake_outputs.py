"""What every bake command writes from its job's summary: lightmaps, the camera view, packed images."""

from __future__ import annotations


def write_bake_outputs(ctx, summary: dict, suffix: str, previews: bool = False) -> None:
    """lightmaps/OBJECT_SUFFIX.exr (and .png with `previews`) for every baked lightmap,
    render.exr and render.png when the job rendered the camera, and the job's images packed into
    the .blend with --save-blend."""
    from ..addon import bridge
    from ..kernels.measure.exr import write_exr
    from .images import write_preview_png
    from .outputs import safe_name

    for name, (lightmap, _mask) in summary["lightmaps"].items():
        write_exr(ctx.output(f"lightmaps/{safe_name(name)}_{suffix}.exr"), lightmap)
        if previews:
            write_preview_png(ctx.output(f"lightmaps/{safe_name(name)}_{suffix}.png"), lightmap)
    if summary["render"] is not None:
        ctx.write_render(summary["render"])
        write_preview_png(ctx.output("render.png"), summary["render"])
    if getattr(ctx.args, "save_blend", False):
        for image in summary["images"].values():
            bridge.pack_image(image)
