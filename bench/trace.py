"""The Whitted tracer against Cycles computing the same model, on two scenes.

    .venv/bin/python bench/trace.py [--scenes raytrace spheres] [--scales 1 2] [--quick]

Scenes: sample_blends/raytrace.blend (a mirror sphere and a hollow glass sphere over a
checkerboard, one point lamp) and "spheres", built here (`scenes.build_spheres`: a solid glass
and a metal sphere of ~6k triangles each over a checkered floor, two point lamps, 192 x 144).

Cycles runs the matched `whitted` model (addon/cycles/: lights as points, no diffuse
bounces, the world not lighting diffuse surfaces, box filter). A converged Cycles render (cached
in out/cache) is the reference. The tracer's quality ladder (supersampling, adaptive edge samples)
and Cycles' sample ladder run alternately; for each tracer setting the time Cycles needs to reach
the same relative MSE is interpolated on its ladder (log-log), which goes on past 128 samples
(below the reference's count) until it is as accurate as every tracer setting; a run of either
side under 2 s is repeated, three in all, and its median taken, after one untimed run of each
side (`cr.warm_up`, a small trace). At the scene's resolution and at 2x2 = 4x its pixel count (--scales 1 2).
The default setting's profile is kept in the JSON: seconds per phase (BVH traversal of the rays
that see and of the shadow rays, surfaces, texture filtering, light sampling, bookkeeping), in
all and per wavefront depth, and the rays per depth.
Writes out/bench/trace.json and out/bench/trace_*.png/svg.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import (  # noqa: E402
    OUT_DIR,
    median_of,
    repeated,
    seconds_to_reach,
    versions,
    write_report,
)
from scenes import build_spheres  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "sample_blends" / "raytrace.blend"
# (supersample n, adaptive edge samples n): from plain pixel centres to dense edge sampling.
LADDER = [(1, 0), (1, 2), (1, 4), (2, 4), (2, 8), (4, 8)]
DEFAULT_SETTING = "1x1 + edges 4x4"  # TracerSettings() and the trace command's defaults


def timed_trace(snap, settings, bvh, resolution) -> tuple[float, object]:
    """(seconds, TraceResult) of one trace of the camera's view."""
    from classic_bake.kernels.trace.tracer import trace

    start = time.perf_counter()
    result = trace(snap, settings, bvh=bvh, resolution=resolution)
    return time.perf_counter() - start, result


