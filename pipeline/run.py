"""Running one command: its arguments, the .blend it opens, staging, timing, metrics.json and the
atomic publish of its outputs."""

from __future__ import annotations

import argparse
import os
import signal
import threading
import warnings
from contextlib import contextmanager
from pathlib import Path

from . import time_estimate
from .arguments import Parser, pixels, positive_float
from .command import Command, RunContext
from .outputs import PhaseTimer, Staging, UsageError, safe_name

# Memory a run may plan for unless --memory-budget-gb says otherwise (lowered to the memory the
# machine has available, where it says): estimates above it are refused before the work starts.
DEFAULT_MEMORY_BUDGET_GB = 8.0
# Peak bytes per camera pixel of a render (render.exr): every pass traces all pixels as one
# wavefront. Measured: `trace` of raytrace.blend peaked at 0.45 GB at 200 x 150 and 1.41 GB at
# 800 x 600 (bpy itself ~0.4 GB): ~2.2 kB per pixel; the sample count adds passes, not memory.
RENDER_BYTES_PER_PIXEL = 2200
# Peak bytes per lightmap texel of a bake. Measured: `texture` of cornell_box.blend peaked at
# 0.35 GB with 0.46 M texels (--lightmap-size 256) and 0.95 GB with 7.4 M (1024): ~85 B a texel.
LIGHTMAP_BYTES_PER_TEXEL = 100
# Peak bytes per scene triangle (Blender's mesh, the snapshot, the BVH, lightmap UVs and bake
# targets), by command. Measured with bench/huge.py on a 2M-triangle terrain (bpy itself ~0.3 GB):
# info peaked at 1.21 GB, lightmap-uv 1.65, bump 1.74, trace 1.8, envmap 1.99 (0.45-0.85 kB a
# triangle), texture 3.22 (1.46 kB), shadowmap 5.0 (2.35 kB: its depth maps' fragments).
SCENE_BYTES_PER_TRIANGLE = {"default": 1000, "info": 600, "texture": 1600, "shadowmap": 2500}
GB = 1 << 30
# A camera scaled below this along any axis sees a flat image (its rays collapse).
CAMERA_MIN_SCALE = 1e-6

# The first bytes of a .blend: plain, gzip-compressed (before 3.0) or zstd-compressed (3.0+).
BLEND_MAGICS = (b"BLENDER", b"\x1f\x8b", b"\x28\xb5\x2f\xfd")


def add_scene_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments every scene command takes."""
    p.add_argument("scene", type=Path, metavar="SCENE.blend", help="the .blend file to read")
    p.add_argument("--out", type=Path, default=None,
                   help="output folder (default: out/COMMAND/SCENE)")
    p.add_argument("--save-blend", action="store_true",
                   help="also write result.blend with the results written back")
    p.add_argument("--resolution", type=pixels, nargs=2, metavar=("W", "H"),
                   help="render.exr size in pixels (default: the scene's render size)")
    p.add_argument("--memory-budget-gb", type=positive_float, default=None, metavar="GB",
                   help="refuse, before any work, a run estimated to need more memory than this "
                        f"(default {DEFAULT_MEMORY_BUDGET_GB:g}, or the memory available if less)")
    p.add_argument("--time-budget-s", type=positive_float, default=None, metavar="S",
                   help="refuse, before any work, a run estimated to take longer than this many "
                        "seconds (default: no limit; the estimate is rough, within about 2x)")


def command_args(cmd: Command, scene: Path, out: Path, resolution=None, argv=()) -> argparse.Namespace:
    """The namespace `cmd` would get from `COMMAND SCENE --out OUT [argv]` on the command line:
    for running one command from another (demo, compare) with the command's own defaults."""
    parser = Parser()
    cmd.add_arguments(parser)
    args = parser.parse_args(list(argv))
    args.scene, args.out, args.save_blend, args.resolution = scene, out, False, resolution
    return args


def check_blend(path: Path) -> Path:
    """The resolved path of a readable .blend file, or UsageError naming what is wrong."""
    if not path.exists():
        raise UsageError(f"scene file not found: {path}")
    if not path.is_file():
        raise UsageError(f"scene path is not a file: {path}")
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError as exc:
        raise UsageError(f"cannot read scene file {path}: {exc.strerror}") from exc
    if not head.startswith(BLEND_MAGICS):
        raise UsageError(f"not a .blend file: {path}")
    return path.resolve()


