"""Radiosity against Cycles on rooms generated from seeds (bench/scenes.py), not on one sample.

    .venv/bin/python bench/generated.py [--scenes 8] [--seeds 11 12 ...] [--quick]

Each run draws new seeds (printed; `--seeds` rebuilds any scene) unless given. Per room: the
radiosity solve and its camera view at the defaults, Cycles' render of the matched model
(`radiosity`, the world lighting where the room opens to it) at a ladder of samples, both against
a converged Cycles render (cached in out/cache). Reported per room: the view's relMSE, its mean
brightness over Cycles', the seconds, and the seconds Cycles needs to reach the same error over
ours; over all rooms: the minimum, median and maximum ratio and error, and the closed rooms'
brightness ratios. Writes out/bench/generated.json.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import OUT_DIR, seconds_to_reach, versions, write_report  # noqa: E402
from scenes import build_room  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=8, help="rooms to draw (default 8)")
    parser.add_argument("--seeds", type=int, nargs="+", default=None,
                        help="the rooms' seeds (default: drawn now, printed)")
    parser.add_argument("--quick", action="store_true", help="fewer samples (smoke run)")
    parser.add_argument("--max-ref-samples", type=int, default=2048)
    args = parser.parse_args()

    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.radiosity.settings import RadiositySettings
    from classic_bake.kernels.radiosity.solve import solve_radiosity
    from classic_bake.kernels.radiosity.view import render_steps

    seeds = args.seeds or [int(s) for s in np.random.default_rng().integers(0, 10**6, args.scenes)]
    print("seeds:", " ".join(map(str, seeds)))
    folder = OUT_DIR / "generated"
    folder.mkdir(parents=True, exist_ok=True)
    counts = [4, 16, 64] if args.quick else [4, 8, 16, 32, 64, 128, 256]
    resolution = (40, 30) if args.quick else (80, 60)
    cr.warm_up()
    rooms = []
    for seed in seeds:
        path = folder / f"room_{seed}.blend"
        drawn = build_room(seed, path)
        model = cr.radiosity(world_lighting=not drawn["closed"])
        ref = cr.reference(path, model, "render", resolution=resolution,
                           samples=256 if args.quick else None, max_samples=args.max_ref_samples,
                           target_rel_mse=2e-4)
        bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
        snap = bridge.snapshot(resolution=resolution)
        start = time.perf_counter()
        solution = solve_radiosity(snap, RadiositySettings())
        view = drain(render_steps(snap, solution, resolution))
        seconds = time.perf_counter() - start
        error = rel_mse(view, ref.image)
        ladder = []
        for n in counts:
            image, spent = cr.render_camera(bpy.context.scene, model, n, resolution=resolution)
            ladder.append({"samples": n, "seconds": spent, "rel_mse": rel_mse(image, ref.image)})
        reach = seconds_to_reach(error, ladder)
        room = {**drawn, "seconds": seconds, "rel_mse": error,
                "brightness_ratio": float(view.mean() / max(ref.image.mean(), 1e-12)),
                "patches": solution.stats["patches"], "solver": solution.stats["solver"],
                "cycles": ladder, "cycles_seconds_to_same_error": reach,
                "ratio": None if reach is None else reach / seconds,
                "reference": {"samples": ref.samples, "noise_rel_mse": ref.noise_rel_mse}}
        rooms.append(room)
        print(f"seed {seed:>7d} {drawn['lighting']:14s} relMSE {error:.2e} brightness "
              f"{room['brightness_ratio']:.3f} {seconds:6.2f} s ratio "
              f"{room['ratio'] if room['ratio'] is not None else float('nan'):.2f}")
    ratios_found = [r["ratio"] for r in rooms if r["ratio"] is not None]
    errors = [r["rel_mse"] for r in rooms]
    closed = [r["brightness_ratio"] for r in rooms if r["closed"]]

    def spread(values):
        return None if not values else {"min": float(np.min(values)),
                                        "median": float(np.median(values)),
                                        "max": float(np.max(values))}

    ratios = {"cycles_vs_radiosity_view_seconds_to_same_rel_mse_median":
              spread(ratios_found)["median"] if ratios_found else None,
              "cycles_vs_radiosity_view_seconds_to_same_rel_mse_min":
              spread(ratios_found)["min"] if ratios_found else None}
    figures = {"seeds": seeds, "resolution": resolution, "rooms": rooms,
               "ratio": spread(ratios_found), "rel_mse": spread(errors),
               "closed_room_brightness_ratio": spread(closed)}
    print("ratio", figures["ratio"], "relMSE", figures["rel_mse"], "closed-room brightness",
          figures["closed_room_brightness_ratio"])
    write_report("generated", ratios, figures, versions("bpy"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
