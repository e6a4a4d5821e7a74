"""Shader-level graphs of real assets, read by the material reader (addon/bridge/materials.py):
a whole shader inside a node group (asset libraries ship their materials so), groups inside
groups, a shader passed into a group, a Transparent BSDF mixed in for cut-outs (leaves, fences:
the pre-2.8 way, still what many importers build), a volume shader in the Surface slot, and the
classic Diffuse and Glossy mixed by a Fresnel or Layer Weight node (against Cycles).

Each grouped or mixed graph is compared with its flat twin, a plain Principled BSDF the reader is
checked against Cycles on elsewhere: the two must read as the same kernel `Material`, field by
field. Where the twin's equality rests on how Cycles shades (a volume in the Surface slot), Cycles
renders both. What a file whose data went missing (a linked library, an image file) reads as is
measured against Cycles' render of it."""

from __future__ import annotations

from dataclasses import fields, replace

import bpy
import numpy as np
import pytest
from blender_parts import (
    against_cycles,
    bare_material,
    lit_floor,
    overhead_sun,
    principled,
    smooth_sphere,
    traced_against_cycles,
    translucent_mix,
)

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr
from classic_bake.addon.bridge.materials import MaterialReader
from classic_bake.addon.bridge.request import SnapshotRequest
from classic_bake.kernels.geometry.scene import Material, Texture
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import trace

RNG = np.random.default_rng(11)
SIDE = 8  # texels of the test images


