"""The material reader follows the node chains artists and importers build between a texture and a
BSDF socket (addon/bridge/socket_values.py): for each node, the value the kernels read equals the
value Cycles shades with.

Each case drives a plane's Emission Color through one chain (the reader is the same for every
socket; a number fed to a colour socket is grey) and compares the kernels' look-ups at the texel
centres of a 32 x 32 bake with Cycles' EMIT bake of the plane. The source image is 8 x 8 with
Closest interpolation, so each of its texels covers 4 x 4 baked texels exactly and a baked texel
is one image texel's value (a bake sample that lands on a texel edge may take the neighbour's:
at most 2% of the texels may differ by more than 1e-3)."""

from __future__ import annotations

import bpy
import numpy as np
import pytest

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr
from classic_bake.addon.bridge.materials import MaterialReader
from classic_bake.addon.bridge.request import SnapshotRequest
from classic_bake.kernels.shading.material_maps import emission_at

BAKE = 32
IMAGE = 8
RNG = np.random.default_rng(7)
PIXELS = RNG.uniform(0.05, 0.95, (IMAGE * IMAGE, 4)).astype(np.float32)


def _plane_with_emission():
    mat = bpy.data.materials.new("Graph")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    bsdf.inputs["Emission Strength"].default_value = 1.0
    mesh = bpy.data.meshes.new("Plane")
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="UVMap").uv.foreach_set("vector", [0, 0, 1, 0, 1, 1, 0, 1])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new("Plane", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return tree, bsdf


def _image_node(tree, colorspace="Non-Color"):
    image = bpy.data.images.new("Source", IMAGE, IMAGE, alpha=True, float_buffer=True)
    image.colorspace_settings.name = colorspace
    image.pixels.foreach_set(PIXELS.ravel())
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = image
    node.interpolation = "Closest"
    return node


def _node(tree, idname, **inputs):
    node = tree.nodes.new(idname)
    for key, value in inputs.items():
        node.inputs[key].default_value = value
    return node


# Each case builds a chain from the image node to the output socket it returns.
def _separate_blue(tree, img):
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    tree.links.new(img.outputs["Color"], sep.inputs["Color"])
    return sep.outputs["Blue"]


def _separate_xyz(tree, img):
    sep = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(img.outputs["Color"], sep.inputs["Vector"])
    return sep.outputs["Y"]


def _math(operation, constant, first=True, clamp=False):
    def build(tree, img):
        math = tree.nodes.new("ShaderNodeMath")
        math.operation = operation
        math.use_clamp = clamp
        k = 1 if first else 0
        math.inputs[k].default_value = constant
        tree.links.new(_separate_blue(tree, img), math.inputs[1 - k])
        return math.outputs[0]
    return build


def _colour_to_number(tree, img):
    math = tree.nodes.new("ShaderNodeMath")
    math.operation = "MULTIPLY"
    math.inputs[1].default_value = 1.5
    tree.links.new(img.outputs["Color"], math.inputs[0])  # a colour read as a number: luminance
    return math.outputs[0]


def _mix(blend, factor, texture_first=True):
    def build(tree, img):
        mix = tree.nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        mix.blend_type = blend
        mix.inputs["Factor"].default_value = factor
        a, b = mix.inputs[6], mix.inputs[7]  # the colour A and B sockets
        other = b if texture_first else a
        other.default_value = (0.9, 0.4, 0.2, 1.0)
        tree.links.new(img.outputs["Color"], a if texture_first else b)
        return mix.outputs[2]
    return build


def _mask_between_colours(tree, img):
    mix = tree.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.inputs[6].default_value = (0.1, 0.2, 0.9, 1.0)
    mix.inputs[7].default_value = (0.9, 0.6, 0.0, 1.0)
    tree.links.new(_separate_blue(tree, img), mix.inputs["Factor"])
    return mix.outputs[2]


def _invert(tree, img):
    node = _node(tree, "ShaderNodeInvert", Fac=0.7)
    tree.links.new(img.outputs["Color"], node.inputs["Color"])
    return node.outputs[0]


def _gamma(tree, img):
    node = _node(tree, "ShaderNodeGamma", Gamma=2.2)
    tree.links.new(img.outputs["Color"], node.inputs["Color"])
    return node.outputs[0]


def _bright_contrast(tree, img):
    node = _node(tree, "ShaderNodeBrightContrast", Bright=0.1, Contrast=0.4)
    tree.links.new(img.outputs["Color"], node.inputs["Color"])
    return node.outputs[0]


def _color_ramp(tree, img):
    node = tree.nodes.new("ShaderNodeValToRGB")
    node.color_ramp.elements[0].color = (0.8, 0.1, 0.1, 1.0)
    node.color_ramp.elements[1].position = 0.7
    node.color_ramp.elements[1].color = (0.1, 0.3, 0.9, 1.0)
    tree.links.new(_separate_blue(tree, img), node.inputs["Fac"])
    return node.outputs["Color"]


def _rgb_curves(tree, img):
    node = tree.nodes.new("ShaderNodeRGBCurve")
    curve = node.mapping.curves[3]
    curve.points.new(0.5, 0.8)
    node.mapping.update()
    tree.links.new(img.outputs["Color"], node.inputs["Color"])
    return node.outputs[0]


def _map_range(tree, img):
    node = tree.nodes.new("ShaderNodeMapRange")
    node.inputs["From Min"].default_value = 0.2
    node.inputs["From Max"].default_value = 0.8
    node.clamp = True
    tree.links.new(_separate_blue(tree, img), node.inputs["Value"])
    return node.outputs["Result"]


def _group(tree, img):
    group = bpy.data.node_groups.new("Scale", "ShaderNodeTree")
    group.interface.new_socket("Colour", in_out="INPUT", socket_type="NodeSocketColor")
    group.interface.new_socket("Colour", in_out="OUTPUT", socket_type="NodeSocketColor")
    inner_in = group.nodes.new("NodeGroupInput")
    inner_out = group.nodes.new("NodeGroupOutput")
    mix = group.nodes.new("ShaderNodeMix")
    mix.data_type = "RGBA"
    mix.blend_type = "MULTIPLY"
    mix.inputs["Factor"].default_value = 1.0
    mix.inputs[7].default_value = (0.5, 0.8, 1.0, 1.0)
    group.links.new(inner_in.outputs[0], mix.inputs[6])
    group.links.new(mix.outputs[2], inner_out.inputs[0])
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    tree.links.new(img.outputs["Color"], node.inputs[0])
    return node.outputs[0]


def _hue_saturation(tree, img):
    node = _node(tree, "ShaderNodeHueSaturation", Hue=0.3, Saturation=1.4, Value=0.8, Fac=0.9)
    tree.links.new(img.outputs["Color"], node.inputs["Color"])
    return node.outputs[0]


def _combine(idname, channel):
    def build(tree, img):
        node = tree.nodes.new(idname)
        for k, socket in enumerate([s for s in node.inputs if s.enabled][:3]):
            socket.default_value = 0.2 + 0.3 * k
        tree.links.new(_separate_blue(tree, img), node.inputs[channel])
        return node.outputs[0]
    return build


def _alpha(tree, img):
    return img.outputs["Alpha"]


def _srgb_image(tree, img):
    """An 8-bit sRGB image (opaque, as a base or emission colour map): decoded after the look-up."""
    image = bpy.data.images.new("Bytes", IMAGE, IMAGE, alpha=True)
    opaque = PIXELS.copy()
    opaque[:, 3] = 1.0
    image.pixels.foreach_set(opaque.ravel())
    img.image = image
    return img.outputs["Color"]


CASES = {
    "image_srgb": _srgb_image, "alpha": _alpha, "separate_color": _separate_blue,
    "separate_xyz": _separate_xyz, "math_multiply": _math("MULTIPLY", 0.6),
    "math_add_clamped": _math("ADD", 0.5, clamp=True), "math_subtract_from": _math(
        "SUBTRACT", 0.95, first=False), "math_divide": _math("DIVIDE", 2.0),
    "colour_as_number": _colour_to_number, "mix_multiply": _mix("MULTIPLY", 1.0),
    "mix_mix": _mix("MIX", 0.3, texture_first=False), "mix_add": _mix("ADD", 0.5),
    "mix_mask": _mask_between_colours, "invert": _invert, "gamma": _gamma,
    "bright_contrast": _bright_contrast, "color_ramp": _color_ramp, "rgb_curves": _rgb_curves,
    "map_range": _map_range, "group": _group, "hue_saturation": _hue_saturation,
    "combine_color": _combine("ShaderNodeCombineColor", 1),
    "combine_xyz": _combine("ShaderNodeCombineXYZ", 2),
}


def _baked_and_ours():
    images, _, masks = cr.bake_lightmaps(bpy.context.scene, cr.albedo(), 4, ["Plane"], "UVMap",
                                         BAKE, "EMIT")
    theirs, mask = images["Plane"], masks["Plane"]
    scene = bridge.snapshot()
    centres = (np.arange(BAKE) + 0.5) / BAKE
    u, v = np.meshgrid(centres, centres[::-1])  # row 0 at the top: v near 1
    uv = np.column_stack([u.ravel(), v.ravel()])
    # The plane's two triangles: find each texel's triangle and barycentrics from the UVs.
    tri_uv = scene.uv.astype(np.float64)
    ours = np.zeros((len(uv), 3))
    done = np.zeros(len(uv), bool)
    for t in range(scene.triangle_count):
        a, b, c = tri_uv[t]
        m = np.column_stack([b - a, c - a])
        st = np.linalg.solve(m, (uv - a).T).T
        inside = (st >= -1e-9).all(axis=1) & (st.sum(axis=1) <= 1 + 1e-9) & ~done
        bary = np.column_stack([1 - st.sum(axis=1), st])[inside]
        ours[inside] = emission_at(scene, np.full(inside.sum(), t), bary)
        done |= inside
    return ours.reshape(BAKE, BAKE, 3), theirs, mask, scene


@pytest.mark.parametrize("case", list(CASES))
def test_the_kernels_read_what_cycles_shades(case):
    tree, bsdf = _plane_with_emission()
    img = _image_node(tree)
    tree.links.new(CASES[case](tree, img), bsdf.inputs["Emission Color"])
    ours, theirs, mask, scene = _baked_and_ours()
    assert not [why for why in scene.ignored if "Emission" in why], scene.ignored
    # Read by the reader itself, not through a Cycles bake of the socket (socket_fallback).
    assert not [m.fallbacks for m in scene.materials if m.fallbacks]
    err = np.abs(ours - theirs).max(axis=2)[mask]
    assert mask.all() and theirs.max() > 0.1  # a real signal, texel by texel
    assert np.mean(err > 1e-3) <= 0.02, (err.max(), np.mean(err > 1e-3))


def test_an_unread_chain_is_listed_with_what_was_used():
    """A Noise Texture feeding the IOR (a socket the kernels hold as one number, so no Cycles
    bake of it is read: test_material_fallback.py) is not modelled: the default is used and
    said so."""
    tree, bsdf = _plane_with_emission()
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs["Fac"], bsdf.inputs["IOR"])
    scene = bridge.snapshot()
    (why,) = [w for w in scene.ignored if "'IOR'" in w]
    assert "material 'Graph'" in why and "'ShaderNodeTexNoise' node: not modelled" in why
    assert "default used" in why


