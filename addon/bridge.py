"""The one crossing between Blender data and kernel arrays.

`snapshot()` reads the evaluated depsgraph (modifiers applied, instances expanded) into a kernel
`Scene`; the `write_*` helpers put kernel results back as images, colour attributes and UV layers.
Everything moves through `foreach_get`/`foreach_set` into preallocated typed arrays. This module owns
the conventions that differ between Blender and the kernels:

* images: Blender stores rows bottom-up, kernels top-down (`_flip_rows`);
* mirrored objects (negative determinant): corners 1 and 2 are swapped so that every kernel triangle
  winds counter-clockwise around the normal Blender shades with;
* colour: byte images in sRGB are decoded to linear here, except textures, which keep their
  encoding and decode each look-up after interpolation, as Cycles does (`Texture.encoding`);
* lights: Blender's power is turned into radiometric quantities by `kernels/lights.py`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import bpy
import numpy as np

from ..kernels.geometry.camera import image_plane
from ..kernels.geometry.scene import Camera, Light, Material, ObjectInfo, Scene, Texture
from ..kernels.shading import lights as light_units

DEFAULT_MATERIAL_NAME = "(default surface)"
# What Cycles shades faces without a material with (measured: a plane under a sun renders to the
# same float as with a material of that surface): Blender 5 a Principled BSDF of its node's
# defaults (base 0.8, roughness 0.5, IOR 1.5, Specular IOR Level 0.5: a specular layer), 4.5 a
# 0.8 grey Diffuse BSDF.
DEFAULT_MATERIAL = (Material(name=DEFAULT_MATERIAL_NAME) if bpy.app.version >= (5, 0, 0)
                    else Material(name=DEFAULT_MATERIAL_NAME, specular=0.0))


@dataclass(frozen=True)
class SnapshotRequest:
    """What one bake needs from the scene; everything else is not read at all.

    | field        | default | meaning                                                         |
    |--------------|---------|-----------------------------------------------------------------|
    | normals      | True    | corner normals (custom normals honoured)                        |
    | uv           | True    | the active render UV layer                                      |
    | lightmap_uv  | None    | name of a UV layer to read as `Scene.lightmap_uv`               |
    | textures     | True    | image and checker textures (a shadow bake reads none)           |
    | materials    | True    | materials beyond ids (False: every triangle gets the default)   |
    | lights       | True    |                                                                 |
    | camera       | True    |                                                                 |
    | objects      | None    | restrict geometry to these object names (None: all renderable)  |
    | world_render | True    | render a world shader the bridge cannot read into a map         |
    |              |         | (`read_world_texture`: Cycles, ~1.2 s); False: black or its     |
    |              |         | socket's colour                                                 |
    """

    normals: bool = True
    uv: bool = True
    lightmap_uv: str | None = None
    textures: bool = True
    materials: bool = True
    lights: bool = True
    camera: bool = True
    objects: tuple[str, ...] | None = None
    world_render: bool = True


# --- small conversions ----------------------------------------------------------------------------


def _flip_rows(pixels: np.ndarray) -> np.ndarray:
    """Kernel images are top row first, Blender's bottom row first; the same flip goes both ways."""
    return pixels[::-1]


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB EOTF (IEC 61966-2-1), applied to colour channels of byte images."""
    c = np.asarray(c, np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _matrix(m) -> np.ndarray:
    """A mathutils.Matrix as a (4, 4) float64 array."""
    return np.array([list(row) for row in m], dtype=np.float64)


def _node_tree(idblock):
    """The node tree Cycles shades `idblock` (material, world, light) with, or None.

    Blender 5.0 always uses node trees and deprecates `use_nodes`; 4.5 still honours the flag.
    """
    if bpy.app.version < (5, 0, 0) and not getattr(idblock, "use_nodes", True):
        return None
    return getattr(idblock, "node_tree", None)


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v)
    return v / n if n > 0 else v


# --- geometry -------------------------------------------------------------------------------------


@dataclass
class _MeshChunk:
    name: str
    source_name: str
    is_instance: bool
    triangles: np.ndarray  # (T, 3, 3) float32, world
    normals: np.ndarray | None  # (T, 3, 3) float32, world, unit
    uv: np.ndarray | None  # (T, 3, 2) float32
    lightmap_uv: np.ndarray | None  # (T, 3, 2) float32
    generated: np.ndarray | None  # (T, 3, 3) float32 Generated texture coordinates
    slot_ids: np.ndarray  # (T,) int32 material slot per triangle
    corner_loops: np.ndarray  # (T, 3) int32
    corner_verts: np.ndarray  # (T, 3) int32
    slot_materials: list = field(default_factory=list)
    topology_matches_original: bool = True


def mesh_triangles(mesh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(corner_verts (T, 3), corner_loops (T, 3), polygon (T,), material slot (T,)) of a mesh, int32."""
    tris = mesh.loop_triangles
    count = len(tris)
    verts = np.empty(count * 3, np.int32)
    loops = np.empty(count * 3, np.int32)
    polys = np.empty(count, np.int32)
    slots = np.empty(count, np.int32)
    tris.foreach_get("vertices", verts)
    tris.foreach_get("loops", loops)
    tris.foreach_get("polygon_index", polys)
    tris.foreach_get("material_index", slots)
    return verts.reshape(-1, 3), loops.reshape(-1, 3), polys, slots


def mesh_positions(mesh) -> np.ndarray:
    """Vertex positions (V, 3) float32, object space."""
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def mesh_corner_normals(mesh) -> np.ndarray:
    """Corner (loop) normals (L, 3) float32, object space, with custom and sharp normals honoured."""
    normals = np.empty(len(mesh.loops) * 3, np.float32)
    if hasattr(mesh, "corner_normals"):  # Blender 4.1+
        mesh.corner_normals.foreach_get("vector", normals)
    else:  # pragma: no cover - older than the manifest allows
        mesh.calc_normals_split()
        mesh.loops.foreach_get("normal", normals)
    return normals.reshape(-1, 3)


def mesh_uv(mesh, name: str | None) -> np.ndarray | None:
    """Per-loop UVs (L, 2) float32 of layer `name` (None: the active render layer), or None."""
    layers = mesh.uv_layers
    if name is None:
        layer = next((lay for lay in layers if lay.active_render), None)
    else:
        layer = layers.get(name)
    if layer is None:
        return None
    uv = np.empty(len(mesh.loops) * 2, np.float32)
    layer.uv.foreach_get("vector", uv)
    return uv.reshape(-1, 2)


