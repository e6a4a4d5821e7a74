"""Flat, Gouraud, Phong and bump-mapped shading against Cycles, on sample_blends/bump.blend.

    .venv/bin/python bench/bump.py [--quick]

Cycles runs the matched `whitted` model (addon/cycles/) and renders the scene's Bump
nodes itself: the reference for every mode is the bumped scene, so the modes without bump show
what leaving the relief out costs. A converged Cycles render (cached in out/cache) is the
reference; the kernel's modes and Cycles' sample ladder run alternately, and for each mode the
time Cycles needs to reach the same relative MSE is interpolated on its ladder (log-log).
Writes out/bench/bump.json, out/bench/bump_speed.png/svg and out/bench/bump_modes.png.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import (  # noqa: E402
    OUT_DIR,
    add_cycles_ratios,
    image_row,
    reference_arguments,
    versions,
    whitted_reference,
    write_report,
)

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "sample_blends" / "bump.blend"
# (shading mode, adaptive edge samples): the lecture's four, then bump with edge samples.
LADDER = [("flat", 0), ("gouraud", 0), ("phong", 0), ("bump", 0), ("bump", 2), ("bump", 4)]
DEFAULT_SETTING = "bump + edges 4x4"  # the bump command's defaults


def main() -> int:
    args = reference_arguments(__doc__.splitlines()[0])

    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.geometry.bvh import BVH
    from classic_bake.kernels.measure.metrics import compare, rel_mse
    from classic_bake.kernels.trace.settings import auto_settings
    from classic_bake.kernels.trace.tracer import trace
    from classic_bake.pipeline.charts import speed_accuracy_chart, sweep_chart

    resolution, model, ref = whitted_reference(SCENE, args.quick, args.max_ref_samples)
    reference = ref.image
    snap = bridge.snapshot(resolution=resolution)
    start = time.perf_counter()
    bvh = BVH.build(snap.triangles)
    build_s = time.perf_counter() - start
    ladder = LADDER[:4] if args.quick else LADDER
    cycles_counts = [1, 2, 4, 8, 16] if args.quick else [1, 2, 4, 8, 16, 32, 64, 128]
    kernel_rows, cycles_rows, views = [], [], {}
    for step in range(max(len(ladder), len(cycles_counts))):  # alternate the two sides
        if step < len(ladder):
            mode, adaptive = ladder[step]
            settings = auto_settings(snap, shading=mode, adaptive=adaptive)
            start = time.perf_counter()
            image = trace(snap, settings, bvh=bvh, resolution=resolution).image
            seconds = time.perf_counter() - start + build_s
            name = f"{mode} + edges {adaptive}x{adaptive}" if adaptive else mode
            m = compare(image, reference)
            kernel_rows.append({"setting": name, "seconds": seconds, "rel_mse": m.rel_mse,
                                "flip": m.flip})
            if adaptive == 0:
                views[mode] = image
        if step < len(cycles_counts):
            image, seconds = cr.render_camera(bpy.context.scene, model, cycles_counts[step],
                                              resolution=resolution)
            cycles_rows.append({"samples": cycles_counts[step], "seconds": seconds,
                                "rel_mse": rel_mse(image, reference)})
    add_cycles_ratios(kernel_rows, cycles_rows)
    # Stability: the Bump nodes' Distance scaled from a quarter to 64x, Cycles re-rendered at each
    # (64 samples, the scene's half resolution): does the kernel follow Cycles into steep relief?
    sweep = {"scale": [], "bump": [], "phong": []}
    half = (resolution[0] // 2, resolution[1] // 2)
    nodes = [n for m in bpy.data.materials if m.node_tree for n in m.node_tree.nodes
             if n.type == "BUMP"]
    base = [n.inputs["Distance"].default_value for n in nodes]
    for scale in ([1, 16] if args.quick else [0.25, 1, 4, 16, 64]):
        for node, distance in zip(nodes, base, strict=True):
            node.inputs["Distance"].default_value = distance * scale
        scaled = bridge.snapshot(resolution=half)
        image, _ = cr.render_camera(bpy.context.scene, model, 64, resolution=half)
        sweep["scale"].append(scale)
        for mode in ("bump", "phong"):
            ours = trace(scaled, auto_settings(scaled, shading=mode), resolution=half).image
            sweep[mode].append(rel_mse(ours, image))
    for node, distance in zip(nodes, base, strict=True):
        node.inputs["Distance"].default_value = distance
    sweep_chart(sweep["scale"], [
        {"label": "bump", "values": sweep["bump"], "axis_label": "relative MSE against Cycles",
         "log": True},
        {"label": "Phong (the relief left out)", "values": sweep["phong"],
         "axis_label": "relative MSE against Cycles (Phong)", "log": True}],
        OUT_DIR / "bump_distance", x_label="Bump node Distance, times the scene's",
        title="Steeper relief: bump against Cycles", marks={"scene": 1}, x_log=True)
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    views["Cycles"] = reference
    image_row({k.capitalize() if k != "Cycles" else "Cycles (reference)": v
               for k, v in views.items()}, OUT_DIR / "bump_modes.png")
    speed_accuracy_chart(kernel_rows, cycles_rows, OUT_DIR / "bump_speed",
                         title=f"Shading modes vs Cycles' Bump nodes, {resolution[0]}x{resolution[1]}",
                         kernel_label="tracer: flat, Gouraud, Phong, bump (+ edge samples)",
                         cycles_label="Cycles (samples per pixel)")
    by_name = {r["setting"]: r for r in kernel_rows}
    reached = [r["ratio"] for r in kernel_rows if r["ratio"] is not None and "bump" in r["setting"]]
    ratios = {"cycles_vs_bump_seconds_to_same_rel_mse": max(reached) if reached else None,
              "cycles_vs_bump_seconds_to_same_rel_mse_default_settings":
                  by_name.get(DEFAULT_SETTING, {}).get("ratio"),
              "phong_vs_bump_rel_mse": by_name["phong"]["rel_mse"] / by_name["bump"]["rel_mse"],
              "gouraud_vs_bump_rel_mse": by_name["gouraud"]["rel_mse"] / by_name["bump"]["rel_mse"]}
    figures = {"resolution": resolution, "bvh_build_s": build_s,
               "reference": {"samples": ref.samples, "noise_rel_mse": ref.noise_rel_mse,
                             "seconds": ref.seconds, "cache_hit": ref.cache_hit},
               "kernel": kernel_rows, "cycles": cycles_rows, "distance_sweep": sweep}
    noise = ref.noise_rel_mse if ref.noise_rel_mse is not None else float("nan")
    print(f"\n{resolution[0]}x{resolution[1]}; reference {ref.samples} samples, noise relMSE "
          f"{noise:.2e}")
    print(f"{'setting':20s} {'s':>6s} {'relMSE':>9s} {'FLIP':>6s} {'Cycles s':>9s} {'ratio':>6s}")
    for r in kernel_rows:
        reach = r["cycles_seconds_to_same_error"]
        print(f"{r['setting']:20s} {r['seconds']:6.2f} {r['rel_mse']:9.2e} "
              f"{(r['flip'] if r['flip'] is not None else float('nan')):6.3f} "
              f"{(reach or float('nan')):9.2f} {(r['ratio'] or float('nan')):6.2f}")
    print(f"{'Cycles samples':20s} {'s':>6s} {'relMSE':>9s}")
    for r in cycles_rows:
        print(f"{r['samples']:<20d} {r['seconds']:6.2f} {r['rel_mse']:9.2e}")
    print("distance x", sweep["scale"], "bump", [f"{e:.2e}" for e in sweep["bump"]], "phong",
          [f"{e:.2e}" for e in sweep["phong"]])
    write_report("bump", ratios, figures, versions("bpy"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
