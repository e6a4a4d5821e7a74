"""Two million triangles through every command: each run either finishes within the memory
budget or is refused before any work with its estimate (issue 43).

    .venv/bin/python bench/huge.py [--triangles 2000000] [--commands NAME ...] [--timeout S]
                                   [--resolution W H]

The scene is Blender's default one (Cube, Camera, Light) over a rolling terrain of about
`--triangles` triangles (bumped by an image height), with a small mirror ball, built here and
saved to out/bench/huge.blend. Each command runs as `python -m classic_bake COMMAND huge.blend
--out TMP` in a process of its own, under a watchdog (a run past --timeout is a hang: its
threads' stacks are saved, then it is killed) and with `--time-budget-s` at the same seconds (a
run its own estimate puts past them is refused before any work); its peak resident memory is
read from the kernel's accounting of the finished child (wait4). The outcome of a run: ok (exit
0, no traceback), refused (exit 2 and one `classic_bake: error:` line; `with_estimate` when the
line gives the memory or time it would need), failed, or hung. The memory budget is the
commands' default (pipeline/run.py: the default budget or the memory available, whichever is
less).

Writes out/bench/huge.json: {"bench": "huge", "ratios": {"held_fraction": runs that finished
within the budget or were refused in one line, over all runs; "peak_over_budget": the largest
peak resident memory over the budget}, "figures": {per command: outcome, seconds, peak GB, the
estimate line, the refusal}, "versions"}.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import OUT_DIR, format_table, versions, write_report  # noqa: E402
from scenes import _material  # noqa: E402
from soak import COMMANDS as TECHNIQUE_COMMANDS  # noqa: E402
from soak import RUNNER, STACK_GRACE_S, TAIL_CHARS  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SCENE = OUT_DIR / "huge.blend"
COMMANDS = ("info", *TECHNIQUE_COMMANDS)
TRIANGLES = 2_000_000
# A run past this is a hang. xatlas charts two million triangles in minutes, not tens of them.
TIMEOUT_S = 1800.0
RESOLUTION = (160, 120)
POLL_S = 0.2
GB = 1024.0 ** 3


def build_scene(path: Path, triangles: int) -> int:
    """The default scene with a rolling terrain of about `triangles` triangles under it (a grid
    of quads, each two triangles) and a small mirror ball (so that `envmap` has an object to
    map); saved to `path`. Returns the scene's triangle count."""
    import bpy
    import numpy as np

    bpy.ops.wm.read_factory_settings(use_empty=False)
    side = max(2, int(round((triangles / 2.0) ** 0.5)))
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=side + 1, y_subdivisions=side + 1, size=12.0,
                                    location=(0.0, 0.0, -1.2))
    terrain = bpy.context.active_object
    terrain.name = "Terrain"
    co = np.empty(len(terrain.data.vertices) * 3, np.float32)
    terrain.data.vertices.foreach_get("co", co)
    co = co.reshape(-1, 3)
    co[:, 2] = 0.15 * np.sin(1.3 * co[:, 0]) * np.cos(0.9 * co[:, 1])
    terrain.data.vertices.foreach_set("co", co.ravel())
    terrain.data.update()
    terrain.data.materials.append(_rough_ground())
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.8,
                                         location=(2.5, 0.0, 0.0))
    ball = bpy.context.active_object
    ball.name = "Mirror"
    bpy.ops.object.shade_smooth()
    mirror = _material(bpy, "Mirror", (0.8, 0.8, 0.8))
    bsdf = next(n for n in mirror.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.0
    ball.data.materials.append(mirror)
    for obj in bpy.context.scene.objects:  # `normalmap` maps the selected meshes
        obj.select_set(obj is terrain)
    bpy.context.view_layer.objects.active = terrain
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    count = 0
    for obj in bpy.context.scene.objects:
        if obj.type == "MESH":
            mesh = obj.evaluated_get(depsgraph).data
            mesh.calc_loop_triangles()
            count += len(mesh.loop_triangles)
    return count


def _rough_ground():
    """A Principled material whose normal is a Bump node over an image height (a packed 256^2
    image of ripples), so that `normalmap` has a relief to make a map of."""
    import bpy
    import numpy as np

    size = 256
    u, v = np.meshgrid(np.linspace(0.0, 8.0 * np.pi, size), np.linspace(0.0, 6.0 * np.pi, size))
    height = 0.5 + 0.25 * np.sin(u) * np.cos(v)
    image = bpy.data.images.new("GroundHeight", size, size, float_buffer=True)
    image.pixels.foreach_set(np.repeat(height.ravel(), 4).astype(np.float32))
    image.pack()
    mat = _material(bpy, "Ground", (0.8, 0.8, 0.8))
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == "BSDF_PRINCIPLED")
    texture = nodes.new("ShaderNodeTexImage")
    texture.image = image
    bump = nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = 0.5
    links.new(texture.outputs["Color"], bump.inputs["Height"])
    links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    return mat


