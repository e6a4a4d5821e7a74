"""Kernel results put back into Blender and shown there: float images (packed or saved as
OpenEXR), float colour attributes, a snapshot's per-corner values on the original mesh's corners,
and the material wiring that makes the viewport and renders show a baked result (undone without
loss by `unwire_baked_display`)."""

from __future__ import annotations

import bpy
import numpy as np

from .images import flip_rows
from .nodes import active_output


def write_image(name: str, pixels: np.ndarray, image=None):
    """Put (H, W, C) float32 linear pixels (row 0 top, C in 1..4) into a float Blender image.

    Reuses `image` (resized if needed) or creates a new float image named `name`. Returns the image.
    """
    pixels = np.asarray(pixels, np.float32)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    height, width, channels = pixels.shape
    rgba = np.ones((height, width, 4), np.float32)
    if channels == 1:
        rgba[..., :3] = pixels
    else:
        rgba[..., :channels] = pixels
    if image is None:
        image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    elif tuple(image.size) != (width, height):
        image.scale(width, height)
    image.pixels.foreach_set(flip_rows(rgba).ravel())
    image.update()
    return image


def save_image_exr(image, pixels: np.ndarray, path: str) -> None:
    """Write `pixels` as OpenEXR at `path` (OpenEXR package) and point `image` at that file."""
    from ...kernels.measure.exr import write_exr

    write_exr(path, pixels)
    image.filepath_raw = path
    image.file_format = "OPEN_EXR"


def pack_image(image) -> None:
    """Keep a float image inside the .blend (as OpenEXR), so nothing depends on outside files.

    Blender stores packed float images premultiplied: colour survives exactly only where alpha is 1,
    which is what every bake writes. Values come back as half floats (relative error < 1e-3).
    """
    image.file_format = "OPEN_EXR"
    image.pack()


def write_color_attribute(mesh, name: str, colors: np.ndarray, domain: str = "POINT"):
    """Write (N, 3|4) float32 linear colours as a float colour attribute on `mesh`.

    `domain` is POINT (N = vertices) or CORNER (N = loops). An attribute of that name with another
    type or domain is replaced; the render and active colour attributes are left as they were unless
    the mesh had none.
    """
    count = len(mesh.vertices) if domain == "POINT" else len(mesh.loops)
    colors = np.asarray(colors, np.float32)
    if colors.shape[0] != count or colors.shape[1] not in (3, 4):
        raise ValueError(f"write_color_attribute: expected ({count}, 3|4) colours for the {domain} "
                         f"domain of '{mesh.name}', got {colors.shape}")
    rgba = np.ones((count, 4), np.float32)
    rgba[:, : colors.shape[1]] = colors
    attrs = mesh.color_attributes
    attr = attrs.get(name)
    if attr is not None and (attr.data_type != "FLOAT_COLOR" or attr.domain != domain):
        attrs.remove(attr)
        attr = None
    if attr is None:
        attr = attrs.new(name=name, type="FLOAT_COLOR", domain=domain)
    attr.data.foreach_set("color", rgba.ravel())
    mesh.update()
    return attr


def read_color_attribute(mesh, name: str) -> np.ndarray:
    """(N, 4) float32 linear colours of a colour attribute (N: its domain's size)."""
    attr = mesh.color_attributes[name]
    out = np.empty(len(attr.data) * 4, np.float32)
    attr.data.foreach_get("color", out)
    return out.reshape(-1, 4)


def write_corner_values(mesh, scene, object_index: int, values: np.ndarray, name: str):
    """Write per-triangle-corner values of one snapshot object onto its original mesh's corners.

    values (T * 3,) or (T * 3, C) in the snapshot's corner order; the object must not have
    topology-changing modifiers (`ObjectInfo.topology_matches_original`). Mirrored objects had
    corners 1 and 2 swapped by the snapshot; `corner_loops` carries the swap, so nothing is lost.
    """
    info = scene.objects[object_index]
    if not info.topology_matches_original:
        raise ValueError(f"object '{info.name}': its evaluated mesh differs from the original")
    loops = scene.corner_loops[scene.object_slice(object_index)].ravel()
    values = np.asarray(values, np.float32)
    if values.ndim == 1:
        values = np.repeat(values[:, None], 3, axis=1)
    per_loop = np.zeros((len(mesh.loops), values.shape[1]), np.float32)
    per_loop[loops] = values
    return write_color_attribute(mesh, name, per_loop, domain="CORNER")


