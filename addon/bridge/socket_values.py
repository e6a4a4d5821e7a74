"""What a shader socket reads: a constant, or a texture with the node chain between them folded in.

Artists' and importers' graphs put nodes between an Image Texture and the BSDF: the glTF importer
a Separate Color (metallic in blue, roughness in green of one image) and Math or Mix nodes for
its factors; texture libraries Invert, Gamma, ColorRamp, RGB Curves and Map Range. `SocketReader`
follows such a chain from a socket back to its source:

* linear nodes of constants (Math ADD / SUBTRACT / MULTIPLY / DIVIDE / MULTIPLY_ADD, Mix of a
  constant and a texture, Invert, Map Range LINEAR, Separate Color / RGB / XYZ channels) fold into
  the texture's `weights`, `gain`, `offset` and `clamp` (kernels/geometry/scene.py, `Texture`);
* point-wise curves (Gamma, Bright/Contrast, ColorRamp, RGB Curves, Float Curve, Hue/Saturation/
  Value of constants) are applied to the image's texels once (`bake_curve`): exact at texel
  centres, the same filtering Cycles does between them up to the curve's bend within one texel;
* Combine Color (RGB) and Combine XYZ of constants and at most one texture put that texture's
  number in its channel (`_combine`);
* node groups (the glTF importer's among them) are entered and left through their sockets, muted
  nodes pass their input through, reroutes are skipped;
* a Color Attribute or (geometry) Attribute node is a texture of kind ATTRIBUTE (vertex colours
  interpolated across each triangle, `attributes.py`); linear nodes fold into it as into an
  image, point-wise curves of it are not modelled (they would bend the interpolated colour);
* everything else is reported (one reason appended to `ignored`) and the socket's own value used
  (the material reader then has Cycles bake the socket where it can: `socket_fallback`).

A colour read where a number is wanted is its luminance (Rec. 709 weights, as Cycles converts),
a vector read as a number the mean of its components.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ...kernels.geometry.scene import Texture
from ...kernels.shading.hue_saturation import hue_saturation_value
from ...kernels.shading.textures import node_chain, srgb_to_linear
from .nodes import MAX_GROUP_DEPTH, follow, group_input_socket, group_output_socket

# Cycles' colour-to-number conversion (linear Rec. 709 luminance, the scene's default working space).
LUMINANCE = (0.2126, 0.7152, 0.0722)
# Texels of the look-up tables a ColorRamp or a curve is sampled into (inputs in [0, 1]).
CURVE_TABLE_SIZE = 1024

# (texture node, what, the Group nodes entered to reach it) -> Texture
TextureSource = Callable[[object, str, tuple], "Texture | None"]


@dataclass(frozen=True, eq=False)
class Value:
    """A socket's value: `const` (3,) where `texture` is None; else the texture's look-up."""

    const: np.ndarray
    texture: Texture | None = None

    def affine(self, gain, offset) -> Value | None:
        """value * gain + offset (per component), or None where a clamp comes before."""
        gain = np.broadcast_to(np.asarray(gain, np.float64), (3,))
        offset = np.broadcast_to(np.asarray(offset, np.float64), (3,))
        if self.texture is None:
            return Value(self.const * gain + offset)
        tex = self.texture
        if tex.clamp:
            return None
        return Value(self.const, replace(tex, gain=(tex.gain * gain).astype(np.float32),
                                         offset=(tex.offset * gain + offset).astype(np.float32)))

    def pick(self, weights) -> Value:
        """One number from (R, G, B, A) weights (4,), in all three components."""
        w = np.asarray(weights, np.float64)
        if self.texture is None:
            number = float(self.const @ w[:3] + w[3])
            return Value(np.full(3, number))
        tex = self.texture
        if tex.clamp:  # a clamped colour's channel: materialise the chain first
            tex = bake_curve(tex, lambda x: x)
        scaled = float(w[:3] @ tex.gain)
        if tex.weights is None:
            new = np.concatenate([w[:3] * tex.gain, w[3:]])
        else:
            new = scaled * np.asarray(tex.weights, np.float64) + np.array([0, 0, 0, w[3]])
        return Value(self.const, replace(tex, weights=new.astype(np.float32),
                                         gain=np.ones(3, np.float32),
                                         offset=np.full(3, w[:3] @ tex.offset, np.float32)))

    def clamped(self) -> Value:
        if self.texture is None:
            return Value(np.clip(self.const, 0.0, 1.0))
        return Value(self.const, replace(self.texture, clamp=True))


class NotFoldable(Exception):
    """A node chain that cannot be folded into its texture (the reader says so and moves on)."""


def bake_curve(texture: Texture, curve: Callable[[np.ndarray], np.ndarray]) -> Texture:
    """`texture` with its node chain and then `curve` ((N, 3) -> (N, 3) linear) applied to every
    texel (an image) or to both colours (a checker): a plain texture of the result. A colour
    attribute has no texels (Cycles bends the colour interpolated at each point): NotFoldable."""
    if texture.kind == "ATTRIBUTE":
        raise NotFoldable("a curve of a colour attribute")
    plain = dict(weights=None, gain=np.ones(3, np.float32), offset=np.zeros(3, np.float32),
                 clamp=False)
    if texture.kind == "CHECKER":
        ones = np.ones((2, 1), np.float32)
        colours = np.concatenate([np.stack([texture.color1, texture.color2]), ones], axis=1)
        out = curve(node_chain(texture, colours).astype(np.float64)).astype(np.float32)
        return replace(texture, color1=out[0], color2=out[1], **plain)
    height, width, _ = texture.pixels.shape
    rgba = texture.pixels.reshape(-1, 4).astype(np.float32, copy=True)
    if texture.encoding == "sRGB":
        rgba[:, :3] = srgb_to_linear(rgba[:, :3])
    out = curve(node_chain(texture, rgba).astype(np.float64))
    pixels = np.concatenate([out.astype(np.float32), rgba[:, 3:]], axis=1)
    return replace(texture, pixels=pixels.reshape(height, width, 4), encoding="linear", **plain)


def pointwise(value: Value, curve: Callable[[np.ndarray], np.ndarray]) -> Value:
    """`curve` ((N, 3) -> (N, 3)) applied to a value: to a constant at once, to a texture's texels."""
    if value.texture is None:
        return Value(np.asarray(curve(value.const[None].astype(np.float64)), np.float64)[0])
    return Value(value.const, bake_curve(value.texture, curve))


