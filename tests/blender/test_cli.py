"""The command line contract: `python -m classic_bake COMMAND SCENE.blend [options]`."""

import json
import subprocess
import sys
from pathlib import Path

import bpy
import pytest

from classic_bake.pipeline.cli import main
from classic_bake.pipeline.outputs import Staging, safe_name

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from support.cli_calls import refusal  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
CORNELL = ROOT / "sample_blends" / "cornell_box.blend"


def run_cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "classic_bake", *map(str, args)],
                          capture_output=True, text=True, timeout=300, cwd=cwd)


def test_info_prints_the_extracted_scene(tmp_path):
    done = run_cli("info", CORNELL, "--out", tmp_path)
    assert done.returncode == 0, done.stderr
    out = done.stdout
    assert "objects" in out and "triangles" in out and "camera: PERSP" in out
    for name in ("Floor", "ShortBlock", "TallBlock"):
        assert f"object {name}" in out
    info = json.loads((tmp_path / "info.json").read_text())
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert info["counts"]["triangles"] > 0
    assert metrics["technique"] == "info" and metrics["seconds"]["total"] > 0
    assert metrics["sizes"]["triangles"] == info["counts"]["triangles"]
    assert not any(p.name.startswith(".classic_bake-") for p in tmp_path.iterdir())


@pytest.mark.parametrize("args, words", [
    (("info", "/no/such/scene.blend"), "not found"),
    (("info", ROOT / "Makefile"), "not a .blend"),
    (("info", ROOT), "not a file"),
    (("nonsense", CORNELL), "invalid choice"),
    (("info", CORNELL, "--resolution", "0", "10"), "resolution"),
    (("lightmap-uv", CORNELL, "--lightmap-size", "4"), "resolution must be"),
])
def test_bad_input_exits_2_with_one_line(args, words, tmp_path, capfd):
    done = (refusal(capfd, *args, "--out", tmp_path / "o") if args[0] != "nonsense"
            else run_cli(*args))  # one of them in a process of its own
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in done.stderr
    assert lines[0].startswith("classic_bake: error:") and words in lines[0]


def test_failed_run_leaves_earlier_outputs(tmp_path):
    assert run_cli("lightmap-uv", CORNELL, "--out", tmp_path, "--save-blend").returncode == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert {"metrics.json", "result.blend", "lightmap_uv.json"} <= set(before)
    failed = run_cli("lightmap-uv", CORNELL, "--out", tmp_path, "--lightmap-size", "4")
    assert failed.returncode == 2
    after = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    assert after == before  # same files, same bytes, no staging folder left behind


def test_failed_first_run_leaves_no_folder(tmp_path):
    out = tmp_path / "new"
    assert run_cli("lightmap-uv", CORNELL, "--out", out, "--lightmap-size", "4").returncode == 2
    assert not out.exists()


def test_the_scene_file_is_never_written(tmp_path):
    before = CORNELL.read_bytes()
    assert run_cli("lightmap-uv", CORNELL, "--out", tmp_path, "--save-blend").returncode == 0
    assert CORNELL.read_bytes() == before
    # result.blend holds the written-back UV layers.
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "result.blend"), load_ui=False,
                             use_scripts=False)
    meshes = [o for o in bpy.data.objects if o.type == "MESH"]
    assert meshes and all("Lightmap" in o.data.uv_layers for o in meshes)


def test_a_file_saved_in_edit_mode_is_baked_in_object_mode(tmp_path):
    """A .blend saved with its only mesh in Edit Mode, whose evaluated data then reads empty
    (the edit mesh's wrapper): the run says it leaves Edit Mode, sees the mesh (it was skipped
    as "no faces"), and what it writes into the mesh stays in result.blend, where Edit Mode's
    mesh would have overwritten it."""
    import math

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location, cam.rotation_euler = (0.0, -3.0, 2.0), (math.radians(55.0), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    bpy.ops.object.mode_set(mode="EDIT")
    path = tmp_path / "editing.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    done = run_cli("radiosity", path, "--out", tmp_path / "out", "--save-blend", "--resolution",
                   "16", "12", "--patches", "20", "--lightmap-size", "16")
    assert done.returncode == 0, done.stderr
    assert "left Edit Mesh mode for Object Mode" in done.stdout
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert not any("no faces" in why for why in metrics["ignored"])
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "out" / "result.blend"), load_ui=False,
                             use_scripts=False)
    plane = bpy.data.objects["Plane"]
    assert plane.mode == "OBJECT" and "Radiosity" in plane.data.color_attributes


