"""The interface as it runs: each technique operator's modal path driven tick by tick to its end and
to Esc half-way (the scene equal before and after), every panel drawn against every sample scene,
undo, where the results land, and the preferences that change what a bake does.

There is no event loop under the pip `bpy` module, so the modal path is driven as Blender drives
it: `begin` (what `invoke` does before it adds the timer), then `modal` with TIMER events until it
returns FINISHED, or an ESC event. Blender cannot make an operator instance outside its operator
machinery, so `Running` binds the operator class's own methods to a plain object that records
reports. The background module has no undo stack (`ed.undo` cannot poll), so "one undo step per
bake" is checked as Blender decides it: an operator with UNDO in its bl_options that returns
FINISHED once is one undo step, and no job pushes steps of its own.
"""

from __future__ import annotations

import inspect
import os
import types
from pathlib import Path

import bpy
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "sample_blends"
SCENES = sorted(p.stem for p in SAMPLES.glob("*.blend"))


# --- each operator at a tiny size: scene, property values, what it must leave behind ---------------

# idname -> (sample scene, scene.classic_bake values, colour attribute, images it writes)
BAKES = {
    "classic_bake.lightmap_uv": ("cornell_box", {"lightmap_resolution": 32}, "", ()),
    "classic_bake.texture": ("bump", {"lightmap_resolution": 32, "texture_adaptive": 0},
                             "Albedo", ("Classic Bake Texture",)),
    "classic_bake.trace": ("raytrace", {"trace_adaptive": 0}, "", ("Classic Bake Trace",)),
    "classic_bake.envmap": ("env_room", {"envmap_face_size": 16, "envmap_adaptive": 0,
                                         "envmap_mips": 0}, "", ("Classic Bake Environment",)),
    "classic_bake.shading": ("bump", {"bump_adaptive": 0}, "", ("Classic Bake Shading",)),
    "classic_bake.shadowmap": ("shadows", {"lightmap_resolution": 32}, "Shadow",
                               ("Classic Bake Shadows",)),
    "classic_bake.radiosity": ("cornell_box", {"lightmap_resolution": 32, "radiosity_patches": 60,
                                               "radiosity_refine": 0, "radiosity_gather_rays": 4},
                               "Radiosity", ("Classic Bake Radiosity",)),
    "classic_bake.hybrid": ("cornell_box", {"hybrid_patches": 60, "hybrid_gather_rays": 4,
                                            "hybrid_adaptive": 0}, "", ("Classic Bake Hybrid",)),
    "classic_bake.normalmap": ("bump", {"normalmap_size": 32}, "", ("Normal BrickFloor",)),
}
RENDER_SIZE = (24, 18)  # camera views: small enough for a few tenths of a second per bake


def operator_classes():
    from classic_bake.operators import bake

    return {cls.bl_idname: cls for cls in bake.CLASSES}


def prepare(open_sample, idname: str):
    """Open the operator's sample scene at its tiny settings."""
    scene_name, values, _, _ = BAKES[idname]
    open_sample(scene_name)
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = RENDER_SIZE
    scene.render.resolution_percentage = 100
    props = scene.classic_bake
    for name, value in values.items():
        if hasattr(props, name):
            setattr(props, name, value)
    if idname == "classic_bake.lightmap_uv":  # it unwraps the selection: select every mesh
        for obj in scene.objects:
            obj.select_set(obj.type == "MESH")
    return scene


class Running:
    """A running operator: the class's own methods bound to a plain object, its reports recorded.

    `tick_budget_ms` None: the preferences' budget (the default when the add-on is registered
    without being enabled); 0: one advance of the job per timer tick."""

    def __init__(self, cls, tick_budget_ms: float | None = None, **props):
        self.cls, self.reports = cls, []
        for name, prop in getattr(cls, "__annotations__", {}).items():  # operator properties
            self.__dict__[name] = props.get(name, prop.keywords.get("default"))
        if tick_budget_ms is not None:
            self.tick_budget_s = lambda context: tick_budget_ms / 1000.0

    def __getattr__(self, name):
        value = getattr(self.cls, name)
        if inspect.isfunction(inspect.getattr_static(self.cls, name)):
            return types.MethodType(value, self)
        return value

    def report(self, kinds, message):
        self.reports.append((set(kinds), message))


