"""The committed sample scenes (sample_blends/*.blend): they open, are complete, render in Cycles,
and are exactly what `sample_blends/make_samples.py` builds today.

Cornell box values are checked against tests/data/cornell_box.json.
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import bpy
import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "sample_blends"
CORNELL_JSON = ROOT / "tests" / "data" / "cornell_box.json"
SCENES = ("cornell_box", "env_room", "bump", "shadows", "raytrace")

POSITION_TOL = 1e-6  # m; float32 coordinates of scenes a few metres across, rebuilt identically
VALUE_TOL = 1e-6  # any other float property (colours, powers, UVs, 8-bit pixels as floats)
MIN_MEAN_RADIANCE = 0.01  # a lit scene's mean pixel is far above this; a black render is 0
MAX_BLEND_BYTES = 1 << 20  # each file under 1 MiB (brief), all together under 3 MiB
MAX_TOTAL_BYTES = 3 << 20


# Light properties the generator sets (each light type has its own subset).
LIGHT_KEYS = ("type", "energy", "shadow_soft_size", "angle", "spot_size", "spot_blend", "shape",
              "size", "size_y")


def _open(path: Path) -> bpy.types.Scene:
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    bpy.context.view_layer.update()  # evaluate matrix_world from the stored transforms
    return bpy.context.scene


def _generator():
    spec = importlib.util.spec_from_file_location("make_samples", SAMPLES / "make_samples.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _principled(mat: bpy.types.Material) -> bpy.types.Node:
    nodes = [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"]
    assert len(nodes) == 1, f"{mat.name}: one Principled BSDF expected"
    return nodes[0]


def _input(node: bpy.types.Node, name: str):
    value = node.inputs[name].default_value
    return tuple(value) if hasattr(value, "__len__") else value


def _is_emissive(mat: bpy.types.Material) -> bool:
    bsdf = _principled(mat)
    return _input(bsdf, "Emission Strength") > 0.0 and max(_input(bsdf, "Emission Color")[:3]) > 0


def _array(collection, attr: str, width: int, dtype=np.float64) -> np.ndarray:
    out = np.empty(len(collection) * width, dtype)
    collection.foreach_get(attr, out)
    return out.reshape(-1, width) if width > 1 else out


def _signature(scene: bpy.types.Scene) -> dict:
    """Everything the generator decides, as plain values and arrays, keyed by name."""
    sig: dict = {}
    for obj in sorted(bpy.data.objects, key=lambda o: o.name):
        entry = {"type": obj.type, "data": obj.data.name,
                 "transform": np.array([*obj.location, *obj.rotation_euler, *obj.scale]),
                 "matrix": np.array(obj.matrix_world, dtype=np.float64)}
        if obj.type == "MESH":
            mesh = obj.data
            entry |= {
                "co": _array(mesh.vertices, "co", 3),
                "loop_vertices": _array(mesh.loops, "vertex_index", 1, np.int64),
                "loop_totals": _array(mesh.polygons, "loop_total", 1, np.int64),
                "material_index": _array(mesh.polygons, "material_index", 1, np.int64),
                "smooth": _array(mesh.polygons, "use_smooth", 1, bool),
                "materials": [m.name for m in mesh.materials],
                "uv_layers": {uv.name: _array(uv.data, "uv", 2) for uv in mesh.uv_layers},
                "corner_normals": _array(mesh.corner_normals, "vector", 3),
                "modifiers": [(m.name, m.type) for m in obj.modifiers],
            }
        elif obj.type == "LIGHT":
            lamp = obj.data
            entry |= {key: getattr(lamp, key) for key in LIGHT_KEYS if hasattr(lamp, key)}
            entry["color"] = tuple(lamp.color)
        elif obj.type == "CAMERA":
            cam = obj.data
            entry |= {k: getattr(cam, k) for k in ("lens", "sensor_width", "sensor_height",
                                                   "sensor_fit", "type")}
        sig[f"object:{obj.name}"] = entry
    for mat in sorted(bpy.data.materials, key=lambda m: m.name):
        bsdf = _principled(mat)
        sig[f"material:{mat.name}"] = {
            "nodes": sorted(n.bl_idname for n in mat.node_tree.nodes),
            "links": sorted((lk.from_node.bl_idname, lk.from_socket.name, lk.to_node.bl_idname,
                             lk.to_socket.name) for lk in mat.node_tree.links),
            **{name: _input(bsdf, name) for name in (
                "Base Color", "Metallic", "Roughness", "IOR", "Specular IOR Level",
                "Transmission Weight", "Emission Color", "Emission Strength")},
        }
    for image in sorted(bpy.data.images, key=lambda i: i.name):
        pixels = np.empty(len(image.pixels), np.float32)
        image.pixels.foreach_get(pixels)
        sig[f"image:{image.name}"] = {
            "size": tuple(image.size), "colorspace": image.colorspace_settings.name,
            "packed": image.packed_file is not None, "pixels": pixels,
        }
    cycles = scene.cycles
    sig["render"] = {
        "engine": scene.render.engine,
        "resolution": (scene.render.resolution_x, scene.render.resolution_y),
        "samples": cycles.samples,
        "bounces": (cycles.max_bounces, cycles.diffuse_bounces, cycles.glossy_bounces,
                    cycles.transmission_bounces),
        "camera": scene.camera.name,
        "world": scene.world.name,
    }
    return sig


def _assert_same(a, b, where: str = "") -> None:
    if isinstance(a, dict):
        assert a.keys() == b.keys(), f"{where}: keys differ: {sorted(a.keys() ^ b.keys())}"
        for key in a:
            _assert_same(a[key], b[key], f"{where}/{key}")
    elif isinstance(a, np.ndarray) or isinstance(a, float):
        a, b = np.asarray(a), np.asarray(b)
        assert a.shape == b.shape, f"{where}: shape {a.shape} != {b.shape}"
        if a.dtype.kind == "f":
            np.testing.assert_allclose(a, b, rtol=0.0, atol=POSITION_TOL, err_msg=where)
        else:
            np.testing.assert_array_equal(a, b, err_msg=where)
    elif isinstance(a, (tuple, list)) and a and isinstance(a[0], float):
        np.testing.assert_allclose(a, b, rtol=0.0, atol=VALUE_TOL, err_msg=where)
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def _render_tiny(scene: bpy.types.Scene, out: Path) -> np.ndarray:
    """Render the scene as it is, only smaller and with fewer samples: (H, W, 3) linear."""
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    scene.render.resolution_percentage = 100
    scene.cycles.samples = 2
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.filepath = str(out)
    bpy.ops.render.render(write_still=True)
    image = bpy.data.images.load(str(out))
    pixels = np.array(image.pixels[:], np.float32).reshape(24, 32, -1)
    return pixels[..., :3]


@pytest.mark.parametrize("name", SCENES)
def test_scene_is_complete_and_renders(name: str, tmp_path: Path) -> None:
    scene = _open(SAMPLES / f"{name}.blend")

    assert scene.camera is not None and scene.camera.name == "Camera"
    assert scene.camera.type == "CAMERA"
    lights = [o for o in scene.objects if o.type == "LIGHT"]
    used = {m for o in scene.objects if o.type == "MESH" for m in o.data.materials}
    assert lights or any(_is_emissive(m) for m in used), "nothing emits light"
    meshes = [o.data for o in scene.objects if o.type == "MESH"]
    assert meshes
    for mesh in meshes:
        assert len(mesh.uv_layers) >= 1, f"{mesh.name} has no UV layer"
        uv = _array(mesh.uv_layers.active.data, "uv", 2)
        assert np.isfinite(uv).all()
    for image in bpy.data.images:
        assert image.packed_file is not None, f"{image.name} is not packed"

    # The settings the brief asks of every scene.
    assert scene.render.engine == "CYCLES" and scene.cycles.device == "CPU"
    assert not scene.cycles.use_denoising and not scene.render.film_transparent
    assert scene.view_settings.view_transform == "Standard"
    for light in lights:
        if light.data.type in {"POINT", "SPOT"}:
            assert light.data.shadow_soft_size == 0.0
        if light.data.type == "SUN":
            assert light.data.angle == 0.0
    for mat in used:
        bsdf = _principled(mat)
        if _input(bsdf, "Metallic") == 0.0 and _input(bsdf, "Transmission Weight") == 0.0:
            assert _input(bsdf, "Specular IOR Level") == 0.0, f"{mat.name} is not Lambertian"

    pixels = _render_tiny(scene, tmp_path / f"{name}.exr")
    assert np.isfinite(pixels).all()
    assert pixels.mean() > MIN_MEAN_RADIANCE, f"{name} renders black"


def test_generator_reproduces_the_committed_scenes(tmp_path: Path) -> None:
    written = _generator().main(["--out", str(tmp_path)])
    assert [p.name for p in written] == [f"{name}.blend" for name in SCENES]
    for name in SCENES:
        committed = _signature(_open(SAMPLES / f"{name}.blend"))
        rebuilt = _signature(_open(tmp_path / f"{name}.blend"))
        _assert_same(committed, rebuilt, name)


def test_scenes_cover_the_features_the_bridge_must_handle() -> None:
    sizes = [(SAMPLES / f"{name}.blend").stat().st_size for name in SCENES]
    assert max(sizes) < MAX_BLEND_BYTES and sum(sizes) < MAX_TOTAL_BYTES

    found = set()
    for name in SCENES:
        scene = _open(SAMPLES / f"{name}.blend")
        for obj in scene.objects:
            if obj.type != "MESH":
                continue
            mesh = obj.data
            if any(m.type == "SUBSURF" for m in obj.modifiers):
                found.add("subdivision")
            if mesh.has_custom_normals:
                found.add("custom normals")
            sharp = mesh.attributes.get("sharp_edge")
            if sharp is not None and any(v.value for v in sharp.data):
                found.add("sharp edges")
            if any(p.loop_total > 4 for p in mesh.polygons):
                found.add("n-gon")
            if any(p.loop_total == 4 for p in mesh.polygons):
                found.add("quads")
            if len({p.material_index for p in mesh.polygons}) >= 2:
                found.add("two material slots")
        for mat in bpy.data.materials:
            kinds = {n.bl_idname for n in mat.node_tree.nodes}
            found |= {k for k in ("ShaderNodeTexChecker", "ShaderNodeTexImage", "ShaderNodeBump")
                      if k in kinds}
    required = {"subdivision", "custom normals", "sharp edges", "n-gon", "quads",
                "two material slots", "ShaderNodeTexChecker", "ShaderNodeTexImage",
                "ShaderNodeBump"}
    assert required <= found, f"no sample scene has: {sorted(required - found)}"


def test_cornell_box_follows_the_published_data() -> None:
    data = json.loads(CORNELL_JSON.read_text())["cornell_original"]
    scene = _open(SAMPLES / "cornell_box.blend")

    def to_blender(points_mm) -> np.ndarray:  # the rotation (x, y, z) -> (-x, z, y), mm -> m
        p = np.asarray(points_mm, float)
        return np.stack([-p[..., 0], p[..., 2], p[..., 1]], axis=-1) * 1e-3

    def world_verts(obj) -> np.ndarray:
        co = _array(obj.data.vertices, "co", 3)
        m = np.array(obj.matrix_world)
        return co @ m[:3, :3].T + m[:3, 3]

    names = {"Floor", "Ceiling", "BackWall", "LeftWall", "RightWall", "ShortBlock",
             "TallBlock", "Light", "Camera"}
    assert {o.name for o in scene.objects} == names

    # Every published corner is a vertex of its object, and nothing else is (ceiling: outer
    # corners plus the light's corners, where the hole is cut).
    keys = {"Floor": ["floor"], "BackWall": ["back_wall"], "LeftWall": ["left_wall"],
            "RightWall": ["right_wall"], "ShortBlock": ["short_block"],
            "TallBlock": ["tall_block"], "Light": ["light"], "Ceiling": ["ceiling", "light"]}
    for name, surface_keys in keys.items():
        expected = np.unique(np.round(np.concatenate(
            [to_blender(data["surfaces"][k]["quads"]).reshape(-1, 3) for k in surface_keys]),
            6), axis=0)
        got = np.unique(np.round(world_verts(scene.objects[name]), 6), axis=0)
        np.testing.assert_allclose(got, expected, atol=POSITION_TOL, err_msg=name)

    # Walls face into the box, blocks face out, the light faces down.
    centre = to_blender([278.0, 274.4, 279.6])
    for name in ("Floor", "Ceiling", "BackWall", "LeftWall", "RightWall", "Light"):
        mesh = scene.objects[name].data
        for poly in mesh.polygons:
            assert np.dot(np.array(poly.normal), centre - np.array(poly.center)) > 0.0, name
    light_normal = np.array(scene.objects["Light"].data.polygons[0].normal)
    np.testing.assert_allclose(light_normal, [0.0, 0.0, -1.0], atol=1e-6)
    # The left wall (x ~ 550 mm, red) is on the image's left: Blender x < camera x.
    assert world_verts(scene.objects["LeftWall"])[:, 0].max() < scene.camera.location.x

    # Reflectances: the D65 RGB renditions of the published spectra.
    rgb = data["rgb_derived_here"]["under_D65"]
    for name, key in (("Floor", "white"), ("LeftWall", "red"), ("RightWall", "green"),
                      ("TallBlock", "white")):
        colour = _input(_principled(scene.objects[name].data.materials[0]), "Base Color")
        np.testing.assert_allclose(colour[:3], rgb[key], atol=1e-6, err_msg=name)

    # The published camera: position, +z viewing direction, 35 mm lens on 25 mm film.
    cam, pub = scene.camera, data["camera"]
    np.testing.assert_allclose(cam.location, to_blender(pub["position"]), atol=POSITION_TOL)
    view = np.array(cam.matrix_world)[:3, :3] @ [0.0, 0.0, -1.0]
    up = np.array(cam.matrix_world)[:3, :3] @ [0.0, 1.0, 0.0]
    np.testing.assert_allclose(view, to_blender(pub["direction"]) * 1e3, atol=1e-6)
    np.testing.assert_allclose(up, to_blender(pub["up"]) * 1e3, atol=1e-6)
    fov = 2.0 * math.degrees(math.atan(cam.data.sensor_width / 2.0 / cam.data.lens))
    assert fov == pytest.approx(pub["vertical_fov_deg_derived"], abs=1e-4)
    assert scene.render.resolution_x == scene.render.resolution_y  # square film
