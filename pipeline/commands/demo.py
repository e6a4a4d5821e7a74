"""`demo`: the main job — every command on every sample scene, then one HTML report."""

from __future__ import annotations

from pathlib import Path

from ...jobs.techniques import TECHNIQUES
from ..command import Command, RunContext
from ..outputs import UsageError, safe_name
from ..run import command_args, run_command

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
    from .info import COMMAND as INFO
    from .technique import technique_command

    # info first (the demo reads its triangle count), then every technique that renders.
    commands = [INFO, *(technique_command(t) for t in TECHNIQUES if t.renders)]
    folder: Path = ctx.args.folder
    scenes = sorted(folder.glob("*.blend"))
    if not scenes:
        raise UsageError(f"no .blend files in {folder}")
    skipped = []
    for scene in scenes:
        for cmd in commands:
            name = cmd.name
            # One folder per run: the report reads OUT/*/metrics.json.
            out = ctx.args.out / f"{safe_name(scene.stem)}-{name}"
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


COMMAND = Command(name="demo", help="run every command on every sample scene and write the report",
                run=run, add_arguments=add_arguments, needs_scene=False)
