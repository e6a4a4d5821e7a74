"""A soak: the sample scenes through every technique command many times, with a CPU-bound process
running beside them, each run under a watchdog. Expected: no hangs, no failures.

    .venv/bin/python bench/soak.py [--repeat N] [--scenes NAME ...] [--commands NAME ...]
                                   [--timeout S] [--resolution W H] [--no-load] [--resume REPORT]

Each run is `python -m classic_bake COMMAND SCENE --out TMP --resolution W H` in a process of its
own (started with Python's fault handler listening for SIGUSR1). A run still going after --timeout
seconds is a hang: it is sent SIGUSR1, so its threads' stacks land in the report, then killed. A
run that exits 2 with one `classic_bake: error:` line is a refusal (envmap on a scene without a
mirror), counted apart; any other non-zero exit, or a traceback, is a failure. The CPU-bound
process is started before the first run and stopped after the last, whatever happens.

Writes out/bench/soak.json after every pass (a soak stopped early keeps its finished passes):
{"bench": "soak", "ratios": {"held_fraction": runs that ended on their own without failing, over
all runs}, "figures": {runs, passes done, hangs, failures, refusals, per command, the slowest
runs, hang stacks and failure messages, segments}, "versions": {...}}.

A soak of many passes may run in segments: `--resume REPORT` continues an earlier report of the
same scenes, commands, resolution, timeout and load, adding passes until --repeat passes in all;
each segment's commit, passes and seconds are kept in `figures.segments`.
"""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import format_table, versions, write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_blends"
COMMANDS = ("lightmap-uv", "texture", "trace", "envmap", "bump", "shadowmap", "radiosity",
            "hybrid", "normalmap")
# Default repeats: issue 43's soak, 50 passes over every scene and command.
REPEAT = 50
# The watchdog: the slowest sample-scene run at 32 x 24 takes ~40 s on two busy cores (radiosity
# of raytrace.blend); five times that is a hang, not a slow run.
TIMEOUT_S = 200.0
# After SIGUSR1, the seconds a hung run gets to write its stacks before it is killed.
STACK_GRACE_S = 5.0
RESOLUTION = (32, 24)
# Kept of a failure's stderr and a hang's stacks in the report.
TAIL_CHARS = 4000
# The load beside the runs: one process spinning on a core.
LOAD = "while True: pass"
# The command run in each process: the fault handler dumps every thread's stack on SIGUSR1.
RUNNER = ("import faulthandler, runpy, signal, sys; "
          "faulthandler.register(signal.SIGUSR1, all_threads=True); "
          "sys.argv = ['classic_bake'] + sys.argv[1:]; "
          "runpy.run_module('classic_bake', run_name='__main__', alter_sys=True)")


def run_once(command: str, scene: Path, out: Path, resolution, timeout: float) -> dict:
    """One watched run: {"command", "scene", "seconds", "outcome": ok | refused | failed | hung,
    "detail"}."""
    args = [sys.executable, "-c", RUNNER, command, str(scene), "--out", str(out), "--quiet"]
    if command != "lightmap-uv":
        args += ["--resolution", str(resolution[0]), str(resolution[1])]
    start = time.perf_counter()
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
        hung = False
    except subprocess.TimeoutExpired:
        hung = True
        proc.send_signal(signal.SIGUSR1)
        try:
            stdout, stderr = proc.communicate(timeout=STACK_GRACE_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            stdout, stderr = proc.communicate()
    seconds = time.perf_counter() - start
    lines = stderr.strip().splitlines()
    if hung:
        outcome, detail = "hung", stderr[-TAIL_CHARS:]
    elif proc.returncode == 0 and "Traceback" not in stderr:
        outcome, detail = "ok", ""
    elif (proc.returncode == 2 and len(lines) == 1
          and lines[0].startswith("classic_bake: error:")):
        outcome, detail = "refused", lines[0]
    else:
        outcome, detail = "failed", f"exit {proc.returncode}: {stderr[-TAIL_CHARS:]}"
    return {"command": command, "scene": scene.stem, "seconds": round(seconds, 2),
            "outcome": outcome, "detail": detail}


def soak(scenes: list[Path], commands: list[str], repeat: int, timeout: float, resolution,
         load: bool, after_pass=None) -> list[dict]:
    """Every command on every scene, `repeat` passes; after_pass(runs) is called after each
    pass (the report is written there, so a soak stopped early keeps its finished passes)."""
    burner = subprocess.Popen([sys.executable, "-c", LOAD]) if load else None
    runs = []
    try:
        with tempfile.TemporaryDirectory(prefix="soak-") as tmp:
            for k in range(repeat):
                for scene in scenes:
                    for command in commands:
                        out = Path(tmp) / f"{command}-{scene.stem}"
                        run = run_once(command, scene, out, resolution, timeout)
                        runs.append(run)
                        if run["outcome"] in ("hung", "failed"):
                            print(f"pass {k + 1}: {command} {scene.name}: {run['outcome']}",
                                  flush=True)
                print(f"pass {k + 1}/{repeat}: {len(runs)} runs, "
                      f"{sum(r['outcome'] == 'hung' for r in runs)} hangs, "
                      f"{sum(r['outcome'] == 'failed' for r in runs)} failures", flush=True)
                if after_pass is not None:
                    after_pass(runs)
    finally:
        if burner is not None:
            burner.terminate()
            burner.wait()
    return runs


def merged(previous: dict, figures: dict) -> dict:
    """An earlier soak report's figures followed by this segment's: counts add, the slowest and
    the refusals are pooled, hangs and failures kept whole."""
    out = dict(figures)
    for key in ("runs", "hangs", "failures", "refusals", "ok", "passes_done"):
        out[key] = previous[key] + figures[key]
    out["seconds"] = round(previous["seconds"] + figures["seconds"], 1)
    out["per_command"] = {
        command: {**{o: previous["per_command"][command][o] + mine[o]
                     for o in ("ok", "refused", "failed", "hung")},
                  "max_seconds": max(previous["per_command"][command]["max_seconds"],
                                     mine["max_seconds"])}
        for command, mine in figures["per_command"].items()}
    out["slowest"] = sorted(previous["slowest"] + figures["slowest"],
                            key=lambda r: -r["seconds"])[:5]
    for key in ("hung", "failed"):
        out[key] = previous[key] + figures[key]
    out["refused"] = sorted(set(previous["refused"]) | set(figures["refused"]))
    out["segments"] = previous.get("segments", [
        {"commit": "not recorded", "passes": previous["passes_done"],
         "seconds": previous["seconds"]}]) + figures["segments"]
    return out


def commit() -> str:
    done = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True,
                          text=True)
    return done.stdout.strip() if done.returncode == 0 else "unknown"