def _image(name: str) -> bpy.types.Image:
    image = bpy.data.images.new(name, SIDE, SIDE, alpha=True, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(RNG.uniform(0.05, 0.95, SIDE * SIDE * 4).astype(np.float32))
    return image


@pytest.fixture
def images():
    """(colour image, normal-map image), made per test (every test starts from factory settings)."""
    return _image("Colour"), _image("Normals")


def _texture(tree, image, output="Color"):
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    return node.outputs[output]


def _normal_map(tree, normals):
    node = tree.nodes.new("ShaderNodeNormalMap")
    node.inputs["Strength"].default_value = 0.7
    tree.links.new(_texture(tree, normals), node.inputs["Color"])
    return node.outputs["Normal"]


def _principled(tree, metallic=0.25, specular=0.3):
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Specular IOR Level"].default_value = specular
    return bsdf


def _flat(images):
    """The twin: a Principled BSDF, base colour from an image, roughness 0.35, a normal map."""
    colour, normals = images
    mat, tree, output = bare_material("Flat")
    bsdf = _principled(tree)
    bsdf.inputs["Roughness"].default_value = 0.35
    tree.links.new(_texture(tree, colour), bsdf.inputs["Base Color"])
    tree.links.new(_normal_map(tree, normals), bsdf.inputs["Normal"])
    tree.links.new(bsdf.outputs["BSDF"], output.inputs["Surface"])
    return mat


def _pbr_group():
    """A group holding the Principled BSDF, its base colour, roughness and normal as inputs (as
    asset libraries build it); metallic and specular are set inside."""
    group = bpy.data.node_groups.new("PBR", "ShaderNodeTree")
    for name, kind in (("Base Color", "NodeSocketColor"), ("Roughness", "NodeSocketFloat"),
                       ("Normal", "NodeSocketVector")):
        group.interface.new_socket(name, in_out="INPUT", socket_type=kind)
    group.interface.new_socket("BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
    inner_in = group.nodes.new("NodeGroupInput")
    inner_out = group.nodes.new("NodeGroupOutput")
    bsdf = _principled(group)
    for name in ("Base Color", "Roughness", "Normal"):
        group.links.new(inner_in.outputs[name], bsdf.inputs[name])
    group.links.new(bsdf.outputs["BSDF"], inner_out.inputs["BSDF"])
    return group


def _group_node(tree, group, images):
    """A Group node of `group` fed like the twin: the images outside, roughness on the node."""
    colour, normals = images
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.inputs["Roughness"].default_value = 0.35
    tree.links.new(_texture(tree, colour), node.inputs["Base Color"])
    tree.links.new(_normal_map(tree, normals), node.inputs["Normal"])
    return node


def _read(mat) -> Material:
    return MaterialReader(SnapshotRequest(socket_bake=None)).read(mat)


def _assert_same_texture(ours: Texture | None, twin: Texture | None, what: str) -> None:
    assert (ours is None) == (twin is None), what
    if ours is None:
        return
    for field in fields(Texture):
        a, b = getattr(ours, field.name), getattr(twin, field.name)
        if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            np.testing.assert_array_equal(a, b, err_msg=f"{what}.{field.name}")
        else:
            assert a == b, f"{what}.{field.name}: {a} != {b}"


def _assert_same_material(ours: Material, twin: Material) -> None:
    """Every field the kernels shade with equal (names and notes aside)."""
    for field in fields(Material):
        if field.name in ("name", "ignored", "fallbacks"):
            continue
        a, b = getattr(ours, field.name), getattr(twin, field.name)
        if isinstance(a, Texture) or isinstance(b, Texture):
            _assert_same_texture(a, b, field.name)
        elif isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
            np.testing.assert_allclose(a, b, rtol=1e-6, atol=1e-7, err_msg=field.name)
        else:
            assert a == b, f"{field.name}: {a} != {b}"


def test_a_shader_inside_a_node_group_reads_as_its_flat_twin(images):
    twin = _read(_flat(images))
    mat, tree, output = bare_material("Grouped")
    node = _group_node(tree, _pbr_group(), images)
    tree.links.new(node.outputs["BSDF"], output.inputs["Surface"])
    ours = _read(mat)
    assert ours.base_color_texture is not None and ours.normal_texture is not None
    assert ours.roughness == np.float32(0.35) and ours.metallic == np.float32(0.25)
    _assert_same_material(ours, twin)
    assert not ours.ignored, ours.ignored


def test_groups_inside_groups_pass_their_inputs_through(images):
    twin = _read(_flat(images))
    inner = _pbr_group()
    outer = bpy.data.node_groups.new("Wrapper", "ShaderNodeTree")
    for item in inner.interface.items_tree:  # the same sockets, passed straight through
        outer.interface.new_socket(item.name, in_out=item.in_out, socket_type=item.socket_type)
    o_in, o_out = outer.nodes.new("NodeGroupInput"), outer.nodes.new("NodeGroupOutput")
    wrapped = outer.nodes.new("ShaderNodeGroup")
    wrapped.node_tree = inner
    for name in ("Base Color", "Roughness", "Normal"):
        outer.links.new(o_in.outputs[name], wrapped.inputs[name])
    outer.links.new(wrapped.outputs["BSDF"], o_out.inputs["BSDF"])
    mat, tree, output = bare_material("Nested")
    node = _group_node(tree, outer, images)
    tree.links.new(node.outputs["BSDF"], output.inputs["Surface"])
    _assert_same_material(_read(mat), twin)


def _tint(tree, shader, destination):
    """In `tree`: a Mix Shader (Fac 0.25) of `shader` (an output socket) and a red Diffuse,
    into `destination` (an input socket)."""
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.25
    red = tree.nodes.new("ShaderNodeBsdfDiffuse")
    red.inputs["Color"].default_value = (0.8, 0.1, 0.1, 1.0)
    tree.links.new(shader, mix.inputs[1])
    tree.links.new(red.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], destination)


def test_a_shader_passed_into_a_group_is_mixed_inside_it():
    # Outside: Principled -> group "Tint" (the tint inside it) -> output; its twin tints flat.
    group = bpy.data.node_groups.new("Tint", "ShaderNodeTree")
    group.interface.new_socket("Shader", in_out="INPUT", socket_type="NodeSocketShader")
    group.interface.new_socket("Shader", in_out="OUTPUT", socket_type="NodeSocketShader")
    _tint(group, group.nodes.new("NodeGroupInput").outputs[0],
          group.nodes.new("NodeGroupOutput").inputs[0])
    mat, tree, output = bare_material("Tinted")
    bsdf = _principled(tree)
    bsdf.inputs["Base Color"].default_value = (0.1, 0.7, 0.2, 1.0)
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    tree.links.new(bsdf.outputs[0], node.inputs[0])
    tree.links.new(node.outputs[0], output.inputs["Surface"])

    flat, f_tree, f_output = bare_material("TintedFlat")
    f_bsdf = _principled(f_tree)
    f_bsdf.inputs["Base Color"].default_value = (0.1, 0.7, 0.2, 1.0)
    _tint(f_tree, f_bsdf.outputs[0], f_output.inputs["Surface"])
    _assert_same_material(_read(mat), _read(flat))


def _cut_out(colour, transparent_first: bool):
    """Mix Shader of a Transparent BSDF and a Principled BSDF whose base colour is `colour`, the
    Fac the image's alpha; `transparent_first`: the Transparent BSDF in the first slot."""
    mat, tree, output = bare_material("CutOut")
    bsdf = _principled(tree)
    tree.links.new(_texture(tree, colour), bsdf.inputs["Base Color"])
    clear = tree.nodes.new("ShaderNodeBsdfTransparent")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(_texture(tree, colour, "Alpha"), mix.inputs["Fac"])
    first, second = (clear, bsdf) if transparent_first else (bsdf, clear)
    tree.links.new(first.outputs[0], mix.inputs[1])
    tree.links.new(second.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], output.inputs["Surface"])
    return mat


def _alpha_twin(colour):
    """The Principled BSDF with the image's alpha in its own Alpha input."""
    mat, tree, output = bare_material("AlphaTwin")
    bsdf = _principled(tree)
    tree.links.new(_texture(tree, colour), bsdf.inputs["Base Color"])
    tree.links.new(_texture(tree, colour, "Alpha"), bsdf.inputs["Alpha"])
    tree.links.new(bsdf.outputs[0], output.inputs["Surface"])
    return mat


