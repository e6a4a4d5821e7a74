"""Radiosity against Cycles on the Cornell box: baked lightmaps and the camera render.

    .venv/bin/python bench/radiosity.py [--size 64] [--ref-samples 1024] [--quick] [--scale]

One process, alternating sides; runs under SHORT_RUN_S are timed three times (median), on both
sides alike, and each side is warmed up first. Cycles bakes the SAME lightmap texels (DIFFUSE
with colour, into the same xatlas lightmap UVs; its texels are rho E / pi, ours B / pi) at a
ladder of samples; the radiosity bake runs at a ladder of patch counts, solvers and form factor
methods. Errors are relative MSE (`kernels.measure.metrics.rel_mse`) against a converged Cycles bake
(`--ref-samples`) over the texels both bake, every object but the emitter (a DIFFUSE bake leaves
out emission). The camera render of the solution is compared with Cycles' render the same way.
For every radiosity rung, the seconds Cycles needs to reach the same error (log-log
interpolation along its ladder, its top rung when it never gets there) over the radiosity
seconds: the ratio `cycles_bake_vs_radiosity_seconds_to_same_rel_mse` is the smallest of these.

--scale: a procedural 100k-triangle scene (a Cornell-like box of finely tessellated walls and
blocks, no Blender), progressive refinement with a shot budget; reports the up-front memory
estimate against the measured peak (tracemalloc) and the seconds.
Writes out/bench/radiosity.json, out/bench/radiosity_*.png/svg and radiosity_cornell.png.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _lightmaps import cycles_lightmaps, radiosity_lightmaps, texel_rel_mse  # noqa: E402
from _report import (  # noqa: E402
    OUT_DIR,
    format_table,
    median_of,
    repeated,
    versions,
    write_report,
)

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "sample_blends" / "cornell_box.blend"
UV_NAME = "Lightmap"
EMITTER = "Light"
RENDER_SIZE = (80, 60)
def seconds_to_reach(ladder: list[dict], error: float) -> tuple[float, bool]:
    """Cycles seconds to reach `error` (log-log interpolation); (top rung's seconds, False) when
    the ladder never gets there."""
    pts = [(r["seconds"], r["rel_mse"]) for r in ladder]
    if pts[0][1] <= error:
        return pts[0][0], True
    for (s0, e0), (s1, e1) in zip(pts[:-1], pts[1:], strict=True):
        if e1 <= error:
            f = np.log(error / e0) / np.log(e1 / e0)
            return float(np.exp(np.log(s0) + f * (np.log(s1) - np.log(s0)))), True
    return pts[-1][0], False


def cornell(args) -> tuple[dict, dict, list]:
    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.jobs.lightmaps import create_lightmap_uvs, lightmap_plan
    from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.radiosity.settings import RadiositySettings
    from classic_bake.kernels.radiosity.view import render_steps
    from classic_bake.pipeline.charts import frontier, speed_accuracy_chart
    from classic_bake.pipeline.images import write_preview_png

    bpy.ops.wm.open_mainfile(filepath=str(SCENE), load_ui=False, use_scripts=False)
    uv = LightmapUVSettings(resolution=args.size, padding=2)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    plan = lightmap_plan(meshes, uv)
    create_lightmap_uvs(meshes, UV_NAME, uv, plan)
    scene = bridge.snapshot(request=bridge.SnapshotRequest(lightmap_uv=UV_NAME),
                            resolution=RENDER_SIZE)
    names = [o.name for o in meshes if o.name != EMITTER]
    objects = [k for k, o in enumerate(scene.objects) if o.source_name in names]
    sizes = {k: plan[scene.objects[k].source_name] for k in objects}
    model = cr.radiosity()
    cr.warm_up()

    def cycles_bake(samples):
        return cycles_lightmaps(bpy.context.scene, model, samples, names, plan, UV_NAME)

    start = time.perf_counter()
    ref_images, ref_masks, ref_seconds = cycles_bake(args.ref_samples)
    ref_render, ref_render_s = cr.render_camera(bpy.context.scene, model, args.ref_samples,
                                                RENDER_SIZE)
    print(f"references: bake {ref_seconds:.1f} s, render {ref_render_s:.1f} s "
          f"({args.ref_samples} samples; {time.perf_counter() - start:.0f} s wall)")

    def radiosity_run(settings):
        images, masks, seconds, result = radiosity_lightmaps(scene, settings, objects, sizes, 2)
        start = time.perf_counter()
        image = drain(render_steps(scene, result, RENDER_SIZE))
        render_s = seconds + time.perf_counter() - start  # solve + bake + camera view
        return images, masks, seconds, image, render_s, result

    # (form factors, solver, patch budget, refinement levels, final gather, source points per
    # patch side)
    rungs = [("raycast", "hierarchical", 25, 0, True, 2), ("raycast", "hierarchical", 25, 0, True, 1),
             ("raycast", "hierarchical", 150, 0, True, 2),
             ("raycast", "hierarchical", 75, 0, True, 1), ("raycast", "hierarchical", 150, 0, True, 1),
             ("raycast", "hierarchical", 300, 0, True, 1),
             ("raycast", "hierarchical", 150, 0, False, 2), ("raycast", "gauss_seidel", 50, 0, True, 2),
             ("raycast", "gauss_seidel", 150, 0, False, 2), ("hemicube", "gauss_seidel", 150, 0, True, 2),
             ("raycast", "progressive", 150, 0, True, 2), ("raycast", "hierarchical", 600, 0, True, 2),
             ("raycast", "hierarchical", 600, 0, True, 1)]
    if not args.quick:
        rungs.insert(5, ("raycast", "gauss_seidel", 300, 1, True, 2))
        rungs.append(("raycast", "hierarchical", 2000, 0, False, 2))
        rungs.append(("raycast", "auto", 400, -1, True, 0))  # RadiositySettings(): the defaults
    # 512 samples: the texel filter brings the finer rungs below 256 samples' error.
    cycles_samples = [1, 4, 16, 64] if args.quick else [1, 4, 16, 64, 256, 512]
    kernel, cycles, kernel_render, cycles_render = [], [], [], []
    best_image = None
    # One untimed coarse run pays the radiosity side's one-off costs (lazy imports, first calls),
    # as `cr.warm_up` pays Cycles'.
    radiosity_run(RadiositySettings(patch_budget=25, refine_levels=0, samples_per_side=1))
    for step in range(max(len(rungs), len(cycles_samples))):  # alternate the two sides
        if step < len(rungs):
            method, solver, budget, levels, gather, side = rungs[step]
            settings = RadiositySettings(method=method, solver=solver, patch_budget=budget,
                                         refine_levels=levels, final_gather=gather,
                                         samples_per_side=side)
            runs, last = repeated(lambda r: r[4], radiosity_run, settings)
            images, masks, _, image, _, result = last
            seconds, render_s = median_of(runs, lambda r: r[2]), median_of(runs, lambda r: r[4])
            error = texel_rel_mse(images, masks, ref_images, ref_masks, names)
            label = (f"{method} {solver} {result.stats['patches']}p"
                     f"{' gather' if gather else ' interpolated'}"
                     f"{' 1pt' if result.stats['samples_per_side'] == 1 else ''}"
                     f"{' (defaults)' if settings == RadiositySettings() else ''}")
            kernel.append({"setting": label, "seconds": seconds, "rel_mse": error,
                           "patches": result.stats["patches"],
                           "per_level": result.stats["per_level"]})
            kernel_render.append({"setting": label, "seconds": render_s,
                                  "rel_mse": rel_mse(image, ref_render)})
            if budget == 300 and gather:
                best_image = image
        if step < len(cycles_samples):
            n = cycles_samples[step]
            bakes, (images, masks, _) = repeated(lambda b: b[2], cycles_bake, n)
            seconds = median_of(bakes, lambda b: b[2])
            cycles.append({"samples": n, "seconds": seconds,
                           "rel_mse": texel_rel_mse(images, masks, ref_images, ref_masks, names)})
            renders, (image, _) = repeated(lambda r: r[1], cr.render_camera, bpy.context.scene,
                                           model, n, RENDER_SIZE)
            seconds = median_of(renders, lambda r: r[1])
            cycles_render.append({"samples": n, "seconds": seconds,
                                  "rel_mse": rel_mse(image, ref_render)})
    ratios, rows = {}, []
    for which, ours, theirs in (("bake", kernel, cycles), ("render", kernel_render, cycles_render)):
        worst = np.inf
        for entry in ours:
            s, reached = seconds_to_reach(theirs, entry["rel_mse"])
            entry["cycles_seconds_to_same_rel_mse"] = s
            entry["cycles_reached"] = reached
            entry["speedup"] = s / entry["seconds"]
            worst = min(worst, entry["speedup"])
        ratios[f"cycles_{which}_vs_radiosity_seconds_to_same_rel_mse"] = float(worst)
        # The rungs no other rung beats on both seconds and error: what the radiosity bake
        # reaches at each error level, at its fastest.
        front = frontier(ours, lambda e: (e["seconds"], e["rel_mse"]))
        ratios[f"cycles_{which}_vs_radiosity_frontier_seconds_to_same_rel_mse"] = float(
            min(e["speedup"] for e in front))
        # The same ratio for the best rung, and for the default settings (the last rung of a full
        # run).
        ratios[f"cycles_{which}_vs_radiosity_best_rung_seconds_to_same_rel_mse"] = float(
            max(e["speedup"] for e in ours))
        if not args.quick:
            ratios[f"cycles_{which}_vs_radiosity_auto_seconds_to_same_rel_mse"] = float(
                ours[-1]["speedup"])
    for e, r in zip(kernel, kernel_render, strict=True):
        rows.append([e["setting"], e["seconds"], e["rel_mse"], e["cycles_seconds_to_same_rel_mse"],
                     e["speedup"], r["rel_mse"], r["speedup"]])
    print(format_table(["radiosity rung", "bake s", "bake rel_mse", "cycles s same err",
                        "speedup", "render rel_mse", "render speedup"], rows))
    print(format_table(["cycles samples", "bake s", "bake rel_mse", "render s", "render rel_mse"],
                       [[c["samples"], c["seconds"], c["rel_mse"], r["seconds"], r["rel_mse"]]
                        for c, r in zip(cycles, cycles_render, strict=True)]))
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    speed_accuracy_chart(kernel, cycles, OUT_DIR / "radiosity_bake", metric="rel_mse",
                         title="Cornell box lightmaps: radiosity vs Cycles DIFFUSE bake",
                         kernel_label="radiosity (patches)", cycles_label="Cycles bake (samples)",
                         kernel_frontier=True)
    speed_accuracy_chart(kernel_render, cycles_render, OUT_DIR / "radiosity_render",
                         metric="rel_mse", title="Cornell box camera: radiosity vs Cycles",
                         kernel_label="radiosity (patches)", cycles_label="Cycles (samples)",
                         kernel_frontier=True)
    if best_image is not None:
        write_preview_png(OUT_DIR / "radiosity_cornell.png", best_image)
    figures = {"bake": {"kernel": kernel, "cycles": cycles}, "render": {"kernel": kernel_render,
               "cycles": cycles_render}, "reference_samples": args.ref_samples,
               "lightmap_sizes": plan, "render_size": RENDER_SIZE}
    return ratios, figures, rows


def scale_scene(target_triangles: int):
    """A Cornell-like box (1 m, inward walls, an emissive ceiling patch, two blocks) whose faces are
    grids, about `target_triangles` triangles in all."""
    sys.path.insert(0, str(ROOT / "tests" / "support"))
    from scene_builder import build

    from classic_bake.kernels.geometry.scene import Material

    def grid(origin, du, dv, n):
        o, du, dv = (np.asarray(x, float) for x in (origin, du, dv))
        i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
        p = lambda a, b: o + (a[..., None] / n) * du + (b[..., None] / n) * dv  # noqa: E731
        a, b, c, d = p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1)
        return np.concatenate([np.stack([a, b, c], -2), np.stack([a, c, d], -2)]).reshape(-1, 3, 3)

    faces = 5 + 2 * 5  # walls + two open-bottom blocks
    n = int(np.sqrt(target_triangles / (2 * faces))) + 1
    white = Material("White", base_color=np.full(3, 0.7, np.float32))
    red = Material("Red", base_color=np.array([0.6, 0.05, 0.05], np.float32))
    green = Material("Green", base_color=np.array([0.1, 0.5, 0.1], np.float32))
    lamp = Material("Lamp", base_color=np.full(3, 0.0, np.float32),
                    emission=np.full(3, 20.0, np.float32))
    parts = [
        (grid([0, 0, 0], [1, 0, 0], [0, 1, 0], n), white),  # floor, up
        (grid([0, 0, 1], [0, 1, 0], [1, 0, 0], n), white),  # ceiling, down
        (grid([0, 1, 0], [1, 0, 0], [0, 0, 1], n), white),  # back wall, -y
        (grid([0, 0, 0], [0, 1, 0], [0, 0, 1], n), red),  # left wall, +x
        (grid([1, 0, 0], [0, 0, 1], [0, 1, 0], n), green),  # right wall, -x
        (grid([0.4, 0.4, 0.999], [0, 0.2, 0], [0.2, 0, 0], 2), lamp),
    ]
    for lo, h in (((0.15, 0.2), 0.3), ((0.55, 0.5), 0.6)):
        x, y = lo
        s = 0.3
        parts += [
            (grid([x, y, h], [s, 0, 0], [0, s, 0], n), white),  # top
            (grid([x, y, 0], [s, 0, 0], [0, 0, h], n), white),  # front (-y)
            (grid([x, y + s, 0], [0, 0, h], [s, 0, 0], n), white),  # back (+y)
            (grid([x, y, 0], [0, 0, h], [0, s, 0], n), white),  # left (-x)
            (grid([x + s, y, 0], [0, s, 0], [0, 0, h], n), white),  # right (+x)
        ]
    return build(parts)


def scale_run(args) -> tuple[dict, dict]:
    import tracemalloc

    from classic_bake.kernels.radiosity.planning import memory_estimate
    from classic_bake.kernels.radiosity.settings import RadiositySettings
    from classic_bake.kernels.radiosity.solve import solve_radiosity

    scene = scale_scene(args.scale_triangles)
    settings = RadiositySettings(solver="progressive", patch_budget=1, patch_size=10.0,
                                 refine_levels=0, samples_per_side=1,
                                 visibility_samples_per_side=1, light_samples_per_side=1,
                                 max_shots=args.scale_shots)
    estimate = memory_estimate(scene.triangle_count, scene.triangle_count, settings,
                               "progressive")
    print(f"scale: {scene.triangle_count} triangles; memory estimate up front "
          f"{estimate['total'] / 2**20:.0f} MiB")
    tracemalloc.start()
    start = time.perf_counter()
    result = solve_radiosity(scene, settings)
    seconds = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    figures = {"triangles": scene.triangle_count, "patches": result.stats["patches"],
               "shots": result.stats["levels"][-1]["iterations"],
               "unshot_fraction": result.stats["levels"][-1]["solver_error"],
               "seconds": seconds, "memory_estimate_bytes": estimate["total"],
               "memory_estimate_parts": estimate, "peak_traced_bytes": peak}
    print(f"scale: {result.stats['patches']} patches, {figures['shots']} shots (unshot "
          f"{figures['unshot_fraction']:.3f} of the emitted power, ambient term covers it) in "
          f"{seconds:.1f} s; peak traced memory {peak / 2**20:.0f} MiB vs estimate "
          f"{estimate['total'] / 2**20:.0f} MiB")
    return {"scale_peak_vs_estimate_bytes": peak / estimate["total"]}, figures


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=64, help="lightmap of the largest object")
    parser.add_argument("--ref-samples", type=int, default=1024, help="converged Cycles samples")
    parser.add_argument("--quick", action="store_true", help="shorter ladders")
    parser.add_argument("--scale", action="store_true", help="also the 100k-triangle scale run")
    parser.add_argument("--scale-only", action="store_true", help="only the scale run")
    parser.add_argument("--scale-triangles", type=int, default=100_000)
    parser.add_argument("--scale-shots", type=int, default=40)
    args = parser.parse_args()
    ratios, figures = {}, {}
    if not args.scale_only:
        r, f, _ = cornell(args)
        ratios.update(r)
        figures["cornell"] = f
    if args.scale or args.scale_only:
        r, f = scale_run(args)
        ratios.update(r)
        figures["scale"] = f
    write_report("radiosity", ratios, figures, versions("bpy", "classic_bake"))
    print({k: round(v, 3) for k, v in ratios.items()})
    return 0


if __name__ == "__main__":
    sys.exit(main())
