"""The batch command's speed-up of 2 workers over 1, on the sample scenes, and the overhead of a
tiled radiosity bake against one process.

    .venv/bin/python bench/batch.py [--quick] [--resolution W H] [--tiles N]

Runs `python -m classic_bake batch` over every sample scene x (trace, bump, texture: each applies
to every sample; a shadow map refuses the Cornell box, which has no lamp) with
--workers 1 and --workers 2 (--force: nothing skipped), alternately, and reports the ratio of their
wall-clock seconds (`one_vs_two_workers_seconds`: above 1, two workers are faster). Each run is a
process of its own, so the batch pays each run's start-up (importing bpy, opening the scene) and
two workers overlap it. --quick: two scenes, one technique, 16 x 12, one repeat.

Tiles: radiosity of the Cornell box, once as one run and once as `--tile prepare`, `--tile K/N`
for K = 1..N one after the other and `merge` (--tiles N, default 4), all in this process (each
part opens the scene as a worker would) after an untimed warm-up run, alternately, best of the
repeats; the merged files are
checked equal to the one run's. `tiled_radiosity_overhead` is the tiled parts' seconds (their
sum, as the merged metrics.json adds them, plus the merge) over the one run's: above 1 by what
splitting costs (each tile opens the scene, makes its snapshot and reads the solution; the
prepare step does the solve and the camera view once). `tiled_gather_overhead` is the lightmap
gather alone: the N tiles' `radiosity` seconds (snapshot, solution read, bake) summed, over one
`--tile 1/1` run's from the same prepared solution (the whole gather in one process).
--quick: 32-texel lightmaps, 60 patches, 24 x 18, two tiles.
Writes out/bench/batch.json.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import format_table, versions, write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_blends"


def jobs_file(folder: Path, scenes: list[Path], techniques: list[str], size) -> Path:
    path = folder / "jobs.toml"
    listed = ", ".join(f"'{s}'" for s in scenes)
    path.write_text(f"out = 'out'\nresolution = [{size[0]}, {size[1]}]\n\n[[job]]\n"
                    f"scenes = [{listed}]\ntechniques = {techniques!r}\n")
    return path


def run_batch(jobs: Path, workers: int) -> float:
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "classic_bake", "batch", str(jobs), "--force",
                           "--quiet", "--workers", str(workers)], capture_output=True, text=True)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"batch failed: {done.stderr.strip()}")
    return seconds


def tiled_radiosity(folder: Path, tiles: int, options: list[str], repeats: int) -> dict:
    """Seconds of one radiosity run against the same bake as tiles (see the module docstring)."""
    import json
    import shutil

    import numpy as np

    from classic_bake.kernels.measure.exr import read_exr
    from classic_bake.pipeline.cli import main as cli

    scene = str(SAMPLES / "cornell_box.blend")

    def run(out: Path, *extra) -> dict:
        if cli(["radiosity", scene, "--out", str(out), "--quiet", *options, *extra]) != 0:
            raise SystemExit(f"radiosity {' '.join(extra)} failed")
        return json.loads((out / "metrics.json").read_text()) if not extra else {}

    run(folder / "warm-up")  # the first run in a process pays its imports: not timed
    one, tiled = {"total": [], "gather": []}, {"total": [], "gather": []}
    for k in range(repeats):
        single = run(folder / f"one-{k}")
        one["total"].append(single["seconds"]["total"])
        out, whole = folder / f"tiled-{k}", folder / f"whole-{k}"
        run(out, "--tile", "prepare")
        shutil.copytree(out / "tiles" / "prepare", whole / "tiles" / "prepare")
        run(whole, "--tile", "1/1")  # the whole gather in one process, from the same solution
        for tile in range(1, tiles + 1):
            run(out, "--tile", f"{tile}/{tiles}")
        if cli(["merge", str(out), "--quiet"]) != 0:
            raise SystemExit("merge failed")
        merged = json.loads((out / "metrics.json").read_text())
        tiled["total"].append(merged["seconds"]["total"])
        one["gather"].append(json.loads((whole / "tiles" / "1-of-1" / "metrics.json")
                                        .read_text())["seconds"]["radiosity"])
        tiled["gather"].append(sum(json.loads((out / "tiles" / f"{t}-of-{tiles}" / "metrics.json")
                                              .read_text())["seconds"]["radiosity"]
                                   for t in range(1, tiles + 1)))
        for name in single["outputs"]:
            if name.endswith(".exr") and not np.array_equal(
                    read_exr(folder / f"one-{k}" / name), read_exr(out / name)):
                raise SystemExit(f"tiled {name} differs from the one run's")
    best = {"one_total": min(one["total"]), "tiled_total": min(tiled["total"]),
            "one_gather": min(one["gather"]), "tiled_gather": min(tiled["gather"])}
    return {"best": best, "one": one, "tiled": tiled, "tiles": tiles, "options": options}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a short smoke run")
    parser.add_argument("--resolution", type=int, nargs=2, default=None, metavar=("W", "H"))
    parser.add_argument("--tiles", type=int, default=None, help="tiles of the radiosity bake (4)")
    args = parser.parse_args()
    scenes = sorted(SAMPLES.glob("*.blend"))
    techniques = ["trace", "bump", "texture"]
    size, repeats = args.resolution or (160, 120), 2
    if args.quick:
        scenes, techniques, size, repeats = scenes[:2], ["trace"], args.resolution or (16, 12), 1
    with tempfile.TemporaryDirectory(prefix="bench-batch-") as folder:
        jobs = jobs_file(Path(folder), scenes, techniques, size)
        seconds = {1: [], 2: []}
        for _ in range(repeats):  # alternately, so that drift in the machine's load hits both
            for workers in (1, 2):
                seconds[workers].append(run_batch(jobs, workers))
        tiles = args.tiles or (2 if args.quick else 4)
        options = (["--lightmap-size", "32", "--patches", "60", "--resolution", "24", "18"]
                   if args.quick else ["--lightmap-size", "256", "--resolution", *map(str, size)])
        tiled = tiled_radiosity(Path(folder), tiles, options, repeats)
    best = {w: min(s) for w, s in seconds.items()}
    runs = len(scenes) * len(techniques)
    ratio = best[1] / best[2]
    print(format_table(["workers", "seconds (best)", "runs", "seconds per run"],
                       [[str(w), best[w], runs, best[w] / runs] for w in (1, 2)]))
    print(f"2 workers over 1: {ratio:.2f}x")
    t = tiled["best"]
    overhead = t["tiled_total"] / t["one_total"]
    gather = t["tiled_gather"] / t["one_gather"]
    print(format_table(["radiosity", "one run (s)", f"{tiles} tiles (s)", "tiled / one"],
                       [["all parts", t["one_total"], t["tiled_total"], overhead],
                        ["lightmap gather", t["one_gather"], t["tiled_gather"], gather]]))
    path = write_report("batch", {"one_vs_two_workers_seconds": ratio,
                                  "tiled_radiosity_overhead": overhead,
                                  "tiled_gather_overhead": gather},
                        {"seconds": seconds, "runs": runs, "resolution": list(size),
                         "scenes": [s.name for s in scenes], "techniques": techniques,
                         "tiled_radiosity": tiled, "quick": args.quick}, versions("bpy"))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
