"""Cycles as the reference (addon/cycles/), checked against analytic values.

Scenes are built here: planes of known albedo (Principled, Specular IOR Level 0: exactly
Lambertian, tests/data/cycles_facts.md), a sun of strength E (irradiance E W/m^2 on a
surface facing it, same file), black world. Sun and point light direct lighting is noise-free in
Cycles, so 1-2 samples give the converged value; tolerances are stated per test.
"""

import json
import math

import bpy
import numpy as np
import pytest
from reference_data import reference_path

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr

SUN_E = 3.0  # W/m^2
SUN_TILT = math.radians(60.0)  # from the zenith: cos = 0.5 on a horizontal plane
TOLERANCE = 0.01  # the bound for bake values (they agree to ~1e-6 in practice)


# --- scene building -------------------------------------------------------------------------------


def material(name, albedo=None, emission=None):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    if emission is not None:
        tree.nodes.remove(bsdf)
        node = tree.nodes.new("ShaderNodeEmission")
        node.inputs["Color"].default_value = (*emission[0], 1.0)
        node.inputs["Strength"].default_value = emission[1]
        output = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
        tree.links.new(node.outputs["Emission"], output.inputs["Surface"])
        return mat
    bsdf.inputs["Base Color"].default_value = (albedo, albedo, albedo, 1.0)
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    return mat


def plane(name, size_x, size_y, mat=None, location=(0, 0, 0), uv_box=(0.0, 0.0, 1.0, 1.0),
          cuts=1, mesh=None):
    """A grid of cuts x cuts quads in z = 0, UV layer "Lightmap" spanning `uv_box` (u0 v0 u1 v1)."""
    if mesh is None:
        n = cuts + 1
        xs, ys = np.linspace(-size_x / 2, size_x / 2, n), np.linspace(-size_y / 2, size_y / 2, n)
        verts = [(x, y, 0.0) for y in ys for x in xs]
        faces = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i)
                 for j in range(cuts) for i in range(cuts)]
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(verts, [], faces)
        co = np.array(verts)[[v for f in faces for v in f]]
        u0, v0, u1, v1 = uv_box
        uv = np.stack([u0 + (co[:, 0] / size_x + 0.5) * (u1 - u0),
                       v0 + (co[:, 1] / size_y + 0.5) * (v1 - v0)], axis=1)
        mesh.uv_layers.new(name="Lightmap").uv.foreach_set("vector", uv.astype(np.float32).ravel())
        if mat is not None:
            mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return obj


def light(kind, location=(0, 0, 5), rotation=(0, 0, 0), **props):
    data = bpy.data.lights.new(kind.title(), kind)
    for key, value in props.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(data.name, data)
    obj.location, obj.rotation_euler = location, rotation
    bpy.context.scene.collection.objects.link(obj)
    return obj


def ortho_camera(width_m, location=(0, 0, 5)):
    data = bpy.data.cameras.new("Cam")
    data.type, data.ortho_scale = "ORTHO", width_m
    cam = bpy.data.objects.new("Cam", data)
    cam.location = location
    scene = bpy.context.scene
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam


def emission_scene():
    """Two emitters seen by an ortho camera 3.2 m wide at 32 x 24 px (0.1 m per pixel): y > 0
    (the image's top 12 rows) radiance TOP, y < 0 radiance BOTTOM; the split is a pixel edge."""
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 32, 24
    top, bottom = ((0.2, 0.5, 1.0), 2.5), ((1.0, 0.25, 0.0), 0.75)
    plane("Top", 4.0, 2.0, material("Top", emission=top), location=(0, 1.0, 0))
    plane("Bottom", 4.0, 2.0, material("Bottom", emission=bottom), location=(0, -1.0, 0))
    ortho_camera(3.2)
    radiance = [np.array(c, np.float32) * s for c, s in (top, bottom)]
    return scene, radiance[0], radiance[1]


# --- settings dumps -------------------------------------------------------------------------------


def rna_dump(struct) -> dict:
    """Every writable plain property of an RNA struct (no pointers or collections)."""
    out = {}
    for prop in struct.bl_rna.properties:
        if prop.is_readonly or prop.type in ("POINTER", "COLLECTION") or prop.identifier in (
                "use_nodes",):  # deprecated on lights in 5.x; the bake never touches it
            continue
        value = getattr(struct, prop.identifier)
        out[prop.identifier] = tuple(value) if hasattr(value, "__len__") and not isinstance(
            value, str) else value
    return out