def test_a_texture_strength_multiplies_the_emission_texture():
    tree, bsdf = _plane_with_emission()
    img = _image_node(tree)
    tree.links.new(img.outputs["Color"], bsdf.inputs["Emission Color"])
    bsdf.inputs["Emission Strength"].default_value = 3.0
    ours, theirs, mask, _ = _baked_and_ours()
    err = np.abs(ours - theirs).max(axis=2)[mask]
    assert np.mean(err > 3e-3) <= 0.02


def test_every_run_lists_the_unread_sockets_in_metrics_json(tmp_path):
    """`info` and a technique's run both write the unread socket into metrics.json."""
    import json
    import subprocess
    import sys

    tree, bsdf = _plane_with_emission()
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs["Fac"], bsdf.inputs["IOR"])
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location = (0.0, 0.0, 4.0)
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    blend = tmp_path / "unread.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    for command in ("info", "texture"):
        out = tmp_path / command
        done = subprocess.run([sys.executable, "-m", "classic_bake", command, str(blend), "--out",
                               str(out), "--resolution", "16", "12"],
                              capture_output=True, text=True, timeout=300)
        assert done.returncode == 0, done.stderr
        metrics = json.loads(next(out.rglob("metrics.json")).read_text())
        listed = metrics["ignored"]
        assert any("'IOR'" in why and "ShaderNodeTexNoise" in why for why in listed), (
            command, listed)


