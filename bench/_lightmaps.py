"""Lightmap bakes the radiosity benches share (bench/radiosity.py, bench/generated.py).

Cycles bakes the SAME lightmap texels as the radiosity bake: DIFFUSE with colour into the same
xatlas lightmap UVs, one call per lightmap size (Cycles bakes one image size per call). Its texels
are rho E / pi, ours B / pi of a non-emitting surface: the same radiance. A DIFFUSE bake leaves
out emission, so emitters are left out of the comparison. Errors are the relative MSE over the
texels both bakes cover.
"""

from __future__ import annotations

import time
from pathlib import Path

from _report import stack_texels

# A seed for Cycles' ladder runs no converged reference uses (references start at the model's
# seed, 0, and count up): a ladder rung and the reference share no samples, so the rung's error
# is not underestimated.
LADDER_SEED = 7919


def cycles_lightmaps(scene, model, samples: int, names, plan: dict, uv_name: str,
                     bake_type: str = "DIFFUSE", seed: int | None = None) -> tuple[dict, dict, float]:
    """Cycles' bake of the objects `names` into their lightmaps at the sizes of `plan`
    ({name: texels per side}). Returns ({name: (H, W, 3)}, {name: (H, W) bool}, seconds)."""
    from classic_bake.addon import cycles as cr

    images, masks, seconds = {}, {}, 0.0
    for size in sorted({plan[n] for n in names}):
        group = [n for n in names if plan[n] == size]
        got, secs, covered = cr.bake_lightmaps(scene, model, samples, group, uv_name, size,
                                               bake_type, seed=seed)
        images.update(got)
        masks.update(covered)
        seconds += secs
    return images, masks, seconds


def cycles_lightmap_reference(path: Path, model, names, plan: dict, uv_name: str, *,
                              samples: int | None, max_samples: int,
                              target_rel_mse: float) -> tuple[dict, dict, dict]:
    """The converged Cycles DIFFUSE bake of `names` from the .blend `path` (which must already hold
    the lightmap UV layers `uv_name`), one cached reference per lightmap size (`cr.reference`:
    samples None chooses the count from the bake's noise). Opens `path` on a cache miss.
    Returns ({name: image}, {name: mask}, {size: {"samples", "noise_rel_mse", "seconds",
    "cache_hit", "texels"}})."""
    from classic_bake.addon import cycles as cr

    images, masks, info = {}, {}, {}
    for size in sorted({plan[n] for n in names}):
        group = tuple(n for n in names if plan[n] == size)
        ref = cr.reference(path, model, "bake", samples=samples, max_samples=max_samples,
                           target_rel_mse=target_rel_mse,
                           bake=cr.BakeSpec(objects=group, uv_layer=uv_name, size=size))
        images.update(ref.images)
        masks.update(ref.masks)
        info[size] = {"samples": ref.samples, "noise_rel_mse": ref.noise_rel_mse,
                      "seconds": ref.seconds, "cache_hit": ref.cache_hit,
                      "texels": int(sum(int(m.sum()) for m in ref.masks.values()))}
    return images, masks, info


def reference_noise(info: dict) -> float | None:
    """The estimated relative MSE of a `cycles_lightmap_reference` against the converged bake,
    over all its texels (None when a fixed sample count made it)."""
    parts = list(info.values())
    if not parts or any(p["noise_rel_mse"] is None for p in parts):
        return None
    return float(sum(p["noise_rel_mse"] * p["texels"] for p in parts)
                 / max(sum(p["texels"] for p in parts), 1))


def radiosity_lightmaps(scene, settings, objects, sizes: dict, padding: int = 2):
    """Solve `scene` (a snapshot carrying the lightmap UVs) with `settings` and bake the objects
    `objects` (indices) at `sizes` ({index: texels}), timed together (the BVH, the solve, the
    bake). Returns ({name: lightmap}, {name: mask}, seconds, RadiosityResult)."""
    from classic_bake.kernels.geometry.bvh import BVH
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.radiosity.lightmap import bake_steps
    from classic_bake.kernels.radiosity.solve import solve_radiosity

    start = time.perf_counter()
    bvh = BVH.build(scene.triangles)
    result = solve_radiosity(scene, settings, bvh)
    bakes = drain(bake_steps(scene, result, objects, sizes, padding))
    seconds = time.perf_counter() - start
    images = {scene.objects[k].source_name: b.lightmap for k, b in bakes.items()}
    masks = {scene.objects[k].source_name: b.lightmap_mask for k, b in bakes.items()}
    return images, masks, seconds, result


def texel_rel_mse(images: dict, masks: dict, ref_images: dict, ref_masks: dict, names) -> float:
    """Relative MSE of `images` against the reference over the texels both cover, every object of
    `names` together."""
    from classic_bake.kernels.measure.metrics import rel_mse

    valid = {n: masks[n] & ref_masks[n] for n in names}
    return rel_mse(stack_texels(images, valid, names), stack_texels(ref_images, valid, names))
