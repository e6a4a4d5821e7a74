"""Light units: the irradiance the bridge implies equals what Cycles renders, within 2%.

A white Lambertian plane (Principled, Specular IOR Level 0, so exactly Lambertian: cycles_facts.md)
under one light, no world, max_bounces 0: a pixel of the plane has radiance rho E / pi, so Cycles'
irradiance is pi * pixel. An orthographic camera a few millimetres wide looks at one receiver
point with a box filter, so the pixel value is E at that point, with no light-path noise for
point, spot and sun lights (they are sampled exactly).
"""

import math

import bpy
import numpy as np
import pytest

from classic_bake.addon import bridge
from classic_bake.addon.cycles import matched_scene, whitted
from classic_bake.kernels.shading.lights import direct_irradiance

TOLERANCE = 0.02  # the bound; point, spot and sun agree to ~1e-5 in practice


def build_plane_scene():
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0
    scene.cycles.pixel_filter_type = "BOX"
    scene.render.resolution_x = scene.render.resolution_y = 4
    scene.world = None
    mesh = bpy.data.meshes.new("Plane")
    s = 40.0
    mesh.from_pydata([(-s, -s, 0), (s, -s, 0), (s, s, 0), (-s, s, 0)], [], [(0, 1, 2, 3)])
    plane = bpy.data.objects.new("Plane", mesh)
    scene.collection.objects.link(plane)
    mat = bpy.data.materials.new("White")
    if hasattr(mat, "use_nodes"):
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (1, 1, 1, 1)
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    mesh.materials.append(mat)
    cam_data = bpy.data.cameras.new("Cam")
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 0.004
    cam = bpy.data.objects.new("Cam", cam_data)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene


def cycles_irradiance(scene, point, tmp_path) -> float:
    scene.camera.location = (point[0], point[1], 5.0)
    scene.render.filepath = str(tmp_path / "probe.exr")
    scene.render.image_settings.file_format = "OPEN_EXR"
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(tmp_path / "probe.exr"))
    value = float(np.array(img.pixels[:]).reshape(-1, 4)[:, 0].mean())
    bpy.data.images.remove(img)
    return math.pi * value


def add_light(kind, location, rotation=(0, 0, 0), **props):
    data = bpy.data.lights.new("Light", kind)
    for key, value in props.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new("Light", data)
    obj.location = location
    obj.rotation_euler = rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


CASES = {
    "point": ("POINT", (0, 0, 2), (0, 0, 0), dict(energy=100.0, shadow_soft_size=0.0),
              [(0, 0), (1.5, 0.5)]),
    "point_exposure_colour": ("POINT", (0, 0, 3), (0, 0, 0),
                              dict(energy=50.0, exposure=1.0, color=(1.0, 0.5, 0.25),
                                   shadow_soft_size=0.0), [(0, 0)]),
    "point_radius": ("POINT", (0, 0, 2), (0, 0, 0), dict(energy=100.0, shadow_soft_size=0.5),
                     [(0, 0)]),
    "sun": ("SUN", (0, 0, 5), (math.radians(60), 0, 0), dict(energy=3.0, angle=0.0), [(0, 0)]),
    # normalize off: the power times the emitter's area (4 pi r^2, 4 at r = 0; pi sin^2(a / 2))
    "point_unnormalized": ("POINT", (0, 0, 2), (0, 0, 0),
                           dict(energy=10.0, shadow_soft_size=0.0, normalize=False), [(0, 0)]),
    "point_unnormalized_radius": ("POINT", (0, 0, 2), (0, 0, 0),
                                  dict(energy=10.0, shadow_soft_size=0.5, normalize=False), [(0, 0)]),
    "spot_unnormalized": ("SPOT", (0, 0, 2), (0, 0, 0),
                          dict(energy=200.0, spot_size=math.radians(60), shadow_soft_size=0.2,
                               normalize=False), [(0, 0)]),
    "sun_unnormalized_angle": ("SUN", (0, 0, 5), (math.radians(30), 0, 0),
                               dict(energy=3.0, angle=0.3, normalize=False), [(0, 0)]),
    "spot": ("SPOT", (0, 0, 2), (0, 0, 0),
             dict(energy=200.0, spot_size=math.radians(60), spot_blend=0.5, shadow_soft_size=0.0),
             [(0, 0), (0.95, 0), (1.1, 0)]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bridge_irradiance_matches_cycles(case, tmp_path):
    kind, location, rotation, props, points = CASES[case]
    scene = build_plane_scene()
    add_light(kind, location, rotation, **props)
    snap = bridge.snapshot(request=bridge.SnapshotRequest(textures=False, camera=False))
    (light,) = snap.lights
    pts = np.array([[x, y, 0.0] for x, y in points])
    predicted = direct_irradiance(light, pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)))[:, 0]
    for point, expected in zip(points, predicted, strict=True):
        measured = cycles_irradiance(scene, point, tmp_path)
        if expected < 1e-3:  # outside the spot cone: both must be dark
            assert measured < 1e-3
            continue
        assert measured == pytest.approx(expected, rel=TOLERANCE), (case, point)


