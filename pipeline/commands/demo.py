"""`demo`: the main job — every command on every sample scene, then one HTML report."""

from __future__ import annotations

from pathlib import Path

from ..cli import COMMANDS, Command, RunContext, command, command_args, run_command
from ..outputs import UsageError, safe_name

# The commands the demo runs on each scene, in order. Techniques join this list as they land.
DEMO_COMMANDS = ("info", "trace", "shadowmap")


def add_arguments(parser) -> None:
    parser.add_argument("folder", type=Path, nargs="?", default=Path("sample_blends"),
                        help="folder of .blend files (default sample_blends)")
    parser.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder")
    parser.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"), default=None,
                        help="render size for every technique (default: each scene's own)")


def run(ctx: RunContext) -> None:
    from ..report import build_report

    folder: Path = ctx.args.folder
    scenes = sorted(folder.glob("*.blend"))
    if not scenes:
        raise UsageError(f"no .blend files in {folder}")
    skipped = []
    for scene in scenes:
        for name in DEMO_COMMANDS:
            if name not in COMMANDS:
                continue
            # One folder per run: the report reads OUT/*/metrics.json.
            out = ctx.args.out / f"{safe_name(scene.stem)}-{name}"
            cmd = COMMANDS[name]
            args = command_args(cmd, scene, out, ctx.args.resolution)
            try:
                run_command(cmd, args)
            except UsageError as exc:  # a technique that does not apply to this scene
                skipped.append(f"{scene.name} {name}: {exc}")
                ctx.say(f"skipped {scene.name} {name}: {exc}")
    ctx.say(f"report: {build_report(ctx.args.out)}")
    if skipped:
        ctx.say(f"{len(skipped)} runs skipped (see above)")


command(Command(name="demo", help="run every command on every sample scene and write the report",
                run=run, add_arguments=add_arguments, needs_scene=False))
