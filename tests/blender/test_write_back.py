"""Write-back helpers of the bridge: images, OpenEXR files, colour attributes and UV layers, read
back through Blender's own API."""

import bmesh
import bpy
import numpy as np
import pytest

from classic_bake.addon import bridge
from classic_bake.kernels.measure.exr import read_exr


def cube(name="Cube"):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")  # calc_uvs fills an existing layer
    bmesh.ops.create_cube(bm, size=1.0, calc_uvs=True)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def test_float_image_round_trip_is_exact_and_top_row_first():
    rng = np.random.default_rng(1)
    pixels = (rng.random((5, 7, 4)) * 10 - 2).astype(np.float32)
    image = bridge.write_image("Baked", pixels)
    assert image.is_float and tuple(image.size) == (7, 5)
    back = bridge.image_pixels(image)
    assert np.array_equal(back, pixels)
    # Blender's first stored row is the image's bottom row.
    first = np.array(image.pixels[: 7 * 4], np.float32).reshape(7, 4)
    assert np.array_equal(first, pixels[-1])


def test_existing_image_is_reused_and_resized():
    image = bridge.write_image("Baked", np.zeros((4, 4, 3), np.float32))
    again = bridge.write_image("Ignored", np.ones((8, 2, 1), np.float32), image=image)
    assert again == image and tuple(image.size) == (2, 8)
    assert np.all(bridge.image_pixels(image) == 1.0)


def test_saved_exr_is_what_blender_loads(tmp_path):
    rng = np.random.default_rng(2)
    pixels = rng.random((6, 9, 4)).astype(np.float32) * 4
    image = bridge.write_image("Lightmap", pixels)
    path = str(tmp_path / "lightmap.exr")
    bridge.save_image_exr(image, pixels, path)
    assert np.array_equal(read_exr(path), pixels)
    loaded = bpy.data.images.load(path)
    assert np.array_equal(bridge.image_pixels(loaded), pixels)


def test_packed_image_survives_save_and_reload(tmp_path):
    pixels = np.linspace(0, 3, 4 * 4 * 4, dtype=np.float32).reshape(4, 4, 4)
    pixels[..., 3] = 1.0  # bakes are opaque; Blender premultiplies colour by alpha when packing
    image = bridge.write_image("Packed", pixels)
    image.use_fake_user = True  # an image nothing uses is not saved
    bridge.pack_image(image)
    blend = str(tmp_path / "packed.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend)
    bpy.ops.wm.open_mainfile(filepath=blend, load_ui=False, use_scripts=False)
    back = bridge.image_pixels(bpy.data.images["Packed"])
    np.testing.assert_allclose(back, pixels, rtol=1e-3)  # packed float images are stored as half


@pytest.mark.parametrize("domain", ["POINT", "CORNER"])
def test_colour_attribute_round_trip(domain):
    obj = cube()
    mesh = obj.data
    n = len(mesh.vertices) if domain == "POINT" else len(mesh.loops)
    colours = np.random.default_rng(3).random((n, 3)).astype(np.float32) * 5  # HDR survives
    bridge.write_color_attribute(mesh, "Radiosity", colours, domain)
    attr = mesh.color_attributes["Radiosity"]
    assert attr.data_type == "FLOAT_COLOR" and attr.domain == domain
    np.testing.assert_array_equal(bridge.read_color_attribute(mesh, "Radiosity")[:, :3], colours)
    # Through the element-wise RNA path as well.
    assert tuple(attr.data[n - 1].color)[:3] == pytest.approx(tuple(colours[n - 1]))


def test_colour_attribute_replaced_when_domain_changes_and_shape_checked():
    mesh = cube().data
    bridge.write_color_attribute(mesh, "A", np.zeros((len(mesh.vertices), 4)), "POINT")
    bridge.write_color_attribute(mesh, "A", np.ones((len(mesh.loops), 4)), "CORNER")
    assert mesh.color_attributes["A"].domain == "CORNER"
    with pytest.raises(ValueError, match="expected"):
        bridge.write_color_attribute(mesh, "A", np.ones((3, 4)), "POINT")


def test_uv_layer_is_added_never_overwritten_and_active_layers_kept():
    mesh = cube().data
    assert mesh.uv_layers.active.name == "UVMap"
    loop_uv = np.random.default_rng(4).random((len(mesh.loops), 2)).astype(np.float32)
    bridge.write_uv_layer(mesh, "Lightmap", loop_uv)
    assert mesh.uv_layers.active.name == "UVMap"
    assert mesh.uv_layers["UVMap"].active_render
    back = np.empty(len(mesh.loops) * 2, np.float32)
    mesh.uv_layers["Lightmap"].uv.foreach_get("vector", back)
    assert np.array_equal(back.reshape(-1, 2), loop_uv)
    with pytest.raises(ValueError, match="already has"):
        bridge.write_uv_layer(mesh, "Lightmap", loop_uv)


def render_centre(scene, tmp_path) -> np.ndarray:
    scene.render.engine = "CYCLES"
    scene.cycles.samples = 1
    scene.cycles.use_denoising = False
    scene.render.resolution_x = scene.render.resolution_y = 8
    scene.render.filepath = str(tmp_path / "r.exr")
    scene.render.image_settings.file_format = "OPEN_EXR"
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(tmp_path / "r.exr"))
    px = bridge.image_pixels(img)
    bpy.data.images.remove(img)
    return px[4, 4, :3]