def generated_coordinates(positions: np.ndarray, texspace) -> np.ndarray:
    """(V, 3) float64 Blender's Generated texture coordinates of object-space positions (V, 3):
    the texture space of `texspace` (a mesh: centre +- size, its bounding box when automatic)
    mapped to the unit cube, as Cycles reads them (its "orco" coordinates; the evaluated
    positions stand for the undeformed ones, which differ only under deforming modifiers)."""
    centre = np.array(texspace.texspace_location, np.float64)
    size = np.array(texspace.texspace_size, np.float64)
    size = np.where(size != 0.0, size, 1.0)
    return (positions - (centre - size)) / (2.0 * size)


def _mesh_chunk(
    name, source_name, is_instance, mesh, matrix, request, original_mesh, slot_materials,
    texspace=None,
) -> _MeshChunk:
    corner_verts, corner_loops, _, slots = mesh_triangles(mesh)
    local = mesh_positions(mesh).astype(np.float64)
    world = local @ matrix[:3, :3].T + matrix[:3, 3]
    mirrored = np.linalg.det(matrix[:3, :3]) < 0.0
    order = [0, 2, 1] if mirrored else [0, 1, 2]
    corner_verts = corner_verts[:, order]
    corner_loops = corner_loops[:, order]
    triangles = world[corner_verts].astype(np.float32)

    normals = None
    if request.normals:
        # Normals transform with the inverse transpose; a zero-scale axis leaves them as they are.
        linear = matrix[:3, :3]
        try:
            normal_matrix = np.linalg.inv(linear).T
        except np.linalg.LinAlgError:
            normal_matrix = np.eye(3)
        loop_n = mesh_corner_normals(mesh).astype(np.float64) @ normal_matrix.T
        length = np.linalg.norm(loop_n, axis=1, keepdims=True)
        loop_n = np.divide(loop_n, length, out=np.zeros_like(loop_n), where=length > 0)
        normals = loop_n[corner_loops].astype(np.float32)

    uv = None
    generated = None
    if request.uv:
        loop_uv = mesh_uv(mesh, None)
        uv = None if loop_uv is None else loop_uv[corner_loops]
        # Texture space: the original mesh's (Cycles' orco), else this one's.
        generated = generated_coordinates(local, texspace or mesh)[corner_verts].astype(np.float32)
    lightmap_uv = None
    if request.lightmap_uv:
        loop_uv = mesh_uv(mesh, request.lightmap_uv)
        lightmap_uv = None if loop_uv is None else loop_uv[corner_loops]

    matches = original_mesh is not None and (
        len(original_mesh.loops) == len(mesh.loops)
        and len(original_mesh.vertices) == len(mesh.vertices)
    )
    return _MeshChunk(
        name=name,
        source_name=source_name,
        is_instance=is_instance,
        triangles=triangles,
        normals=normals,
        uv=uv,
        lightmap_uv=lightmap_uv,
        generated=generated,
        slot_ids=slots,
        corner_loops=corner_loops,
        corner_verts=corner_verts,
        slot_materials=slot_materials,
        topology_matches_original=matches,
    )


# --- materials ------------------------------------------------------------------------------------


def _follow(socket):
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


def _active_output(tree, kind: str):
    outputs = [n for n in tree.nodes if n.type == kind]
    for node in outputs:
        if getattr(node, "is_active_output", False) and node.target in ("ALL", "CYCLES"):
            return node
    return outputs[0] if outputs else None


def stored_srgb(image) -> bool:
    """Whether Cycles keeps `image` sRGB-encoded and decodes each look-up after interpolating: an
    8-bit image in the sRGB colour space."""
    return not image.is_float and image.colorspace_settings.name == "sRGB"


def image_pixels(image, decode: bool = True) -> np.ndarray | None:
    """An image's pixels as (H, W, 4) float32, row 0 top, or None if it has no data: linear, or
    with decode=False sRGB-encoded where the image stores them so (`stored_srgb`)."""
    width, height = image.size
    if width == 0 or height == 0:
        return None
    buf = np.empty(width * height * 4, np.float32)
    image.pixels.foreach_get(buf)
    pixels = _flip_rows(buf.reshape(height, width, 4)).copy()
    if decode and stored_srgb(image):
        pixels[..., :3] = srgb_to_linear(pixels[..., :3])
    return pixels


# Mix and Add Shaders nested deeper than this are not followed (a shader tree is finite, but a
# node group could repeat one mix many times; eight levels hold 256 leaves).
MAX_SHADER_MIX_DEPTH = 8


