"""Normal maps made (issue 40): a 4096 x 4096 height -> normal map against the machine's memory
bandwidth measured in the same run, and MikkTSpace tangents of a ~1M-corner mesh against
Blender's own `Mesh.calc_tangents`.

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

Writes out/bench/normalmap.json. `--quick` runs 256^2 maps and a 100 x 100 grid (a smoke run).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import best_of, format_table, versions, write_report  # noqa: E402

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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small sizes (smoke run)")
    args = parser.parse_args()
    repeats = 1 if args.quick else 3
    started = time.perf_counter()
    bandwidth = copy_bandwidth(16 if args.quick else COPY_MIB, repeats)
    maps = map_figures(256 if args.quick else 4096, bandwidth, repeats)
    tangents = tangent_figures(100 if args.quick else 500, repeats)
    print(f"copy bandwidth {bandwidth / 1e9:.2f} GB/s")
    print(format_table(["case", "size", "seconds", "Mtexel/s", "of bandwidth"],
                       [[r["case"], r["size"], r["seconds"], r["texels_per_s"] / 1e6,
                         r["fraction_of_copy_bandwidth"]] for r in maps]))
    print(f"tangents, {tangents['corners']} corners: kernel {tangents['kernel_seconds']:.3f} s, "
          f"calc_tangents {tangents['calc_tangents_seconds']:.3f} s, max difference "
          f"{tangents['max_tangent_difference']:.2g}, {tangents['sign_mismatches']} signs differ")
    ratios = {f"map_fraction_of_copy_bandwidth/{r['case']}": r["fraction_of_copy_bandwidth"]
              for r in maps}
    ratios["calc_tangents_vs_kernel_seconds"] = (tangents["calc_tangents_seconds"]
                                                 / tangents["kernel_seconds"])
    import bpy

    figures = {"copy_bandwidth_bytes_per_s": bandwidth, "maps": maps, "tangents": tangents,
               "quick": args.quick, "seconds": time.perf_counter() - started}
    path = write_report("normalmap", ratios, figures,
                        {**versions(), "blender": bpy.app.version_string})
    print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
