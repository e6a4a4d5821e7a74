"""Texture mapping against Cycles: baked albedo lightmaps and the camera's view of the albedo.

    .venv/bin/python bench/texture.py [--quick] [--max-ref-samples N]

Scenes: sample_blends/raytrace.blend (a checker plane) and env_room.blend (an image-textured
floor), each baked at two lightmap sizes: 256 texels (texture magnified: several texels a checker
square) and 16 (minified: a texel spans squares or image texels, where a centre look-up aliases).
Cycles bakes the same texels with its colour-only DIFFUSE bake (`addon/cycles`, bake type
ALBEDO) at a ladder of samples, against its own bake at the reference's samples; the kernel bakes
them with one centre look-up per texel (the lecture's mapping alone), then with its footprint
filter (auto), then finer. The camera's view (the tracer's albedo output) runs against Cycles'
Diffuse Color pass the same way, reference converged and cached in out/cache. One process, the
two sides alternating; for each kernel rung, the seconds Cycles needs to reach the same relative
MSE (log-log on its ladder) over the kernel's seconds (snapshot included).
Writes out/bench/texture.json, texture_speed_*.png/svg and texture_views.png.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import (  # noqa: E402
    OUT_DIR,
    format_table,
    image_row,
    reference_arguments,
    seconds_to_reach,
    stack_texels,
    versions,
    write_report,
)

ROOT = Path(__file__).resolve().parents[1]
SCENES = ("raytrace", "env_room")
# The textured object each scene's pictures show.
SHOWN = {"raytrace": "CheckerPlane", "env_room": "Floor"}
SIZES = (256, 16)  # magnified, minified
UV_NAME = "Lightmap"
# (label, cells per side): one centre look-up, the footprint's choice, then finer.
BAKE_LADDER = [("centre look-up", 1), ("auto (footprint)", 0), ("4x4 cells", 4),
               ("8x8 cells", 8)]
# (label, texture filter, silhouette samples) of the camera view.
VIEW_LADDER = [("centre look-up", 1, 0), ("centre + edges", 1, 4), ("default (3x3 boxes)", 3, 4),
               ("6x6 boxes", 6, 4)]


def bake_case(name: str, size: int, args) -> dict:
    """One scene at one lightmap size: the kernel's bake ladder against Cycles'."""
    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.jobs.lightmaps import create_lightmap_uvs, lightmap_plan, mesh_objects
    from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings
    from classic_bake.kernels.bake.texture_bake import (
        TextureBakeSettings,
        stats,
        texture_bake_steps,
    )
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.progress import drain

    bpy.ops.wm.open_mainfile(filepath=str(ROOT / "sample_blends" / f"{name}.blend"),
                             load_ui=False, use_scripts=False)
    meshes = mesh_objects(bpy.context)
    uv = LightmapUVSettings(resolution=size, padding=2)
    plan = lightmap_plan(meshes, uv)
    create_lightmap_uvs(meshes, UV_NAME, uv, plan)
    model = cr.albedo()
    cr.warm_up()

    def cycles(samples: int):
        images, masks, seconds = {}, {}, 0.0
        for group_size in sorted(set(plan.values())):
            group = [o.name for o in meshes if plan[o.name] == group_size]
            got, secs, m = cr.bake_lightmaps(bpy.context.scene, model, samples, group, UV_NAME,
                                             group_size, "ALBEDO")
            images.update(got)
            masks.update(m)
            seconds += secs
        return images, masks, seconds

    ref_samples = 256 if args.quick else args.max_ref_samples
    ref_images, ref_masks, ref_seconds = cycles(ref_samples)
    counts = [1, 4, 16, 64] if args.quick else [1, 2, 4, 8, 16, 32, 64, 128]
    kernel_rows, cycles_rows, lightmaps = [], [], {}
    for step in range(max(len(BAKE_LADDER), len(counts))):
        if step < len(BAKE_LADDER):
            label, cells = BAKE_LADDER[step]
            start = time.perf_counter()
            scene = bridge.snapshot(request=bridge.SnapshotRequest(lightmap_uv=UV_NAME))
            objects = [k for k, o in enumerate(scene.objects) if not o.is_instance]
            sizes = {k: plan[scene.objects[k].source_name] for k in objects}
            bakes = drain(texture_bake_steps(scene, objects, sizes, 2,
                                             TextureBakeSettings(samples_per_side=cells)))
            seconds = time.perf_counter() - start
            images = {scene.objects[k].source_name: b.lightmap for k, b in bakes.items()}
            masks = {n: ref_masks[n] & bakes_mask for n, bakes_mask in
                     ((scene.objects[k].source_name, b.lightmap_mask) for k, b in bakes.items())}
            kernel_rows.append({"setting": label, "seconds": seconds,
                                "rel_mse": rel_mse(stack_texels(images, masks, sorted(images)),
                                                   stack_texels(ref_images, masks, sorted(images))),
                                "look_ups": stats(bakes)["cells"]})
            lightmaps[label] = images
        if step < len(counts):
            images, masks, seconds = cycles(counts[step])
            both = {n: masks[n] & ref_masks[n] for n in images}
            cycles_rows.append({"samples": counts[step], "seconds": seconds,
                                "rel_mse": rel_mse(stack_texels(images, both, sorted(images)),
                                                   stack_texels(ref_images, both, sorted(images)))})
    for row in kernel_rows:
        reach = seconds_to_reach(row["rel_mse"], cycles_rows)
        row["cycles_seconds_to_same_rel_mse"] = reach
        row["ratio"] = None if reach is None else reach / row["seconds"]
    shown = SHOWN[name]
    covered = ref_masks[shown][..., None]  # Cycles' bake is not dilated: show the charts only
    return {"kernel": kernel_rows, "cycles": cycles_rows, "reference_samples": ref_samples,
            "reference_seconds": ref_seconds, "lightmap_sizes": plan,
            "lightmaps": {k: v[shown] * covered for k, v in lightmaps.items()},
            "reference_lightmap": ref_images[shown] * covered, "object": shown}


def view_case(name: str, args) -> dict:
    """One scene's camera view: the tracer's albedo output against Cycles' Diffuse Color pass."""
    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.bake.texture_bake import render_steps
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.progress import drain

    path = ROOT / "sample_blends" / f"{name}.blend"
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    resolution = bridge.render_resolution(bpy.context.scene)
    model = cr.albedo()
    cr.warm_up()
    ref = cr.reference(path, model, "render", resolution=resolution,
                       samples=128 if args.quick else None, max_samples=args.max_ref_samples,
                       target_rel_mse=1e-4)
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    counts = [1, 4, 16, 64] if args.quick else [1, 2, 4, 8, 16, 32, 64, 128]
    kernel_rows, cycles_rows, views = [], [], {}
    for step in range(max(len(VIEW_LADDER), len(counts))):
        if step < len(VIEW_LADDER):
            label, texture_filter, adaptive = VIEW_LADDER[step]
            start = time.perf_counter()
            scene = bridge.snapshot(resolution=resolution)
            image = drain(render_steps(scene, resolution, texture_filter=texture_filter,
                                       adaptive=adaptive))
            seconds = time.perf_counter() - start
            kernel_rows.append({"setting": label, "seconds": seconds,
                                "rel_mse": rel_mse(image, ref.image)})
            views[label] = image
        if step < len(counts):
            image, seconds = cr.render_camera(bpy.context.scene, model, counts[step],
                                              resolution=resolution)
            cycles_rows.append({"samples": counts[step], "seconds": seconds,
                                "rel_mse": rel_mse(image, ref.image)})
    for row in kernel_rows:
        reach = seconds_to_reach(row["rel_mse"], cycles_rows)
        row["cycles_seconds_to_same_rel_mse"] = reach
        row["ratio"] = None if reach is None else reach / row["seconds"]
    return {"kernel": kernel_rows, "cycles": cycles_rows, "resolution": resolution,
            "reference": {"samples": ref.samples, "noise_rel_mse": ref.noise_rel_mse,
                          "cache_hit": ref.cache_hit},
            "views": views, "reference_image": ref.image}


