"""The scene bridge's snapshot against what Blender itself reports.

Blender's own numbers come from another path than the bridge's: bmesh on the evaluated mesh,
transformed by the object's world matrix, tessellated by bmesh and measured with mathutils; per-face
data read through the RNA collections one element at a time.
"""

from pathlib import Path

import bmesh
import bpy
import numpy as np
import pytest
from mathutils.geometry import area_tri

from classic_bake.addon import bridge
from classic_bake.addon.bridge.render_state import render_state
from classic_bake.kernels.geometry.scene import geometric_normals, triangle_areas

CURVE_LIKE = {"CURVE", "SURFACE", "META", "FONT"}
SAMPLES = sorted((Path(__file__).resolve().parents[2] / "sample_blends").glob("*.blend"))


def blender_reference(context=None):
    """(triangle count, world area, {object name: triangles}) of every renderable mesh instance.

    A curve-like object (curve, surface, text, metaball) is read as itself, through `to_mesh`,
    and its own geometry's MESH instance is skipped: the other of the depsgraph's two entries for
    it than the bridge reads."""
    context = context or bpy.context
    depsgraph = context.evaluated_depsgraph_get()
    count, area, per_object = 0, 0.0, {}
    for inst in depsgraph.object_instances:
        obj = inst.object
        own = inst.is_instance and inst.parent is not None and inst.parent.original == obj.original
        if obj.type not in CURVE_LIKE | {"MESH"} or obj.original.hide_render or (
                own and obj.original.type in CURVE_LIKE):
            continue
        mesh = obj.to_mesh()
        bm = bmesh.new()
        bm.from_mesh(mesh)
        bm.transform(inst.matrix_world)
        looptris = bm.calc_loop_triangles()
        tris = len(looptris)
        count += tris
        area += sum(area_tri(*(loop.vert.co for loop in lt)) for lt in looptris)
        per_object[obj.original.name] = per_object.get(obj.original.name, 0) + tris
        bm.free()
        obj.to_mesh_clear()
    return count, area, per_object


def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def grid_object(name, size=2.0, cuts=3):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_grid(bm, x_segments=cuts, y_segments=cuts, size=size / 2)
    bm.to_mesh(mesh)
    bm.free()
    mesh.uv_layers.new(name="UVMap")
    return link(bpy.data.objects.new(name, mesh))


def cube_object(name, size=1.0):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=size, calc_uvs=True)
    bm.to_mesh(mesh)
    bm.free()
    return link(bpy.data.objects.new(name, mesh))


def test_modifiers_are_applied():
    obj = cube_object("Cube")
    obj.modifiers.new("Subdivision", "SUBSURF").levels = 2
    snap = bridge.snapshot()
    count, area, _ = blender_reference()
    assert snap.triangle_count == count == 6 * 16 * 2  # 2 levels: each quad into 16
    assert triangle_areas(snap.triangles).sum() == pytest.approx(area, rel=1e-5)
    assert snap.objects[0].topology_matches_original is False


def test_transforms_and_mirroring_keep_normals_outward():
    obj = cube_object("Mirrored")
    obj.scale = (-1.0, 2.0, 0.5)
    obj.location = (3.0, 0.0, 1.0)
    snap = bridge.snapshot()
    # CCW winding around the shading normal, and outward-facing on a convex closed mesh.
    geo = geometric_normals(snap.triangles)
    corner_mean = snap.normals.mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", geo, corner_mean) > 0.99)
    centre = np.array([3.0, 0.0, 1.0])
    outward = snap.triangles.mean(axis=1) - centre
    assert np.all(np.einsum("ij,ij->i", geo, outward) > 0)
    assert triangle_areas(snap.triangles).sum() == pytest.approx(blender_reference()[1], rel=1e-6)