def scene_dump(scene) -> dict:
    dump = {
        "cycles": rna_dump(scene.cycles),
        "render": rna_dump(scene.render),
        "image_settings": rna_dump(scene.render.image_settings),
        "bake": rna_dump(scene.render.bake),
        "view": rna_dump(scene.view_settings),
        "world_visibility": rna_dump(scene.world.cycles_visibility) if scene.world else None,
        "camera": scene.camera.name if scene.camera else None,
    }
    for obj in scene.objects:
        if obj.type == "LIGHT":
            dump[f"light {obj.name}"] = rna_dump(obj.data)
    return dump


def data_dump() -> dict:
    """What a bake must not leave behind: datablocks, nodes, slots, selection, attributes."""
    return {
        "images": sorted(i.name for i in bpy.data.images if i.type != "RENDER_RESULT"),
        "materials": sorted(m.name for m in bpy.data.materials),
        "nodes": {m.name: sorted(n.name for n in m.node_tree.nodes) for m in bpy.data.materials
                  if m.node_tree},
        "active_nodes": {m.name: getattr(m.node_tree.nodes.active, "name", None)
                         for m in bpy.data.materials if m.node_tree},
        "slots": {o.name: [(s.link, getattr(s.material, "name", None)) for s in o.material_slots]
                  for o in bpy.data.objects},
        "selected": sorted(o.name for o in bpy.context.scene.objects if o.select_get()),
        "active": getattr(bpy.context.view_layer.objects.active, "name", None),
        "attributes": {m.name: sorted(a.name for a in m.color_attributes) for m in bpy.data.meshes},
    }


# --- tests ----------------------------------------------------------------------------------------


def test_matched_scene_sets_each_model_and_restores_every_setting():
    scene, _, _ = emission_scene()
    scene.render.engine = "BLENDER_EEVEE" if bpy.app.version >= (5, 0, 0) else "BLENDER_EEVEE_NEXT"
    scene.cycles.use_denoising = True
    scene.cycles.pixel_filter_type = "GAUSSIAN"
    scene.cycles.sample_clamp_indirect = 10.0
    scene.render.film_transparent = True
    scene.world = bpy.data.worlds.new("Sky")
    sun = light("SUN", angle=0.2)
    point = light("POINT", shadow_soft_size=0.25)
    spot = light("SPOT", shadow_soft_size=0.5)
    area = light("AREA", size=1.5)
    before = scene_dump(scene)

    with cr.matched_scene(cr.whitted(5)) as log:
        c = scene.cycles
        assert (c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces,
                c.transparent_max_bounces) == (5, 0, 5, 5, 8)
        assert not (c.caustics_reflective or c.caustics_refractive or c.use_denoising
                    or c.use_adaptive_sampling or scene.render.film_transparent)
        assert (c.blur_glossy, c.pixel_filter_type, c.filter_width) == (0.0, "BOX", 1.0)
        assert c.sample_clamp_indirect == 0.0 and scene.render.engine == "CYCLES"
        assert (sun.data.angle, point.data.shadow_soft_size, spot.data.shadow_soft_size) == (0, 0, 0)
        assert area.data.size == 1.5  # area lights keep their emitter
        assert scene.world.cycles_visibility.diffuse is False
        assert scene.world.cycles_visibility.glossy is True  # the sky stays visible in mirrors
        assert log.changed  # the log knows what it has to undo
    assert scene_dump(scene) == before

    with cr.matched_scene(cr.radiosity(24, world_lighting=True)):
        c = scene.cycles
        assert (c.max_bounces, c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces) == (
            24, 24, 0, 0)
        assert point.data.shadow_soft_size == 0.0 and area.data.size == 1.5
        assert scene.world.cycles_visibility.diffuse is True
    with pytest.raises(KeyError), cr.matched_scene(cr.direct()):  # restored on errors too
        assert scene.cycles.max_bounces == 0 and sun.data.angle == 0.0
        assert area.data.size == np.float32(cr.AREA_POINT_SIZE)  # direct(): areas as points
        raise KeyError("inside")
    assert scene_dump(scene) == before

    # A render changes samples, size and the output format on the way: all restored as well.
    cr.render_camera(scene, cr.direct(), 1, resolution=(4, 3))
    assert scene_dump(scene) == before


