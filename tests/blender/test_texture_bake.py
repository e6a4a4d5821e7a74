"""Texture mapping from Blender: operator, cancel, command line, and Cycles' colour-only bake and
Diffuse Color pass of the same texels and pixels."""

import json
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr
from classic_bake.jobs.texture import texture_bake_job
from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings
from classic_bake.kernels.bake.texture_bake import TextureBakeSettings
from classic_bake.kernels.measure.exr import read_exr
from classic_bake.kernels.measure.metrics import rel_mse
from classic_bake.kernels.progress import drain

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "sample_blends" / "raytrace.blend"
PLANE = "CheckerPlane"


def _bake(size: int, cells: int = 0, render: bool = False):
    summary = drain(texture_bake_job(bpy.context, TextureBakeSettings(samples_per_side=cells),
                             "Lightmap", LightmapUVSettings(resolution=size, padding=2),
                             render=render, resolution=(48, 36)))
    return summary


def test_operator_bakes_lightmaps_colour_attributes_and_the_view(addon, open_sample):
    open_sample("raytrace")
    props = bpy.context.scene.classic_bake
    props.lightmap_resolution = 64
    bpy.context.scene.render.resolution_x, bpy.context.scene.render.resolution_y = 32, 24
    assert bpy.ops.classic_bake.texture() == {"FINISHED"}
    plane = bpy.data.objects[PLANE]
    assert "Lightmap" in plane.data.uv_layers
    albedo = bridge.read_color_attribute(plane.data, "Albedo")
    assert albedo.shape[1] >= 3 and albedo[:, :3].max() <= 1.0 and albedo[:, :3].min() >= 0.0
    lightmap = bridge.image_pixels(bpy.data.images[f"Texture {PLANE}"])
    assert lightmap.shape[:2] == (64, 64) and lightmap[..., :3].std() > 0.05  # the checker
    view = bridge.image_pixels(bpy.data.images["Classic Bake Texture"])
    assert view.shape[:2] == (24, 32)


@pytest.mark.slow
def test_cancel_removes_the_lightmap_uvs_it_created(open_sample):
    open_sample("raytrace")
    before = {o.name: [lay.name for lay in o.data.uv_layers] for o in bpy.data.objects
              if o.type == "MESH"}
    job = texture_bake_job(bpy.context, TextureBakeSettings(), "Lightmap",
                           LightmapUVSettings(resolution=32, padding=2))
    next(job)
    job.close()
    after = {o.name: [lay.name for lay in o.data.uv_layers] for o in bpy.data.objects
             if o.type == "MESH"}
    assert after == before
    assert not any(img.name.startswith("Texture ") for img in bpy.data.images)


@pytest.mark.slow
def test_a_text_object_is_reported_not_written(open_sample):
    open_sample("raytrace")
    bpy.ops.object.text_add(location=(0.0, 0.0, 0.5))
    bpy.context.object.data.extrude = 0.05
    summary = _bake(32)
    assert "Text: a font object has no mesh to hold a colour attribute" in summary.skipped
    assert "Text" not in summary.attributes
    assert PLANE in summary.attributes