def event(kind: str):
    return types.SimpleNamespace(type=kind, value="PRESS")


def run_to_end(op, context, limit: int = 100_000) -> tuple[set, int]:
    """begin, then TIMER events until the operator stops; returns its last status and the ticks."""
    status = op.begin(context)
    assert status == {"RUNNING_MODAL"}, op.reports
    assert op.modal(context, event("MOUSEMOVE")) == {"PASS_THROUGH"}  # other events pass
    for ticks in range(1, limit):
        status = op.modal(context, event("TIMER"))
        if status != {"RUNNING_MODAL"}:
            return status, ticks
    raise AssertionError("the job never finished")


def image_digest(image) -> tuple:
    """An image's name, size, type and pixels (reading them loads an unloaded image: a job that
    reads a texture loads it too, which changes nothing)."""
    pixels = np.empty(len(image.pixels), np.float32)
    image.pixels.foreach_get(pixels)
    return (image.name, tuple(image.size), image.is_float, hash(pixels.tobytes()))


def scene_state() -> dict:
    """What a bake may change: meshes' UV layers, attributes (with their data) and active colour
    attributes, objects' materials, material node trees (nodes and links), images (pixels)."""
    state = {}
    for mesh in bpy.data.meshes:
        attributes = []
        for attr in mesh.attributes:
            if attr.name.startswith("."):  # internal (selection, UV pin) flags
                continue
            width = {"FLOAT_VECTOR": 3, "FLOAT_COLOR": 4, "BYTE_COLOR": 4, "FLOAT2": 2,
                     "QUATERNION": 4}.get(attr.data_type, 1)
            key = {"FLOAT_VECTOR": "vector", "FLOAT_COLOR": "color", "BYTE_COLOR": "color",
                   "FLOAT2": "vector"}.get(attr.data_type, "value")
            data = np.zeros(len(attr.data) * width, np.float64)
            try:
                attr.data.foreach_get(key, data)
            except (TypeError, AttributeError, RuntimeError):
                data = np.zeros(0)
            attributes.append((attr.name, attr.domain, attr.data_type, hash(data.tobytes())))
        colours = mesh.color_attributes
        state["mesh", mesh.name] = (
            tuple(layer.name for layer in mesh.uv_layers), mesh.uv_layers.active_index,
            tuple(sorted(attributes)), colours.active_color_name, colours.render_color_index)
    for obj in bpy.data.objects:
        state["object", obj.name] = tuple(s.material.name if s.material else "" for s in
                                          obj.material_slots)
    for mat in bpy.data.materials:
        tree = mat.node_tree
        nodes = tuple(sorted((n.name, n.bl_idname, getattr(n, "is_active_output", None))
                             for n in tree.nodes)) if tree else ()
        links = tuple(sorted((link.from_node.name, link.from_socket.identifier,
                              link.to_node.name, link.to_socket.identifier)
                             for link in tree.links)) if tree else ()
        state["material", mat.name] = (nodes, links)
    state["images"] = tuple(sorted(image_digest(image) for image in bpy.data.images))
    return state


def test_every_technique_operator_is_driven_here(addon):
    """A new technique's operator gets its modal, Esc and undo tests by an entry in BAKES."""
    assert set(operator_classes()) == set(BAKES)


# --- the modal path ---------------------------------------------------------------------------------

@pytest.mark.parametrize("idname", list(BAKES))
def test_modal_path_runs_to_the_end_and_shows_the_result(addon, open_sample, idname):
    prepare(open_sample, idname)
    context = bpy.context
    op = Running(operator_classes()[idname])
    status, ticks = run_to_end(op, context)
    assert status == {"FINISHED"}, op.reports
    kinds, message = op.reports[-1]
    assert kinds == {"INFO"} and message.endswith(" s)")  # one line with the time it took
    check_results(idname)