def test_a_file_whose_output_format_no_longer_exists_renders_and_keeps_it():
    # Saved by Blender 2.79 with JPEG output in colour mode 32, which matches none of today's
    # items (RNA reads it as ""): it cannot be set back, and trying raised, so no reference of
    # such a file could be rendered. The format comes back, and with it the colour mode Blender
    # gives JPEG (RGB).
    bpy.ops.wm.open_mainfile(filepath=str(reference_path("old_output_format.blend")),
                             load_ui=False, use_scripts=False)
    scene, top, bottom = emission_scene()
    settings = scene.render.image_settings
    assert (settings.file_format, settings.color_mode) == ("JPEG", "")
    pixels, _ = cr.render_camera(scene, cr.whitted(2), samples=1)
    np.testing.assert_allclose(pixels[0, 0], top, rtol=1e-5)
    assert (settings.file_format, settings.color_mode) == ("JPEG", "RGB")


def test_render_camera_returns_exact_linear_radiance_top_row_first():
    scene, top, bottom = emission_scene()
    # The view transform and its exposure must not touch the scene-linear EXR.
    scene.view_settings.view_transform = "AgX"
    scene.view_settings.exposure = 2.0
    pixels, seconds = cr.render_camera(scene, cr.whitted(2), samples=64)
    assert pixels.shape == (24, 32, 3) and pixels.dtype == np.float32 and seconds > 0.0
    # A 1-px box filter keeps each pixel inside its own area: the rows next to the split (a pixel
    # edge) are not blended. Cycles' default 1.5-px Blackman-Harris filter blends them by 3-6% at
    # 64 samples (measured), which is why this render takes 64 samples instead of 1.
    np.testing.assert_allclose(pixels[:12], np.broadcast_to(top, (12, 32, 3)), rtol=1e-6)
    np.testing.assert_allclose(pixels[12:], np.broadcast_to(bottom, (12, 32, 3)), rtol=1e-6)
    small, _ = cr.render_camera(scene, cr.direct(), samples=1, resolution=(8, 6))
    assert small.shape == (6, 8, 3)


def test_lightmap_bakes_of_lambertian_planes_under_a_sun():
    scene = bpy.context.scene
    scene.world = None
    white = material("White", 1.0)
    grey = material("Grey", 0.5)
    # UVs span [0.25, 0.75]^2 of a 16^2 lightmap: texels 4..11 in both directions are covered.
    box = (0.25, 0.25, 0.75, 0.75)
    plane("WhitePlane", 2.0, 2.0, white, (0, 0, 0), box)
    plane("GreyPlane", 2.0, 2.0, grey, (3, 0, 0), box)
    plane("GreyTwin", 2.0, 2.0, grey, (6, 0, 0), box)  # shares Grey: needs its own image
    plane("Bare", 2.0, 2.0, None, (9, 0, 0), box)  # no material: Cycles' 0.8 diffuse
    light("SUN", rotation=(SUN_TILT, 0, 0), energy=SUN_E, angle=0.3)
    names = ["WhitePlane", "GreyPlane", "GreyTwin", "Bare"]
    albedo = {"WhitePlane": 1.0, "GreyPlane": 0.5, "GreyTwin": 0.5, "Bare": 0.8}
    irradiance = SUN_E * math.cos(SUN_TILT)
    covered = np.zeros((16, 16), bool)
    covered[4:12, 4:12] = True
    before, settings_before = data_dump(), scene_dump(scene)

    def bake(bake_type, **kw):
        images, seconds, masks = cr.bake_lightmaps(scene, cr.direct(), 1, names, "Lightmap", 16,
                                                   bake_type, **kw)
        assert seconds > 0.0 and set(images) == set(names)
        for name in names:
            assert images[name].shape == (16, 16, 3)
            np.testing.assert_array_equal(masks[name], covered)
            assert np.all(images[name][~covered] == 0.0)  # untouched texels stay cleared
        return {name: images[name][covered] for name in names}

    # DIFFUSE with the colour pass: the radiance a Lambertian surface sends out, rho E / pi, so
    # a radiosity kernel's exitance is B = pi * value = rho E.
    for name, values in bake("DIFFUSE").items():
        np.testing.assert_allclose(values, albedo[name] * irradiance / math.pi, rtol=TOLERANCE)
    # Without it: E / pi whatever the albedo (radiance divided by the albedo).
    for values in bake("DIFFUSE", use_color=False).values():
        np.testing.assert_allclose(values, irradiance / math.pi, rtol=TOLERANCE)
    for name, values in bake("COMBINED").items():
        np.testing.assert_allclose(values, albedo[name] * irradiance / math.pi, rtol=TOLERANCE)
    assert data_dump() == before and scene_dump(scene) == settings_before