def socket_constant(socket) -> np.ndarray:
    """(3,) float64 of an unlinked socket's own value (a number in all three)."""
    value = getattr(socket, "default_value", 0.0)
    try:
        seq = np.asarray(value[:], np.float64)
    except TypeError:
        return np.full(3, float(value))
    if socket.type == "RGBA":
        return seq[:3]
    if socket.type == "VECTOR":
        return np.resize(seq, 3)
    return np.full(3, float(seq.mean()))


def _convert(value: Value, from_type: str, to_type: str) -> Value:
    """Cycles' implicit conversion between socket types (colour or vector to a number)."""
    if to_type == "VALUE" and from_type == "RGBA":
        return value.pick((*LUMINANCE, 0.0))
    if to_type == "VALUE" and from_type == "VECTOR":
        return value.pick((1 / 3, 1 / 3, 1 / 3, 0.0))
    return value


class SocketReader:
    """Reads sockets of one material's tree; `texture_of(node, what, groups)` makes a kernel
    `Texture` of an Image or Checker Texture node reached inside the Group nodes `groups` (or
    None, having said why in `ignored`)."""

    def __init__(self, texture_of: TextureSource, ignored: list):
        self.texture_of = texture_of
        self.ignored = ignored

    def read(self, socket, what: str, groups: tuple = ()) -> Value | None:
        """The value `socket` reads, or None (its reason in `ignored`) where the chain feeding it
        is not modelled."""
        node, out = follow(socket)
        if node is None:
            return Value(socket_constant(socket))
        try:
            value = self._node(node, out, what, groups)
        except NotFoldable as why:
            self._say(what, node, f"{why} is not modelled")
            return None
        return None if value is None else _convert(value, out.type, socket.type)

    def _say(self, what: str, node, why: str = "not modelled") -> None:
        self.ignored.append(f"'{what}' driven by a '{node.bl_idname}' node: {why}; its default used")

    def _node(self, node, out, what: str, groups: tuple) -> Value | None:
        kind = node.type
        if node.mute:
            through = [link for link in node.internal_links if link.to_socket == out]
            return self.read(through[0].from_socket, what, groups) if through else Value(
                np.zeros(3))
        if kind == "VALUE":
            return Value(np.full(3, float(out.default_value)))
        if kind == "RGB":
            return Value(np.asarray(out.default_value[:3], np.float64))
        if kind in ("TEX_IMAGE", "TEX_CHECKER"):
            return self._texture(node, out, what, groups)
        if kind in ("SEPARATE_COLOR", "SEPRGB", "SEPXYZ"):
            return self._separate(node, out, what, groups)
        if kind == "MATH":
            return self._math(node, what, groups)
        if kind in ("MIX", "MIX_RGB"):
            return self._mix(node, what, groups)
        if kind == "INVERT":
            fac = self._constant(node.inputs["Fac"], what, groups)
            colour = self.read(node.inputs["Color"], what, groups)
            if fac is None or colour is None:
                return None
            return colour.affine(1.0 - 2.0 * fac, fac)
        if kind == "MAP_RANGE":
            return self._map_range(node, what, groups)
        if kind in ("GAMMA", "BRIGHTCONTRAST", "VALTORGB", "CURVE_RGB", "CURVE_FLOAT"):
            return self._curve(node, out, what, groups)
        if kind == "HUE_SAT":
            return self._hue_saturation(node, what, groups)
        if kind in ("COMBINE_COLOR", "COMBRGB", "COMBXYZ"):
            return self._combine(node, what, groups)
        if kind == "GROUP":
            return self._group(node, out, what, groups)
        if kind == "GROUP_INPUT" and groups:
            socket = group_input_socket(groups, node, out)
            return None if socket is None else self.read(socket, what, groups[:-1])
        if kind in ("ATTRIBUTE", "VERTEX_COLOR"):
            return self._attribute(node, out, what, groups)
        self._say(what, node)
        return None

    def _constant(self, socket, what, groups) -> float | None:
        """A number that must be constant (a factor), or None (said why)."""
        value = self.read(socket, what, groups)
        if value is None:
            return None
        if value.texture is not None:
            self.ignored.append(f"'{what}': a texture as the factor of '{socket.node.name}' is "
                                f"not modelled; its default used")
            return None
        return float(value.const[0])

    def _attribute(self, node, out, what, groups) -> Value | None:
        """A Color Attribute or geometry Attribute node's colour (its Fac: the channels' mean); an
        Attribute node naming none reads 0 in Cycles (measured)."""
        if node.type == "ATTRIBUTE" and node.attribute_type != "GEOMETRY":
            self._say(what, node, "an attribute of an object, instancer or view layer is not "
                      "modelled")
            return None
        if node.type == "ATTRIBUTE" and not node.attribute_name:
            return Value(np.zeros(3))
        if out.name == "Alpha":
            self._say(what, node, "a colour attribute's alpha is not modelled")
            return None
        texture = self.texture_of(node, what, groups)
        if texture is None:
            return None
        value = Value(np.zeros(3), texture)
        return value.pick((1 / 3, 1 / 3, 1 / 3, 0.0)) if out.identifier == "Fac" else value

    def _texture(self, node, out, what, groups) -> Value | None:
        texture = self.texture_of(node, what, groups)
        if texture is None:
            return None
        value = Value(np.zeros(3), texture)
        if out.name == "Alpha":
            return value.pick((0.0, 0.0, 0.0, 1.0))
        if node.type == "TEX_CHECKER" and out.identifier == "Fac":  # 1 on colour 1's squares
            return Value(np.zeros(3), replace(texture, color1=np.ones(3, np.float32),
                                              color2=np.zeros(3, np.float32)))
        return value

    def _separate(self, node, out, what, groups) -> Value | None:
        if node.type == "SEPARATE_COLOR" and node.mode != "RGB":
            self._say(what, node, f"{node.mode} channels are not modelled")
            return None
        source = self.read(node.inputs[0], what, groups)
        if source is None:
            return None
        index = {"Red": 0, "R": 0, "X": 0, "Green": 1, "G": 1, "Y": 1,
                 "Blue": 2, "B": 2, "Z": 2}.get(out.name)
        if index is None:
            self._say(what, node, f"output '{out.name}' is not modelled")
            return None
        weights = np.zeros(4)
        weights[index] = 1.0
        return source.pick(weights)

    def _math(self, node, what, groups) -> Value | None:
        op = node.operation
        sockets = [s for s in node.inputs if s.enabled]
        values = [self.read(s, what, groups) for s in sockets]
        if any(v is None for v in values):
            return None
        textured = [k for k, v in enumerate(values) if v.texture is not None]
        result = None
        if not textured:
            c = [v.const[0] for v in values]
            table = {"ADD": lambda: c[0] + c[1], "SUBTRACT": lambda: c[0] - c[1],
                     "MULTIPLY": lambda: c[0] * c[1],
                     "DIVIDE": lambda: c[0] / c[1] if c[1] != 0.0 else 0.0,
                     "MULTIPLY_ADD": lambda: c[0] * c[1] + c[2],
                     "POWER": lambda: c[0] ** c[1] if c[0] > 0.0 else 0.0,
                     "MINIMUM": lambda: min(c[0], c[1]), "MAXIMUM": lambda: max(c[0], c[1])}
            if op in table:
                result = Value(np.full(3, float(table[op]())))
        elif len(textured) == 1:
            k = textured[0]
            tex, others = values[k], [v.const[0] for j, v in enumerate(values) if j != k]
            if op == "ADD":
                result = tex.affine(1.0, others[0])
            elif op == "SUBTRACT":
                result = tex.affine(1.0, -others[0]) if k == 0 else tex.affine(-1.0, others[0])
            elif op == "MULTIPLY":
                result = tex.affine(others[0], 0.0)
            elif op == "DIVIDE" and k == 0 and others[0] != 0.0:
                result = tex.affine(1.0 / others[0], 0.0)
            elif op == "MULTIPLY_ADD" and k < 2:
                result = tex.affine(others[0], others[1])
        if result is None:
            self._say(what, node, f"Math '{op}' of these inputs is not modelled")
            return None
        return result.clamped() if node.use_clamp else result

    def _mix(self, node, what, groups) -> Value | None:
        legacy = node.type == "MIX_RGB"
        if legacy:
            fac_socket, a_socket, b_socket = node.inputs["Fac"], node.inputs[1], node.inputs[2]
            blend, clamp = node.blend_type, node.use_clamp
        else:
            if node.data_type not in ("FLOAT", "RGBA"):
                self._say(what, node, f"a {node.data_type} mix is not modelled")
                return None
            fac_socket, a_socket, b_socket = [s for s in node.inputs if s.enabled][:3]
            blend = node.blend_type if node.data_type == "RGBA" else "MIX"
            clamp = node.data_type == "RGBA" and node.clamp_result
        a, b = self.read(a_socket, what, groups), self.read(b_socket, what, groups)
        fac_value = self.read(fac_socket, what, groups)
        if a is None or b is None or fac_value is None:
            return None
        result = None
        if fac_value.texture is not None:
            # (1 - f) A + f B of constants A, B: linear in the factor (a mask between colours)
            if blend == "MIX" and a.texture is None and b.texture is None:
                result = fac_value.affine(b.const - a.const, a.const)
        else:
            f = float(fac_value.const[0])
            if legacy or getattr(node, "clamp_factor", True):
                f = min(max(f, 0.0), 1.0)
            result = self._blend(blend, f, a, b)
        if result is None:
            self._say(what, node, f"a '{blend}' mix of these inputs is not modelled")
            return None
        return result.clamped() if clamp else result

    @staticmethod
    def _blend(blend: str, f: float, a: Value, b: Value) -> Value | None:
        """Cycles' MIX, MULTIPLY, ADD and SUBTRACT blends with a constant factor, where at most one
        side is a texture."""
        if a.texture is not None and b.texture is not None:
            return None
        if a.texture is None and b.texture is None:
            ops = {"MIX": lambda x, y: (1 - f) * x + f * y,
                   "MULTIPLY": lambda x, y: x * ((1 - f) + f * y),
                   "ADD": lambda x, y: x + f * y, "SUBTRACT": lambda x, y: x - f * y}
            return Value(ops[blend](a.const, b.const)) if blend in ops else None
        if a.texture is not None:  # A textured, B constant
            gains = {"MIX": (1 - f, f * b.const), "MULTIPLY": ((1 - f) + f * b.const, 0.0),
                     "ADD": (1.0, f * b.const), "SUBTRACT": (1.0, -f * b.const)}
            return a.affine(*gains[blend]) if blend in gains else None
        gains = {"MIX": (f, (1 - f) * a.const), "MULTIPLY": (f * a.const, (1 - f) * a.const),
                 "ADD": (f, a.const), "SUBTRACT": (-f, a.const)}
        return b.affine(*gains[blend]) if blend in gains else None

    def _map_range(self, node, what, groups) -> Value | None:
        if node.data_type != "FLOAT" or node.interpolation_type != "LINEAR":
            self._say(what, node, f"{node.interpolation_type} mapping is not modelled")
            return None
        sockets = [s for s in node.inputs if s.enabled][:5]
        value = self.read(sockets[0], what, groups)
        bounds = [self._constant(s, what, groups) for s in sockets[1:5]]
        if value is None or any(b is None for b in bounds):
            return None
        from_min, from_max, to_min, to_max = bounds
        if from_max == from_min:
            return Value(np.full(3, to_min))
        scale = (to_max - to_min) / (from_max - from_min)
        result = value.affine(scale, to_min - from_min * scale)
        if result is not None and node.clamp and to_min == 0.0 and to_max == 1.0:
            result = result.clamped()
        elif result is not None and node.clamp:
            lo, hi = min(to_min, to_max), max(to_min, to_max)
            result = pointwise(result, lambda x: np.clip(x, lo, hi))
        return result

    def _curve(self, node, out, what, groups) -> Value | None:
        kind = node.type
        if kind == "GAMMA":
            gamma = self._constant(node.inputs["Gamma"], what, groups)
            source = self.read(node.inputs["Color"], what, groups)
            if gamma is None or source is None:
                return None
            return pointwise(source, lambda x: np.where(x > 0.0, np.abs(x) ** gamma, x))
        if kind == "BRIGHTCONTRAST":
            bright = self._constant(node.inputs["Bright"], what, groups)
            contrast = self._constant(node.inputs["Contrast"], what, groups)
            source = self.read(node.inputs["Color"], what, groups)
            if bright is None or contrast is None or source is None:
                return None
            a, b = 1.0 + contrast, bright - contrast * 0.5  # Cycles' svm_brightness_contrast
            return pointwise(source, lambda x: np.maximum(a * x + b, 0.0))
        if kind == "VALTORGB":
            source = self.read(node.inputs["Fac"], what, groups)
            if source is None:
                return None
            ramp = node.color_ramp
            xs = np.linspace(0.0, 1.0, CURVE_TABLE_SIZE)
            table = np.array([ramp.evaluate(float(x)) for x in xs], np.float64)  # (K, 4)
            lut = np.repeat(table[:, 3:4], 3, axis=1) if out.name == "Alpha" else table[:, :3]
            return pointwise(source, lambda x: _lookup(lut, x[:, :1]))
        mapping = node.mapping
        fac = self._constant(node.inputs["Fac"], what, groups)
        source = self.read(node.inputs[1], what, groups)
        if fac is None or source is None:
            return None
        mapping.initialize()
        xs = np.linspace(0.0, 1.0, CURVE_TABLE_SIZE)
        if kind == "CURVE_FLOAT":
            lut = np.array([[mapping.evaluate(mapping.curves[0], float(x))] for x in xs])
            return pointwise(source, lambda x: (1 - fac) * x + fac * _lookup(lut, x[:, :1]))
        combined = mapping.curves[3]
        lut = np.array([[mapping.evaluate(mapping.curves[c], mapping.evaluate(combined, float(x)))
                         for c in range(3)] for x in xs])
        return pointwise(source, lambda x: (1 - fac) * x + fac * np.column_stack(
            [_lookup(lut[:, c:c + 1], x[:, c:c + 1])[:, 0] for c in range(3)]))

    def _hue_saturation(self, node, what, groups) -> Value | None:
        """Hue/Saturation/Value with constant hue, saturation, value and factor, point-wise."""
        names = ("Hue", "Saturation", "Value", "Fac")
        constants = [self._constant(node.inputs[name], what, groups) for name in names]
        source = self.read(node.inputs["Color"], what, groups)
        if source is None or any(c is None for c in constants):
            return None
        hue, saturation, value, fac = constants
        return pointwise(source, lambda x: hue_saturation_value(x, hue, saturation, value, fac))

    def _combine(self, node, what, groups) -> Value | None:
        """Combine Color (RGB) or Combine XYZ of constants and at most one texture: the texture's
        number (each input reads one) in its channel, the constants in theirs."""
        if node.type == "COMBINE_COLOR" and node.mode != "RGB":
            self._say(what, node, f"{node.mode} channels are not modelled")
            return None
        sockets = [s for s in node.inputs if s.enabled][:3]
        values = [self.read(s, what, groups) for s in sockets]
        if any(v is None for v in values):
            return None
        textured = [k for k, v in enumerate(values) if v.texture is not None]
        consts = np.array([v.const[0] if v.texture is None else 0.0 for v in values])
        if not textured:
            return Value(consts)
        if len(textured) > 1:
            self._say(what, node, "more than one texture combined is not modelled")
            return None
        k = textured[0]
        result = values[k].affine(np.eye(3)[k], consts)
        if result is None:
            self._say(what, node, "a clamped texture combined is not modelled")
        return result

    def _group(self, node, out, what, groups) -> Value | None:
        if node.node_tree is None or len(groups) >= MAX_GROUP_DEPTH:
            self._say(what, node, "an empty or too deeply nested group")
            return None
        socket = group_output_socket(node, out)
        if socket is None:
            self._say(what, node, "its output is not found in the group")
            return None
        return self.read(socket, what, groups + (node,))


def _lookup(table: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(N, C) linear interpolation in a (K, C) table over [0, 1] at x (N, 1), clamped."""
    k = len(table) - 1
    pos = np.clip(x[:, 0], 0.0, 1.0) * k
    i = np.minimum(pos.astype(np.int64), k - 1)
    t = (pos - i)[:, None]
    return table[i] * (1.0 - t) + table[i + 1] * t