def print_case(title: str, case: dict) -> None:
    print(f"\n{title}")
    print(format_table(["kernel rung", "s", "relMSE", "Cycles s same err", "ratio"],
                       [[r["setting"], r["seconds"], r["rel_mse"],
                         r["cycles_seconds_to_same_rel_mse"], r["ratio"]]
                        for r in case["kernel"]]))
    print(format_table(["Cycles samples", "s", "relMSE"],
                       [[r["samples"], r["seconds"], r["rel_mse"]] for r in case["cycles"]]))


def _report_case(case: dict, key: str, heading: str, title: str, kernel_label: str,
                 cycles_label: str) -> dict:
    """Print one case's table, draw its speed-accuracy chart; its kernel rows by setting."""
    from classic_bake.pipeline.charts import speed_accuracy_chart

    print_case(heading, case)
    speed_accuracy_chart(case["kernel"], case["cycles"], OUT_DIR / f"texture_speed_{key}",
                         title=title, kernel_label=kernel_label, cycles_label=cycles_label)
    return {r["setting"]: r for r in case["kernel"]}


def main() -> int:
    args = reference_arguments(__doc__.splitlines()[0])

    OUT_DIR.mkdir(parents=True, exist_ok=True)
    figures, ratios, pictures = {}, {}, {}
    for name in SCENES:
        for size in SIZES:
            case = bake_case(name, size, args)
            key = f"{name}_bake_{size}"
            by = _report_case(case, key, f"{name}: lightmaps, {size} texels (object "
                              f"{case['object']})", f"{name} albedo lightmaps at {size} texels vs "
                              "Cycles", "texture bake (cells per texel)",
                              "Cycles colour bake (samples)")
            if size == min(SIZES):
                pictures[f"{name}: centre look-up"] = case["lightmaps"]["centre look-up"]
                pictures[f"{name}: filtered (auto)"] = case["lightmaps"]["auto (footprint)"]
                pictures[f"{name}: Cycles {case['reference_samples']} spp"] = \
                    case["reference_lightmap"]
            ratios[f"cycles_bake_vs_texture_{key}_seconds_to_same_rel_mse"] = \
                by["auto (footprint)"]["ratio"]
            ratios[f"centre_vs_filtered_{key}_rel_mse"] = (
                by["centre look-up"]["rel_mse"] / max(by["auto (footprint)"]["rel_mse"], 1e-30))
            figures[key] = {k: v for k, v in case.items()
                            if k not in ("lightmaps", "reference_lightmap")}
        case = view_case(name, args)
        key = f"{name}_view"
        by = _report_case(case, key, f"{name}: camera view {case['resolution']}",
                          f"{name} albedo view vs Cycles' Diffuse Color pass",
                          "texture view (filter, edges)", "Cycles (samples per pixel)")
        ratios[f"cycles_render_vs_texture_{key}_seconds_to_same_rel_mse"] = \
            by["default (3x3 boxes)"]["ratio"]
        figures[key] = {k: v for k, v in case.items() if k not in ("views", "reference_image")}
    image_row(pictures, OUT_DIR / "texture_views.png", width=2.6)
    write_report("texture", ratios, figures, versions("bpy"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