def test_shadow_bake_is_a_zero_one_map_even_for_a_bouncing_model():
    scene = bpy.context.scene
    scene.world = None
    plane("Ground", 2.0, 2.0, material("Ground", 0.8))
    # An occluder over x < 0, 0.5 m up, wider than the ground along y; the sun shines straight
    # down, so the shadow edge x = 0 falls on u = 0.5: a texel edge of a 16-texel lightmap.
    plane("Occluder", 2.0, 3.0, material("Occluder", 0.8), location=(-1.0, 0.0, 0.5))
    light("SUN", energy=SUN_E, angle=0.1)
    # radiosity() bounces 32 times: the SHADOW bake must force max_bounces 0 to stay 0-1.
    images, _, masks = cr.bake_lightmaps(scene, cr.radiosity(), 2, ["Ground"], "Lightmap", 16,
                                         "SHADOW")
    shadow = images["Ground"][..., 0]
    assert masks["Ground"].all()
    assert np.all(shadow[:, :8] == 0.0) and np.all(shadow[:, 8:] == 1.0)


def test_color_attribute_bake_matches_a_point_light_per_vertex():
    scene = bpy.context.scene
    scene.world = None
    rho, power, height = 0.5, 200.0, 1.5
    ground = plane("Ground", 2.0, 2.0, material("Ground", rho), cuts=2)  # 3 x 3 vertices
    light("POINT", location=(0.3, 0.2, height), energy=power, shadow_soft_size=0.4)
    co = bridge.mesh_positions(ground.data).astype(np.float64)  # (9, 3), object = world
    delta = np.array([0.3, 0.2, height]) - co
    d2 = np.einsum("ij,ij->i", delta, delta)
    irradiance = power / (4.0 * math.pi) * (height / np.sqrt(d2)) / d2  # I cos / d^2, radius 0
    before = data_dump()

    values, seconds = cr.bake_color_attributes(scene, cr.direct(), 1, ["Ground"], "Baked",
                                               "DIFFUSE", keep=True)
    assert seconds > 0.0 and values["Ground"].shape == (9, 3)
    expected = np.repeat((rho * irradiance / math.pi)[:, None], 3, axis=1)
    np.testing.assert_allclose(values["Ground"], expected, rtol=TOLERANCE)
    stored = bridge.read_color_attribute(ground.data, "Baked")  # written on the mesh, per vertex
    assert ground.data.color_attributes["Baked"].domain == "POINT"
    np.testing.assert_array_equal(stored[:, :3], values["Ground"])
    assert bpy.data.lights["Point"].shadow_soft_size == np.float32(0.4)  # radius 0 in bakes only

    ground.data.color_attributes.remove(ground.data.color_attributes["Baked"])
    values2, _ = cr.bake_color_attributes(scene, cr.direct(), 1, ["Ground"], "Baked", "DIFFUSE")
    np.testing.assert_allclose(values2["Ground"], values["Ground"], rtol=1e-6)
    assert data_dump() == before  # without keep, the attribute is temporary


def test_direct_model_turns_area_lights_into_points_of_the_same_power():
    # An unnormalised 0.5 x 0.4 m area light (radiance P / (pi 1 m^2): emitted power P * 0.2 W)
    # 1.2 m over a 3 x 3 grid, facing down. direct() shrinks it to a 1 mm emitter of the same
    # power: a one-sided point of intensity P_e cos(theta_e) / pi, so E = P_e h^2 / (pi d^4).
    scene = bpy.context.scene
    scene.world = None
    rho, power, height, centre = 0.5, 300.0, 1.2, np.array([0.2, -0.1])
    ground = plane("Ground", 2.0, 2.0, material("Ground", rho), cuts=2)
    area = light("AREA", location=(*centre, height), energy=power, shape="RECTANGLE", size=0.5,
                 size_y=0.4, normalize=False)
    co = bridge.mesh_positions(ground.data).astype(np.float64)
    d2 = np.sum((co[:, :2] - centre) ** 2, axis=1) + height**2
    emitted = power * 0.5 * 0.4
    irradiance = emitted * height**2 / (math.pi * d2**2)
    values, _ = cr.bake_color_attributes(scene, cr.direct(), 4, ["Ground"], "Baked", "DIFFUSE")
    np.testing.assert_allclose(values["Ground"][:, 0], rho * irradiance / math.pi, rtol=TOLERANCE)
    assert (area.data.size, area.data.normalize, area.data.energy) == (0.5, False, power)


