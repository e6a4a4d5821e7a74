"""One material socket baked by Cycles into a float image over an object's UVs (`bake_socket`),
for node graphs the bridge cannot read itself (the bridge's `socket_fallback` decides when).

Like the world map (`world_map.render_world_map`), the bake runs in a temporary scene that holds
nothing but a temporary object: a copy of the evaluated mesh, placed as the object is (so
Object and Position coordinates read the same), with the faces of other materials removed (so
they cannot overwrite shared UV space), shaded by a copy of the material whose output is an
Emission shader fed by what feeds the socket. Cycles' EMIT bake of that copy is the socket's
value at every texel. Every temporary datablock is removed afterwards; the user's scene, object,
mesh and material are not touched.
"""

from __future__ import annotations

import contextlib
import time

import bmesh
import bpy
import mathutils
import numpy as np

from ..bridge.images import image_pixels
from .settings import TEMP_PREFIX

# The socket's value is written as emitted radiance: strength 1 leaves it as it is.
UNIT_STRENGTH = 1.0
# A fixed seed: the same graph bakes the same texels in every run (the cache relies on it).
BAKE_SEED = 0


def bake_socket(source, depsgraph, material, node_name: str, socket_identifier: str,
                as_number: bool, uv_layer: str, size: int, samples: int, margin: int,
                strength_identifier: str | None = None,
                blend: tuple | None = None) -> tuple[np.ndarray, float]:
    """The value the linked input `socket_identifier` of node `node_name` in `material` takes
    over `source`'s UV layer `uv_layer`, baked by Cycles: ((size, size, 4) float32 linear, row 0
    top, alpha 1; seconds of the bake operator).

    `source` is the original object, read as evaluated in `depsgraph` (modifiers applied);
    `as_number`: the socket takes a number, so the link passes through a Math node first and
    Cycles converts a colour or vector to a number as it would for the socket (luminance, mean);
    a colour socket's link feeds the Emission colour as it is. `samples` per texel, spread over
    its area; `margin` texels of the charts extended outwards (bilinear look-ups at a chart's
    rim then read no black). With `strength_identifier`, the node's input of that identifier
    (linked or not) is the Emission strength: the bake is colour x strength, an emission's
    radiance. With `blend` ((node, identifier) of a factor, (node, identifier) of another
    input), the bake is the two inputs' values mixed by the factor's, (1 - f) this + f other
    (what a Mix Shader of two shaders makes of their inputs of one kind)."""
    with contextlib.ExitStack() as stack:
        mat = _emission_copy(material, node_name, socket_identifier, as_number,
                             strength_identifier, blend)
        stack.callback(bpy.data.materials.remove, mat)
        image = bpy.data.images.new(f"{TEMP_PREFIX}_socket", size, size, alpha=True,
                                    float_buffer=True)
        stack.callback(bpy.data.images.remove, image)
        image.colorspace_settings.name = "Non-Color"  # the bake's values, untransformed
        target = mat.node_tree.nodes.new("ShaderNodeTexImage")
        target.image = image
        mat.node_tree.nodes.active = target
        mesh = _material_mesh(source, depsgraph, material)
        stack.callback(bpy.data.meshes.remove, mesh)
        mesh.materials.clear()
        mesh.materials.append(mat)
        mesh.polygons.foreach_set("material_index", np.zeros(len(mesh.polygons), np.int32))
        scene = bpy.data.scenes.new(f"{TEMP_PREFIX}_socket")
        stack.callback(bpy.data.scenes.remove, scene)
        obj = bpy.data.objects.new(f"{TEMP_PREFIX}_socket", mesh)
        stack.callback(bpy.data.objects.remove, obj)
        scene.collection.objects.link(obj)
        obj.matrix_world = mathutils.Matrix(source.evaluated_get(depsgraph).matrix_world)
        # What an Object Info node reads of it (its colour, its pass index) as of the source.
        obj.color, obj.pass_index = source.color, source.pass_index
        scene.render.engine = "CYCLES"
        scene.cycles.device = "CPU"
        scene.cycles.samples = int(samples)
        scene.cycles.seed = BAKE_SEED
        scene.cycles.use_adaptive_sampling = False
        layer = scene.view_layers[0]
        obj.select_set(True, view_layer=layer)
        layer.objects.active = obj
        with bpy.context.temp_override(scene=scene, view_layer=layer, active_object=obj,
                                       object=obj, selected_objects=[obj],
                                       selected_editable_objects=[obj]):
            start = time.perf_counter()
            bpy.ops.object.bake(type="EMIT", target="IMAGE_TEXTURES", uv_layer=uv_layer,
                                margin=int(margin), margin_type="EXTEND", use_clear=True,
                                use_selected_to_active=False, save_mode="INTERNAL",
                                use_split_materials=False, use_automatic_name=False)
            seconds = time.perf_counter() - start
        pixels = image_pixels(image)
        pixels[..., 3] = 1.0  # texels outside the charts (alpha 0) are never read
    return pixels, seconds


