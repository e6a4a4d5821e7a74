"""Bump mapping from Blender: the operator, the command line, and the bumped view against Cycles
rendering the same Bump nodes (see kernels/bump.py)."""

import json
import math
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
from blender_parts import normal_mapped, tiles_for_bumps, tilted_tiles

from classic_bake.addon import bridge
from classic_bake.kernels.measure.exr import read_exr

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "sample_blends" / "bump.blend"


def _phong_and_bump_errors(snap, resolution) -> dict:
    """{"phong", "bump"}: relMSE of the traced view (adaptive 4) with the relief left out and
    drawn, against Cycles' Whitted model of the scene (128 samples)."""
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.trace.settings import auto_settings
    from classic_bake.kernels.trace.tracer import trace

    settings = auto_settings(snap, adaptive=4)
    reference, _ = cr.render_camera(bpy.context.scene, cr.whitted(settings.max_depth), 128,
                                    resolution=resolution)
    return {mode: rel_mse(trace(snap, auto_settings(snap, adaptive=4, shading=mode),
                                resolution=resolution).image, reference)
            for mode in ("phong", "bump")}


def test_operator_renders_each_shading_mode(addon, open_sample):
    open_sample("bump")
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 40, 30
    props = scene.classic_bake
    props.bump_adaptive = 0
    views = {}
    for mode in ("FLAT", "GOURAUD", "PHONG", "BUMP"):
        props.bump_shading = mode.lower()
        assert bpy.ops.classic_bake.shading() == {"FINISHED"}
        views[mode] = bridge.image_pixels(bpy.data.images["Classic Bake Shading"])[..., :3].copy()
        assert views[mode].shape == (30, 40, 3) and np.all(np.isfinite(views[mode]))
    assert np.abs(views["BUMP"] - views["PHONG"]).max() > 0.01  # the bricks' and peel's relief


def test_cancelled_shading_writes_nothing(addon, open_sample):
    from classic_bake.jobs.bump import IMAGE_NAME, shading_job
    from classic_bake.kernels.trace.settings import auto_settings

    open_sample("bump")
    snap = bridge.snapshot(resolution=(20, 15))
    job = shading_job(snap, auto_settings(snap, adaptive=0), resolution=(20, 15))
    next(job)
    job.close()
    assert IMAGE_NAME not in bpy.data.images


