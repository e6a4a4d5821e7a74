"""The world as a light (kernels/world_light.py): a uniform colour and an equirectangular
Environment Texture, the background the camera sees and the sky light surfaces receive, against
Cycles."""

import math

import bpy
import numpy as np
import pytest
from blender_parts import bare_material, colour_world, hdri_world, node_world

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr
from classic_bake.jobs.radiosity import radiosity_bake_job
from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings
from classic_bake.kernels.measure.metrics import rel_mse
from classic_bake.kernels.progress import drain
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import trace


@pytest.mark.parametrize("mapping", [None, "POINT", "TEXTURE"])
def test_the_camera_sees_the_environment_map_as_cycles_does(mapping):
    """A smooth map (red along u, green along v) seen by a 60-degree camera looking along +x
    from the origin, the map's centre, as it is or turned by a Mapping node of the Generated
    coordinates (rotation (0.3, 0, 1.2) rad, scale (1, 1, 1.3)): the tracer's escaping rays read
    it as Cycles' background does (relMSE under 1e-4 against a 16-sample box-filtered render; no
    geometry in view)."""
    height, width = 64, 128
    v, u = np.mgrid[0:height, 0:width]
    pixels = np.stack([(u + 0.5) / width, 1.0 - (v + 0.5) / height,
                       np.full((height, width), 0.2)], axis=-1).astype(np.float32)
    scene = hdri_world(pixels, strength=1.5)
    if mapping is not None:
        tree = scene.world.node_tree
        env = next(n for n in tree.nodes if n.type == "TEX_ENVIRONMENT")
        coords, node = tree.nodes.new("ShaderNodeTexCoord"), tree.nodes.new("ShaderNodeMapping")
        node.vector_type = mapping
        node.inputs["Rotation"].default_value = (0.3, 0.0, 1.2)
        node.inputs["Scale"].default_value = (1.0, 1.0, 1.3)
        tree.links.new(coords.outputs["Generated"], node.inputs["Vector"])
        tree.links.new(node.outputs["Vector"], env.inputs["Vector"])
    bpy.ops.mesh.primitive_plane_add(size=0.1, location=(-5.0, 0.0, 0.0))  # behind the camera
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.angle = math.radians(60.0)
    cam.rotation_euler = (math.radians(90.0), 0.0, math.radians(-90.0))  # looking along +x
    scene.collection.objects.link(cam)
    scene.camera = cam
    snap = bridge.snapshot()
    assert snap.world_texture is not None
    assert (snap.world_transform is None) == (mapping is None)
    error = _traced_against_cycles(scene, (48, 32), depth=1, samples=16)
    print(f"background relMSE {error:.2e}")
    assert error < 1e-4


def _traced_against_cycles(scene, resolution, depth: int, samples: int) -> float:
    """relMSE of the tracer's view (2 x 2 points a pixel) against Cycles' Whitted model."""
    ours = trace(bridge.snapshot(resolution=resolution),
                 TracerSettings(max_depth=depth, adaptive=0, supersample=2),
                 resolution=resolution).image
    theirs, _ = cr.render_camera(scene, cr.whitted(depth), samples,
                                 resolution=resolution)
    return rel_mse(ours, theirs)


def _floor_and_box_against_cycles(scene, lift=0.25, floor=None) -> tuple[list[float], float]:
    """A grey floor (or of material `floor`) and a unit box `lift` m over it (0: resting on it)
    under the scene's world, no lamp, baked by radiosity and by Cycles' DIFFUSE bake with the world
    lighting diffuse surfaces (128 samples): each object's mean ratio over the texels both bake,
    and the relMSE of all."""
    from blender_parts import principled

    grey, _ = principled("Grey", base=(0.6, 0.6, 0.6))
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    bpy.context.active_object.data.materials.append(floor or grey)
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, 0.0, 0.5 + lift))
    bpy.context.active_object.data.materials.append(grey)
    uv = LightmapUVSettings(resolution=32, padding=2)
    summary = drain(radiosity_bake_job(bpy.context, RadiositySettings(patch_budget=150), "Lightmap",
                               uv, render=False))
    sizes = summary.extra["lightmap_sizes"]
    ratios, ours, theirs = [], [], []
    for name in ("Plane", "Cube"):
        images, _, masks = cr.bake_lightmaps(
            scene, cr.radiosity(world_lighting=True), 128, [name], "Lightmap",
            sizes[name], "DIFFUSE")
        texels, baked = summary.lightmaps[name]
        valid = baked & masks[name]
        ours.append(texels[valid][:, :3])
        theirs.append(images[name][valid][:, :3])
        ratios.append(float(ours[-1].mean() / theirs[-1].mean()))
        print(f"{name}: mean ours/cycles {ratios[-1]:.3f}")
    return ratios, rel_mse(np.concatenate(ours), np.concatenate(theirs))


