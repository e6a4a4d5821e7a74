"""Blender materials reduced to kernel `Material`s: the node-tree reader (Principled, Diffuse,
Glossy, Glass, Refraction, Emission, Transparent, Translucent and Holdout shaders, Mix and Add
Shaders of them (by a constant, a Fresnel or a mask), node groups holding any of these, image
and checker textures, normal maps, bumps, a Displacement node's bump) and a record of everything
it does not model (`Material.ignored`). What drives a socket is read through `socket_values.py`
(node chains between a texture and the socket); base colour, emission, metallic, roughness and
alpha may come from textures.

Node groups are walked as Cycles flattens them (`nodes.follow_through`): the reader keeps the
Group nodes it entered to reach the node it reads (`MaterialReader._groups`), so a socket inside
a group that reads the group's input reads what the Group node's input is given outside.

Textures keep their encoding: an sRGB byte image is decoded per look-up after interpolation, as
Cycles does (`Texture.encoding`).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, replace

import bpy
import numpy as np

from ...kernels.geometry.scene import Material, Texture
from ...kernels.shading.optics import fresnel_dielectric
from ...kernels.shading.specular_layer import layer_f0
from ...kernels.shading.textures import MISSING_TEXEL, texture_mean
from .images import image_pixels, stored_srgb, tile_pixels
from .nodes import active_output, follow_through, node_tree
from .request import SnapshotRequest
from .socket_fallback import BakeTarget, SocketFallback
from .socket_values import SocketReader, Value, pointwise

DEFAULT_MATERIAL_NAME = "(default surface)"
# What Cycles shades faces without a material with (measured: a plane under a sun renders to the
# same float as with a material of that surface): Blender 5 a Principled BSDF of its node's
# defaults (base 0.8, roughness 0.5, IOR 1.5, Specular IOR Level 0.5: a specular layer), 4.5 a
# 0.8 grey Diffuse BSDF.
DEFAULT_MATERIAL = (Material(name=DEFAULT_MATERIAL_NAME) if bpy.app.version >= (5, 0, 0)
                    else Material(name=DEFAULT_MATERIAL_NAME, specular=0.0))


# Mix and Add Shaders nested deeper than this are not followed (a shader tree is finite, but a
# node group could repeat one mix many times; eight levels hold 256 leaves).
MAX_SHADER_MIX_DEPTH = 8
# Cycles evaluates volume closures only in a material's Volume slot: one in the Surface slot adds
# nothing (measured: a Principled BSDF plus a Volume Absorption renders as the BSDF alone).
VOLUME_SHADER_PREFIX = "ShaderNodeVolume"
# Mix weights this close to 1 (or a transparency this close to 1) count as 1: a Fac of 1 picks
# one shader whole, whatever float rounding left of 1 - Fac.
MIX_WEIGHT_EPS = 1e-9
# `facing_ior`: midpoints of the cosine quadrature (the Fresnel curve is smooth: 1e-5 relative),
# and the largest IOR the fit returns (Fresnel mean 0.92: Facing curves beyond read as mirrors).
FACING_FIT_STEPS = 2048
FACING_FIT_MAX_IOR = 100.0
# The Light Path outputs a Mix Shader may choose a Transparent BSDF by: which input the
# Transparent BSDF is in (Fac 0 picks the first) and the `Material` flag the other shader takes:
# seen by camera rays alone (glTF's unlit materials import so), or passed by shadow rays
# (architectural glass is often made so).
LIGHT_PATH_MIXES = {"Is Camera Ray": (0, "camera_only"), "Is Shadow Ray": (1, "shadowless")}


@dataclass(frozen=True)
class Relief:
    """What feeds a shader's Normal (`Material`'s fields of the same names): a tangent-space
    normal map, a Bump node's height, or both (a Normal Map into a Bump node's Normal)."""

    normal_texture: Texture | None = None
    normal_strength: float = 1.0
    height_texture: Texture | None = None
    bump_strength: float = 1.0
    bump_distance: float = 1.0

    def fields(self) -> dict:
        """The `Material` fields of this relief."""
        return dict(normal_texture=self.normal_texture, normal_strength=self.normal_strength,
                    height_texture=self.height_texture, bump_strength=self.bump_strength,
                    bump_distance=self.bump_distance)


def _lobe_weighted_roughness(dielectric: Material, metal: Material):
    """The one roughness a point of metal share M (N, 3) takes for a masked mix of a dielectric
    and a metal of their own roughness, as a curve for `pointwise`: their roughness weighted by
    what each lobe reflects there, M x the metal's mean colour and (1 - M) x the dielectric
    layer's F0 (the kernels give a point one roughness for all its lobes; Cycles draws two).
    The metal's lobe outshines the layer's wherever it is a part of the point, as the constant
    mix's metal roughness has it (`mix_materials`), and the ends stay the parts' own."""
    shine_m = float(np.mean(metal.base_color))
    shine_d = layer_f0(dielectric.ior, dielectric.specular)

    def curve(share: np.ndarray) -> np.ndarray:
        m = np.clip(share, 0.0, 1.0)
        w_m, w_d = m * shine_m, (1.0 - m) * shine_d
        total = w_m + w_d
        linear = m * metal.roughness + (1.0 - m) * dielectric.roughness  # neither reflects
        return np.where(total > 0.0, (w_m * metal.roughness + w_d * dielectric.roughness)
                        / np.where(total > 0.0, total, 1.0), linear)
    return curve


def mix_materials(name: str, parts: list, ignored: list) -> Material:
    """One `Material` for the weighted sum of parts [(weight, Material)] (a Mix Shader's 1 - Fac
    and Fac, an Add Shader's 1 and 1), as a Principled BSDF splits a surface: part i reflects
    diffusely with weight w_i (1 - m_i)(1 - t_i), as a metal with w_i m_i, transmits with
    w_i (1 - m_i) t_i (m: metallic, t: transmission). The sum keeps the diffuse albedo exactly
    (sum of the diffuse weights times base colours: what radiosity and Cycles' DIFFUSE bake read),
    the emission exactly, and the three weights' shares; the metal parts keep their own tint
    (`Material.metal_color`: a white Glossy over a red Diffuse reflects white), the glass parts
    take the base colour, roughness and IOR their parts' weighted means, the specular layer the
    diffuse parts' weighted level, the sheens their weights' sum (`_sheen_fields`). A base
    texture is kept where its part is the only diffuse one (else the first textured part's,
    noted)."""
    weights = np.array([w for w, _ in parts], np.float64)
    sheen = _sheen_fields(parts, ignored)
    unlit = [m.camera_only for _, m in parts]
    if any(unlit) and not all(unlit):
        ignored.append("a mix of an unlit shader (seen by the camera alone) with others: the "
                       "mix read as seen by every ray")
    d_w = np.array([w * (1.0 - m.metallic) * (1.0 - m.transmission) for w, m in parts])
    m_w = np.array([w * m.metallic for w, m in parts])
    t_w = np.array([w * (1.0 - m.metallic) * m.transmission for w, m in parts])
    diffuse, metal, glass = float(d_w.sum()), float(m_w.sum()), float(t_w.sum())
    total = diffuse + metal + glass
    emission = sum((w * m.emission.astype(np.float64) for w, m in parts), np.zeros(3))
    emission_texture = _mixed_emission_texture(parts, emission, ignored)
    if emission_texture is not None:
        emission = np.zeros(3)
    if any(m.metallic_texture is not None or m.roughness_texture is not None for _, m in parts):
        ignored.append("a mix of shaders with metallic or roughness textures: their defaults used")
    if total <= 0.0:
        return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                        emission=emission.astype(np.float32), emission_texture=emission_texture,
                        camera_only=all(unlit), ignored=tuple(ignored), **sheen)

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
        metal_edge=next((m.metal_edge for w, m in parts if w * m.metallic > 0.0
                         and m.metal_edge is not None), None),
        specular_tint=next((m.specular_tint for w, m in parts if w * (1.0 - m.metallic) > 0.0
                            and m.specular_tint is not None), None),
        metallic=metal / total,
        roughness=float(mean([m.roughness for _, m in parts], m_w + t_w, weights)),
        ior=float(mean([m.ior for _, m in parts], t_w, weights)),
        transmission=glass / (glass + diffuse) if glass + diffuse > 0.0 else 0.0,
        specular=float(mean([m.specular for _, m in parts], d_w, weights)),
        emission=emission.astype(np.float32),
        emission_texture=emission_texture,
        translucent=sum((w * m.translucent.astype(np.float64) for w, m in parts),
                        np.zeros(3)).astype(np.float32),
        normal_texture=None if normal is None else normal.normal_texture,
        normal_strength=1.0 if normal is None else normal.normal_strength,
        height_texture=None if normal is None else normal.height_texture,
        bump_strength=1.0 if normal is None else normal.bump_strength,
        bump_distance=1.0 if normal is None else normal.bump_distance,
        camera_only=all(unlit), ignored=tuple(ignored), **sheen)


def with_transparency(name: str, parts: list, ignored: list) -> Material:
    """`mix_materials` of parts [(weight, Material)] some of which let light through (a
    Transparent BSDF is a part of alpha 0, a Principled BSDF's Alpha its own).

    Cycles shades sum_i w_i (a_i S_i + (1 - a_i) T), T passing the ray on; the kernels shade
    a S + (1 - a) T. So a = 1 - sum_i w_i (1 - a_i), and S mixes the parts with weights
    w_i a_i / a. A part's alpha texture counts as its constant alpha here (noted), unless that
    part is the whole mix."""
    if len(parts) == 1 and abs(parts[0][0] - 1.0) <= MIX_WEIGHT_EPS:
        return replace(parts[0][1], ignored=tuple(ignored))
    fabric = [(w, m) for w, m in parts if _pure_sheen(m)]
    if fabric and len(fabric) < len(parts):  # Sheen BSDFs beside the rest: their light added
        surface = with_transparency(name, [(w, m) for w, m in parts if not _pure_sheen(m)], ignored)
        sheen = _sheen_fields([(1.0, surface), *fabric], ignored)
        return replace(surface, ignored=tuple(ignored), **sheen)
    glowing = _with_emitters(name, parts, ignored)
    if glowing is not None:
        return glowing
    if not any(m.has_alpha for _, m in parts):
        return mix_materials(name, parts, ignored)
    if any(m.alpha_texture is not None for _, m in parts):
        ignored.append("an alpha texture in a mix of shaders: its part's constant alpha used")
    transparency = sum(w * (1.0 - m.alpha) for w, m in parts)
    if transparency >= 1.0 - MIX_WEIGHT_EPS:
        if transparency > 1.0 + MIX_WEIGHT_EPS:
            ignored.append(f"a mix passing {transparency:.3g} of the light it receives (a "
                           f"Transparent BSDF added to others): alpha 0 used")
        return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0, alpha=0.0,
                        ignored=tuple(ignored))
    alpha = 1.0 - transparency
    surface = [(w * m.alpha / alpha, replace(m, alpha=1.0, alpha_texture=None))
               for w, m in parts if w * m.alpha > 0.0]
    return replace(mix_materials(name, surface, ignored), alpha=alpha, ignored=tuple(ignored))


def _with_emitters(name: str, parts: list, ignored: list) -> Material | None:
    """Emission shaders added to one surface of weight 1 (an Add Shader, as the glTF importer of
    Blender 2.8 to 3.x built emissive materials): that surface whole (its metallic, roughness,
    normal and alpha maps kept) with the emitters' light added to its own. None for any other
    mix."""
    emitters = [(w, m) for w, m in parts if _pure_emitter(m)]
    surfaces = [(w, m) for w, m in parts if not _pure_emitter(m)]
    if not emitters or len(surfaces) != 1 or abs(surfaces[0][0] - 1.0) > MIX_WEIGHT_EPS:
        return None
    surface = surfaces[0][1]
    lights = emitters + [(1.0, surface)]
    emission = sum((w * m.emission.astype(np.float64) for w, m in lights), np.zeros(3))
    texture = _mixed_emission_texture(lights, emission, ignored)
    if texture is not None:
        emission = np.zeros(3)
    return replace(surface, name=name, emission=emission.astype(np.float32),
                   emission_texture=texture, ignored=tuple(ignored))


def _pure_sheen(m: Material) -> bool:
    """Whether `m` is a Sheen BSDF alone: it reflects by its sheen only."""
    return (m.sheen > 0.0 and _pure_emitter(m) and not m.emission.any()
            and m.emission_texture is None)


def _sheen_fields(parts: list, ignored: list) -> dict:
    """The sheen `Material` fields of a sum of parts [(weight, Material)]: the weights add, tint
    and roughness their weighted means; the first sheen's textures, model and layering ({}: no
    sheen)."""
    sheens = [(w * m.sheen, m) for w, m in parts if w * m.sheen > 0.0]
    if not sheens:
        return {}
    if len({(m.sheen_model, m.sheen_layer) for _, m in sheens}) > 1:
        ignored.append("sheens of different kinds in one mix: the first one's kind used")
    total = sum(w for w, _ in sheens)
    first = sheens[0][1]
    return {"sheen": total,
            "sheen_tint": (sum(w * m.sheen_tint.astype(np.float64) for w, m in sheens) / total
                           ).astype(np.float32),
            "sheen_roughness": sum(w * m.sheen_roughness for w, m in sheens) / total,
            "sheen_tint_texture": first.sheen_tint_texture,
            "sheen_roughness_texture": first.sheen_roughness_texture,
            "sheen_model": first.sheen_model, "sheen_layer": first.sheen_layer}


def _pure_emitter(m: Material) -> bool:
    """Whether `m` only emits (an Emission shader): it reflects and transmits nothing."""
    return (m.base_color_texture is None and not np.any(m.base_color > 0.0) and m.specular == 0.0
            and m.metallic == 0.0 and m.transmission == 0.0 and not m.has_alpha)


def _mixed_emission_texture(parts: list, constant: np.ndarray, ignored: list) -> Texture | None:
    """The emission texture of a mix of shaders: the one textured part's, times its weight, plus
    the other parts' constant emission (`constant`, their weighted sum); None without one."""
    textured = [(w, m) for w, m in parts if m.emission_texture is not None]
    if not textured:
        return None
    if len(textured) > 1:
        ignored.append("a mix of shaders with several emission textures: the first one's used")
    weight, part = textured[0]
    texture = part.emission_texture
    return replace(texture, gain=(texture.gain * weight).astype(np.float32),
                   offset=(texture.offset * weight + constant).astype(np.float32))


def _scaled_texture(texture: Texture, factor: float, ignored: list) -> Texture:
    """`texture` with its colours times `factor` (1: itself); an sRGB-encoded image, whose
    texels are decoded after filtering, is kept as it is (noted)."""
    if abs(factor - 1.0) < 1e-9:
        return texture
    if texture.kind == "ATTRIBUTE":
        return scaled_texture(texture, factor)
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


def scaled_texture(texture: Texture | None, factor: float) -> Texture | None:
    """`texture`'s look-ups times `factor` (an emission strength), through its node chain."""
    if texture is None or factor == 1.0:
        return texture
    return replace(texture, gain=(texture.gain * factor).astype(np.float32),
                   offset=(texture.offset * factor).astype(np.float32))


def _simple_part(m: Material) -> bool:
    """Whether a mixed shader's Material has no layer beyond a dielectric's or a metal's: no
    transmission, coat, sheen, emission, alpha, translucency or metal tint of its own
    (`_masked_mix`)."""
    return (m.transmission == 0.0 and m.coat == 0.0 and m.sheen == 0.0
            and m.metal_color is None and m.alpha == 1.0 and m.alpha_texture is None
            and not np.any(m.emission) and m.emission_texture is None
            and not np.any(m.translucent) and not m.camera_only)


def _plain_part(m: Material) -> bool:
    """A `_simple_part` of constant colour, roughness and metallic 0 or 1 (`_plain_masked`)."""
    return (_simple_part(m) and m.base_color_texture is None and m.metallic_texture is None
            and m.roughness_texture is None and m.metallic in (0.0, 1.0))


def _first_relief(parts: list) -> dict:
    """The Material fields of the first part with a normal or bump map ({} if none): a mix's
    relief, as `mix_materials` takes it."""
    relief = next((m for m in parts if m.normal_texture is not None
                   or m.height_texture is not None), None)
    if relief is None:
        return {}
    return dict(normal_texture=relief.normal_texture, normal_strength=relief.normal_strength,
                height_texture=relief.height_texture, bump_strength=relief.bump_strength,
                bump_distance=relief.bump_distance)


def facing_ior(blend: float) -> float:
    """The IOR whose dielectric Fresnel reflectance has the cosine-weighted hemispherical mean of
    a Layer Weight's Facing output, 1 - cos^b (b = 2 Blend below 0.5, 0.5 / (1 - Blend) above;
    Cycles' svm_node_layer_weight): mean b / (b + 2). Bisection on log IOR over [1, 100]."""
    b = 2.0 * blend if blend < 0.5 else 0.5 / max(1.0 - blend, 1e-5)
    target = b / (b + 2.0)
    mu = (np.arange(FACING_FIT_STEPS) + 0.5) / FACING_FIT_STEPS  # midpoints on [0, 1]

    def mean_reflectance(ior: float) -> float:
        return float(np.mean(2.0 * mu * fresnel_dielectric(mu, 1.0 / ior)))

    lo, hi = 0.0, np.log(FACING_FIT_MAX_IOR)
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if mean_reflectance(np.exp(mid)) < target else (lo, mid)
    return float(np.exp(0.5 * (lo + hi)))


def mapping_transform(node) -> np.ndarray | None:
    """(2, 3) affine [A | t] that a Mapping node of constants applies to (u, v): Point
    p' = R(S p) + L, Texture p' = S^-1 R^-1 (p - L) (Blender's mapping node), R a turn about z.
    None where an input is linked, the rotation leaves the UV plane or the type is another."""
    inputs = node.inputs
    if node.vector_type not in ("POINT", "TEXTURE") or any(
            inputs[name].is_linked for name in ("Location", "Rotation", "Scale")):
        return None
    location = np.array(inputs["Location"].default_value[:2], np.float64)
    rx, ry, rz = inputs["Rotation"].default_value
    if abs(rx) > MAPPING_PLANAR_EPS or abs(ry) > MAPPING_PLANAR_EPS:
        return None
    scale = np.array(inputs["Scale"].default_value[:2], np.float64)
    turn = np.array([[np.cos(rz), -np.sin(rz)], [np.sin(rz), np.cos(rz)]])
    if node.vector_type == "POINT":
        a, t = turn @ np.diag(scale), location
    else:
        if np.any(scale == 0.0):
            return None
        a = np.diag(1.0 / scale) @ turn.T
        t = -a @ location
    return np.column_stack([a, t])


# A Mapping node's rotation about x or y below this (radians) keeps the UV plane in itself.
MAPPING_PLANAR_EPS = 1e-9


class MaterialReader:
    """Reduces Blender materials to kernel `Material`s, recording what it could not model."""

    def __init__(self, request: SnapshotRequest):
        self.request = request
        # image name -> pixels, or {tile: pixels} for a UDIM image; None: no pixels
        self.images: dict[str, np.ndarray | dict[int, np.ndarray] | None] = {}
        # Sockets it cannot read are baked by Cycles over the object's UVs (socket_fallback.py);
        # a bake that reads no textures bakes none but the alpha (coverage casts shadows).
        self.fallback = (None if request.socket_bake is None
                         else SocketFallback(request.socket_bake))
        self._mat, self._target, self._baked, self._scaled = None, None, [], False
        self._groups: tuple = ()  # the Group nodes entered to reach the node being read

    @contextmanager
    def _inside(self, groups: tuple):
        """Read nodes reached inside the Group nodes `groups` (outermost first) meanwhile."""
        outer, self._groups = self._groups, groups
        try:
            yield
        finally:
            self._groups = outer

    def read(self, mat, target: BakeTarget | None = None) -> Material:
        """The kernel `Material` of `mat` on the object `target` (which a socket read through a
        Cycles bake is baked over; None: such sockets take their defaults, listed as ignored)."""
        self._mat, self._target, self._baked, self._groups = mat, target, [], ()
        self._scaled = False
        material = self._material(mat)
        return replace(material, fallbacks=tuple(self._baked)) if self._baked else material

    @property
    def object_dependent(self) -> bool:
        """Whether the last `read` baked a socket over its object or scaled a displacement by
        it (another object using the material needs a read of its own)."""
        return bool(self._baked) or self._scaled

    def _material(self, mat) -> Material:
        if mat is None:
            return DEFAULT_MATERIAL
        if not self.request.materials:
            return Material(name=mat.name, specular=0.0)
        tree = node_tree(mat)
        if tree is None:
            return Material(
                name=mat.name,
                base_color=np.array(mat.diffuse_color[:3], np.float32),
                metallic=float(mat.metallic),
                roughness=float(mat.roughness),
                ignored=("no shader nodes: viewport display colour used",),
            )
        ignored: list[str] = []
        output = active_output(tree, "OUTPUT_MATERIAL")
        if output is None:
            return Material(name=mat.name, ignored=("no Material Output node",))
        absorption = self._absorption(output.inputs["Volume"], ignored)
        node, _, groups = follow_through(output.inputs["Surface"])
        if node is None:
            return Material(name=mat.name, base_color=np.zeros(3, np.float32),
                            ignored=tuple(ignored + ["no surface shader: black"]))
        with self._inside(groups):
            material = self._shader(mat.name, node, ignored)
        material = self._displacement(mat, output.inputs["Displacement"], material)
        if absorption is None:
            return material
        if material.transmission <= 0.0:
            why = "a volume inside a surface that does not refract is not modelled"
            return replace(material, ignored=material.ignored + (why,))
        return replace(material, absorption=absorption)

    def _displacement(self, mat, socket, material: Material) -> Material:
        """`material` with the bump Cycles makes of a Displacement node in the output's
        Displacement slot (methods Bump and Both; `ShaderGraph::bump_from_displacement`): the
        height (Height - Midlevel) x Scale along the normal, through a Bump node of strength 1 and
        distance 1 whose normal every closure takes, i.e. a bump of distance Scale over the
        node's height texture. Object space (the node's default) measures Scale in the object's
        units: times the object's scale (the geometric mean of its axes' where they differ,
        noted). A surface with a relief of its own keeps that (the displacement noted)."""
        if not socket.is_linked:
            return material
        notes: list[str] = []
        relief = self._displacement_relief(mat, socket, material, notes)
        return replace(material, **relief, ignored=material.ignored + tuple(notes))

    def _displacement_relief(self, mat, socket, material: Material, notes: list) -> dict:
        """`_displacement`'s Material fields (none where it is not modelled, said in `notes`)."""
        method = getattr(mat, "displacement_method", "BUMP")
        node, _, groups = follow_through(socket)
        if node is None or node.type != "DISPLACEMENT":
            kind = "nothing" if node is None else f"a '{node.bl_idname}' node"
            notes.append(f"displacement from {kind} is not modelled (a Displacement node is)")
            return {}
        if method == "DISPLACEMENT":
            notes.append("true displacement (the method 'Displacement Only') is not modelled")
            return {}
        if method == "BOTH":
            notes.append("true displacement (of 'Displacement and Bump') is not modelled; its "
                         "bump is")
        if material.height_texture is not None or material.normal_texture is not None:
            notes.append("displacement over a surface's own bump or normal map is not modelled")
            return {}
        with self._inside(groups):
            height = self._height(node.inputs["Height"], notes)
            if height is None:
                return {}
            if node.inputs["Normal"].is_linked:
                notes.append("a Displacement node's Normal input is not modelled (the surface's "
                             "normal used)")
            distance = self._value(node.inputs["Scale"], notes)
        if node.space == "OBJECT":
            distance *= self._object_scale(notes)
        return dict(height_texture=height, bump_strength=1.0, bump_distance=distance)

    def _object_scale(self, ignored: list) -> float:
        """The uniform scale of the object the material is read for (1 without one); the
        material's read then belongs to that object (`object_dependent`)."""
        if self._target is None:
            return 1.0
        self._scaled = True
        axes = np.abs(np.array(self._target.source.matrix_world.to_scale(), np.float64))
        if not np.allclose(axes, axes[0], rtol=1e-4):
            ignored.append("an object-space displacement on a non-uniformly scaled object: "
                           "its scales' geometric mean used")
        return float(np.prod(axes) ** (1.0 / 3.0))

    def _absorption(self, socket, ignored: list) -> np.ndarray | None:
        """The absorption coefficient (3,) 1/m of the medium a Volume Absorption in the Volume
        slot `socket` fills the mesh with: (1 - Color) x Density, as Cycles' node sets it. None
        when the slot is empty or holds another volume shader (noted: not modelled)."""
        if not socket.is_linked:
            return None
        node, _, groups = follow_through(socket)
        if node is None:
            return None
        if node.type != "VOLUME_ABSORPTION":
            ignored.append(f"volume shader '{node.bl_idname}' in the Volume slot is not modelled "
                           f"(a Volume Absorption is)")
            return None
        with self._inside(groups):
            color, _ = self._color(node.inputs["Color"], ignored, textures=False)
            density = self._value(node.inputs["Density"], ignored)
        sigma = np.clip(1.0 - color, 0.0, None) * max(density, 0.0)
        return sigma.astype(np.float32) if sigma.any() else None

    def _shader(self, name: str, node, ignored: list, depth: int = 0) -> Material:
        """The kernel `Material` of the shader node `node` (a BSDF, an emission, or a Mix or
        Add Shader of such, `_mixed`), reached inside the Group nodes `self._groups`."""
        kind = node.type
        if kind in ("MIX_SHADER", "ADD_SHADER") and depth < MAX_SHADER_MIX_DEPTH:
            return self._mixed(name, node, ignored, depth)
        if kind == "BSDF_PRINCIPLED":
            return self._principled(name, node, ignored)
        # Every BSDF's Normal input as the Principled's: a normal map or a bump on it.
        relief = self._normal(node.inputs["Normal"], ignored).fields() if "Normal" in node.inputs \
            else {}
        if kind == "BSDF_DIFFUSE":
            color, tex = self._color(node.inputs["Color"], ignored)
            return Material(name=name, base_color=color, base_color_texture=tex, specular=0.0,
                            ignored=tuple(ignored), **relief)
        if kind == "EMISSION":
            emission, tex = self._emission(node.inputs["Color"], node.inputs["Strength"], ignored)
            return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                            emission=emission, emission_texture=tex, ignored=tuple(ignored))
        if kind == "BSDF_GLASS":
            # Cycles' Glass BSDF tints each refraction by its colour, the Principled by the square
            # root of its base colour (the kernels' rule): stored squared, it passes as Cycles does.
            color, _ = self._color(node.inputs["Color"], ignored, textures=False)
            tint = np.clip(color, 0.0, None).astype(np.float32)  # its reflection's too
            return Material(name=name, base_color=tint**2, transmission=1.0, glass_tint=tint,
                            roughness=self._value(node.inputs["Roughness"], ignored),
                            ior=self._value(node.inputs["IOR"], ignored), ignored=tuple(ignored),
                            **relief)
        if kind in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC"):
            color, tex = self._color(node.inputs["Color"], ignored)
            return Material(name=name, base_color=color, base_color_texture=tex, metallic=1.0,
                            roughness=self._value(node.inputs["Roughness"], ignored),
                            ignored=tuple(ignored), **relief)
        if kind == "BSDF_METALLIC":
            return self._metallic(name, node, ignored, relief)
        if kind == "BSDF_SHEEN":  # added beside a surface, not layered over it
            color, color_texture = self._color(node.inputs["Color"], ignored)
            rough, rough_texture = self._number(node.inputs["Roughness"], ignored)
            return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                            sheen=1.0, sheen_tint=np.clip(color, 0.0, None).astype(np.float32),
                            sheen_tint_texture=color_texture,
                            sheen_roughness=min(max(rough, 0.0), 1.0),
                            sheen_roughness_texture=rough_texture, sheen_model=node.distribution,
                            sheen_layer=False, ignored=tuple(ignored))
        if kind == "BSDF_TRANSPARENT":
            color, _ = self._color(node.inputs["Color"], ignored, textures=False)
            if not np.allclose(color, 1.0):
                ignored.append("a tinted Transparent BSDF: light passes it untinted")
            return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                            alpha=0.0, ignored=tuple(ignored))
        if kind == "GROUP" and node.node_tree is not None and node.node_tree.original.is_missing:
            # A placeholder without nodes: no closure, black in Cycles (measured). An evaluated
            # copy (a snapshot reads the depsgraph's materials) says so on its original only.
            ignored.append(f"node group '{node.node_tree.name}' is missing (its library file "
                           f"was not found): no surface (black), as Cycles renders it")
            return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                            ignored=tuple(ignored))
        if kind == "BSDF_REFRACTION":  # a glass that reflects nothing (its tint: a Glass BSDF's)
            color, _ = self._color(node.inputs["Color"], ignored, textures=False)
            tint = np.clip(color, 0.0, None).astype(np.float32)
            return Material(name=name, base_color=tint**2, transmission=1.0,
                            glass_tint=np.zeros(3, np.float32),
                            roughness=self._value(node.inputs["Roughness"], ignored),
                            ior=self._value(node.inputs["IOR"], ignored), ignored=tuple(ignored),
                            **relief)
        if kind == "BSDF_TRANSLUCENT":  # light from behind the surface alone
            color, _ = self._color(node.inputs["Color"], ignored, textures=False)
            return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                            translucent=np.clip(color, 0.0, None).astype(np.float32),
                            ignored=tuple(ignored), **relief)
        # No light at all: a Holdout's; Cycles has no closure for the EEVEE Specular node
        # (measured black in its renders, 4.5 and 5.2).
        if kind in ("HOLDOUT", "EEVEE_SPECULAR"):
            if kind == "EEVEE_SPECULAR":
                ignored.append("an EEVEE Specular shader: black, as Cycles renders it")
            return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                            ignored=tuple(ignored))
        if kind == "SUBSURFACE_SCATTERING":  # the light it spreads under the surface, left out
            color, tex = self._color(node.inputs["Color"], ignored)
            ignored.append("a Subsurface Scattering shader is taken as a Diffuse BSDF of its colour")
            return Material(name=name, base_color=color, base_color_texture=tex, specular=0.0,
                            ignored=tuple(ignored), **relief)
        if node.bl_idname.startswith(VOLUME_SHADER_PREFIX):
            ignored.append(f"volume shader '{node.bl_idname}' in the Surface slot: no surface "
                           f"(black), as Cycles renders it")
            return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                            ignored=tuple(ignored))
        ignored.append(f"surface shader '{node.bl_idname}' is not modelled: grey diffuse used")
        return Material(name=name, ignored=tuple(ignored))

    def _metallic(self, name: str, node, ignored: list, relief: dict) -> Material:
        """A Metallic BSDF (Blender 4.3+) as a metal: in F82 mode its Base Color (textures too)
        and Edge Tint, the F82-tint Fresnel Cycles uses (`Material.metal_edge`); in Physical
        Conductor mode Schlick's curve from the normal incidence reflectance of its complex IOR
        n + ik, ((n - 1)^2 + k^2) / ((n + 1)^2 + k^2) per channel (noted). Anisotropy and thin
        film are noted when they would change it."""
        inputs = node.inputs
        roughness, roughness_tex = self._number(inputs["Roughness"], ignored)
        if node.fresnel_type == "PHYSICAL_CONDUCTOR":
            n = self._color(inputs["IOR"], ignored, textures=False)[0].astype(np.float64)
            k = self._color(inputs["Extinction"], ignored, textures=False)[0].astype(np.float64)
            color = (((n - 1.0) ** 2 + k * k) / ((n + 1.0) ** 2 + k * k)).astype(np.float32)
            tex = None
            ignored.append("a Metallic BSDF's physical conductor Fresnel is taken as Schlick's "
                           "curve from its reflectance at normal incidence")
            edge = None
        else:
            color, tex = self._color(inputs["Base Color"], ignored)
            tint, _ = self._color(inputs["Edge Tint"], ignored, textures=False)
            edge = None if np.allclose(tint, 1.0, atol=1e-3) else np.clip(tint, 0.0, 1.0)
        if inputs["Anisotropy"].is_linked or inputs["Anisotropy"].default_value != 0.0:
            ignored.append("a Metallic BSDF's anisotropy is not modelled (isotropic)")
        if "Thin Film Thickness" in inputs and self._in_use(inputs["Thin Film Thickness"]):
            ignored.append("a Metallic BSDF's thin film is not modelled")
        return Material(name=name, base_color=color, base_color_texture=tex, metallic=1.0,
                        roughness=roughness, roughness_texture=roughness_tex,
                        metal_edge=None if edge is None else edge.astype(np.float32),
                        ignored=tuple(ignored), **relief)

    def _mixed(self, name: str, node, ignored: list, depth: int) -> Material:
        """A Mix Shader (weights 1 - Fac and Fac; a Fac fed by a node the reader cannot hold
        as one number takes its mean or default, noted) or an Add Shader (weights 1 and 1) of
        two shaders, as one `Material` (`mix_materials`, `with_transparency`); an unlinked
        shader input, or a volume shader (Cycles evaluates those in the Volume slot only), is a
        black surface (no closure: Cycles absorbs there). Mixes read otherwise: a Fresnel's
        (`_fresnel_layer`), a mask's (`_masked_mix`), a Light Path's (`_light_path_mix`) and a cut-out
        (`_cut_out`).

        A Mix Shader of a Transparent BSDF and one other shader is that shader with Fac (or
        1 - Fac) as its alpha, read as the Principled Alpha is (a texture too): the cut-out
        leaves and fences of imported assets."""
        sockets = [s for s in node.inputs if s.type == "SHADER"]
        sources = []
        for socket in sockets:
            source, _, groups = follow_through(socket, self._groups)
            if source is not None and source.bl_idname.startswith(VOLUME_SHADER_PREFIX):
                ignored.append(f"volume shader '{source.bl_idname}' in the Surface slot: no "
                               f"surface, as Cycles renders it")
                source = None
            sources.append((source, groups))
        if node.type != "ADD_SHADER":  # the mixes read otherwise, the first that applies
            for special in (self._light_path_mix, self._cut_out, self._fresnel_layer,
                            self._masked_mix):
                material = special(name, node.inputs["Fac"], sources, ignored, depth)
                if material is not None:
                    return material
        if node.type == "ADD_SHADER":
            weights = [1.0, 1.0]
        else:
            fac = min(max(self._value(node.inputs["Fac"], ignored), 0.0), 1.0)
            weights = [1.0 - fac, fac]
        parts = []
        for (source, groups), weight in zip(sources, weights, strict=True):
            if source is None or weight == 0.0:
                continue
            with self._inside(groups):
                parts.append((weight, self._shader(name, source, ignored, depth + 1)))
        return with_transparency(name, parts, ignored)

    def _light_path_mix(self, name: str, fac_socket, sources: list, ignored: list,
                        depth: int) -> Material | None:
        """A Mix Shader whose Fac is a Light Path's Is Camera Ray or Is Shadow Ray, of a
        Transparent BSDF (what the other rays meet) and a shader: that shader, flagged as
        `LIGHT_PATH_MIXES` says. None for any other mix."""
        feed, out, _ = follow_through(fac_socket, self._groups)
        if feed is None or feed.type != "LIGHT_PATH" or out.identifier not in LIGHT_PATH_MIXES:
            return None
        at, flag = LIGHT_PATH_MIXES[out.identifier]
        (passed, passed_groups), (seen, groups) = sources[at], sources[1 - at]
        if passed is None or passed.type != "BSDF_TRANSPARENT" or seen is None:
            return None
        with self._inside(passed_groups):
            self._shader(name, passed, ignored, depth + 1)  # its notes (a tint)
        with self._inside(groups):
            surface = self._shader(name, seen, ignored, depth + 1)
        return replace(surface, **{flag: True}, ignored=tuple(ignored))

    def _cut_out(self, name: str, fac_socket, sources: list, ignored: list,
                 depth: int) -> Material | None:
        """A Mix Shader of a Transparent BSDF and one other shader whose Fac a texture drives:
        that shader with the texture (or 1 - it) as its alpha, times its own alpha. None for
        any other mix (a constant Fac goes the general way, `with_transparency`)."""
        kinds = [None if source is None else source.type for source, _ in sources]
        if kinds.count("BSDF_TRANSPARENT") != 1 or None in kinds:
            return None
        fac = self._read_or_bake(fac_socket, self._any_texture(ignored), [], bake=True)
        if fac is None or fac.texture is None:
            return None
        surface_at = 1 - kinds.index("BSDF_TRANSPARENT")  # Fac weighs the second input
        coverage = fac if surface_at == 1 else fac.affine(-1.0, 1.0)
        if coverage is None:
            return None
        source, groups = sources[surface_at]
        with self._inside(groups):
            surface = self._shader(name, source, ignored, depth + 1)
        transparent, groups = sources[1 - surface_at]
        with self._inside(groups):
            self._shader(name, transparent, ignored, depth + 1)  # its notes (a tint)
        if surface.alpha_texture is not None:
            ignored.append("a cut-out mix of a shader with its own alpha texture: the mix's "
                           "texture used")
        texture = replace(coverage.texture,
                          gain=(coverage.texture.gain * surface.alpha).astype(np.float32),
                          offset=(coverage.texture.offset * surface.alpha).astype(np.float32))
        return replace(surface, alpha=1.0, alpha_texture=texture, ignored=tuple(ignored))

    def _fresnel_layer(self, name: str, fac_socket, sources: list, ignored: list,
                       depth: int) -> Material | None:
        """A Mix Shader of an opaque non-metal base (Fac 0) and a Glossy BSDF (Fac 1) whose Fac
        is a Fresnel node's, or a Layer Weight's (Fresnel: IOR 1 / (1 - Blend); Facing: the IOR
        whose Fresnel reflects as much over the hemisphere, noted): the classic Cycles material
        before the Principled BSDF. Read as that base under a Principled specular layer of the
        IOR and the Glossy's roughness: in Cycles the two render within relMSE 1e-3 of each other
        (a sphere under a sun, roughness 0.05-0.4, IOR 1.45), where the Fac's default (0.5)
        made half the surface a mirror. The Glossy's colour is not modelled (noted where it is
        not white). None for any other mix."""
        feed, out, _ = follow_through(fac_socket, self._groups)
        (base_node, base_groups), (gloss_node, gloss_groups) = sources
        if (feed is None or feed.type not in ("FRESNEL", "LAYER_WEIGHT") or base_node is None
                or gloss_node is None or gloss_node.type not in ("BSDF_GLOSSY", "BSDF_ANISOTROPIC")
                or (feed.type == "LAYER_WEIGHT" and out.identifier not in ("Fresnel", "Facing"))):
            return None
        baked, noted = len(self._baked), len(ignored)
        with self._inside(base_groups):
            base = self._shader(name, base_node, ignored, depth + 1)
        if base.metallic > 0.0 or base.transmission > 0.0:
            del self._baked[baked:], ignored[noted:]  # the general way reads it again
            return None
        with self._inside(gloss_groups):
            gloss = self._shader(name, gloss_node, ignored, depth + 1)
        if feed.type == "FRESNEL":
            ior = self._value(feed.inputs["IOR"], ignored)
        else:
            blend = min(max(self._value(feed.inputs["Blend"], ignored), 0.0), 1.0 - 1e-5)
            if out.identifier == "Fresnel":
                ior = 1.0 / (1.0 - blend)
            else:
                ior = facing_ior(blend)
                ignored.append(f"a Layer Weight's Facing mixing a Glossy over its base: read as a "
                               f"specular layer of IOR {ior:.3g}, whose Fresnel reflects as much "
                               f"over the hemisphere")
        if feed.inputs["Normal"].is_linked:
            ignored.append("the Fresnel mix's own Normal input is not modelled (the surface's)")
        # The Glossy's colour scales its reflection; the layer's F0 scales so (Specular IOR
        # Level 0.5 keeps F0, so 0.5 x its grey level), its grazing reflection stays white.
        tint = gloss.base_color if gloss.metal_color is None else gloss.metal_color
        grey = float(np.mean(tint))
        if gloss.base_color_texture is not None or not np.allclose(tint, grey, atol=1e-3):
            ignored.append("a Glossy's colour under a Fresnel mix: its grey level used")
        if gloss.roughness_texture is not None:
            ignored.append("a Glossy's roughness texture under a Fresnel mix: its default used")
        return replace(base, specular=0.5 * max(grey, 0.0), ior=max(ior, 1.0 + 1e-6),
                       roughness=gloss.roughness, ignored=tuple(ignored))

    def _masked_mix(self, name: str, fac_socket, sources: list, ignored: list,
                    depth: int) -> Material | None:
        """A Mix Shader of two shaders whose Fac a texture drives (a dirt or paint mask; a
        procedural mask baked by Cycles), each a dielectric or a metal without layers of its
        own (`_simple_part`): per texel, the mix's fields are the parts' blended by the mask M.
        Parts of constant fields: texture look-ups through the mask (`_plain_masked`); parts
        with textures of their own: Cycles bakes of their inputs mixed by the mask
        (`_blended_mix`). None for any other mix (the general way: the mask's mean, noted)."""
        if not fac_socket.is_linked or any(source is None for source, _ in sources):
            return None
        if any(source.type == "BSDF_TRANSPARENT" for source, _ in sources):
            return None
        notes: list[str] = []
        baked = len(self._baked)
        parts = []
        for source, groups in sources:
            with self._inside(groups):
                parts.append(self._shader(name, source, notes, depth + 1))
        # The parts' own bakes go: the blends replace them, or the general way reads them again.
        del self._baked[baked:]
        material = None
        if all(_plain_part(m) for m in parts):
            material = self._plain_masked(fac_socket, parts, notes)
        elif all(_simple_part(m) for m in parts):
            material = self._blended_mix(fac_socket, sources, parts, notes)
        if material is None:
            del self._baked[baked:]
            return None
        ignored.extend(notes)
        return replace(material, name=name, ignored=tuple(ignored))

    def _plain_masked(self, fac_socket, parts: list, notes: list) -> Material | None:
        """`_masked_mix` of two parts of constant fields: both dielectric or both metal: base
        colour and roughness (1 - M) a + M b; a dielectric and a metal: the dielectric's colour
        as the base, the metal's as its tint (`metal_color`), metallic M (or 1 - M). Their
        reliefs: the first part's that has one, as for constant mixes."""
        fac = self._read(fac_socket, [], bake=True)
        if fac is None or fac.texture is None:
            return None
        a, b = parts
        rough = fac.affine(b.roughness - a.roughness, a.roughness)
        if rough is None:
            return None
        fields = dict(roughness=a.roughness if b.roughness == a.roughness else 0.5,
                      roughness_texture=None if b.roughness == a.roughness else rough.texture)
        if a.metallic == b.metallic:
            base = fac.affine(b.base_color - a.base_color, a.base_color)
            if base is None:
                return None
            fields.update(base_color=a.base_color, base_color_texture=base.texture,
                          metallic=a.metallic, ior=0.5 * (a.ior + b.ior),
                          specular=0.5 * (a.specular + b.specular))
            if a.metallic == 0.0 and a.specular != b.specular:
                notes.append("a masked mix of two specular levels: their mean used")
        else:
            dielectric, metal = (a, b) if b.metallic == 1.0 else (b, a)
            metallic = fac if b.metallic == 1.0 else fac.affine(-1.0, 1.0)
            if metallic is None:
                return None
            fields.update(base_color=dielectric.base_color, metal_color=metal.base_color,
                          metallic=0.0, metallic_texture=metallic.texture, ior=dielectric.ior,
                          specular=dielectric.specular)
            if b.roughness != a.roughness:
                rough = pointwise(metallic, _lobe_weighted_roughness(dielectric, metal))
                fields.update(roughness=0.5, roughness_texture=rough.texture)
        return Material(name="", **fields, **_first_relief(parts))

    def _blended_mix(self, fac_socket, sources: list, parts: list,
                     notes: list) -> Material | None:
        """`_masked_mix` of parts with textures of their own (Principled, Diffuse or Glossy
        shaders in the material's own tree): each field the two read as a texture is the two
        sockets mixed by the mask, baked by Cycles over the UVs (`SocketFallback`, `blend`):
        base colour always, roughness and metallic where both parts have that input, else the
        one part's (a Diffuse's metallic 0 and a Glossy's 1, blended by the mask). The
        specular level is the dielectric parts' (their mean). None where a bake cannot be
        made (a node group, no UVs): the general way."""
        fields = {"BSDF_PRINCIPLED": ("Base Color", "Metallic", "Roughness"),
                  "BSDF_DIFFUSE": ("Color", None, None),
                  "BSDF_GLOSSY": ("Color", None, "Roughness"),
                  "BSDF_ANISOTROPIC": ("Color", None, "Roughness")}
        nodes = [source for source, _ in sources]
        if (self.fallback is None or self._mat is None or not self.request.textures
                or any(groups for _, groups in sources) or self._groups
                or any(node.type not in fields for node in nodes)):
            return None

        def blend(k: int, as_number: bool) -> Texture | None:
            a, b = (node.inputs[fields[node.type][k]] for node in nodes)
            texture, entry = self.fallback.texture(self._mat, a, as_number, self._target,
                                                   blend=(fac_socket, b))
            if texture is None:
                return None
            self._baked.append(entry)
            return texture

        base = blend(0, False)
        if base is None:
            return None
        a, b = parts
        out = dict(base_color=a.base_color, base_color_texture=base)
        if all(fields[node.type][1] for node in nodes):
            out.update(metallic=0.0, metallic_texture=blend(1, True))
            if out["metallic_texture"] is None:
                return None
        elif a.metallic_texture is None and b.metallic_texture is None:
            fac = self._read(fac_socket, [], bake=True)
            metallic = None if fac is None else fac.affine(b.metallic - a.metallic, a.metallic)
            if metallic is None:
                return None
            out.update(metallic=float(metallic.const[0]), metallic_texture=metallic.texture)
        else:
            return None
        rough = [k for k, node in enumerate(nodes) if fields[node.type][2]]
        if len(rough) == 2:
            out.update(roughness=0.5, roughness_texture=blend(2, True))
            if out["roughness_texture"] is None:
                return None
        elif rough:  # a Diffuse beside: the other's roughness (a bake of it named again)
            node = nodes[rough[0]]
            value, texture = self._number(node.inputs[fields[node.type][2]], notes)
            out.update(roughness=value, roughness_texture=texture)
        dielectric = [m for m, node in zip(parts, nodes, strict=True)
                      if node.type in ("BSDF_PRINCIPLED", "BSDF_DIFFUSE")]
        levels = {m.specular for m in dielectric}
        if len(levels) > 1:
            notes.append("a masked mix of two specular levels: their mean used")
        return Material(name="", specular=float(np.mean(sorted(levels))) if levels else 0.5,
                        ior=float(np.mean([m.ior for m in dielectric] or [1.5])), **out,
                        **_first_relief(parts))

    def _any_texture(self, ignored):
        """A `texture_of` that reads textures even where the request reads no colours: coverage
        decides where shadows fall."""
        def texture_of(node, what, groups):
            with self._inside(groups):
                return self._texture(node, ignored, what)
        return texture_of

    def _principled(self, name, node, ignored) -> Material:
        inputs = node.inputs
        color, tex = self._color(inputs["Base Color"], ignored)
        emission, emission_tex = self._emission(inputs["Emission Color"],
                                                inputs["Emission Strength"], ignored)
        metallic, metallic_tex = self._number(inputs["Metallic"], ignored)
        roughness, roughness_tex = self._number(inputs["Roughness"], ignored)
        # Left out, noted where they change the look (thin film: 4.2+, diffuse roughness: 4.3+).
        for socket, what in (("Subsurface Weight", "Subsurface Weight"),
                             ("Thin Film Thickness", "Thin Film (iridescence)"),
                             ("Diffuse Roughness", "Diffuse Roughness (Oren-Nayar)")):
            if socket in inputs and self._in_use(inputs[socket]):
                ignored.append(f"{what} is not modelled")
        edge = None  # 4.0+: Specular Tint is F0's tint on a dielectric, F82's on a metal
        if "Specular Tint" in inputs:
            tint, _ = self._color(inputs["Specular Tint"], ignored, textures=False)
            if not np.allclose(tint, 1.0, atol=1e-3):
                edge = np.clip(tint, 0.0, 1.0).astype(np.float32)
        sheen = self._sheen(inputs, ignored)
        alpha, alpha_tex = self._alpha(inputs["Alpha"], ignored) if "Alpha" in inputs else (1.0, None)
        relief = self._normal(inputs["Normal"], ignored)
        coat = self._coat(inputs, ignored, relief)
        return Material(
            name=name,
            base_color=color,
            base_color_texture=tex,
            metallic=metallic,
            roughness=roughness,
            ior=self._value(inputs["IOR"], ignored),
            transmission=self._value(inputs["Transmission Weight"], ignored),
            specular=self._value(inputs["Specular IOR Level"], ignored),
            emission=emission,
            emission_texture=emission_tex,
            metallic_texture=metallic_tex,
            roughness_texture=roughness_tex,
            alpha=alpha,
            alpha_texture=alpha_tex,
            metal_edge=edge,
            specular_tint=edge,
            ignored=tuple(ignored),
            **relief.fields(),
            **coat,
            **sheen,
        )

    def _sheen(self, inputs, ignored) -> dict:
        """The Principled sheen's `Material` fields (a microfiber layer over the rest): weight
        (a constant: a texture driving it is noted, its mean used), tint and roughness (constants
        or textures); {} where there is none."""
        if "Sheen Weight" not in inputs:
            return {}
        weight = max(self._value(inputs["Sheen Weight"], ignored), 0.0)
        if weight <= 0.0:
            return {}
        tint, tint_texture = self._color(inputs["Sheen Tint"], ignored)
        rough, rough_texture = self._number(inputs["Sheen Roughness"], ignored)
        return {"sheen": weight, "sheen_tint": np.clip(tint, 0.0, None).astype(np.float32),
                "sheen_tint_texture": tint_texture, "sheen_roughness": min(max(rough, 0.0), 1.0),
                "sheen_roughness_texture": rough_texture}

    def _coat(self, inputs, ignored, relief: Relief) -> dict:
        """The Principled coat's `Material` fields: weight, roughness, IOR and tint as constants
        (a texture driving one is noted, its mean used); {} where there is no coat, and over
        a normal or bump map, whose coat is noted and left out: there the coat's mirror ray
        made a ribbed glTF test asset further from Cycles (relMSE 0.051 -> 0.114) where a
        plain coated plane comes nearer (0.0067 -> 0.0010)."""
        if "Coat Weight" not in inputs:
            return {}
        weight = min(max(self._value(inputs["Coat Weight"], ignored), 0.0), 1.0)
        if weight <= 0.0:
            return {}
        if relief.normal_texture is not None or relief.height_texture is not None:
            ignored.append("Coat Weight over a normal or bump map is not modelled")
            return {}
        normal, surface = inputs["Coat Normal"], inputs["Normal"]
        if normal.is_linked and not (surface.is_linked and normal.links[0].from_socket
                                     == surface.links[0].from_socket):
            ignored.append("a Coat Normal of its own is not modelled: the surface's normal used")
        tint, _ = self._color(inputs["Coat Tint"], ignored, textures=False)
        return {"coat": weight,
                "coat_roughness": min(max(self._value(inputs["Coat Roughness"], ignored), 0.0), 1.0),
                "coat_ior": max(self._value(inputs["Coat IOR"], ignored), 1.0),
                "coat_tint": np.clip(tint, 0.0, None).astype(np.float32)}

    def _read(self, socket, ignored, bake: bool = False) -> Value | None:
        """What `socket` reads (socket_values.py): a constant or a texture with its node chain.
        A bake that reads no textures follows chains of constants only (a texture: its default).
        With `bake` (a socket the kernels read as a texture), a chain the reader cannot follow
        is baked by Cycles instead (`SocketFallback`) and named in the material's `fallbacks`."""
        if self.request.textures:
            texture_of = self._any_texture(ignored)
        else:
            def texture_of(node, what, groups):
                return None
        return self._read_or_bake(socket, texture_of, ignored, bake and self.request.textures)

    def _read_or_bake(self, socket, texture_of, ignored, bake: bool) -> Value | None:
        """`SocketReader`'s value of `socket`; where it cannot follow the chain and `bake`, the
        texture Cycles bakes of it (`SocketFallback`, named in `fallbacks`) instead of the
        reader's reasons in `ignored`."""
        unread: list[str] = []
        value = SocketReader(texture_of, unread).read(socket, socket.name, self._groups)
        if value is None and bake and self.fallback is not None and self._mat is not None:
            texture, entry = self.fallback.texture(self._mat, socket, socket.type != "RGBA",
                                                   self._target)
            if texture is not None:
                self._baked.append(entry)
                return Value(np.zeros(3), texture)
            unread = [f"{why} (not baked by Cycles: {entry})" for why in unread]
        ignored.extend(unread)
        return value

    def _emission(self, color_socket, strength_socket, ignored
                  ) -> tuple[np.ndarray, Texture | None]:
        """Emitted radiance, colour x strength: (constant (3,), None) or (0, texture). A strength
        the reader cannot hold as one number (a texture, or a chain it cannot follow) has Cycles
        bake the product (`SocketFallback`); else the colour is read (and baked where it must
        be) and scaled by the strength."""
        unread: list[str] = []
        strength = self._read(strength_socket, unread)
        if ((strength is None or strength.texture is not None) and self.request.textures
                and self.fallback is not None and self._mat is not None):
            texture, entry = self.fallback.texture(self._mat, color_socket, False, self._target,
                                                   strength=strength_socket)
            if texture is not None:
                self._baked.append(entry)
                return np.zeros(3, np.float32), texture
        color, texture = self._color(color_socket, ignored)
        factor = self._value(strength_socket, ignored)  # its reasons, where it is not read
        radiance = color * factor * (texture is None)
        return radiance.astype(np.float32), scaled_texture(texture, factor)

    def _in_use(self, socket) -> bool:
        """Whether a number socket of an input the kernels leave out is above 0, or fed by
        what the reader cannot hold as one number (read through groups: their values)."""
        value = self._read(socket, [])
        return value is None or value.texture is not None or value.const[0] > 0.0

    def _value(self, socket, ignored) -> float:
        """A number: the socket's chain of constants, the texture's mean where a texture drives
        it (noted), or its default where the chain is not modelled (noted by the reader)."""
        value = self._read(socket, ignored)
        if value is None:
            return float(socket.default_value)
        if value.texture is not None:
            return float(self._texture_constant(socket, value.texture, ignored)[0])
        return float(value.const[0])

    def _number(self, socket, ignored) -> tuple[float, Texture | None]:
        """A number that may come from a texture: (constant, None) or (default, texture)."""
        value = self._read(socket, ignored, bake=True)
        if value is None:
            return float(socket.default_value), None
        if value.texture is None:
            return float(value.const[0]), None
        return float(socket.default_value), value.texture

    def _alpha(self, socket, ignored) -> tuple[float, Texture | None]:
        """The Principled Alpha: (constant, None) or (1, texture). Read with its texture even
        when the bake reads no colours: coverage decides where shadows fall (a leaf card)."""
        value = self._read_or_bake(socket, self._any_texture(ignored), ignored, bake=True)
        if value is None:
            return min(max(float(socket.default_value), 0.0), 1.0), None
        if value.texture is None:
            return min(max(float(value.const[0]), 0.0), 1.0), None
        return 1.0, value.texture

    def _color(self, socket, ignored, textures=True) -> tuple[np.ndarray, Texture | None]:
        """A colour that may come from a texture: (constant, None) or (default, texture); with
        `textures` False a texture is noted and its mean used (`_texture_constant`)."""
        default = np.array(socket.default_value[:3], np.float32)
        value = self._read(socket, ignored, bake=textures)
        if value is None:
            return default, None
        if value.texture is None:
            return value.const.astype(np.float32), None
        if not textures:
            return self._texture_constant(socket, value.texture, ignored), None
        return default, value.texture

    @staticmethod
    def _texture_constant(socket, texture: Texture, ignored: list) -> np.ndarray:
        """(3,) float32: what stands for a texture driving a socket the kernels take as a
        constant: its mean over the image (`texture_mean`), noted; the socket's own value where
        it has none (a colour attribute)."""
        mean = texture_mean(texture)
        if mean is None:
            ignored.append(f"'{socket.name}' driven by a texture is not modelled: its default used")
            value = socket.default_value
            return np.array(value[:3] if hasattr(value, "__len__") else [value] * 3, np.float32)
        ignored.append(f"'{socket.name}' driven by a texture is not modelled: the texture's mean "
                       f"used")
        return mean

    def _uv_layer(self, node, ignored, what, generated: bool
                  ) -> tuple[bool, str | None, str, np.ndarray | None]:
        """(ok, uv layer name or None for the active render layer, "UV" or "GENERATED", a (2, 3)
        UV transform or None) of a texture node's Vector: unlinked, an Image Texture reads UVs
        and a Checker the Generated coordinates; a Mapping node of constants on UVs (glTF's
        KHR_texture_transform) becomes the transform. `generated`: whether this use can read
        Generated coordinates (base colours can; bump and normal maps, whose tangent frames
        follow the UVs, read UVs instead)."""
        vec_node, vec_socket, groups = follow_through(node.inputs["Vector"], self._groups)
        if vec_node is not None and vec_node.type == "MAPPING":
            with self._inside(groups):
                transform = mapping_transform(vec_node)
                inner = follow_through(vec_node.inputs["Vector"], groups)[0]
                if transform is None or inner is None:
                    ignored.append(f"{what}: a Mapping node with linked, 3D or unlinked inputs "
                                   f"is not modelled")
                    return False, None, "UV", None
                ok, layer, coordinates, _ = self._uv_layer(vec_node, ignored, what, False)
            return ok, layer, coordinates, transform
        if vec_node is None and node.type != "TEX_CHECKER":
            return True, None, "UV", None
        if vec_node is None or (vec_node.type == "TEX_COORD" and vec_socket.name == "Generated"):
            if generated:
                return True, None, "GENERATED", None
            ignored.append(f"{what}: a texture on Generated coordinates is read on UVs")
            return True, None, "UV", None
        if vec_node.type == "UVMAP":
            return True, (vec_node.uv_map or None), "UV", None
        if vec_node.type == "TEX_COORD" and vec_socket.name == "UV":
            return True, None, "UV", None
        ignored.append(f"{what}: texture coordinates from '{vec_node.bl_idname}' are not modelled")
        return False, None, "UV", None

    def _texture(self, node, ignored, what, generated: bool = True) -> Texture | None:
        if node.type in ("VERTEX_COLOR", "ATTRIBUTE"):  # read per corner (`attributes.py`)
            name = node.layer_name if node.type == "VERTEX_COLOR" else node.attribute_name
            return Texture(kind="ATTRIBUTE", name=name, coordinates="ATTRIBUTE",
                           extension="EXTEND")
        if node.type == "TEX_IMAGE":
            ok, uv_layer, coordinates, uv_transform = self._uv_layer(node, ignored, what, generated)
            if not ok:
                return None
            if node.projection != "FLAT":
                ignored.append(f"{what}: the image's {node.projection} projection is not "
                               f"modelled: read flat")
            if node.interpolation in ("Cubic", "Smart"):
                ignored.append(f"{what}: {node.interpolation} interpolation read as Linear")
            image = node.image
            pixels = udim = None
            if image is not None:
                if image.name not in self.images:
                    if image.source == "TILED":
                        self.images[image.name] = tile_pixels(image, decode=False) or None
                    else:
                        self.images[image.name] = image_pixels(image, decode=False)
                pixels = self.images[image.name]
                if isinstance(pixels, dict):  # UDIM tiles: `pixels` the largest
                    udim, pixels = pixels, max(pixels.values(), key=lambda p: p.shape[0] * p.shape[1])
            if pixels is None:
                missing = "no image" if image is None else f"image '{image.name}' has no pixels"
                ignored.append(f"{what}: {missing} (missing file?): magenta, as Cycles reads it")
                return Texture(kind="IMAGE", name=f"{what}: missing image",
                               pixels=np.array(MISSING_TEXEL, np.float32).reshape(1, 1, 4),
                               extension="EXTEND", interpolation="CLOSEST", uv_layer=uv_layer,
                               coordinates=coordinates, encoding="linear")
            return Texture(
                kind="IMAGE",
                name=image.name,
                pixels=pixels,
                extension=node.extension if node.extension != "MIRROR" else "MIRROR",
                interpolation="CLOSEST" if node.interpolation == "Closest" else "LINEAR",
                uv_layer=uv_layer,
                coordinates=coordinates,
                encoding="sRGB" if stored_srgb(image) else "linear",
                uv_transform=uv_transform,
                udim=udim,
            )
        if node.type == "TEX_CHECKER":
            ok, uv_layer, coordinates, uv_transform = self._uv_layer(node, ignored, what, generated)
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
                uv_transform=uv_transform,
            )
        return None

    def _normal(self, socket, ignored) -> Relief:
        """The relief feeding a Normal socket."""
        node, _, groups = follow_through(socket, self._groups)
        if node is None:
            return Relief()
        with self._inside(groups):
            return self._normal_node(node, ignored)

    def _normal_node(self, node, ignored) -> Relief:
        """`_normal` of the node feeding a Normal: a Normal Map, a Bump, or a Bump whose Normal
        a Normal Map feeds (the bump on the mapped normal, as Cycles chains them)."""
        if node.type == "NORMAL_MAP":
            if node.space != "TANGENT":
                ignored.append(f"normal map in {node.space} space is not modelled")
                return Relief()
            return Relief(normal_texture=self._texture_feeding(node.inputs["Color"], ignored,
                                                               "Normal Map"),
                          normal_strength=self._value(node.inputs["Strength"], ignored))
        if node.type == "BUMP":
            tex = self._height(node.inputs["Height"], ignored)
            below = self._normal(node.inputs["Normal"], ignored)
            if below.height_texture is not None:
                ignored.append("a Bump node's Normal input from another Bump node (chained "
                               "bumps) is not modelled: the inner one's height left out")
            distance = self._value(node.inputs["Distance"], ignored)
            # Invert: the height pushes the surface inwards, the same as a negated distance.
            return Relief(normal_texture=below.normal_texture,
                          normal_strength=below.normal_strength, height_texture=tex,
                          bump_strength=self._value(node.inputs["Strength"], ignored),
                          bump_distance=-distance if node.invert else distance)
        ignored.append(f"normal input from '{node.bl_idname}' is not modelled")
        return Relief()

    def _height(self, socket, ignored) -> Texture | None:
        """The height a Bump or Displacement node reads, as a texture on the UVs its slope is
        taken along: an image or checker with the node chain between it and the socket folded in
        (`socket_values.py`), or, where the reader cannot follow the chain (a procedural texture)
        or the texture reads other coordinates, the height Cycles bakes of the socket over the
        object's UVs (`SocketFallback`, named in `fallbacks`). None: unlinked, a constant (no
        relief either way), or neither (noted)."""
        if not socket.is_linked:
            return None
        value = self._read(socket, ignored, bake=True)
        if value is None or value.texture is None:
            return None
        if value.texture.coordinates == "UV":
            return value.texture
        why = f"a {socket.node.bl_label} height read along {value.texture.coordinates} coordinates"
        if self.fallback is not None and self._mat is not None and self.request.textures:
            texture, entry = self.fallback.texture(self._mat, socket, True, self._target)
            if texture is not None:
                self._baked.append(entry)
                return texture
            why += f" (not baked by Cycles: {entry})"
        ignored.append(f"{why} is not modelled")
        return None

    def _texture_feeding(self, socket, ignored, what) -> Texture | None:
        """The image or checker texture feeding `socket` directly (through reroutes and groups),
        read on UVs (a normal or bump map, whose tangent frames follow the UVs); else None."""
        node, _, groups = follow_through(socket, self._groups)
        if node is None or node.type not in ("TEX_IMAGE", "TEX_CHECKER"):
            return None
        with self._inside(groups):
            return self._texture(node, ignored, what, False)
