"""`compare SCENE.blend --technique T`: the technique's quality ladder against Cycles' sample ladder.

Every technique writes `render.exr`, the camera's view of its result; this command runs the
technique's own command at each rung of its ladder and Cycles with the matching model
(`addon/cycles/`) at increasing samples, alternately, against a converged Cycles
reference (cached in out/cache). It writes per-rung metrics (relative MSE, RMSE, PSNR, HDR-FLIP),
error images of the best rung, and the speed-accuracy chart, all listed in metrics.json's
`comparison` section, which the HTML report shows.
"""

from __future__ import annotations

from pathlib import Path

from ...jobs.techniques import BY_NAME
from ..command import Command, RunContext
from ..outputs import UsageError
from ..run import command_args, open_blend, run_command
from .technique import technique_command

# The techniques with a camera view, a matched Cycles model and a quality ladder.
COMPARABLE = sorted(n for n, t in BY_NAME.items() if t.renders and t.cycles_model and t.ladder)
CYCLES_SAMPLES = [1, 2, 4, 8, 16, 32, 64]
# `--sweep PARAM`: the values swept by default (the failure modes the lecture names: acne and
# peter-panning in eps, the depth limit, the patch count, the parallax search, the face size) and
# the options a sweep needs beside them. A sweep replaces the technique's ladder.
SWEEPS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "eps": (("0", "1e-3", "1e-2", "0.03", "0.1", "0.3", "1", "3"), ("--eps-mode", "fixed")),
    "depth": (("0", "1", "2", "4", "8"), ()),
    "patches": (("25", "50", "100", "200", "400", "800"), ()),
    "parallax_steps": (("0", "1", "2", "4", "8"), ()),
    "face_size": (("8", "16", "32", "64", "128"), ()),
    "map_size": (("64", "128", "256", "512", "1024"), ()),
}


def add_arguments(parser) -> None:
    parser.add_argument("--technique", required=True, choices=COMPARABLE,
                        help="which technique to compare")
    parser.add_argument("--max-samples", type=int, default=64,
                        help="top of Cycles' sample ladder (default 64)")
    parser.add_argument("--rungs", type=int, default=0,
                        help="run only the cheapest N rungs of the technique's ladder (0: all)")
    parser.add_argument("--defaults-only", action="store_true",
                        help="one rung: the technique at its default settings (instead of the "
                             "ladder)")
    parser.add_argument("--sweep", metavar="PARAM", default=None,
                        help="instead of the ladder, run the technique at each value of one of its "
                             f"options and chart the error against it ({', '.join(SWEEPS)}, or any "
                             "option with --sweep-values)")
    parser.add_argument("--sweep-values", nargs="+", default=None, metavar="V",
                        help="the values --sweep runs (default: the table in compare.py)")
    parser.add_argument("--reference-samples", type=int, default=0,
                        help="cap of the converged Cycles reference's samples (0: the default "
                             "cap); its measured noise is recorded beside the metrics")