def test_a_transparent_mix_reads_as_the_principled_alpha(images):
    colour = images[0]
    twin = _read(_alpha_twin(colour))
    assert twin.alpha_texture is not None
    _assert_same_material(_read(_cut_out(colour, transparent_first=True)), twin)
    # The Transparent BSDF second: the surface weighs 1 - Fac, so the coverage is 1 - alpha.
    flipped = _read(_cut_out(colour, transparent_first=False))
    coverage = replace(twin.alpha_texture, gain=-twin.alpha_texture.gain,
                       offset=1.0 - twin.alpha_texture.offset)
    _assert_same_material(flipped, replace(twin, alpha_texture=coverage))


def test_a_constant_transparent_mix_is_a_partial_alpha():
    mat, tree, output = bare_material("Veil")
    clear = tree.nodes.new("ShaderNodeBsdfTransparent")
    grey = tree.nodes.new("ShaderNodeBsdfDiffuse")
    grey.inputs["Color"].default_value = (0.5, 0.4, 0.3, 1.0)
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.3  # 0.7 transparent, 0.3 diffuse
    tree.links.new(clear.outputs[0], mix.inputs[1])
    tree.links.new(grey.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], output.inputs["Surface"])
    ours = _read(mat)
    assert abs(ours.alpha - 0.3) < 1e-6 and ours.alpha_texture is None
    np.testing.assert_allclose(ours.base_color, (0.5, 0.4, 0.3), rtol=1e-6)
    assert ours.specular == 0.0 and ours.metallic == 0.0


def _plane_under_a_sun(mat):
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    bpy.context.object.data.materials.append(mat)
    return overhead_sun(3.0)[0]


def test_a_volume_shader_in_the_surface_slot_adds_nothing():
    mat, tree, output = bare_material("Fog")
    bsdf = _principled(tree, metallic=0.0, specular=0.5)
    bsdf.inputs["Base Color"].default_value = (0.6, 0.5, 0.4, 1.0)
    tree.links.new(bsdf.outputs[0], output.inputs["Surface"])
    scene = _plane_under_a_sun(mat)
    alone = cr.render_camera(scene, cr.whitted(2), 4, (8, 8))[0]
    twin = _read(mat)
    add = tree.nodes.new("ShaderNodeAddShader")
    fog = tree.nodes.new("ShaderNodeVolumeAbsorption")
    tree.links.new(bsdf.outputs[0], add.inputs[0])
    tree.links.new(fog.outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], output.inputs["Surface"])
    # Cycles: the same image as the BSDF alone (volume closures count in the Volume slot only).
    np.testing.assert_allclose(cr.render_camera(scene, cr.whitted(2), 4, (8, 8))[0], alone,
                               rtol=1e-6)
    ours = _read(mat)
    _assert_same_material(ours, twin)
    assert any("volume shader" in note for note in ours.ignored)


def test_a_normal_map_inside_a_group_gets_its_tangent_frames(images):
    # The whole shader, normal map and its image included, inside one group: the snapshot reads
    # the map and builds the tangent frames it is read in, as for the flat twin.
    colour, normals = images
    group = bpy.data.node_groups.new("Sealed", "ShaderNodeTree")
    group.interface.new_socket("BSDF", in_out="OUTPUT", socket_type="NodeSocketShader")
    bsdf = _principled(group)
    group.links.new(_normal_map(group, normals), bsdf.inputs["Normal"])
    group.links.new(bsdf.outputs["BSDF"], group.nodes.new("NodeGroupOutput").inputs["BSDF"])
    mat, tree, output = bare_material("Sealed")
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    tree.links.new(node.outputs["BSDF"], output.inputs["Surface"])
    _plane_under_a_sun(mat)
    scene = bridge.snapshot()
    sealed = next(m for m in scene.materials if m.name == "Sealed")
    assert sealed.normal_texture is not None and sealed.normal_texture.name == "Normals"
    assert scene.corner_tangents is not None
    # The plane's tangents follow its UVs' u axis: world +x, unit length.
    np.testing.assert_allclose(scene.corner_tangents.reshape(-1, 3),
                               np.tile([1.0, 0.0, 0.0], (scene.triangle_count * 3, 1)), atol=1e-6)


def test_a_group_from_a_missing_library_is_no_surface_as_cycles_renders_it(tmp_path):
    # lib.blend holds a group; main.blend links it into its material; then lib.blend is gone.
    group = _pbr_group()
    group.use_fake_user = True
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "lib.blend"))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    with bpy.data.libraries.load(str(tmp_path / "lib.blend"), link=True) as (source, target):
        target.node_groups = ["PBR"]
    mat, tree, output = bare_material("Linked")
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = bpy.data.node_groups["PBR"]
    tree.links.new(node.outputs["BSDF"], output.inputs["Surface"])
    scene = _plane_under_a_sun(mat)
    bpy.context.scene.world = bpy.data.worlds.new("Black")
    bpy.context.scene.world.color = (0.0, 0.0, 0.0)
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "main.blend"))
    (tmp_path / "lib.blend").unlink()
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "main.blend"), load_ui=False,
                             use_scripts=False)
    scene = bpy.context.scene
    assert bpy.data.node_groups["PBR"].is_missing
    np.testing.assert_array_equal(cr.render_camera(scene, cr.whitted(2), 1, (8, 8))[0], 0.0)
    ours = _read(bpy.data.materials["Linked"])
    np.testing.assert_array_equal(ours.emission, 0.0)
    np.testing.assert_array_equal(ours.base_color, 0.0)
    assert ours.specular == 0.0 and ours.metallic == 0.0
    # A snapshot reads the depsgraph's evaluated copy of the material: the same.
    snapped = next(m for m in bridge.snapshot().materials if m.name == "Linked")
    np.testing.assert_array_equal(snapped.base_color, 0.0)
    assert snapped.specular == 0.0 and any("missing" in note for note in snapped.ignored)
    assert any("missing" in note for note in ours.ignored)