def open_blend(path: Path) -> list[str]:
    """Open a .blend with script auto-execution off (drivers and registered scripts do not run),
    in Object Mode: a file saved in Edit Mode is left for Object Mode, as a user would before a
    bake, so that what is written into its meshes stays there (Edit Mode's mesh would overwrite
    it, on saving result.blend too). Returns what it did, one line each."""
    import bpy

    try:
        bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    except RuntimeError as exc:
        first = str(exc).strip().splitlines()[-1] if str(exc).strip() else "unknown error"
        raise UsageError(f"cannot open {path}: {first}") from exc
    from ..addon.bridge.object_mode import leave_edit_mode

    return [f"{line}: the file was saved in it" for line in leave_edit_mode(bpy.context)]


def versions() -> dict:
    import platform

    import numpy

    out = {"python": platform.python_version(), "numpy": numpy.__version__}
    try:
        import bpy

        out["blender"] = bpy.app.version_string
    except ImportError:
        pass
    return out


_stopped: list[int] = []  # signals received during this run
_deferring: list[bool] = [False]


def _interrupt(signum, frame):
    _stopped.append(signum)
    if not _deferring[0]:
        raise KeyboardInterrupt


@contextmanager
def interrupts_deferred():
    """SIGINT and SIGTERM recorded but acted on only after the block: opening a file runs
    Blender's load handlers, which would print and swallow the KeyboardInterrupt, and a publish
    half done is worse than one finished or never started."""
    _deferring[0] = True
    try:
        yield
    finally:
        _deferring[0] = False
    _check_stopped()


def _check_stopped() -> None:
    """Raise KeyboardInterrupt again if a signal's was swallowed (Blender's handlers catch and
    print exceptions raised inside them)."""
    if _stopped:
        raise KeyboardInterrupt


@contextmanager
def sigterm_as_interrupt():
    """SIGTERM (what `timeout`, CI and service managers send) takes the same clean path as
    Ctrl-C: KeyboardInterrupt, so the staging folder is removed and earlier outputs stay."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _stopped.clear()
    # Ctrl-C too, where Python's own handler has it: recorded, so that a swallowed one still stops.
    signums = [signal.SIGTERM] + [signal.SIGINT] * (
        signal.getsignal(signal.SIGINT) is signal.default_int_handler)
    previous = {signum: signal.signal(signum, _interrupt) for signum in signums}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        _stopped.clear()


def check_save_blend(scene_path: Path, out_dir: Path) -> None:
    """--save-blend writes OUT/result.blend: refuse when that is the input scene itself (chaining
    `CMD D/result.blend --out D --save-blend`), which is never written in place."""
    target = out_dir / "result.blend"
    try:
        same = target.exists() and os.path.samefile(target, scene_path)
    except OSError:
        same = False
    if same:
        raise UsageError(f"--save-blend would overwrite the input scene {scene_path} (it is "
                         f"{target}); choose another --out, or copy the scene first")


def check_camera(cmd: Command) -> None:
    """A technique writes render.exr, the camera's view: with no usable camera, say so before
    any work (the Blender panel bakes lightmaps without one)."""
    if not cmd.is_technique:
        return
    import bpy

    camera = bpy.context.scene.camera
    if camera is None:
        raise UsageError(f"{cmd.name}: the scene has no camera, so there is no render.exr to "
                         "write; add a camera (the Blender panel bakes lightmaps without one)")
    if camera.type != "CAMERA":
        raise UsageError(f"{cmd.name}: the scene camera '{camera.name}' is a "
                         f"{camera.type.lower()} object, not a camera")
    if getattr(camera.data, "type", "PERSP") == "PANO":
        raise UsageError(f"{cmd.name}: camera '{camera.name}' is panoramic: only perspective "
                         "and orthographic cameras are supported")
    import numpy as np

    linear = np.array(camera.matrix_world, np.float64)[:3, :3]
    if not np.isfinite(linear).all() or np.linalg.norm(linear, axis=0).min() < CAMERA_MIN_SCALE:
        raise UsageError(f"{cmd.name}: camera '{camera.name}' is scaled to (nearly) 0, so it "
                         "sees nothing; give it a scale of 1")


def missing_libraries() -> list[str]:
    """One line per linked library whose file is missing (its objects are simply absent)."""
    import bpy

    return [f"library '{lib.name}': file {lib.filepath} not found, so what it links is missing"
            for lib in bpy.data.libraries
            if not os.path.exists(bpy.path.abspath(lib.filepath, library=lib.library))]


def available_memory_bytes() -> int | None:
    """The memory the machine has available now (Linux /proc/meminfo MemAvailable), or None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def memory_budget(args) -> tuple[float, str]:
    """(bytes a run may plan for, where that figure comes from)."""
    given = getattr(args, "memory_budget_gb", None)
    if given is not None:
        return given * GB, "--memory-budget-gb"
    budget, source = DEFAULT_MEMORY_BUDGET_GB * GB, "the default budget"
    available = available_memory_bytes()
    if available is not None and available < budget:
        budget, source = float(available), "the memory available"
    return budget, source