def mix_materials(name: str, parts: list, ignored: list) -> Material:
    """One `Material` for the weighted sum of parts [(weight, Material)] (a Mix Shader's 1 - Fac
    and Fac, an Add Shader's 1 and 1), as a Principled BSDF splits a surface: part i reflects
    diffusely with weight w_i (1 - m_i)(1 - t_i), as a metal with w_i m_i, transmits with
    w_i (1 - m_i) t_i (m: metallic, t: transmission). The sum keeps the diffuse albedo exactly
    (sum of the diffuse weights times base colours: what radiosity and Cycles' DIFFUSE bake read),
    the emission exactly, and the three weights' shares; the metal parts keep their own tint
    (`Material.metal_color`: a white Glossy over a red Diffuse reflects white), the glass parts
    take the base colour, roughness and IOR their parts' weighted means, the specular layer the
    diffuse parts' weighted level. A base texture is kept where its part is the only diffuse one
    (else the first textured part's, noted)."""
    weights = np.array([w for w, _ in parts], np.float64)
    d_w = np.array([w * (1.0 - m.metallic) * (1.0 - m.transmission) for w, m in parts])
    m_w = np.array([w * m.metallic for w, m in parts])
    t_w = np.array([w * (1.0 - m.metallic) * m.transmission for w, m in parts])
    diffuse, metal, glass = float(d_w.sum()), float(m_w.sum()), float(t_w.sum())
    total = diffuse + metal + glass
    emission = sum((w * m.emission.astype(np.float64) for w, m in parts), np.zeros(3))
    if total <= 0.0:
        return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                        emission=emission.astype(np.float32), ignored=tuple(ignored))

    def mean(values: list, *by: np.ndarray):  # one value per part, weighted by the first of `by`
        w = next(x for x in by if x.sum() > 0.0)  # with a positive sum
        return np.tensordot(w, np.asarray(values, np.float64), axes=1) / w.sum()

    colours = [m.base_color for _, m in parts]

    if diffuse > 0.0:
        # (1 - metallic)(1 - transmission) = diffuse / total below, so this base gives the sum's
        # diffuse albedo.
        base = mean(colours, d_w) * total
    else:
        base = mean(colours, m_w + t_w)
    textured = [(dw, m) for dw, (_, m) in zip(d_w, parts, strict=True)
                if m.base_color_texture is not None and dw > 0.0]
    texture = None
    if textured:
        dw, source = textured[0]
        if len(textured) > 1 or any(x > 0.0 and m.base_color_texture is None
                                    for x, (_, m) in zip(d_w, parts, strict=True)):
            ignored.append("a mix of shaders with a texture: the first textured part's texture "
                           "stands for every diffuse part's colour")
        texture = _scaled_texture(source.base_color_texture, dw * total / diffuse, ignored)
    normal = next((m for _, m in parts if m.normal_texture is not None or
                   m.height_texture is not None), None)
    # The metal parts' own tint (a white Glossy over a red Diffuse reflects white), where it is
    # not the base colour the diffuse albedo fixed.
    tint = None
    if metal > 0.0:
        tint = mean([m.base_color if m.metal_color is None else m.metal_color
                     for _, m in parts], m_w)
        if texture is None and np.allclose(tint, base, rtol=1e-6, atol=1e-7):
            tint = None
    return Material(
        name=name, base_color=base.astype(np.float32), base_color_texture=texture,
        metal_color=None if tint is None else tint.astype(np.float32),
        metallic=metal / total,
        roughness=float(mean([m.roughness for _, m in parts], m_w + t_w, weights)),
        ior=float(mean([m.ior for _, m in parts], t_w, weights)),
        transmission=glass / (glass + diffuse) if glass + diffuse > 0.0 else 0.0,
        specular=float(mean([m.specular for _, m in parts], d_w, weights)),
        emission=emission.astype(np.float32),
        normal_texture=None if normal is None else normal.normal_texture,
        height_texture=None if normal is None else normal.height_texture,
        bump_strength=1.0 if normal is None else normal.bump_strength,
        bump_distance=1.0 if normal is None else normal.bump_distance,
        ignored=tuple(ignored))


def _scaled_texture(texture: Texture, factor: float, ignored: list) -> Texture:
    """`texture` with its colours times `factor` (1: itself); an sRGB-encoded image, whose
    texels are decoded after filtering, is kept as it is (noted)."""
    if abs(factor - 1.0) < 1e-9:
        return texture
    if texture.kind == "CHECKER":
        return replace(texture, color1=(texture.color1 * factor).astype(np.float32),
                       color2=(texture.color2 * factor).astype(np.float32))
    if texture.encoding == "sRGB":
        ignored.append(f"texture '{texture.name}' in a mix of shaders: its share "
                       f"{factor:.3g} of the colour not applied (an sRGB image)")
        return texture
    pixels = texture.pixels.copy()
    pixels[..., :3] *= factor
    return replace(texture, pixels=pixels)