def test_a_missing_image_reads_magenta_as_cycles_renders_it():
    # An asset whose texture file did not come along: Cycles shades the Image Texture as colour
    # (1, 0, 1), alpha 1; the kernels read the same, so the traced view matches Cycles' render.
    mat, tree, output = bare_material("Gone")
    bsdf = _principled(tree, metallic=0.0, specular=0.0)
    image = bpy.data.images.new("Gone", 4, 4)
    image.source = "FILE"
    image.filepath = "//textures/not_here.png"
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])
    tree.links.new(node.outputs["Alpha"], bsdf.inputs["Alpha"])
    tree.links.new(bsdf.outputs[0], output.inputs["Surface"])
    scene = _plane_under_a_sun(mat)
    theirs = cr.render_camera(scene, cr.whitted(2), 4, (8, 8))[0]
    ours = _read(mat)
    np.testing.assert_array_equal(ours.base_color_texture.pixels, [[[1.0, 0.0, 1.0, 1.0]]])
    assert any("magenta" in note for note in ours.ignored)
    snap = bridge.snapshot(resolution=(8, 8))
    traced = trace(snap, TracerSettings(max_depth=2), resolution=(8, 8)).image
    np.testing.assert_allclose(traced, theirs, rtol=2e-3, atol=1e-4)
    np.testing.assert_allclose(theirs[4, 4], (3.0 / np.pi, 0.0, 3.0 / np.pi), rtol=1e-4)


def test_an_emission_added_to_a_surface_reads_as_its_principled_emission(images):
    # Blender 2.8-3.x's glTF importer built emissive materials as an Add Shader of an Emission
    # and the Principled BSDF: the same as the Principled's own emission, its maps all kept.
    colour, normals = images
    mat, tree, output = bare_material("Glowing")
    bsdf = _principled(tree)
    tree.links.new(_texture(tree, colour), bsdf.inputs["Base Color"])
    tree.links.new(_texture(tree, normals, "Alpha"), bsdf.inputs["Roughness"])
    glow = tree.nodes.new("ShaderNodeEmission")
    glow.inputs["Strength"].default_value = 2.0
    tree.links.new(_texture(tree, normals), glow.inputs["Color"])
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(glow.outputs[0], add.inputs[0])
    tree.links.new(bsdf.outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], output.inputs["Surface"])

    twin, t_tree, t_output = bare_material("GlowingTwin")
    t_bsdf = _principled(t_tree)
    t_tree.links.new(_texture(t_tree, colour), t_bsdf.inputs["Base Color"])
    t_tree.links.new(_texture(t_tree, normals, "Alpha"), t_bsdf.inputs["Roughness"])
    t_tree.links.new(_texture(t_tree, normals), t_bsdf.inputs["Emission Color"])
    t_bsdf.inputs["Emission Strength"].default_value = 2.0
    t_tree.links.new(t_bsdf.outputs[0], t_output.inputs["Surface"])
    ours = _read(mat)
    assert ours.roughness_texture is not None and ours.emission_texture is not None
    _assert_same_material(ours, _read(twin))


def _mixed_sphere(mat, out, mix, first, second) -> None:
    """Wire shaders `first` (Fac 0) and `second` (Fac 1) into Mix Shader `mix`, the mix into
    `mat`'s output `out`, and put a smooth sphere of `mat` on the stage."""
    tree = mat.node_tree
    tree.links.new(first.outputs[0], mix.inputs[1])
    tree.links.new(second.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    smooth_sphere(mat)


def _classic_sphere(fac_node: str, output: str, glossy_colour=(0.8, 0.8, 0.8)):
    """A smooth sphere of the pre-Principled classic on a grey floor under a sun: a red Diffuse
    (Fac 0) and a Glossy (roughness 0.15, `glossy_colour`) mixed by `fac_node`'s `output` (a
    Fresnel of IOR 1.45, a Layer Weight of Blend 0.3)."""
    scene = lit_floor()
    mat, tree, out = bare_material("Classic")
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.7, 0.1, 0.1, 1.0)
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    glossy.inputs["Color"].default_value = (*glossy_colour, 1.0)
    glossy.inputs["Roughness"].default_value = 0.15
    mix = tree.nodes.new("ShaderNodeMixShader")
    fac = tree.nodes.new(fac_node)
    if fac_node == "ShaderNodeFresnel":
        fac.inputs["IOR"].default_value = 1.45
    else:
        fac.inputs["Blend"].default_value = 0.3
    tree.links.new(fac.outputs[output], mix.inputs["Fac"])
    _mixed_sphere(mat, out, mix, diffuse, glossy)
    return scene


