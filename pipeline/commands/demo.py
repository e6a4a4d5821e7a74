"""`demo`: the main job — every technique on every sample scene beside Cycles, then one HTML report.

Each technique with a matched Cycles model runs as `compare` (at its default settings, against
Cycles' first sample counts and a converged reference, cached in out/cache so that a second demo
skips it); the others run on their own. The report leads with a gallery: a row per scene, a column per
technique, ours | Cycles | error under each.
"""

from __future__ import annotations

from pathlib import Path

from ...jobs.techniques import TECHNIQUES
from ..arguments import pixels
from ..command import Command, RunContext
from ..outputs import UsageError, safe_name
from ..run import command_args, run_command

# The demo's cost: each technique at its defaults, Cycles to 16 samples, references capped at 256
# samples, half the scenes' size. DEMO_BUDGET_S is what the README promises for a fresh clone on a
# 2-core machine (the references computed, not cached); bench/demo.py measures it.
DEMO_BUDGET_S = 10 * 60
DEMO_CYCLES_SAMPLES = 16
DEMO_REFERENCE_SAMPLES = 256
DEMO_SCALE = 0.5


def add_arguments(parser) -> None:
    parser.add_argument("folder", type=Path, nargs="?", default=Path("sample_blends"),
                        help="folder of .blend files (default sample_blends)")
    parser.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder")
    parser.add_argument("--resolution", type=pixels, nargs=2, metavar=("W", "H"), default=None,
                        help="render size for every technique (default: half each scene's own)")
    parser.add_argument("--no-compare", action="store_true",
                        help="run the techniques alone, without Cycles")


def _scene_resolution(info_dir: Path) -> tuple[int, int] | None:
    """DEMO_SCALE times the camera resolution the scene's `info` run found (None: no camera)."""
    import json

    try:
        width, height = json.loads((info_dir / "info.json").read_text())["camera"]["resolution"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return max(16, round(width * DEMO_SCALE)), max(16, round(height * DEMO_SCALE))


def run(ctx: RunContext) -> None:
    from ..report import build_report
    from .compare import COMMAND as COMPARE
    from .compare import COMPARABLE
    from .info import COMMAND as INFO
    from .technique import technique_command

    folder: Path = ctx.args.folder
    scenes = sorted(folder.glob("*.blend"))
    if not scenes:
        raise UsageError(f"no .blend files in {folder}")
    import json
    import time

    began = time.perf_counter()
    skipped, seconds = [], {}
    for scene in scenes:
        stem = safe_name(scene.stem)
        info_dir = ctx.args.out / f"{stem}-info"
        run_command(INFO, command_args(INFO, scene, info_dir, ctx.args.resolution))
        resolution = ctx.args.resolution or _scene_resolution(info_dir)
        for technique in (t for t in TECHNIQUES if t.renders):
            # One folder per run: the report reads OUT/*/metrics.json.
            out = ctx.args.out / f"{stem}-{technique.name}"
            if technique.name in COMPARABLE and not ctx.args.no_compare:
                cmd, argv = COMPARE, ["--technique", technique.name, "--defaults-only",
                                      "--max-samples", str(DEMO_CYCLES_SAMPLES),
                                      "--reference-samples", str(DEMO_REFERENCE_SAMPLES)]
            else:
                cmd, argv = technique_command(technique), []
            start = time.perf_counter()
            try:
                run_command(cmd, command_args(cmd, scene, out, resolution, argv))
                seconds[out.name] = time.perf_counter() - start
            except UsageError as exc:  # a technique that does not apply to this scene
                skipped.append(f"{scene.name} {technique.name}: {exc}")
                ctx.say(f"skipped {scene.name} {technique.name}: {exc}")
    total = time.perf_counter() - began
    # What the demo cost on this machine (the README states the budget; no test times it).
    (ctx.args.out / "demo.json").write_text(json.dumps(
        {"seconds_total": total, "seconds_per_run": seconds, "skipped": skipped}, indent=1))
    ctx.say(f"report: {build_report(ctx.args.out)} ({total:.0f} s)")
    if skipped:
        ctx.say(f"{len(skipped)} runs skipped (see above)")


COMMAND = Command(name="demo", help="run every command on every sample scene and write the report",
                run=run, add_arguments=add_arguments, needs_scene=False)