@pytest.mark.slow
def test_cli_writes_lightmaps_render_and_metrics(tmp_path):
    done = subprocess.run([sys.executable, "-m", "classic_bake", "texture", str(SCENE), "--out",
                           str(tmp_path), "--lightmap-size", "32", "--resolution", "32", "24"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert read_exr(tmp_path / "render.exr").shape == (24, 32, 3)
    assert read_exr(tmp_path / "lightmaps" / f"{PLANE}_albedo.exr").shape[:2] == (32, 32)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["sizes"]["textured_materials"] == ["Checkerboard"]
    assert metrics["sizes"]["look_ups"] >= metrics["sizes"]["baked_texels"] > 0
    bad = subprocess.run([sys.executable, "-m", "classic_bake", "texture", str(SCENE), "--cells",
                          "-1", "--out", str(tmp_path / "x")], capture_output=True, text=True,
                         timeout=300)
    assert bad.returncode == 2 and "samples_per_side" in bad.stderr


@pytest.mark.slow
@pytest.mark.skipif(bpy.app.version < (5, 0, 0), reason=(
    "Cycles 4.5 filters baked texels otherwise: its 256-sample bake of this plane differs from "
    "its 1-sample one in 54 distinct texel values against 5.2's 126, and from the kernel's "
    "texel ∩ triangle box mean by relMSE 0.17 (5.2: 0.0004); not characterised yet"))
def test_a_minified_checker_matches_cycles_converged_colour_bake(open_sample):
    """The checker plane on a 16-texel lightmap: a texel spans about a checker square. Against
    Cycles' colour-only DIFFUSE bake at 256 samples, the filtered bake is within 0.01 relMSE
    (measured 0.00039), a centre look-up per texel is 20x worse (aliasing: measured 0.041), and
    Cycles at 4 samples is worse than the filter (measured 0.048; 64 samples 0.00072)."""
    open_sample("raytrace")
    filtered = _bake(16)
    centre = _bake(16, cells=1)
    images, _, masks = cr.bake_lightmaps(
        bpy.context.scene, cr.albedo(), 256, [PLANE], "Lightmap", 16, "ALBEDO")
    ref, mask = images[PLANE], masks[PLANE]
    ours = filtered.lightmaps[PLANE][0]
    err = rel_mse(ours[mask][:, None], ref[mask][:, None])
    err_centre = rel_mse(centre.lightmaps[PLANE][0][mask][:, None], ref[mask][:, None])
    assert err < 0.01 and err_centre > 20 * err
    one, _, _ = cr.bake_lightmaps(
        bpy.context.scene, cr.albedo(), 4, [PLANE], "Lightmap", 16, "ALBEDO")
    assert rel_mse(one[PLANE][mask][:, None], ref[mask][:, None]) > err


@pytest.mark.slow
def test_the_view_matches_cycles_diffuse_color_pass(open_sample):
    """The camera view of the albedo (48 x 36) against Cycles' Diffuse Color pass at 256
    samples: the checker plane, the spheres black (metal and glass reflect nothing diffusely),
    the background 0 (measured relMSE 0.0015)."""
    open_sample("raytrace")
    summary = _bake(16, render=True)
    image, _ = cr.render_camera(bpy.context.scene, cr.albedo(), 256,
                                resolution=(48, 36))
    assert rel_mse(summary.render, image) < 0.01
    assert np.abs(summary.render[0]).max() == 0.0  # the top row sees the sky: 0, as Cycles


def test_a_checker_on_generated_coordinates_matches_cycles():
    """A Checker Texture left unlinked reads the Generated coordinates (each object's texture
    space mapped to the unit cube), in three dimensions: on a tilted cube's faces the squares
    follow x, y and z, and on a flat plane z = 0.5 (Cycles' nudge floors 0.5 * 4 to 1, odd) swaps
    the colours that (u, v, 0) would give. The camera's albedo view against Cycles' Diffuse Color
    pass, and the cube's lightmap against Cycles' colour bake (measured at 256 and 64 samples:
    relMSE 0.0079 and 0.0078; read on UVs, as before, 3.75 and 0.52)."""
    from blender_parts import checker, lit_scene, oblique_camera, plane, principled

    scene = lit_scene()
    oblique_camera(scene)
    mat, bsdf = principled("Generated")
    checker(mat, bsdf, scale=4.0, coordinates=None)
    # Grey, not black: relMSE would weigh a black pixel's anti-aliasing 25 times a white one's.
    mat.node_tree.nodes["Checker Texture"].inputs["Color2"].default_value = (0.2, 0.2, 0.2, 1.0)
    plane(mat, size=4.0)
    bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.3, 0.0, 0.6), rotation=(0.4, 0.3, 0.6))
    cube = bpy.context.object
    cube.data.materials.append(mat)
    summary = _bake(32, render=True)  # the view at 48 x 36
    image, _ = cr.render_camera(scene, cr.albedo(), 64,
                                resolution=(48, 36))
    assert rel_mse(summary.render, image) < 0.02
    if bpy.app.version < (5, 0, 0):
        return  # Cycles 4.5 filters baked texels otherwise (the minified checker's test above)
    ours = summary.lightmaps[cube.name][0]
    images, _, masks = cr.bake_lightmaps(
        scene, cr.albedo(), 64, [cube.name], "Lightmap", len(ours), "ALBEDO")
    ref, mask = images[cube.name], masks[cube.name]
    assert rel_mse(ours[mask][:, None], ref[mask][:, None]) < 0.02


def test_the_view_darkens_under_the_specular_layer_as_cycles_does():
    """A plane with the default specular layer (level 0.5, roughness 0.2) seen at 72 degrees:
    Cycles' Diffuse Color pass falls from 91% of the base colour at the near rows to 67% at the
    far ones (the layer's albedo rises towards grazing views, kernels/specular_layer.py); the
    tracer's albedo view follows it (measured relMSE 3.5e-4 over the plane, rows within 0.1%)."""
    from blender_parts import BASE, lit_scene, oblique_camera, plane, principled

    from classic_bake.kernels.trace.settings import TracerSettings
    from classic_bake.kernels.trace.tracer import trace

    scene = lit_scene()
    mat, bsdf = principled("Layered")
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    bsdf.inputs["Roughness"].default_value = 0.2
    plane(mat, size=6.0)
    oblique_camera(scene)
    cycles, _ = cr.render_camera(scene, cr.albedo(), 64,
                                 resolution=(32, 24))
    ours = trace(bridge.snapshot(resolution=(32, 24)),
                 TracerSettings(max_depth=0, output="albedo")).image
    plane = (cycles.sum(axis=2) > 0) & (ours.sum(axis=2) > 0)
    shade = cycles[..., 0] / BASE[0]
    rows = [r for r in range(24) if plane[r].sum() > 8]
    assert shade[rows[0]][plane[rows[0]]].mean() < 0.75 < 0.88 < shade[rows[-1]][plane[rows[-1]]].mean()
    assert rel_mse(ours[plane], cycles[plane]) < 2e-3