@pytest.mark.parametrize("fac_node, output, bound", [
    ("ShaderNodeFresnel", "Fac", 1.5e-3), ("ShaderNodeLayerWeight", "Fresnel", 1.5e-3),
    ("ShaderNodeLayerWeight", "Facing", 0.06)])
def test_a_fresnel_mix_of_diffuse_and_glossy_reads_as_a_specular_layer(fac_node, output, bound):
    """Diffuse and Glossy mixed by a Fresnel (or a Layer Weight) is read as the Diffuse under a
    Principled specular layer of that IOR and the Glossy's roughness, F0 scaled by its grey.
    Against Cycles at 96 x 72: Fresnel 5.1e-4, the Layer Weight's Fresnel 4.9e-4 (the Fac's
    default 0.5, as the reader took it, 0.52), its Facing 3.1e-2 (an IOR of the same mean
    reflectance; noted: the curves differ in shape; 0.28 at the default)."""
    snap, error = traced_against_cycles(_classic_sphere(fac_node, output), samples=512)
    mat = next(m for m in snap.materials if m.name == "Classic")
    assert mat.metallic == 0.0 and mat.roughness == pytest.approx(0.15)
    assert mat.specular == pytest.approx(0.4) and mat.ior > 1.0
    assert any("Facing" in why for why in mat.ignored) == (output == "Facing")
    print(fac_node, output, "relMSE against Cycles", error)
    assert error < bound


def _textured_parts(tree, a, b):
    """Colour the first part by a Noise texture through a red-to-blue ColorRamp (procedural),
    the second by a UV Checker of gold and grey."""
    colour = "Base Color" if a.type == "BSDF_PRINCIPLED" else "Color"
    noise = tree.nodes.new("ShaderNodeTexNoise")
    noise.inputs["Scale"].default_value = 3.0
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    ramp.color_ramp.elements[0].color = (0.7, 0.1, 0.1, 1.0)
    ramp.color_ramp.elements[1].color = (0.1, 0.2, 0.7, 1.0)
    tree.links.new(noise.outputs[0], ramp.inputs["Fac"])
    tree.links.new(ramp.outputs["Color"], a.inputs[colour])
    checker = tree.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 3.0
    checker.inputs["Color1"].default_value = (0.9, 0.7, 0.3, 1.0)
    checker.inputs["Color2"].default_value = (0.8, 0.8, 0.8, 1.0)
    tree.links.new(tree.nodes.new("ShaderNodeUVMap").outputs[0], checker.inputs["Vector"])
    tree.links.new(checker.outputs["Color"], b.inputs[colour])


def _masked_sphere(parts: str, mask: str, textured: bool = False):
    """A smooth sphere on a grey floor under a sun whose material mixes two plain shaders by a
    mask: a red rough dielectric and a gold metal (`parts` "principled"), or a red Diffuse and
    a grey Glossy ("diffuse glossy"); the mask a UV Checker's Fac (6 squares a unit) or a Noise
    texture through a steep ColorRamp ("noise": procedural, Generated coordinates)."""
    scene = lit_floor()
    mat, tree, out = bare_material("Masked")
    if parts == "principled":
        a = tree.nodes.new("ShaderNodeBsdfPrincipled")
        a.inputs["Base Color"].default_value = (0.7, 0.1, 0.1, 1.0)
        a.inputs["Roughness"].default_value = 0.6
        b = tree.nodes.new("ShaderNodeBsdfPrincipled")
        b.inputs["Base Color"].default_value = (0.9, 0.7, 0.3, 1.0)
        b.inputs["Metallic"].default_value = 1.0
    else:
        a = tree.nodes.new("ShaderNodeBsdfDiffuse")
        a.inputs["Color"].default_value = (0.7, 0.1, 0.1, 1.0)
        b = tree.nodes.new("ShaderNodeBsdfGlossy")
    b.inputs["Roughness"].default_value = 0.25
    if textured:
        _textured_parts(tree, a, b)
    mix = tree.nodes.new("ShaderNodeMixShader")
    if mask == "checker":
        checker = tree.nodes.new("ShaderNodeTexChecker")
        checker.inputs["Scale"].default_value = 6.0
        tree.links.new(tree.nodes.new("ShaderNodeUVMap").outputs[0], checker.inputs["Vector"])
        tree.links.new(checker.outputs[1], mix.inputs["Fac"])  # its Fac
    elif mask == "soft noise":  # the Noise's Fac itself: shares between 0 and 1 everywhere
        noise = tree.nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 4.0
        tree.links.new(noise.outputs[0], mix.inputs["Fac"])
    else:
        noise = tree.nodes.new("ShaderNodeTexNoise")
        noise.inputs["Scale"].default_value = 4.0
        ramp = tree.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.elements[0].position = 0.45
        ramp.color_ramp.elements[1].position = 0.55
        tree.links.new(noise.outputs[0], ramp.inputs["Fac"])
        tree.links.new(ramp.outputs["Color"], mix.inputs["Fac"])
    _mixed_sphere(mat, out, mix, a, b)
    return scene