class _MaterialReader:
    """Reduces Blender materials to kernel `Material`s, recording what it could not model."""

    def __init__(self, request: SnapshotRequest):
        self.request = request
        self.images: dict[str, np.ndarray | None] = {}

    def read(self, mat) -> Material:
        if mat is None:
            return DEFAULT_MATERIAL
        if not self.request.materials:
            return Material(name=mat.name, specular=0.0)
        tree = _node_tree(mat)
        if tree is None:
            return Material(
                name=mat.name,
                base_color=np.array(mat.diffuse_color[:3], np.float32),
                metallic=float(mat.metallic),
                roughness=float(mat.roughness),
                ignored=("no shader nodes: viewport display colour used",),
            )
        ignored: list[str] = []
        output = _active_output(tree, "OUTPUT_MATERIAL")
        if output is None:
            return Material(name=mat.name, ignored=("no Material Output node",))
        if output.inputs["Volume"].is_linked:
            ignored.append("volume shader")
        if output.inputs["Displacement"].is_linked:
            ignored.append("displacement (bump mapping reads Bump/Normal Map nodes only)")
        node, _ = _follow(output.inputs["Surface"])
        if node is None:
            return Material(name=mat.name, base_color=np.zeros(3, np.float32),
                            ignored=tuple(ignored + ["no surface shader: black"]))
        return self._shader(mat.name, node, ignored)

    def _shader(self, name: str, node, ignored: list, depth: int = 0) -> Material:
        """The kernel `Material` of the shader node `node` (a BSDF, an emission, or a Mix or
        Add Shader of such, `_mixed`)."""
        kind = node.type
        if kind in ("MIX_SHADER", "ADD_SHADER") and depth < MAX_SHADER_MIX_DEPTH:
            return self._mixed(name, node, ignored, depth)
        if kind == "BSDF_PRINCIPLED":
            return self._principled(name, node, ignored)
        if kind == "BSDF_DIFFUSE":
            color, tex = self._color(node.inputs["Color"], ignored)
            return Material(name=name, base_color=color, base_color_texture=tex, specular=0.0,
                            ignored=tuple(ignored))
        if kind == "EMISSION":
            color, _ = self._color(node.inputs["Color"], ignored, textures=False)
            strength = self._value(node.inputs["Strength"], ignored)
            return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                            emission=(color * strength).astype(np.float32), ignored=tuple(ignored))
        if kind == "BSDF_GLASS":
            color, _ = self._color(node.inputs["Color"], ignored, textures=False)
            return Material(name=name, base_color=color, transmission=1.0,
                            roughness=self._value(node.inputs["Roughness"], ignored),
                            ior=self._value(node.inputs["IOR"], ignored), ignored=tuple(ignored))
        if kind in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC"):
            color, tex = self._color(node.inputs["Color"], ignored)
            return Material(name=name, base_color=color, base_color_texture=tex, metallic=1.0,
                            roughness=self._value(node.inputs["Roughness"], ignored),
                            ignored=tuple(ignored))
        ignored.append(f"surface shader '{node.bl_idname}' is not modelled: grey diffuse used")
        return Material(name=name, ignored=tuple(ignored))

    def _mixed(self, name: str, node, ignored: list, depth: int) -> Material:
        """A Mix Shader (weights 1 - Fac and Fac; a Fac fed by a node takes its default, noted)
        or an Add Shader (weights 1 and 1) of two shaders, as one `Material` (`mix_materials`);
        an unlinked shader input is a black surface (no closure: Cycles absorbs there)."""
        add = node.type == "ADD_SHADER"
        sockets = [s for s in node.inputs if s.type == "SHADER"]
        if add:
            weights = [1.0, 1.0]
        else:
            fac = min(max(self._value(node.inputs["Fac"], ignored), 0.0), 1.0)
            weights = [1.0 - fac, fac]
        parts = []
        for socket, weight in zip(sockets, weights, strict=True):
            source, _ = _follow(socket)
            if source is None or weight == 0.0:
                continue
            parts.append((weight, self._shader(name, source, ignored, depth + 1)))
        return mix_materials(name, parts, ignored)

    def _principled(self, name, node, ignored) -> Material:
        inputs = node.inputs
        color, tex = self._color(inputs["Base Color"], ignored)
        emission, _ = self._color(inputs["Emission Color"], ignored, textures=False)
        strength = self._value(inputs["Emission Strength"], ignored)
        for unmodelled in ("Subsurface Weight", "Coat Weight", "Sheen Weight"):
            if unmodelled in inputs and (
                inputs[unmodelled].is_linked or inputs[unmodelled].default_value > 0
            ):
                ignored.append(f"{unmodelled} is not modelled")
        if "Alpha" in inputs and (inputs["Alpha"].is_linked or inputs["Alpha"].default_value < 1):
            ignored.append("alpha is not modelled: opaque")
        normal_tex, height_tex, strength_b, distance_b = self._normal(inputs["Normal"], ignored)
        return Material(
            name=name,
            base_color=color,
            base_color_texture=tex,
            metallic=self._value(inputs["Metallic"], ignored),
            roughness=self._value(inputs["Roughness"], ignored),
            ior=self._value(inputs["IOR"], ignored),
            transmission=self._value(inputs["Transmission Weight"], ignored),
            specular=self._value(inputs["Specular IOR Level"], ignored),
            emission=(emission * strength).astype(np.float32),
            normal_texture=normal_tex,
            height_texture=height_tex,
            bump_strength=strength_b,
            bump_distance=distance_b,
            ignored=tuple(ignored),
        )

    def _value(self, socket, ignored) -> float:
        node, _ = _follow(socket)
        if node is not None:
            if node.type == "VALUE":
                return float(node.outputs[0].default_value)
            ignored.append(f"'{socket.name}' driven by a '{node.bl_idname}' node: its default used")
        return float(socket.default_value)

    def _color(self, socket, ignored, textures=True) -> tuple[np.ndarray, Texture | None]:
        default = np.array(socket.default_value[:3], np.float32)
        node, _ = _follow(socket)
        if node is None:
            return default, None
        if node.type == "RGB":
            return np.array(node.outputs[0].default_value[:3], np.float32), None
        if textures and self.request.textures:
            tex = self._texture(node, ignored, what=socket.name)
            if tex is not None:
                return default, tex
        elif node.type in ("TEX_IMAGE", "TEX_CHECKER"):
            return default, None  # not requested: this bake does not read textures
        ignored.append(f"'{socket.name}' driven by a '{node.bl_idname}' node: its default used")
        return default, None

    def _uv_layer(self, node, ignored, what, generated: bool
                  ) -> tuple[bool, str | None, str]:
        """(ok, uv layer name or None for the active render layer, "UV" or "GENERATED") of a
        texture node's Vector: unlinked, an Image Texture reads UVs and a Checker the Generated
        coordinates. `generated`: whether this use can read Generated coordinates (base colours
        can; bump and normal maps, whose tangent frames follow the UVs, read UVs instead)."""
        vec_node, vec_socket = _follow(node.inputs["Vector"])
        if vec_node is None and node.type != "TEX_CHECKER":
            return True, None, "UV"
        if vec_node is None or (vec_node.type == "TEX_COORD" and vec_socket.name == "Generated"):
            if generated:
                return True, None, "GENERATED"
            ignored.append(f"{what}: a texture on Generated coordinates is read on UVs")
            return True, None, "UV"
        if vec_node.type == "UVMAP":
            return True, (vec_node.uv_map or None), "UV"
        if vec_node.type == "TEX_COORD" and vec_socket.name == "UV":
            return True, None, "UV"
        ignored.append(f"{what}: texture coordinates from '{vec_node.bl_idname}' are not modelled")
        return False, None, "UV"

    def _texture(self, node, ignored, what, generated: bool = True) -> Texture | None:
        if node.type == "TEX_IMAGE":
            ok, uv_layer, coordinates = self._uv_layer(node, ignored, what, generated)
            image = node.image
            if image is None or not ok:
                return None
            pixels = self.images.get(image.name)
            if image.name not in self.images:
                pixels = self.images[image.name] = image_pixels(image, decode=False)
            if pixels is None:
                ignored.append(f"{what}: image '{image.name}' has no pixels (missing file?)")
                return None
            return Texture(
                kind="IMAGE",
                name=image.name,
                pixels=pixels,
                extension=node.extension if node.extension != "MIRROR" else "MIRROR",
                interpolation="CLOSEST" if node.interpolation == "Closest" else "LINEAR",
                uv_layer=uv_layer,
                coordinates=coordinates,
                encoding="sRGB" if stored_srgb(image) else "linear",
            )
        if node.type == "TEX_CHECKER":
            ok, uv_layer, coordinates = self._uv_layer(node, ignored, what, generated)
            linked = [s.name for s in node.inputs if s.name != "Vector" and s.is_linked]
            if not ok or linked:
                if linked:
                    ignored.append(f"{what}: checker inputs {linked} are linked: not modelled")
                return None
            return Texture(
                kind="CHECKER",
                name=node.name,
                color1=np.array(node.inputs["Color1"].default_value[:3], np.float32),
                color2=np.array(node.inputs["Color2"].default_value[:3], np.float32),
                scale=float(node.inputs["Scale"].default_value),
                uv_layer=uv_layer,
                coordinates=coordinates,
            )
        return None

    def _normal(self, socket, ignored):
        node, _ = _follow(socket)
        if node is None:
            return None, None, 1.0, 1.0
        if node.type == "NORMAL_MAP":
            if node.space != "TANGENT":
                ignored.append(f"normal map in {node.space} space is not modelled")
                return None, None, 1.0, 1.0
            tex_node, _ = _follow(node.inputs["Color"])
            tex = self._texture(tex_node, ignored, "Normal Map", False) if tex_node else None
            strength = self._value(node.inputs["Strength"], ignored)
            return tex, None, strength, 1.0
        if node.type == "BUMP":
            tex_node, _ = _follow(node.inputs["Height"])
            tex = self._texture(tex_node, ignored, "Bump height", False) if tex_node else None
            if tex_node is not None and tex is None:
                ignored.append(f"bump height from '{tex_node.bl_idname}' is not modelled")
            if node.inputs["Normal"].is_linked:
                ignored.append("a Bump node's Normal input (chained bumps) is not modelled")
            distance = self._value(node.inputs["Distance"], ignored)
            # Invert: the height pushes the surface inwards, the same as a negated distance.
            return (None, tex, self._value(node.inputs["Strength"], ignored),
                    -distance if node.invert else distance)
        ignored.append(f"normal input from '{node.bl_idname}' is not modelled")
        return None, None, 1.0, 1.0