def test_custom_normals_are_honoured():
    obj = grid_object("Plane")
    mesh = obj.data
    tilted = np.array([0.6, 0.0, 0.8])
    mesh.normals_split_custom_set([tuple(tilted)] * len(mesh.loops))
    snap = bridge.snapshot()
    np.testing.assert_allclose(snap.normals.reshape(-1, 3), np.tile(tilted, (snap.triangle_count * 3, 1)),
                               atol=1e-4)


def test_instances_are_expanded():
    cube = cube_object("Proto")
    coll = bpy.data.collections.new("Protos")
    bpy.context.scene.collection.children.link(coll)
    bpy.context.scene.collection.objects.unlink(cube)
    coll.objects.link(cube)
    for k in range(3):
        empty = link(bpy.data.objects.new(f"Instancer{k}", None))
        empty.instance_type = "COLLECTION"
        empty.instance_collection = coll
        empty.location = (3.0 * k, 0.0, 0.0)
    coll.hide_render = False
    snap = bridge.snapshot()
    count, area, _ = blender_reference()
    assert snap.triangle_count == count == 12 * 4  # the prototype itself plus three instances
    assert sum(o.is_instance for o in snap.objects) == 3
    assert len({o.name for o in snap.objects}) == len(snap.objects)
    assert triangle_areas(snap.triangles).sum() == pytest.approx(area, rel=1e-6)


def test_curves_text_surfaces_and_metaballs_are_read_once():
    bpy.ops.curve.primitive_bezier_circle_add(location=(0.0, 0.0, 0.0))
    bpy.context.object.data.bevel_depth = 0.1
    bpy.ops.surface.primitive_nurbs_surface_sphere_add(location=(3.0, 0.0, 0.0))
    bpy.ops.object.metaball_add(type="BALL", location=(6.0, 0.0, 0.0))
    bpy.ops.object.text_add(location=(9.0, 0.0, 0.0))
    bpy.context.object.data.extrude = 0.1
    bpy.ops.curve.primitive_bezier_curve_add(location=(12.0, 0.0, 0.0))  # no bevel: no faces
    snap = bridge.snapshot()
    with render_state(bpy.context.scene):  # Cycles renders the metaball at its render resolution
        count, area, per_object = blender_reference()
    assert snap.triangle_count == count
    assert triangle_areas(snap.triangles).sum() == pytest.approx(area, rel=1e-6)
    # One object each, named as in the outliner, none twice.
    assert sorted(o.name for o in snap.objects) == sorted(n for n, t in per_object.items() if t)
    assert sorted(per_object) == ["BézierCircle", "BézierCurve", "Mball", "SurfSphere", "Text"]
    assert not any(o.is_instance for o in snap.objects)  # each is the object itself


def test_hair_curves_and_point_clouds_are_skipped_with_a_note():
    """Cycles renders hair curves and point clouds; the kernels read meshes only, so each such
    object is named among what the snapshot leaves out, once however often it is instanced."""
    bpy.ops.mesh.primitive_plane_add()
    hair = bpy.data.hair_curves.new("Fur")
    hair.add_curves([4, 4])
    for k in range(2):  # the same data twice: noted by object
        bpy.context.scene.collection.objects.link(bpy.data.objects.new(f"Fur{k}", hair))
    cloud = bpy.data.objects.new("Dust", bpy.data.pointclouds.new("Dust"))
    bpy.context.scene.collection.objects.link(cloud)
    snap = bridge.snapshot()
    assert [o.name for o in snap.objects] == ["Plane"]
    notes = [why for why in snap.ignored if "the kernels read meshes only" in why]
    assert len(notes) == 3 and sum("hair curves" in why for why in notes) == 2
    assert any("'Dust' (a point cloud)" in why for why in notes)