def run_watched(command: str, scene: Path, out: Path, resolution, timeout: float) -> dict:
    """One run: outcome, seconds, peak resident GB (wait4's ru_maxrss), the estimate line."""
    import subprocess

    args = [sys.executable, "-c", RUNNER, command, str(scene), "--out", str(out)]
    if command != "lightmap-uv":
        args += ["--resolution", str(resolution[0]), str(resolution[1])]
    if command not in ("info", "lightmap-uv"):
        # A run its own estimate puts past the watchdog is refused up front, as a user's would be.
        args += ["--time-budget-s", f"{timeout:g}"]
    with tempfile.TemporaryFile("w+") as stdout, tempfile.TemporaryFile("w+") as stderr:
        start = time.perf_counter()
        proc = subprocess.Popen(args, stdout=stdout, stderr=stderr, text=True, cwd=ROOT)
        hung, status, usage = False, None, None
        while status is None:
            pid, code, rusage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                status, usage = code, rusage
            elif time.perf_counter() - start > timeout and not hung:
                hung = True
                proc.send_signal(signal.SIGUSR1)  # its threads' stacks, then the end
                time.sleep(STACK_GRACE_S)
                proc.kill()
            else:
                time.sleep(POLL_S)
        proc.returncode = os.waitstatus_to_exitcode(status)
        seconds = time.perf_counter() - start
        stdout.seek(0)
        stderr.seek(0)
        out_text, err_text = stdout.read(), stderr.read()
    lines = err_text.strip().splitlines()
    estimate = next((ln.strip() for ln in out_text.splitlines() if "estimate:" in ln), "")
    if hung:
        outcome, detail = "hung", err_text[-TAIL_CHARS:]
    elif proc.returncode == 0 and "Traceback" not in err_text:
        outcome, detail = "ok", ""
    elif proc.returncode == 2 and len(lines) == 1 and lines[0].startswith("classic_bake: error:"):
        outcome, detail = "refused", lines[0]
    else:
        outcome, detail = "failed", f"exit {proc.returncode}: {err_text[-TAIL_CHARS:]}"
    return {"command": command, "outcome": outcome, "seconds": round(seconds, 1),
            "peak_gb": round(usage.ru_maxrss * 1024 / GB, 2), "estimate": estimate,
            "detail": detail}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--triangles", type=int, default=TRIANGLES)
    parser.add_argument("--commands", nargs="+", default=list(COMMANDS), choices=COMMANDS)
    parser.add_argument("--timeout", type=float, default=TIMEOUT_S)
    parser.add_argument("--resolution", type=int, nargs=2, default=RESOLUTION, metavar=("W", "H"))
    args = parser.parse_args()

    from classic_bake.pipeline.run import memory_budget

    budget, source = memory_budget(argparse.Namespace(memory_budget_gb=None))
    triangles = build_scene(SCENE, args.triangles)
    print(f"{SCENE.name}: {triangles:,} triangles; memory budget {budget / GB:.1f} GB "
          f"({source})", flush=True)
    runs = []
    with tempfile.TemporaryDirectory(prefix="huge-") as tmp:
        for command in args.commands:
            run = run_watched(command, SCENE, Path(tmp) / command, args.resolution, args.timeout)
            # Held: finished within the budget, or refused in one line (the memory estimate's
            # refusals say the GB they would need).
            run["with_estimate"] = run["outcome"] == "refused" and (
                "GB" in run["detail"] or "--time-budget-s" in run["detail"])
            run["held"] = ((run["outcome"] == "ok" and run["peak_gb"] * GB <= budget)
                           or run["outcome"] == "refused")
            runs.append(run)
            print(f"{command}: {run['outcome']} in {run['seconds']} s, peak {run['peak_gb']} GB "
                  f"{run['estimate']} {run['detail'][:300]}", flush=True)
    print(format_table(["command", "outcome", "s", "peak GB", "held"],
                       [[r["command"], r["outcome"], r["seconds"], r["peak_gb"], r["held"]]
                        for r in runs]))
    ratios = {"held_fraction": sum(r["held"] for r in runs) / len(runs),
              "peak_over_budget": max(r["peak_gb"] for r in runs) * GB / budget}
    figures = {"triangles": triangles, "budget_gb": round(budget / GB, 2), "budget_from": source,
               "resolution": list(args.resolution), "timeout_s": args.timeout, "runs": runs}
    path = write_report("huge", ratios, figures, versions())
    print(f"wrote {path}")
    return 0 if all(r["held"] for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
