"""Environment mapping from Blender: the operator, the command line, and the mirror against a
Cycles render of true reflections (see kernels/envmap.py)."""

import json
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest

from classic_bake.addon import bridge
from classic_bake.kernels.measure.exr import read_exr

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "sample_blends" / "env_room.blend"


def test_operator_writes_the_view_and_the_cube_map(addon, open_sample):
    open_sample("env_room")
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 40, 30
    scene.classic_bake.trace_adaptive = 0
    assert bpy.ops.classic_bake.envmap() == {"FINISHED"}
    view = bridge.image_pixels(bpy.data.images["Classic Bake Environment"])
    assert view.shape[:2] == (30, 40) and np.all(np.isfinite(view)) and view[..., :3].max() > 0.1
    strip = bpy.data.images["Classic Bake Cube MirrorSphere"]
    size = strip.size[1]
    assert tuple(strip.size) == (6 * size, size) and size >= 16  # six square faces in a row
    assert bridge.image_pixels(strip)[..., :3].mean() > 0.0


def test_selected_only_without_a_selection_is_a_clear_error(addon, open_sample):
    open_sample("env_room")
    scene = bpy.context.scene
    scene.classic_bake.envmap_selected_only = True
    for obj in scene.objects:
        obj.select_set(False)
    with pytest.raises(RuntimeError, match="Select the objects"):
        bpy.ops.classic_bake.envmap()
    assert "Classic Bake Environment" not in bpy.data.images


def test_cancelled_envmap_writes_nothing(addon, open_sample):
    from classic_bake.jobs.envmap import IMAGE_NAME, envmap_job
    from classic_bake.kernels.envmap.envmap import EnvMapSettings
    from classic_bake.kernels.trace.settings import auto_settings

    open_sample("env_room")
    snap = bridge.snapshot(resolution=(20, 15))
    job = envmap_job(snap, EnvMapSettings(face_size=16), auto_settings(snap, adaptive=0),
                     resolution=(20, 15))
    next(job)
    job.close()
    assert IMAGE_NAME not in bpy.data.images
    assert not any(i.name.startswith("Classic Bake Cube") for i in bpy.data.images)


def test_cli_envmap_writes_view_faces_and_sizes(tmp_path):
    done = subprocess.run([sys.executable, "-m", "classic_bake", "envmap", str(SCENE), "--out",
                           str(tmp_path), "--resolution", "32", "24", "--adaptive", "0",
                           "--face-size", "24"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert read_exr(tmp_path / "render.exr").shape == (24, 32, 3)
    faces = read_exr(tmp_path / "cube" / "MirrorSphere.exr")  # OpenEXR's cube: N x 6N, stacked
    assert faces.shape == (6 * 24, 24, 3) and np.all(np.isfinite(faces))
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["sizes"]["maps"]["MirrorSphere"]["face_size"] == 24
    # One ray per texel of the faces and their one-texel borders, 2 x 2 again at edges: each
    # edge texel adds 4 rays (some, not all, texels are edges).
    mapped = metrics["sizes"]["maps"]["MirrorSphere"]
    assert mapped["face_samples"] == [1, 2]
    edge_rays = metrics["sizes"]["face_rays"] - 6 * 26 * 26
    assert mapped["face_rays"] == metrics["sizes"]["face_rays"]
    assert edge_rays % 4 == 0 and 0 < edge_rays < 4 * 6 * 26 * 26
    assert metrics["seconds"]["total"] > 0 and metrics["stage_seconds"]["capture"] > 0


def test_cli_envmap_refuses_an_unknown_object(tmp_path):
    done = subprocess.run([sys.executable, "-m", "classic_bake", "envmap", str(SCENE), "--out",
                           str(tmp_path), "--resolution", "16", "12", "--objects", "Nope"],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 2 and "Nope" in done.stderr


@pytest.mark.slow
def test_mapped_mirror_is_close_to_cycles_true_reflections(tmp_path, open_sample):
    """Cycles with the Whitted model (true mirror rays) at 128 samples. The mapped sphere differs
    by parallax (the sphere stands on a pedestal: the floor is a metre away) and the map's
    resolution; the parallax search takes most of the parallax away. Measured at 96 x 72: relMSE
    over the sphere's pixels 0.041 traced, 0.081 mapped, 0.258 with the lecture's look-up alone."""
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.envmap import envmap
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.trace.settings import auto_settings
    from classic_bake.kernels.trace.tracer import trace

    open_sample("env_room")
    resolution = (96, 72)
    snap = bridge.snapshot(resolution=resolution)
    settings = auto_settings(snap, adaptive=4)
    mapped = envmap.render(snap, envmap.EnvMapSettings(), settings, resolution=resolution).image
    lecture = envmap.render(snap, envmap.EnvMapSettings(parallax_steps=0), settings,
                            resolution=resolution).image
    traced = trace(snap, settings, resolution=resolution).image
    reference, _ = cr.render_camera(bpy.context.scene, cr.whitted(settings.max_depth), 128,
                                    resolution=resolution)
    sphere_id = next(k for k, o in enumerate(snap.objects) if o.source_name == "MirrorSphere")
    sphere = snap.object_ids[_hit_triangles(snap, resolution)] == sphere_id
    errors = {name: rel_mse(image[sphere][:, None], reference[sphere][:, None])
              for name, image in (("mapped", mapped), ("lecture", lecture), ("traced", traced))}
    print(f"sphere pixels {sphere.sum()}: relMSE", errors)
    assert sphere.sum() > 50
    assert errors["traced"] < errors["mapped"] < 0.2
    assert errors["mapped"] < errors["lecture"] / 2
    # Away from the sphere (and the edge samples next to it) the view is the tracer's own.
    near = sphere.copy()
    for axis in (0, 1):
        near |= np.roll(sphere, 1, axis) | np.roll(sphere, -1, axis)
    np.testing.assert_allclose(mapped[~near], traced[~near], rtol=1e-5, atol=1e-6)


def _hit_triangles(snap, resolution):
    """(H, W) triangle hit by each pixel-centre camera ray (-1: none)."""
    from classic_bake.kernels.geometry.bvh import BVH
    from classic_bake.kernels.geometry.camera import camera_rays

    o, d = camera_rays(snap.camera, *resolution)
    hits = BVH.build(snap.triangles).intersect(o.reshape(-1, 3), d.reshape(-1, 3))
    tri = np.where(hits.tri >= 0, hits.tri, 0)
    return tri.reshape(resolution[1], resolution[0])


def test_compare_button_measures_the_mapped_view(addon, open_sample):
    open_sample("env_room")
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    props = scene.classic_bake
    props.compare_technique, props.compare_samples, props.trace_adaptive = "ENVMAP", 16, 0
    assert bpy.ops.classic_bake.compare() == {"FINISHED"}
    assert 0 <= props.compare_rel_mse < 0.2 and props.compare_kernel_seconds > 0
    kernel = bridge.image_pixels(bpy.data.images["Classic Bake Kernel View"])
    assert kernel.shape == (24, 32, 4) and np.all(np.isfinite(kernel))