@pytest.mark.parametrize("lift", [0.25, 0.0])
def test_a_uniform_world_lights_an_open_scene_as_cycles_does(lift):
    """The world (a blue-grey colour) the only light, the box hovering or resting on the floor
    (its base, flat on the floor, black in Cycles: its rays meet the floor at once): each
    object's mean within 3% and the relMSE under 0.01 (measured: hovering, floor and box 0.999,
    relMSE 0.0022, most of it Cycles' own noise at 128 samples; resting, 1.004 and 0.998, relMSE
    0.0022, where rays lifted in front of the base saw the sky below it: box 1.224, relMSE 0.62)."""

    scene = colour_world()
    ratios, error = _floor_and_box_against_cycles(scene, lift)
    print(f"relMSE {error:.4f}")
    np.testing.assert_allclose(ratios, 1.0, atol=0.03)
    assert error < 0.01


@pytest.mark.slow
def test_a_floor_under_a_bright_sky_and_dark_ground_is_lit_from_above():
    """A sky of radiance 1.2 above the horizon over a ground of 0.1 below: the floor sees the sky
    only, so the map's mean (0.65) would leave it 46% dark; read along each sky ray, both
    objects' means within 3% (measured 1.000 and 1.006)."""
    height, width = 32, 64
    pixels = np.full((height, width, 3), 0.1, np.float32)
    pixels[: height // 2] = 1.2
    ratios, _ = _floor_and_box_against_cycles(hdri_world(pixels))
    np.testing.assert_allclose(ratios, 1.0, atol=0.03)


def _plane_view_against_cycles(material, facing_down: bool = False) -> float:
    """A 6 m plane of `material` under the blue-grey world alone, seen at 50-85 degrees from above
    (`oblique_camera`; facing down: the camera sees its back): the radiosity camera view's mean
    over the plane against a 128-sample Cycles render of the world-lit radiosity model."""
    from blender_parts import WORLD, oblique_camera, plane

    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.radiosity.solve import solve_radiosity
    from classic_bake.kernels.radiosity.view import render_steps

    scene = colour_world()
    sheet = plane(material, size=6.0)
    if facing_down:
        sheet.rotation_euler = (math.pi, 0.0, 0.0)
    oblique_camera(scene)
    resolution = (64, 48)
    snap = bridge.snapshot(resolution=resolution)
    result = solve_radiosity(snap, RadiositySettings(patch_budget=50))
    image = drain(render_steps(snap, result, resolution))
    theirs, _ = cr.render_camera(scene, cr.radiosity(
        world_lighting=True), 128, resolution=resolution)
    on_plane = np.abs(image - np.asarray(WORLD, np.float32)).max(axis=2) > 1e-6
    assert on_plane.mean() > 0.5
    return float(image[on_plane].mean() / theirs[on_plane].mean())


@pytest.mark.parametrize("base, roughness, bound", [(0.5, 0.5, 0.01), (0.0, 0.3, 0.03)])
def test_the_radiosity_view_shows_the_world_in_the_glossy_layer(base, roughness, bound):
    """A Principled plane (Specular IOR Level 0.5) under the blue-grey world alone, seen at
    50-85 degrees: Cycles lights its glossy layer straight from the world (no glossy bounce
    needed), which the radiosity camera view draws along each pixel's mirror direction times
    the layer's E(mu) (`_reflected_emitters`). Mean over the plane against a 128-sample
    render: measured 1.0006 (grey, roughness 0.5; 0.83 without the layer's world light) and
    0.985 (black, roughness 0.3, where the layer is all there is)."""
    from blender_parts import principled

    mat, bsdf = principled("Glossy", base=(base, base, base))
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    bsdf.inputs["Roughness"].default_value = roughness
    ratio = _plane_view_against_cycles(mat)
    print(f"plane mean ours/cycles {ratio:.4f}")
    assert abs(ratio - 1.0) < bound


@pytest.mark.slow
def test_a_sunny_map_bakes_as_cycles_does():
    """A map of a blue-grey sky (0.3) with a small bright sun (2 x 2 texels of 440 at 45 degrees
    up, ~3 W/m^2 on a surface facing it): the sun leaves the map as a sun lamp
    (`world_light.extract_suns`), so the floor and the box get its light and the box's sharp
    shadow from shadow rays, not from the few cosine rays that would meet a spot of 0.007 sr.
    Both objects' means within 3% of Cycles' world-lit DIFFUSE bake (measured 1.001 and 0.993,
    relMSE 0.0012; left in the map for the sky rays: 2.18 and 1.26, relMSE 4.5)."""
    height, width = 64, 128
    pixels = np.full((height, width, 3), 0.3, np.float32)
    pixels[16:18, 40:42] = 440.0
    ratios, error = _floor_and_box_against_cycles(hdri_world(pixels), lift=0.0)
    print(f"relMSE {error:.4f}")
    np.testing.assert_allclose(ratios, 1.0, atol=0.03)


def test_the_back_of_a_sheet_under_the_world_as_cycles_shows_it():
    """A plane turned to face down (Lambertian grey), seen from above: the camera sees its back,
    which Cycles shades on the side it is seen from, lit by the world above it. The radiosity
    view's back faces take the world's light from their own sky rays (`final_gather.back_exitance`):
    the plane's mean within 3% of a 128-sample render (measured 0.9987; black before)."""
    from blender_parts import principled

    mat, _ = principled("Grey", base=(0.6, 0.6, 0.6))
    ratio = _plane_view_against_cycles(mat, facing_down=True)
    print(f"back of the plane ours/cycles {ratio:.4f}")
    assert abs(ratio - 1.0) < 0.03


def test_info_names_the_map_and_its_sun():
    """`info` (its `describe`) reports the world's map and the sun radiosity will take from it:
    towards the texels' mean direction, with their sum L dOmega."""
    from classic_bake.kernels.shading.world_light import texel_directions
    from classic_bake.pipeline.commands.info import describe

    pixels = np.full((64, 128, 3), 0.3, np.float32)
    pixels[16:18, 40:42] = 440.0
    hdri_world(pixels)
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    world = describe(bridge.snapshot())["world_map"]
    assert world["image"] == "Sky" and world["size"] == [128, 64]
    (sun,) = world["suns"]
    _, omega = texel_directions(64, 128)
    np.testing.assert_allclose(sun["irradiance"], 440.0 * omega[16:18, 40:42].sum(), rtol=1e-5)
    assert 0.6 < sun["direction"][2] < 0.75  # about 45 degrees up


@pytest.mark.parametrize("base, roughness, bound", [(0.5, 0.5, 0.02), (0.0, 0.3, 0.06)])
def test_a_maps_sun_shines_in_the_tracers_rough_lobes(base, roughness, bound):
    """A Principled plane under a sky (0.2) with a small sun placed where the camera sees its
    mirror image: the Whitted model hides the world from diffuse rays but its glossy lobes see
    it, and Cycles lights them from the sun by sampling the map. The tracer takes the sun out of
    the map as a highlight-only lamp (`world_light.extract_suns`) and its rough lobes' rays read
    the map without it. relMSE against a 512-sample render under the bound (measured 0.0087 and
    0.035; with the sun left in the map for the lobes' one ray: 3.6 and 0.54)."""
    from blender_parts import oblique_camera, plane, principled

    pixels = np.full((64, 128, 3), 0.2, np.float32)
    pixels[26:28, 31:33] = 400.0  # 17 degrees up towards +y: the mirror of the camera's view
    scene = hdri_world(pixels)
    mat, bsdf = principled("Glossy", base=(base, base, base))
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    bsdf.inputs["Roughness"].default_value = roughness
    plane(mat, size=6.0)
    oblique_camera(scene)
    error = _traced_against_cycles(scene, (64, 48), depth=4, samples=512)
    print(f"relMSE {error:.4f}")
    assert error < bound


def test_a_rough_floor_reflects_a_striped_sky_blurred_as_cycles_does():
    """A grey Principled plane (Specular IOR Level 0.5) under a sky of bright stripes 5.6 degrees
    wide, no lamp: in the Whitted model its diffuse base is dark and its rough layer shows the
    sky, which Cycles' lobe blurs. Where the tracer's one reflected ray stands for the lobe it
    reads the map averaged over it (`trace/world_lobes.py`). Roughness 0.8: relMSE against a
    512-sample render under 0.01 (measured 2.7e-3; the map read along the one ray: 3.3e-2, a
    sharp mirror image of the stripes). Cycles 4.5's layer reflects ~40% more at the grazing
    views of the image's bottom rows than 5.2's, which the tracer's tables follow (2.1e-2 there;
    the same at roughness 0.3): 0.03 on 4.5."""
    from blender_parts import oblique_camera, plane, principled
    from scene_builder import striped_sky

    scene = hdri_world(striped_sky(bright=(1.5, 1.2, 0.8)))
    mat, bsdf = principled("Floor", base=(0.55, 0.5, 0.45))
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    bsdf.inputs["Roughness"].default_value = 0.8
    plane(mat, size=6.0)
    oblique_camera(scene)
    error = _traced_against_cycles(scene, (64, 48), depth=4, samples=512)
    print(f"relMSE {error:.2e}")
    assert error < (0.01 if bpy.app.version >= (5, 0, 0) else 0.03)


def test_a_rough_metal_box_under_a_bright_overhead_light_matches_cycles():
    """A roughness-1 metal box on a floor under a map dark but for a bright cap over the top 30
    degrees (a studio's softbox; stripes round the horizon), no lamp. Its lobes' rays share the
    lobe by the light's shadowing, G2 / G1 (`glossy_lobe.py`), and read the map's mean over the
    lobe besides (`Tracer._lobe_sky_mean`): relMSE against a 512-sample render under 0.01
    (measured 4.1e-3 on 5.2 and on 4.5; 2.0e-2 with equal shares and the rays alone, their
    faces speckled and 3% off)."""
    from blender_parts import oblique_camera, plane, principled
    from scene_builder import striped_sky

    pixels = striped_sky(dark=0.1)
    pixels[: pixels.shape[0] // 6] = 6.0
    scene = hdri_world(pixels)
    floor, floor_bsdf = principled("Floor", base=(0.55, 0.5, 0.45))
    floor_bsdf.inputs["Roughness"].default_value = 0.9
    plane(floor, size=6.0)
    metal, metal_bsdf = principled("Metal", base=(0.8, 0.8, 0.8), metallic=1.0)
    metal_bsdf.inputs["Roughness"].default_value = 1.0
    bpy.ops.mesh.primitive_cube_add(size=0.9, location=(0.0, 0.0, 0.45),
                                    rotation=(0.0, 0.0, math.radians(30.0)))
    bpy.context.object.data.materials.append(metal)
    oblique_camera(scene)
    error = _traced_against_cycles(scene, (64, 48), depth=4, samples=512)
    print(f"relMSE {error:.2e}")
    assert error < 0.01


def _sky_world(elevation_deg: float = 30.0):
    """The scene's world: a Sky Texture (the version's default model: Multiple Scattering in
    5.x, Nishita in 4.5) with its sun disc `elevation_deg` up, 40 degrees round."""
    scene, tree = node_world("Sky")
    sky = tree.nodes.new("ShaderNodeTexSky")
    sky.sun_elevation = math.radians(elevation_deg)
    sky.sun_rotation = math.radians(40.0)
    tree.links.new(sky.outputs["Color"], tree.nodes["Background"].inputs["Color"])
    return scene


@pytest.mark.slow
def test_a_sky_texture_world_bakes_as_cycles_does():
    """A Sky Texture (which the bridge cannot read itself) is rendered into a map by Cycles
    (`cycles.world_map.render_world_map`); its sun disc leaves the map as a sun lamp, the rest
    lights through the sky rays. The floor and the resting box within 3% of Cycles' world-lit
    DIFFUSE bake, relMSE under 0.03, most of it Cycles' noise of a sun it finds through the
    world's importance map (measured: 5.2's Multiple Scattering sky 0.999 and 1.000, relMSE
    0.0083 (0.998 and 0.999 at 768 x 384); 4.5's Nishita sky 0.992 and 0.997, relMSE 0.0166
    (0.991 and 0.996); read as black before, 0)."""
    scene = _sky_world()
    snap = bridge.snapshot(request=bridge.SnapshotRequest(camera=False))
    assert snap.world_texture is not None and snap.world_texture.name.endswith("(rendered)")
    assert any("rendered by Cycles" in why for why in snap.ignored)
    ratios, error = _floor_and_box_against_cycles(scene, lift=0.0)
    print(f"relMSE {error:.4f}")
    np.testing.assert_allclose(ratios, 1.0, atol=0.03)
    assert error < 0.03


def test_the_camera_sees_a_sky_texture_as_cycles_does():
    """The rendered sky as the tracer's background: a 60-degree camera looking at the horizon
    away from the sun, against Cycles' 16-sample box-filtered render (relMSE under 1e-3;
    measured 6.6e-5 on 5.2, 1.7e-5 on 4.5)."""
    scene = _sky_world()
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.angle = math.radians(60.0)
    cam.rotation_euler = (math.radians(80.0), 0.0, math.radians(140.0))
    scene.collection.objects.link(cam)
    scene.camera = cam
    error = _traced_against_cycles(scene, (48, 32), depth=1, samples=16)
    print(f"sky background relMSE {error:.2e}")
    assert error < 1e-3


@pytest.mark.parametrize("kind", ["MIX_SHADER", "ADD_SHADER"])
def test_a_floor_of_mixed_shaders_bakes_as_cycles_does(kind):
    """A floor whose surface is a Mix Shader (Fac 0.3) or an Add Shader of a red Diffuse BSDF and
    a white Glossy BSDF (roughness 0.3), under the blue-grey world: read as one Principled-like
    material (`bridge.mix_materials`: diffuse albedo 0.7 x red, or red, exactly; the glossy part
    a metal share), both objects' means within 3% of Cycles' DIFFUSE bake (measured on 5.2: 1.000
    and 0.998, relMSE 0.0009 mixed, 0.0010 added; read as a 0.8 grey surface before, the shader
    not modelled: the floor 5.9x and 4.1x, relMSE 11 and 8.7)."""

    scene = colour_world()
    mat, tree, output = bare_material("Mixed")
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.7, 0.1, 0.08, 1.0)
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Roughness"].default_value = 0.3
    mix = tree.nodes.new("ShaderNodeMixShader" if kind == "MIX_SHADER" else "ShaderNodeAddShader")
    shaders = [s for s in mix.inputs if s.type == "SHADER"]
    if kind == "MIX_SHADER":
        mix.inputs["Fac"].default_value = 0.3
    tree.links.new(diffuse.outputs[0], shaders[0])
    tree.links.new(glossy.outputs[0], shaders[1])
    tree.links.new(mix.outputs[0], output.inputs["Surface"])
    ratios, error = _floor_and_box_against_cycles(scene, floor=mat)
    print(f"relMSE {error:.4f}")
    read = bridge.snapshot(request=bridge.SnapshotRequest(camera=False))
    floor = next(m for m in read.materials if m.name == "Mixed")
    share = 0.7 if kind == "MIX_SHADER" else 1.0
    np.testing.assert_allclose((1.0 - floor.metallic) * (1.0 - floor.transmission)
                               * floor.base_color, np.array([0.7, 0.1, 0.08]) * share, rtol=1e-5)
    # The glossy part keeps its own (grey-white) tint, not the diffuse red.
    np.testing.assert_allclose(floor.metal_color, glossy.inputs["Color"].default_value[:3],
                               rtol=1e-6)
    np.testing.assert_allclose(ratios, 1.0, atol=0.03)


def test_a_light_path_world_lights_as_diffuse_rays_see_it():
    """The common backdrop set-up: a Mix Shader of two Backgrounds by Light Path's Is Camera Ray,
    the camera shown black, everything else lit by the blue-grey colour. The world is rendered as
    a diffuse bounce ray reads the Light Path node (`cycles.world_map.render_world_map(lighting=
    True)`), so the floor and the box bake within 3% of Cycles (measured on 5.2 and 4.5: 0.999
    and 0.999, relMSE 0.0022; 0 before, lit by the camera's black version)."""
    scene = _backdrop_world((0.0, 0.0, 0.0))
    ratios, error = _floor_and_box_against_cycles(scene)
    print(f"relMSE {error:.4f}")
    np.testing.assert_allclose(ratios, 1.0, atol=0.03)
    assert len(bpy.data.worlds) == 1  # the copy rendered for lighting is gone


def _backdrop_world(backdrop):
    """The scene's world: a Mix Shader of two Backgrounds by Light Path's Is Camera Ray, the
    camera shown `backdrop` (RGB), every other ray the blue-grey `WORLD`. Returns the scene."""
    from blender_parts import WORLD

    scene, tree = node_world("Backdrop")
    lit = tree.nodes["Background"]
    lit.inputs["Color"].default_value = (*WORLD, 1.0)
    shown = tree.nodes.new("ShaderNodeBackground")
    shown.inputs["Color"].default_value = (*backdrop, 1.0)
    path = tree.nodes.new("ShaderNodeLightPath")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    shaders = [s for s in mix.inputs if s.type == "SHADER"]
    tree.links.new(lit.outputs[0], shaders[0])
    tree.links.new(shown.outputs[0], shaders[1])
    output = next(n for n in tree.nodes if n.type == "OUTPUT_WORLD")
    tree.links.new(mix.outputs[0], output.inputs["Surface"])
    return scene


@pytest.mark.parametrize("technique", ["trace", "shadowmap", "radiosity"])
def test_a_light_path_world_shows_the_camera_its_backdrop(technique):
    """The backdrop set-up with a warm white backdrop: the camera's background is the world
    rendered as camera rays see it (`bridge.world.read_camera_world`), while the surfaces, the
    metal ball's reflection among them, take the blue-grey world that other rays see. A metal
    ball (roughness 0.2) on the grey floor under a sun, against Cycles' models, 256 samples,
    96 x 72: relMSE 2.5e-4 (trace), 6.8e-4 (shadow maps), 6.9e-4 (radiosity); the camera shown the
    lighting world, 2.5e-2 in each."""
    from blender_parts import against_cycles, lit_floor, principled, smooth_sphere

    scene = lit_floor()
    _backdrop_world((0.9, 0.85, 0.8))
    metal, bsdf = principled("Metal", base=(0.9, 0.9, 0.9), metallic=1.0)
    bsdf.inputs["Roughness"].default_value = 0.2
    smooth_sphere(metal, radius=0.6)
    snap, error = against_cycles(technique, scene, depth=2)
    assert snap.camera_world is not None
    print(f"relMSE {error:.2e}")
    assert error < 3e-3


def test_bakes_that_see_no_light_render_no_world():
    """An albedo bake under a Sky Texture: the world shader is not rendered into a map (it would
    cost ~2 s and light nothing), nor for a shadow-mask bake without its camera view."""
    from blender_parts import principled

    from classic_bake.jobs.shadowmap import shadow_bake_job
    from classic_bake.jobs.texture import texture_bake_job
    from classic_bake.kernels.bake.texture_bake import TextureBakeSettings
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.shading.direct_light import DirectLightSettings

    _sky_world()
    grey, _ = principled("Grey", base=(0.6, 0.6, 0.6))
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    bpy.context.active_object.data.materials.append(grey)
    sun = bpy.data.lights.new("Sun", "SUN")
    bpy.context.scene.collection.objects.link(bpy.data.objects.new("Sun", sun))
    uv = LightmapUVSettings(resolution=16, padding=2)
    albedo = drain(texture_bake_job(bpy.context, TextureBakeSettings(), "Lightmap", uv,
                                         render=False))
    shadows = drain(shadow_bake_job(bpy.context, DirectLightSettings(), "Lightmap", uv,
                                         render=False))
    assert albedo.scene.world_texture is None and shadows.scene.world_texture is None


@pytest.mark.parametrize("image", ["unset", "missing file"])
def test_an_environment_texture_without_its_image_is_magenta_as_in_cycles(image):
    # A world whose HDRI did not come along: Cycles shows (1, 0, 1) x strength; so do the kernels.
    scene = bpy.context.scene
    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(camera)
    scene.camera = camera
    scene.world = bpy.data.worlds.new("Gone")
    if bpy.app.version < (5, 0, 0):
        scene.world.use_nodes = True
    tree = scene.world.node_tree
    background = next(n for n in tree.nodes if n.type == "BACKGROUND")
    background.inputs["Strength"].default_value = 2.0
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    if image == "missing file":
        env.image = bpy.data.images.new("Gone", 4, 4)
        env.image.source = "FILE"
        env.image.filepath = "//hdri/not_here.hdr"
    theirs = cr.render_camera(scene, cr.whitted(2), 1, (4, 4))[0]
    np.testing.assert_allclose(theirs, np.broadcast_to((2.0, 0.0, 2.0), theirs.shape))
    snap = bridge.snapshot(resolution=(4, 4))
    np.testing.assert_allclose(snap.world_color, (2.0, 0.0, 2.0))
    assert any("magenta" in note for note in snap.ignored), snap.ignored
    ours = trace(snap, TracerSettings(max_depth=1), resolution=(4, 4)).image
    np.testing.assert_allclose(ours, theirs, rtol=1e-6)


@pytest.mark.parametrize("hidden, technique, surface, bound", [
    ("camera", "trace", "metal", 3e-3), ("camera", "shadowmap", "metal", 3e-3),
    ("camera", "radiosity", "metal", 3e-3), ("glossy", "trace", "metal", 2e-3),
    ("glossy", "shadowmap", "metal", 2e-3), ("glossy", "radiosity", "metal", 2e-3),
    ("glossy", "trace", "mapped metal", 5e-3), ("transmission", "trace", "glass", 2e-3),
    ("diffuse", "radiosity", "plastic", 3e-3)])
def test_the_worlds_ray_visibility_is_honoured(hidden, technique, surface, bound):
    """A ball on the grey floor under a sun and the blue-grey world, the world hidden from one
    kind of ray (World > Settings > Ray Visibility): from the camera the background is black, from
    glossy rays a metal (roughness 0.5) reflects no sky, from transmission rays a glass ball shows
    none through it, from diffuse rays the world lights nothing in radiosity. Against Cycles'
    models, 256 samples, 96 x 72: relMSE 1.5e-4 to 9.5e-4 (measured on 5.2; a metal under a
    striped map with glossy rays hidden included), where the flags ignored gave 5.6 (camera),
    0.13 to 0.15 (glossy), 3.2 (transmission), 0.50 (diffuse)."""
    from blender_parts import against_cycles, lit_floor, principled, smooth_sphere
    from scene_builder import striped_sky

    scene = lit_floor()
    if surface == "mapped metal":
        hdri_world(striped_sky(bright=(1.5, 1.2, 0.8)))
    mat, bsdf = principled("Ball", base=(0.7, 0.3, 0.2), metallic=float("metal" in surface))
    if surface == "glass":
        bsdf.inputs["Transmission Weight"].default_value = 1.0
        bsdf.inputs["Roughness"].default_value = 0.0
        bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    smooth_sphere(mat, radius=0.6)
    setattr(scene.world.cycles_visibility, hidden, False)
    snap, error = against_cycles(technique, scene, depth=2)
    assert snap.world_hidden_from == (hidden,)
    print(f"relMSE {error:.2e}")
    assert error < bound
