"""Shadow maps against Cycles' SHADOW bake, light by light, on sample_blends/shadows.blend.

    .venv/bin/python bench/shadowmap.py [--size 256] [--quick]

For each light (the others hidden) Cycles bakes a SHADOW lightmap (max_bounces 0, lights as points)
of every object at a ladder of samples, and the kernel bakes the same texels at a ladder of map
resolutions, alternately. The reference is Cycles at the top of its ladder. Reported: the fraction
of texels that disagree and the seconds of each, the ratio of Cycles' cheapest bake to the kernel's
automatic setting, and the eps sweep (acne: lit texels the map shadows; leak: shadowed texels the
map lights, the peter-panning side) for every light and a grazing sun.
Writes out/bench/shadowmap.json and out/bench/shadowmap_*.png/svg.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import OUT_DIR, versions, write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "sample_blends" / "shadows.blend"
UV_NAME = "Lightmap"


def kernel_visibility(scene, targets, light, settings):
    """(seconds, {object: (N,) visibility}) of one light over every object's texels."""
    from classic_bake.kernels.shading import direct_light as dl
    from classic_bake.kernels.shadow.shadowmap import Receivers

    one = replace(scene, lights=(light,))
    start = time.perf_counter()
    sets = list(targets.items())
    # As the shadowmap job does: every object's texels together, read in place.
    receivers = Receivers.of_parts([t.points for _, (t, _, _) in sets],
                                   [t.geo_normals for _, (t, _, _) in sets])
    spacing = dl.median_spacing([sp for _, (_, sp, _) in sets], [len(t) for _, (t, _, _) in sets])
    vis = np.ones((1, len(receivers)), np.float32)
    for _ in dl.light_visibility_steps(one, receivers, spacing, settings, vis):
        pass
    seconds = time.perf_counter() - start
    out, first = {}, 0
    for name, (t, _, _) in sets:
        out[name] = vis[0, first:first + len(t)]
        first += len(t)
    return seconds, out


def compared_texels(t, light) -> np.ndarray:
    """(N,) bool: the texels both bakes define the same way.

    Left out: texels facing away from the light (attached shadow: the kernel's mask says 0, Cycles'
    SHADOW pass 1, and E = 0 makes either irrelevant to shading) and the charts' border texels,
    which Cycles' multi-sample bakes average with the empty space beyond the chart.
    """
    from classic_bake.kernels.shading.lights import direct_irradiance

    facing = direct_irradiance(light, t.points, t.geo_normals)[:, 0] > 0
    inner = t.mask.copy()
    for axis in (0, 1):
        for shift in (-1, 1):
            inner &= np.roll(t.mask, shift, axis=axis)
    inner[0, :] = inner[-1, :] = inner[:, 0] = inner[:, -1] = False
    return facing & inner[t.rows, t.cols]


def disagreement(ours: dict, theirs: dict, targets: dict) -> float:
    wrong = total = 0
    for name, (t, _, valid) in targets.items():
        truth = theirs[name][t.rows, t.cols, 0] > 0.5
        wrong += np.count_nonzero(((ours[name] > 0.5) != truth) & valid)
        total += valid.sum()
    return wrong / max(total, 1)