def _scene_triangles(context, with_area_over: float = 0.0) -> tuple[int, float]:
    """(triangles of the renderable evaluated meshes, and the sum over them of max(1, 2 area /
    with_area_over^2): patches of that edge, when `with_area_over` > 0)."""
    import numpy as np

    from ..addon.bridge import mesh as bridge_mesh
    from ..addon.bridge.transforms import matrix_array

    depsgraph = context.evaluated_depsgraph_get()
    count, patches = 0, 0.0
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != "MESH" or obj.original.hide_render:
            continue
        verts, _, _, _ = bridge_mesh.mesh_triangles(obj.data)
        count += len(verts)
        if with_area_over > 0.0 and len(verts):
            m = matrix_array(inst.matrix_world)
            with np.errstate(all="ignore"):
                c = (bridge_mesh.mesh_positions(obj.data).astype(np.float64) @ m[:3, :3].T)[verts]
                area = 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)
                per = np.maximum(1.0, np.nan_to_num(2.0 * area / with_area_over ** 2, posinf=1e30))
            patches += float(per.sum())
    return count, patches


def estimate_memory(cmd: Command, args, sizes: dict | None = None) -> list[tuple[float, str, str]]:
    """What a technique run will need before it starts: [(bytes, what, the flag that lowers
    it)]. The scene: its triangles x SCENE_BYTES_PER_TRIANGLE (by command); the camera view:
    pixels x RENDER_BYTES_PER_PIXEL; lightmaps: their texels at the planned sizes x
    LIGHTMAP_BYTES_PER_TEXEL; radiosity and the hybrid's first pass: the solve's estimate
    (`kernels/radiosity/planning.memory_estimate`) over the patches it will make, at least one
    per triangle (--patch-size: the surface over that edge; else the --patches budget).
    `sizes`, when given, receives the work's size: rays, texels, triangles, patches."""
    import bpy

    from ..addon.bridge import mesh as bridge_mesh
    from ..jobs.techniques import BY_NAME
    from ..kernels.radiosity import planning

    scene = bpy.context.scene
    out = []
    sizes = {} if sizes is None else sizes
    triangles = sizes["triangles"] = _scene_triangles(bpy.context)[0]
    per = SCENE_BYTES_PER_TRIANGLE.get(cmd.name, SCENE_BYTES_PER_TRIANGLE["default"])
    out.append((triangles * per, f"the scene's {triangles:,} triangles",
                "fewer triangles (decimate, or hide objects from the render)"))
    if cmd.is_technique:
        if args.resolution:
            width, height = args.resolution
        else:
            pct = scene.render.resolution_percentage / 100.0
            width = max(1, int(scene.render.resolution_x * pct))
            height = max(1, int(scene.render.resolution_y * pct))
        samples = getattr(args, "supersample", 1) or 1
        sizes["rays"] = width * height * samples ** 2
        out.append((width * height * RENDER_BYTES_PER_PIXEL,
                    f"the camera view at {width} x {height} pixels ({width * height * samples ** 2:,} "
                    "rays a bounce)", "--resolution W H"))
    technique = BY_NAME.get(cmd.name)
    if technique is not None and "lightmap_size" in {o.name for o in technique.all_options()}:
        from ..jobs.lightmaps import lightmap_plan, lightmap_settings, mesh_objects

        uv_name, uv_settings = lightmap_settings(technique.values_from_args(args))
        objects = [o for o in mesh_objects(bpy.context)
                   if bridge_mesh.object_problem(o) is None]
        texels = sum(size * size for size in lightmap_plan(objects, uv_settings).values())
        sizes["texels"] = texels
        unwrap = sum(len(mesh.loop_triangles) for mesh in
                     {o.data for o in objects if uv_name not in o.data.uv_layers})
        if unwrap:  # the bake charts these first (xatlas)
            sizes["unwrap_triangles"] = unwrap
        out.append((texels * LIGHTMAP_BYTES_PER_TEXEL, f"the lightmaps of {len(objects)} objects "
                    f"({texels:,} texels)", "a smaller --lightmap-size"))
    if cmd.name in ("radiosity", "hybrid"):  # the hybrid's first pass is the radiosity solve
        settings = technique.settings(technique.values_from_args(args), None)
        settings = getattr(settings, "radiosity", settings)
        if settings.patch_size > 0.0:  # the surface over that edge (the count is known)
            by_size = _scene_triangles(bpy.context, settings.patch_size)[1]
            patches, flag = max(triangles, by_size), "a larger --patch-size"
        else:
            patches, flag = max(triangles, settings.patch_budget), "fewer triangles"
        n = int(min(patches, 1e15))
        sizes["patches"] = n
        solver = settings.solver if settings.solver != "auto" else (
            "gauss_seidel" if n * n * 8 <= settings.dense_memory_limit else "progressive")
        lean = settings if settings.samples_per_side else type(settings)(
            **{**{f: getattr(settings, f) for f in settings.__dataclass_fields__},
               "samples_per_side": 1})
        need = planning.memory_estimate(n, triangles, lean, solver)["total"]
        out.append((float(need), f"the radiosity solve over {n:,} patches ({triangles:,} "
                    f"triangles, {solver.replace('_', '-')} solver)", flag))
    return out


