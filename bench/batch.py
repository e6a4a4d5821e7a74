"""The batch command's speed-up of 2 workers over 1, on the sample scenes.

    .venv/bin/python bench/batch.py [--quick] [--resolution W H]

Runs `python -m classic_bake batch` over every sample scene x (trace, bump, shadowmap) with
--workers 1 and --workers 2 (--force: nothing skipped), alternately, and reports the ratio of their
wall-clock seconds (`one_vs_two_workers_seconds`: above 1, two workers are faster). Each run is a
process of its own, so the batch pays each run's start-up (importing bpy, opening the scene) and
two workers overlap it. --quick: two scenes, one technique, 16 x 12, one repeat.
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


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a short smoke run")
    parser.add_argument("--resolution", type=int, nargs=2, default=None, metavar=("W", "H"))
    args = parser.parse_args()
    scenes = sorted(SAMPLES.glob("*.blend"))
    techniques = ["trace", "bump", "shadowmap"]
    size, repeats = args.resolution or (160, 120), 2
    if args.quick:
        scenes, techniques, size, repeats = scenes[:2], ["trace"], args.resolution or (16, 12), 1
    with tempfile.TemporaryDirectory(prefix="bench-batch-") as folder:
        jobs = jobs_file(Path(folder), scenes, techniques, size)
        seconds = {1: [], 2: []}
        for _ in range(repeats):  # alternately, so that drift in the machine's load hits both
            for workers in (1, 2):
                seconds[workers].append(run_batch(jobs, workers))
    best = {w: min(s) for w, s in seconds.items()}
    runs = len(scenes) * len(techniques)
    ratio = best[1] / best[2]
    print(format_table(["workers", "seconds (best)", "runs", "seconds per run"],
                       [[str(w), best[w], runs, best[w] / runs] for w in (1, 2)]))
    print(f"2 workers over 1: {ratio:.2f}x")
    path = write_report("batch", {"one_vs_two_workers_seconds": ratio},
                        {"seconds": seconds, "runs": runs, "resolution": list(size),
                         "scenes": [s.name for s in scenes], "techniques": techniques,
                         "quick": args.quick}, versions("bpy"))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
