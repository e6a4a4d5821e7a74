"""The main job's cost: `demo` on the sample scenes, as on a fresh clone, against its stated budget.

    .venv/bin/python bench/demo.py [--warm]

Runs `python -m classic_bake demo sample_blends` in a new empty working folder, so the converged
Cycles references are computed as on a fresh clone (the cache, `out/cache`, is relative to the
working folder); `--warm` runs it a second time there, with the references cached. The budget is
`DEMO_BUDGET_S` of pipeline/commands/demo.py, the figure the README states. Ratios: the budget
over the seconds taken (above 1: within the budget). Per run (scene x technique) seconds come from
the demo's own demo.json. Writes out/bench/demo.json.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import versions, write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def run_demo(workdir: Path) -> dict:
    """One `demo` run in workdir: wall seconds, and the demo's own per-run seconds."""
    out = workdir / "out" / "demo"
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "classic_bake", "demo", str(ROOT / "sample_blends"),
                           "--out", str(out), "--quiet"], cwd=workdir, capture_output=True,
                          text=True)
    seconds = time.perf_counter() - start
    if done.returncode != 0:
        raise SystemExit(f"demo failed ({done.returncode}): {done.stderr.strip()[-2000:]}")
    own = json.loads((out / "demo.json").read_text(encoding="utf-8"))
    return {"seconds": seconds, "seconds_per_run": own["seconds_per_run"],
            "skipped": own["skipped"]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--warm", action="store_true",
                        help="run a second time with the references cached")
    args = parser.parse_args()
    from classic_bake.pipeline.commands.demo import DEMO_BUDGET_S

    ratios, figures = {}, {"budget_s": DEMO_BUDGET_S}
    with tempfile.TemporaryDirectory(prefix="classic-bake-demo-") as folder:
        runs = [("fresh_clone", run_demo(Path(folder)))]
        if args.warm:
            runs.append(("references_cached", run_demo(Path(folder))))
    for name, run in runs:
        figures[name] = run
        ratios[f"demo_budget_vs_seconds_{name}"] = DEMO_BUDGET_S / run["seconds"]
        slowest = sorted(run["seconds_per_run"].items(), key=lambda kv: -kv[1])[:5]
        print(f"{name}: {run['seconds']:.0f} s (budget {DEMO_BUDGET_S:.0f} s); slowest runs: "
              + ", ".join(f"{k} {v:.0f} s" for k, v in slowest))
    write_report("demo", ratios, figures, versions("bpy"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
