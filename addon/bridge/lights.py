"""Blender lights as kernel `Light`s: Blender's power turned into radiometric quantities by
`kernels/shading/lights.py` (intensity, irradiance, radiance)."""

from __future__ import annotations

import numpy as np

from ...kernels.geometry.scene import Light
from ...kernels.shading import lights as light_units
from .nodes import active_output, follow, node_tree
from .transforms import unit


def light_power(light) -> tuple[float, np.ndarray]:
    """(power or strength scalar, linear colour (3,)) of a Blender light, exposure included."""
    power = float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))
    color = np.array(light.color[:3], np.float64)
    if getattr(light, "use_temperature", False):
        color = color * np.array(light.temperature_color[:3], np.float64)
    return power, color


def unnormalized_factor(light) -> float:
    """What Cycles multiplies a Blender point, spot or sun light's power by when its `normalize`
    is off (its emitter's area, `lights.unnormalized_scale`); 1 when on, and for area lights
    (their radiance takes it: `lights.area_radiance`)."""
    if light.type == "AREA" or getattr(light, "normalize", True):
        return 1.0
    return light_units.unnormalized_scale(light.type, float(getattr(light, "shadow_soft_size", 0.0)),
                                          float(getattr(light, "angle", 0.0)))


def light_node_factor(tree) -> tuple[np.ndarray, str | None]:
    """What a light's node tree multiplies its light by, (3,), as Cycles renders it: the Emission
    node's colour times its strength (1 without a tree or an Emission). Read: constant sockets,
    a Color from an RGB node, a Strength from a Light Falloff's Quadratic output of Smooth 0 (its
    Strength: Blender's lamps fall off as 1/d^2 already). Anything else: (1, 1, 1) and why."""
    ones = np.ones(3)
    output = None if tree is None else active_output(tree, "OUTPUT_LIGHT")
    node = None if output is None else follow(output.inputs["Surface"])[0]
    if node is None:
        return ones, None
    if node.type != "EMISSION":
        return ones, f"light nodes ({node.bl_label} into the output) are not modelled"
    color, strength = node.inputs["Color"], node.inputs["Strength"]
    value = np.array(color.default_value[:3], np.float64)
    if color.is_linked:
        source, _ = follow(color)
        if source is None or source.type != "RGB":
            return ones, "light nodes (a Color not from an RGB node) are not modelled"
        value = np.array(source.outputs[0].default_value[:3], np.float64)
    scale = float(strength.default_value)
    if strength.is_linked:
        source, socket = follow(strength)
        if (source is None or source.type != "LIGHT_FALLOFF" or socket.name != "Quadratic"
                or any(s.is_linked for s in source.inputs)
                or float(source.inputs["Smooth"].default_value) != 0.0):
            return ones, ("light nodes (a Strength other than a Light Falloff's Quadratic of "
                          "Smooth 0) are not modelled")
        scale = float(source.inputs["Strength"].default_value)
    return value * scale, None


def is_portal(light) -> bool:
    """Whether `light` is a Cycles portal (an area light marked so, Light > Portal): it emits
    nothing and is unseen, a hint for sampling the world through a window; no light at all to
    the kernels."""
    return light.type == "AREA" and bool(getattr(getattr(light, "cycles", None), "is_portal", False))


def read_light(name: str, light, matrix: np.ndarray) -> tuple[Light, list[str]]:
    """A Blender light datablock placed by `matrix` (4, 4) as a kernel `Light`, plus what was ignored."""
    ignored: list[str] = []
    rot = matrix[:3, :3]
    scale = np.linalg.norm(rot, axis=0)
    position = matrix[:3, 3].copy()
    axis_x, axis_y = unit(rot[:, 0]), unit(rot[:, 1])
    direction = unit(-rot[:, 2])
    power, color = light_power(light)
    power *= unnormalized_factor(light)
    common = dict(name=name, position=position, direction=direction, axis_x=axis_x, axis_y=axis_y,
                  cast_shadow=bool(getattr(light, "use_shadow", True)))
    factor, why = light_node_factor(node_tree(light))
    color = color * factor
    if why is not None:
        ignored.append(f"light '{name}': {why}")
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
