"""Environment-mapped mirrors against Cycles' true reflections, on sample_blends/env_room.blend.

    .venv/bin/python bench/envmap.py [--quick]

Cycles runs the matched `whitted` model (addon/cycles/), whose mirror reflections are
traced rays: what the cube map approximates. A converged Cycles render (cached in out/cache) is
the reference. The kernel's ladder (face size x parallax steps, and the Whitted tracer itself,
which traces the reflections) and Cycles' sample ladder run alternately; for each kernel setting
the time Cycles needs to reach the same relative MSE is interpolated on its ladder (log-log), over
the whole image and over the mirror's pixels alone. A sweep of the parallax steps shows the
technique's failure mode (a near environment) and what the correction does to it.
Writes out/bench/envmap.json and out/bench/envmap_*.png/svg.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import (  # noqa: E402
    OUT_DIR,
    image_row,
    reference_arguments,
    seconds_to_reach,
    versions,
    whitted_reference,
    write_report,
)

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "sample_blends" / "env_room.blend"
MIRROR = "MirrorSphere"
# (face size, parallax steps): 0 is the automatic size; steps 0 is the lecture's look-up.
LADDER = [(16, 0), (0, 0), (32, 4), (0, 4), (128, 4), (256, 4)]
DEFAULT_SETTING = "auto faces, 4 steps"  # EnvMapSettings()


def label(face: int, steps: int) -> str:
    return f"{'auto' if face == 0 else face} faces, {steps} steps"


def comparison_figure(views: dict, sphere: np.ndarray, path: Path) -> None:
    """The mirror up close: the lecture's look-up, the parallax search, traced reflections."""
    rows, cols = np.nonzero(sphere)
    pad = 12
    crop = (slice(max(rows.min() - pad, 0), rows.max() + pad),
            slice(max(cols.min() - pad, 0), cols.max() + pad))
    image_row({"the lecture's look-up": views["auto faces, 0 steps"],
               "with the parallax search": views[DEFAULT_SETTING],
               "traced reflections": views["traced"]}, path, crop)


