"""Shared helpers of the benchmarks: timing, versions, and the out/bench/NAME.json report.

Every benchmark writes `{"bench": NAME, "ratios": {...}, "figures": {...}, "versions": {...}}`;
each ratio is named for what it divides (e.g. `bvh_vs_bvhtree_rays_per_s/...`).
"""

from __future__ import annotations

import json
import platform
import time
from collections.abc import Callable
from importlib import metadata
from pathlib import Path

import numpy as np

OUT_DIR = Path(__file__).resolve().parents[1] / "out" / "bench"


def best_of(fn: Callable[[], object], repeats: int = 3) -> float:
    """The shortest wall-clock time of `repeats` calls of fn, seconds (noise only adds time)."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


def timed(fn: Callable[..., object], *args: object) -> float:
    """Wall-clock seconds of one call fn(*args)."""
    start = time.perf_counter()
    fn(*args)
    return time.perf_counter() - start


def versions(*packages: str) -> dict[str, str]:
    """Python, NumPy, the machine, and each named package's installed version (if any)."""
    found = {
        "python": platform.python_version(),
        "numpy": np.__version__,
        "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
    }
    for name in packages:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = "not installed"
    return found


def write_report(
    name: str,
    ratios: dict[str, float],
    figures: dict[str, object],
    versions_: dict[str, str],
    out_dir: Path | None = None,
) -> Path:
    """Write out/bench/NAME.json and return its path."""
    folder = out_dir or OUT_DIR
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{name}.json"
    report = {"bench": name, "ratios": ratios, "figures": figures, "versions": versions_}
    path.write_text(json.dumps(report, indent=1, sort_keys=True, default=float) + "\n")
    return path


def format_table(header: list[str], rows: list[list[object]]) -> str:
    """A plain-text table, columns right-aligned except the first."""
    cells = [[str(c) for c in header]] + [
        [f"{c:.3g}" if isinstance(c, float) else str(c) for c in row] for row in rows
    ]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = []
    for k, row in enumerate(cells):
        first = row[0].ljust(widths[0])
        rest = [c.rjust(w) for c, w in zip(row[1:], widths[1:], strict=True)]
        lines.append("  ".join([first, *rest]))
        if k == 0:
            lines.append("  ".join("-" * w for w in widths))
    return "\n".join(lines)


if __name__ == "__main__":
    print("bench/_report.py is a helper module; run bench/rays.py")


def stack_texels(images: dict, masks: dict, names) -> np.ndarray:
    """Every masked texel of the lightmaps `names` ({name: (H, W, 3)}, masks {name: (H, W)}) as
    one (N, 1, 3) image, for one relative MSE over several objects."""
    return np.concatenate([images[n][masks[n]] for n in names])[:, None, :]


def seconds_to_reach(error: float, ladder: list[dict], metric: str = "rel_mse") -> float | None:
    """Seconds Cycles needs for `error` in `metric`, log-log interpolated on its ladder (None:
    never)."""
    pts = sorted((r["seconds"], r[metric]) for r in ladder)
    for (t0, e0), (t1, e1) in zip(pts, pts[1:], strict=False):
        if e1 <= error <= e0 and e0 > e1:
            f = (np.log(error) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp(np.log(t0) + f * (np.log(t1) - np.log(t0))))
    if pts and error >= pts[0][1]:
        return pts[0][0]  # already reached by the cheapest rung
    return None


def add_cycles_ratios(rows: list[dict], cycles: list[dict]) -> None:
    """For each kernel rung: Cycles' seconds to its error on Cycles' ladder
    (`cycles_seconds_to_same_error`) and that over the rung's seconds (`ratio`; None: never)."""
    for row in rows:
        reach = seconds_to_reach(row["rel_mse"], cycles)
        row["cycles_seconds_to_same_error"] = reach
        row["ratio"] = None if reach is None else reach / row["seconds"]


def whitted_reference(scene: Path, quick: bool, max_samples: int) -> tuple:
    """Open `scene`, and fetch (or render and cache) its converged Cycles render under the
    Whitted tracer's model at the scene's own resolution and the tracer's automatic depth.

    Returns (resolution (W, H), model, reference) with the file opened again afterwards (the
    reference render leaves Cycles' settings as it found them, but not the open file)."""
    import bpy

    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.trace.settings import auto_settings

    bpy.ops.wm.open_mainfile(filepath=str(scene), load_ui=False, use_scripts=False)
    resolution = bridge.render_resolution(bpy.context.scene)
    model = cr.whitted(auto_settings(bridge.snapshot(resolution=resolution)).max_depth)
    cr.warm_up()
    ref = cr.reference(scene, model, "render", resolution=resolution,
                       samples=128 if quick else None, max_samples=max_samples,
                       target_rel_mse=1e-4)
    bpy.ops.wm.open_mainfile(filepath=str(scene), load_ui=False, use_scripts=False)
    return resolution, model, ref


def image_row(images: dict, path: Path, crop: tuple | None = None, width: float = 3.0) -> None:
    """Linear images side by side, titled by their keys, as an sRGB preview figure (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from classic_bake.pipeline.images import preview_rgb8

    fig, axes = plt.subplots(1, len(images), figsize=(width * len(images), 0.85 * width + 0.05))
    for ax, (title, image) in zip(np.atleast_1d(axes), images.items(), strict=True):
        ax.imshow(preview_rgb8(image if crop is None else image[crop]), interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def reference_arguments(description: str):
    """The command line of a bench against a converged Cycles reference: --quick (short ladders)
    and --max-ref-samples (the reference's cap)."""
    import argparse

    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--quick", action="store_true", help="short ladders (smoke run)")
    parser.add_argument("--max-ref-samples", type=int, default=1024,
                        help="cap of the converged Cycles reference (default 1024)")
    return parser.parse_args()


# A run of either side shorter than this is repeated, REPEATS runs in all, and its median taken:
# one 0.2 s run on the shared 2-core machine varies by +-30% from one moment to the next
# (measured: the same 74-patch bake 0.15-0.29 s within minutes).
SHORT_RUN_S = 2.0
REPEATS = 3


def repeated(seconds_of, run, *args) -> tuple[list, object]:
    """Calls run(*args) once, and REPEATS times in all when seconds_of(its result) is under
    SHORT_RUN_S. Returns (every result, the last): each run gives the same values (fixed seeds),
    only their seconds differ."""
    runs = [run(*args)]
    while len(runs) < REPEATS and seconds_of(runs[0]) < SHORT_RUN_S:
        runs.append(run(*args))
    return runs, runs[-1]


def median_of(runs: list, seconds_of) -> float:
    return float(np.median([seconds_of(r) for r in runs]))
