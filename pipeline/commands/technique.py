"""A command per technique record: `python -m classic_bake NAME SCENE.blend [options]` runs the
record's job on the scene and writes render.exr (+ render.png), the job's files and metrics.json."""

from __future__ import annotations

from ..arguments import add_technique_arguments
from ..command import Command, RunContext
from ..outputs import UsageError


def output_name(name: str) -> str:
    """A job's file name ("cube/Mirror Ball.exr") as given: `Staging.file` makes it safe and
    unique (two names that clean alike never share a file) and keeps its extension."""
    return name


def write_files(ctx: RunContext, summary) -> None:
    """render.exr/png when the job rendered the camera, then every file the job named (by
    extension: .exr linear, .png a tone-mapped preview, or the bytes as they are when the job
    hands uint8 data, e.g. a normal map, .json data; a callable is a writer the job made for a
    format its kernels write themselves, e.g. an OpenEXR cube map with its envmap attribute,
    called with the path); with --save-blend the job's images are packed into the saved file."""
    from ...addon.bridge import write_back

    write_outputs(ctx.staging, summary)
    if getattr(ctx.args, "save_blend", False):
        for image in summary.images.values():
            write_back.pack_image(image)


def write_outputs(staging, summary) -> None:
    """`write_files` without the Blender side: render.exr/png and the job's files into
    `staging` (`merge` writes a whole run's files with it)."""
    from ...kernels.measure.exr import write_exr
    from ..images import write_png, write_preview_png

    if summary.render is not None:
        write_exr(staging.file("render.exr"), summary.render)
        write_preview_png(staging.file("render.png"), summary.render)
    for name, data in summary.files.items():
        safe = output_name(name)
        if callable(data):
            data(staging.file(safe))
        elif safe.endswith(".json"):
            staging.write_json(safe, data)
        elif safe.endswith(".png") and getattr(data, "dtype", None) == "uint8":
            write_png(staging.file(safe), data)
        elif safe.endswith(".png"):
            write_preview_png(staging.file(safe), data)
        else:
            write_exr(staging.file(safe), data)


def check_tile(technique, tile, args) -> None:
    """`--tile` as this technique can run it (one line otherwise)."""
    if tile.prepare and not technique.tile_prepare:
        raise UsageError(f"{technique.name}: --tile prepare: its tiles need no prepare step; "
                         "run --tile K/N")
    if getattr(args, "save_blend", False):
        raise UsageError(f"{technique.name}: --tile bakes a part, so there is no result.blend; "
                         "leave out --save-blend")


def tile_outputs(summary, tile):
    """A tile's outputs moved into its folder OUT/tiles/NAME/ (jobs/tiles.py), render.exr and
    render.png among them, where `merge` finds them."""
    files = {}
    if summary.render is not None:
        files["render.exr"] = files["render.png"] = summary.render
        summary.render = None
    files.update(summary.files)
    summary.files = {f"{tile.folder}/{name}": data for name, data in files.items()}
    return summary


def technique_command(technique) -> Command:
    """The CLI command of a technique record."""

    def run(ctx: RunContext) -> None:
        import bpy

        from ..quality import apply_target

        tile = getattr(ctx.args, "tile", None)
        if tile is not None:
            check_tile(technique, tile, ctx.args)
        if getattr(ctx.args, "target_error", None) is not None:
            apply_target(ctx, technique)
        values = {**vars(ctx.args), **technique.values_from_args(ctx.args),
                  "out_dir": ctx.staging.out_dir}
        with ctx.phase(technique.prefix):
            try:
                from ...kernels.progress import drain

                summary = drain(technique.start(bpy.context, values, ctx.resolution), ctx.progress())
            except ValueError as exc:
                raise UsageError(f"{technique.name}: {exc}") from exc
        if tile is not None:
            summary = tile_outputs(summary, tile)
        elif technique.renders and summary.render is None:
            raise UsageError(f"{technique.name}: the scene has no camera, so there is no render.exr")
        with ctx.phase("write"):
            write_files(ctx, summary)
        ctx.record.settings = summary.settings
        ctx.record.sizes = summary.sizes
        ctx.record.extra.update(summary.extra)
        if summary.skipped:
            ctx.record.extra["skipped"] = summary.skipped
        if summary.scene is not None:
            # What the snapshot did not model (per material: each socket read from a default
            # and why), in every run's metrics.json as in `info`.
            ctx.record.extra["ignored"] = [*summary.scene.ignored, *summary.notes]
            from .info import baked_sockets  # and what it read through a Cycles bake

            ctx.record.extra["fallbacks"] = baked_sockets(summary.scene)
        ctx.say(summary.message)
        if getattr(ctx.args, "target_error", None) is not None:
            from ..quality import check_target

            check_target(ctx, technique, summary)
        for why in summary.skipped:
            ctx.say(f"  skipped: {why}")

    return Command(name=technique.name, help=technique.help, run=run,
                   add_arguments=lambda parser: add_technique_arguments(parser, technique),
                   is_technique=technique.renders)
