"""Normal maps made (issue 40): a 4096 x 4096 height -> normal map against the machine's memory
bandwidth measured in the same run, MikkTSpace tangents of a ~1M-corner mesh against Blender's
own `Mesh.calc_tangents`, and the high -> low bake against Cycles' NORMAL bake at equal angular
error.

    .venv/bin/python bench/normalmap.py [--quick]

* **Height -> normal map.** A 4096^2 float height image at its own size (the kernel's texel path:
  central differences, normalisation, encoding to colours) and a procedural pattern (the orange
  peel, evaluated per texel). The least memory traffic such a map needs is reading the heights
  once (8 bytes a texel) and writing the normals and the colours once (12 + 12 bytes); divided by
  the map's seconds that is the kernel's effective bandwidth, reported as a fraction of the copy
  bandwidth `np.copyto` reaches on a 256 MiB array in the same run (read + write counted).
* **Tangents.** A 500 x 500 quad grid bent into a wave (250 000 quads, 1 000 000 corners, smooth
  normals, one UV map with a mirrored half): the kernels' `mikktspace_tangents` on arrays from
  `foreach_get` against `Mesh.calc_tangents` on the same mesh, and the largest difference.
* **High -> low.** A smooth 12-sided cylinder (2 m) under a copy with a Subdivision Surface of
  level 6 and a Displace modifier (a Clouds relief of 2 cm, features a few texels across), baked
  into the cylinder's UV map at 512^2 (cage 0.1 m, max ray 1 m). The reference is the texel's box
  average of the high normals: our own bake at 8x the size (4096^2, 64 samples per texel on a
  regular grid), the unit normals of each texel's 8 x 8 block averaged. Cycles' converged bake is
  not used: it jitters each sample within the texel but folds it back into the one high triangle
  its centre ray hit (`bake_clamp_mirror_repeat`), so on a high mesh finer than the texels it
  converges to that triangle's average, not the texel's (its error against the box average is
  reported). Ours runs 1 (what the job does: the texel's centre, as Cycles' first sample), 2 x 2
  and 4 x 4 samples (the bench bakes at 2x and 4x the size and averages blocks), each timed from
  Blender's objects (evaluated meshes, MikkTSpace frames, BVH, rays); Cycles' NORMAL bake with
  Selected to Active runs 1, 2, 4, ... 256 samples (the bake operator's seconds, scene export
  included). Error: per-texel angle to the reference over the chart texels, mean and p99. For
  each of our rungs the seconds Cycles needs for the same mean angle are interpolated on its
  ladder (`_report.seconds_to_reach`); the ratio is those over ours.

Writes out/bench/normalmap.json. `--quick` runs 256^2 maps, a 100 x 100 grid and a 64^2
high -> low bake of a level-4 high mesh (a smoke run).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from _report import (  # noqa: E402
    best_of,
    format_table,
    versions,
    write_report,
)

COPY_MIB = 256  # the bandwidth probe's array
# Bytes per texel a height -> normal map must move at least: float64 height in, float32 normal
# and float32 colour out.
MAP_BYTES_PER_TEXEL = 8 + 12 + 12


def copy_bandwidth(mib: int, repeats: int = 3) -> float:
    """Bytes per second `np.copyto` moves between two arrays of `mib` MiB (read + write)."""
    src = np.ones(mib * 2**20 // 8, np.float64)
    dst = np.empty_like(src)
    seconds = best_of(lambda: np.copyto(dst, src), repeats)
    return 2.0 * src.nbytes / seconds


def map_figures(size: int, bandwidth: float, repeats: int) -> list[dict]:
    from classic_bake.kernels.normalmap.from_height import NormalMapSettings, normal_map
    from classic_bake.kernels.normalmap.heights import ImageHeight, ProceduralHeight

    rng = np.random.default_rng(40)
    image = ImageHeight(rng.random((size, size)).astype(np.float32))
    settings = NormalMapSettings(size=size, strength=0.01)
    rows = []
    for case, source in (("image", image), ("orange_peel", ProceduralHeight("orange_peel"))):
        seconds = best_of(lambda s=source: normal_map(s, settings), repeats)
        effective = MAP_BYTES_PER_TEXEL * size * size / seconds
        rows.append({"case": case, "size": size, "seconds": seconds,
                     "texels_per_s": size * size / seconds,
                     "effective_bytes_per_s": effective,
                     "fraction_of_copy_bandwidth": effective / bandwidth})
    return rows


def wave_grid(n: int):
    """A bpy mesh: n x n quads on [0, 1]^2 bent into a wave, smooth, UVs mirrored for u > 1/2."""
    import bpy

    x, y = np.meshgrid(np.linspace(0.0, 1.0, n + 1), np.linspace(0.0, 1.0, n + 1))
    z = 0.1 * np.sin(6.0 * x) * np.cos(4.0 * y)
    verts = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    a = (i * (n + 1) + j).ravel()
    quads = np.stack([a, a + 1, a + n + 2, a + n + 1], axis=1)
    mesh = bpy.data.meshes.new("Wave")
    mesh.vertices.add(len(verts))
    mesh.vertices.foreach_set("co", verts.astype(np.float32).ravel())
    mesh.loops.add(quads.size)
    mesh.loops.foreach_set("vertex_index", quads.astype(np.int32).ravel())
    mesh.polygons.add(len(quads))
    mesh.polygons.foreach_set("loop_start", np.arange(0, quads.size, 4, dtype=np.int32))
    mesh.update(calc_edges=True)
    mesh.shade_smooth()
    corner = verts[quads.ravel()]
    uv = np.stack([np.abs(corner[:, 0] - 0.5) * 2.0, corner[:, 1]], axis=1)  # mirrored at 1/2
    mesh.uv_layers.new(name="UVMap").uv.foreach_set("vector", uv.astype(np.float32).ravel())
    return mesh


def tangent_figures(n: int, repeats: int) -> dict:
    from classic_bake.kernels.normalmap.mikktspace import mikktspace_tangents

    mesh = wave_grid(n)

    def get(collection, attribute, width, dtype=np.float32):
        out = np.empty(len(collection) * width, dtype)
        collection.foreach_get(attribute, out)
        return out.reshape(-1, width) if width > 1 else out

    arrays = (get(mesh.vertices, "co", 3), get(mesh.loops, "vertex_index", 1, np.int32),
              get(mesh.corner_normals, "vector", 3), get(mesh.uv_layers["UVMap"].uv, "vector", 2),
              get(mesh.polygons, "loop_start", 1, np.int32),
              get(mesh.polygons, "loop_total", 1, np.int32))
    ours_s = best_of(lambda: mikktspace_tangents(*arrays), repeats)
    blender_s = best_of(lambda: mesh.calc_tangents(uvmap="UVMap"), repeats)
    ours = mikktspace_tangents(*arrays)
    mesh.calc_tangents(uvmap="UVMap")
    theirs = get(mesh.loops, "tangent", 3)
    signs = get(mesh.loops, "bitangent_sign", 1)
    return {"corners": len(mesh.loops), "kernel_seconds": ours_s, "calc_tangents_seconds": blender_s,
            "max_tangent_difference": float(np.abs(ours.tangents - theirs).max()),
            "sign_mismatches": int((ours.signs != signs).sum())}


# The high -> low pair and bake (see the module docstring).
PAIR_SIZE, PAIR_LEVELS, PAIR_RELIEF_M, PAIR_NOISE_SCALE = 512, 6, 0.02, 0.05
PAIR_CAGE_M, PAIR_MAX_RAY_M = 0.1, 1.0
PAIR_REFERENCE_K = 8  # reference samples per texel: K x K
PAIR_KERNEL_K = (1, 2, 4)  # our rungs, K x K samples per texel
PAIR_CYCLES_SAMPLES = (1, 2, 4, 8, 16, 32, 64, 128, 256)
PAIR_CYCLES_CONVERGED = 1024  # samples of Cycles' converged bake, the second reference
# A Cycles rung within this share of our mean angle counts as reaching it (its first sample is the
# texel's centre, as ours: equal to a few thousandths of a degree, either side).
REACH_TOLERANCE = 0.01


def unit(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(length, 1e-12)


def block_average(normals: np.ndarray, mask: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """A (kS, kS, 3) map of unit normals with its chart mask (kS, kS) averaged over k x k blocks:
    ((S, S, 3) unit normals of the blocks' covered texels, (S, S) how many were covered)."""
    size = normals.shape[0] // k
    weights = mask.reshape(size, k, size, k).astype(np.float64)
    total = (normals.reshape(size, k, size, k, 3) * weights[..., None]).sum(axis=(1, 3))
    return unit(total), weights.sum(axis=(1, 3))


def cycles_seconds_to(error: float, cycles: list[dict], metric: str) -> float | None:
    """Cycles' seconds to reach `error` in `metric` on its ladder (rows by samples): the fastest
    rung within REACH_TOLERANCE of it, or log-log interpolated between consecutive rungs whose
    error falls through it; None: never. (Cycles' error against the box average grows with its
    samples, so `_report.seconds_to_reach`, which takes the ladder as falling, does not fit.)"""
    times = [r["seconds"] for r in cycles if r[metric] <= error * (1.0 + REACH_TOLERANCE)]
    for a, b in zip(cycles, cycles[1:], strict=False):
        if b[metric] < error < a[metric]:
            f = (np.log(error) - np.log(a[metric])) / (np.log(b[metric]) - np.log(a[metric]))
            times.append(float(np.exp(np.log(a["seconds"])
                                      + f * (np.log(b["seconds"]) - np.log(a["seconds"])))))
    return min(times) if times else None


def high_to_low_figures(quick: bool, repeats: int) -> dict:
    """Our high -> low bake and Cycles' against the box-averaged reference and against Cycles'
    converged bake (module docstring)."""
    import bpy

    from classic_bake.addon.bridge import normal_maps
    from classic_bake.kernels.normalmap.from_height import NormalMapSettings
    from classic_bake.kernels.normalmap.high_to_low import HighToLowSettings, high_to_low_steps
    from classic_bake.kernels.progress import drain

    sys.path.insert(0, str(ROOT / "tests" / "support"))
    from normalmap_pairs import cycles_normal_bake, low_and_high

    size = 64 if quick else PAIR_SIZE
    ladder = (1, 2) if quick else PAIR_KERNEL_K
    reference_k = 4 if quick else PAIR_REFERENCE_K
    samples = PAIR_CYCLES_SAMPLES[:5] if quick else PAIR_CYCLES_SAMPLES
    bpy.ops.wm.read_factory_settings(use_empty=True)
    low, high = low_and_high("cylinder", levels=4 if quick else PAIR_LEVELS,
                             displace=PAIR_RELIEF_M, noise_scale=PAIR_NOISE_SCALE)
    depsgraph = bpy.context.evaluated_depsgraph_get()
    bake = HighToLowSettings(cage=PAIR_CAGE_M, max_ray=PAIR_MAX_RAY_M)

    def ours(k: int):
        """Our bake at k x k samples per texel, from Blender's objects: ((S, S, 3) unit normals,
        the chart mask (k = 1) or covered samples per texel, misses)."""
        made_low, _ = normal_maps.low_mesh(low, depsgraph, None)
        made_high = normal_maps.high_mesh(high, depsgraph)
        made = drain(high_to_low_steps(made_low, made_high,
                                       NormalMapSettings(size=k * size, padding=0), bake))
        if k == 1:
            return made.normals, made.mask, made.misses
        normals, covered = block_average(made.normals, made.mask, k)
        return normals, covered, made.misses

    def cycles_bake(count: int, seed: int = 1):
        pixels, seconds = cycles_normal_bake(low, high, size, PAIR_CAGE_M, PAIR_MAX_RAY_M, count,
                                             seed=seed)
        return unit(2.0 * pixels[..., :3].astype(np.float64) - 1.0), seconds

    start = time.perf_counter()
    box, box_covered, _ = ours(reference_k)
    box_seconds = time.perf_counter() - start
    _, chart, _ = ours(1)
    converged_samples = 64 if quick else PAIR_CYCLES_CONVERGED
    converged, converged_seconds = cycles_bake(converged_samples, seed=2)  # another seed
    high_triangles = len(normal_maps.high_mesh(high, depsgraph).triangles)

    def error(normals: np.ndarray) -> dict:
        out = {}
        for prefix, reference in (("", box), ("cycles_ref_", converged)):
            cos = np.clip((unit(normals[chart]) * reference[chart]).sum(-1), -1.0, 1.0)
            angle = np.degrees(np.arccos(cos))
            out |= {f"{prefix}mean_deg": float(angle.mean()),
                    f"{prefix}p99_deg": float(np.percentile(angle, 99))}
        return out

    kernel_seconds = {k: float("inf") for k in ladder}
    cycles_seconds = {s: float("inf") for s in samples}
    kernel_maps, cycles_maps = {}, {}
    for _ in range(repeats):  # alternately, so that a passing load hurts both alike
        for k in ladder:
            start = time.perf_counter()
            kernel_maps[k] = ours(k)
            kernel_seconds[k] = min(kernel_seconds[k], time.perf_counter() - start)
        for s in samples:
            cycles_maps[s], seconds = cycles_bake(s)
            cycles_seconds[s] = min(cycles_seconds[s], seconds)
    cycles = [{"samples": s, "seconds": cycles_seconds[s], **error(cycles_maps[s])}
              for s in samples]
    kernel = []
    for k in ladder:
        row = {"setting": f"{k} x {k}", "samples_per_texel": k * k, "seconds": kernel_seconds[k],
               "misses": kernel_maps[k][2], **error(kernel_maps[k][0])}
        for prefix in ("", "cycles_ref_"):
            reach = cycles_seconds_to(row[f"{prefix}mean_deg"], cycles, f"{prefix}mean_deg")
            row[f"{prefix}cycles_seconds_to_same_mean_deg"] = reach
            row[f"{prefix}ratio"] = None if reach is None else reach / row["seconds"]
        kernel.append(row)
    return {"size": size, "chart_texels": int(chart.sum()), "high_triangles": high_triangles,
            "cage_m": PAIR_CAGE_M, "max_ray_m": PAIR_MAX_RAY_M, "relief_m": PAIR_RELIEF_M,
            "reference": f"our bake at {reference_k * size}^2, {reference_k} x {reference_k} "
                         "blocks averaged (the texel's box average)",
            "reference_seconds": box_seconds,
            "reference_chart_texels_covered": int((box_covered[chart] > 0).sum()),
            "cycles_reference": f"Cycles' NORMAL bake at {converged_samples} samples (seed 2)",
            "cycles_reference_seconds": converged_seconds,
            "cycles_reference_vs_box_mean_deg": error(converged)["mean_deg"],
            "kernel": kernel, "cycles": cycles}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke run)")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    started = time.perf_counter()
    bandwidth = copy_bandwidth(16 if args.quick else COPY_MIB, repeats)
    maps = map_figures(256 if args.quick else 4096, bandwidth, repeats)
    tangents = tangent_figures(100 if args.quick else 500, repeats)
    pair = high_to_low_figures(args.quick, 1 if args.quick else 2)
    print(f"copy bandwidth {bandwidth / 1e9:.2f} GB/s")
    print(format_table(["case", "size", "seconds", "Mtexel/s", "of bandwidth"],
                       [[r["case"], r["size"], r["seconds"], r["texels_per_s"] / 1e6,
                         r["fraction_of_copy_bandwidth"]] for r in maps]))
    print(f"tangents, {tangents['corners']} corners: kernel {tangents['kernel_seconds']:.3f} s, "
          f"calc_tangents {tangents['calc_tangents_seconds']:.3f} s, max difference "
          f"{tangents['max_tangent_difference']:.2g}, {tangents['sign_mismatches']} signs differ")
    print(f"high -> low, {pair['size']}^2 ({pair['chart_texels']} chart texels, "
          f"{pair['high_triangles']} high triangles); error against {pair['reference']} "
          f"(box) and against {pair['cycles_reference']} (Cycles'; "
          f"{pair['cycles_reference_vs_box_mean_deg']:.3f} degrees from the box average):")

    def reach(r, prefix):
        seconds = r[f"{prefix}cycles_seconds_to_same_mean_deg"]
        return "never" if seconds is None else f"{seconds:.3g} s = {r[f'{prefix}ratio']:.3g}x"

    print(format_table(
        ["bake", "seconds", "box mean", "box p99", "Cycles' mean", "Cycles' p99",
         "Cycles to box mean", "Cycles to Cycles' mean"],
        [[f"ours {r['samples_per_texel']} spp", r["seconds"], r["mean_deg"], r["p99_deg"],
          r["cycles_ref_mean_deg"], r["cycles_ref_p99_deg"], reach(r, ""),
          reach(r, "cycles_ref_")] for r in pair["kernel"]]
        + [[f"Cycles {r['samples']} spp", r["seconds"], r["mean_deg"], r["p99_deg"],
            r["cycles_ref_mean_deg"], r["cycles_ref_p99_deg"], "", ""] for r in pair["cycles"]]))
    ratios = {f"map_fraction_of_copy_bandwidth/{r['case']}": r["fraction_of_copy_bandwidth"]
              for r in maps}
    for r in pair["kernel"]:
        for prefix, reference in (("", "box"), ("cycles_ref_", "cycles_ref")):
            if r[f"{prefix}ratio"] is not None:
                ratios[f"cycles_vs_kernel_seconds_to_same_mean_angle/high_to_low_{reference}_"
                       f"{r['samples_per_texel']}spp"] = r[f"{prefix}ratio"]
    ratios["calc_tangents_vs_kernel_seconds"] = (tangents["calc_tangents_seconds"]
                                                 / tangents["kernel_seconds"])
    import bpy

    figures = {"copy_bandwidth_bytes_per_s": bandwidth, "maps": maps, "tangents": tangents,
               "high_to_low": pair,
               "quick": args.quick, "seconds": time.perf_counter() - started}
    path = write_report("normalmap", ratios, figures,
                        {**versions(), "blender": bpy.app.version_string})
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