def test_material_ids_and_uvs_survive():
    obj = grid_object("Two")
    red, blue = bpy.data.materials.new("Red"), bpy.data.materials.new("Blue")
    obj.data.materials.append(red)
    obj.data.materials.append(blue)
    for poly in obj.data.polygons:
        poly.material_index = poly.index % 2
    uv = obj.data.uv_layers["UVMap"].uv
    for k, item in enumerate(uv):
        item.vector = (k * 0.01, 1.0 - k * 0.02)
    snap = bridge.snapshot()
    mesh = obj.data
    mesh.calc_loop_triangles()
    for t, tri in enumerate(mesh.loop_triangles):
        expected = mesh.materials[mesh.polygons[tri.polygon_index].material_index].name
        assert snap.materials[snap.material_ids[t]].name == expected
        for c in range(3):
            np.testing.assert_allclose(snap.uv[t, c], uv[tri.loops[c]].vector, atol=0)


def test_hidden_from_render_is_left_out_and_hidden_in_viewports_is_read_as_cycles_renders():
    """Cycles renders what is hidden in viewports only: an object disabled in viewports or
    hidden in the view layer (the eye), a collection disabled in viewports or hidden in the
    view layer; it leaves out what is disabled in renders. Every flag is put back."""
    cube_object("Seen")
    cube_object("Hidden").hide_render = True
    off = cube_object("Off")
    off.hide_viewport = True
    eye = cube_object("Eye")
    eye.hide_set(True)
    scene, layers = bpy.context.scene, bpy.context.view_layer.layer_collection
    for name in ("Disabled", "Unseen"):
        collection = bpy.data.collections.new(name)
        scene.collection.children.link(collection)
        inside = cube_object(f"In {name}")
        scene.collection.objects.unlink(inside)
        collection.objects.link(inside)
    bpy.data.collections["Disabled"].hide_viewport = True
    layers.children["Unseen"].hide_viewport = True
    snap = bridge.snapshot()
    assert sorted(o.name for o in snap.objects) == ["Eye", "In Disabled", "In Unseen", "Off",
                                                    "Seen"]
    assert off.hide_viewport and eye.hide_get()  # put back
    assert bpy.data.collections["Disabled"].hide_viewport and layers.children["Unseen"].hide_viewport


def test_modifiers_are_read_with_their_render_settings():
    """Cycles renders a Subdivision Surface at its Render level (Blender's default modifier:
    1 in viewports, 2 in renders) and leaves out a modifier shown in viewports only; the
    snapshot reads the same geometry, and the file keeps its viewport settings."""
    smooth = cube_object("Smooth")
    subsurf = smooth.modifiers.new("Subdivision", "SUBSURF")
    subsurf.levels, subsurf.render_levels = 1, 2
    preview = cube_object("Preview")
    only_viewport = preview.modifiers.new("Subdivision", "SUBSURF")
    only_viewport.show_render = False
    snap = bridge.snapshot()
    counts = {o.name: o.tri_count for o in snap.objects}
    assert counts == {"Smooth": 6 * 16 * 2, "Preview": 12}
    assert (subsurf.levels, only_viewport.show_viewport) == (1, True)
    dg = bpy.context.evaluated_depsgraph_get()
    assert len(smooth.evaluated_get(dg).data.polygons) == 6 * 4  # the viewport's level again


def test_request_limits_what_is_read():
    cube_object("Cube")
    snap = bridge.snapshot(request=bridge.SnapshotRequest(uv=False, lights=False, camera=False,
                                                          textures=False))
    assert snap.lights == () and snap.camera is None
    assert np.all(snap.uv == 0)