@pytest.mark.parametrize("idname", list(BAKES))
def test_esc_half_way_leaves_the_scene_as_it_was(addon, open_sample, idname):
    prepare(open_sample, idname)
    context = bpy.context
    before = scene_state()
    op = Running(operator_classes()[idname], tick_budget_ms=0.0)  # one job step per tick
    assert op.begin(context) == {"RUNNING_MODAL"}
    assert op.modal(context, event("TIMER")) == {"RUNNING_MODAL"}  # one step in: half-way
    assert op.modal(context, event("ESC")) == {"CANCELLED"}
    assert op.reports[-1][0] == {"WARNING"} and "cancelled" in op.reports[-1][1]
    assert op._timer is None
    after = scene_state()
    assert after == before, [key for key in before.keys() | after.keys()
                             if before.get(key) != after.get(key)]


def check_results(idname: str) -> None:
    """After a bake: the images exist, the colour attribute is active and rendered on every mesh
    that took it, lightmap UVs exist where the operator makes them."""
    _, _, attribute, images = BAKES[idname]
    for name in images:
        assert name in bpy.data.images, (name, list(bpy.data.images.keys()))
        assert tuple(bpy.data.images[name].size) != (0, 0)
    if attribute:
        meshes = [o.data for o in bpy.context.scene.objects if o.type == "MESH"
                  and attribute in o.data.color_attributes]
        assert meshes
        for mesh in meshes:
            colours = mesh.color_attributes
            assert colours.active_color_name == attribute
            assert colours.render_color_index == colours.find(attribute)
        shading = [a.spaces.active.shading for a in bpy.context.screen.areas if a.type == "VIEW_3D"]
        assert all(s.color_type == "VERTEX" for s in shading if s.type == "SOLID")
    if idname == "classic_bake.lightmap_uv":
        assert all("Lightmap" in o.data.uv_layers for o in bpy.context.scene.objects
                   if o.type == "MESH")


# --- the blocking path and undo ---------------------------------------------------------------------

@pytest.mark.parametrize("idname", list(BAKES))
def test_blocking_call_is_one_undoable_step(addon, open_sample, idname):
    prepare(open_sample, idname)
    cls = operator_classes()[idname]
    assert {"REGISTER", "UNDO"} <= set(cls.bl_options)  # every job writes Blender data
    category, name = idname.split(".")
    call = getattr(getattr(bpy.ops, category), name)
    assert call() == {"FINISHED"}
    check_results(idname)
    # The job pushes no undo steps of its own: nothing in the code path calls ed.undo_push.
    import classic_bake

    for path in (Path(classic_bake.__file__).parent / d for d in ("jobs", "operators")):
        for source in path.glob("*.py"):
            assert "undo_push" not in source.read_text(), source


def test_compare_operator_is_undoable_too(addon):
    from classic_bake.operators.compare import CLASSICBAKE_OT_compare

    assert {"REGISTER", "UNDO"} <= set(CLASSICBAKE_OT_compare.bl_options)


def test_invoke_without_a_window_blocks(addon, open_sample):
    """`bpy.ops...('INVOKE_DEFAULT')` from a script with no window runs to the end at once."""
    prepare(open_sample, "classic_bake.trace")
    op = Running(operator_classes()["classic_bake.trace"])

    class NoWindow:  # bpy.context as a script without a window sees it
        window = None

        def __getattr__(self, name):
            return getattr(bpy.context, name)

    context = NoWindow()
    assert op.invoke(context, event("LEFTMOUSE")) == {"FINISHED"}
    assert "Classic Bake Trace" in bpy.data.images


def test_invoke_in_the_background_blocks(addon, open_sample):
    """In background Blender (and the bpy module) no event loop sends timer events: invoking runs
    the bake to the end instead of waiting for ticks that never come."""
    assert bpy.app.background
    prepare(open_sample, "classic_bake.shading")
    assert bpy.ops.classic_bake.shading("INVOKE_DEFAULT") == {"FINISHED"}
    assert "Classic Bake Shading" in bpy.data.images


