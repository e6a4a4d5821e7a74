"""A digest of a shader node tree (`tree_digest`): equal digests shade equal values, so a bake
of one of its sockets can be reused (`socket_fallback`).

It covers what Cycles reads: every node's type, name, mute state and own properties (enums,
numbers, colour ramps, curves, the images they name, node groups entered recursively), every
input's default value and every link. It leaves out what only the editor shows (location,
width, selection, labels, colours of frames).
"""

from __future__ import annotations

import hashlib

import bpy

# Structs and collections inside a node are followed this deep: a curve's point sits at depth 4
# (mapping > curves > curve > points > point), a ColorRamp's element at 2; nothing a shader node
# reads lies deeper.
MAX_STRUCT_DEPTH = 6
# Node properties that only the editor shows; the rest of a node's properties are its own.
EDITOR_ONLY = frozenset({
    "rna_type", "name", "label", "location", "location_absolute", "width", "height",
    "dimensions", "select", "show_options", "show_preview", "hide", "show_texture", "color",
    "use_custom_color", "parent", "internal_links", "inputs", "outputs", "type", "bl_idname",
    "bl_label", "bl_description", "bl_icon", "bl_static_type", "bl_width_default",
    "bl_width_min", "bl_width_max", "bl_height_default", "bl_height_min", "bl_height_max",
    "is_active_output", "warning_propagation", "color_tag", "select_index"})


def tree_digest(tree) -> str:
    """SHA-256 hex of what `tree` (a material's or a group's node tree) shades with."""
    return hashlib.sha256(repr(_tree(tree, ())).encode()).hexdigest()


def _tree(tree, inside: tuple) -> tuple:
    if tree.as_pointer() in inside:  # a group containing itself: said once
        return ("recursive", tree.name)
    inside = inside + (tree.as_pointer(),)
    nodes = tuple(_node(node, inside) for node in sorted(tree.nodes, key=lambda n: n.name))
    links = tuple(sorted(
        (link.from_node.name, link.from_socket.identifier, link.to_node.name,
         link.to_socket.identifier, link.is_muted, link.is_valid) for link in tree.links))
    return (tree.bl_idname, nodes, links)


def _node(node, inside: tuple) -> tuple:
    props = tuple((prop.identifier, _value(getattr(node, prop.identifier, None), inside, 0))
                  for prop in node.bl_rna.properties if prop.identifier not in EDITOR_ONLY)
    inputs = tuple((s.identifier, _value(getattr(s, "default_value", None), inside, 0))
                   for s in node.inputs)
    return (node.bl_idname, node.name, node.mute, props, inputs)


def _value(value, inside: tuple, depth: int):
    """A hashable description of an RNA value: plain values as they are, arrays as tuples,
    datablocks by what identifies their content, structs by their properties."""
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, bpy.types.NodeTree):
        return _tree(value, inside)
    if isinstance(value, bpy.types.Image):
        return ("image", value.name, value.filepath, tuple(value.size), value.source,
                value.colorspace_settings.name, value.alpha_mode, value.is_dirty)
    if isinstance(value, bpy.types.ID):
        return (type(value).__name__, value.name_full)
    if isinstance(value, bpy.types.bpy_prop_collection):
        if depth >= MAX_STRUCT_DEPTH:
            return len(value)
        return tuple(_value(item, inside, depth + 1) for item in value)
    if isinstance(value, bpy.types.bpy_struct):
        if depth >= MAX_STRUCT_DEPTH:
            return type(value).__name__
        return tuple((prop.identifier, _value(getattr(value, prop.identifier, None), inside,
                                              depth + 1))
                     for prop in value.bl_rna.properties if prop.identifier != "rna_type")
    try:
        return tuple(_value(item, inside, depth + 1) for item in value)  # arrays, vectors
    except TypeError:
        return repr(value)
