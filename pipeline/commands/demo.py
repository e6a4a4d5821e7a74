"""`demo`: the main job — every command on every sample scene, into one output folder."""

from __future__ import annotations

from pathlib import Path

from ..cli import COMMANDS, Command, RunContext, command, run_command
from ..outputs import UsageError, safe_name

# The commands the demo runs on each scene, in order. Techniques join this list as they land.
DEMO_COMMANDS = ("info",)


def add_arguments(parser) -> None:
    parser.add_argument("folder", type=Path, nargs="?", default=Path("sample_blends"),
                        help="folder of .blend files (default sample_blends)")
    parser.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder")


def run(ctx: RunContext) -> None:
    import argparse

    folder: Path = ctx.args.folder
    scenes = sorted(folder.glob("*.blend"))
    if not scenes:
        raise UsageError(f"no .blend files in {folder}")
    for scene in scenes:
        for name in DEMO_COMMANDS:
            cmd = COMMANDS[name]
            out = ctx.args.out / safe_name(scene.stem) / name
            args = argparse.Namespace(scene=scene, out=out, save_blend=False, resolution=None)
            run_command(cmd, args)


command(Command(name="demo", help="run every command on every sample scene", run=run,
                add_arguments=add_arguments, needs_scene=False))