def test_an_image_editor_shows_the_bake(addon, open_sample):
    prepare(open_sample, "classic_bake.trace")
    area = next(a for a in bpy.context.screen.areas if a.type != "VIEW_3D")
    area.type = "IMAGE_EDITOR"
    assert area.spaces.active.image is None
    assert bpy.ops.classic_bake.trace() == {"FINISHED"}
    assert area.spaces.active.image == bpy.data.images["Classic Bake Trace"]


# --- panels -----------------------------------------------------------------------------------------

LAYOUT_METHODS = ("row", "column", "box", "split", "column_flow", "grid_flow")


class RecordingLayout:
    """A stand-in for `UILayout` where there is no window: records every call and checks that each
    property and operator it names exists and each icon is Blender's."""

    ICONS = set(bpy.types.UILayout.bl_rna.functions["label"].parameters["icon"].enum_items.keys())

    def __init__(self, calls=None):
        self.calls = [] if calls is None else calls

    def __getattr__(self, name):
        if name in LAYOUT_METHODS:
            def sub(*args, **kwargs):
                self.calls.append((name, args, kwargs))
                return RecordingLayout(self.calls)
            return sub
        if name in ("separator", "separator_spacer"):
            return lambda *args, **kwargs: self.calls.append((name, args, kwargs))
        raise AttributeError(f"the panel called UILayout.{name}, which the recorder lacks")

    def _icon(self, kwargs):
        icon = kwargs.get("icon")
        assert icon is None or icon in self.ICONS, f"unknown icon {icon!r}"

    def prop(self, data, property, **kwargs):
        assert property in data.bl_rna.properties, f"{data!r} has no property {property!r}"
        self._icon(kwargs)
        self.calls.append(("prop", (property,), kwargs))

    def operator(self, idname, **kwargs):
        category, name = idname.split(".")
        op = getattr(getattr(bpy.ops, category), name)
        op.get_rna_type()  # raises KeyError for an operator that is not registered
        self._icon(kwargs)
        self.calls.append(("operator", (idname,), kwargs))
        return types.SimpleNamespace()  # operator properties may be set on it

    def label(self, **kwargs):
        self._icon(kwargs)
        self.calls.append(("label", (), kwargs))


def draw(panel_cls) -> list:
    """The calls `panel_cls.draw` makes on its layout."""
    layout = RecordingLayout()
    panel_cls.draw(types.SimpleNamespace(layout=layout), bpy.context)
    return layout.calls


@pytest.mark.parametrize("scene_name", SCENES)
def test_every_panel_draws_against_every_sample_scene(addon, open_sample, scene_name):
    from classic_bake.addon import panel
    from classic_bake.jobs.techniques import TECHNIQUES

    open_sample(scene_name)
    props = bpy.context.scene.classic_bake
    drawn = {}
    for compared in (False, True):  # the compare section shows its figures after a comparison
        props.compare_rel_mse, props.compare_flip = (0.01, 0.2) if compared else (-1.0, -1.0)
        for cls in panel.CLASSES:
            drawn[cls.__name__, compared] = draw(cls)
    buttons = {args[0] for calls in drawn.values() for kind, args, _ in calls if kind == "operator"}
    assert buttons == {t.operator.idname for t in TECHNIQUES} | {"classic_bake.compare"}
    compare_labels = [c for c in drawn["CLASSICBAKE_PT_compare", True] if c[0] == "label"]
    assert any("Relative MSE" in c[2]["text"] for c in compare_labels)
    header = drawn["CLASSICBAKE_PT_main", False][0]
    meshes = sum(1 for o in bpy.context.scene.objects if o.type == "MESH")
    assert header[0] == "label" and header[2]["text"].startswith(f"{meshes} meshes")


def test_preferences_draw(enabled_addon):
    prefs = enabled_addon
    layout = RecordingLayout()

    class Drawn:  # the preferences with a recording layout (their own is read-only)
        def __getattr__(self, name):
            return layout if name == "layout" else getattr(prefs, name)

    type(prefs).draw(Drawn(), bpy.context)
    names = [args[0] for kind, args, _ in layout.calls if kind == "prop"]
    assert names == ["tick_budget_ms", "save_images", "output_dir", "threads"]


