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
from ..run import command_args, run_command
from .technique import technique_command

# The techniques with a camera view, a matched Cycles model and a quality ladder.
COMPARABLE = sorted(n for n, t in BY_NAME.items() if t.renders and t.cycles_model and t.ladder)
CYCLES_SAMPLES = [1, 2, 4, 8, 16, 32, 64]


def add_arguments(parser) -> None:
    parser.add_argument("--technique", required=True, choices=COMPARABLE,
                        help="which technique to compare")
    parser.add_argument("--max-samples", type=int, default=64,
                        help="top of Cycles' sample ladder (default 64)")


def run(ctx: RunContext) -> None:
    import json

    import bpy

    from ...addon.cycles import cache, runner
    from ...kernels.measure.exr import read_exr
    from ...kernels.measure.metrics import compare, error_images
    from ..charts import speed_accuracy_chart
    from ..images import write_error_png, write_preview_png

    technique = ctx.args.technique
    if technique not in COMPARABLE:
        raise UsageError(f"technique {technique!r} cannot be compared with Cycles")
    record, sub = BY_NAME[technique], technique_command(BY_NAME[technique])
    scene_path = Path(ctx.args.scene).resolve()
    rungs_dir = ctx.staging.path / "rungs"
    kernel_rows, cycles_rows, images = [], [], {}
    counts = [n for n in CYCLES_SAMPLES if n <= ctx.args.max_samples]
    ladder = [list(rung) for rung in record.ladder]
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
                reference = cache.reference(scene_path, model, "render", resolution=ctx.resolution)
            bpy.ops.wm.open_mainfile(filepath=str(scene_path), load_ui=False, use_scripts=False)
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

    bpy.ops.wm.open_mainfile(filepath=str(scene_path), load_ui=False, use_scripts=False)
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


COMMAND = Command(name="compare", help="a technique's quality ladder against Cycles' sample ladder",
                run=run, add_arguments=add_arguments)