def acne_and_leak(ours: dict, theirs: dict, targets: dict) -> tuple[float, float]:
    lit = dark = acne = leak = 0
    for name, (t, _, valid) in targets.items():
        truth = (theirs[name][t.rows, t.cols, 0] > 0.5)[valid]
        mine = (ours[name] > 0.5)[valid]
        lit += truth.sum()
        dark += (~truth).sum()
        acne += np.count_nonzero(truth & ~mine)
        leak += np.count_nonzero(~truth & mine)
    return acne / max(lit, 1), leak / max(dark, 1)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256, help="lightmap texels per side")
    parser.add_argument("--quick", action="store_true", help="small ladders (for a smoke run)")
    args = parser.parse_args()

    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.jobs.lightmaps import create_lightmap_uvs, lightmap_plan
    from classic_bake.kernels.bake.bake_targets import lightmap_targets
    from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings
    from classic_bake.kernels.geometry.scene import triangle_areas
    from classic_bake.kernels.shading import direct_light as dl
    from classic_bake.kernels.shadow.shadowmap import ShadowMapSettings
    from classic_bake.pipeline.charts import speed_accuracy_chart, sweep_chart

    bpy.ops.wm.open_mainfile(filepath=str(SCENE), load_ui=False, use_scripts=False)
    uv = LightmapUVSettings(resolution=args.size, padding=2)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    plan = lightmap_plan(meshes, uv)  # one texel density: the largest object gets --size
    create_lightmap_uvs(meshes, UV_NAME, uv, plan)
    scene = bridge.snapshot(request=bridge.SnapshotRequest(lightmap_uv=UV_NAME, textures=False))
    areas = triangle_areas(scene.triangles)
    base_targets = {}
    for k, info in enumerate(scene.objects):
        t = lightmap_targets(scene, k, plan[info.source_name])
        area = float(areas[scene.object_slice(k)].sum())
        base_targets[info.source_name] = (t, dl.receiver_spacing(t, area))
    names = [o.name for o in meshes]
    light_objs = {o.name: o for o in bpy.context.scene.objects if o.type == "LIGHT"}
    cr.warm_up()
    # The kernel's warm-up, as Cycles has its own: its first call pays for NumPy's first touches
    # of fresh memory and lazy set-up (measured 37 ms cold against 20 ms warm for the same sun).
    kernel_visibility(scene, {n: (t, sp, None) for n, (t, sp) in base_targets.items()},
                      scene.lights[0], dl.DirectLightSettings())

    samples_ladder = [1, 4] if args.quick else [1, 4, 16]
    repeats = 1 if args.quick else 3
    reference_samples = 16 if args.quick else 64
    map_ladder = [0, 512, 1024] if args.quick else [0, 512, 1024, 2048, 4096]
    eps_values = [0.0] + list(np.geomspace(1e-5, 0.3, 8 if args.quick else 14))

    def cycles_bake(light_name, samples):
        """Cycles' SHADOW bake of every object with only `light_name` on (visibility restored)."""
        saved = {name: obj.hide_render for name, obj in light_objs.items()}
        try:
            for name, obj in light_objs.items():
                obj.hide_render = name != light_name
            images, seconds = {}, 0.0
            for size in sorted(set(plan.values())):  # Cycles bakes one image size per call
                group = [n for n in names if plan[n] == size]
                got, secs, _ = cr.bake_lightmaps(bpy.context.scene, cr.direct(), samples, group,
                                                 UV_NAME, size, "SHADOW")
                images.update(got)
                seconds += secs
        finally:
            for name, obj in light_objs.items():
                obj.hide_render = saved[name]
        return seconds, images

    figures, ratios, rows = {"lights": {}}, {}, []
    totals = {"kernel_auto_s": 0.0, "cycles_1spp_s": 0.0}
    sweeps = {}
    # Every light as it is, and the sun again at a grazing 8 degrees above the horizon.
    cases = [(light.name, light.name, None) for light in scene.lights]
    if "Sun" in light_objs:
        cases.append(("Sun (grazing 8 deg)", "Sun", 8.0))
    for label, source, elevation in cases:
        sun = light_objs.get("Sun")
        saved = tuple(sun.rotation_euler) if sun else None
        if elevation is not None:
            sun.rotation_euler = (np.radians(90.0 - elevation), 0.0, saved[2])
            bpy.context.view_layer.update()
        current = bridge.snapshot(request=bridge.SnapshotRequest(textures=False, camera=False))
        light = replace(next(li for li in current.lights if li.name == source), name=label)
        _, reference = cycles_bake(source, reference_samples)
        targets = {n: (t, sp, compared_texels(t, light)) for n, (t, sp) in base_targets.items()}
        # The headline pair, timed REPEATS times alternately; the fastest of each side counts (a
        # 20 ms kernel call varies by +-40% on this shared 2-core machine between single runs).
        auto_settings = dl.DirectLightSettings()
        best_kernel = best_cycles = float("inf")
        for _ in range(repeats):
            best_kernel = min(best_kernel, kernel_visibility(scene, targets, light, auto_settings)[0])
            best_cycles = min(best_cycles, cycles_bake(source, 1)[0])
        kernel_ladder, cycles_ladder = [], []
        for step in range(max(len(map_ladder), len(samples_ladder))):  # alternate the two sides
            if step < len(map_ladder):
                res = map_ladder[step]
                settings = dl.DirectLightSettings(
                    shadow=ShadowMapSettings(resolution=res or 2048), auto_resolution=res == 0)
                seconds, ours = kernel_visibility(scene, targets, light, settings)
                kernel_ladder.append({"setting": "auto" if res == 0 else f"map {res}",
                                      "seconds": seconds,
                                      "disagree": disagreement(ours, reference, targets)})
            if step < len(samples_ladder):
                seconds, theirs = cycles_bake(source, samples_ladder[step])
                as_vis = {n: theirs[n][t.rows, t.cols, 0] for n, (t, _, _) in targets.items()}
                cycles_ladder.append({"samples": samples_ladder[step], "seconds": seconds,
                                      "disagree": disagreement(as_vis, reference, targets)})
        sweep = {"eps": [], "acne": [], "leak": []}
        for eps in eps_values:
            settings = dl.DirectLightSettings(shadow=ShadowMapSettings(eps_mode="fixed", eps=eps))
            _, ours = kernel_visibility(scene, targets, light, settings)
            acne, leak = acne_and_leak(ours, reference, targets)
            sweep["eps"].append(eps)
            sweep["acne"].append(acne)
            sweep["leak"].append(leak)
        _, ours = kernel_visibility(scene, targets, light, dl.DirectLightSettings())
        auto_acne, auto_leak = acne_and_leak(ours, reference, targets)
        sweep["auto"] = {"acne": auto_acne, "leak": auto_leak}
        sweeps[label] = sweep
        if sun is not None:
            sun.rotation_euler = saved
        auto = kernel_ladder[0]
        figures["lights"][label] = {"kind": light.kind, "kernel": kernel_ladder,
                                    "auto_fastest_s": best_kernel, "cycles_1spp_fastest_s": best_cycles,
                                    "cycles": cycles_ladder, "reference_samples": reference_samples}
        totals["kernel_auto_s"] += best_kernel
        totals["cycles_1spp_s"] += best_cycles
        rows.append((label, auto["disagree"], best_kernel, best_cycles,
                     auto_acne, auto_leak))
        stem = OUT_DIR / f"shadowmap_{light.kind.lower()}{'_grazing' if elevation else ''}"
        OUT_DIR.mkdir(parents=True, exist_ok=True)
        speed_accuracy_chart(
            [{"setting": r["setting"], "seconds": r["seconds"], "disagree": max(r["disagree"], 1e-6)}
             for r in kernel_ladder],
            [{"samples": r["samples"], "seconds": r["seconds"], "disagree": max(r["disagree"], 1e-6)}
             for r in cycles_ladder],
            Path(str(stem) + "_speed"), metric="disagree",
            title=f"Shadow map vs Cycles SHADOW bake: {label}",
            kernel_label="shadow map (map resolution)", cycles_label="Cycles SHADOW bake (samples)")
        sweep_chart([max(e, 1e-6) for e in sweep["eps"]],
                    [{"label": "acne: lit texels shadowed", "values": sweep["acne"],
                      "axis_label": "acne (fraction of lit texels)"},
                     {"label": "leak: shadowed texels lit (peter-panning)", "values": sweep["leak"],
                      "axis_label": "leak (fraction of shadowed texels)"}],
                    Path(str(stem) + "_eps"), x_label="eps (m); 0 drawn at 1e-6", x_log=True,
                    title=f"Depth tolerance sweep: {label} (auto: acne {auto_acne:.2%}, "
                          f"leak {auto_leak:.2%})")
    ratios["cycles_1spp_vs_shadowmap_auto_seconds"] = totals["cycles_1spp_s"] / totals["kernel_auto_s"]
    figures["totals"] = totals
    figures["sweeps"] = sweeps
    figures["lightmap_sizes"] = plan
    figures["texels"] = int(sum(len(t) for t, _ in base_targets.values()))
    print(f"{'light':24s} {'disagree':>9s} {'kernel s':>9s} {'cycles 1spp s':>14s} {'acne':>7s} {'leak':>7s}")
    for name, dis, ks, cs, acne, leak in rows:
        print(f"{name:24s} {dis:9.4%} {ks:9.3f} {cs:14.3f} {acne:7.3%} {leak:7.3%}")
    print(f"Cycles' 1-sample bakes take {ratios['cycles_1spp_vs_shadowmap_auto_seconds']:.1f}x the "
          "kernel's automatic setting")
    write_report("shadowmap", ratios, figures, versions("bpy", "classic_bake"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