# --- preferences that do something -----------------------------------------------------------------

@pytest.fixture
def enabled_addon():
    """Classic Bake enabled as a user enables it (so its preferences exist); yields them."""
    assert bpy.ops.preferences.addon_enable(module="classic_bake") == {"FINISHED"}
    from classic_bake.addon import preferences

    try:
        yield preferences.get()
    finally:
        bpy.ops.preferences.addon_disable(module="classic_bake")


def test_saved_images_go_to_the_preferences_output_folder(enabled_addon, open_sample, tmp_path):
    from classic_bake.addon.bridge import image_pixels
    from classic_bake.kernels.measure.exr import read_exr

    prefs = enabled_addon
    prefs.save_images, prefs.output_dir = True, str(tmp_path)
    prepare(open_sample, "classic_bake.texture")
    assert bpy.ops.classic_bake.texture() == {"FINISHED"}
    saved = sorted(p.name for p in tmp_path.glob("*.exr"))
    lightmaps = sorted(n for n in bpy.data.images.keys() if n.startswith("Texture "))
    assert saved == sorted(bpy.path.clean_name(n) + ".exr" for n in lightmaps)
    image = bpy.data.images[lightmaps[0]]
    on_disk = read_exr(tmp_path / saved[0])
    assert np.array_equal(on_disk[..., :3], image_pixels(image)[..., :3])  # float32, exact


def test_nothing_is_saved_unless_asked(enabled_addon, open_sample, tmp_path):
    prefs = enabled_addon
    prefs.save_images, prefs.output_dir = False, str(tmp_path)
    prepare(open_sample, "classic_bake.trace")
    assert bpy.ops.classic_bake.trace() == {"FINISHED"}
    assert list(tmp_path.iterdir()) == []


def test_threads_preference_caps_the_kernels_cores(enabled_addon, open_sample):
    from classic_bake.kernels.geometry.bvh import BVHSettings
    from classic_bake.kernels.geometry.threads import core_count, set_core_limit

    prefs = enabled_addon
    prepare(open_sample, "classic_bake.trace")
    try:
        prefs.threads = 1
        assert bpy.ops.classic_bake.trace() == {"FINISHED"}
        assert core_count() == 1 and BVHSettings().thread_count == 1
        prefs.threads = 0
        assert bpy.ops.classic_bake.trace() == {"FINISHED"}
        assert core_count() == (os.cpu_count() or 1)
    finally:
        prefs.threads = 0
        set_core_limit(0)


def test_tick_budget_sets_the_work_per_tick(enabled_addon, open_sample):
    prefs = enabled_addon
    prepare(open_sample, "classic_bake.trace")
    cls = operator_classes()["classic_bake.trace"]
    prefs.tick_budget_ms = 5.0
    assert Running(cls).tick_budget_s(bpy.context) == pytest.approx(0.005)
    prefs.tick_budget_ms = 1000.0
    op = Running(cls)
    status, ticks = run_to_end(op, bpy.context)
    # A 24 x 18 trace (~0.1 s) fits one second's tick; a few on a machine busy with other work.
    assert status == {"FINISHED"} and ticks <= 3


# --- scripted bakes: the README's examples, run as written -----------------------------------------

README = ROOT / "README.md"
INSTALLED_MODULE = "bl_ext.user_default.classic_bake"  # what Blender names the installed extension


def readme_example(name: str) -> str:
    """The command between the README's `<!-- BEGIN name -->` markers."""
    text = README.read_text()
    block = text.split(f"<!-- BEGIN {name} -->", 1)[1].split(f"<!-- END {name} -->", 1)[0]
    return next(line for line in block.splitlines() if line.startswith("blender "))


def tiny_scene(open_sample, tmp_path, name: str) -> Path:
    """A copy of a sample scene rendering 24 x 18 (a script's '//' paths land beside it)."""
    open_sample(name)
    bpy.context.scene.render.resolution_x, bpy.context.scene.render.resolution_y = RENDER_SIZE
    path = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