def test_reference_cache_hit_and_miss(tmp_path):
    scene, top, _ = emission_scene()
    scene.render.resolution_x, scene.render.resolution_y = 8, 6
    path = tmp_path / "emitters.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    cache = tmp_path / "cache"

    first = cr.reference(path, cr.direct(), "render", samples=2, cache_dir=cache)
    assert not first.cache_hit and first.image.shape == (6, 8, 3) and first.samples == 2
    np.testing.assert_allclose(first.image[0], np.broadcast_to(top, (8, 3)), rtol=1e-6)
    meta = json.loads((first.path / "meta.json").read_text())
    assert meta["key"] == first.key and meta["settings"]["model"]["name"] == "direct"

    # A hit reads the cache: same pixels, the seconds recorded by the first call, nothing opened.
    bpy.ops.wm.read_factory_settings(use_empty=True)
    second = cr.reference(path, cr.direct(), "render", samples=2, cache_dir=cache)
    assert second.cache_hit and second.key == first.key
    assert second.seconds == meta["seconds"] == first.seconds
    np.testing.assert_array_equal(second.image, first.image)
    assert bpy.context.scene.camera is None  # a hit does not open the .blend

    changed = [cr.reference(path, cr.direct(), "render", samples=3, cache_dir=cache),
               cr.reference(path, cr.whitted(2), "render", samples=2, cache_dir=cache),
               cr.reference(path, cr.direct(), "render", samples=2, cache_dir=cache,
                            resolution=(4, 3))]
    assert not any(r.cache_hit for r in changed)
    assert len({first.key, *(r.key for r in changed)}) == 4

    # Lightmaps keep their coverage masks through the cache.
    spec = cr.BakeSpec(objects=("Top",), bake_type="COMBINED", size=8)
    baked = cr.reference(path, cr.direct(), "bake", samples=1, cache_dir=cache, bake=spec)
    again = cr.reference(path, cr.direct(), "bake", samples=1, cache_dir=cache, bake=spec)
    assert again.cache_hit and again.masks["Top"].all()
    np.testing.assert_array_equal(again.images["Top"], baked.images["Top"])
    np.testing.assert_allclose(again.images["Top"], np.broadcast_to(top, (8, 8, 3)), rtol=1e-6)


def write_png(path, value):
    """A 2 x 2 PNG of one grey `value` (8-bit), saved to `path`."""
    image = bpy.data.images.new(f"grey{value}", 2, 2)
    image.pixels.foreach_set(np.tile([value, value, value, 1.0], 4).astype(np.float32))
    image.filepath_raw, image.file_format = str(path), "PNG"
    image.save()
    bpy.data.images.remove(image)


def test_reference_cache_misses_when_a_file_the_blend_reads_changes(tmp_path):
    scene, top, _ = emission_scene()
    scene.render.resolution_x, scene.render.resolution_y = 8, 6
    write_png(tmp_path / "tint.png", 128 / 255)
    tree = bpy.data.materials["Top"].node_tree
    texture = tree.nodes.new("ShaderNodeTexImage")
    texture.image = bpy.data.images.load(str(tmp_path / "tint.png"))
    texture.image.colorspace_settings.name = "Non-Color"
    tree.links.new(texture.outputs["Color"], tree.nodes["Emission"].inputs["Color"])
    path = tmp_path / "textured.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path), relative_remap=True)
    cache = tmp_path / "cache"

    first = cr.reference(path, cr.direct(), "render", samples=1, cache_dir=cache)
    np.testing.assert_allclose(first.image[0], 128 / 255 * top[2], rtol=1e-3)
    assert cr.reference(path, cr.direct(), "render", samples=1, cache_dir=cache).cache_hit

    # The .blend's bytes are the same, the image it reads is not: a miss, rendered again.
    write_png(tmp_path / "tint.png", 64 / 255)
    second = cr.reference(path, cr.direct(), "render", samples=1, cache_dir=cache)
    assert not second.cache_hit and second.key == first.key
    np.testing.assert_allclose(second.image[0], 64 / 255 * top[2], rtol=1e-3)
    assert cr.reference(path, cr.direct(), "render", samples=1, cache_dir=cache).cache_hit
    assert cr.cached_render(path, cr.direct(), None, cache_dir=cache).image[0, 0, 2] == pytest.approx(
        64 / 255 * top[2], rel=1e-3)


