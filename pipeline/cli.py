"""The command line: `python -m classic_bake COMMAND SCENE.blend [options]`.

The same commands run inside Blender as `blender -b -c classic_bake COMMAND SCENE.blend [options]`
(registered with `bpy.utils.register_cli_command` by the extension). Every scene command:

* opens SCENE.blend with script auto-execution off;
* writes into `--out DIR` (default `out/COMMAND/SCENE`) its outputs, a `metrics.json` (technique,
  settings, seconds per phase and in total, sizes), `result.blend` with `--save-blend`, and, for
  every technique, `render.exr`: the scene camera's view of its result rendered by the kernels,
  linear, at the scene's render resolution unless `--resolution W H` is given;
* exits 2 with one line naming the problem on bad arguments or unreadable input, 130 when
  interrupted, and leaves earlier outputs and the .blend file as they were unless it succeeded.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .outputs import PhaseTimer, RunRecord, Staging, UsageError, safe_name

PROG = "python -m classic_bake"
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130
# The first bytes of a .blend: plain, gzip-compressed (before 3.0) or zstd-compressed (3.0+).
BLEND_MAGICS = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")


@dataclass(frozen=True)
class Command:
    """One CLI command. `run(ctx)` does the work; the pipeline does files, timing and errors."""

    name: str
    help: str
    run: Callable[[RunContext], None]
    add_arguments: Callable[[argparse.ArgumentParser], None] = lambda parser: None
    needs_scene: bool = True
    is_technique: bool = False  # techniques must write render.exr


COMMANDS: dict[str, Command] = {}


def command(cmd: Command) -> Command:
    """Register `cmd` (modules in `pipeline/commands/` call this at import)."""
    if cmd.name in COMMANDS:
        raise ValueError(f"command {cmd.name!r} registered twice")
    COMMANDS[cmd.name] = cmd
    return cmd


class RunContext:
    """What a command sees: its arguments, a staging folder, a phase timer and the run record."""

    def __init__(self, cmd: Command, args: argparse.Namespace, staging: Staging, timer: PhaseTimer):
        self.command = cmd
        self.args = args
        self.staging = staging
        self.timer = timer
        scene = getattr(args, "scene", None)
        self.record = RunRecord(technique=cmd.name, scene=str(scene) if scene else "")
        self.resolution: tuple[int, int] | None = getattr(args, "resolution", None)

    def phase(self, name: str):
        """`with ctx.phase("trace"): ...` adds the block's seconds to metrics.json."""
        return self.timer.phase(name)

    def output(self, name: str) -> Path:
        """A staging path for output `name`; it is published into --out on success."""
        return self.staging.file(name)

    def write_render(self, pixels) -> Path:
        """Write the technique's camera view as linear `render.exr` (the Cycles comparison input)."""
        from ..kernels.measure.exr import write_exr

        path = self.output("render.exr")
        write_exr(path, pixels)
        return path

    def say(self, message: str) -> None:
        print(message, flush=True)


class _Parser(argparse.ArgumentParser):
    """argparse that raises UsageError instead of printing usage and exiting."""

    def error(self, message):
        raise UsageError(message)


def _resolution(text: str) -> int:
    value = int(text)
    if not 1 <= value <= 16384:
        raise argparse.ArgumentTypeError(f"resolution must be in [1, 16384], got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    from . import commands  # noqa: F401  (registers every command)

    parser = _Parser(prog=PROG, description="Bake classic mapping and global-shading techniques "
                     "with NumPy kernels, and compare them with Cycles.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for cmd in COMMANDS.values():
        p = sub.add_parser(cmd.name, help=cmd.help, description=cmd.help)
        if cmd.needs_scene:
            p.add_argument("scene", type=Path, metavar="SCENE.blend", help="the .blend file to read")
            p.add_argument("--out", type=Path, default=None,
                           help="output folder (default: out/COMMAND/SCENE)")
            p.add_argument("--save-blend", action="store_true",
                           help="also write result.blend with the results written back")
            p.add_argument("--resolution", type=_resolution, nargs=2, metavar=("W", "H"),
                           help="render.exr size in pixels (default: the scene's render size)")
        cmd.add_arguments(p)
    return parser


def command_args(cmd: Command, scene: Path, out: Path, resolution=None, argv=()) -> argparse.Namespace:
    """The namespace `cmd` would get from `COMMAND SCENE --out OUT [argv]` on the command line:
    for running one command from another (demo, compare) with the command's own defaults."""
    parser = _Parser()
    cmd.add_arguments(parser)
    args = parser.parse_args(list(argv))
    args.scene, args.out, args.save_blend, args.resolution = scene, out, False, resolution
    return args


def check_blend(path: Path) -> Path:
    """The resolved path of a readable .blend file, or UsageError naming what is wrong."""
    if not path.exists():
        raise UsageError(f"scene file not found: {path}")
    if not path.is_file():
        raise UsageError(f"scene path is not a file: {path}")
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise UsageError(f"cannot read scene file {path}: {exc.strerror}") from exc
    if not head.startswith(BLEND_MAGICS):
        raise UsageError(f"not a .blend file: {path}")
    return path.resolve()


def open_blend(path: Path) -> None:
    """Open a .blend with script auto-execution off (drivers and registered scripts do not run)."""
    import bpy

    try:
        bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    except RuntimeError as exc:
        first = str(exc).strip().splitlines()[-1] if str(exc).strip() else "unknown error"
        raise UsageError(f"cannot open {path}: {first}") from exc


def versions() -> dict:
    import platform

    import numpy

    out = {"python": platform.python_version(), "numpy": numpy.__version__}
    try:
        import bpy

        out["blender"] = bpy.app.version_string
    except ImportError:
        pass
    return out


def run_command(cmd: Command, args: argparse.Namespace) -> int:
    """Run one parsed command with staging, timing, metrics.json and publish."""
    if not cmd.needs_scene:
        cmd.run(RunContext(cmd, args, None, PhaseTimer()))
        return 0
    scene_path = check_blend(args.scene)
    out_dir = args.out or Path("out") / cmd.name / safe_name(scene_path.stem)
    staging = Staging(out_dir)
    timer = PhaseTimer()
    ctx = RunContext(cmd, args, staging, timer)
    try:
        with timer.phase("open"):
            open_blend(scene_path)
        cmd.run(ctx)
        if cmd.is_technique and not (staging.path / "render.exr").exists():
            raise RuntimeError(f"technique {cmd.name!r} wrote no render.exr")
        if args.save_blend:
            import bpy

            with timer.phase("save_blend"):
                bpy.ops.wm.save_as_mainfile(filepath=str(staging.file("result.blend")), copy=True,
                                            compress=True)
        record = ctx.record
        record.seconds = timer.totals()
        record.versions = versions()
        record.outputs = [f for f in staging.files if f != "metrics.json"]
        staging.write_json("metrics.json", record.as_json())
        published = staging.publish()
    except BaseException:
        staging.discard()
        raise
    ctx.say(f"wrote {len(published)} files to {out_dir}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of `python -m classic_bake`; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        parser = build_parser()
        if not argv or argv[0] in ("-h", "--help"):
            parser.print_help()
            return 0 if argv else EXIT_USAGE
        args = parser.parse_args(argv)
        return run_command(COMMANDS[args.command], args)
    except UsageError as exc:
        print(f"classic_bake: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("classic_bake: interrupted; no outputs were changed", file=sys.stderr)
        return EXIT_INTERRUPTED


def blender_command(argv: list[str]) -> int:
    """`blender -c classic_bake ...`: the same commands inside a running Blender."""
    return main(argv)
