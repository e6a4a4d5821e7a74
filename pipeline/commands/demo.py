"""`demo`: the main job — every command on every sample scene, then one HTML report."""

from __future__ import annotations

from pathlib import Path

from ..cli import COMMANDS, Command, RunContext, command, command_args, run_command
from ..outputs import UsageError, safe_name

# The commands the demo runs on each scene, in order. Techniques join this list as they land.
DEMO_COMMANDS = ("info", "texture", "trace", "envmap", "bump", "shadowmap", "radiosity")
# Radiosity makes at least one patch per triangle and solves all of them: the demo bakes it only on
# scenes this small (the Cornell box), to stay a few minutes long. `radiosity SCENE` runs any scene.
DEMO_MAX_TRIANGLES = {"radiosity": 500}


def add_arguments(parser) -> None:
    parser.add_argument("folder", type=Path, nargs="?", default=Path("sample_blends"),
                        help="folder of .blend files (default sample_blends)")
    parser.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder")
    parser.add_argument("--resolution", type=int, nargs=2, metavar=("W", "H"), default=None,
                        help="render size for every technique (default: each scene's own)")


def _triangles(info_dir: Path) -> int | None:
    """The triangle count the scene's `info` run found (None if it did not run)."""
    import json

    try:
        return int(json.loads((info_dir / "info.json").read_text())["counts"]["triangles"])
    except (OSError, ValueError, KeyError):
        return None


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
            limit = DEMO_MAX_TRIANGLES.get(name)
            triangles = _triangles(ctx.args.out / f"{safe_name(scene.stem)}-info")
            if limit is not None and triangles is not None and triangles > limit:
                why = f"{triangles} triangles; the demo runs {name} on scenes under {limit}"
                skipped.append(f"{scene.name} {name}: {why}")
                ctx.say(f"skipped {scene.name} {name}: {why}")
                continue
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