def camera_on(obj):
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type = "ORTHO"
    cam.data.ortho_scale = 0.2
    cam.location = (0.0, 0.0, 3.0)
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    bpy.context.scene.world = None


def test_wired_attribute_shows_in_renders_and_unwiring_restores(tmp_path):
    obj = cube()
    mat = bpy.data.materials.new("Original")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True  # 4.5 creates materials without a node tree
    obj.data.materials.append(mat)
    original_nodes = sorted(n.name for n in mat.node_tree.nodes)
    mesh = obj.data
    bridge.write_color_attribute(mesh, "Baked", np.tile([0.25, 0.5, 2.0], (len(mesh.vertices), 1)))
    camera_on(obj)
    (wired,) = bridge.wire_baked_display(obj, attribute="Baked")
    assert wired == mat
    np.testing.assert_allclose(render_centre(bpy.context.scene, tmp_path), [0.25, 0.5, 2.0], rtol=1e-3)
    bridge.unwire_baked_display(mat)
    assert sorted(n.name for n in mat.node_tree.nodes) == original_nodes
    active = [n for n in mat.node_tree.nodes if n.type == "OUTPUT_MATERIAL" and n.is_active_output]
    assert len(active) == 1 and active[0].inputs["Surface"].is_linked


def test_wired_lightmap_image_uses_its_uv_layer_and_copies_shared_materials(tmp_path):
    a, b = cube("A"), cube("B")
    shared = bpy.data.materials.new("Shared")
    a.data.materials.append(shared)
    b.data.materials.append(shared)
    b.data = a.data.copy()  # separate meshes, same material
    b.data.materials[0] = shared
    loop_uv = np.full((len(a.data.loops), 2), 0.5, np.float32)
    bridge.write_uv_layer(a.data, "Lightmap", loop_uv)
    image = bridge.write_image("A_lightmap", np.full((4, 4, 3), 0.75, np.float32))
    camera_on(a)
    b.location = (10.0, 0.0, 0.0)
    (wired,) = bridge.wire_baked_display(a, image=image, uv_layer="Lightmap")
    assert wired != shared and b.material_slots[0].material == shared
    np.testing.assert_allclose(render_centre(bpy.context.scene, tmp_path), 0.75, rtol=1e-3)
    with pytest.raises(ValueError, match="exactly one"):
        bridge.wire_baked_display(a)
