"""Normal maps made from heights (jobs/normalmap.py, issue 40) through real Blender: the command
line's files, the flat and DirectX cases, the operator's image and material wiring (and its
undo), a cancelled job changing nothing, degenerate UVs and steep heights, and the checks against
Cycles: the generated map rendered through a Normal Map node gives the shading normals Cycles
gives the Bump node it was made from (a plane, and bump.blend's camera), and it matches Cycles'
own tangent-space NORMAL bake texel by texel."""

import json
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

from classic_bake.addon import bridge
from classic_bake.addon.bridge import normal_maps
from classic_bake.jobs.normalmap import RECORD
from classic_bake.kernels.measure.exr import read_exr
from classic_bake.kernels.normalmap.encode import rgb_to_normals
from classic_bake.kernels.progress import drain

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from support.blender_parts import plane, principled  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "sample_blends" / "bump.blend"
HEIGHT_TEXELS = 64
BUMP_DISTANCE_M = 0.1  # on the 2 m plane: s = 0.05, tilts up to 13 degrees
# 8-bit colours hold a unit normal to within half a code per channel: |n| within 1 +- 3/255.
BYTE_LENGTH_TOLERANCE = 3.0 / 255.0


def values(**overrides) -> dict:
    """The record's default option values with `overrides`."""
    return {**{o.name: o.default for o in RECORD.all_options()}, **overrides}


def height_image(name: str, heights: np.ndarray):
    """A float Non-Color image of heights (H, W), row 0 at the top."""
    height, width = heights.shape
    image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    rgba = np.ones((height, width, 4), np.float32)
    rgba[..., :3] = heights[..., None]
    image.pixels.foreach_set(rgba[::-1].ravel())
    return image


def smooth_heights(n: int = HEIGHT_TEXELS) -> np.ndarray:
    """A smooth relief: 0.5 + 0.25 sin(4 pi u) cos(6 pi v), at texel centres (row 0 top)."""
    centres = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(centres, 1.0 - centres)
    return 0.5 + 0.25 * np.sin(4.0 * np.pi * u) * np.cos(6.0 * np.pi * v)


def bumped_plane(heights: np.ndarray | None = None, distance: float = BUMP_DISTANCE_M):
    """A 2 m plane (UV layer "Lightmap" over [0, 1]^2) whose Principled BSDF's Normal comes from
    a Bump node of a height image: (object, material, bsdf, bump)."""
    mat, bsdf = principled("Relief")
    tree = mat.node_tree
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = height_image("Height", smooth_heights() if heights is None else heights)
    texture.interpolation = "Linear"
    bump = tree.nodes.new("ShaderNodeBump")
    bump.inputs["Distance"].default_value = distance
    tree.links.new(texture.outputs["Color"], bump.inputs["Height"])
    tree.links.new(bump.outputs["Normal"], bsdf.inputs["Normal"])
    return plane(mat), mat, bsdf, bump


def links_of(mat) -> list[tuple[str, str, str, str]]:
    return sorted((lk.from_node.name, lk.from_socket.identifier, lk.to_node.name,
                   lk.to_socket.identifier) for lk in mat.node_tree.links)


def test_cli_writes_png_and_exr_of_unit_normals_per_object(tmp_path):
    done = subprocess.run([sys.executable, "-m", "classic_bake", "normalmap", str(SCENE), "--out",
                           str(tmp_path), "--size", "64"], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert sorted(metrics["normal_maps"]) == ["BrickFloor", "Orange"]
    for name in ("BrickFloor", "Orange"):
        rgb = read_exr(tmp_path / "normalmap" / f"{name}.exr")
        assert rgb.shape == (64, 64, 3)
        n = 2.0 * rgb.astype(np.float64) - 1.0
        np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)
        assert n[..., 2].min() > 0.0 and np.abs(n[..., :2]).max() > 0.01  # the relief is there
        png = bpy.data.images.load(str(tmp_path / "normalmap" / f"{name}.png"))
        png.colorspace_settings.name = "Non-Color"
        assert tuple(png.size) == (64, 64)
        pixels = bridge.image_pixels(png)[..., :3]
        length = np.linalg.norm(2.0 * pixels - 1.0, axis=-1)
        assert np.abs(length - 1.0).max() < BYTE_LENGTH_TOLERANCE
        np.testing.assert_allclose(pixels, rgb, atol=0.5 / 255 + 1e-6)  # 8 bits of the same map
        info = metrics["normal_maps"][name]
        assert info["uv_layer"] == "UVMap" and info["degenerate_texels"] == 0