def _input(tree, node_name: str, identifier: str):
    return next(s for s in tree.nodes[node_name].inputs if s.identifier == identifier)


def _feed(tree, socket, as_number: bool, target) -> None:
    """Feed `target` (a colour input) with what feeds `socket`, or its own value unlinked."""
    if socket.is_linked:
        tree.links.new(socket.links[0].from_socket, target)
        return
    value = socket.default_value
    if target.type == "VALUE":
        target.default_value = value if as_number else sum(value[:3]) / 3.0
    else:
        target.default_value = (value, value, value, 1.0) if as_number else tuple(value)


def _emission_copy(material, node_name: str, socket_identifier: str, as_number: bool,
                   strength_identifier: str | None = None, blend: tuple | None = None):
    """A temporary copy of `material` whose only output is an Emission shader fed by what feeds
    the socket (its own value where it is unlinked), of strength 1 or what feeds the input
    `strength_identifier` of the same node; with `blend` (`bake_socket`), by a Mix of it and
    the other input by the factor."""
    mat = material.copy()
    mat.name = f"{TEMP_PREFIX}_socket"
    tree = mat.node_tree
    node = tree.nodes[node_name]
    socket = next(s for s in node.inputs if s.identifier == socket_identifier)
    strength = next((s for s in node.inputs if s.identifier == strength_identifier), None)
    source = socket.links[0].from_socket if socket.is_linked else None
    strength_source = strength.links[0].from_socket if strength and strength.is_linked else None
    if blend is not None:  # a colour Mix of the two inputs (numbers as grey colours)
        (fac_node, fac_id), (other_node, other_id) = blend
        mix = tree.nodes.new("ShaderNodeMix")
        mix.data_type = "RGBA"
        mix.clamp_factor = True
        inputs = {s.identifier: s for s in mix.inputs}
        _feed(tree, _input(tree, fac_node, fac_id), True, inputs["Factor_Float"])
        _feed(tree, socket, as_number, inputs["A_Color"])
        _feed(tree, _input(tree, other_node, other_id), as_number, inputs["B_Color"])
        source = next(s for s in mix.outputs if s.identifier == "Result_Color")
    for output in [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"]:
        tree.nodes.remove(output)
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = (
        UNIT_STRENGTH if strength is None else strength.default_value)
    if strength_source is not None:
        tree.links.new(strength_source, emission.inputs["Strength"])
    if source is None:  # an unlinked colour (beside a linked strength): its own value
        value = socket.default_value
        emission.inputs["Color"].default_value = (
            (value, value, value, 1.0) if as_number else tuple(value))
    else:
        if as_number:  # Cycles' own conversion of a colour or vector to the socket's number
            number = tree.nodes.new("ShaderNodeMath")
            number.operation = "ADD"
            number.inputs[1].default_value = 0.0
            tree.links.new(source, number.inputs[0])
            source = number.outputs[0]
        tree.links.new(source, emission.inputs["Color"])
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    output.target = "ALL"
    tree.links.new(emission.outputs[0], output.inputs["Surface"])
    return mat


def _material_mesh(source, depsgraph, material):
    """A temporary copy of `source`'s evaluated mesh (all its layers, the original's texture
    space for Generated coordinates) holding only the faces shaded by `material`."""
    evaluated = source.evaluated_get(depsgraph)
    mesh = bpy.data.meshes.new_from_object(evaluated, preserve_all_data_layers=True,
                                           depsgraph=depsgraph)
    mesh.name = f"{TEMP_PREFIX}_socket"
    if source.type == "MESH":
        mesh.use_auto_texspace = False
        mesh.texspace_location = source.data.texspace_location
        mesh.texspace_size = source.data.texspace_size
    slots = [slot.material for slot in evaluated.material_slots]
    keep = {k for k, mat in enumerate(slots) if mat == material}
    if len(keep) < len(slots):
        bm = bmesh.new()
        bm.from_mesh(mesh)
        others = [f for f in bm.faces if f.material_index not in keep]
        bmesh.ops.delete(bm, geom=others, context="FACES")
        bm.to_mesh(mesh)
        bm.free()
    return mesh