def check_estimates(cmd: Command, args, ctx: RunContext | None = None) -> None:
    """Refuse, before any work, a run whose estimate (the sum of its parts) exceeds the memory
    budget, or the time budget when --time-budget-s is given: one line with the estimate, its
    largest part, the budget and the flag that lowers that part. With `ctx`, the estimates are
    said in the run's first lines and kept in metrics.json (`estimate`). Every command that opens
    a scene is estimated (info and the map makers by their triangles and texels)."""
    budget, source = memory_budget(args)
    sizes: dict = {}
    try:
        parts = estimate_memory(cmd, args, sizes)
    except ValueError as exc:  # settings the kernel refuses (--patches 0): the same one line
        raise UsageError(f"{cmd.name}: {exc}") from exc
    total = sum(need for need, _, _ in parts)
    timing = time_estimate.estimate_seconds(cmd.name, sizes)
    seconds = sum(s for s, _, _ in timing)
    if ctx is not None:
        ctx.record.extra["estimate"] = {
            "memory_bytes": int(total), "seconds": round(seconds, 1), "sizes": sizes,
            "note": "rough, before the work started (pipeline/time_estimate.py)"}
        ctx.say(f"estimate: about {total / GB:.2g} GB and {time_estimate.rough_seconds(seconds)} "
                "(rough)")
    time_budget = getattr(args, "time_budget_s", None)
    if time_budget is not None and seconds > time_budget:
        _, what, flag = max(timing)
        lower = f"lower it with {flag}, or raise" if flag else "raise"
        raise UsageError(f"{cmd.name}: would take {time_estimate.rough_seconds(seconds)} (rough), "
                         f"over --time-budget-s {time_budget:g}, mostly for {what}; {lower} "
                         "--time-budget-s")
    if total > budget:
        _, what, flag = max(parts)  # the largest part, and the flag that lowers it
        raise UsageError(f"{cmd.name}: would need about {total / GB:.3g} GB, over {source} of "
                         f"{budget / GB:.3g} GB, mostly for {what}; lower it with {flag}, or "
                         "raise --memory-budget-gb")


