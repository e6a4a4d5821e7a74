"""`batch JOBS.toml`: sample scenes x two cheap techniques at 24 x 18 on 2 workers finish, their
outputs equal single runs bit for bit, a second run skips everything, a batch killed half-way
finishes the rest when run again, and bad job files fail before any worker starts."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from classic_bake.kernels.measure.exr import read_exr
from classic_bake.pipeline.cli import main
from classic_bake.pipeline.commands.batch import MANIFEST, SUMMARY, load_batch, settings_argv
from classic_bake.pipeline.outputs import UsageError

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "sample_blends"
SCENES = ("raytrace", "bump")
TECHNIQUES = ("trace", "bump")
SIZE = (24, 18)


def write_jobs(folder: Path, workers: int = 2, scenes=SCENES, settings="{ adaptive = 0 }") -> Path:
    path = folder / "jobs.toml"
    listed = ", ".join(f'"{SAMPLES / name}.blend"' for name in scenes)
    path.write_text(f'out = "out"\nworkers = {workers}\nresolution = [{SIZE[0]}, {SIZE[1]}]\n\n'
                    f'[[job]]\nscenes = [{listed}]\n'
                    f'techniques = [{", ".join(f"{chr(34)}{t}{chr(34)}" for t in TECHNIQUES)}]\n'
                    f"settings = {settings}\n")
    return path


def batch(jobs: Path, *extra, **popen):
    return subprocess.run([sys.executable, "-m", "classic_bake", "batch", str(jobs), *extra],
                          capture_output=True, text=True, timeout=600, **popen)


def statuses(out: Path) -> dict:
    return {run["folder"]: run["status"] for run in json.loads((out / SUMMARY).read_text())}


@pytest.mark.slow
def test_two_workers_equal_single_runs_and_a_second_run_skips_everything(tmp_path):
    jobs = write_jobs(tmp_path, scenes=("bump",))  # one scene x two techniques: two runs at once
    done = batch(jobs)
    assert done.returncode == 0, done.stdout + done.stderr
    out = tmp_path / "out"
    runs = statuses(out)
    assert len(runs) == 2 and set(runs.values()) == {"done"}
    assert "2 runs: 2 done, 0 skipped (unchanged), 0 failed" in done.stdout
    # Each run's render.exr against the same command run alone, in this process (all cores):
    # bit for bit; the kernels' thread split changes which rows a thread takes, not a pixel.
    for folder in runs:
        scene, technique = folder.split("-")[:2]
        single = tmp_path / "single" / folder
        assert main([technique, str(SAMPLES / f"{scene}.blend"), "--out", str(single),
                     "--resolution", *map(str, SIZE), "--adaptive", "0", "--quiet"]) == 0
        batched, alone = read_exr(out / folder / "render.exr"), read_exr(single / "render.exr")
        assert batched.shape == (SIZE[1], SIZE[0], 3) and np.array_equal(batched, alone), folder
        manifest = json.loads((out / folder / MANIFEST).read_text())
        assert manifest["inputs"]["technique"] == technique
        assert manifest["inputs"]["settings"] == {"adaptive": 0}
    again = batch(jobs)
    assert again.returncode == 0 and set(statuses(out).values()) == {"skipped"}
    assert "2 runs: 0 done, 2 skipped (unchanged), 0 failed" in again.stdout
    # A deleted output re-runs just its run; --force re-runs all.
    gone = sorted(runs)[0]
    (out / gone / "render.png").unlink()
    again = batch(jobs)
    assert again.returncode == 0
    assert {f for f, s in statuses(out).items() if s == "done"} == {gone}
    forced = batch(jobs, "--force", "--workers", "1")
    assert forced.returncode == 0 and set(statuses(out).values()) == {"done"}


@pytest.mark.slow
def test_a_batch_killed_half_way_finishes_the_rest(tmp_path):
    jobs = write_jobs(tmp_path, workers=1)
    out = tmp_path / "out"
    # A session of its own, so that the batch and the worker it started are killed together.
    process = subprocess.Popen([sys.executable, "-m", "classic_bake", "batch", str(jobs)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                               start_new_session=True)
    try:
        deadline = time.monotonic() + 300
        while not list(out.glob(f"*/{MANIFEST}")) and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    finished = {p.parent.name for p in out.glob(f"*/{MANIFEST}")}
    assert 1 <= len(finished) < 4
    done = batch(jobs)
    assert done.returncode == 0, done.stdout + done.stderr
    runs = statuses(out)
    assert len(runs) == 4
    assert {f for f, s in runs.items() if s == "skipped"} == finished
    assert all(s == "done" for f, s in runs.items() if f not in finished)


def test_settings_become_the_techniques_options(tmp_path):
    assert settings_argv({"depth": 2, "final_gather": False, "all_modes": True,
                          "resolution": [4, 3]}) == [
        "--depth", "2", "--no-final-gather", "--all-modes", "--resolution", "4", "3"]
    jobs = tmp_path / "jobs.toml"
    jobs.write_text(f"[[job]]\nscenes = ['{SAMPLES}/*.blend']\ntechniques = ['trace']\n"
                    "settings = [{}, { name = 'deep', depth = 3 }, { supersample = 2 }]\n")
    batch = load_batch(jobs)
    scenes = sorted(p.stem for p in SAMPLES.glob("*.blend"))
    assert [r.name for r in batch.runs[:3]] == [f"{scenes[0]}-trace", f"{scenes[0]}-trace-deep",
                                                f"{scenes[0]}-trace-supersample-2"]
    assert len(batch.runs) == 3 * len(scenes) and batch.out == tmp_path / "out" / "batch"
    assert batch.runs[1].argv(None)[-2:] == ["--depth", "3"]


@pytest.mark.parametrize("text, words", [
    ("[[job]]\nscenes = ['missing.blend']\ntechniques = ['trace']\n", "no scene file"),
    (f"[[job]]\nscenes = ['{SAMPLES}/bump.blend']\ntechniques = ['nope']\n", "unknown technique"),
    (f"[[job]]\nscenes = ['{SAMPLES}/bump.blend']\ntechniques = ['trace']\n"
     "settings = { depht = 2 }\n", "unrecognized arguments"),
    ("out = 'x'\n", "no [[job]]"),
    ("[[job]\n", "jobs.toml"),
])
def test_bad_job_files_fail_before_any_worker(tmp_path, text, words):
    path = tmp_path / "jobs.toml"
    path.write_text(text)
    with pytest.raises(UsageError, match=re.escape(words)):
        load_batch(path)
    assert not (tmp_path / "out").exists()


def test_workers_run_this_python_or_the_given_blender(tmp_path):
    from classic_bake.pipeline.commands.batch import worker_command, worker_environment

    assert worker_command(None) == [sys.executable, "-m", "classic_bake"]  # the bpy module
    blender = tmp_path / "blender"
    assert worker_command(blender) == [str(blender), "-b", "-c", "classic_bake"]
    share = worker_environment(2)["PYTHON_CPU_COUNT"]
    assert share == str(max(1, (os.cpu_count() or 1) // 2))


@pytest.mark.slow
def test_a_changed_scene_file_reruns_its_runs(tmp_path):
    import bpy

    scene = tmp_path / "scene.blend"
    bpy.ops.wm.open_mainfile(filepath=str(SAMPLES / "bump.blend"), load_ui=False, use_scripts=False)
    bpy.ops.wm.save_as_mainfile(filepath=str(scene), copy=True)
    jobs = tmp_path / "jobs.toml"
    jobs.write_text("out = 'out'\nresolution = [8, 6]\n\n[[job]]\nscenes = ['scene.blend']\n"
                    "techniques = ['trace']\n")
    assert batch(jobs).returncode == 0
    assert batch(jobs).returncode == 0 and statuses(tmp_path / "out") == {"scene-trace": "skipped"}
    bpy.data.objects["Orange"].location.z += 0.1  # the scene changes: its hash does
    bpy.ops.wm.save_as_mainfile(filepath=str(scene))
    assert batch(jobs).returncode == 0 and statuses(tmp_path / "out") == {"scene-trace": "done"}