@pytest.mark.parametrize("path", SAMPLES, ids=lambda p: p.stem)
def test_sample_scene_snapshot_matches_blender(path):
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
    snap = bridge.snapshot()
    count, area, per_object = blender_reference()
    assert snap.triangle_count == count > 0
    assert triangle_areas(snap.triangles).sum() == pytest.approx(area, rel=1e-5)
    for name, tris in per_object.items():
        assert sum(o.tri_count for o in snap.objects if o.source_name == name) == tris
    assert np.all(np.isfinite(snap.triangles)) and np.all(np.isfinite(snap.normals))
    lengths = np.linalg.norm(snap.normals, axis=-1)
    np.testing.assert_allclose(lengths[lengths > 0], 1.0, atol=1e-5)
    # Shading normals lie in the hemisphere of the geometric normal, except where artists bend
    # them hard (custom normals): at least 99% of corners agree.
    geo = geometric_normals(snap.triangles)
    agree = np.einsum("tj,tcj->tc", geo, snap.normals) > 0
    assert agree.mean() > 0.99
    assert snap.camera is not None
    assert snap.lights or any(m.is_emissive for m in snap.materials)


def test_an_environment_texture_world_is_read_as_its_mean_over_the_sphere():
    """An equirectangular float image bright in its upper half (2.0) and black below, strength
    1.5: the upper and lower halves of the sphere hold equal solid angles, so the mean radiance is
    1.0 x 1.5 whatever the rows' count (rows weighted by cos(latitude)); a plain pixel mean would
    give the same here, so a second image bright only in its top quarter of rows (the polar cap
    above 45 degrees: (1 - sin 45) / 2 = 14.6% of the sphere) tells them apart. The map itself
    reaches the kernels as a Texture of radiance, the strength applied."""
    from blender_parts import hdri_world

    for rows, expected in ((16, 1.0), (8, 2.0 * (1.0 - np.sin(np.pi / 4)) / 2.0)):
        pixels = np.zeros((32, 64, 3), np.float32)
        pixels[:rows] = 2.0  # rows counted from the top
        scene = hdri_world(pixels, strength=1.5)
        color, ignored = bridge.read_world(scene)
        np.testing.assert_allclose(color, 1.5 * expected, rtol=0.01)
        assert not ignored  # an equirectangular map is modelled whole (`read_world_texture`)
        texture = bridge.read_world_texture(scene)
        np.testing.assert_allclose(texture.pixels[..., :3], 1.5 * pixels, rtol=1e-6)


def test_faces_without_a_material_shade_as_cycles_default_surface():
    """A plane with no material under a sun, seen at 55 degrees: Cycles shades it with its
    default surface, a default Principled BSDF in Blender 5 (its specular layer: 11% brighter
    here than a 0.8 grey Diffuse BSDF) and that Diffuse BSDF in 4.5. The shadow-map view of the
    snapshot (the bridge's `DEFAULT_MATERIAL`) within 3% of Cycles' direct-light render (measured:
    0.981 on 5.2, the specular layer's own error; 1.0000 on 4.5; 5.2 read as a diffuse surface:
    0.907)."""
    import math

    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.shading import direct_light

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=4)
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    lamp = bpy.data.objects.new("Sun", sun)
    lamp.rotation_euler = (math.radians(30), 0.0, 0.0)
    scene.collection.objects.link(lamp)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, 4.5, 3.0)
    cam.rotation_euler = (math.radians(55), 0.0, math.radians(180))
    scene.collection.objects.link(cam)
    scene.camera = cam
    resolution = (16, 12)
    snap = bridge.snapshot(resolution=resolution)
    ours = drain(direct_light.render_steps(snap, direct_light.DirectLightSettings(), resolution,
                                           edge_samples=1))
    theirs, _ = cr.render_camera(scene, cr.direct(), 64, resolution)
    ratio = float(ours[4:9, 4:12].mean() / theirs[4:9, 4:12].mean())
    print(f"default surface, ours/cycles {ratio:.4f}")
    assert abs(ratio - 1.0) < 0.03