def test_flat_height_gives_flat_map_and_directx_flips_green():
    obj, _, _, _ = bumped_plane(np.full((16, 16), 0.3))
    obj.select_set(True)
    summary = drain(RECORD.start(bpy.context, values(size=32)))
    rgb = bridge.image_pixels(summary.images["Plane"])[..., :3]
    np.testing.assert_allclose(rgb, np.broadcast_to([0.5, 0.5, 1.0], rgb.shape), atol=1e-6)
    assert summary.images["Plane"].colorspace_settings.name == "Non-Color"
    np.testing.assert_array_equal(summary.files["normalmap/Plane.png"],
                                  np.broadcast_to(np.uint8([128, 128, 255]), (32, 32, 3)))
    # A procedural pattern: DirectX stores the same normals with green turned round.
    opengl = drain(RECORD.start(bpy.context, values(size=32, source="orange_peel")))
    opengl = opengl.files["normalmap/Plane.exr"].copy()
    directx = drain(RECORD.start(bpy.context, values(size=32, source="orange_peel",
                                                     green="DIRECTX")))
    directx = directx.files["normalmap/Plane.exr"]
    np.testing.assert_allclose(rgb_to_normals(opengl), rgb_to_normals(directx, "DIRECTX"),
                               atol=1e-6)
    assert np.abs(opengl[..., 1] - directx[..., 1]).max() > 0.01


def test_operator_writes_the_image_and_wires_the_material(addon):
    obj, mat, bsdf, bump = bumped_plane()
    before = links_of(mat)
    obj.select_set(True)
    props = bpy.context.scene.classic_bake
    props.normalmap_size, props.normalmap_wire = 32, True
    assert bpy.ops.classic_bake.normalmap() == {"FINISHED"}
    image = bpy.data.images["Normal Plane"]
    assert tuple(image.size) == (32, 32) and image.is_float
    assert image.colorspace_settings.name == "Non-Color"
    # Image Texture (the map) -> Normal Map (tangent space, the plane's UV layer) -> BSDF Normal.
    normal_map = bsdf.inputs["Normal"].links[0].from_node
    assert normal_map.type == "NORMAL_MAP"
    assert (normal_map.space, normal_map.uv_map) == ("TANGENT", "Lightmap")
    texture = normal_map.inputs["Color"].links[0].from_node
    assert texture.type == "TEX_IMAGE" and texture.image == image
    uv = texture.inputs["Vector"].links[0].from_node
    assert uv.type == "UVMAP" and uv.uv_map == "Lightmap"
    # The Bump node the map was made from stays in the tree, disconnected from the BSDF.
    assert bump.name in mat.node_tree.nodes and not bump.outputs["Normal"].is_linked
    assert json.loads(mat[normal_maps.PREVIOUS_NORMAL_LINKS]) == {
        bsdf.name: [bump.name, bump.outputs["Normal"].identifier]}
    # Running again replaces the wiring (one map node chain), and unwiring restores the material.
    assert bpy.ops.classic_bake.normalmap() == {"FINISHED"}
    assert sum(1 for n in mat.node_tree.nodes if n.type == "NORMAL_MAP") == 1
    normal_maps.unwire_normal_map(mat)
    assert links_of(mat) == before
    assert normal_maps.PREVIOUS_NORMAL_LINKS not in mat


def test_procedural_map_keeps_an_existing_bump_and_chains_into_it():
    obj, mat, bsdf, bump = bumped_plane()
    before = links_of(mat)
    obj.select_set(True)
    drain(RECORD.start(bpy.context, values(size=16, source="bricks", wire=True)))
    assert bsdf.inputs["Normal"].links[0].from_node == bump  # the material's relief stays
    assert bump.inputs["Normal"].links[0].from_node.type == "NORMAL_MAP"  # and takes the map
    normal_maps.unwire_normal_map(mat)
    assert links_of(mat) == before


def test_cancelled_job_changes_nothing():
    obj, mat, _, _ = bumped_plane()
    obj.select_set(True)
    images, links = sorted(bpy.data.images.keys()), links_of(mat)
    nodes = sorted(mat.node_tree.nodes.keys())
    job = RECORD.start(bpy.context, values(size=32, wire=True))
    next(job)
    job.close()
    assert sorted(bpy.data.images.keys()) == images
    assert links_of(mat) == links and sorted(mat.node_tree.nodes.keys()) == nodes
    assert normal_maps.PREVIOUS_NORMAL_LINKS not in mat