# --- lights, camera, world ------------------------------------------------------------------------


def light_power(light) -> tuple[float, np.ndarray]:
    """(power or strength scalar, linear colour (3,)) of a Blender light, exposure included."""
    power = float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))
    color = np.array(light.color[:3], np.float64)
    if getattr(light, "use_temperature", False):
        color = color * np.array(light.temperature_color[:3], np.float64)
    return power, color


def _light_nodes_are_default(tree) -> bool:
    """True if a light's node tree only passes an untouched Emission (colour 1, strength 1) out."""
    if tree is None:
        return True
    output = _active_output(tree, "OUTPUT_LIGHT")
    if output is None:
        return True
    node, _ = _follow(output.inputs["Surface"])
    if node is None:
        return True
    if node.type != "EMISSION" or any(s.is_linked for s in node.inputs):
        return False
    color = tuple(node.inputs["Color"].default_value[:3])
    return np.allclose(color, 1.0) and np.isclose(node.inputs["Strength"].default_value, 1.0)


def read_light(name: str, light, matrix: np.ndarray) -> tuple[Light, list[str]]:
    """A Blender light datablock placed by `matrix` (4, 4) as a kernel `Light`, plus what was ignored."""
    ignored: list[str] = []
    rot = matrix[:3, :3]
    scale = np.linalg.norm(rot, axis=0)
    position = matrix[:3, 3].copy()
    axis_x, axis_y = _unit(rot[:, 0]), _unit(rot[:, 1])
    direction = _unit(-rot[:, 2])
    power, color = light_power(light)
    common = dict(name=name, position=position, direction=direction, axis_x=axis_x, axis_y=axis_y,
                  cast_shadow=bool(getattr(light, "use_shadow", True)))
    if not _light_nodes_are_default(_node_tree(light)):
        ignored.append(f"light '{name}': light nodes are not modelled")
    kind = light.type
    if kind in ("POINT", "SPOT"):
        extra = {}
        if kind == "SPOT":
            extra = dict(spot_size=float(light.spot_size), spot_blend=float(light.spot_blend),
                         spot_square=bool(light.use_square))
            if not np.allclose(scale[0], scale[1]):
                ignored.append(f"light '{name}': non-uniform spot scale (elliptic cone) not modelled")
        return Light(kind=kind, intensity=light_units.point_intensity(power, color),
                     radius=float(light.shadow_soft_size), **extra, **common), ignored
    if kind == "SUN":
        return Light(kind="SUN", irradiance=light_units.sun_irradiance(power, color),
                     angle=float(light.angle), **common), ignored
    if kind == "AREA":
        shape = light.shape
        size_x = float(light.size) * scale[0]
        size_y = (float(light.size_y) if shape in ("RECTANGLE", "ELLIPSE") else float(light.size))
        size_y *= scale[1]
        area = light_units.area_of_shape(shape, size_x, size_y)
        radiance = light_units.area_radiance(power, color, area, getattr(light, "normalize", True))
        if getattr(light, "spread", np.pi) < np.pi - 1e-6:
            ignored.append(f"light '{name}': area light spread is not modelled (full hemisphere)")
        return Light(kind="AREA", radiance=radiance, shape=shape, size_x=size_x, size_y=size_y,
                     **common), ignored
    raise ValueError(f"light '{name}' has unknown type {kind}")


