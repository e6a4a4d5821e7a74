"""`batch JOBS.toml`: scenes x techniques x settings, run by several worker processes, resumable.

    python -m classic_bake batch JOBS.toml [--workers N] [--out DIR] [--force]

JOBS.toml (paths and globs are relative to the file's folder):

    out = "out/batch"              # default output folder (--out overrides)
    workers = 2                    # default worker count (--workers overrides)
    resolution = [320, 240]        # render.exr size of every run (default: each scene's own)

    [[job]]
    scenes = ["scenes/*.blend"]    # files or globs
    techniques = ["trace", "shadowmap"]
    settings = [{}, { depth = 2, supersample = 2 }]   # one table or a list: a run per table

A setting is a technique's command-line option without its dashes (`depth = 2` is `--depth 2`;
`final_gather = false` is `--no-final-gather`; `all_modes = true` is `--all-modes`); a table may
name itself (`name = "deep"`), else its folder is named after its values. Every run is a worker
process `python -m classic_bake TECHNIQUE SCENE --out OUT/SCENE-TECHNIQUE[-SETTINGS] ...` (with
`--blender PATH`, or when the batch itself runs in Blender as `blender -c classic_bake batch`:
`BLENDER -b -c classic_bake ...`), its log in OUT/.batch-logs/.

Resumable: when a run succeeds, the batch writes `batch-manifest.json` into its folder, last; it
holds the run's inputs: the scene file's SHA-256, the technique, the settings and the resolution. A
run whose folder holds a manifest with the same inputs (and every output its metrics.json lists) is
skipped, so a batch killed half-way finishes the rest when run again, and editing a scene or a
setting re-runs only what it affects.
The outputs of a run are published atomically (pipeline/outputs.py), so a run killed half-way
leaves no manifest and earlier outputs as they were.

Each of N workers gets 1/N of the cores (`PYTHON_CPU_COUNT`, which os.cpu_count() reports from
Python 3.13, and the BLAS thread variables), so N workers do not oversubscribe the machine.
"""

from __future__ import annotations

import glob
import hashlib
import json
import os
import re
import subprocess
import sys
import time
import tomllib
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

from ..command import Command, RunContext
from ..outputs import UsageError, safe_name

MANIFEST = "batch-manifest.json"
LOG_FOLDER = ".batch-logs"
SUMMARY = "batch-summary.json"
MANIFEST_VERSION = 1  # bump when what a run's inputs are changes
POLL_S = 0.1  # how often the batch looks at its workers
RUNNING_SHARE = 0.9  # the most a running worker's own progress counts for in the batch's
MAX_TAG_LENGTH = 60  # a settings folder suffix longer than this becomes a hash
_PERCENT = re.compile(r"\s(\d{1,3})% ")  # a worker's --verbose progress line: "trace  40% ..."


@dataclass(frozen=True)
class Run:
    """One scene x technique x settings run of a batch."""

    scene: Path
    technique: str
    settings: tuple[tuple[str, object], ...]  # (option, value), in the table's order
    tag: str  # "" or the settings' folder suffix
    out: Path

    @property
    def name(self) -> str:
        return self.out.name

    def argv(self, resolution) -> list[str]:
        """The command line after `python -m classic_bake`."""
        args = [self.technique, str(self.scene), "--out", str(self.out), "--verbose"]
        if resolution:
            args += ["--resolution", *map(str, resolution)]
        return args + settings_argv(dict(self.settings))

    def inputs(self, resolution, scene_hash: str) -> dict:
        """What the manifest records and a later batch compares."""
        return {"version": MANIFEST_VERSION, "scene_sha256": scene_hash,
                "technique": self.technique, "settings": dict(self.settings),
                "resolution": list(resolution) if resolution else None}


@dataclass
class Outcome:
    run: Run
    status: str  # "done", "skipped", "failed"
    seconds: float = 0.0
    log: Path | None = None
    detail: str = ""


@dataclass
class Batch:
    runs: list[Run]
    out: Path
    workers: int
    resolution: tuple[int, int] | None
    outcomes: list[Outcome] = field(default_factory=list)


