"""`report DIR`: one self-contained HTML page for every run folder under DIR."""

from __future__ import annotations

from pathlib import Path

from ..command import Command, RunContext
from ..outputs import UsageError


def add_arguments(parser) -> None:
    parser.add_argument("folder", type=Path, help="a folder of run folders (each with metrics.json)")
    parser.add_argument("--title", default="Classic Bake against Cycles", help="page title")


def run(ctx: RunContext) -> None:
    from ..report import build_report

    folder: Path = ctx.args.folder
    if not folder.is_dir():
        raise UsageError(f"not a folder: {folder}")
    if not any(folder.glob("*/metrics.json")):
        raise UsageError(f"no run folders (*/metrics.json) in {folder}")
    ctx.say(f"report: {build_report(folder, title=ctx.args.title)}")


COMMAND = Command(name="report", help="write an HTML report of every run under a folder", run=run,
                add_arguments=add_arguments, needs_scene=False)