def test_a_mapping_node_on_uvs_moves_the_look_up():
    """glTF's KHR_texture_transform arrives as a Mapping node (Point) between the UVs and the
    image: scale 2, a quarter turn and a shift of a quarter, against Cycles' EMIT bake."""
    import math

    tree, bsdf = _plane_with_emission()
    img = _image_node(tree)
    coords = tree.nodes.new("ShaderNodeTexCoord")
    mapping = tree.nodes.new("ShaderNodeMapping")
    mapping.inputs["Scale"].default_value = (2.0, 2.0, 1.0)
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.pi / 2)
    mapping.inputs["Location"].default_value = (0.25, 0.0, 0.0)
    tree.links.new(coords.outputs["UV"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], img.inputs["Vector"])
    tree.links.new(img.outputs["Color"], bsdf.inputs["Emission Color"])
    ours, theirs, mask, scene = _baked_and_ours()
    assert not scene.ignored or all("Mapping" not in why for why in scene.ignored)
    err = np.abs(ours - theirs).max(axis=2)[mask]
    assert theirs.max() > 0.1 and np.mean(err > 1e-3) <= 0.02, (err.max(), np.mean(err > 1e-3))


def test_a_coat_is_read_and_one_over_a_normal_map_is_noted_and_left_out():
    tree, bsdf = _plane_with_emission()
    bsdf.inputs["Coat Weight"].default_value = 0.6
    bsdf.inputs["Coat Roughness"].default_value = 0.2
    bsdf.inputs["Coat IOR"].default_value = 1.7
    bsdf.inputs["Coat Tint"].default_value = (1.0, 0.5, 0.25, 1.0)
    graph = next(m for m in bridge.snapshot().materials if m.name == "Graph")
    assert (graph.coat, graph.coat_ior) == pytest.approx((0.6, 1.7))
    assert graph.coat_roughness == pytest.approx(0.2)
    np.testing.assert_allclose(graph.coat_tint, (1.0, 0.5, 0.25))
    normal_map = tree.nodes.new("ShaderNodeNormalMap")
    tree.links.new(_image_node(tree).outputs["Color"], normal_map.inputs["Color"])
    tree.links.new(normal_map.outputs["Normal"], bsdf.inputs["Normal"])
    graph = next(m for m in bridge.snapshot().materials if m.name == "Graph")
    assert graph.coat == 0.0 and graph.normal_texture is not None
    assert any("Coat Weight over a normal or bump map" in why for why in graph.ignored)