def run_command(cmd: Command, args: argparse.Namespace) -> int:
    """Run one parsed command with staging, timing, metrics.json and publish."""
    with sigterm_as_interrupt():
        return _run_command(cmd, args)


def _run_command(cmd: Command, args: argparse.Namespace) -> int:
    if not cmd.needs_scene:
        cmd.run(RunContext(cmd, args, None, PhaseTimer()))
        return 0
    scene_path = check_blend(args.scene)
    out_dir = args.out or Path("out") / cmd.name / safe_name(scene_path.stem)
    if args.save_blend:
        check_save_blend(scene_path, out_dir)
    staging = Staging(out_dir)
    timer = PhaseTimer()
    ctx = RunContext(cmd, args, staging, timer)
    try:
        with timer.phase("open"), interrupts_deferred():
            for line in open_blend(scene_path):
                ctx.say(f"  {line}")
        check_camera(cmd)
        with timer.phase("estimate"):
            check_estimates(cmd, args, ctx)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", RuntimeWarning)
            cmd.run(ctx)
        _note_warnings(ctx, caught)
        missing = missing_libraries()
        if missing:  # in metrics.json beside what the snapshot ignored, and said once
            ctx.record.extra["ignored"] = [*ctx.record.extra.get("ignored", ()), *missing]
            for why in missing:
                ctx.say(f"  missing: {why}")
        _check_stopped()
        tile = getattr(args, "tile", None)
        if cmd.is_technique and tile is None and not (staging.path / "render.exr").exists():
            raise UsageError(f"{cmd.name}: the technique wrote no render.exr")
        if cmd.is_technique:  # `info` lists them among what it ignores
            _say_skipped(ctx)
        if args.save_blend:
            import bpy

            with timer.phase("save_blend"):
                bpy.ops.wm.save_as_mainfile(filepath=str(staging.file("result.blend")), copy=True,
                                            compress=True)
        record = ctx.record
        record.seconds = timer.totals()
        record.versions = versions()
        # A tile's record goes into its folder (jobs/tiles.py), where `merge` reads it.
        record_name = "metrics.json" if tile is None else f"{tile.folder}/metrics.json"
        record.outputs = [f for f in staging.files if f != record_name]
        if tile is not None:
            record.extra["tile"] = {"index": tile.index, "count": tile.count, "name": tile.name}
        if staging.renamed:  # requested name -> the safe, unique file it was written as
            record.extra["file_names"] = dict(staging.renamed)
        staging.write_json(record_name, record.as_json())
        with interrupts_deferred():
            published = staging.publish()
    except OSError as exc:  # a full disk, a permission changed mid-run: one line, nothing changed
        staging.discard()
        where = f" ({exc.filename})" if exc.filename else ""
        raise UsageError(f"cannot write the outputs{where}: {exc.strerror or exc}; earlier "
                         f"outputs in {out_dir} are as they were") from exc
    except BaseException:
        staging.discard()
        raise
    ctx.say(f"wrote {len(published)} files to {out_dir}")
    return 0


def _say_skipped(ctx: RunContext) -> None:
    """Print each object the snapshot skipped (bad geometry) that the command did not print."""
    said = set(ctx.record.extra.get("skipped", ()))
    for why in ctx.record.extra.get("ignored", ()):
        if why.endswith("; skipped") and why not in said:
            ctx.say(f"  skipped: {why.removesuffix('; skipped')}")


def _note_warnings(ctx: RunContext, caught) -> None:
    """NumPy's RuntimeWarnings (overflow, invalid value) summarised once, not leaked to stderr:
    one line, and each distinct one with its place in metrics.json `warnings`."""
    seen = {}
    for w in caught:
        if issubclass(w.category, RuntimeWarning):
            key = f"{Path(w.filename).name}:{w.lineno}: {w.message}"
            seen[key] = seen.get(key, 0) + 1
        else:  # others as Python would show them
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    if seen:
        ctx.record.extra["warnings"] = [f"{key} (x{n})" for key, n in seen.items()]
        ctx.say(f"  note: {sum(seen.values())} numerical warnings, listed in metrics.json "
                "'warnings'")