def test_cli_bump_writes_every_mode(tmp_path):
    done = subprocess.run([sys.executable, "-m", "classic_bake", "bump", str(SCENE), "--out",
                           str(tmp_path), "--resolution", "32", "24", "--adaptive", "0",
                           "--all-modes"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    render = read_exr(tmp_path / "render.exr")
    for mode in ("flat", "gouraud", "phong", "bump"):
        assert read_exr(tmp_path / "modes" / f"{mode}.exr").shape == (24, 32, 3)
    np.testing.assert_array_equal(render, read_exr(tmp_path / "modes" / "bump.exr"))
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    assert metrics["settings"]["shading"] == "bump"
    assert sorted(metrics["sizes"]["bumped_materials"]) == ["Bricks", "OrangePeel"]


def test_bumped_view_matches_cycles_bump_nodes(open_sample):
    """Cycles (the `whitted` model, 128 samples) renders the Bump nodes; at 80 x 60 the bumped
    view's relMSE was 4.2e-4, Phong's (the relief left out) 3.6e-3."""
    open_sample("bump")
    resolution = (80, 60)
    errors = _phong_and_bump_errors(bridge.snapshot(resolution=resolution), resolution)
    print("relMSE against Cycles", errors)
    assert errors["bump"] < 0.002 and errors["bump"] < errors["phong"] / 4


def test_bump_node_settings_reach_the_kernel(open_sample):
    """Distance and Strength as set; Invert pushes the relief inwards (a negated distance); a
    chained bump (the node's Normal input from another Bump node) is reported as not modelled."""
    open_sample("bump")
    bricks = bpy.data.materials["Bricks"]
    node = next(n for n in bricks.node_tree.nodes if n.type == "BUMP")
    node.inputs["Distance"].default_value = 0.02
    node.inputs["Strength"].default_value = 0.5
    mat = next(m for m in bridge.snapshot().materials if m.name == "Bricks")
    assert mat.height_texture is not None
    assert abs(mat.bump_distance - 0.02) < 1e-7 and abs(mat.bump_strength - 0.5) < 1e-7
    node.invert = True
    assert abs(next(m for m in bridge.snapshot().materials
                    if m.name == "Bricks").bump_distance + 0.02) < 1e-7
    chained = bricks.node_tree.nodes.new("ShaderNodeBump")  # a second relief under the first
    bricks.node_tree.links.new(node.inputs["Height"].links[0].from_socket, chained.inputs["Height"])
    bricks.node_tree.links.new(chained.outputs["Normal"], node.inputs["Normal"])
    mat = next(m for m in bridge.snapshot().materials if m.name == "Bricks")
    assert any("chained" in why for why in mat.ignored)


def test_normal_map_nodes_match_cycles(open_sample):
    """bump.blend with its Bump nodes replaced by a tangent-space Normal Map of tilted tiles (x
    along u, y along v; Non-Color): the kernel's normal-mapped view against Cycles (`whitted`,
    64 samples, 80 x 60): measured 0.0013 against Phong's 0.095 (the tiles left out). A wrong
    green channel or tangent would shade half the tiles the wrong way."""
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.trace.settings import auto_settings
    from classic_bake.kernels.trace.tracer import trace

    open_sample("bump")
    tiles_for_bumps(("Bricks", "OrangePeel"))
    resolution = (80, 60)
    snap = bridge.snapshot(resolution=resolution)
    assert all(m.normal_texture is not None for m in snap.materials if m.name in ("Bricks",
                                                                              "OrangePeel"))
    reference, _ = cr.render_camera(bpy.context.scene, cr.whitted(4), 64, resolution=resolution)
    errors = {mode: rel_mse(trace(snap, auto_settings(snap, shading=mode),
                                  resolution=resolution).image, reference)
              for mode in ("phong", "bump")}
    print("relMSE against Cycles", errors)
    assert errors["bump"] < 0.02 and errors["bump"] < errors["phong"] / 5


def test_steep_normal_maps_reflect_about_a_valid_normal_as_cycles_does():
    """A glossy floor (roughness 0.25) of tiles tilted 1.0 / -0.9 rad by a Normal Map, seen at
    30 degrees above it under a sun and a grey world: many tilted normals face away from the
    camera, or reflect its view below the floor. Cycles' glossy closures bend such a normal
    towards the geometric one until the reflection leaves the surface, its diffuse ones keep
    it (a tile tilted away from the sun stays dark); so do the kernels (`SurfaceHits.spec`).
    Measured against Cycles (`whitted`, 64 samples, 64 x 48): 0.0026 in Blender 5.2 (0.010 in
    4.5, whose Cycles shades steep reliefs a little differently); bending the normal for the
    diffuse base too gave 0.57. A Normal Map strength of 2, applied in tangent space as Cycles
    does: 0.0047 (blending the world normals instead: 0.032)."""
    from blender_parts import principled

    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.trace.settings import auto_settings
    from classic_bake.kernels.trace.tracer import trace

    scene = bpy.context.scene
    mat, bsdf = principled("Tiles", base=(0.5, 0.5, 0.5))
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    bsdf.inputs["Roughness"].default_value = 0.25
    normal_map = normal_mapped(mat, bsdf, tilted_tiles(tilts=(1.0, -0.9)))
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="UV").uv.foreach_set("vector", [0, 0, 1, 0, 1, 1, 0, 1])
    mesh.materials.append(mat)
    scene.collection.objects.link(bpy.data.objects.new("Floor", mesh))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.rotation_euler = 3.0, (math.radians(30), 0.0, math.radians(40))
    scene.collection.objects.link(sun)
    scene.world = bpy.data.worlds.new("Grey")
    scene.world.color = (0.3, 0.3, 0.3)
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location, camera.rotation_euler = (0.0, -4.0, 2.3), (math.radians(60), 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    resolution = (64, 48)
    bound = 0.01 if bpy.app.version >= (5, 0, 0) else 0.02
    for strength in (1.0, 2.0):
        normal_map.inputs["Strength"].default_value = strength
        snap = bridge.snapshot(resolution=resolution)
        reference, _ = cr.render_camera(scene, cr.whitted(4), 64, resolution=resolution)
        error = rel_mse(trace(snap, auto_settings(snap), resolution=resolution).image, reference)
        print("relMSE against Cycles at strength", strength, error)
        assert error < bound * strength


def test_a_bump_on_a_normal_map_matches_cycles(open_sample):
    """bump.blend's Bump nodes kept, a Normal Map of tilted tiles feeding each one's Normal (how
    texture libraries wire a height map over a normal map): Cycles bumps the mapped normal, and
    so do the kernels. Either relief alone (the bump was all that was read before) is far
    further from Cycles' render (`whitted`, 64 samples, 80 x 60)."""
    from dataclasses import replace

    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.trace.settings import auto_settings
    from classic_bake.kernels.trace.tracer import trace

    open_sample("bump")
    image = tilted_tiles()
    names = ("Bricks", "OrangePeel")
    for name in names:
        tree = bpy.data.materials[name].node_tree
        tex = tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        normal_map = tree.nodes.new("ShaderNodeNormalMap")
        normal_map.inputs["Strength"].default_value = 0.8
        tree.links.new(tex.outputs["Color"], normal_map.inputs["Color"])
        bump = next(n for n in tree.nodes if n.type == "BUMP")
        tree.links.new(normal_map.outputs["Normal"], bump.inputs["Normal"])
    resolution = (80, 60)
    snap = bridge.snapshot(resolution=resolution)
    both = [m for m in snap.materials if m.name in names]
    assert all(m.normal_texture is not None and m.height_texture is not None for m in both)
    assert all(abs(m.normal_strength - 0.8) < 1e-6 and not m.ignored for m in both)
    reference, _ = cr.render_camera(bpy.context.scene, cr.whitted(4), 64, resolution=resolution)

    def error(**fields):
        scene = replace(snap, materials=tuple(replace(m, **fields) if m.name in names else m
                                              for m in snap.materials))
        return rel_mse(trace(scene, auto_settings(scene), resolution=resolution).image, reference)

    errors = {"chained": error(), "bump only": error(normal_texture=None),
              "normal map only": error(height_texture=None)}
    print("relMSE against Cycles", errors)
    assert errors["chained"] < 0.02
    assert errors["chained"] < min(errors["bump only"], errors["normal map only"]) / 2


def _bump_as_displacement(mat, space, scale):
    """Rewire `mat`'s Bump node as Cycles' bump from displacement: its height texture into a
    Displacement node (`space`, Scale `scale`, Midlevel 0.5) in the output's Displacement slot,
    the BSDF's Normal left unlinked; the material's method Bump Only."""
    tree = mat.node_tree
    bump = next(n for n in tree.nodes if n.type == "BUMP")
    height = bump.inputs["Height"].links[0].from_socket
    tree.nodes.remove(bump)
    node = tree.nodes.new("ShaderNodeDisplacement")
    node.space = space
    node.inputs["Scale"].default_value = scale
    node.inputs["Midlevel"].default_value = 0.5
    tree.links.new(height, node.inputs["Height"])
    output = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    tree.links.new(node.outputs["Displacement"], output.inputs["Displacement"])
    mat.displacement_method = "BUMP"


def test_a_displacement_nodes_bump_matches_cycles(open_sample):
    """A height texture into the output's Displacement slot (Bump Only, Cycles' default) is a
    bump of distance Scale in world space, Scale times the object's scale in object space: the
    sample's two bumps rewired so (the orange scaled 1.5x in object space) give the Bump nodes'
    distance 0.01, and the view matches Cycles within the Bump nodes' bound (measured 7.4e-4;
    the relief left out 5.0e-3). 'Displacement Only' moves vertices (noted, not modelled)."""
    open_sample("bump")
    _bump_as_displacement(bpy.data.materials["Bricks"], "WORLD", 0.01)
    _bump_as_displacement(bpy.data.materials["OrangePeel"], "OBJECT", 0.01 / 1.5)
    orange = bpy.data.objects["Orange"]
    orange.scale = (1.5, 1.5, 1.5)
    resolution = (80, 60)
    snap = bridge.snapshot(resolution=resolution)
    for mat in snap.materials[1:]:
        assert mat.height_texture is not None and abs(mat.bump_distance - 0.01) < 1e-6, mat.name
        assert not any("isplacement" in why for why in mat.ignored)
    errors = _phong_and_bump_errors(snap, resolution)
    print("relMSE against Cycles", errors)
    assert errors["bump"] < 0.002 and errors["bump"] < errors["phong"] / 4

    bpy.data.materials["Bricks"].displacement_method = "DISPLACEMENT"
    bricks = next(m for m in bridge.snapshot().materials if m.name == "Bricks")
    assert bricks.height_texture is None
    assert any("Displacement Only" in why for why in bricks.ignored)


def _height_through(mat, variant):
    """Put a ColorRamp (0.2 .. 0.8) between `mat`'s height image and its Bump node, or replace
    the image by a Noise Texture (scale 8, Generated coordinates; Distance 0.05)."""
    tree = mat.node_tree
    bump = next(n for n in tree.nodes if n.type == "BUMP")
    image = bump.inputs["Height"].links[0].from_socket
    if variant == "ramp":
        ramp = tree.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].position = 0.2
        ramp.color_ramp.elements[1].position = 0.8
        tree.links.new(image, ramp.inputs["Fac"])
        tree.links.new(ramp.outputs["Color"], bump.inputs["Height"])
    else:
        noise = tree.nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 8.0
        tree.links.new(noise.outputs["Fac"], bump.inputs["Height"])
        bump.inputs["Distance"].default_value = 0.05


def test_bump_heights_through_node_chains_and_procedural_textures_match_cycles(open_sample):
    """A height image through a ColorRamp is read with the ramp folded in (socket_values.py);
    a procedural height (a Noise Texture on Generated coordinates) is baked by Cycles over the
    UVs and named in `fallbacks`. Both were left out (flat). Measured at 80 x 60 against Cycles:
    the ramp 1.1e-3 (6.3e-3 flat), the noise 2.2e-3 (3.7e-3 flat; the bake's size does not move
    it: 256 to 1024 texels a side 2.21e-3 to 2.17e-3)."""
    for variant, bound, gain in (("ramp", 0.002, 4.0), ("noise", 0.003, 1.4)):
        open_sample("bump")
        for name in ("Bricks", "OrangePeel"):
            _height_through(bpy.data.materials[name], variant)
        resolution = (80, 60)
        snap = bridge.snapshot(resolution=resolution)
        for mat in snap.materials[1:]:
            assert mat.height_texture is not None, (variant, mat.name)
            assert bool(mat.fallbacks) == (variant == "noise"), (variant, mat.name)
        errors = _phong_and_bump_errors(snap, resolution)
        print(variant, "relMSE against Cycles", errors)
        assert errors["bump"] < bound and errors["bump"] * gain < errors["phong"], variant