def test_mixed_shaders_keep_diffuse_albedo_emission_and_shares():
    """`bridge.mix_materials`: a 0.25/0.75 mix of a red diffuse surface and a blue half-metal
    that glows keeps the sum's diffuse albedo, emission and metal share; a textured part alone
    diffuse keeps its texture (a checker's colours scaled when the parts' weights do not add up
    to 1)."""
    from classic_bake.kernels.geometry.scene import Material, Texture

    red = Material(name="r", base_color=np.array([0.8, 0.1, 0.1], np.float32), specular=0.0)
    blue = Material(name="b", base_color=np.array([0.1, 0.2, 0.9], np.float32), metallic=0.5,
                    emission=np.array([2.0, 0.0, 0.0], np.float32))
    mixed = bridge.mix_materials("m", [(0.25, red), (0.75, blue)], [])
    albedo = (1.0 - mixed.metallic) * (1.0 - mixed.transmission) * mixed.base_color
    np.testing.assert_allclose(albedo, 0.25 * red.base_color + 0.75 * 0.5 * blue.base_color,
                               rtol=1e-6)
    np.testing.assert_allclose(mixed.emission, [1.5, 0.0, 0.0])
    assert mixed.metallic == pytest.approx(0.375)
    np.testing.assert_allclose(mixed.metal_color, blue.base_color, rtol=1e-6)  # the metal's tint
    assert mixed.specular == pytest.approx((0.25 * 0.0 + 0.375 * 0.5) / 0.625)
    checker = Texture(kind="CHECKER", color1=np.ones(3, np.float32),
                      color2=np.zeros(3, np.float32), scale=4.0)
    textured = Material(name="t", base_color_texture=checker, specular=0.0)
    half = bridge.mix_materials("h", [(0.5, textured)], [])  # the other half black
    assert half.metallic == 0.0 and half.transmission == 0.0
    np.testing.assert_allclose(half.base_color_texture.color1, 0.5)
    same = bridge.mix_materials("s", [(0.4, textured), (0.6, Material(name="g", metallic=1.0))],
                                [])
    assert same.base_color_texture is checker and same.metallic == pytest.approx(0.6)


def test_cycles_ray_visibility_and_holdouts_are_noted():
    cube_object("Plain")
    backdrop = cube_object("Backdrop")
    backdrop.visible_camera = backdrop.visible_shadow = backdrop.visible_glossy = False
    cube_object("Catcher").is_shadow_catcher = True
    # a new lamp object reads visible_camera False and is_shadow_catcher True: unused for lamps
    bpy.context.scene.collection.objects.link(
        bpy.data.objects.new("Lamp", bpy.data.lights.new("Lamp", "POINT")))
    notes = bridge.snapshot().ignored
    # camera and shadow visibility are modelled (test_trace.py, test_camera_views.py), glossy not
    backdrop = [why for why in notes if "'Backdrop'" in why]
    assert len(backdrop) == 1 and "hides it from glossy rays" in backdrop[0]
    assert any("'Catcher'" in why and "shadow catcher" in why for why in notes)
    assert not any("'Plain'" in why or "'Lamp'" in why for why in notes)


def test_mesh_light_linking_world_volumes_and_holdout_collections_are_noted():
    """What Cycles renders from settings the kernels do not model is named, not dropped: an
    emissive mesh's light and shadow linking (a lamp's is modelled: test_light_linking.py), a
    world volume, a collection held out or indirect only in the view layer. A scene without
    them has no such note."""
    glow = cube_object("Glow")
    lamp = bpy.data.objects.new("Rim", bpy.data.lights.new("Rim", "POINT"))
    bpy.context.scene.collection.objects.link(lamp)
    assert not any("linking" in why or "volume" in why for why in bridge.snapshot().ignored)
    chosen = bpy.data.collections.new("Chosen")
    chosen.objects.link(cube_object("Hero"))
    for emitter in (lamp, glow):
        emitter.light_linking.receiver_collection = chosen
        emitter.light_linking.blocker_collection = chosen
    world = bpy.data.worlds.new("Foggy")
    bpy.context.scene.world = world
    tree = world.node_tree or _world_tree(world)
    fog = tree.nodes.new("ShaderNodeVolumePrincipled")
    output = next(n for n in tree.nodes if n.type == "OUTPUT_WORLD")
    tree.links.new(fog.outputs[0], output.inputs["Volume"])
    held, indirect = bpy.data.collections.new("Held"), bpy.data.collections.new("Bounce")
    for collection in (held, indirect):
        bpy.context.scene.collection.children.link(collection)
        collection.objects.link(cube_object(f"In{collection.name}"))
    layers = bpy.context.view_layer.layer_collection.children
    layers["Held"].holdout = True
    layers["Bounce"].indirect_only = True
    notes = bridge.snapshot().ignored
    assert any("'Glow'" in why and "light linking of an emissive mesh" in why for why in notes)
    assert any("'Glow'" in why and "shadow linking" in why for why in notes)
    assert not any("'Rim'" in why for why in notes)
    assert any("volume shader ('ShaderNodeVolumePrincipled')" in why for why in notes)
    assert any("'Held': a holdout" in why for why in notes)
    assert any("'Bounce': indirect only" in why for why in notes)


