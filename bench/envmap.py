"""Environment-mapped mirrors against Cycles' true reflections, on sample_blends/env_room.blend.

    .venv/bin/python bench/envmap.py [--quick] [--parts view faces growth]

Cycles runs the matched `whitted` model (addon/cycles/), whose mirror reflections are
traced rays: what the cube map approximates. A converged Cycles render (cached in out/cache) is
the reference. The kernel's ladder (face size x parallax steps, and the Whitted tracer itself,
which traces the reflections) and Cycles' sample ladder run alternately; for each kernel setting
the time Cycles needs to reach the same relative MSE is interpolated on its ladder (log-log), over
the whole image and over the mirror's pixels alone. A sweep of the parallax steps shows the
technique's failure mode (a near environment) and what the correction does to it.

Two more parts (`--parts`): `faces`, the six faces the kernel captures against six Cycles
90-degree cameras at the mirror's centre (the mirror hidden from what sees, as the capture hides
it), at equal error against a converged Cycles render of the same faces, as a ratio of seconds;
`growth`, the mirror's parallax error as the object grows relative to its room (a room of
coloured, lamp-lit walls built here; the lecture's look-up and the parallax search against the
tracer's own reflections, which are exact for the map's error alone).
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
    add_cycles_ratios,
    image_row,
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
# --quick: the lecture's look-up at two sizes and the default (the ratios divide by it).
QUICK_LADDER = [(16, 0), (0, 0), (0, 4)]


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


def view_part(args) -> tuple[dict, dict]:
    """The camera view against Cycles and the tracer, the parallax-steps sweep: (ratios, figures)."""

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

    ladder = QUICK_LADDER if args.quick else LADDER
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
    return ratios, figures


# --- the six faces against six Cycles cameras ------------------------------------------------------
# Kernel rungs of the capture: (n, a): n x n rays per face texel, a x a again at edges (1: no
# edge pass), box-filtered like Cycles' 1-px box.
FACE_RUNGS = ((1, 1), (2, 1), (1, 2), (1, 3), (1, 4), (3, 1))
# Cycles' ladder of samples per face pixel, and its converged reference (two seeds of half each,
# whose difference estimates the reference's own noise).
FACE_CYCLES_COUNTS = (1, 2, 4, 8, 16, 32, 64, 128)
FACE_REFERENCE_SAMPLES = 2048
# --quick: a small face and short ladders (a smoke run: its figures mean nothing).
QUICK_FACE_SIZE = 16
QUICK_FACE_COUNTS = (1, 4)
QUICK_FACE_REFERENCE = 64


def face_camera_object(bpy, centre, face: int):
    """A 90-degree square camera at `centre` looking along `face`'s forward axis, up its V axis
    (the image's columns along U, rows down V): the view `capture_steps` renders that face with."""
    from mathutils import Matrix

    from classic_bake.kernels.envmap.cubemap import FACE_FORWARD, FACE_U, FACE_V

    data = bpy.data.cameras.get("Classic Bake Face") or bpy.data.cameras.new("Classic Bake Face")
    data.lens_unit, data.angle, data.sensor_fit = "FOV", 0.5 * np.pi, "AUTO"
    data.clip_start, data.shift_x, data.shift_y = 1e-3, 0.0, 0.0
    obj = bpy.data.objects.get("Classic Bake Face") or bpy.data.objects.new("Classic Bake Face",
                                                                            data)
    if obj.name not in bpy.context.scene.collection.objects:
        bpy.context.scene.collection.objects.link(obj)
    u, v, f = FACE_U[face], FACE_V[face], FACE_FORWARD[face]
    # Blender's camera looks down its local -Z with +Y up and +X right.
    obj.matrix_world = Matrix([[u[k], v[k], -f[k], centre[k]] for k in range(3)]
                              + [[0.0, 0.0, 0.0, 1.0]])
    return obj


def cycles_faces(bpy, cr, model, centre, size: int, samples: int, seed: int = 0
                 ) -> tuple[np.ndarray, float]:
    """(6, S, S, 3) float32 faces rendered by Cycles, and the seconds of the six renders."""
    scene = bpy.context.scene
    camera = scene.camera
    faces, seconds = [], 0.0
    try:
        for face in range(6):
            scene.camera = face_camera_object(bpy, centre, face)
            image, t = cr.render_camera(scene, model, samples, resolution=(size, size), seed=seed)
            faces.append(image)
            seconds += t
    finally:
        scene.camera = camera
    return np.stack(faces), seconds


def faces_part(quick: bool) -> tuple[dict, dict]:
    """The capture against Cycles' six cameras at equal error: (ratios, figures)."""
    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.envmap import envmap
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.trace.settings import auto_settings

    bpy.ops.wm.open_mainfile(filepath=str(SCENE), load_ui=False, use_scripts=False)
    resolution = bridge.render_resolution(bpy.context.scene)
    snap = bridge.snapshot(resolution=resolution)
    tracer = auto_settings(snap)
    mirror = next(k for k, o in enumerate(snap.objects) if o.source_name == MIRROR)
    size = QUICK_FACE_SIZE if quick else envmap.auto_face_size(snap, mirror, resolution)
    defaults = envmap.EnvMapSettings()
    default_rung = (defaults.face_supersample, defaults.face_edge_samples)
    centre, _ = envmap.object_bounds(snap, mirror)
    # What the capture leaves out, Cycles leaves out too: the mirror from every ray that sees
    # (it still casts shadows), the area lamps from camera rays (the kernels' view adds a lamp a
    # mirror meets exactly, not from the map).
    obj = bpy.data.objects[MIRROR]
    obj.visible_camera = obj.visible_glossy = obj.visible_transmission = False
    for lamp in bpy.data.objects:
        if lamp.type == "LIGHT":
            lamp.visible_camera = False
    model = cr.whitted(tracer.max_depth)
    cr.warm_up()
    half = (QUICK_FACE_REFERENCE if quick else FACE_REFERENCE_SAMPLES) // 2
    ref_a, ref_seconds_a = cycles_faces(bpy, cr, model, centre, size, half, seed=101)
    ref_b, ref_seconds_b = cycles_faces(bpy, cr, model, centre, size, half, seed=202)
    reference = 0.5 * (ref_a + ref_b)
    # The two halves differ by twice the noise of their mean (independent): a quarter of that.
    noise = 0.25 * faces_rel_mse(ref_a, ref_b)
    counts = QUICK_FACE_COUNTS if quick else FACE_CYCLES_COUNTS
    rungs = (default_rung,) if quick else FACE_RUNGS
    kernel_rows, cycles_rows, faces = [], [], None
    for step in range(max(len(counts), len(rungs))):  # alternate the two sides
        if step < len(rungs):
            n, a = rungs[step]
            start = time.perf_counter()
            env = drain(envmap.capture_steps(snap, mirror, size, tracer, supersample=n,
                                             edge_samples=a))
            seconds = time.perf_counter() - start
            faces = env.face_images() if faces is None else faces
            setting = f"{n} x {n} rays per texel" + (f" + edges {a} x {a}" if a > n else "")
            kernel_rows.append({"setting": setting, "supersample": n, "edge_samples": a,
                                "seconds": seconds, "rays": env.rays,
                                "rel_mse": faces_rel_mse(env.face_images(), reference)})
        if step < len(counts):
            image, seconds = cycles_faces(bpy, cr, model, centre, size, counts[step])
            cycles_rows.append({"samples": counts[step], "seconds": seconds,
                                "rel_mse": faces_rel_mse(image, reference)})
    add_cycles_ratios(kernel_rows, cycles_rows)
    reached = [r["ratio"] for r in kernel_rows if r["ratio"] is not None]
    ratios = {"cycles_vs_envmap_faces_seconds_to_same_rel_mse": max(reached) if reached else None,
              "cycles_vs_envmap_faces_seconds_to_same_rel_mse_default_settings":
                  next(r["ratio"] for r in kernel_rows
                       if (r["supersample"], r["edge_samples"]) == default_rung)}
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    write_preview_strip(OUT_DIR / "envmap_faces_cycles.png", faces, reference)
    print(f"\nsix faces of {size} x {size} texels; reference {2 * half} samples, noise relMSE "
          f"{noise:.2e} ({ref_seconds_a + ref_seconds_b:.1f} s)")
    for r in kernel_rows:
        print(f"kernel {r['setting']:22s} {r['seconds']:7.2f} s  relMSE {r['rel_mse']:.3e}  "
              f"ratio {r['ratio'] if r['ratio'] is None else round(r['ratio'], 2)}")
    for r in cycles_rows:
        print(f"Cycles {r['samples']:5d} samples        {r['seconds']:7.2f} s  "
              f"relMSE {r['rel_mse']:.3e}")
    figures = {"face_size": size, "centre": [float(c) for c in centre],
               "reference": {"samples": 2 * half, "noise_rel_mse": noise,
                             "seconds": ref_seconds_a + ref_seconds_b},
               "kernel": kernel_rows, "cycles": cycles_rows, "default_rung": list(default_rung),
               "goal": "Cycles' six cameras at least 10x the capture's seconds at equal error"}
    return ratios, figures


def faces_rel_mse(faces: np.ndarray, reference: np.ndarray) -> float:
    """Relative MSE of (6, S, S, 3) faces, all six as one (6 S, S, 3) image."""
    from classic_bake.kernels.measure.metrics import rel_mse

    return rel_mse(faces.reshape(-1, *faces.shape[2:]), reference.reshape(-1, *faces.shape[2:]))


def write_preview_strip(path: Path, kernel: np.ndarray, cycles: np.ndarray) -> None:
    """Six faces side by side, the kernel's above Cycles' (a check of the faces' orientation)."""
    from classic_bake.pipeline.images import write_preview_png

    rows = [np.concatenate(list(faces), axis=1) for faces in (kernel, cycles)]
    write_preview_png(path, np.concatenate(rows, axis=0))


# --- parallax as the object grows ------------------------------------------------------------------
# Sphere radius over the room's half-width: from a small ball to one filling most of the room.
GROWTH = (0.05, 0.1, 0.2, 0.3, 0.45, 0.6)
QUICK_GROWTH = (0.1, 0.3)
ROOM_HALF = 2.0  # m: the room is [-2, 2]^3, the sphere at its centre
# Walls: diffuse colours lit by a point lamp off-centre, so each wall holds gradients and shadows.
WALL_ALBEDOS = ((0.8, 0.3, 0.3), (0.3, 0.8, 0.3), (0.3, 0.3, 0.8),
                (0.8, 0.8, 0.3), (0.3, 0.8, 0.8), (0.8, 0.3, 0.8))
GROWTH_RESOLUTION = (64, 64)
QUICK_GROWTH_RESOLUTION = (24, 24)


def growth_scene(radius: float, resolution: tuple[int, int]):
    """A chrome sphere of `radius` at the centre of a room of six coloured Lambertian walls lit
    by a point lamp, seen by an orthographic camera just in front of it (filling the view)."""
    from classic_bake.kernels.geometry.scene import Material
    from classic_bake.kernels.trace.emitters import point_light

    sys.path.insert(0, str(ROOT / "tests" / "support"))
    from scene_builder import build, ortho_camera, tessellated_box, uv_sphere

    walls = tessellated_box(2, 2.0 * ROOM_HALF) - ROOM_HALF
    normals = np.cross(walls[:, 1] - walls[:, 0], walls[:, 2] - walls[:, 0])
    side = np.argmax(np.abs(normals), axis=1) * 2 + (np.take_along_axis(
        normals, np.argmax(np.abs(normals), axis=1)[:, None], 1)[:, 0] < 0)
    parts = [(walls[side == k], Material(name=f"wall{k}", specular=0.0,
                                         base_color=np.array(WALL_ALBEDOS[k], np.float32)))
             for k in range(6) if np.any(side == k)]
    chrome = Material(name="chrome", base_color=np.full(3, 0.9, np.float32), metallic=1.0,
                      roughness=0.0)
    parts.append((uv_sphere((0.0, 0.0, 0.0), radius, 32, 64), chrome))
    cam = ortho_camera((0.0, -(radius + ROOM_HALF) / 2, 0.1), (0.0, 1.0, -0.25), (0, 0, 1),
                       2.2 * radius, resolution)
    lamp = point_light("Lamp", (0.9, -1.1, 1.4), np.full(3, 60.0))
    return build(parts, cam, [lamp]), len(parts) - 1


def growth_part(quick: bool) -> tuple[dict, dict]:
    """The mirror's error against traced reflections as the sphere grows: (ratios, figures)."""
    from classic_bake.kernels.envmap import envmap
    from classic_bake.kernels.geometry.bvh import BVH
    from classic_bake.kernels.geometry.camera import camera_rays
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.trace.settings import TracerSettings
    from classic_bake.kernels.trace.tracer import trace
    from classic_bake.pipeline.charts import sweep_chart

    resolution = QUICK_GROWTH_RESOLUTION if quick else GROWTH_RESOLUTION
    settings = TracerSettings(max_depth=1, adaptive=0)
    sweep = {"radius_over_half_room": [], "rel_mse_lecture": [], "rel_mse_parallax": [],
             "face_size": []}
    for share in QUICK_GROWTH if quick else GROWTH:
        scene, mirror = growth_scene(share * ROOM_HALF, resolution)
        traced = trace(scene, settings).image
        o, d = camera_rays(scene.camera, *resolution)
        first = BVH.build(scene.triangles).intersect(o.reshape(-1, 3), d.reshape(-1, 3)).tri
        ball = (np.where(first >= 0, scene.object_ids[np.maximum(first, 0)], -1) == mirror
                ).reshape(resolution[1], resolution[0])
        sweep["radius_over_half_room"].append(share)
        for steps, key in ((0, "rel_mse_lecture"), (envmap.PARALLAX_STEPS, "rel_mse_parallax")):
            result = envmap.render(scene, envmap.EnvMapSettings(parallax_steps=steps), settings)
            sweep[key].append(rel_mse(result.image[ball][:, None], traced[ball][:, None]))
        sweep["face_size"].append(result.maps[0].size)
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    sweep_chart(sweep["radius_over_half_room"], [
        {"label": "the lecture's look-up", "values": sweep["rel_mse_lecture"],
         "axis_label": "mirror's relative MSE against traced reflections", "log": True},
        {"label": f"parallax search ({envmap.PARALLAX_STEPS} steps)",
         "values": sweep["rel_mse_parallax"],
         "axis_label": "mirror's relative MSE against traced reflections", "log": True}],
        OUT_DIR / "envmap_growth", x_label="sphere radius / half the room's width",
        title="Parallax error as the mirror grows in its room")
    print("radius / half room", sweep["radius_over_half_room"])
    print("  lecture ", [f"{e:.3g}" for e in sweep["rel_mse_lecture"]])
    print("  parallax", [f"{e:.3g}" for e in sweep["rel_mse_parallax"]])
    largest = -1
    ratios = {"lecture_vs_corrected_rel_mse_mirror_largest_sphere":
              sweep["rel_mse_lecture"][largest] / max(sweep["rel_mse_parallax"][largest], 1e-30)}
    return ratios, {"resolution": resolution, "sweep": sweep}


def main() -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="short ladders (smoke run)")
    parser.add_argument("--max-ref-samples", type=int, default=1024,
                        help="cap of the converged Cycles reference (default 1024)")
    parser.add_argument("--parts", nargs="+", choices=("view", "faces", "growth"),
                        default=["view", "faces", "growth"], help="what to run (default: all)")
    args = parser.parse_args()
    ratios, figures = {}, {}
    for name, part in (("view", view_part), ("faces", lambda a: faces_part(a.quick)),
                       ("growth", lambda a: growth_part(a.quick))):
        if name in args.parts:
            got_ratios, got_figures = part(args)
            ratios.update(got_ratios)
            figures[name] = got_figures
    figures["parts"] = list(args.parts)
    figures["quick"] = bool(args.quick)
    write_report("envmap", ratios, figures, versions("bpy"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