def render_resolution(scene) -> tuple[int, int]:
    """The render size in pixels, percentage applied as Blender does (integer truncation)."""
    r = scene.render
    pct = r.resolution_percentage
    return max(1, r.resolution_x * pct // 100), max(1, r.resolution_y * pct // 100)


def read_camera(scene, cam_obj, resolution: tuple[int, int] | None = None) -> Camera:
    """The scene camera as a kernel `Camera`; raises ValueError for panoramic cameras."""
    cam = cam_obj.data
    if cam.type not in ("PERSP", "ORTHO"):
        raise ValueError(f"camera '{cam_obj.name}' is {cam.type}: only perspective and "
                         "orthographic cameras are modelled")
    resolution = resolution or render_resolution(scene)
    r = scene.render
    plane_min, plane_max = image_plane(
        cam.type,
        resolution,
        lens_mm=cam.lens,
        sensor_width_mm=cam.sensor_width,
        sensor_height_mm=cam.sensor_height,
        sensor_fit=cam.sensor_fit,
        ortho_scale=cam.ortho_scale,
        shift=(cam.shift_x, cam.shift_y),
        pixel_aspect=(r.pixel_aspect_x, r.pixel_aspect_y),
    )
    matrix = _matrix(cam_obj.matrix_world)
    for k in range(3):  # rigid: the camera's scale does not change its view
        matrix[:3, k] = _unit(matrix[:3, k])
    return Camera(kind=cam.type, matrix_world=matrix, plane_min=plane_min, plane_max=plane_max,
                  resolution=tuple(resolution), clip_start=float(cam.clip_start),
                  clip_end=float(cam.clip_end))


def read_world(scene, mapped=None) -> tuple[np.ndarray, list[str]]:
    """The uniform background radiance (3,) of the world (an Environment Texture's mean over the
    sphere), and what was ignored. mapped: the world's map as `read_world_texture` read it, when
    the caller has it (its mean is taken from those pixels instead of reading the image again)."""
    world = scene.world
    if world is None:
        return np.zeros(3, np.float32), []
    tree = _node_tree(world)
    if tree is None:
        return np.array(world.color[:3], np.float32), []
    unread = _world_render_reason(scene)
    if unread is not None and mapped is not None:  # rendered by `read_world_texture`
        width, height = mapped.pixels.shape[1], mapped.pixels.shape[0]
        note = f"world: {unread}, rendered by Cycles into a {width} x {height} map"
        if _has_light_path(world):
            note += (" as diffuse rays see it through its Light Path node (the map lights the "
                     "surfaces; the camera's view of the world shows it too)")
        return _equirect_mean(mapped.pixels), [note]
    output = _active_output(tree, "OUTPUT_WORLD")
    if output is None:
        return np.zeros(3, np.float32), ["world has no World Output node: black"]
    node, _ = _follow(output.inputs["Surface"])
    if node is None:
        return np.zeros(3, np.float32), []
    if node.type != "BACKGROUND":
        return np.zeros(3, np.float32), [f"world shader '{node.bl_idname}' is not modelled: black"]
    ignored = []
    color = np.array(node.inputs["Color"].default_value[:3], np.float32)
    color_node, _ = _follow(node.inputs["Color"])
    strength = float(node.inputs["Strength"].default_value)
    if mapped is not None:  # strength applied already
        return _equirect_mean(mapped.pixels), ignored
    mean = environment_mean(color_node) if color_node is not None else None
    if mean is not None:
        color = mean
        if color_node.projection != "EQUIRECTANGULAR":
            ignored.append(f"world colour from the mirror-ball Environment Texture "
                           f"'{color_node.image.name}' taken as its mean "
                           f"{np.round(mean, 4).tolist()}: the kernels see a uniform world")
        elif color_node.inputs["Vector"].is_linked and world_mapping(color_node) is None:
            ignored.append(f"world: the Environment Texture '{color_node.image.name}' is read "
                           "along world directions; what feeds its Vector (other than a Mapping "
                           "of Generated coordinates) is not modelled")
    elif color_node is not None:
        ignored.append(f"world colour from '{color_node.bl_idname}' is not modelled: the "
                       "socket's own colour used")
    return color * strength, ignored


def _world_surface(scene):
    """The shader node feeding the scene's world output (None: no world, no nodes, no output or
    nothing linked to it)."""
    world = scene.world
    tree = _node_tree(world) if world is not None else None
    output = _active_output(tree, "OUTPUT_WORLD") if tree is not None else None
    return _follow(output.inputs["Surface"])[0] if output is not None else None


def _world_map_nodes(scene):
    """(Background node, equirectangular Environment Texture node feeding its colour) of the
    scene's world, or None where the world is not that."""
    node = _world_surface(scene)
    if node is None or node.type != "BACKGROUND":
        return None
    env = _follow(node.inputs["Color"])[0]
    if env is None or env.type != "TEX_ENVIRONMENT" or env.image is None \
            or env.projection != "EQUIRECTANGULAR":
        return None
    return node, env


def _world_env_mapping(scene) -> np.ndarray | None:
    """`world_mapping` of the world's map, None where it is the identity or not modelled (then
    the map is read along the world direction) or there is no map."""
    nodes = _world_map_nodes(scene)
    mapping = world_mapping(nodes[1]) if nodes is not None else None
    identity = np.hstack([np.eye(3), np.zeros((3, 1))])
    return None if mapping is None or np.allclose(mapping, identity) else mapping


def read_world_texture(scene, render: bool = True):
    """The world's equirectangular radiance map, a kernel `Texture` (linear RGB times the
    Background's strength), when an Environment Texture of that projection feeds the world's
    Background colour (through nothing or a modelled Mapping, `world_mapping`). A world shader
    the bridge cannot read so (`_world_render_reason`: a Sky Texture, a procedural texture, a
    mix of shaders, a mirror-ball map) is rendered into a map by Cycles when `render`
    (`cycles_reference.render_world_map`). Else None (the kernels use `read_world`'s uniform
    colour)."""
    nodes = _world_map_nodes(scene)
    if nodes is not None and world_mapping(nodes[1]) is not None \
            and (pixels := image_pixels(nodes[1].image)) is not None:
        node, env = nodes
        pixels[..., :3] *= float(node.inputs["Strength"].default_value)
        return Texture(kind="IMAGE", name=env.image.name, pixels=pixels, extension="REPEAT",
                       interpolation="CLOSEST" if env.interpolation == "Closest" else "LINEAR")
    if not render or _world_render_reason(scene) is None:
        return None
    from .cycles_reference import render_world_map  # it imports this module

    try:
        rgb, _ = render_world_map(scene.world, lighting=_has_light_path(scene.world))
    except RuntimeError:  # no Cycles in this build: `read_world` notes the shader as not read
        return None
    pixels = np.concatenate([rgb, np.ones(rgb.shape[:2] + (1,), np.float32)], axis=-1)
    return Texture(kind="IMAGE", name=f"{scene.world.name} (rendered)", pixels=pixels,
                   extension="REPEAT", interpolation="LINEAR")


def _has_light_path(world) -> bool:
    """Whether the world's own node tree holds a Light Path node."""
    tree = _node_tree(world)
    return tree is not None and any(n.type == "LIGHT_PATH" for n in tree.nodes)


def _world_render_reason(scene) -> str | None:
    """What of the world's shader the bridge cannot read itself (a few words), or None where it
    reads all of it: no world, a world colour, nothing linked to the output, or a Background of
    an unlinked strength whose colour is constant or an equirectangular Environment Texture with
    an image, read along the world direction or through a Mapping node `world_mapping` models."""
    node = _world_surface(scene)
    if node is None:
        return None
    if node.type != "BACKGROUND":
        return f"the shader '{node.bl_idname}'"
    if node.inputs["Strength"].is_linked:
        return "a strength fed by a node"
    color = _follow(node.inputs["Color"])[0]
    if color is None:
        return None
    if color.type != "TEX_ENVIRONMENT":
        return f"a colour from '{color.bl_idname}'"
    if color.image is None:
        return "an Environment Texture without an image"
    if color.projection != "EQUIRECTANGULAR":
        return f"the mirror-ball Environment Texture '{color.image.name}'"
    if world_mapping(color) is None:
        return f"the Environment Texture '{color.image.name}' read along a vector not modelled"
    return None


def world_mapping(env) -> np.ndarray | None:
    """(3, 4) affine map [A | t] that a Mapping node between the world's Generated coordinates
    (the view direction d) and the Environment Texture `env` applies, the map read along
    normalize(A d + t) as Cycles does; the identity when nothing feeds the texture's Vector, None
    when something else does. Cycles' Mapping: Point R (S o d) + T, Vector R (S o d), Texture the
    inverse of Point, R = Rz Ry Rx of the Euler angles."""
    identity = np.hstack([np.eye(3), np.zeros((3, 1))])
    mapping, _ = _follow(env.inputs["Vector"])
    if mapping is None:
        return identity
    if mapping.type != "MAPPING" or mapping.vector_type not in ("POINT", "VECTOR", "TEXTURE"):
        return None
    source, socket = _follow(mapping.inputs["Vector"])
    if source is None or source.type != "TEX_COORD" or socket.name != "Generated":
        return None

    def value(name):
        sock = mapping.inputs.get(name)
        return np.array(sock.default_value[:3], np.float64) if sock is not None else None

    x, y, z = value("Rotation")
    cx, sx, cy, sy, cz, sz = np.cos(x), np.sin(x), np.cos(y), np.sin(y), np.cos(z), np.sin(z)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    linear = rz @ ry @ rx @ np.diag(value("Scale"))
    offset = value("Location") if mapping.vector_type == "POINT" else np.zeros(3)
    if mapping.vector_type == "TEXTURE":  # the inverse of Point: S^-1 o R^-1 (d - T)
        inverse = np.linalg.inv(linear)
        linear, offset = inverse, -inverse @ value("Location")
    return np.hstack([linear, offset[:, None]])


def environment_mean(node) -> np.ndarray | None:
    """(3,) float32: the mean radiance over all directions of an Environment Texture node's
    image (linear), or None for any other node or one without pixels. An equirectangular row at
    latitude phi covers a solid angle in proportion to cos(phi), so rows are weighted by it (a
    plain pixel mean would count the poles' few steradians as much as the equator's); a mirror
    ball's pixels are averaged inside its disc."""
    if node is None or node.type != "TEX_ENVIRONMENT" or node.image is None:
        return None
    pixels = image_pixels(node.image)
    if pixels is None:
        return None
    if node.projection == "EQUIRECTANGULAR":
        return _equirect_mean(pixels)
    height, width = pixels.shape[:2]  # MIRROR_BALL: the disc inscribed in the image
    y, x = np.mgrid[0:height, 0:width]
    disc = (2.0 * (x + 0.5) / width - 1.0) ** 2 + (2.0 * (y + 0.5) / height - 1.0) ** 2 <= 1.0
    return pixels[disc][:, :3].astype(np.float64).mean(axis=0).astype(np.float32)


def _equirect_mean(pixels: np.ndarray) -> np.ndarray:
    """(3,) float32 mean over the sphere of an equirectangular image (H, W, >= 3), row 0 at the
    top: each row weighted by cos(latitude), its share of the sphere."""
    height = pixels.shape[0]
    latitude = (0.5 - (np.arange(height) + 0.5) / height) * np.pi
    rows = pixels[..., :3].astype(np.float64).mean(axis=1)  # (H, 3)
    return (np.cos(latitude) @ rows / np.cos(latitude).sum()).astype(np.float32)


# --- the snapshot ---------------------------------------------------------------------------------


def snapshot(context=None, request: SnapshotRequest = SnapshotRequest(),
             resolution: tuple[int, int] | None = None) -> Scene:
    """Read the evaluated scene of `context` (default: bpy.context) into a kernel `Scene`."""
    context = context or bpy.context
    scene = context.scene
    depsgraph = context.evaluated_depsgraph_get()
    ignored: list[str] = []
    chunks: list[_MeshChunk] = []
    lights: list[Light] = []
    instance_counts: dict[str, int] = {}

    for original in scene.objects:
        if original.hide_viewport and not original.hide_render:
            ignored.append(f"object '{original.name}': disabled in viewports, so not evaluated")

    for inst in depsgraph.object_instances:
        obj = inst.object
        source = obj.original
        holder = inst.parent.original if inst.is_instance and inst.parent else source
        if source.hide_render or holder.hide_render:
            continue
        # The depsgraph lists a curve, surface, text or metaball object twice: as itself and as
        # a MESH instance of its evaluated geometry parented to itself (4.5 and 5.2; the same
        # triangles, which Cycles renders once). Only MESH entries are read, and that instance
        # stands for the object itself.
        if obj.type not in ("MESH", "LIGHT"):
            continue
        is_instance = inst.is_instance and not (holder == source and source.type != "MESH")
        matrix = _matrix(inst.matrix_world)
        base = source.name if not is_instance else f"{holder.name}/{source.name}"
        k = instance_counts.get(base, 0)
        instance_counts[base] = k + 1
        name = base if k == 0 else f"{base}#{k}"
        if obj.type == "LIGHT":
            if request.lights:
                light, why = read_light(name, obj.data, matrix)
                lights.append(light)
                ignored.extend(why)
            continue
        if request.objects is not None and source.name not in request.objects:
            continue
        slot_materials = [slot.material for slot in obj.material_slots]
        original_mesh = source.data if source.type == "MESH" and not is_instance else None
        chunks.append(_mesh_chunk(name, source.name, is_instance, obj.data, matrix, request,
                                  original_mesh, slot_materials,
                                  source.data if source.type == "MESH" else None))

    # Materials: one table for the whole scene, in first-seen order; index 0 is the default surface.
    reader = _MaterialReader(request)
    materials: list[Material] = [DEFAULT_MATERIAL]
    material_index: dict[str, int] = {}
    for chunk in chunks:
        table = np.zeros(max(1, len(chunk.slot_materials)), np.int32)
        for slot, mat in enumerate(chunk.slot_materials):
            if mat is None:
                continue
            key = mat.name_full
            if key not in material_index:
                material_index[key] = len(materials)
                materials.append(reader.read(mat))
            table[slot] = material_index[key]
        # Out-of-range slots render with the default surface in Cycles; do the same.
        in_range = chunk.slot_ids < len(chunk.slot_materials)
        chunk.slot_ids = np.where(in_range, table[np.minimum(chunk.slot_ids, table.size - 1)], 0)
    for mat in materials:
        ignored.extend(f"material '{mat.name}': {why}" for why in mat.ignored)

    camera = None
    if request.camera:
        if scene.camera is None:
            ignored.append("the scene has no camera")
        else:
            camera = read_camera(scene, scene.camera, resolution)
    texture = read_world_texture(scene, render=request.world_render)
    world, why = read_world(scene, texture)
    ignored.extend(why)
    return replace(_assemble(chunks, materials, lights, camera, world, request, ignored),
                   world_texture=texture,
                   world_transform=None if texture is None else _world_env_mapping(scene))


def _assemble(chunks, materials, lights, camera, world, request, ignored) -> Scene:
    counts = [c.triangles.shape[0] for c in chunks]
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(int)
    objects = []
    for k, chunk in enumerate(chunks):
        if chunk.uv is None and request.uv:
            ignored.append(f"object '{chunk.name}' has no UV layer: textures read UV (0, 0)")
        objects.append(ObjectInfo(
            name=chunk.name, source_name=chunk.source_name, tri_start=int(starts[k]),
            tri_count=counts[k], has_uv=chunk.uv is not None,
            has_lightmap_uv=chunk.lightmap_uv is not None,
            topology_matches_original=chunk.topology_matches_original,
            is_instance=chunk.is_instance))

    def stack(attr, shape, dtype):
        parts = [getattr(c, attr) if getattr(c, attr) is not None else np.zeros((n,) + shape, dtype)
                 for c, n in zip(chunks, counts, strict=True)]
        return np.concatenate(parts).astype(dtype) if parts else np.zeros((0,) + shape, dtype)

    return Scene(
        triangles=stack("triangles", (3, 3), np.float32),
        normals=stack("normals", (3, 3), np.float32),
        uv=stack("uv", (3, 2), np.float32),
        lightmap_uv=stack("lightmap_uv", (3, 2), np.float32) if request.lightmap_uv else None,
        generated=stack("generated", (3, 3), np.float32) if request.uv else None,
        material_ids=stack("slot_ids", (), np.int32),
        object_ids=np.repeat(np.arange(len(chunks), dtype=np.int32), counts),
        corner_loops=stack("corner_loops", (3,), np.int32),
        corner_verts=stack("corner_verts", (3,), np.int32),
        objects=tuple(objects),
        materials=tuple(materials),
        lights=tuple(lights),
        camera=camera,
        world_color=np.asarray(world, np.float32),
        ignored=tuple(ignored),
    )


# --- write-back -----------------------------------------------------------------------------------


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
    image.pixels.foreach_set(_flip_rows(rgba).ravel())
    image.update()
    return image


def save_image_exr(image, pixels: np.ndarray, path: str) -> None:
    """Write `pixels` as OpenEXR at `path` (OpenEXR package) and point `image` at that file."""
    from ..kernels.measure.exr import write_exr

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


def write_uv_layer(mesh, name: str, loop_uv: np.ndarray):
    """Create UV layer `name` on `mesh` with per-loop UVs (L, 2); existing layers stay untouched.

    Raises ValueError if a layer of that name exists (never overwritten) or the mesh has no room.
    The active and active-render layers are kept as they were.
    """
    if mesh.uv_layers.get(name) is not None:
        raise ValueError(f"mesh '{mesh.name}' already has a UV layer '{name}'")
    active = mesh.uv_layers.active.name if mesh.uv_layers.active else None
    render = next((lay.name for lay in mesh.uv_layers if lay.active_render), None)
    layer = mesh.uv_layers.new(name=name, do_init=False)
    if layer is None:
        raise ValueError(f"mesh '{mesh.name}' cannot take another UV layer (Blender allows 8)")
    layer.uv.foreach_set("vector", np.ascontiguousarray(loop_uv, np.float32).ravel())
    if active is not None:
        mesh.uv_layers.active = mesh.uv_layers[active]
    if render is not None:
        mesh.uv_layers[render].active_render = True
    mesh.update()
    return mesh.uv_layers[name]


def lightmap_loop_uv(obj, settings) -> tuple[np.ndarray, dict]:
    """Unwrap `obj`'s original mesh with xatlas: per-loop lightmap UVs (L, 2) and a summary.

    Texel density follows world-space size (the object's scale applied), so charts of one object
    get the same density. Each polygon is kept in one chart (`unwrap`'s `polygons`); one whose
    triangles still disagree on a loop's UV (none should) is counted in the summary
    (`split_polygons`), the last triangle's UV winning.
    """
    from ..kernels.bake.lightmap_uv import unwrap

    mesh = obj.data
    corner_verts, corner_loops, polys, _ = mesh_triangles(mesh)
    matrix = _matrix(obj.matrix_world)
    world = mesh_positions(mesh).astype(np.float64) @ matrix[:3, :3].T
    result = unwrap(world, corner_verts, settings, polys)
    loop_uv = np.zeros((len(mesh.loops), 2), np.float32)
    flat_loops = corner_loops.ravel()
    flat_uv = result.corner_uv.reshape(-1, 2)
    loop_uv[flat_loops] = flat_uv
    # A loop written by several triangles must have received the same UV from each.
    disagree = np.any(np.abs(loop_uv[flat_loops] - flat_uv) > 0, axis=1).reshape(-1, 3).any(1)
    summary = {"charts": result.chart_count, "utilization": result.utilization,
               "split_polygons": int(np.unique(polys[disagree]).size)}
    return loop_uv, summary


def ensure_lightmap_uv(obj, name: str, settings) -> tuple[bool, dict]:
    """Give `obj`'s mesh a lightmap UV layer `name` unless it has one. Returns (created, summary)."""
    if obj.type != "MESH":
        raise ValueError(f"object '{obj.name}' is a {obj.type}, not a mesh: no lightmap UVs")
    if obj.data.uv_layers.get(name) is not None:
        return False, {}
    loop_uv, summary = lightmap_loop_uv(obj, settings)
    write_uv_layer(obj.data, name, loop_uv)
    return True, summary


# --- material wiring ------------------------------------------------------------------------------

WIRING_TAG = "classic_bake"  # custom property on every node the wiring adds
_ORIGINAL_OUTPUT = "classic_bake_original_output"  # material property: the output to restore


def _material_slots_for_display(obj, single_user: bool):
    """The materials of `obj` to wire, creating one where a slot is empty or there are none.

    With `single_user` (a per-object lightmap image) a material shared with other objects is
    replaced in this object's slot by a copy, so the other objects keep showing their own bake.
    """
    if len(obj.material_slots) == 0:
        obj.data.materials.append(bpy.data.materials.new(f"{obj.name} (baked)"))
    materials = []
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None:
            mat = slot.material = bpy.data.materials.new(f"{obj.name} (baked)")
        elif single_user and mat.users > 1:
            mat = slot.material = mat.copy()
        if bpy.app.version < (5, 0, 0):
            mat.use_nodes = True
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
    materials = _material_slots_for_display(obj, single_user=image is not None)
    for mat in materials:
        unwire_baked_display(mat)
        tree = mat.node_tree
        current = _active_output(tree, "OUTPUT_MATERIAL")
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
