"""Radiosity and shadow maps against Cycles on rooms generated from seeds (bench/scenes.py).

    .venv/bin/python bench/generated.py [--scenes 8] [--seeds 11 12 ...] [--quick]

Each run draws new seeds (printed; `--seeds` rebuilds any scene) unless given, the lightings in
turn. Every room gets
lightmap UVs as the `radiosity` and `shadowmap` commands make them by default (the automatic plan:
one texel density, the largest object at the default lightmap size), saved with the room so
Cycles' cached references bake the same texels. Per room:

* **radiosity bake**: the radiosity solve and lightmap bake at the defaults (and, unless --quick,
  a finer setting for the error floor) against Cycles' DIFFUSE bake of the same texels at a ladder
  of samples (1, 4, 16, then x4 up to 256 and x2 past it while it has not reached our error, up
  to --bake-cap, 512), both against a converged Cycles DIFFUSE bake (cached in out/cache);
  emitters left out (bench/_lightmaps.py).
  Errors are net of the reference's own noise (estimated from its two halves, subtracted from
  every error measured against it; `rel_mse_raw` keeps the measured one). The ratio: Cycles'
  seconds to the defaults' texel relMSE over ours; where its ladder stops short of that error,
  a lower bound (its top rung's seconds), and beside it the ratio extrapolated from that rung
  as Monte Carlo error falls (`extrapolate`), which the checks do not use.
* **radiosity view**: the camera view of the same solution against Cycles' render of the matched
  model (`radiosity`, the world lighting where the room opens to it): relMSE, mean brightness
  over converged Cycles', and Cycles' seconds to the same error over ours (solve + view).
* **shadow-map bake** (rooms lit by a lamp: area, point, spot or the sun through the window): the
  shadow-map visibility of every texel at the automatic settings against Cycles' SHADOW bake of
  the matched `direct` model (bench/shadowmap.py's texels and disagreement); the ratio: Cycles'
  seconds to the larger of our disagreement and 0.5% over ours.

Over all rooms: the minimum, median and maximum of each ratio, and the issue's checks (the
radiosity bake ratio's median >= 10 and minimum >= 3; relMSE <= 0.005 at the defaults and view
brightness within 1% of Cycles on every closed room; the shadow-map ratio's median >= 20 at
< 0.5% disagreeing texels). Writes out/bench/generated.json.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _lightmaps import (  # noqa: E402
    LADDER_SEED,
    cycles_lightmap_reference,
    cycles_lightmaps,
    radiosity_lightmaps,
    reference_noise,
    texel_rel_mse,
)
from _report import OUT_DIR, format_table, seconds_to_reach, versions, write_report  # noqa: E402
from scenes import build_room  # noqa: E402

UV_NAME = "Lightmap"
ROOT = Path(__file__).resolve().parents[1]
# What a room's file depends on: the room builder and the lightmap UV code.
ROOM_SOURCES = (ROOT / "bench" / "scenes.py", ROOT / "kernels" / "bake" / "lightmap_uv.py",
                ROOT / "jobs" / "lightmaps.py")
BAKE_TARGET_REL_MSE = 0.005  # the target for the defaults on every closed room
SHADOW_TARGET_DISAGREE = 0.005  # fraction of texels
BRIGHTNESS_TOLERANCE = 0.01
# Cycles' bake ladder climbs by 4x up to here, then by 2x (a 256-sample bake of a room takes
# 1.5-3.5 minutes).
LADDER_X4_TOP = 256
# A metric of 0 (a Cycles rung that disagrees nowhere) would break log-log interpolation.
FLOOR = 1e-6


def spread(values) -> dict | None:
    values = [v for v in values if v is not None]
    return None if not values else {"min": float(np.min(values)),
                                    "median": float(np.median(values)),
                                    "max": float(np.max(values))}


def reach(error: float, ladder: list[dict], metric: str) -> tuple[float, bool]:
    """(Cycles' seconds to `error` on its ladder, True) or, when it never gets there, (its top
    rung's seconds, False): the ratio is then a lower bound."""
    points = [{"seconds": r["seconds"], metric: max(r[metric], FLOOR)} for r in ladder]
    found = seconds_to_reach(max(error, FLOOR), points, metric)
    if found is None:
        return max(r["seconds"] for r in ladder), False
    return found, True


def extrapolate(error: float, ladder: list[dict], metric: str) -> float:
    """Cycles' seconds to `error` past its ladder's top rung, as Monte Carlo error falls: relMSE
    (a variance) as 1 / samples, so as 1 / seconds once the per-sample time is steady (the top
    rung's, 256 samples or more of a bake)."""
    top = max(ladder, key=lambda r: r["seconds"])
    return top["seconds"] * max(top[metric], FLOOR) / max(error, FLOOR)


def prepare_room(seed: int, path: Path) -> tuple[dict, dict]:
    """Build the room of `seed` into `path` with the radiosity job's automatic lightmap UVs saved
    in it. Returns (what was drawn, the lightmap plan {object: texels per side}).

    A room built before by the same bench/scenes.py and lightmap code is reused as it is (its
    sidecar PATH.json says what was drawn and planned): Blender does not write the same bytes
    twice for one scene, and the cached Cycles references are keyed by the file's bytes, so a
    rerun with --seeds measures against the references it already has."""
    import bpy

    from classic_bake.jobs.lightmaps import lightmap_uvs
    from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings

    sidecar = path.with_suffix(".json")
    made_by = hashlib.sha256(b"".join(
        f.read_bytes() for f in ROOM_SOURCES)).hexdigest()
    if path.is_file() and sidecar.is_file():
        known = json.loads(sidecar.read_text())
        if known.get("made_by") == made_by:
            return known["drawn"], known["plan"]
    drawn = build_room(seed, path)
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    with lightmap_uvs(bpy.context, UV_NAME, LightmapUVSettings()) as plan:
        plan = dict(plan)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    sidecar.write_text(json.dumps({"made_by": made_by, "drawn": drawn, "plan": plan},
                                  default=lambda v: v.tolist()))
    return drawn, plan


def radiosity_room(args, path: Path, drawn: dict, plan: dict) -> dict:
    """The radiosity bake and view of one room against Cycles."""
    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.radiosity.settings import RadiositySettings
    from classic_bake.kernels.radiosity.view import render_steps

    resolution = (40, 30) if args.quick else (80, 60)
    view_counts = [4, 16, 64] if args.quick else [4, 8, 16, 32, 64, 128, 256]
    # Cycles' bake ladder: these, then four times the samples (twice past LADDER_X4_TOP, where a
    # rung costs minutes) while it has not reached the radiosity bake's error, up to the cap.
    bake_counts, bake_cap = ([1, 4], 16) if args.quick else ([1, 4, 16], args.bake_cap)
    model = cr.radiosity(world_lighting=not drawn["closed"])
    names = [n for n in plan if n not in drawn["emitters"]]
    ref_view = cr.reference(path, model, "render", resolution=resolution,
                            samples=256 if args.quick else None,
                            max_samples=args.max_ref_samples, target_rel_mse=2e-4)
    ref_images, ref_masks, ref_info = cycles_lightmap_reference(
        path, model, names, plan, UV_NAME, samples=None,
        max_samples=32 if args.quick else args.max_ref_bake_samples,
        target_rel_mse=args.bake_target_rel_mse)
    # The reference's own noise (estimated from its two halves) adds to every error measured
    # against it, ours and Cycles' rungs alike: the net error subtracts it.
    noise = reference_noise(ref_info) or 0.0

    def net(error: float) -> float:
        return max(error - noise, FLOOR)

    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    snap = bridge.snapshot(request=bridge.SnapshotRequest(lightmap_uv=UV_NAME),
                           resolution=resolution)
    objects = [k for k, o in enumerate(snap.objects) if o.source_name in names]
    sizes = {k: plan[snap.objects[k].source_name] for k in objects}
    rungs = [("defaults", RadiositySettings())]
    if not args.quick:  # a finer setting: where the error stops falling (the floor)
        rungs.append(("fine", RadiositySettings(patch_budget=1600, gather_rays=64)))
    bake, view = [], None
    for label, settings in rungs:
        images, masks, seconds, result = radiosity_lightmaps(snap, settings, objects, sizes, 2)
        error = texel_rel_mse(images, masks, ref_images, ref_masks, names)
        bake.append({"setting": label, "seconds": seconds, "rel_mse_raw": error,
                     "rel_mse": net(error), "patches": result.stats["patches"],
                     "solver": result.stats["solver"]})
        if view is None:  # the defaults' camera view: the solve's seconds and the view's
            start = time.perf_counter()
            image = drain(render_steps(snap, result, resolution))
            view = {"seconds": result.stats["seconds"] + time.perf_counter() - start,
                    "rel_mse": rel_mse(image, ref_view.image),
                    "brightness_ratio": float(image.mean() / max(ref_view.image.mean(), 1e-12))}
    cycles_bake, cycles_view = [], []
    best = min(e["rel_mse"] for e in bake)
    while bake_counts:
        n = bake_counts.pop(0)
        images, masks, seconds = cycles_lightmaps(bpy.context.scene, model, n, names, plan,
                                                  UV_NAME, seed=LADDER_SEED)
        error = texel_rel_mse(images, masks, ref_images, ref_masks, names)
        cycles_bake.append({"samples": n, "seconds": seconds, "rel_mse_raw": error,
                            "rel_mse": net(error)})
        step = 4 * n if 4 * n <= LADDER_X4_TOP else 2 * n
        if not bake_counts and net(error) > best and step <= bake_cap:
            bake_counts.append(step)
    for n in view_counts:
        image, seconds = cr.render_camera(bpy.context.scene, model, n, resolution=resolution,
                                          seed=LADDER_SEED)
        cycles_view.append({"samples": n, "seconds": seconds,
                            "rel_mse": rel_mse(image, ref_view.image)})
    for entry in bake:
        entry["cycles_seconds_to_same_rel_mse"], entry["cycles_reached"] = reach(
            entry["rel_mse"], cycles_bake, "rel_mse")
        entry["ratio"] = entry["cycles_seconds_to_same_rel_mse"] / entry["seconds"]
        # Past the ladder's top the ratio above is a lower bound; this one extrapolates.
        entry["ratio_extrapolated"] = (entry["ratio"] if entry["cycles_reached"] else
                                       extrapolate(entry["rel_mse"], cycles_bake, "rel_mse")
                                       / entry["seconds"])
    view["cycles_seconds_to_same_rel_mse"], view["cycles_reached"] = reach(
        view["rel_mse"], cycles_view, "rel_mse")
    view["ratio"] = view["cycles_seconds_to_same_rel_mse"] / view["seconds"]
    texels = {n: int(ref_masks[n].sum()) for n in names}
    return {"bake": {"radiosity": bake, "cycles": cycles_bake, "reference": ref_info,
                     "reference_noise_rel_mse": noise,
                     "texels": int(sum(texels.values())),
                     "error_floor": {"radiosity": min(e["rel_mse"] for e in bake),
                                     "cycles": min(c["rel_mse"] for c in cycles_bake)}},
            "view": {**view, "cycles": cycles_view, "resolution": resolution,
                     "reference": {"samples": ref_view.samples,
                                   "noise_rel_mse": ref_view.noise_rel_mse}}}


def shadow_room(args, path: Path, drawn: dict, plan: dict) -> dict:
    """The shadow-map bake of the room's lamp against Cycles' SHADOW bake (the file `path` open)."""
    import bpy
    from shadowmap import compared_texels, disagreement, kernel_visibility

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.bake.bake_targets import lightmap_targets
    from classic_bake.kernels.geometry.scene import triangle_areas
    from classic_bake.kernels.shading import direct_light as dl

    repeats = 1 if args.quick else 5  # the least of each side's repeats: both sides alike
    counts = [1, 4] if args.quick else [1, 4, 16]
    snap = bridge.snapshot(request=bridge.SnapshotRequest(lightmap_uv=UV_NAME, textures=False,
                                                          camera=False))
    light = next(li for li in snap.lights if li.name == drawn["lamp"])
    areas = triangle_areas(snap.triangles)
    targets = {}
    for k, info in enumerate(snap.objects):
        t = lightmap_targets(snap, k, plan[info.source_name])
        area = float(areas[snap.object_slice(k)].sum())
        targets[info.source_name] = (t, dl.receiver_spacing(t, area), compared_texels(t, light))
    names = list(targets)
    model = cr.direct()
    reference = cycles_lightmaps(bpy.context.scene, model, 16 if args.quick else 64, names, plan,
                                 UV_NAME, "SHADOW")[0]
    kernel_visibility(snap, targets, light, dl.DirectLightSettings())  # its warm-up
    seconds, ours = float("inf"), None
    for _ in range(repeats):
        s, ours = kernel_visibility(snap, targets, light, dl.DirectLightSettings())
        seconds = min(seconds, s)
    ours_disagree = disagreement(ours, reference, targets)
    ladder = []
    for n in counts:
        best = float("inf")
        for _ in range(repeats):
            images, _, s = cycles_lightmaps(bpy.context.scene, model, n, names, plan, UV_NAME,
                                            "SHADOW", seed=LADDER_SEED)
            best = min(best, s)
        theirs = {m: images[m][t.rows, t.cols, 0] for m, (t, _, _) in targets.items()}
        ladder.append({"samples": n, "seconds": best,
                       "disagree": disagreement(theirs, reference, targets)})
    target = max(ours_disagree, SHADOW_TARGET_DISAGREE)
    cycles_s, reached = reach(target, ladder, "disagree")
    return {"light": light.kind, "seconds": seconds, "disagree": ours_disagree,
            "compared_texels": int(sum(int(v.sum()) for _, _, v in targets.values())),
            "cycles": ladder, "cycles_target_disagree": target,
            "cycles_seconds_to_target": cycles_s, "cycles_reached": reached,
            "ratio": cycles_s / seconds, "reference_samples": 16 if args.quick else 64}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=8, help="rooms to draw (default 8)")
    parser.add_argument("--seeds", type=int, nargs="+", default=None,
                        help="the rooms' seeds (default: drawn now, printed)")
    parser.add_argument("--quick", action="store_true",
                        help="short ladders, references of few samples (a smoke run: its "
                             "errors and ratios mean little)")
    parser.add_argument("--max-ref-samples", type=int, default=2048,
                        help="cap of the converged Cycles references (default 2048)")
    parser.add_argument("--max-ref-bake-samples", type=int, default=1024,
                        help="cap of the converged Cycles lightmap bakes (default 1024)")
    parser.add_argument("--bake-cap", type=int, default=512,
                        help="the most samples Cycles' bake ladder climbs to while it has not "
                             "reached the radiosity bake's error (default 512; past it the "
                             "ratio is a lower bound)")
    parser.add_argument("--bake-target-rel-mse", type=float, default=4e-4,
                        help="the converged bake reference's halves agree to this relMSE "
                             "(its own error a quarter of it; default 4e-4)")
    args = parser.parse_args()

    from classic_bake.addon import cycles as cr

    # New seeds, each lighting (seed mod 6, bench/scenes.py) in turn: eight rooms cover all six.
    drawn = np.random.default_rng().integers(0, 10**6, args.scenes)
    seeds = args.seeds or [int(s - s % 6 + k % 6) for k, s in enumerate(drawn)]
    print("seeds:", " ".join(map(str, seeds)), flush=True)
    folder = OUT_DIR / "generated"
    folder.mkdir(parents=True, exist_ok=True)
    cr.warm_up()
    rooms = []
    for seed in seeds:
        start = time.perf_counter()
        path = folder / f"room_{seed}.blend"
        drawn, plan = prepare_room(seed, path)
        room = {**drawn, "lightmap_sizes": plan, **radiosity_room(args, path, drawn, plan)}
        room["shadowmap"] = shadow_room(args, path, drawn, plan) if drawn["lamp"] else None
        room["wall_seconds"] = time.perf_counter() - start
        rooms.append(room)
        b, v, s = room["bake"]["radiosity"][0], room["view"], room["shadowmap"]
        print(f"seed {seed:>7d} {drawn['lighting']:14s} bake relMSE {b['rel_mse']:.2e} "
              f"{b['seconds']:.2f} s x{b['ratio']:.1f} | view relMSE {v['rel_mse']:.2e} "
              f"brightness {v['brightness_ratio']:.3f} x{v['ratio']:.1f}"
              + (f" | shadow {s['disagree']:.3%} {s['seconds'] * 1e3:.0f} ms x{s['ratio']:.1f}"
                 if s else "") + f" ({room['wall_seconds']:.0f} s)", flush=True)

    def bound(reached: bool) -> str:
        return "" if reached else ">="

    rows = []
    for r in rooms:
        b, v, s = r["bake"]["radiosity"][0], r["view"], r["shadowmap"]
        rows.append([str(r["seed"]), r["lighting"], "yes" if r["closed"] else "no",
                     max(r["lightmap_sizes"].values()), r["bake"]["texels"], b["patches"],
                     b["rel_mse"], b["rel_mse_raw"], r["bake"]["error_floor"]["radiosity"],
                     r["bake"]["error_floor"]["cycles"], b["seconds"],
                     b["cycles_seconds_to_same_rel_mse"],
                     f"{bound(b['cycles_reached'])}{b['ratio']:.3g}",
                     "" if b["cycles_reached"] else f"{b['ratio_extrapolated']:.3g}",
                     v["rel_mse"], v["brightness_ratio"], f"{bound(v['cycles_reached'])}{v['ratio']:.3g}",
                     "-" if s is None else f"{s['disagree']:.3%}",
                     "-" if s is None else s["seconds"],
                     "-" if s is None else f"{bound(s['cycles_reached'])}{s['ratio']:.3g}"])
    print(format_table(["seed", "lighting", "closed", "lm size", "texels", "patches",
                        "bake relMSE", "raw", "floor", "cycles floor", "bake s", "cycles s same",
                        "bake ratio", "extrapolated", "view relMSE", "brightness", "view ratio",
                        "shadow disagree", "shadow s", "shadow ratio"], rows))

    closed = [r for r in rooms if r["closed"]]
    lit = [r for r in rooms if r["shadowmap"] is not None]
    bake_ratio = spread([r["bake"]["radiosity"][0]["ratio"] for r in rooms])
    bake_extrapolated = spread([r["bake"]["radiosity"][0]["ratio_extrapolated"] for r in rooms])
    view_ratio = spread([r["view"]["ratio"] for r in rooms])
    shadow_ratio = spread([r["shadowmap"]["ratio"] for r in lit])
    ratios = {}
    for name, found in (("cycles_vs_radiosity_bake_seconds_to_same_rel_mse", bake_ratio),
                        ("cycles_vs_radiosity_view_seconds_to_same_rel_mse", view_ratio),
                        ("cycles_vs_shadowmap_bake_seconds_to_same_disagreement", shadow_ratio)):
        for key in ("min", "median", "max"):
            if found is not None:
                ratios[f"{name}_{key}"] = found[key]
    checks = {
        "radiosity_bake_ratio_median_ge_10_and_min_ge_3":
            bake_ratio is not None and bake_ratio["median"] >= 10 and bake_ratio["min"] >= 3,
        "radiosity_bake_defaults_rel_mse_le_0.005_every_closed_room":
            all(r["bake"]["radiosity"][0]["rel_mse"] <= BAKE_TARGET_REL_MSE for r in closed),
        "radiosity_view_brightness_within_1pct_every_closed_room":
            all(abs(r["view"]["brightness_ratio"] - 1) <= BRIGHTNESS_TOLERANCE for r in closed),
        "shadowmap_bake_ratio_median_ge_20":
            shadow_ratio is not None and shadow_ratio["median"] >= 20,
        "shadowmap_disagreement_lt_0.005_every_lamp_room":
            all(r["shadowmap"]["disagree"] < SHADOW_TARGET_DISAGREE for r in lit),
    }
    figures = {
        "seeds": seeds, "quick": args.quick, "rooms": rooms, "checks": checks,
        "radiosity_bake": {
            "ratio": bake_ratio, "ratio_extrapolated": bake_extrapolated,
            "rel_mse_defaults": spread([r["bake"]["radiosity"][0]["rel_mse"] for r in rooms]),
            "closed_rooms_rel_mse_defaults_max": max(
                (r["bake"]["radiosity"][0]["rel_mse"] for r in closed), default=None),
            "error_floor": {str(r["seed"]): r["bake"]["error_floor"] for r in rooms}},
        "radiosity_view": {
            "ratio": view_ratio, "rel_mse": spread([r["view"]["rel_mse"] for r in rooms]),
            "closed_room_brightness_ratio": spread([r["view"]["brightness_ratio"]
                                                    for r in closed])},
        "shadowmap_bake": {"ratio": shadow_ratio,
                           "disagree": spread([r["shadowmap"]["disagree"] for r in lit])},
    }
    print("seeds:", " ".join(map(str, seeds)))
    print("radiosity bake ratio", bake_ratio, "(extrapolated past Cycles' ladder:",
          bake_extrapolated, ") | view ratio", view_ratio, "| shadow-map ratio", shadow_ratio)
    print("closed-room view brightness", figures["radiosity_view"]["closed_room_brightness_ratio"])
    for name, ok in checks.items():
        print(f"{'PASS' if ok else 'FAIL'} {name}")
    write_report("generated", ratios, figures, versions("bpy"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