def settings_argv(settings: dict) -> list[str]:
    """Command-line options of a settings table (see the module docstring)."""
    argv = []
    for key, value in settings.items():
        flag = "--" + key.replace("_", "-")
        if value is True:
            argv.append(flag)
        elif value is False:
            argv.append("--no-" + flag[2:])
        elif isinstance(value, list):
            argv += [flag, *map(str, value)]
        else:
            argv += [flag, str(value)]
    return argv


def settings_tag(settings: dict) -> str:
    """A folder suffix naming a settings table: its `name`, or its values (a hash when long)."""
    if not settings:
        return ""
    text = "_".join(f"{k}-{'-'.join(map(str, v)) if isinstance(v, list) else v}"
                    for k, v in settings.items())
    if len(text) > MAX_TAG_LENGTH:
        return hashlib.sha256(text.encode()).hexdigest()[:12]
    return safe_name(text)


def file_hash(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _list(table: dict, key: str, where: str) -> list:
    value = table.get(key)
    if isinstance(value, str | dict):
        value = [value]
    if not isinstance(value, list) or not value:
        raise UsageError(f"{where}: '{key}' must be a non-empty list")
    return value


def check_arguments(technique: str, scene: Path, argv: list[str]) -> None:
    """Parse a run's command line as its worker will, so bad settings fail before any worker."""
    from ...jobs.techniques import BY_NAME
    from ..run import Parser, add_scene_arguments
    from .technique import technique_command

    if technique not in BY_NAME:
        raise UsageError(f"unknown technique '{technique}' (one of {', '.join(BY_NAME)})")
    parser = Parser(prog=f"batch {technique}")
    add_scene_arguments(parser)
    technique_command(BY_NAME[technique]).add_arguments(parser)
    try:
        parser.parse_args([str(scene), *argv])
    except UsageError as exc:
        raise UsageError(f"{technique} {scene.name}: {exc}") from exc


def load_batch(path: Path, out: Path | None = None, workers: int | None = None) -> Batch:
    """The runs of JOBS.toml, checked (every scene exists, every setting parses)."""
    try:
        spec = tomllib.loads(path.read_text())
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror}") from exc
    except tomllib.TOMLDecodeError as exc:
        raise UsageError(f"{path}: {exc}") from exc
    base = path.resolve().parent
    out = Path(out) if out is not None else base / spec.get("out", "out/batch")
    workers = int(workers if workers is not None else spec.get("workers", 1))
    if workers < 1:
        raise UsageError("--workers must be at least 1")
    resolution = spec.get("resolution")
    if resolution is not None and (len(resolution) != 2 or not all(
            isinstance(n, int) and 1 <= n <= 16384 for n in resolution)):
        raise UsageError(f"{path}: resolution must be two sizes in [1, 16384]")
    jobs = spec.get("job", [])
    if not jobs:
        raise UsageError(f"{path}: no [[job]] tables")
    runs, seen = [], set()
    for k, job in enumerate(jobs, 1):
        where = f"{path.name} job {k}"
        scenes = []
        for pattern in _list(job, "scenes", where):
            found = sorted(Path(p) for p in glob.glob(str(base / pattern))) if any(
                c in pattern for c in "*?[") else [base / pattern]
            if not found or not all(p.is_file() for p in found):
                raise UsageError(f"{where}: no scene file matches '{pattern}'")
            scenes += found
        settings_list = job.get("settings", [{}])
        settings_list = [settings_list] if isinstance(settings_list, dict) else settings_list
        for scene in scenes:
            for technique in _list(job, "techniques", where):
                for table in settings_list:
                    table = dict(table)
                    tag = safe_name(str(table.pop("name"))) if "name" in table else settings_tag(table)
                    folder = f"{safe_name(scene.stem)}-{technique}" + (f"-{tag}" if tag else "")
                    if folder in seen:
                        continue  # the same run listed twice
                    seen.add(folder)
                    run = Run(scene.resolve(), technique, tuple(table.items()), tag, out / folder)
                    check_arguments(technique, scene, run.argv(resolution)[2:])
                    runs.append(run)
    return Batch(runs, out, workers, tuple(resolution) if resolution else None)


