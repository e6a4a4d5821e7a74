"""The two-pass renderer against Cycles' full global illumination, on the Cornell box with a mirror
sphere and a glass sphere (built from sample_blends/cornell_box.blend).

    .venv/bin/python bench/hybrid.py [--quick] [--size 96]

One run measures, against a converged Cycles render of the `global_illumination` model (diffuse,
glossy and transmission bounces, no caustics; cached in out/cache): the Whitted tracer alone, the
radiosity view alone and the hybrid's quality ladder, each with its time; Cycles' sample ladder in
the same run, so that the time Cycles needs to reach each hybrid rung's error is interpolated
(log-log); a run of either side under 2 s is repeated, three in all, and its median taken. The
hybrid's time counts the radiosity pass in full (one view) and, separately, the trace pass alone
(the solve amortised over many views). The caustics' share: a Cycles render with
reflective and refractive caustics against one without, relMSE and the change in mean radiance.
Stability: the patch budget and the final gather's rays swept, error charted.
Writes out/bench/hybrid.json and out/bench/hybrid_*.png/svg.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import (  # noqa: E402
    OUT_DIR,
    add_cycles_ratios,
    median_of,
    repeated,
    versions,
    write_report,
)

ROOT = Path(__file__).resolve().parents[1]
BASE_SCENE = ROOT / "sample_blends" / "cornell_box.blend"
SCENE = OUT_DIR / "hybrid_cornell_spheres.blend"
# (patch budget, edge samples, n x n samples per pixel), the final gather on: from a coarse solve
# at pixel centres to the defaults and beyond. (Without the gather the solve refines the spheres'
# fine triangles into thousands of patches: minutes, not seconds, on this scene.)
LADDER = [(100, 0, 1), (400, 0, 1), (200, 4, 1), (400, 4, 1), (400, 8, 1), (1200, 4, 1)]


def build_scene(path: Path) -> None:
    """The Cornell box with a mirror sphere (front left) and a glass sphere (front right)."""
    import bpy
    import numpy as np

    bpy.ops.wm.open_mainfile(filepath=str(BASE_SCENE), load_ui=False, use_scripts=False)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    corners = np.array([o.matrix_world @ v.co for o in meshes for v in o.data.vertices])
    lo, hi = corners.min(axis=0), corners.max(axis=0)
    size = hi - lo
    radius = 0.16 * size[0]
    for name, (fx, fy), inputs in (
            ("MirrorBall", (0.28, 0.25), {"Metallic": 1.0, "Roughness": 0.0,
                                          "Base Color": (0.9, 0.9, 0.9, 1.0)}),
            ("GlassBall", (0.72, 0.20), {"Transmission Weight": 1.0, "Roughness": 0.0,
                                         "IOR": 1.5, "Base Color": (1.0, 1.0, 1.0, 1.0)})):
        bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, segments=48, ring_count=24, location=(
            lo[0] + fx * size[0], lo[1] + fy * size[1], lo[2] + radius))
        ball = bpy.context.active_object
        ball.name = name
        bpy.ops.object.shade_smooth()
        mat = bpy.data.materials.new(name)
        if bpy.app.version < (5, 0, 0):
            mat.use_nodes = True
        bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
        for key, value in inputs.items():
            bsdf.inputs[key].default_value = value
        ball.data.materials.append(mat)
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))


def timed_hybrid(snap, settings, resolution) -> tuple[float, object]:
    """(seconds, HybridResult) of one two-pass render of the camera's view."""
    from classic_bake.kernels.hybrid.two_pass import hybrid_steps
    from classic_bake.kernels.progress import drain

    start = time.perf_counter()
    result = drain(hybrid_steps(snap, settings, resolution))
    return time.perf_counter() - start, result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short ladders (smoke run)")
    parser.add_argument("--size", type=int, default=96, help="image side, pixels (default 96)")
    parser.add_argument("--max-ref-samples", type=int, default=4096,
                        help="cap of the converged Cycles reference (default 4096)")
    args = parser.parse_args()

    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.hybrid.two_pass import HybridSettings, hybrid_steps, pass_one_settings
    from classic_bake.kernels.measure.metrics import compare, rel_mse
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.radiosity.settings import RadiositySettings
    from classic_bake.kernels.radiosity.solve import solve_radiosity
    from classic_bake.kernels.radiosity.view import render_steps
    from classic_bake.kernels.trace.settings import auto_settings
    from classic_bake.kernels.trace.tracer import trace
    from classic_bake.pipeline.charts import speed_accuracy_chart, sweep_chart
    from classic_bake.pipeline.images import write_preview_png

    build_scene(SCENE)
    resolution = (args.size // 2, args.size // 2) if args.quick else (args.size, args.size)
    cr.warm_up()
    model = cr.global_illumination(16)
    ref = cr.reference(SCENE, model, "render", resolution=resolution,
                       samples=256 if args.quick else None, max_samples=args.max_ref_samples,
                       target_rel_mse=2e-4)
    reference = ref.image
    bpy.ops.wm.open_mainfile(filepath=str(SCENE), load_ui=False, use_scripts=False)
    snap = bridge.snapshot(resolution=resolution)
    tracer = auto_settings(snap)

    # The two methods alone, at their defaults.
    start = time.perf_counter()
    whitted = trace(snap, tracer, resolution=resolution).image
    whitted_s = time.perf_counter() - start
    start = time.perf_counter()
    solution = solve_radiosity(snap, RadiositySettings())
    radiosity_view = drain(render_steps(snap, solution, resolution))
    radiosity_s = time.perf_counter() - start
    alone = {"whitted": {"seconds": whitted_s, **compare(whitted, reference).to_dict()},
             "radiosity_view": {"seconds": radiosity_s,
                                **compare(radiosity_view, reference).to_dict()}}

    ladder = LADDER[:3] if args.quick else LADDER
    cycles_counts = [4, 8, 16, 32] if args.quick else [4, 8, 16, 32, 64, 128, 256, 512]
    kernel_rows, cycles_rows = [], []
    for step in range(max(len(ladder), len(cycles_counts))):  # alternate the two sides
        if step < len(ladder):
            budget, edges, samples = ladder[step]
            settings = HybridSettings(radiosity=pass_one_settings(patch_budget=budget),
                                      tracer=auto_settings(snap, adaptive=edges,
                                                           supersample=samples))
            runs, (seconds, result) = repeated(lambda r: r[0], timed_hybrid, snap, settings,
                                               resolution)
            m = compare(result.image, reference)
            kernel_rows.append({
                "setting": f"{budget} patches, {samples}x{samples} + edges {edges}",
                "seconds": median_of(runs, lambda r: r[0]),
                "trace_seconds": median_of(runs, lambda r: r[1].seconds["trace"]),
                "radiosity_seconds": median_of(runs, lambda r: r[1].seconds["radiosity"]),
                "rel_mse": m.rel_mse, "flip": m.flip})
            if step == len(ladder) - 1:
                write_preview_png(OUT_DIR / "hybrid.png", result.image)
        if step < len(cycles_counts):
            renders, (image, _) = repeated(lambda r: r[1], cr.render_camera, bpy.context.scene,
                                           model, cycles_counts[step], resolution)
            seconds = median_of(renders, lambda r: r[1])
            cycles_rows.append({"samples": cycles_counts[step], "seconds": seconds,
                                "rel_mse": rel_mse(image, reference)})
    add_cycles_ratios(kernel_rows, cycles_rows)
    for row in kernel_rows:
        reach = row["cycles_seconds_to_same_error"]
        row["ratio_amortised"] = None if reach is None else reach / row["trace_seconds"]
    write_preview_png(OUT_DIR / "hybrid_reference.png", reference)
    write_preview_png(OUT_DIR / "hybrid_whitted.png", whitted)
    write_preview_png(OUT_DIR / "hybrid_radiosity_view.png", radiosity_view)

    # What neither pass carries: caustics (lamp -> mirror or glass -> diffuse).
    caustic_model = cr.global_illumination(16, caustics=True)
    caustic = cr.reference(SCENE, caustic_model, "render", resolution=resolution,
                           samples=256 if args.quick else None, max_samples=args.max_ref_samples,
                           target_rel_mse=2e-4).image
    caustics = {"rel_mse_with_vs_without": rel_mse(caustic, reference),
                "mean_radiance_share": float((caustic.mean() - reference.mean()) / caustic.mean())}

    # Stability: the patch budget and the gather's rays swept.
    budgets = [50, 100, 200, 400] if args.quick else [50, 100, 200, 400, 800, 1600]
    rays = [4, 16] if args.quick else [2, 4, 8, 16, 32, 64]
    sweep = {"patches": budgets, "rel_mse": [], "gather_rays": rays, "rays_rel_mse": []}
    bpy.ops.wm.open_mainfile(filepath=str(SCENE), load_ui=False, use_scripts=False)
    for budget in budgets:
        settings = HybridSettings(radiosity=pass_one_settings(patch_budget=budget),
                                  tracer=auto_settings(snap, adaptive=0))
        sweep["rel_mse"].append(rel_mse(drain(hybrid_steps(snap, settings, resolution)).image,
                                        reference))
    for count in rays:
        settings = HybridSettings(radiosity=pass_one_settings(gather_rays=count),
                                  tracer=auto_settings(snap, adaptive=0))
        sweep["rays_rel_mse"].append(rel_mse(drain(hybrid_steps(snap, settings, resolution)).image,
                                             reference))
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    sweep_chart(budgets, [{"label": "relative MSE against Cycles", "values": sweep["rel_mse"],
                           "axis_label": "relative MSE (dimensionless)", "log": True}],
                OUT_DIR / "hybrid_patches", x_label="patch budget", x_log=True,
                title="Two passes: error against the patch budget")
    sweep_chart(rays, [{"label": "relative MSE against Cycles", "values": sweep["rays_rel_mse"],
                        "axis_label": "relative MSE (dimensionless)", "log": True}],
                OUT_DIR / "hybrid_gather_rays", x_label="final gather rays per point", x_log=True,
                title="Two passes: error against the final gather's rays")
    speed_accuracy_chart(kernel_rows, cycles_rows, OUT_DIR / "hybrid_speed",
                         title=f"Two passes vs Cycles (full GI), {resolution[0]}x{resolution[1]}",
                         kernel_label="radiosity + ray tracing",
                         cycles_label="Cycles (samples per pixel)")
    reached = [r for r in kernel_rows if r["ratio"] is not None]
    best = min(kernel_rows, key=lambda r: r["rel_mse"])
    ratios = {
        "cycles_vs_hybrid_seconds_to_same_rel_mse_one_view":
            max((r["ratio"] for r in reached), default=None),
        "cycles_vs_hybrid_seconds_to_same_rel_mse_amortised":
            max((r["ratio_amortised"] for r in reached), default=None),
        "whitted_vs_hybrid_rel_mse": alone["whitted"]["rel_mse"] / best["rel_mse"],
        "radiosity_view_vs_hybrid_rel_mse": alone["radiosity_view"]["rel_mse"] / best["rel_mse"],
    }
    figures = {"resolution": resolution,
               "reference": {"samples": ref.samples, "noise_rel_mse": ref.noise_rel_mse,
                             "seconds": ref.seconds, "cache_hit": ref.cache_hit},
               "alone": alone, "kernel": kernel_rows, "cycles": cycles_rows,
               "caustics": caustics, "sweep": sweep}
    print(f"{resolution[0]}x{resolution[1]}; reference {ref.samples} samples")
    for name, row in alone.items():
        print(f"{name:16s} {row['seconds']:7.2f} s relMSE {row['rel_mse']:.2e}")
    for r in kernel_rows:
        print(f"{r['setting']:32s} {r['seconds']:7.2f} s relMSE {r['rel_mse']:.2e} "
              f"ratio {r['ratio'] or float('nan'):.2f} amortised "
              f"{r['ratio_amortised'] or float('nan'):.2f}")
    for r in cycles_rows:
        print(f"Cycles {r['samples']:<6d} {r['seconds']:7.2f} s relMSE {r['rel_mse']:.2e}")
    print("caustics:", caustics)
    write_report("hybrid", ratios, figures, versions("bpy"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