@pytest.mark.slow
def test_the_readme_script_bakes_through_the_bpy_module(open_sample, tmp_path):
    """`blender -b scene.blend --python-expr "..."`: the same expression, with the pip module in a
    fresh process (the scene opened first, as `blender -b scene.blend` does)."""
    import shlex
    import subprocess
    import sys

    words = shlex.split(readme_example("script example"))
    assert words[:2] == ["blender", "-b"] and words[3] == "--python-expr"
    expression = words[4].replace(INSTALLED_MODULE, "classic_bake")
    expression = expression.replace("lightmap_resolution = 256", "lightmap_resolution = 32")
    scene = tiny_scene(open_sample, tmp_path, "bump")
    script = (f"import bpy; bpy.ops.wm.open_mainfile(filepath={str(scene)!r}, load_ui=False, "
              f"use_scripts=False)\n{expression}")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=300, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.count("{'FINISHED'}") == 2, done.stdout
    baked = sorted(p.name for p in (tmp_path / "baked").iterdir())
    assert "Classic_Bake_Trace.exr" in baked
    assert any(name.startswith("Texture_") for name in baked), baked


def test_the_readme_command_runs_as_blender_calls_it(addon, open_sample, tmp_path, monkeypatch):
    """`blender -b -c classic_bake ...`: Blender calls the function registered under
    "classic_bake" with the arguments after the id and exits with what it returns."""
    import json
    import shlex

    words = shlex.split(readme_example("command example"))
    assert words[:4] == ["blender", "-b", "-c", "classic_bake"]
    argv = words[4:]
    scene = tiny_scene(open_sample, tmp_path, "raytrace")
    argv[argv.index("scene.blend")] = str(scene)
    argv[argv.index("--out") + 1] = str(tmp_path / "out")
    at = argv.index("--resolution")
    argv[at + 1:at + 3] = [str(n) for n in RENDER_SIZE]
    # The handler the extension registered (the `addon` fixture ran register()).
    import classic_bake

    registered = {}
    real = bpy.utils.register_cli_command
    monkeypatch.setattr(bpy.utils, "register_cli_command",
                        lambda cli_id, execute: registered.setdefault(cli_id, execute)
                        and real(cli_id, execute))
    classic_bake.unregister()
    classic_bake.register()
    assert registered["classic_bake"](argv) == 0
    metrics = json.loads((tmp_path / "out" / "metrics.json").read_text())
    assert metrics["technique"] == "trace" and metrics["settings"]["max_depth"] == 4
    assert (tmp_path / "out" / "render.exr").is_file()


def test_the_output_folder_is_beside_the_blend_or_in_the_temporary_folder(enabled_addon, tmp_path):
    import os

    from classic_bake.operators.job import output_folder

    prefs = enabled_addon
    prefs.save_images = False
    assert output_folder(bpy.context) is None  # nothing is saved unless asked
    prefs.save_images, prefs.output_dir = True, "//baked"
    assert output_folder(bpy.context) == os.path.join(bpy.app.tempdir, "baked")  # unsaved file
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    assert Path(output_folder(bpy.context)) == tmp_path / "baked"


def test_a_script_is_told_what_the_scene_lacks(addon):
    with pytest.raises(RuntimeError, match="The scene needs a camera"):
        bpy.ops.classic_bake.trace()
    with pytest.raises(RuntimeError, match="The scene has no meshes"):
        bpy.ops.classic_bake.radiosity()


def test_a_bake_started_in_edit_mode_runs_in_object_mode(enabled_addon, open_sample):
    """The texture bake pressed with a mesh in Edit Mode: the operator leaves Edit Mode first
    (reporting it), so the colour attribute it writes stays in the mesh (Edit Mode's mesh would
    overwrite it on leaving)."""
    scene = prepare(open_sample, "classic_bake.texture")
    mesh = next(o for o in scene.objects if o.type == "MESH")
    bpy.context.view_layer.objects.active = mesh
    bpy.ops.object.mode_set(mode="EDIT")
    assert bpy.ops.classic_bake.texture() == {"FINISHED"}
    assert bpy.context.mode == "OBJECT"
    assert any("Albedo" in o.data.color_attributes for o in scene.objects if o.type == "MESH")