@pytest.mark.parametrize("parts, mask, textured, bound", [
    ("principled", "checker", False, 4e-3), ("diffuse glossy", "checker", False, 1.5e-3),
    ("principled", "noise", False, 5e-3), ("principled", "soft noise", False, 5e-3),
    ("principled", "checker", True, 3e-3), ("diffuse glossy", "checker", True, 2e-3)])
def test_two_shaders_mixed_by_a_mask_are_read_texel_by_texel(parts, mask, textured, bound):
    """A Mix Shader of two shaders whose Fac a mask drives (a texture, or a procedural mask
    Cycles bakes over the UVs): the parts' fields blended by the mask at each hit. Plain parts:
    metallic, roughness, colour as textures through the mask; parts with textures of their own
    (a procedural colour, a checker): each field the two sockets mixed by the mask, baked by
    Cycles. A point between a dielectric and a metal takes one roughness, theirs weighted by
    what each lobe reflects (`materials._lobe_weighted_roughness`). Against Cycles at 96 x 72:
    the red dielectric and gold metal 2.0e-3, Diffuse and Glossy 6.3e-4, under a noise mask
    2.2e-3, under the soft noise 1.9e-3 (4.2e-3 with the roughness blended linearly), textured
    1.4e-3 and 1.0e-3; with the mask's mean for the Fac (a uniform blend) 0.16, 0.41, 0.13,
    0.14 and 0.27."""
    snap, error = traced_against_cycles(_masked_sphere(parts, mask, textured), samples=512)
    assert not any("Fac" in why or "Factor" in why for why in snap.ignored), snap.ignored
    print(parts, mask, "relMSE against Cycles", error)
    assert error < bound


def test_a_soft_mask_between_a_dielectric_and_a_metal_in_the_shadow_map_view():
    """The red dielectric (roughness 0.6) and gold metal (0.25) under the soft noise mask, in
    the shadow-map view against Cycles' direct model (256 samples, 96 x 72): relMSE 1.5e-3 with
    the lobe-weighted roughness, 6.1e-3 with the roughness blended linearly (the metal's lobe too
    wide where the mask is half way)."""
    from blender_parts import view_against_cycles

    _masked_sphere("principled", "soft noise", False)
    _, error = view_against_cycles("shadowmap")
    print(f"relMSE {error:.2e}")
    assert error < 4e-3


@pytest.mark.parametrize("shader, bound", [
    ("translucent", 8e-3), ("ShaderNodeBsdfRefraction", 1.5e-2), ("ShaderNodeHoldout", 1e-3),
    ("ShaderNodeSubsurfaceScattering", 5e-3), ("ShaderNodeEeveeSpecular", 1e-3)])
def test_less_common_shaders_read_as_cycles_renders_them(shader, bound):
    """A sphere on a floor under a sun: half Diffuse, half Translucent (a closed solid: light
    from behind its surface never reaches it, so the Translucent half is black), a Refraction
    BSDF (a glass that reflects nothing), a Holdout (black), a Subsurface Scattering shader
    (colour (0.8, 0.5, 0.4), scale 0.05: a Diffuse of its colour, noted) and an EEVEE Specular
    (black in Cycles). Each was grey diffuse; against Cycles at 96 x 72: 4.4e-3, 8.3e-3,
    2.6e-4, 1.8e-3, 2.6e-4 (grey diffuse: 0.27, 0.097, 1.9, 0.088, 1.9)."""
    scene = lit_floor()
    mat, tree, out = bare_material("Odd")
    node = translucent_mix(tree) if shader == "translucent" else tree.nodes.new(shader)
    if shader == "ShaderNodeSubsurfaceScattering":
        node.inputs["Color"].default_value = (0.8, 0.5, 0.4, 1.0)
        node.inputs["Scale"].default_value = 0.05
    tree.links.new(node.outputs[0], out.inputs["Surface"])
    smooth_sphere(mat)
    snap, error = traced_against_cycles(scene)
    assert not any("grey diffuse" in why for why in snap.ignored), snap.ignored
    print(shader, "relMSE against Cycles", error)
    assert error < bound


@pytest.mark.parametrize("fresnel, edge, bound, note", [
    ("F82", (1.0, 1.0, 1.0), 2e-3, None), ("F82", None, 2e-3, None),
    ("PHYSICAL_CONDUCTOR", None, 4e-3, "physical conductor")])
