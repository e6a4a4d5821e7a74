"""Vertex colours: Color Attribute and Attribute nodes read per corner and interpolated across each
triangle (addon/bridge/attributes.py, `Texture` kind ATTRIBUTE), as Cycles shades them.

A 4 x 4 grid seen from above, lit by a sun of pi W/m^2 along the normal and a black world, so a
Lambertian pixel's radiance is its albedo (tests/data/cycles_facts.md); the base colour comes from
an attribute of random values. The traced view must match Cycles' render (a 1-pixel box filter:
a pixel's mean of a linear ramp is its centre's value; pixels across a face edge, where corner and
face values jump, are supersampled 8 x 8) on an object without UVs too, where the Cycles bake
fallback cannot help."""

from __future__ import annotations

import math

import bpy
import numpy as np
import pytest
from blender_parts import overhead_sun

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr
from classic_bake.kernels.measure.metrics import rel_mse
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import trace

SIZE = 24  # pixels per side
# relMSE of the traced view against Cycles' 256-sample render: measured up to 1.7e-4 (the 8 x 8
# samples of pixels straddling faces of different colours: 1.2e-4 to 1.5e-4 against 1024 samples);
# a misread colour, or such pixels left unsupersampled, gives 1e-3 to 1e-2.
TOLERANCE = 3e-4
EDGE_SAMPLES = 8
CYCLES_SAMPLES = 256


def _grid(uv: bool = True):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4, size=4.0)
    grid = bpy.context.object
    if not uv:
        grid.data.uv_layers.remove(grid.data.uv_layers[0])
    scene, _ = overhead_sun(math.pi)
    scene.world = bpy.data.worlds.new("Black")
    scene.world.color = (0.0, 0.0, 0.0)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    return grid


def _attribute(mesh, name, data_type, domain, seed):
    attribute = mesh.attributes.new(name, data_type, domain)
    rng = np.random.default_rng(seed)
    count = len(attribute.data)
    if data_type in ("FLOAT_COLOR", "BYTE_COLOR"):
        values = np.c_[rng.uniform(0.05, 0.95, (count, 3)), np.ones(count)]
        attribute.data.foreach_set("color", values.ravel())
    else:
        attribute.data.foreach_set("value", rng.uniform(0.05, 0.95, count))
    return attribute


def _lambertian(mesh):
    """A Principled BSDF without its specular layer (exactly Lambertian): (tree, bsdf)."""
    mat = bpy.data.materials.new("Painted")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    mesh.materials.append(mat)
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    return tree, bsdf


def _traced_and_rendered():
    scene = bpy.context.scene
    theirs = cr.render_camera(scene, cr.whitted(2), CYCLES_SAMPLES, (SIZE, SIZE))[0]
    snap = bridge.snapshot(resolution=(SIZE, SIZE))
    ours = trace(snap, TracerSettings(max_depth=2, adaptive=EDGE_SAMPLES),
                 resolution=(SIZE, SIZE)).image
    return snap, ours, theirs


def _color_attribute_node(tree, bsdf, name):
    node = tree.nodes.new("ShaderNodeVertexColor")
    node.layer_name = name
    tree.links.new(node.outputs["Color"], bsdf.inputs["Base Color"])


def _attribute_node(tree, bsdf, name, output):
    node = tree.nodes.new("ShaderNodeAttribute")
    node.attribute_name = name
    tree.links.new(node.outputs[output], bsdf.inputs["Base Color"])


CASES = {
    # (data type, domain, node, output)
    "byte colours on points": ("BYTE_COLOR", "POINT", "color", "Color"),
    "float colours on corners": ("FLOAT_COLOR", "CORNER", "attribute", "Color"),
    "numbers on faces, Fac": ("FLOAT", "FACE", "attribute", "Fac"),
    "numbers on points, Color": ("FLOAT", "POINT", "attribute", "Color"),
}


@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("uv", [True, False], ids=["with UVs", "without UVs"])
def test_the_traced_view_of_an_attribute_matches_cycles(case, uv):
    data_type, domain, kind, output = CASES[case]
    grid = _grid(uv)
    _attribute(grid.data, "Paint", data_type, domain, seed=len(case))
    tree, bsdf = _lambertian(grid.data)
    if kind == "color":
        _color_attribute_node(tree, bsdf, "Paint")
    else:
        _attribute_node(tree, bsdf, "Paint", output)
    snap, ours, theirs = _traced_and_rendered()
    assert not any("attribute" in note for note in snap.ignored), snap.ignored
    assert snap.corner_colors is not None
    assert rel_mse(ours, theirs) < TOLERANCE
    assert np.ptp(theirs) > 0.3  # the colours do vary across the view


def test_the_default_colour_attribute_and_a_missing_name_read_as_cycles_reads_them():
    grid = _grid()
    _attribute(grid.data, "Other", "FLOAT_COLOR", "POINT", seed=1)
    _attribute(grid.data, "Shown", "FLOAT_COLOR", "POINT", seed=2)
    grid.data.color_attributes.render_color_index = 1  # "Shown"
    tree, bsdf = _lambertian(grid.data)
    _color_attribute_node(tree, bsdf, "")  # naming none: the default (render) attribute
    snap, ours, theirs = _traced_and_rendered()
    assert rel_mse(ours, theirs) < TOLERANCE
    shown = np.array([c.color[:3] for c in grid.data.attributes["Shown"].data], np.float32)
    np.testing.assert_array_equal(snap.corner_colors, shown[snap.corner_verts])
    # A name the mesh lacks reads 0: black, in both.
    tree.nodes["Color Attribute"].layer_name = "Nope"
    snap, ours, theirs = _traced_and_rendered()
    np.testing.assert_array_equal(theirs, 0.0)
    np.testing.assert_array_equal(ours, 0.0)


def test_an_emission_attribute_lights_each_triangle_with_its_mean():
    # Emission colour from a colour attribute: the triangles that light others emit their
    # attribute's mean (its value at the centroid, the corners' mean: the ramp is linear).
    grid = _grid()
    attribute = _attribute(grid.data, "Glow", "FLOAT_COLOR", "POINT", seed=3)
    tree, bsdf = _lambertian(grid.data)
    bsdf.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    bsdf.inputs["Emission Strength"].default_value = 2.0
    node = tree.nodes.new("ShaderNodeVertexColor")
    node.layer_name = "Glow"
    tree.links.new(node.outputs["Color"], bsdf.inputs["Emission Color"])
    snap = bridge.snapshot()
    values = np.empty(len(attribute.data) * 4, np.float32)
    attribute.data.foreach_get("color", values)
    rgb = values.reshape(-1, 4)[:, :3]
    expected = 2.0 * rgb[snap.corner_verts].mean(axis=1)
    np.testing.assert_allclose(snap.triangle_radiance, expected, rtol=1e-5, atol=1e-6)


def test_an_attribute_node_naming_none_reads_black_as_in_cycles():
    grid = _grid()
    _attribute(grid.data, "Paint", "FLOAT_COLOR", "POINT", seed=4)
    tree, bsdf = _lambertian(grid.data)
    _attribute_node(tree, bsdf, "", "Color")  # unlike a Color Attribute node: no default
    snap, ours, theirs = _traced_and_rendered()
    np.testing.assert_array_equal(theirs, 0.0)
    np.testing.assert_array_equal(ours, 0.0)
    assert not any("Attribute" in note for note in snap.ignored), snap.ignored