def _world_tree(world):
    """The node tree of `world` (Blender 4.5 makes it when nodes are turned on)."""
    world.use_nodes = True
    return world.node_tree


@pytest.mark.parametrize("instancing", ["FACES", "PARTICLES"])
def test_an_instancer_is_shown_as_in_renders(instancing):
    """An object instancing a cube on its faces or by particles is itself rendered or not by its
    render flag (Instancing > Show Instancer > Render), whatever the viewport's: the snapshot
    reads it so (and leaves the file's flags as they were). Traced against Cycles' Whitted model
    with the instancer hidden in renders (a plate over the floor, 96 x 72): relMSE 1.1e-4 on its
    faces, 5.9e-5 by particles; drawn by its viewport flag, the plate took 0.092 and 0.082."""
    from blender_parts import lit_floor, principled, traced_against_cycles

    scene = lit_floor()
    bpy.ops.mesh.primitive_plane_add(size=1.6, location=(0.0, 0.0, 0.8))
    plate = bpy.context.object
    plate.name = "Plate"
    plate.data.materials.append(principled("Green", base=(0.2, 0.5, 0.2))[0])
    bpy.ops.mesh.primitive_cube_add(size=0.3, location=(0.0, 0.0, 1.2))
    cube = bpy.context.object
    cube.data.materials.append(principled("Red", base=(0.7, 0.3, 0.2))[0])
    if instancing == "FACES":
        cube.parent, plate.instance_type = plate, "FACES"
    else:
        system = plate.modifiers.new("Scatter", "PARTICLE_SYSTEM").particle_system.settings
        system.count, system.render_type, system.instance_object = 6, "OBJECT", cube
        system.frame_end, system.physics_type = 1, "NO"
        cube.location = (3.0, 3.0, -5.0)  # the original out of view
    plate.show_instancer_for_viewport, plate.show_instancer_for_render = False, True
    assert "Plate" in [o.name for o in bridge.snapshot().objects]
    plate.show_instancer_for_viewport, plate.show_instancer_for_render = True, False
    snap, error = traced_against_cycles(scene, depth=2)
    assert "Plate" not in [o.name for o in snap.objects]
    assert any(o.name.startswith("Plate/") for o in snap.objects)  # its instances stay
    assert plate.show_instancer_for_viewport  # the file as it was
    print(f"relMSE {error:.2e}")
    assert error < 3e-3


def test_hair_particles_are_noted():
    """Hair particles rendered as strands (Render As Path) are curves in Cycles: named among
    what the snapshot leaves out; the same system rendered as objects is not."""
    bpy.ops.mesh.primitive_plane_add()
    system = bpy.context.object.modifiers.new("Fur", "PARTICLE_SYSTEM").particle_system
    system.settings.type = "HAIR"
    assert any("hair particles 'Fur'" in why for why in bridge.snapshot().ignored)
    system.settings.render_type = "OBJECT"
    assert not any("hair particles" in why for why in bridge.snapshot().ignored)