def blender_version() -> str:
    done = subprocess.run([sys.executable, "-c", "import bpy; print(bpy.app.version_string)"],
                          capture_output=True, text=True)
    return done.stdout.strip().splitlines()[-1] if done.returncode == 0 else "unknown"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=REPEAT, help=f"passes (default {REPEAT})")
    parser.add_argument("--scenes", nargs="+", default=None,
                        help="sample scene names (default: every sample_blends/*.blend)")
    parser.add_argument("--commands", nargs="+", default=list(COMMANDS), choices=COMMANDS)
    parser.add_argument("--timeout", type=float, default=TIMEOUT_S,
                        help=f"seconds before a run counts as hung (default {TIMEOUT_S:g})")
    parser.add_argument("--resolution", type=int, nargs=2, default=RESOLUTION, metavar=("W", "H"))
    parser.add_argument("--no-load", action="store_true",
                        help="no CPU-bound process beside the runs")
    parser.add_argument("--resume", type=Path, default=None, metavar="REPORT",
                        help="continue this earlier soak report up to --repeat passes in all")
    args = parser.parse_args()
    if args.repeat < 1 or args.timeout <= 0:
        parser.error("--repeat must be >= 1 and --timeout > 0")
    names = args.scenes or sorted(p.stem for p in SAMPLES.glob("*.blend"))
    previous = None
    if args.resume is not None:
        previous = json.loads(args.resume.read_text())["figures"]
        same = {"scenes": names, "commands": args.commands, "timeout_s": args.timeout,
                "resolution": list(args.resolution), "cpu_load_beside": not args.no_load}
        differs = [k for k, v in same.items() if previous.get(k) != v]
        if differs:
            parser.error(f"--resume: {args.resume} differs in {', '.join(differs)}")
        if previous["passes_done"] >= args.repeat:
            parser.error(f"--resume: {args.resume} already has {previous['passes_done']} passes")
    scenes = [SAMPLES / f"{name}.blend" for name in names]
    missing = [s.name for s in scenes if not s.is_file()]
    if missing:
        parser.error(f"no such sample scene: {', '.join(missing)}")

    started = time.perf_counter()

    def report(runs: list[dict]) -> dict:
        count = {o: sum(r["outcome"] == o for r in runs)
                 for o in ("ok", "refused", "failed", "hung")}
        per_command = {}
        for command in args.commands:
            mine = [r for r in runs if r["command"] == command]
            per_command[command] = {**{o: sum(r["outcome"] == o for r in mine) for o in count},
                                    "max_seconds": max((r["seconds"] for r in mine), default=0.0)}
        held = (count["ok"] + count["refused"]) / len(runs)
        figures = {
            "runs": len(runs), "hangs": count["hung"], "failures": count["failed"],
            "refusals": count["refused"], "ok": count["ok"], "repeat": args.repeat,
            "passes_done": len(runs) // (len(scenes) * len(args.commands)),
            "scenes": names, "commands": args.commands, "timeout_s": args.timeout,
            "resolution": list(args.resolution), "cpu_load_beside": not args.no_load,
            "seconds": round(time.perf_counter() - started, 1), "per_command": per_command,
            "slowest": sorted(runs, key=lambda r: -r["seconds"])[:5],
            "hung": [r for r in runs if r["outcome"] == "hung"],
            "failed": [r for r in runs if r["outcome"] == "failed"],
            "refused": sorted({f"{r['command']} {r['scene']}: {r['detail']}" for r in runs
                               if r["outcome"] == "refused"}),
        }
        figures["segments"] = [{"commit": head, "passes": figures["passes_done"],
                                "seconds": figures["seconds"]}]
        if previous is not None:
            figures = merged(previous, figures)
            held = (figures["ok"] + figures["refusals"]) / figures["runs"]
        write_report("soak", {"held_fraction": held}, figures,
                     {**versions(), "blender": blender})
        return {"count": count, "per_command": per_command}

    blender, head = blender_version(), commit()
    passes = args.repeat - (previous["passes_done"] if previous else 0)
    runs = soak(scenes, args.commands, passes, args.timeout, args.resolution,
                not args.no_load, after_pass=report)
    summary = report(runs)
    count, per_command = summary["count"], summary["per_command"]
    rows = [[c, *(v[o] for o in count), v["max_seconds"]] for c, v in per_command.items()]
    print(format_table(["command", *count, "max s"], rows))
    print(f"this segment: {len(runs)} runs, {count['hung']} hangs, {count['failed']} failures, "
          f"{count['refused']} refusals; wrote out/bench/soak.json")
    return 1 if count["hung"] or count["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
