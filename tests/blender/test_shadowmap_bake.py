"""Shadow-map bakes from Blender: operator, cancel, command line, and Cycles' SHADOW bake."""

import json
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr
from classic_bake.jobs.shadowmap import shadow_bake_job
from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings
from classic_bake.kernels.measure.exr import read_exr
from classic_bake.kernels.progress import drain
from classic_bake.kernels.shading.direct_light import DirectLightSettings

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "sample_blends" / "shadows.blend"
UV = LightmapUVSettings(resolution=64, padding=2)


def test_operator_bakes_lightmaps_and_colour_attributes(addon, open_sample):
    open_sample("shadows")
    props = bpy.context.scene.classic_bake
    props.lightmap_resolution = 64
    bpy.context.scene.render.resolution_x, bpy.context.scene.render.resolution_y = 32, 24
    assert bpy.ops.classic_bake.shadowmap() == {"FINISHED"}
    ground = bpy.data.objects["Ground"]
    assert "Lightmap" in ground.data.uv_layers
    mask = bridge.read_color_attribute(ground.data, "Shadow")[:, 0]
    assert mask.min() >= 0 and mask.max() <= 1 and mask.max() == 1.0
    lightmap = bridge.image_pixels(bpy.data.images["Shadow Ground"])[..., 0]
    assert lightmap.shape == (64, 64) and 0 < lightmap.mean() < 1
    assert "Classic Bake Shadows" in bpy.data.images


def test_cancel_removes_the_lightmap_uvs_it_created(open_sample):
    open_sample("shadows")
    before = {o.name: [lay.name for lay in o.data.uv_layers] for o in bpy.data.objects
              if o.type == "MESH"}
    job = shadow_bake_job(bpy.context, DirectLightSettings(), "Lightmap", UV)
    next(job)
    job.close()
    after = {o.name: [lay.name for lay in o.data.uv_layers] for o in bpy.data.objects
             if o.type == "MESH"}
    assert after == before
    assert not any(img.name.startswith("Shadow ") for img in bpy.data.images)


@pytest.mark.slow
def test_cli_writes_lightmaps_render_and_metrics(tmp_path):
    done = subprocess.run([sys.executable, "-m", "classic_bake", "shadowmap", str(SCENE), "--out",
                           str(tmp_path), "--lightmap-size", "64", "--resolution", "32", "24"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert read_exr(tmp_path / "render.exr").shape == (24, 32, 3)
    ground = read_exr(tmp_path / "lightmaps" / "Ground_shadow.exr")
    assert ground.shape == (64, 64, 1)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["sizes"]["baked_texels"] > 0 and metrics["settings"]["eps_mode"] == "auto"
    bad = subprocess.run([sys.executable, "-m", "classic_bake", "shadowmap", str(SCENE), "--pcf", "2",
                          "--out", str(tmp_path / "x")], capture_output=True, text=True, timeout=300)
    assert bad.returncode == 2 and "pcf" in bad.stderr


def test_each_light_agrees_with_cycles_shadow_bake(open_sample):
    """Per light, the kernel's visibility and Cycles' SHADOW bake (max_bounces 0, lights as points)
    disagree on under 0.5% of the ground's 64 x 64 texels (the issue's target; measured 0.00-0.08%)."""
    open_sample("shadows")
    summary = drain(shadow_bake_job(bpy.context, DirectLightSettings(), "Lightmap", UV, render=False))
    ours = summary.extra["per_light"]["Ground"]  # (L, 64, 64)
    names = [light.name for light in summary.scene.lights]
    lights = [o for o in bpy.context.scene.objects if o.type == "LIGHT"]
    for k, name in enumerate(names):
        for obj in lights:
            obj.hide_render = obj.name != name
        images, _, masks = cr.bake_lightmaps(
            bpy.context.scene, cr.direct(), 1, ["Ground"], "Lightmap", 64, "SHADOW")
        theirs = images["Ground"][..., 0] > 0.5
        valid = masks["Ground"] & summary.lightmaps["Ground"][1]
        disagree = np.count_nonzero(((ours[k] > 0.5) != theirs) & valid) / valid.sum()
        print(f"{name}: {disagree:.4%} of {valid.sum()} texels disagree")
        assert disagree < 0.005, (name, disagree)