def test_a_volume_is_read_inside_glass_and_noted_where_it_is_not_modelled():
    tree, bsdf = _plane_with_emission()
    output = next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")
    volume = tree.nodes.new("ShaderNodeVolumeAbsorption")
    volume.inputs["Color"].default_value = (0.5, 0.75, 1.0, 1.0)
    volume.inputs["Density"].default_value = 4.0
    tree.links.new(volume.outputs["Volume"], output.inputs["Volume"])

    def graph():
        return next(m for m in bridge.snapshot().materials if m.name == "Graph")

    # behind an opaque surface no ray enters: no medium, and the note says so
    assert not graph().absorption.any()
    assert any("volume inside a surface that does not refract" in why for why in graph().ignored)
    bsdf.inputs["Transmission Weight"].default_value = 1.0
    np.testing.assert_allclose(graph().absorption, (2.0, 1.0, 0.0))  # (1 - Color) x Density
    assert not graph().ignored
    scatter = tree.nodes.new("ShaderNodeVolumePrincipled")
    tree.links.new(scatter.outputs["Volume"], output.inputs["Volume"])
    assert not graph().absorption.any()
    assert any("'ShaderNodeVolumePrincipled' in the Volume slot is not modelled" in why
               for why in graph().ignored)


def test_a_sheen_bsdf_beside_a_surface_adds_its_sheen_and_leaves_the_surface_whole():
    from blender_parts import bare_material, plane

    mat, tree, output = bare_material("Graph")
    plane(mat)
    glass = tree.nodes.new("ShaderNodeBsdfGlass")
    glass.inputs["IOR"].default_value = 1.45
    fuzz = tree.nodes.new("ShaderNodeBsdfSheen")
    fuzz.inputs["Color"].default_value = (0.2, 0.4, 0.8, 1.0)
    fuzz.inputs["Roughness"].default_value = 0.7
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.25
    tree.links.new(glass.outputs["BSDF"], mix.inputs[1])
    tree.links.new(fuzz.outputs["BSDF"], mix.inputs[2])
    tree.links.new(mix.outputs["Shader"], output.inputs["Surface"])
    graph = next(m for m in bridge.snapshot().materials if m.name == "Graph")
    # the glass stays glass (its transmission not diluted by the sheen's black base)
    assert graph.transmission == pytest.approx(1.0) and graph.ior == pytest.approx(1.45)
    assert (graph.sheen, graph.sheen_roughness) == pytest.approx((0.25, 0.7))
    np.testing.assert_allclose(graph.sheen_tint, (0.2, 0.4, 0.8), rtol=1e-6)
    assert graph.sheen_model == "MICROFIBER" and not graph.sheen_layer
    principled = tree.nodes.new("ShaderNodeBsdfPrincipled")
    principled.inputs["Sheen Weight"].default_value = 0.5
    tree.links.new(principled.outputs["BSDF"], mix.inputs[1])
    graph = next(m for m in bridge.snapshot().materials if m.name == "Graph")
    assert graph.specular == pytest.approx(0.5) and graph.sheen == pytest.approx(0.75 * 0.5 + 0.25)
    assert any("sheens of different kinds" in why for why in graph.ignored)