def run(ctx: RunContext) -> None:
    import json

    import bpy

    from ...addon.cycles import cache, runner
    from ...kernels.measure.exr import read_exr
    from ...kernels.measure.metrics import compare, error_images
    from ..charts import speed_accuracy_chart, sweep_chart
    from ..images import write_error_png, write_preview_png

    technique = ctx.args.technique
    if technique not in COMPARABLE:
        raise UsageError(f"technique {technique!r} cannot be compared with Cycles")
    record, sub = BY_NAME[technique], technique_command(BY_NAME[technique])
    scene_path = Path(ctx.args.scene).resolve()
    rungs_dir = ctx.staging.path / "rungs"
    kernel_rows, cycles_rows, images = [], [], {}
    counts = [n for n in CYCLES_SAMPLES if n <= ctx.args.max_samples]
    if not counts:
        raise UsageError(f"--max-samples {ctx.args.max_samples}: Cycles' ladder starts at "
                         f"{CYCLES_SAMPLES[0]} sample")
    ladder = [list(rung) for rung in record.ladder]
    sweep = ctx.args.sweep
    if sweep is not None:
        ladder = _sweep_rungs(record, sweep, ctx.args.sweep_values)
    if ctx.args.defaults_only:
        ladder = [[]]
    if ctx.args.rungs > 0:
        ladder = ladder[:ctx.args.rungs]
    model = reference = None
    for step in range(max(len(ladder), len(counts))):  # the two ladders alternate
        if step < len(ladder):
            out = rungs_dir / f"rung{step}"
            args = command_args(sub, scene_path, out, ctx.resolution, ladder[step])
            with ctx.phase("kernel"):
                run_command(sub, args)
            metrics = json.loads((out / "metrics.json").read_text())
            seconds = metrics["seconds"]["total"] - metrics["seconds"].get("open", 0.0)
            images[step] = read_exr(out / "render.exr")
            kernel_rows.append({"setting": " ".join(ladder[step]) or "default",
                                "argv": list(ladder[step]), "seconds": seconds})
            if model is None:
                model = record.cycles_model(metrics["settings"])
        if model is not None and reference is None:
            with ctx.phase("cycles_reference"):
                cap = {"max_samples": ctx.args.reference_samples} if ctx.args.reference_samples \
                    else {}
                reference = cache.reference(scene_path, model, "render", resolution=ctx.resolution,
                                            **cap)
            open_blend(scene_path)
        if step < len(counts):
            with ctx.phase("cycles"):
                image, seconds = runner.render_camera(bpy.context.scene, model, counts[step],
                                                  resolution=ctx.resolution)
            m = compare(image, reference.image).to_dict()
            cycles_rows.append({"samples": counts[step], "seconds": seconds, **m})
    for step, row in enumerate(kernel_rows):
        row.update(compare(images[step], reference.image).to_dict())
    best = min(range(len(kernel_rows)), key=lambda k: kernel_rows[k]["rel_mse"])
    from ...addon.bridge import SnapshotRequest, snapshot
    from ..quality import record_ladder, scene_features

    open_blend(scene_path)
    # The features read geometry, lights and materials: no world shader is rendered for them.
    features = scene_features(snapshot(request=SnapshotRequest(world_render=False),
                                       resolution=ctx.resolution), ctx.resolution)
    db = record_ladder(technique, scene_path.name, features, kernel_rows)
    errors = error_images(images[best], reference.image)
    write_preview_png(ctx.output("render.png"), images[best])
    write_preview_png(ctx.output("cycles_reference.png"), reference.image)
    write_error_png(ctx.output("error_rel_se.png"), errors.rel_se)
    if errors.flip is not None:
        write_error_png(ctx.output("error_flip.png"), errors.flip, vmax=1.0)
    ctx.write_render(images[best])
    chart = speed_accuracy_chart(kernel_rows, cycles_rows, ctx.staging.path / "speed_accuracy",
                                 title=f"{technique} against Cycles ({scene_path.name})",
                                 kernel_label=f"{technique} (quality ladder)",
                                 cycles_label="Cycles (samples per pixel)")
    charts = [Path(p).name for p in chart.paths]
    if sweep is not None:
        values = [float(rung[1]) for rung in ladder]
        swept = sweep_chart(values, [
            {"label": "relative MSE against Cycles", "values": [r["rel_mse"] for r in kernel_rows],
             "axis_label": "relative MSE (dimensionless)", "log": True},
            {"label": "seconds", "values": [r["seconds"] for r in kernel_rows],
             "axis_label": "seconds"}],
            ctx.staging.path / f"sweep_{sweep}", x_label=sweep,
            x_log=min(values) > 0 and max(values) / min(values) >= 20,
            title=f"{technique}: error against {sweep} ({scene_path.name})")
        charts = [Path(p).name for p in swept.paths] + charts
    for name in charts:
        ctx.output(name)  # stage the chart files for publishing
    ctx.record.settings = {"technique": technique, "ladder": [r["setting"] for r in kernel_rows],
                           "cycles_samples": counts, "reference_samples": reference.samples}
    ctx.record.extra["comparison"] = {
        "metrics": {k: v for k, v in kernel_rows[best].items() if k not in ("setting",)},
        "ladder": {"kernel": kernel_rows, "cycles": cycles_rows},
        "charts": [c for c in charts if c.endswith(".png")],
        "reference": {"samples": reference.samples, "noise_rel_mse": reference.noise_rel_mse,
                      "cache_hit": reference.cache_hit},
        "quality_db": str(db), "features": features,
    }
    ctx.say(f"{technique}: best rung '{kernel_rows[best]['setting']}' relMSE "
            f"{kernel_rows[best]['rel_mse']:.3g} in {kernel_rows[best]['seconds']:.2f} s; Cycles "
            + ", ".join(f"{r['samples']} spp {r['rel_mse']:.3g} in {r['seconds']:.2f} s"
                        for r in cycles_rows))


def _sweep_rungs(record, param: str, values) -> list[list[str]]:
    """One rung per value of option `param` of the technique (its CLI flag, the value, and the
    options the sweep needs beside it)."""
    option = next((o for o in record.all_options() if o.name == param and o.cli), None)
    if option is None:
        names = ", ".join(o.name for o in record.all_options() if o.cli)
        raise UsageError(f"--sweep {param}: {record.name} has no such option ({names})")
    default_values, extra = SWEEPS.get(param, ((), ()))
    values = values or default_values
    if not values:
        raise UsageError(f"--sweep {param}: give the values with --sweep-values")
    try:
        [float(v) for v in values]
    except ValueError as exc:
        raise UsageError(f"--sweep {param}: values must be numbers ({exc})") from exc
    return [[option.cli_flag(), str(v), *extra] for v in values]


COMMAND = Command(name="compare", help="a technique's quality ladder against Cycles' sample ladder",
                run=run, add_arguments=add_arguments)