def test_a_metallic_bsdf_reads_as_a_metal(fresnel, edge, bound, note):
    """A sphere of Blender 4.3's Metallic BSDF (base (0.9, 0.6, 0.3), roughness 0.3) on a floor
    under a sun: a metal of F0 its Base Color and the F82-tint Fresnel of its Edge Tint (F82
    mode), or Schlick's curve from the reflectance of its complex IOR at normal incidence
    (Physical Conductor, the node's default copper-like n and k). Against Cycles at 96 x 72:
    5.3e-4 with a white edge tint (exactly Schlick's), 4.4e-4 with the default tint (1.5e-3
    with Schlick's curve) and 1.2e-3 as a conductor (noted); read as grey diffuse, 0.06 and
    0.07."""
    scene = lit_floor()
    mat, tree, out = bare_material("Metal")
    metal = tree.nodes.new("ShaderNodeBsdfMetallic")
    metal.fresnel_type = fresnel
    if fresnel == "F82":  # the conductor's inputs are its IOR and extinction instead
        metal.inputs["Base Color"].default_value = (0.9, 0.6, 0.3, 1.0)
    metal.inputs["Roughness"].default_value = 0.3
    if edge is not None:
        metal.inputs["Edge Tint"].default_value = (*edge, 1.0)
    tree.links.new(metal.outputs[0], out.inputs["Surface"])
    smooth_sphere(mat)
    snap, error = traced_against_cycles(scene)
    read = next(m for m in snap.materials if m.name == "Metal")
    assert read.metallic == 1.0 and read.roughness == pytest.approx(0.3)
    assert any(note in why for why in read.ignored) if note else not read.ignored
    assert (read.metal_edge is not None) == (fresnel == "F82" and edge is None)
    print(fresnel, edge, "relMSE against Cycles", error)
    assert error < bound


def test_a_principled_metals_specular_tint_is_its_f82_tint():
    """A Principled metal sphere (base (0.9, 0.6, 0.5), roughness 0.3) with Specular Tint
    (0.5, 0.9, 0.5): on a metal Cycles takes it as the F82 tint, read as the Metallic BSDF's
    Edge Tint is. Against Cycles at 96 x 72: relMSE 4.5e-4; Schlick's curve (the tint left
    out) 3.3e-3."""
    scene = lit_floor()
    mat, bsdf = principled("Edged", base=(0.9, 0.6, 0.5), metallic=1.0)
    bsdf.inputs["Roughness"].default_value = 0.3
    bsdf.inputs["Specular Tint"].default_value = (0.5, 0.9, 0.5, 1.0)
    smooth_sphere(mat)
    snap, error = traced_against_cycles(scene)
    read = next(m for m in snap.materials if m.name == "Edged")
    np.testing.assert_allclose(read.metal_edge, (0.5, 0.9, 0.5))
    assert not read.ignored, read.ignored
    print("relMSE against Cycles", error)
    assert error < 1.5e-3


@pytest.mark.parametrize("shader", ["ShaderNodeBsdfDiffuse", "ShaderNodeBsdfMetallic"])
def test_every_bsdfs_normal_input_takes_its_normal_map(shader):
    """A plane of a Diffuse BSDF (or a Metallic BSDF of roughness 0.35) whose Normal a
    tangent-space Normal Map of tilted tiles drives, under a sun, seen at 72 degrees: read as
    the Principled's Normal is. Against Cycles at 80 x 60: the Diffuse 1.1e-4, the Metallic
    8.7e-3 (a normal-mapped Principled metal: 9.9e-3); the Diffuse's map left out, 5.6e-2."""
    from blender_parts import lit_scene, normal_mapped, oblique_camera, plane, tilted_tiles

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = lit_scene()
    mat, tree, out = bare_material("Tiles")
    bsdf = tree.nodes.new(shader)
    if shader == "ShaderNodeBsdfMetallic":
        bsdf.inputs["Roughness"].default_value = 0.35
    tree.links.new(bsdf.outputs[0], out.inputs["Surface"])
    normal_mapped(mat, bsdf, tilted_tiles())
    plane(mat, size=6.0)
    oblique_camera(scene)
    snap, error = traced_against_cycles(scene, resolution=(80, 60))
    assert next(m for m in snap.materials if m.name == "Tiles").normal_texture is not None
    print(shader, "relMSE against Cycles", error)
    assert error < (1e-3 if shader == "ShaderNodeBsdfDiffuse" else 1.5e-2)


@pytest.mark.parametrize("socket, value, note", [
    ("Thin Film Thickness", 500.0, "Thin Film"), ("Diffuse Roughness", 1.0, "Diffuse Roughness")])
def test_principled_inputs_the_kernels_leave_out_are_noted(socket, value, note):
    """A Principled dielectric with a thin film or an Oren-Nayar roughness: each is left out (on
    a dark sphere under a sun, relMSE 3.6e-3 and 4.5e-3 against Cycles) and says so, where each
    was dropped without a word."""
    mat, bsdf = principled("Odd", base=(0.1, 0.1, 0.1))
    bsdf.inputs[socket].default_value = value
    read = MaterialReader(SnapshotRequest()).read(mat)
    assert [why for why in read.ignored if note in why], read.ignored
    bsdf.inputs[socket].default_value = 0.0
    assert not MaterialReader(SnapshotRequest()).read(mat).ignored