def main() -> int:
    args = reference_arguments(__doc__.splitlines()[0])

    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.envmap import envmap
    from classic_bake.kernels.geometry.bvh import BVH
    from classic_bake.kernels.geometry.camera import camera_rays
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.trace.settings import auto_settings
    from classic_bake.kernels.trace.tracer import trace
    from classic_bake.pipeline.charts import speed_accuracy_chart, sweep_chart
    from classic_bake.pipeline.images import write_preview_png

    resolution, model, ref = whitted_reference(SCENE, args.quick, args.max_ref_samples)
    reference = ref.image
    snap = bridge.snapshot(resolution=resolution)
    tracer = auto_settings(snap)
    mirror = next(k for k, o in enumerate(snap.objects) if o.source_name == MIRROR)
    origins, dirs = camera_rays(snap.camera, *resolution)
    first = BVH.build(snap.triangles).intersect(origins.reshape(-1, 3), dirs.reshape(-1, 3)).tri
    sphere = (np.where(first >= 0, snap.object_ids[np.maximum(first, 0)], -1) == mirror).reshape(
        resolution[1], resolution[0])

    def errors(image) -> dict:
        return {"rel_mse": rel_mse(image, reference),
                "rel_mse_mirror": rel_mse(image[sphere][:, None], reference[sphere][:, None])}

    ladder = LADDER[:3] if args.quick else LADDER
    cycles_counts = [1, 2, 4, 8, 16] if args.quick else [1, 2, 4, 8, 16, 32, 64, 128]
    kernel_rows, cycles_rows, tracer_row, views = [], [], None, {}
    for step in range(max(len(ladder) + 1, len(cycles_counts))):  # alternate the two sides
        if step < len(ladder):
            face, steps = ladder[step]
            settings = envmap.EnvMapSettings(face_size=face, parallax_steps=steps)
            start = time.perf_counter()
            result = envmap.render(snap, settings, tracer, resolution=resolution)
            seconds = time.perf_counter() - start
            kernel_rows.append({"setting": label(face, steps), "seconds": seconds,
                                "face_size": result.maps[0].size, "parallax_steps": steps,
                                "capture_seconds": result.seconds["capture"],
                                **errors(result.image)})
            views[label(face, steps)] = result.image
            if label(face, steps) == DEFAULT_SETTING:
                write_preview_png(OUT_DIR / "envmap_view.png", result.image)
                write_preview_png(OUT_DIR / "envmap_faces.png", envmap.strip_image(result.maps[0]))
        elif step == len(ladder):  # the peer that traces the reflections
            start = time.perf_counter()
            image = views["traced"] = trace(snap, tracer, resolution=resolution).image
            tracer_row = {"setting": "traced reflections", "seconds": time.perf_counter() - start,
                          **errors(image)}
        if step < len(cycles_counts):
            image, seconds = cr.render_camera(bpy.context.scene, model, cycles_counts[step],
                                              resolution=resolution)
            cycles_rows.append({"samples": cycles_counts[step], "seconds": seconds,
                                **errors(image)})
    for row in kernel_rows + [tracer_row]:
        for metric in ("rel_mse", "rel_mse_mirror"):
            reach = seconds_to_reach(row[metric], cycles_rows, metric)
            row[f"cycles_seconds_{metric}"] = reach
            row[f"ratio_{metric}"] = None if reach is None else reach / row["seconds"]
    # Stability: the parallax steps, from the lecture's look-up to well past convergence.
    # Against the tracer's own reflections too: the map's error alone, without what the tracer
    # and the map both leave out (area lights seen in mirrors).
    traced_mirror = views["traced"][sphere][:, None]
    sweep = {"steps": [], "rel_mse_mirror": [], "rel_mse_vs_traced": []}
    for steps in range(0, 3 if args.quick else 7):
        result = envmap.render(snap, envmap.EnvMapSettings(parallax_steps=steps),
                               auto_settings(snap, adaptive=0), resolution=resolution)
        sweep["steps"].append(steps)
        sweep["rel_mse_mirror"].append(errors(result.image)["rel_mse_mirror"])
        sweep["rel_mse_vs_traced"].append(rel_mse(result.image[sphere][:, None], traced_mirror))
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    sweep_chart(sweep["steps"], [
        {"label": "mirror's relative MSE against Cycles", "values": sweep["rel_mse_mirror"],
         "axis_label": "relative MSE against Cycles", "log": True},
        {"label": "... against the tracer's reflections", "values": sweep["rel_mse_vs_traced"],
         "axis_label": "relative MSE against traced reflections", "log": True}],
        OUT_DIR / "envmap_parallax", x_label="parallax steps (0: the lecture's look-up)",
        title="Parallax correction sweep (auto face size)", marks={"default": 4})
    for metric, stem, what in (("rel_mse", "envmap_speed", "whole image"),
                               ("rel_mse_mirror", "envmap_speed_mirror", "mirror's pixels")):
        speed_accuracy_chart([{**r, "rel_mse": r[metric]} for r in kernel_rows + [tracer_row]],
                             [{**r, "rel_mse": r[metric]} for r in cycles_rows],
                             OUT_DIR / stem,
                             title=f"Environment mapping vs Cycles (true reflections), {what}",
                             kernel_label="cube-mapped mirror (face size x steps) and tracer",
                             cycles_label="Cycles (samples per pixel)")
    default = next(r for r in kernel_rows if r["setting"] == DEFAULT_SETTING)
    ratios = {}
    for metric, name in (("rel_mse", "image"), ("rel_mse_mirror", "mirror")):
        reached = [r[f"ratio_{metric}"] for r in kernel_rows if r[f"ratio_{metric}"] is not None]
        key = f"cycles_vs_envmap_seconds_to_same_rel_mse_{name}"
        ratios[key] = max(reached) if reached else None
        ratios[f"{key}_default_settings"] = default[f"ratio_{metric}"]
        ratios[f"{key}_worst_setting"] = min(reached) if reached else None
    ratios["tracer_vs_envmap_seconds_default_settings"] = tracer_row["seconds"] / default["seconds"]
    lecture = next(r for r in kernel_rows if r["setting"] == "auto faces, 0 steps")
    ratios["lecture_vs_corrected_rel_mse_mirror"] = (lecture["rel_mse_mirror"]
                                                      / default["rel_mse_mirror"])
    figures = {"resolution": resolution, "depth": tracer.max_depth,
               "mirror_pixels": int(sphere.sum()),
               "reference": {"samples": ref.samples, "noise_rel_mse": ref.noise_rel_mse,
                             "seconds": ref.seconds, "cache_hit": ref.cache_hit},
               "kernel": kernel_rows, "tracer": tracer_row, "cycles": cycles_rows,
               "parallax_sweep": sweep}
    noise = ref.noise_rel_mse if ref.noise_rel_mse is not None else float("nan")
    print(f"\n{resolution[0]}x{resolution[1]}, {int(sphere.sum())} mirror pixels; reference "
          f"{ref.samples} samples, noise relMSE {noise:.2e}")
    print(f"{'setting':22s} {'s':>6s} {'faces':>5s} {'relMSE':>9s} {'mirror':>9s} "
          f"{'ratio':>6s} {'ratio mirror':>12s}")
    for r in kernel_rows + [tracer_row]:
        print(f"{r['setting']:22s} {r['seconds']:6.2f} {r.get('face_size', ''):>5} "
              f"{r['rel_mse']:9.2e} {r['rel_mse_mirror']:9.2e} "
              f"{(r['ratio_rel_mse'] or float('nan')):6.2f} "
              f"{(r['ratio_rel_mse_mirror'] or float('nan')):12.2f}")
    print(f"{'Cycles samples':22s} {'s':>6s} {'':>5s} {'relMSE':>9s} {'mirror':>9s}")
    for r in cycles_rows:
        print(f"{r['samples']:<22d} {r['seconds']:6.2f} {'':>5s} {r['rel_mse']:9.2e} "
              f"{r['rel_mse_mirror']:9.2e}")
    print("parallax steps", sweep["steps"], "mirror relMSE",
          [f"{e:.3g}" for e in sweep["rel_mse_mirror"]])
    comparison_figure(views, sphere, OUT_DIR / "envmap_compare.png")
    write_report("envmap", ratios, figures, versions("bpy"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