def read_manifest(folder: Path) -> dict | None:
    try:
        return json.loads((folder / MANIFEST).read_text())
    except (OSError, ValueError):
        return None


def outputs_present(folder: Path) -> bool:
    """Every file the run's metrics.json lists is still there (someone may have deleted some)."""
    try:
        listed = json.loads((folder / "metrics.json").read_text()).get("outputs", [])
    except (OSError, ValueError, AttributeError):
        return False
    return all((folder / name).is_file() for name in listed)


def write_manifest(folder: Path, inputs: dict, seconds: float) -> None:
    """The run's inputs, written last and atomically: its presence means the run finished."""
    temporary = folder / (MANIFEST + ".tmp")
    temporary.write_text(json.dumps({"inputs": inputs, "seconds": round(seconds, 3),
                                     "finished": time.strftime("%Y-%m-%dT%H:%M:%SZ",
                                                               time.gmtime())}, indent=2) + "\n")
    os.replace(temporary, folder / MANIFEST)


def worker_environment(workers: int) -> dict:
    """The environment of one of `workers` workers: its share of the cores."""
    share = str(max(1, (os.cpu_count() or 1) // workers))
    env = dict(os.environ)
    env.update(PYTHON_CPU_COUNT=share, OMP_NUM_THREADS=share, OPENBLAS_NUM_THREADS=share,
               MKL_NUM_THREADS=share, CYCLES_THREADS=share)
    return env


def worker_command(blender: Path | None) -> list[str]:
    """`--blender PATH`: that Blender with the extension; inside Blender (`blender -c classic_bake
    batch`): the same Blender, since its bundled Python cannot import bpy on its own; else this
    Python with the bpy module."""
    if blender is None:
        try:
            import bpy

            binary = bpy.app.binary_path  # "" in the bpy module
        except ImportError:
            binary = ""
        blender = Path(binary) if binary else None
    if blender is not None:
        return [str(blender), "-b", "-c", "classic_bake"]
    return [sys.executable, "-m", "classic_bake"]


def last_progress(log: Path) -> float:
    """The last progress fraction a worker printed (its --verbose lines), 0 before any."""
    try:
        with open(log, "rb") as f:
            f.seek(max(0, f.seek(0, os.SEEK_END) - 4096))
            tail = f.read().decode("utf-8", "replace")
    except OSError:
        return 0.0
    found = _PERCENT.findall(tail)
    return min(int(found[-1]), 100) / 100.0 if found else 0.0


def run_batch(batch: Batch, force: bool = False, blender: Path | None = None, bar=None,
              say=print) -> list[Outcome]:
    """Run every run not already current, `batch.workers` at a time; returns the outcomes in the
    batch's order. `bar(fraction)` sees the batch's progress (finished runs plus the running
    ones' own progress)."""
    logs = batch.out / LOG_FOLDER
    logs.mkdir(parents=True, exist_ok=True)
    hashes: dict[Path, str] = {}
    outcomes: dict[Run, Outcome] = {}
    pending = deque()
    for run in batch.runs:
        if run.scene not in hashes:
            hashes[run.scene] = file_hash(run.scene)
        inputs = run.inputs(batch.resolution, hashes[run.scene])
        manifest = read_manifest(run.out)
        if (not force and manifest is not None and manifest.get("inputs") == inputs
                and outputs_present(run.out)):
            outcomes[run] = Outcome(run, "skipped", manifest.get("seconds", 0.0))
        else:
            pending.append((run, inputs))
    total = len(batch.runs)
    finished = len(outcomes)
    if bar is not None:
        bar(finished / total if total else 1.0)
    running: dict[subprocess.Popen, tuple[Run, dict, float, Path]] = {}
    env, command = worker_environment(batch.workers), worker_command(blender)
    try:
        while pending or running:
            while pending and len(running) < batch.workers:
                run, inputs = pending.popleft()
                (run.out / MANIFEST).unlink(missing_ok=True)  # no longer current, if it was
                log = logs / f"{run.name}.log"
                with open(log, "wb") as out:
                    worker = subprocess.Popen([*command, *run.argv(batch.resolution)], stdout=out,
                                              stderr=subprocess.STDOUT, env=env)
                running[worker] = (run, inputs, time.perf_counter(), log)
            for worker in [w for w in running if w.poll() is not None]:
                run, inputs, began, log = running.pop(worker)
                seconds = time.perf_counter() - began
                if worker.returncode == 0 and (run.out / "metrics.json").is_file():
                    write_manifest(run.out, inputs, seconds)
                    outcomes[run] = Outcome(run, "done", seconds, log)
                else:
                    lines = log.read_text(errors="replace").strip().splitlines()
                    outcomes[run] = Outcome(run, "failed", seconds, log,
                                            lines[-1] if lines else f"exit {worker.returncode}")
                    say(f"failed: {run.name}: {outcomes[run].detail} (log {log})")
                finished += 1
            if bar is not None and total:
                # A running worker counts for at most RUNNING_SHARE of its run: after its
                # kernels' last yield it still writes its outputs and exits.
                partial = sum(min(last_progress(r[3]), RUNNING_SHARE) for r in running.values())
                bar((finished + partial) / total)
            if running:
                time.sleep(POLL_S)
    except BaseException:
        for worker in running:  # only the workers this batch started
            worker.terminate()
        for worker in running:
            try:
                worker.wait(timeout=10)
            except subprocess.TimeoutExpired:
                worker.kill()
        raise
    return [outcomes[run] for run in batch.runs]


def summary_table(outcomes: list[Outcome]) -> str:
    """A plain-text table: run, status, seconds; then the counts."""
    rows = [("run", "technique", "settings", "status", "seconds")]
    for o in outcomes:
        settings = " ".join(settings_argv(dict(o.run.settings))) or "-"
        rows.append((o.run.scene.name, o.run.technique, settings, o.status,
                     f"{o.seconds:.1f}" if o.status != "skipped" else "-"))
    widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip()
             for row in rows]
    lines.insert(1, "  ".join("-" * w for w in widths))
    counts = {s: sum(o.status == s for o in outcomes) for s in ("done", "skipped", "failed")}
    lines.append(f"{len(outcomes)} runs: {counts['done']} done, {counts['skipped']} skipped "
                 f"(unchanged), {counts['failed']} failed")
    return "\n".join(lines)


def add_arguments(parser) -> None:
    parser.add_argument("jobs", type=Path, metavar="JOBS.toml",
                        help="scenes x techniques x settings (format: pipeline/commands/batch.py)")
    parser.add_argument("--out", type=Path, default=None,
                        help="output folder (default: the file's `out`, else out/batch)")
    parser.add_argument("--workers", type=int, default=None,
                        help="worker processes run at once (default: the file's `workers`, else 1)")
    parser.add_argument("--force", action="store_true",
                        help="run everything, even runs whose inputs are unchanged")
    parser.add_argument("--blender", type=Path, default=None, metavar="PATH",
                        help="workers run `PATH -b -c classic_bake ...` (the extension installed) "
                             "instead of this Python with the bpy module")


def run(ctx: RunContext) -> None:
    batch = load_batch(ctx.args.jobs, ctx.args.out, ctx.args.workers)
    ctx.say(f"batch: {len(batch.runs)} runs, {batch.workers} workers, into {batch.out}")
    with ctx.phase("batch"):
        outcomes = run_batch(batch, force=ctx.args.force, blender=ctx.args.blender,
                             bar=ctx.progress("batch"), say=ctx.say)
    ctx.say(summary_table(outcomes))
    summary = [{"folder": o.run.name, "scene": str(o.run.scene), "technique": o.run.technique,
                "settings": dict(o.run.settings), "status": o.status,
                "seconds": round(o.seconds, 3), "detail": o.detail} for o in outcomes]
    (batch.out / SUMMARY).write_text(json.dumps(summary, indent=2) + "\n")
    failed = [o for o in outcomes if o.status == "failed"]
    if failed:
        raise UsageError(f"{len(failed)} of {len(outcomes)} runs failed; logs in "
                         f"{batch.out / LOG_FOLDER}")


COMMAND = Command(name="batch", help="run scenes x techniques x settings from a TOML file on "
                  "several worker processes, skipping runs whose inputs are unchanged",
                  run=run, add_arguments=add_arguments, needs_scene=False)