@pytest.mark.parametrize("roughness", [0.0, 0.35])
@pytest.mark.parametrize("technique", ["trace", "shadowmap", "radiosity"])
def test_a_dielectrics_specular_tint_tints_its_layer(technique, roughness):
    """A dark Principled dielectric sphere (base 0.05, Specular IOR Level 1: F0 0.08) with
    Specular Tint (1, 0.3, 0.3) on a floor under a sun and a blue-grey world, its layer a
    mirror or rough: the tint scales F0 head on and leaves grazing white
    (`specular_layer.tinted_albedo`), in what the layer reflects of its surroundings and of the
    lamps. Against Cycles at 96 x 72 (the tracer's Whitted model, the direct model of the
    shadow-map view, the radiosity model), mirror / rough: the tracer 1.6e-4 / 4.8e-4, the
    shadow-map view 3.1e-4 / 5.5e-4, the radiosity view 7.6e-4 / 9.9e-4; the tint left out
    (white), 1.4e-2 / 1.2e-2, 9.1e-3 / 8.7e-3 and 7.0e-3 / 8.3e-3."""
    scene = lit_floor()
    mat, bsdf = principled("Tinted", base=(0.05, 0.05, 0.05))
    bsdf.inputs["Specular IOR Level"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Specular Tint"].default_value = (1.0, 0.3, 0.3, 1.0)
    smooth_sphere(mat)
    snap, error = against_cycles(technique, scene)
    read = next(m for m in snap.materials if m.name == "Tinted")
    np.testing.assert_allclose(read.specular_tint, (1.0, 0.3, 0.3))
    assert not read.ignored, read.ignored
    print(technique, roughness, "relMSE against Cycles", error)
    assert error < {"trace": 1e-3, "shadowmap": 1.5e-3, "radiosity": 2e-3}[technique]


@pytest.mark.parametrize("technique", ["trace", "shadowmap", "radiosity"])
def test_a_dim_specular_tint_leaves_the_base_more_light(technique):
    """A light grey Principled sphere (base 0.8, roughness 0.5) whose Specular Tint (0.1, 0.2,
    0.3) has no white channel, as glTF's KHR_materials_specular colour often comes in: its
    layer reflects that much less, and the base keeps 1 - the layer's albedo in the tint's
    largest channel, as Cycles layers them (`specular_layer.view_tables`). Against Cycles at
    96 x 72: the tracer 5.3e-4, the shadow-map view 5.3e-4, the radiosity view 2.5e-3; with
    the base under the untinted layer's albedo 6.7e-4, 6.4e-4 and 2.8e-3; the tint left out
    altogether 1.4e-3, 6.8e-4 and 2.7e-3."""
    scene = lit_floor()
    mat, bsdf = principled("Dim", base=(0.8, 0.8, 0.8))
    bsdf.inputs["Specular IOR Level"].default_value = 0.5
    bsdf.inputs["Roughness"].default_value = 0.5
    bsdf.inputs["Specular Tint"].default_value = (0.1, 0.2, 0.3, 1.0)
    smooth_sphere(mat)
    snap, error = against_cycles(technique, scene)
    np.testing.assert_allclose(next(m for m in snap.materials if m.name == "Dim").specular_tint,
                               (0.1, 0.2, 0.3), rtol=1e-6)
    print(technique, "relMSE against Cycles", error)
    assert error < {"trace": 1e-3, "shadowmap": 1e-3, "radiosity": 4e-3}[technique]


@pytest.mark.parametrize("technique, bound", [("trace", 2e-3), ("shadowmap", 3e-3),
                                               ("radiosity", 4e-3)])
def test_a_surface_transparent_to_shadow_rays_casts_no_shadow(technique, bound):
    """A sphere whose material a Light Path's Is Shadow Ray switches to a Transparent BSDF (how
    architectural glass is often made to let the sun in), on a floor under a sun: seen as its
    Principled surface, it casts no shadow (`Material.shadowless`): the tracer's shadow rays,
    the shadow maps and the radiosity solve's lamp and emitter shadow rays pass it, its bounce
    light still meets it. Against Cycles at 96 x 72: the tracer 6.8e-4, the shadow-map view
    9.1e-4, the radiosity view 1.2e-3; read as its surface alone (its shadow cast),
    3.7e-2 (tracer) and 2.1e-2 (radiosity, compare)."""
    scene = lit_floor()
    mat, tree, out = bare_material("Shadowless")
    path = tree.nodes.new("ShaderNodeLightPath")
    clear = tree.nodes.new("ShaderNodeBsdfTransparent")
    surface = tree.nodes.new("ShaderNodeBsdfPrincipled")
    surface.inputs["Base Color"].default_value = (0.7, 0.5, 0.3, 1.0)
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(path.outputs["Is Shadow Ray"], mix.inputs[0])
    tree.links.new(surface.outputs[0], mix.inputs[1])
    tree.links.new(clear.outputs[0], mix.inputs[2])
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    smooth_sphere(mat)
    snap, error = against_cycles(technique, scene)
    read = next(m for m in snap.materials if m.name == "Shadowless")
    assert read.shadowless and not read.ignored, read.ignored
    print(technique, "relMSE against Cycles", error)
    assert error < bound