def test_an_image_projection_or_interpolation_the_kernels_do_not_read_is_noted():
    tree, bsdf = _plane_with_emission()
    image = _image_node(tree, "sRGB")
    tree.links.new(image.outputs["Color"], bsdf.inputs["Base Color"])
    image.projection, image.interpolation = "BOX", "Cubic"
    notes = next(m for m in bridge.snapshot().materials if m.name == "Graph").ignored
    assert any("BOX projection is not modelled" in why for why in notes)
    assert any("Cubic interpolation read as Linear" in why for why in notes)


def test_factor_outputs_are_found_by_identifier_whatever_their_label():
    """Blender 5 labels a Checker's and an Attribute node's Fac output 'Factor' (identifier
    'Fac'): the Checker's Fac is 1 on colour 1's squares and 0 on colour 2's, the Attribute's
    the mean of its colour, as Cycles shades them, not the colour itself."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.mesh.primitive_plane_add()
    mat = bpy.data.materials.new("Factors")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    checker = tree.nodes.new("ShaderNodeTexChecker")
    tree.links.new(checker.outputs[1], bsdf.inputs["Roughness"])
    attribute = tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "Paint"
    tree.links.new(attribute.outputs[2], bsdf.inputs["Base Color"])
    assert checker.outputs[1].identifier == attribute.outputs[2].identifier == "Fac"
    read = MaterialReader(SnapshotRequest()).read(mat)
    rough = read.roughness_texture
    assert rough.kind == "CHECKER"
    np.testing.assert_array_equal(rough.color1, 1.0)
    np.testing.assert_array_equal(rough.color2, 0.0)
    np.testing.assert_allclose(read.base_color_texture.weights, (1 / 3, 1 / 3, 1 / 3, 0.0))