def test_dependency_hashes_cover_every_udim_tile_and_missing_files(tmp_path):
    for tile in (1001, 1002):
        (tmp_path / f"paint.{tile}.png").write_bytes(b"tile %d" % tile)
    blend = tmp_path / "scene.blend"
    paths = ["//paint.<UDIM>.png", "//gone.png", "//none.<UDIM>.png"]
    before = cr.dependency_hashes(blend, paths)
    assert before["//gone.png"] is None and before["//none.<UDIM>.png"] is None
    assert before["//paint.<UDIM>.png"] is not None
    (tmp_path / "paint.1002.png").write_bytes(b"painted over")
    assert cr.dependency_hashes(blend, paths)["//paint.<UDIM>.png"] != before["//paint.<UDIM>.png"]
    (tmp_path / "gone.png").write_bytes(b"back")
    assert cr.dependency_hashes(blend, paths)["//gone.png"] == cr.file_sha256(tmp_path / "gone.png")


def test_auto_samples_converge_on_a_noise_free_scene_and_ladder_entries(tmp_path):
    scene, top, bottom = emission_scene()
    path = tmp_path / "emitters.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    ref = cr.reference(path, cr.direct(), "render", cache_dir=tmp_path / "cache",
                       resolution=(8, 6))
    # Emission seen directly has no noise: the halves agree at once.
    assert ref.samples == 2 * cr.START_SAMPLES and ref.noise_rel_mse == 0.0
    ladder = cr.sample_ladder(bpy.context.scene, cr.direct(), [1, 2], resolution=(8, 6))
    assert [e["samples"] for e in ladder] == [1, 2]
    assert all(e["seconds"] > 0 and e["image"].shape == (6, 8, 3) for e in ladder)
    np.testing.assert_allclose(ladder[1]["image"], ref.image, rtol=1e-6)
    assert cr.doubling_counts(20) == [1, 2, 4, 8, 16, 20]


def test_converged_run_doubles_until_the_halves_agree():
    # A synthetic renderer: truth 1 everywhere plus Gaussian noise of variance 0.04 / n.
    rng = np.random.default_rng(7)
    calls = []

    def fake(n, seed):
        calls.append((n, seed))
        image = 1.0 + rng.normal(0.0, math.sqrt(0.04 / n), (64, 64, 3))
        return cr.CyclesRun("render", n, 0.001 * n, {"render": image.astype(np.float32)})

    run, noise = cr.converged_run(fake, target_rel_mse=1e-3, start_samples=8, max_samples=4096)
    # relMSE(halves) ~ 2 * 0.04 / n / (1 + 0.01) <= 1e-3 first at n = 128 per half.
    assert run.samples == 256
    assert len({seed for _, seed in calls}) == len(calls)  # every chunk has its own seed
    assert noise == pytest.approx(0.25 * 2 * 0.04 / 128 / 1.01, rel=0.1)
    assert run.seconds == pytest.approx(0.001 * 256)
    capped, _ = cr.converged_run(fake, target_rel_mse=1e-9, start_samples=8, max_samples=64)
    assert capped.samples == 64


def test_a_cameras_depth_of_field_is_turned_off_for_the_pinhole_kernels():
    """A grey ball on a floor seen through a camera with depth of field on (f/0.5, focused 0.5 m
    away: everything blurred): the models turn it off while Cycles renders, as the kernels'
    cameras are pinholes, put it back after, and the snapshot notes it. The tracer against Cycles
    at 96 x 72: relMSE 2.1e-4; against the blurred render 0.085."""
    from blender_parts import lit_floor, principled, smooth_sphere, traced_against_cycles

    scene = lit_floor()
    smooth_sphere(principled("Grey", base=(0.5, 0.5, 0.5))[0])
    dof = scene.camera.data.dof
    dof.use_dof, dof.aperture_fstop, dof.focus_distance = True, 0.5, 0.5
    snap, error = traced_against_cycles(scene)
    print("relMSE against Cycles", error)
    assert error < 2e-3
    assert dof.use_dof and any("depth of field" in why for why in snap.ignored)
