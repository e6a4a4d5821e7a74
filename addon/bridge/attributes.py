"""Mesh attributes that materials read as colours (Color Attribute and Attribute nodes: vertex
colours), per triangle corner: which ones a material's node tree names (`attribute_names`), their
values at the corners (`corner_attribute`), and which one each material's textures read
(`material_attribute`).

What Cycles reads (measured on a plane under a sun of pi W/m^2, where the radiance is the albedo):
a byte colour attribute as its linear value (`color`, not `color_srgb`); a name the mesh lacks
as 0; a Color Attribute node naming none as the mesh's default colour attribute, an Attribute
node naming none as 0; an Attribute node's Fac as the mean of the three channels.
"""

from __future__ import annotations

import numpy as np

from ...kernels.geometry.scene import Material
from .nodes import node_tree, tree_nodes

# RNA field and component count of each attribute type a colour can be made of: colours give
# their RGB, vectors their components (a 2D vector (x, y, 0)), numbers all three channels.
_FIELDS = {"FLOAT_COLOR": ("color", 4), "BYTE_COLOR": ("color", 4), "FLOAT_VECTOR": ("vector", 3),
           "FLOAT2": ("vector", 2), "FLOAT": ("value", 1), "INT": ("value", 1),
           "BOOLEAN": ("value", 1)}
# The key under which a Color Attribute node naming no attribute reads the default one.
DEFAULT_COLOR = ""


def attribute_names(materials) -> set[str]:
    """Names of the attributes the Color Attribute and (geometry) Attribute nodes of `materials`
    (Blender materials, None for empty slots), and of the node groups they hold, read;
    DEFAULT_COLOR for a Color Attribute node naming none."""
    names: set[str] = set()
    for mat in materials:
        tree = node_tree(mat) if mat is not None else None
        for node in tree_nodes(tree) if tree is not None else ():
            if node.type == "VERTEX_COLOR":
                names.add(node.layer_name)
            elif (node.type == "ATTRIBUTE" and node.attribute_type == "GEOMETRY"
                  and node.attribute_name):
                names.add(node.attribute_name)
    return names


def corner_attribute(mesh, name: str, corner_loops: np.ndarray, corner_verts: np.ndarray,
                     polygons: np.ndarray) -> np.ndarray | None:
    """(T, 3, 3) float32 linear values of attribute `name` of `mesh` at each triangle's corners
    (loops corner_loops (T, 3), vertices corner_verts (T, 3), faces polygons (T,)); None where the
    mesh has no such attribute (Cycles reads 0) or it is of a type or domain no colour is made
    of (an edge's, a string)."""
    if name == DEFAULT_COLOR:
        colors = mesh.color_attributes
        index = colors.render_color_index
        attribute = colors[index] if 0 <= index < len(colors) else None
    else:
        attribute = mesh.attributes.get(name)
    if attribute is None or attribute.data_type not in _FIELDS:
        return None
    where = {"CORNER": corner_loops, "POINT": corner_verts,
             "FACE": np.repeat(polygons[:, None], 3, axis=1)}.get(attribute.domain)
    if where is None:
        return None
    rna_field, width = _FIELDS[attribute.data_type]
    raw = np.empty(len(attribute.data) * width,
                   {"INT": np.int32, "BOOLEAN": bool}.get(attribute.data_type, np.float32))
    attribute.data.foreach_get(rna_field, raw)
    values = raw.reshape(-1, width).astype(np.float32)
    if width == 1:
        rgb = np.repeat(values, 3, axis=1)
    else:
        rgb = np.zeros((len(values), 3), np.float32)
        rgb[:, :min(width, 3)] = values[:, :3]
    return rgb[where]


def material_attribute(material: Material, ignored: list) -> str | None:
    """The attribute `material`'s textures read per corner (base colour first, then emission,
    metallic, roughness), or None; a second name is noted (one attribute per triangle)."""
    textures = (material.base_color_texture, material.emission_texture,
                material.metallic_texture, material.roughness_texture)
    names = list(dict.fromkeys(t.name for t in textures if t is not None and t.kind == "ATTRIBUTE"))
    if len(names) > 1:
        ignored.append(f"material '{material.name}': colour attributes {names} read; only "
                       f"'{names[0]}' is held per corner, the others read it too")
    return names[0] if names else None
