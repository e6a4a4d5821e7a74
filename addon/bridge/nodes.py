"""Walking shader node trees: which tree Cycles shades a datablock with, which node feeds a socket,
which output node is active."""

from __future__ import annotations

import bpy


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
