"""UDIM (tiled) images, as texture painters export them: the material reader loads every tile
(`bridge.images.tile_pixels`, from files or packed data) and the kernels look each UV up in the
tile holding it (`kernels.shading.textures.sample_tiles`). A strip of quads whose UVs cross tiles
1001, 1002 and an absent 1003 is traced and rendered by Cycles: the same colours, pixel for
pixel, for each extension mode (it acts within a tile)."""

from __future__ import annotations

import os

import bpy
import numpy as np
import pytest
from blender_parts import bare_material

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import trace

RED, GREEN, MAGENTA = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 0.0, 1.0)
WIDTH, HEIGHT = 12, 4  # pixels: a quarter of a UV unit each across u in [-0.5, 2.5]


def write_tile(path, rgb, side=16):
    image = bpy.data.images.new("tile", side, side)
    image.pixels.foreach_set(np.tile([*rgb, 1.0], side * side).astype(np.float32))
    image.filepath_raw, image.file_format = str(path), "PNG"
    image.save()
    bpy.data.images.remove(image)


def udim_strip(folder, extension="REPEAT"):
    """Tiles 1001 (red) and 1002 (green) on disk; an emissive strip 3 m x 1 m seen by an ortho
    camera, u running -0.5 .. 2.5 over quads that each stay in one tile (Cycles loads the tiles
    the mesh's vertices fall in). Returns the tiled image."""
    write_tile(folder / "paint.1001.png", RED)
    write_tile(folder / "paint.1002.png", GREEN)
    image = bpy.data.images.load(str(folder / "paint.1001.png"))
    image.source = "TILED"  # finds paint.1002.png beside it
    image.colorspace_settings.name = "Non-Color"
    xs, us = [-1.5, -1.0, 0.0, 1.0, 1.5], [-0.5, 0.0, 1.0, 2.0, 2.5]
    mesh = bpy.data.meshes.new("Strip")
    mesh.from_pydata([(x, y, 0.0) for y in (-0.5, 0.5) for x in xs], [],
                     [(i, i + 1, i + 6, i + 5) for i in range(4)])
    uv = [c for i in range(4) for c in (us[i], 0, us[i + 1], 0, us[i + 1], 1, us[i], 1)]
    mesh.uv_layers.new(name="UV").uv.foreach_set("vector", np.array(uv, np.float32))
    mat, tree, output = bare_material("Painted")
    texture, emission = tree.nodes.new("ShaderNodeTexImage"), tree.nodes.new("ShaderNodeEmission")
    texture.image, texture.extension = image, extension
    tree.links.new(texture.outputs["Color"], emission.inputs["Color"])
    tree.links.new(emission.outputs[0], output.inputs["Surface"])
    mesh.materials.append(mat)
    scene = bpy.context.scene
    scene.collection.objects.link(bpy.data.objects.new("Strip", mesh))
    camera = bpy.data.cameras.new("Camera")
    camera.type, camera.ortho_scale = "ORTHO", 3.0
    scene.camera = bpy.data.objects.new("Camera", camera)
    scene.camera.location = (0.0, 0.0, 5.0)
    scene.collection.objects.link(scene.camera)
    return image


@pytest.mark.parametrize("extension, left", [("REPEAT", RED), ("CLIP", (0.0, 0.0, 0.0))])
def test_udim_tiles_trace_as_cycles_renders_them(tmp_path, extension, left):
    image = udim_strip(tmp_path, extension)
    assert [t.number for t in image.tiles] == [1001, 1002]
    theirs = cr.render_camera(bpy.context.scene, cr.direct(), 1, (WIDTH, HEIGHT))[0]
    snap = bridge.snapshot(resolution=(WIDTH, HEIGHT))
    ours = trace(snap, TracerSettings(max_depth=1), resolution=(WIDTH, HEIGHT)).image
    # u < 0 reads tile 1001 through its extension; u in [2, 2.5] has no tile: magenta.
    expected = [left] * 2 + [RED] * 4 + [GREEN] * 4 + [MAGENTA] * 2
    np.testing.assert_allclose(theirs[HEIGHT // 2], expected, atol=1e-6)
    np.testing.assert_allclose(ours, theirs, atol=1e-6)


def test_packed_udim_tiles_read_without_their_files(tmp_path):
    image = udim_strip(tmp_path)
    image.pack()
    for tile in (1001, 1002):
        os.remove(tmp_path / f"paint.{tile}.png")
    snap = bridge.snapshot(resolution=(WIDTH, HEIGHT))
    texture = next(m for m in snap.materials if m.name == "Painted").emission_texture
    assert sorted(texture.udim) == [1001, 1002]
    np.testing.assert_allclose(texture.udim[1001][..., :3], np.broadcast_to(RED, (16, 16, 3)))
    np.testing.assert_allclose(texture.udim[1002][..., :3], np.broadcast_to(GREEN, (16, 16, 3)))
    assert not [i for i in bpy.data.images if i.name != image.name]  # the tiles' loads removed