def _angles(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Degrees between the (H, W, 3) vectors of a and b."""
    a = a / np.maximum(np.linalg.norm(a, axis=-1, keepdims=True), 1e-12)  # world pixels: 0
    b = b / np.maximum(np.linalg.norm(b, axis=-1, keepdims=True), 1e-12)
    return np.degrees(np.arccos(np.clip((a * b).sum(-1), -1.0, 1.0)))


def test_generated_map_shades_as_cycles_bump_node(addon):
    """Cycles renders the plane's shading normals (Normal pass, 48 x 48, 4 samples, the same
    seed, so the same sample positions) with the Bump node, then with the map the operator made
    from it (128 x 128 from the 64 x 64 height) through its Normal Map node. Measured: mean
    angular error 0.23 degrees, 99th percentile 0.68 (the relief tilts the normals 7.5 degrees
    on average, 13 at most); under a sun 50 degrees from the zenith the lit renders differ by
    relMSE 1.6e-5 (Blender 5.2; printed)."""
    from classic_bake.addon import cycles as cr
    from classic_bake.addon.cycles.models import CyclesModel
    from classic_bake.kernels.measure.metrics import rel_mse

    obj, mat, bsdf, _ = bumped_plane()
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.data.type, camera.data.ortho_scale = "ORTHO", 2.0
    camera.location = (0.0, 0.0, 3.0)  # looking down -z at the whole plane
    scene.collection.objects.link(camera)
    scene.camera = camera
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (0.9, 0.0, 0.6)  # 50 degrees from the zenith: the relief shows
    scene.collection.objects.link(sun)
    normals = CyclesModel(name="normals", max_bounces=0, diffuse_bounces=0, glossy_bounces=0,
                          transmission_bounces=0, render_pass="Normal")
    resolution = (48, 48)
    bumped, _ = cr.render_camera(scene, normals, 4, resolution=resolution)
    lit_bumped, _ = cr.render_camera(scene, cr.direct(), 4, resolution=resolution)

    obj.select_set(True)
    props = scene.classic_bake
    props.normalmap_size, props.normalmap_wire = 128, True
    assert bpy.ops.classic_bake.normalmap() == {"FINISHED"}
    mapped, _ = cr.render_camera(scene, normals, 4, resolution=resolution)
    lit_mapped, _ = cr.render_camera(scene, cr.direct(), 4, resolution=resolution)

    error = _angles(mapped, bumped)
    tilt = _angles(bumped, np.broadcast_to([0.0, 0.0, 1.0], bumped.shape))
    lit = rel_mse(lit_mapped, lit_bumped)
    print(f"angular error mean {error.mean():.3f} p99 {np.percentile(error, 99):.3f} max "
          f"{error.max():.3f} degrees; tilt mean {tilt.mean():.2f}; lit relMSE {lit:.3g}")
    assert tilt.mean() > 3.0  # the relief is there to be matched
    assert error.mean() < 1.0
    assert lit < 1e-3


@pytest.mark.parametrize("source", ["checker", "bricks"])
def test_procedural_sources_give_finite_unit_normals(source):
    obj, _, _, _ = bumped_plane()
    obj.select_set(True)
    summary = drain(RECORD.start(bpy.context, values(size=32, source=source, strength=2.0)))
    n = 2.0 * summary.files["normalmap/Plane.exr"].astype(np.float64) - 1.0
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)
    assert summary.extra["normal_maps"]["Plane"]["degenerate_texels"] == 0


def test_sample_scene_maps_shade_as_its_bump_nodes(addon, open_sample):
    """bump.blend's camera (Normal pass, 80 x 60, 4 samples, one seed) with its two Bump nodes,
    then with 512^2 maps made from them and wired in: on the brick floor and on the orange (a
    UV sphere, u stretched 3.1 m around the equator and nothing at the poles: each texel takes
    its triangle's stretch, `surface_metric`). Measured: mean 0.68 degrees, 99th percentile 2.7
    (the brick mortar's edges); at 160 x 120 0.65 (floor 0.71, orange 0.32; 0.40 with 1024^2
    maps), and with one strength per object instead of the stretch the orange was 1.1."""
    from classic_bake.addon import cycles as cr
    from classic_bake.addon.cycles.models import CyclesModel

    open_sample("bump")
    scene = bpy.context.scene
    normals = CyclesModel(name="normals", max_bounces=0, diffuse_bounces=0, glossy_bounces=0,
                          transmission_bounces=0, render_pass="Normal")
    resolution = (80, 60)
    bumped, _ = cr.render_camera(scene, normals, 4, resolution=resolution)
    props = scene.classic_bake
    props.normalmap_size, props.normalmap_wire = 512, True
    assert bpy.ops.classic_bake.normalmap() == {"FINISHED"}
    mapped, _ = cr.render_camera(scene, normals, 4, resolution=resolution)
    seen = np.linalg.norm(bumped, axis=-1) > 0.5  # not the world
    error = _angles(mapped, bumped)[seen]
    print(f"bump.blend: angular error mean {error.mean():.3f}, p99 "
          f"{np.percentile(error, 99):.3f} degrees over {seen.sum()} pixels")
    assert error.mean() < 1.0


def test_zero_area_uvs_and_steep_heights_give_finite_unit_normals_and_counts():
    """Two quads, the second with every UV at one point (no parametrisation), under a checker's
    steps at 100 times the usual relief: the map stays finite and unit, the collapsed UV face is
    counted (two triangles) and the steps' texels are reported steep."""
    mat, _ = principled("Steps")
    mesh = bpy.data.meshes.new("Strip")
    mesh.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (2, 1, 0)], [],
                     [(0, 1, 2, 3), (1, 4, 5, 2)])
    uv = [0, 0, 1, 0, 1, 1, 0, 1] + [0.5, 0.5] * 4
    mesh.uv_layers.new(name="UVMap").uv.foreach_set("vector", uv)
    mesh.materials.append(mat)
    obj = bpy.data.objects.new("Strip", mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.select_set(True)
    summary = drain(RECORD.start(bpy.context, values(size=64, source="checker")))
    n = 2.0 * summary.files["normalmap/Strip.exr"].astype(np.float64) - 1.0
    assert np.all(np.isfinite(n))
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)
    info = summary.extra["normal_maps"]["Strip"]
    assert info["degenerate_uv_triangles"] == 2 and info["degenerate_texels"] == 0
    steep = drain(RECORD.start(bpy.context, values(size=64, source="checker", strength=100.0)))
    assert steep.extra["normal_maps"]["Strip"]["steep_texels"] > 0
    n = 2.0 * steep.files["normalmap/Strip.exr"].astype(np.float64) - 1.0
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-5)