WIRING_TAG = "classic_bake"  # custom property on every node the wiring adds
_ORIGINAL_OUTPUT = "classic_bake_original_output"  # material property: the output to restore


def materials_to_wire(obj, single_user: bool, suffix: str = "baked") -> list:
    """The materials of `obj` to wire (each once), creating one ("OBJECT (suffix)") where a slot
    is empty or there are none.

    With `single_user` (a per-object image: a lightmap, a normal map) a material shared with
    other objects is replaced in this object's slot by a copy, so the other objects keep their own.
    """
    if len(obj.material_slots) == 0:
        obj.data.materials.append(bpy.data.materials.new(f"{obj.name} ({suffix})"))
    materials = []
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None:
            mat = slot.material = bpy.data.materials.new(f"{obj.name} ({suffix})")
        elif single_user and mat.users > 1:
            mat = slot.material = mat.copy()
        if bpy.app.version < (5, 0, 0):
            mat.use_nodes = True  # creates a Principled BSDF and an output in 4.5
        if mat not in materials:
            materials.append(mat)
    return materials


def unwire_baked_display(mat) -> None:
    """Remove what `wire_baked_display` added to `mat` and make its original output active again."""
    tree = mat.node_tree
    if tree is None:
        return
    for node in [n for n in tree.nodes if n.get(WIRING_TAG)]:
        tree.nodes.remove(node)
    original = tree.nodes.get(mat.get(_ORIGINAL_OUTPUT, ""))
    if original is not None:
        original.is_active_output = True
    if _ORIGINAL_OUTPUT in mat:
        del mat[_ORIGINAL_OUTPUT]


def wire_baked_display(obj, *, attribute: str | None = None, image=None,
                       uv_layer: str | None = None) -> list:
    """Make Blender's viewport and renders show a baked result on `obj`, losing nothing.

    The baked radiance (a colour attribute by name, or a lightmap `image` read through `uv_layer`)
    feeds an Emission shader into a new Material Output that becomes the active one; the original
    output and every original node stay in the material (`unwire_baked_display` restores them).
    Returns the materials wired.
    """
    if (attribute is None) == (image is None):
        raise ValueError("wire_baked_display: give exactly one of attribute= and image=")
    materials = materials_to_wire(obj, single_user=image is not None)
    for mat in materials:
        unwire_baked_display(mat)
        tree = mat.node_tree
        current = active_output(tree, "OUTPUT_MATERIAL")
        if current is not None:
            mat[_ORIGINAL_OUTPUT] = current.name
        nodes, links = tree.nodes, tree.links
        if attribute is not None:
            source = nodes.new("ShaderNodeVertexColor")
            source.layer_name = attribute
            color = source.outputs["Color"]
        else:
            source = nodes.new("ShaderNodeTexImage")
            source.image = image
            source.interpolation = "Linear"
            source.extension = "EXTEND"  # lightmap charts are padded; never wrap across the atlas
            uv = nodes.new("ShaderNodeUVMap")
            uv.uv_map = uv_layer or ""
            links.new(uv.outputs["UV"], source.inputs["Vector"])
            uv[WIRING_TAG] = True
            uv.location = (-700, -400)
            color = source.outputs["Color"]
        emission = nodes.new("ShaderNodeEmission")
        output = nodes.new("ShaderNodeOutputMaterial")
        output.target = "ALL"
        links.new(color, emission.inputs["Color"])
        links.new(emission.outputs["Emission"], output.inputs["Surface"])
        for node, x in ((source, -450), (emission, -150), (output, 100)):
            node[WIRING_TAG] = True
            node.location = (x, -400)
        output.is_active_output = True
    return materials
