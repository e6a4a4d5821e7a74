"""Cycles and EEVEE rendering the environment-mapped material against the kernels' own view, on
sample_blends/env_room.blend.

    .venv/bin/python bench/envmap_eevee.py [--samples N] [--resolution W H]

The environment-mapping job bakes the mirror ball's map at its defaults and wires the material
(Show in Materials, box-projected: the room is a box). The kernels' view of the ball (the
parallax search, 3 x 3 rays per pixel) is what the wired material should show; Cycles and EEVEE
each render the scene with it. The kernels' view is compared with each render over the ball's
inner pixels (`interior_pixels`; the render is the reference of the relative error, as in the
wired-material tests), and EEVEE with Cycles. EEVEE runs on whatever OpenGL the machine has
(here Mesa's software renderer: no GPU); its first render compiles the scene's shaders, so two
renders are timed and the second is the one compared.

Writes out/bench/envmap_eevee.json: ratios {"eevee_vs_cycles_rel_mse_to_kernels": the kernels'
relMSE against EEVEE over theirs against Cycles}, figures {per renderer: relMSE, median pixel
relMSE, seconds; EEVEE against Cycles}, out/bench/envmap_eevee.png (kernels | Cycles | EEVEE) and
out/bench/envmap_eevee.npz (the three images and the mask).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import OUT_DIR, versions, write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENE = ROOT / "sample_blends" / "env_room.blend"
MIRROR = "MirrorSphere"
# Twice the wired-material test's size each way: the ball's ~800 inner pixels, most of them the
# checkered floor's reflection, where pixel filters differ most.
RESOLUTION = (192, 144)
# Samples per pixel of both renderers (the material is an emission look-up: what noise there is
# comes from the pixel filter's samples over the ball's changing reflection).
SAMPLES = 64
# The kernels' view: rays per pixel side (as the wired-material test of env_room).
SUPERSAMPLE = 3
# EEVEE's pixel filter radius: the nearest to Cycles' 1-px box (the matched models'). At EEVEE's
# default 1.5 px the ball's median pixel came out 1.7% brighter than Cycles' (its wider filter
# brings the bright ceiling in); at 0.5 px 0.2% darker (96 x 72, measured).
EEVEE_FILTER_PX = 0.5


def eevee_render(scene, samples: int, resolution) -> tuple[np.ndarray, float]:
    """(H, W, 3) float32 linear EEVEE render of the scene camera (row 0 top), and the seconds of
    the render alone; the scene left as it was."""
    import bpy

    from classic_bake.addon.cycles.runner import _render_result, exr_output
    from classic_bake.addon.cycles.settings import SettingsLog
    from classic_bake.kernels.measure.exr import read_exr

    log = SettingsLog()
    try:
        log.set(scene.render, "engine", "BLENDER_EEVEE")
        log.set(scene.eevee, "taa_render_samples", int(samples))
        log.set(scene.render, "filter_size", EEVEE_FILTER_PX)
        with exr_output(scene, log, resolution) as folder:
            start = time.perf_counter()
            bpy.ops.render.render(write_still=False, scene=scene.name)
            seconds = time.perf_counter() - start
            path = str(Path(folder) / "render.exr")
            _render_result().save_render(path, scene=scene)
            return read_exr(path)[:, :, :3].copy(), seconds
    finally:
        log.restore()


def errors(test: np.ndarray, reference: np.ndarray, pixels: np.ndarray) -> dict:
    """relMSE over `pixels` and the median pixel's (mean over channels)."""
    from classic_bake.kernels.measure.metrics import REL_MSE_EPS, rel_mse

    t, r = test[pixels], reference[pixels]
    per_pixel = ((t - r) ** 2 / (r ** 2 + REL_MSE_EPS)).mean(axis=1)
    return {"rel_mse": rel_mse(t[:, None], r[:, None]),
            "median_pixel_rel_mse": float(np.median(per_pixel))}


def strip(path: Path, images: list[np.ndarray]) -> None:
    """Side by side, as the pipeline's tone-mapped preview PNG."""
    from classic_bake.pipeline.images import write_preview_png

    write_preview_png(path, np.concatenate(images, axis=1))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=SAMPLES)
    parser.add_argument("--resolution", type=int, nargs=2, default=RESOLUTION)
    args = parser.parse_args()
    resolution = tuple(args.resolution)

    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.jobs.envmap import EnvMapOutputs, envmap_job
    from classic_bake.kernels.envmap.envmap import EnvMapSettings
    from classic_bake.kernels.measure.object_mask import interior_pixels
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.trace.settings import auto_settings

    bpy.ops.wm.open_mainfile(filepath=str(SCENE), load_ui=False, use_scripts=False)
    scene = bpy.context.scene
    snap = bridge.snapshot(resolution=resolution)
    tracer = auto_settings(snap, adaptive=0, supersample=SUPERSAMPLE)
    start = time.perf_counter()
    summary = drain(envmap_job(snap, EnvMapSettings(), tracer, resolution, mips=0,
                               outputs=EnvMapOutputs(wire=True, box_projection=True)))
    kernel_seconds = time.perf_counter() - start
    kernels = summary.render
    mirror = next(k for k, o in enumerate(snap.objects) if o.source_name == MIRROR)
    pixels = interior_pixels(snap, resolution, mirror)

    cr.warm_up()
    cycles, cycles_seconds = cr.render_camera(scene, cr.whitted(tracer.max_depth), args.samples,
                                              resolution=resolution)
    _, eevee_first_seconds = eevee_render(scene, args.samples, resolution)
    eevee, eevee_seconds = eevee_render(scene, args.samples, resolution)

    figures = {
        "scene": SCENE.name, "resolution": list(resolution), "samples": args.samples,
        "ball_pixels": int(pixels.sum()), "kernels_seconds": kernel_seconds,
        "cycles": {**errors(kernels, cycles, pixels), "seconds": cycles_seconds},
        "eevee": {**errors(kernels, eevee, pixels), "seconds": eevee_seconds,
                  "first_render_seconds": eevee_first_seconds},
        "eevee_vs_cycles": errors(eevee, cycles, pixels),
        "compared": "the kernels' view against each renderer's render of the wired material "
                    "(the reference), over the ball's inner pixels",
    }
    ratios = {"eevee_vs_cycles_rel_mse_to_kernels":
              figures["eevee"]["rel_mse"] / max(figures["cycles"]["rel_mse"], 1e-30)}
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    strip(OUT_DIR / "envmap_eevee.png", [kernels, cycles, eevee])
    np.savez_compressed(OUT_DIR / "envmap_eevee.npz", kernels=kernels, cycles=cycles,
                        eevee=eevee, pixels=pixels)
    for name in ("cycles", "eevee"):
        row = figures[name]
        print(f"{name:7s} relMSE {row['rel_mse']:.3g}  median pixel "
              f"{row['median_pixel_rel_mse']:.3g}  {row['seconds']:.2f} s")
    print(f"EEVEE against Cycles: relMSE {figures['eevee_vs_cycles']['rel_mse']:.3g}  median "
          f"pixel {figures['eevee_vs_cycles']['median_pixel_rel_mse']:.3g}")
    write_report("envmap_eevee", ratios, figures, versions("bpy"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
