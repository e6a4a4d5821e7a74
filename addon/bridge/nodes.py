"""Walking shader node trees: which tree Cycles shades a datablock with, which node feeds a socket
(within one tree, or across node groups), which output node is active."""

from __future__ import annotations

import bpy

# Node groups nested deeper than this are not entered (Blender forbids a group inside itself, so
# only a malformed file reaches it).
MAX_GROUP_DEPTH = 16
# Groups entered and left along one link path by `follow_through`: each pass through a group
# costs two (in, out), and a real graph passes a handful.
MAX_GROUP_HOPS = 256


def node_tree(idblock):
    """The node tree Cycles shades `idblock` (material, world, light) with, or None.

    Blender 5.0 always uses node trees and deprecates `use_nodes`; 4.5 still honours the flag.
    """
    if bpy.app.version < (5, 0, 0) and not getattr(idblock, "use_nodes", True):
        return None
    return getattr(idblock, "node_tree", None)


def follow(socket):
    """The node and output socket feeding `socket`, skipping reroutes; (None, None) if unlinked."""
    while socket is not None and socket.is_linked:
        link = socket.links[0]
        if not link.is_valid or link.is_muted:
            return None, None
        node = link.from_node
        if node.type == "REROUTE":
            socket = node.inputs[0]
            continue
        return node, link.from_socket
    return None, None


def active_output(tree, kind: str):
    """The output node of type `kind` that Cycles uses (active, target ALL or CYCLES), else the
    first of that type, else None."""
    outputs = [n for n in tree.nodes if n.type == kind]
    for node in outputs:
        if getattr(node, "is_active_output", False) and node.target in ("ALL", "CYCLES"):
            return node
    return outputs[0] if outputs else None


def tree_nodes(tree, depth: int = 0):
    """Every node of `tree` and of the node groups it holds (nested up to MAX_GROUP_DEPTH), each
    group's nodes where its Group node stands."""
    for node in tree.nodes:
        yield node
        if node.type == "GROUP" and node.node_tree is not None and depth < MAX_GROUP_DEPTH:
            yield from tree_nodes(node.node_tree, depth + 1)


def group_output_socket(group, out):
    """The socket inside Group node `group` that its output `out` passes on: the input of the
    group's active Group Output node with out's identifier; None if there is none."""
    tree = group.node_tree
    if tree is None:
        return None
    outputs = [n for n in tree.nodes if n.type == "GROUP_OUTPUT"]
    output = next((n for n in outputs if n.is_active_output), outputs[0] if outputs else None)
    if output is None:
        return None
    return next((s for s in output.inputs if s.identifier == out.identifier), None)


def group_input_socket(groups: tuple, node, out):
    """The input of the Group node `groups[-1]` (the group entered last) that the Group Input
    node `node`'s output `out` reads inside it; None if no group was entered or `node` lies in
    another tree."""
    if not groups or node.id_data != groups[-1].node_tree:
        return None
    return next((s for s in groups[-1].inputs if s.identifier == out.identifier), None)


def follow_through(socket, groups: tuple = ()):
    """`follow` across node groups, as Cycles flattens them: a Group node's output goes on from
    the matching socket inside the group (the Group node pushed onto `groups`), a Group Input
    node's output from the matching input of the group it was entered by (popped).

    socket: a socket in the tree of `groups[-1]` (the material's own tree when `groups` is
    empty); groups: the Group nodes entered to reach it, outermost first.
    Returns (node, its output socket, the Group nodes entered to reach that node); (None, None,
    groups) where the chain ends unlinked. A group with no matching output, or a Group Input
    not entered through `groups`, is returned as the node itself (for the caller to report).
    """
    for _ in range(MAX_GROUP_HOPS):
        node, out = follow(socket)
        if node is None or node.mute:
            return node, out, groups
        if node.type == "GROUP" and len(groups) < MAX_GROUP_DEPTH:
            inner = group_output_socket(node, out)
            if inner is None:
                return node, out, groups
            socket, groups = inner, groups + (node,)
        elif node.type == "GROUP_INPUT":
            outer = group_input_socket(groups, node, out)
            if outer is None:
                return node, out, groups
            socket, groups = outer, groups[:-1]
        else:
            return node, out, groups
    return None, None, groups
