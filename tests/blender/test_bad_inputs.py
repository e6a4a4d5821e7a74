"""Bad inputs through the command line (issue 43): each scene is built by a few lines of `bpy` from
Blender's default scene (Cube, Camera, Light), saved to a temporary folder and run as
`python -m classic_bake ...` in a subprocess with a timeout (a hang fails the test). Each case
asserts the exit code and either one clear line on stderr (no traceback) or the sensible result,
and that earlier outputs are untouched where a run fails. Refusals that come before any work
(bad flags, budgets, cameras) call the same entry point in this process
(`support.cli_calls.refusal`)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import bpy
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from support.cli_calls import refusal  # noqa: E402

# A hang (xatlas looping on inf coordinates ran for minutes) fails well before this.
TIMEOUT_S = 120
SMALL = ("--resolution", "16", "12", "--lightmap-size", "16")


def run_cli(*args, timeout=TIMEOUT_S):
    return subprocess.run([sys.executable, "-m", "classic_bake", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


def assert_one_line_error(done, *words):
    assert done.returncode == 2, (done.stdout, done.stderr)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr, done.stderr
    assert lines[0].startswith("classic_bake: error:")
    for word in words:
        assert word in lines[0], lines[0]


def assert_clean(done):
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr and "Warning" not in done.stderr, done.stderr
    figures = [ln for ln in done.stdout.lower().splitlines() if "non-finite" not in ln]
    assert not any(word in ln.split() or f"{word}," in ln for ln in figures
                   for word in ("nan", "inf")), done.stdout  # no figure printed as nan


def default_scene():
    bpy.ops.wm.read_factory_settings(use_empty=False)
    assert {"Cube", "Camera", "Light"} <= set(bpy.data.objects.keys())
    return bpy.context.scene


def add_mesh(name, verts, faces, location=(0.0, 0.0, 0.0)):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_plane(name, z=-1.5):
    return add_mesh(name, [(-3, -3, z), (3, -3, z), (3, 3, z), (-3, 3, z)], [(0, 1, 2, 3)])


def save(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


def snapshot_dir(folder: Path) -> dict:
    """{relative path: bytes} of every file under `folder` (hidden ones included)."""
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def hidden(folder: Path) -> list[str]:
    return [p.name for p in folder.iterdir() if p.name.startswith(".")]


# --- 1. data lost or overwritten ---------------------------------------------------------------

HOSTILE_NAMES = [".", "..", "a/b", "a_b", "Würfel", "W rfel", "Cube", "cube",
                 "L" * 40 + "ong" * 30 + "A", "L" * 40 + "ong" * 30 + "B"]


def test_names_that_clean_alike_never_share_a_file(tmp_path):
    default_scene()
    bpy.data.objects.remove(bpy.data.objects["Cube"])
    for k, name in enumerate(HOSTILE_NAMES):
        add_mesh(name, [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [(0, 1, 2, 3)],
                 location=(2 * k - 10, 0, 0))
    names = sorted(o.name for o in bpy.data.objects if o.type == "MESH")  # as Blender kept them
    assert len(names) == len(HOSTILE_NAMES)
    scene = save(tmp_path / "names.blend")
    out = tmp_path / "out"
    done = run_cli("texture", scene, "--out", out, *SMALL)
    assert_clean(done)
    metrics = json.loads((out / "metrics.json").read_text())
    where = metrics["lightmap_files"]
    assert sorted(where) == names
    assert len(set(map(str.casefold, where.values()))) == len(names)  # one file per object
    for name, rel in where.items():
        assert (out / rel).is_file() and rel.endswith("_albedo.exr"), (name, rel)
        assert (out / rel.replace(".exr", ".png")).is_file()  # the preview beside it, not over it
        assert len(Path(rel).name) <= 120
    exrs = list((out / "lightmaps").glob("*.exr"))
    assert len(exrs) == len(names) == len(list((out / "lightmaps").glob("*.png")))
    assert where["a_b"] == "lightmaps/a_b_albedo.exr"  # a name that is already safe keeps itself


def test_save_blend_never_writes_the_input_in_place(tmp_path):
    default_scene()
    out = tmp_path / "d"
    first = run_cli("lightmap-uv", save(tmp_path / "in.blend"), "--out", out, "--save-blend")
    assert first.returncode == 0, first.stderr
    before = snapshot_dir(out)
    done = run_cli("lightmap-uv", out / "result.blend", "--out", out, "--save-blend")
    assert_one_line_error(done, "--save-blend", "input scene")
    assert snapshot_dir(out) == before
    # Without --save-blend the chain is fine and result.blend is left as it is.
    chained = run_cli("info", out / "result.blend", "--out", out)
    assert chained.returncode == 0, chained.stderr
    assert (out / "result.blend").read_bytes() == before["result.blend"]


def test_a_failed_publish_leaves_the_previous_set_whole(tmp_path):
    default_scene()
    scene = save(tmp_path / "s.blend")
    out = tmp_path / "out"
    assert run_cli("texture", scene, "--out", out, *SMALL).returncode == 0
    (out / "render.png").unlink()
    (out / "render.png").mkdir()  # a folder where a file of the set belongs
    before = snapshot_dir(out)
    done = run_cli("texture", scene, "--out", out, *SMALL, "--cells", "2")
    assert_one_line_error(done, "render.png", "folder")
    assert snapshot_dir(out) == before  # render.exr, metrics.json and the lightmaps as they were
    assert (out / "render.png").is_dir() and hidden(out) == []


def test_a_folder_symlink_in_out_is_never_written_through(tmp_path):
    default_scene()
    scene = save(tmp_path / "s.blend")
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "lightmaps").symlink_to(elsewhere, target_is_directory=True)
    done = run_cli("texture", scene, "--out", out, *SMALL)
    assert_one_line_error(done, "symbolic link")
    assert list(elsewhere.iterdir()) == [] and sorted(p.name for p in out.iterdir()) == ["lightmaps"]


def test_sigterm_is_handled_like_ctrl_c(tmp_path):
    default_scene()
    scene = save(tmp_path / "s.blend")
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("earlier output")
    proc = subprocess.Popen([sys.executable, "-m", "classic_bake", "trace", str(scene), "--out",
                             str(out), "--resolution", "320", "240", "--supersample", "4"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not hidden(out) and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.01)
        assert proc.poll() is None, "the run ended before it could be stopped"
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=TIMEOUT_S)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "interrupted" in err
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]  # no staging folder left


# --- 2. clear errors instead of tracebacks ----------------------------------------------------

@pytest.mark.parametrize("command", ["texture", "shadowmap"])
def test_no_camera_fails_before_baking(command, tmp_path, capfd):
    default_scene()
    bpy.data.objects.remove(bpy.data.objects["Camera"])
    done = refusal(capfd, command, save(tmp_path / "s.blend"), "--out", tmp_path / "out", *SMALL)
    assert_one_line_error(done, "no camera")
    assert "baked" not in done.stdout and not (tmp_path / "out").exists()


def test_a_panoramic_camera_is_one_line(tmp_path, capfd):
    default_scene()
    bpy.data.objects["Camera"].data.type = "PANO"
    scene = save(tmp_path / "s.blend")
    assert_one_line_error(run_cli("trace", scene, "--out", tmp_path / "a", *SMALL[:3]),
                          "panoramic", "only perspective and orthographic")
    assert_one_line_error(refusal(capfd, "info", scene, "--out", tmp_path / "b"),
                          "PANO", "only perspective and orthographic")


def test_a_camera_scaled_to_zero_is_one_line(tmp_path, capfd):
    default_scene()
    bpy.data.objects["Camera"].scale = (0.0, 0.0, 0.0)
    done = refusal(capfd, "trace", save(tmp_path / "s.blend"), "--out", tmp_path / "out", *SMALL[:3])
    assert_one_line_error(done, "scaled", "Camera")


def test_a_missing_linked_library_is_named(tmp_path):
    default_scene()
    bpy.data.objects["Cube"].name = "Linked"
    save(tmp_path / "lib.blend")
    default_scene()
    with bpy.data.libraries.load(str(tmp_path / "lib.blend"), link=True) as (src, dst):
        dst.objects = ["Linked"]
    bpy.context.scene.collection.objects.link(dst.objects[0])
    scene = save(tmp_path / "s.blend")
    (tmp_path / "lib.blend").unlink()
    out = tmp_path / "out"
    done = run_cli("trace", scene, "--out", out, *SMALL[:3])
    assert_clean(done)
    assert "lib.blend" in done.stdout and "not found" in done.stdout
    ignored = json.loads((out / "metrics.json").read_text())["ignored"]
    assert any("lib.blend" in why and "not found" in why for why in ignored)


BAD_KINDS = {"nan": "non-finite", "inf": "out of range", "scale0": "no surface area",
             "collapsed": "no surface area", "no_faces": "no faces"}


def _bad_object(kind: str, name: str):
    """An object `name` with `kind` geometry (a copy of the default cube, or a faceless mesh)."""
    if kind == "no_faces":
        return add_mesh(name, [(0, 0, 0), (1, 0, 0), (0, 1, 0)], [])
    cube = bpy.data.objects["Cube"].copy()
    cube.data = cube.data.copy()
    cube.name = name
    bpy.context.scene.collection.objects.link(cube)
    if kind in ("nan", "inf"):
        cube.data.vertices[0].co = (float(kind), 0.0, 0.0)
    elif kind == "scale0":
        cube.scale = (0.0, 0.0, 0.0)
    elif kind == "collapsed":
        for v in cube.data.vertices:
            v.co = (0.5, 0.5, 0.5)
    return cube


def _bad_geometry(*kinds: str) -> dict:
    """The default scene with a floor and, for each kind, an object named after it ('Bad' for
    one kind); the cube itself removed. Returns {object name: the words its skip line says}."""
    default_scene()
    add_plane("Floor")
    named = {("Bad" if len(kinds) == 1 else f"Bad_{kind}"): kind for kind in kinds}
    for name, kind in named.items():
        _bad_object(kind, name)
    bpy.data.objects.remove(bpy.data.objects["Cube"])
    return {name: BAD_KINDS[kind] for name, kind in named.items()}


@pytest.mark.parametrize("command", ["info", "texture", "shadowmap"])
def test_bad_geometry_is_skipped_by_name(command, tmp_path):
    """Every kind of bad object in one scene: each is skipped with a line naming it."""
    words_of = _bad_geometry(*BAD_KINDS)
    out = tmp_path / "out"
    args = () if command == "info" else SMALL
    done = run_cli(command, save(tmp_path / "s.blend"), "--out", out, *args)
    assert_clean(done)
    metrics = json.loads((out / "metrics.json").read_text())  # valid JSON: no nan written
    for name, words in words_of.items():
        line = next(ln for ln in done.stdout.splitlines() if f"'{name}'" in ln)
        assert words in line and "skipped" in line, line
        assert any(f"'{name}'" in why and words in why for why in metrics["ignored"])
    if command != "info":
        assert list(metrics["lightmap_files"]) == ["Floor"]


@pytest.mark.parametrize("kind, words", [("nan", "non-finite"), ("inf", "out of range")])
def test_lightmap_uv_names_a_non_finite_object(kind, words, tmp_path, capfd):
    # Blender stores inf as FLT_MAX: out of range, never handed to xatlas (which loops on it).
    _bad_geometry(kind)
    done = refusal(capfd, "lightmap-uv", save(tmp_path / "s.blend"), "--out", tmp_path / "out")
    assert_one_line_error(done, "'Bad'", words)


def test_a_mesh_xatlas_crashes_on_is_named(tmp_path, capfd):
    # xatlas 0.0.11 ends its process on a dense sphere whose pole rows are collapsed (250 rings of
    # 500 quads, 250k triangles, in well under a second); charted in a child process, the run
    # ends with one line naming the object (and a way round it), and this process goes on.
    default_scene()
    rings, segments = 250, 500
    theta = np.linspace(0.0, np.pi, rings + 1)[:, None]
    phi = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)[None, :]
    verts = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                      np.cos(theta) + 0.0 * phi], -1).reshape(-1, 3)
    a = np.arange(rings * segments).reshape(rings, segments)
    b = np.roll(a, -1, axis=1)
    quads = np.stack([a, a + segments, b + segments, b], -1).reshape(-1, 4)
    add_mesh("DenseBall", verts.tolist(), quads.tolist())
    scene = save(tmp_path / "s.blend")
    done = refusal(capfd, "lightmap-uv", scene, "--out", tmp_path / "out")
    if done.returncode == 0:  # an xatlas build without the defect charts it
        return
    assert_one_line_error(done, "'DenseBall'", "xatlas crashed", "Lightmap Pack")
    assert not (tmp_path / "out").exists()


def test_tiny_objects_still_get_lightmap_uvs(tmp_path):
    default_scene()
    bpy.data.objects["Cube"].scale = (1e-4, 1e-4, 1e-4)  # 2e-4 m: small, but has an area
    out = tmp_path / "out"
    done = run_cli("lightmap-uv", save(tmp_path / "s.blend"), "--out", out)
    assert_clean(done)
    report = json.loads((out / "lightmap_uv.json").read_text())
    assert report["Cube"]["created"] and report["Cube"]["charts"] > 0


@pytest.mark.parametrize("args, words", [
    (("shadowmap", "--eps", "nan"), "finite"),
    (("shadowmap", "--eps", "inf"), "finite"),
    (("shadowmap", "--slope-bias", "nan"), "finite"),
    (("trace", "--min-weight", "nan"), "finite"),
    (("trace", "--offset-scale=-inf"), "finite"),
    (("trace", "--min-weight", "abc"), "not a number"),
    (("texture", "--uv-name", ""), "empty"),
    (("texture", "--uv-name", "  "), "empty"),
    (("trace", "--resolution", "0", "0"), "resolution"),
    (("trace", "--resolution", "-4", "-4"), "resolution"),
])
def test_bad_flags_are_refused_up_front(args, words, tmp_path, capfd):
    default_scene()
    scene = save(tmp_path / "s.blend")
    done = refusal(capfd, args[0], scene, "--out", tmp_path / "out", *args[1:])
    assert_one_line_error(done, words)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("size", [("0", "0"), ("-4", "-4")])
def test_demo_refuses_a_bad_resolution(size, tmp_path, capfd):
    assert_one_line_error(refusal(capfd, "demo", tmp_path, "--out", tmp_path / "o", "--resolution", *size),
                          "resolution")


# --- 3. estimates before work -----------------------------------------------------------------

@pytest.mark.parametrize("args, words", [
    (("radiosity", "--patch-size", "1e-6"), ("patches", "GB", "--patch-size")),
    (("trace", "--resolution", "16384", "16384"), ("16384 x 16384", "GB", "--resolution")),
    (("texture", "--resolution", "64", "48", "--lightmap-size", "16",
      "--memory-budget-gb", "0.001"),
     ("64 x 48", "--memory-budget-gb", "--resolution")),
    (("shadowmap", "--resolution", "16", "12", "--lightmap-size", "16384"),
     ("lightmaps", "texels", "--lightmap-size")),
    (("trace", "--memory-budget-gb", "nan"), ("finite",)),
    (("trace", "--memory-budget-gb", "0"), ("above 0",)),
    (("trace", "--resolution", "1000", "1000", "--time-budget-s", "5"),
     ("--time-budget-s", "camera rays", "--resolution")),
    (("trace", "--time-budget-s", "nan"), ("finite",)),
])
def test_runs_over_the_memory_or_time_budget_are_refused_up_front(args, words, tmp_path, capfd):
    default_scene()
    scene = save(tmp_path / "s.blend")
    start = time.monotonic()
    done = refusal(capfd, args[0], scene, "--out", tmp_path / "out", *args[1:])
    assert_one_line_error(done, *words)
    assert time.monotonic() - start < 60 and not (tmp_path / "out").exists()


def test_a_scene_over_the_memory_budget_names_its_triangles(tmp_path, capfd):
    default_scene()
    bpy.ops.mesh.primitive_uv_sphere_add(segments=256, ring_count=128)  # 65k triangles
    scene = save(tmp_path / "s.blend")
    done = refusal(capfd, "trace", scene, "--out", tmp_path / "out", "--resolution", "8", "6",
                   "--memory-budget-gb", "0.01")
    assert_one_line_error(done, "triangles", "fewer triangles", "--memory-budget-gb")
    assert not (tmp_path / "out").exists()


# --- 4. silent wrong output -------------------------------------------------------------------

@pytest.mark.parametrize("command", ["info", "trace", "shadowmap", "texture", "radiosity"])
def test_negative_light_and_infinite_emission_are_noted_not_written(command, tmp_path):
    from classic_bake.kernels.measure.exr import read_exr

    default_scene()
    add_plane("Floor")
    bpy.data.objects["Light"].data.energy = -1000.0
    bsdf = bpy.data.materials["Material"].node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Emission Strength"].default_value = float("inf")  # stored as FLT_MAX
    bsdf.inputs["Emission Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    out = tmp_path / "out"
    args = () if command == "info" else ("--resolution", "16", "12")
    done = run_cli(command, save(tmp_path / "s.blend"), "--out", out, *args)
    assert_clean(done)
    ignored = json.loads((out / "metrics.json").read_text())["ignored"]
    assert any("'Light'" in why and "negative power" in why for why in ignored)
    assert any("'Material'" in why and "emission" in why for why in ignored)
    for exr in out.rglob("*.exr"):
        pixels = read_exr(exr)
        assert (pixels >= 0.0).all() and (pixels < 1e15).all(), exr