def test_map_matches_cycles_own_tangent_space_normal_bake():
    """Cycles' NORMAL bake (tangent space, OpenGL axes, 4 samples) of the Bump-node plane into a
    64 x 64 float image, against the map made from that Bump at the same size, texel by texel.
    Measured: mean angular error 0.45 degrees, 99th percentile 1.3, max 1.9 (128^2 at 16
    samples: 0.41, 1.0, 1.1). What is left is the slope's footprint: Cycles differences the
    bilinear height over a tiny step, the map one texel either side."""
    obj, mat, _, _ = bumped_plane()
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device, scene.cycles.samples = "CPU", 4
    size = 64
    baked = bpy.data.images.new("Cycles Normal Bake", size, size, alpha=True, float_buffer=True)
    baked.colorspace_settings.name = "Non-Color"
    target = mat.node_tree.nodes.new("ShaderNodeTexImage")
    target.image = baked
    mat.node_tree.nodes.active = target
    bpy.context.view_layer.objects.active = obj
    obj.select_set(True)
    assert bpy.ops.object.bake(type="NORMAL", normal_space="TANGENT", normal_r="POS_X",
                               normal_g="POS_Y", normal_b="POS_Z", margin=0,
                               uv_layer="Lightmap", target="IMAGE_TEXTURES") == {"FINISHED"}
    theirs = bridge.image_pixels(baked)
    mat.node_tree.nodes.remove(target)
    ours = drain(RECORD.start(bpy.context, values(size=size))).files["normalmap/Plane.exr"]
    covered = theirs[..., 3] > 0.5
    error = _angles(2.0 * ours - 1.0, 2.0 * theirs[..., :3] - 1.0)[covered]
    print(f"against Cycles' NORMAL bake: mean {error.mean():.3f}, p99 "
          f"{np.percentile(error, 99):.3f}, max {error.max():.3f} degrees over {covered.sum()} texels")
    assert covered.sum() == size * size
    assert error.mean() < 1.0 and np.percentile(error, 99) < 2.5


def test_rewriting_a_map_at_another_size_keeps_its_pixels():
    """A map made again at another size reuses its image: resized, Non-Color, the new pixels."""
    first = np.full((16, 16, 3), 0.25, np.float32)
    image = normal_maps.write_normal_image("Normal Resized", first)
    second = np.random.default_rng(3).random((32, 32, 3)).astype(np.float32)
    again = normal_maps.write_normal_image("Normal Resized", second, image=image)
    assert again == image and tuple(image.size) == (32, 32)
    assert image.colorspace_settings.name == normal_maps.NON_COLOR
    np.testing.assert_allclose(bridge.image_pixels(image)[..., :3], second, atol=1e-6)