def test_a_mesh_in_edit_mode_is_read_as_cycles_renders_it():
    """The snapshot reads a mesh in Edit Mode through its evaluated mesh (to_mesh), in place:
    the same triangles as in Object Mode, and the mode left as it was."""
    from classic_bake.addon import bridge

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_cube_add(size=1.0)
    objects = bridge.snapshot().triangles
    bpy.ops.object.mode_set(mode="EDIT")
    editing = bridge.snapshot().triangles
    assert bpy.context.mode == "EDIT_MESH"
    assert objects.shape == editing.shape == (12, 3, 3)
    assert (objects == editing).all()


def test_in_process_entry_point_matches(tmp_path, capsys):
    # What `blender -c classic_bake ...` calls (registered by the extension).
    assert main(["info", str(CORNELL), "--out", str(tmp_path)]) == 0
    assert "TallBlock" in capsys.readouterr().out
    assert main(["info", str(tmp_path / "missing.blend")]) == 2


def test_cli_command_is_registered_with_blender(tmp_path, capsys, monkeypatch):
    # `blender -c classic_bake ARGS...` calls the function registered under "classic_bake" with the
    # list of arguments after the id and exits with its return value: record what register() hands
    # to Blender, then call it as Blender does.
    import classic_bake

    registered = {}
    real_register = bpy.utils.register_cli_command

    def recording_register(cli_id, execute):
        registered[cli_id] = execute
        return real_register(cli_id, execute)

    monkeypatch.setattr(bpy.utils, "register_cli_command", recording_register)
    classic_bake.register()
    try:
        assert classic_bake._cli_handle is not None
        assert list(registered) == ["classic_bake"]
        execute = registered["classic_bake"]
        assert execute(["info", str(CORNELL), "--out", str(tmp_path)]) == 0
        assert "TallBlock" in capsys.readouterr().out
        assert (tmp_path / "metrics.json").is_file()
        assert execute(["info", str(tmp_path / "missing.blend")]) == 2
    finally:
        classic_bake.unregister()
    assert classic_bake._cli_handle is None


@pytest.mark.parametrize("name, expected", [
    ("Cube", "Cube"),
    ("../../etc/passwd", "etc_passwd"),
    ("a/b\\c", "a_b_c"),
    ("CON", "_CON"),
    ("nul.exr", "_nul.exr"),
    ("...", "unnamed"),
    ("Würfel Ω", "W_rfel"),
    ("x" * 500, "x" * 120),
])
def test_safe_names(name, expected):
    assert safe_name(name) == expected


def test_staged_paths_never_leave_the_output_folder(tmp_path):
    staging = Staging(tmp_path)
    for hostile in ("../escape.txt", "/abs/path.txt", "a/../../b.txt"):
        path = staging.file(hostile)
        assert staging.path in path.resolve().parents
    staging.discard()
    assert list(tmp_path.iterdir()) == []


def test_report_command_builds_a_page_from_run_folders(tmp_path):
    runs = tmp_path / "runs"
    assert run_cli("info", CORNELL, "--out", runs / "cornell-info").returncode == 0
    done = run_cli("report", runs)
    assert done.returncode == 0, done.stderr
    html = (runs / "index.html").read_text()
    assert "cornell_box.blend" in html and "info" in html
    empty = tmp_path / "empty"
    empty.mkdir()
    failed = run_cli("report", empty)
    assert failed.returncode == 2 and "no run folders" in failed.stderr
