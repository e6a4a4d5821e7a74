"""Running one command: its arguments, the .blend it opens, staging, timing, metrics.json and the
atomic publish of its outputs."""

from __future__ import annotations

import argparse
from pathlib import Path

from .command import Command, RunContext
from .outputs import PhaseTimer, Staging, UsageError, safe_name

# The first bytes of a .blend: plain, gzip-compressed (before 3.0) or zstd-compressed (3.0+).
BLEND_MAGICS = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")


class Parser(argparse.ArgumentParser):
    """argparse that raises UsageError instead of printing usage and exiting."""

    def error(self, message):
        raise UsageError(message)


def _resolution(text: str) -> int:
    value = int(text)
    if not 1 <= value <= 16384:
        raise argparse.ArgumentTypeError(f"resolution must be in [1, 16384], got {value}")
    return value


def add_scene_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments every scene command takes."""
    p.add_argument("scene", type=Path, metavar="SCENE.blend", help="the .blend file to read")
    p.add_argument("--out", type=Path, default=None,
                   help="output folder (default: out/COMMAND/SCENE)")
    p.add_argument("--save-blend", action="store_true",
                   help="also write result.blend with the results written back")
    p.add_argument("--resolution", type=_resolution, nargs=2, metavar=("W", "H"),
                   help="render.exr size in pixels (default: the scene's render size)")


def command_args(cmd: Command, scene: Path, out: Path, resolution=None, argv=()) -> argparse.Namespace:
    """The namespace `cmd` would get from `COMMAND SCENE --out OUT [argv]` on the command line:
    for running one command from another (demo, compare) with the command's own defaults."""
    parser = Parser()
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