def print_profile(row: dict) -> None:
    """The default setting's seconds per phase, and per depth, as a short table."""
    phases = row["profile"]["seconds"]
    total = sum(phases.values())
    print(f"profile of {row['setting']} ({total:.2f} s in phases):")
    for phase, seconds in sorted(phases.items(), key=lambda kv: -kv[1]):
        print(f"  {phase:18s} {seconds:7.3f} s {100 * seconds / max(total, 1e-9):5.1f} %")
    print(f"  rays per depth: {row['rays_per_depth']}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", choices=("raytrace", "spheres"),
                        default=["raytrace", "spheres"], help="scenes to run (default: both)")
    parser.add_argument("--scales", type=int, nargs="+", default=[1, 2],
                        help="resolution multipliers per side (2: 4x the pixels)")
    parser.add_argument("--quick", action="store_true", help="short ladders (smoke run)")
    parser.add_argument("--max-ref-samples", type=int, default=1024,
                        help="cap of the converged Cycles reference (default 1024)")
    args = parser.parse_args()

    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.geometry.bvh import BVH
    from classic_bake.kernels.measure.metrics import compare, rel_mse
    from classic_bake.kernels.trace.settings import auto_settings
    from classic_bake.kernels.trace.tracer import trace
    from classic_bake.pipeline.charts import speed_accuracy_chart, sweep_chart
    from classic_bake.pipeline.images import write_preview_png

    ladder = LADDER[:3] if args.quick else LADDER
    cycles_counts = [1, 2, 4, 8, 16] if args.quick else [1, 2, 4, 8, 16, 32, 64, 128]
    figures, ratios = {}, {}
    cr.warm_up()
    for name in args.scenes:
        path = SCENE if name == "raytrace" else OUT_DIR / "trace_spheres.blend"
        if name == "spheres":
            build_spheres(path)
        # The sample scene's ratios keep their plain names; another scene's carry its name.
        suffix = "" if name == "raytrace" else f"_{name}"
        figures[name] = {"scales": {}}
        bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
        base = bridge.render_resolution(bpy.context.scene)
        for scale in args.scales:
            resolution = (base[0] * scale, base[1] * scale)
            snap = bridge.snapshot(resolution=resolution)
            depth = auto_settings(snap).max_depth
            model = cr.whitted(depth)
            ref = cr.reference(path, model, "render", resolution=resolution,
                               samples=128 if args.quick else None, max_samples=args.max_ref_samples,
                               target_rel_mse=1e-4)
            reference = ref.image
            bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
            snap = bridge.snapshot(resolution=resolution)
            start = time.perf_counter()
            bvh = BVH.build(snap.triangles)
            build_s = time.perf_counter() - start
            kernel_rows, cycles_rows = [], []
            # One untimed small trace pays the tracer's one-off costs (first calls, the BVH's
            # thread choice), as `cr.reference` pays Cycles' with `cr.warm_up`.
            trace(snap, auto_settings(snap), bvh=bvh, resolution=(32, 24))
            for step in range(max(len(ladder), len(cycles_counts))):  # alternate the two sides
                if step < len(ladder):
                    n, a = ladder[step]
                    settings = auto_settings(snap, supersample=n, adaptive=a)
                    runs, (_, result) = repeated(lambda r: r[0], timed_trace, snap, settings,
                                                 bvh, resolution)
                    seconds = median_of(runs, lambda r: r[0]) + build_s
                    m = compare(result.image, reference)
                    kernel_rows.append({"setting": f"{n}x{n} + edges {a}x{a}", "seconds": seconds,
                                        "rel_mse": m.rel_mse, "flip": m.flip,
                                        "rays": result.stats.camera_rays + result.stats.secondary_rays
                                        + result.stats.shadow_rays,
                                        "pruned_branches": result.stats.pruned_branches})
                    if kernel_rows[-1]["setting"] == DEFAULT_SETTING:
                        kernel_rows[-1]["profile"] = result.stats.phases
                        kernel_rows[-1]["rays_per_depth"] = result.stats.rays_per_depth
                    if step == 2:
                        write_preview_png(OUT_DIR / f"trace{suffix}_x{scale}.png", result.image)
                if step < len(cycles_counts):
                    renders, (image, _) = repeated(lambda r: r[1], cr.render_camera,
                                                   bpy.context.scene, model, cycles_counts[step],
                                                   resolution)
                    seconds = median_of(renders, lambda r: r[1])
                    cycles_rows.append({"samples": cycles_counts[step], "seconds": seconds,
                                        "rel_mse": rel_mse(image, reference)})
            # Cycles' ladder goes on (below the reference's own sample count) until it is as
            # accurate as every tracer setting: each setting's time is then read off the ladder.
            samples = cycles_counts[-1] * 2
            while (not args.quick and samples < ref.samples
                   and min(r["rel_mse"] for r in cycles_rows) > min(r["rel_mse"] for r in kernel_rows)):
                renders, (image, _) = repeated(lambda r: r[1], cr.render_camera, bpy.context.scene,
                                               model, samples, resolution)
                cycles_rows.append({"samples": samples, "seconds": median_of(renders, lambda r: r[1]),
                                    "rel_mse": rel_mse(image, reference)})
                samples *= 2
            # Stability: the ray tree's depth limit, from camera rays only to deeper than needed.
            sweep = {"depth": [], "rel_mse": [], "mean_radiance": [], "depth_limited": []}
            for d in range(0, depth + 3):
                result = trace(snap, auto_settings(snap, max_depth=d, adaptive=0), bvh=bvh,
                               resolution=resolution)
                sweep["depth"].append(d)
                sweep["rel_mse"].append(rel_mse(result.image, reference))
                sweep["mean_radiance"].append(float(result.image.mean()))
                sweep["depth_limited"].append(result.stats.depth_limited)
            sweep_chart(sweep["depth"], [
                {"label": "relative MSE against Cycles", "values": sweep["rel_mse"],
                 "axis_label": "relative MSE (dimensionless)", "log": True},
                {"label": "rays still alive at the depth limit", "values": sweep["depth_limited"],
                 "axis_label": "rays cut by the limit"}],
                OUT_DIR / f"trace{suffix}_depth_x{scale * scale}", x_label="maximum ray-tree depth",
                title=f"Depth limit sweep (auto depth {depth})", marks={"auto": depth})
            for row in kernel_rows:
                reach = seconds_to_reach(row["rel_mse"], cycles_rows)
                row["cycles_seconds_to_same_error"] = reach
                row["ratio"] = None if reach is None else reach / row["seconds"]
            best = max((r for r in kernel_rows if r["ratio"] is not None), key=lambda r: r["ratio"],
                       default=None)
            key = f"cycles_vs_tracer_seconds_to_same_rel_mse_x{scale * scale}_pixels{suffix}"
            ratios[key] = None if best is None else best["ratio"]
            default = next(r for r in kernel_rows if r["setting"] == DEFAULT_SETTING)
            ratios[f"{key}_default_settings"] = default["ratio"]
            reached = [r["ratio"] for r in kernel_rows if r["ratio"] is not None]
            ratios[f"{key}_worst_setting"] = min(reached) if reached else None
            # The floor leaves out the most expensive rung (the ladder's last).
            below_top = [r["ratio"] for r in kernel_rows[:-1] if r["ratio"] is not None]
            ratios[f"{key}_worst_setting_below_top"] = min(below_top) if below_top else None
            figures[name]["scales"][f"x{scale * scale}"] = {
                "resolution": resolution, "depth": depth, "bvh_build_s": build_s,
                "reference": {"samples": ref.samples, "noise_rel_mse": ref.noise_rel_mse,
                              "seconds": ref.seconds, "cache_hit": ref.cache_hit},
                "kernel": kernel_rows, "cycles": cycles_rows, "depth_sweep": sweep}
            OUT_DIR.mkdir(parents=True, exist_ok=True)
            speed_accuracy_chart(kernel_rows, cycles_rows, OUT_DIR / f"trace{suffix}_speed_x{scale * scale}",
                                 title=f"Whitted tracer vs Cycles (whitted model), {resolution[0]}x"
                                       f"{resolution[1]}",
                                 kernel_label="tracer (n x n + edge samples)",
                                 cycles_label="Cycles (samples per pixel)")
            noise = ref.noise_rel_mse if ref.noise_rel_mse is not None else float("nan")
            print(f"\n{resolution[0]}x{resolution[1]} (depth {depth}); reference {ref.samples} samples, "
                  f"noise relMSE {noise:.2e}")
            print(f"{'tracer setting':22s} {'s':>7s} {'relMSE':>9s} {'FLIP':>6s} "
                  f"{'Cycles s':>9s} {'ratio':>6s}")
            for r in kernel_rows:
                reach = r["cycles_seconds_to_same_error"]
                print(f"{r['setting']:22s} {r['seconds']:7.2f} {r['rel_mse']:9.2e} {r['flip']:6.3f} "
                      f"{(reach or float('nan')):9.2f} {(r['ratio'] or float('nan')):6.2f}")
            print(f"{'Cycles samples':22s} {'s':>7s} {'relMSE':>9s}")
            for r in cycles_rows:
                print(f"{r['samples']:<22d} {r['seconds']:7.2f} {r['rel_mse']:9.2e}")
            print_profile(default)
    write_report("trace", ratios, figures, versions("bpy", "embreex"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