@pytest.mark.parametrize("normalize", [True, False])
def test_area_light_radiance_matches_cycles(normalize, tmp_path):
    # Area lights are sampled stochastically by Cycles: 256 samples keep its noise under 1%.
    scene = build_plane_scene()
    scene.cycles.samples = 256
    add_light("AREA", (0, 0, 1.5), energy=100.0, shape="RECTANGLE", size=2.0, size_y=1.0,
              normalize=normalize)
    snap = bridge.snapshot(request=bridge.SnapshotRequest(textures=False, camera=False))
    (light,) = snap.lights
    predicted = direct_irradiance(light, np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]]))[0, 0]
    assert cycles_irradiance(scene, (0, 0), tmp_path) == pytest.approx(predicted, rel=TOLERANCE)


def test_a_portal_is_no_light(tmp_path):
    """An area light marked as a Cycles portal emits nothing (it guides the world's sampling
    through a window): the snapshot has no light for it, and Cycles' irradiance under a portal
    of 500 W over the plane, lit by a sun, is the sun's alone."""
    scene = build_plane_scene()
    scene.world = bpy.data.worlds.new("Black")  # Cycles 5.2 crashes on a portal with no world
    scene.world.color = (0.0, 0.0, 0.0)  # 4.5's world without nodes; 5.2's has a Background
    for node in scene.world.node_tree.nodes if scene.world.node_tree else ():
        if node.type == "BACKGROUND":
            node.inputs["Strength"].default_value = 0.0
    sun = add_light("SUN", (0, 0, 5), energy=2.0, angle=0.0)
    portal = add_light("AREA", (0, 0, 1.0), energy=500.0, size=2.0)
    portal.data.cycles.is_portal = True
    snap = bridge.snapshot(request=bridge.SnapshotRequest(textures=False, camera=False))
    assert [light.name for light in snap.lights] == [sun.name]
    assert cycles_irradiance(scene, (0, 0), tmp_path) == pytest.approx(2.0, rel=TOLERANCE)


def _light_nodes(obj, falloff_output="Quadratic"):
    """The light's node tree: an RGB node (0.2, 0.6, 1) into the Emission colour, a Light
    Falloff (strength 3) output into its strength."""
    data = obj.data
    if hasattr(data, "use_nodes"):
        data.use_nodes = True
    tree = data.node_tree
    emission = next(n for n in tree.nodes if n.type == "EMISSION")
    rgb = tree.nodes.new("ShaderNodeRGB")
    rgb.outputs[0].default_value = (0.2, 0.6, 1.0, 1.0)
    falloff = tree.nodes.new("ShaderNodeLightFalloff")
    falloff.inputs["Strength"].default_value = 3.0
    tree.links.new(rgb.outputs[0], emission.inputs["Color"])
    tree.links.new(falloff.outputs[falloff_output], emission.inputs["Strength"])


def test_a_lights_emission_nodes_scale_its_light_as_in_cycles(tmp_path):
    """A point light whose node tree colours its Emission with an RGB node and sets its strength
    by a Light Falloff's Quadratic output (glTF-IO's Cycles lamp test does): the light is
    multiplied by colour x strength, every channel within 2% of Cycles (it was read white, 1x,
    and noted). A Linear falloff (distance-dependent) is noted and left out."""
    scene = build_plane_scene()
    _light_nodes(add_light("POINT", (0, 0, 2), energy=100.0, shadow_soft_size=0.0))
    snap = bridge.snapshot(request=bridge.SnapshotRequest(textures=False, camera=False))
    assert not any("light nodes" in why for why in snap.ignored)
    predicted = direct_irradiance(snap.lights[0], np.array([[0.5, 0.0, 0.0]]),
                                  np.array([[0.0, 0.0, 1.0]]))[0]
    scene.camera.location = (0.5, 0.0, 5.0)
    scene.render.filepath = str(tmp_path / "probe.exr")
    scene.render.image_settings.file_format = "OPEN_EXR"
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(str(tmp_path / "probe.exr"))
    measured = math.pi * np.array(img.pixels[:]).reshape(-1, 4)[:, :3].mean(axis=0)
    np.testing.assert_allclose(predicted, measured, rtol=TOLERANCE)
    np.testing.assert_allclose(predicted / predicted[2], (0.2, 0.6, 1.0), rtol=1e-6)

    bpy.ops.wm.read_factory_settings(use_empty=True)
    build_plane_scene()
    _light_nodes(add_light("POINT", (0, 0, 2), energy=100.0), falloff_output="Linear")
    snap = bridge.snapshot(request=bridge.SnapshotRequest(textures=False, camera=False))
    assert any("Light Falloff" in why for why in snap.ignored)


def test_a_model_that_shrinks_lights_keeps_an_unnormalised_lights_power(tmp_path):
    """The Whitted model renders point lights at radius 0 and suns at angle 0; an unnormalised
    light's power scales with that size (x 0.126 at r = 0.1, x 4 at r = 0), so the model folds the
    scale into its energy: Cycles' irradiance is the scene's within 2%, and the light is as it
    was after the block."""
    scene = build_plane_scene()
    scene.cycles.samples = 64
    point = add_light("POINT", (0, 0, 3), energy=100.0, shadow_soft_size=0.1, normalize=False)
    sun = add_light("SUN", (0, 0, 5), energy=2.0, angle=0.2, normalize=False)
    before = cycles_irradiance(scene, (0, 0), tmp_path)
    with matched_scene(whitted(0), scene):
        assert point.data.shadow_soft_size == 0.0 and sun.data.angle == 0.0
        shrunk = cycles_irradiance(scene, (0, 0), tmp_path)
    assert shrunk == pytest.approx(before, rel=TOLERANCE)
    assert (point.data.energy, point.data.normalize, sun.data.energy) == (100.0, False, 2.0)
