"""The world shader as the kernels see it: a uniform background colour (`read_world`) and, where
there is one, an equirectangular radiance map (`read_world_texture`): read from an Environment
Texture, or rendered by Cycles (`cycles.world_map`) where the bridge cannot read the shader."""

from __future__ import annotations

import numpy as np

from ...kernels.geometry.scene import Texture
from ...kernels.shading.textures import MISSING_TEXEL
from ..cycles.world_map import render_world_map
from .images import image_pixels
from .nodes import active_output, follow, node_tree


def read_world(scene, mapped=None) -> tuple[np.ndarray, list[str]]:
    """The uniform background radiance (3,) of the world (an Environment Texture's mean over the
    sphere), and what was ignored. mapped: the world's map as `read_world_texture` read it, when
    the caller has it (its mean is taken from those pixels instead of reading the image again)."""
    world = scene.world
    if world is None:
        return np.zeros(3, np.float32), []
    tree = node_tree(world)
    if tree is None:
        return np.array(world.color[:3], np.float32), []
    unread = _world_render_reason(scene)
    if unread is not None and mapped is not None:  # rendered by `read_world_texture`
        width, height = mapped.pixels.shape[1], mapped.pixels.shape[0]
        note = f"world: {unread}, rendered by Cycles into a {width} x {height} map"
        if _has_light_path(world):
            note += (" as diffuse rays see it through its Light Path node (the map lights the "
                     "surfaces), and again as camera rays see it (the background)")
        return _equirect_mean(mapped.pixels), [note]
    output = active_output(tree, "OUTPUT_WORLD")
    if output is None:
        return np.zeros(3, np.float32), ["world has no World Output node: black"]
    node, _ = follow(output.inputs["Surface"])
    if node is None:
        return np.zeros(3, np.float32), []
    if node.type != "BACKGROUND":
        return np.zeros(3, np.float32), [f"world shader '{node.bl_idname}' is not modelled: black"]
    ignored = []
    color = np.array(node.inputs["Color"].default_value[:3], np.float32)
    color_node, _ = follow(node.inputs["Color"])
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
    elif color_node is not None and color_node.type == "TEX_ENVIRONMENT":
        color = np.array(MISSING_TEXEL[:3], np.float32)
        what = "no image" if color_node.image is None else f"image '{color_node.image.name}'"
        ignored.append(f"world: the Environment Texture's {what} has no pixels (missing "
                       "file?): magenta, as Cycles renders it")
    elif color_node is not None:
        ignored.append(f"world colour from '{color_node.bl_idname}' is not modelled: the "
                       "socket's own colour used")
    return color * strength, ignored


# The world's ray visibility flags the kernels honour (`Scene.world_hidden_from`); its shadow and
# volume-scatter flags change nothing they model.
WORLD_RAY_KINDS = ("camera", "diffuse", "glossy", "transmission")


def world_hidden_from(scene) -> tuple[str, ...]:
    """The ray kinds Cycles hides the scene's world from (World > Settings > Ray Visibility);
    () for none or no world."""
    flags = getattr(scene.world, "cycles_visibility", None) if scene.world is not None else None
    return tuple(kind for kind in WORLD_RAY_KINDS if not getattr(flags, kind, True))


def world_volume_notes(scene) -> list[str]:
    """A note where the world's Volume output is linked (fog, god rays): Cycles fills the scene
    with it, the kernels see clear air; [] otherwise."""
    world = scene.world
    tree = node_tree(world) if world is not None else None
    output = active_output(tree, "OUTPUT_WORLD") if tree is not None else None
    node = follow(output.inputs["Volume"])[0] if output is not None else None
    if node is None:
        return []
    return [f"world: a volume shader ('{node.bl_idname}') fills the scene in Cycles; not "
            f"modelled, the kernels see clear air"]


def _world_surface(scene):
    """The shader node feeding the scene's world output (None: no world, no nodes, no output or
    nothing linked to it)."""
    world = scene.world
    tree = node_tree(world) if world is not None else None
    output = active_output(tree, "OUTPUT_WORLD") if tree is not None else None
    return follow(output.inputs["Surface"])[0] if output is not None else None


def _world_map_nodes(scene):
    """(Background node, equirectangular Environment Texture node feeding its colour) of the
    scene's world, or None where the world is not that."""
    node = _world_surface(scene)
    if node is None or node.type != "BACKGROUND":
        return None
    env = follow(node.inputs["Color"])[0]
    if env is None or env.type != "TEX_ENVIRONMENT" or env.image is None \
            or env.projection != "EQUIRECTANGULAR":
        return None
    return node, env


def world_env_mapping(scene) -> np.ndarray | None:
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
    (`cycles.world_map.render_world_map`). Else None (the kernels use `read_world`'s uniform
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
    # no Cycles in this build: None, and `read_world` notes the shader as not read
    return _rendered_map(scene.world, _has_light_path(scene.world), "rendered")


def read_camera_world(scene, render: bool = True):
    """The world as camera rays see it, rendered by Cycles into an equirectangular map (a kernel
    `Texture`), where that differs from what lights the surfaces (`read_world_texture` renders a
    world with a Light Path node as diffuse rays see it: a backdrop shown to the camera, a map
    lighting the scene); None otherwise."""
    if not render or scene.world is None or not _has_light_path(scene.world) \
            or _world_render_reason(scene) is None:
        return None
    return _rendered_map(scene.world, False, "as the camera sees it")


def _rendered_map(world, lighting: bool, what: str) -> Texture | None:
    """`world` rendered by Cycles into an equirectangular map (`render_world_map`, as diffuse
    rays see it with `lighting`), a kernel `Texture` named '<world> (<what>)'; None where this
    build has no Cycles."""
    try:
        rgb, _ = render_world_map(world, lighting=lighting)
    except RuntimeError:
        return None
    pixels = np.concatenate([rgb, np.ones(rgb.shape[:2] + (1,), np.float32)], axis=-1)
    return Texture(kind="IMAGE", name=f"{world.name} ({what})", pixels=pixels,
                   extension="REPEAT", interpolation="LINEAR")


def _has_light_path(world) -> bool:
    """Whether the world's own node tree holds a Light Path node."""
    tree = node_tree(world)
    return tree is not None and any(n.type == "LIGHT_PATH" for n in tree.nodes)


def _world_render_reason(scene) -> str | None:
    """What of the world's shader the bridge cannot read itself (a few words), or None where it
    reads all of it: no world, a world colour, nothing linked to the output, or a Background of
    an unlinked strength whose colour is constant or an equirectangular Environment Texture,
    read along the world direction or through a Mapping node `world_mapping` models (one without
    an image is magenta, `read_world`)."""
    node = _world_surface(scene)
    if node is None:
        return None
    if node.type != "BACKGROUND":
        return f"the shader '{node.bl_idname}'"
    if node.inputs["Strength"].is_linked:
        return "a strength fed by a node"
    color = follow(node.inputs["Color"])[0]
    if color is None:
        return None
    if color.type != "TEX_ENVIRONMENT":
        return f"a colour from '{color.bl_idname}'"
    if color.image is None:
        return None
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
    mapping, _ = follow(env.inputs["Vector"])
    if mapping is None:
        return identity
    if mapping.type != "MAPPING" or mapping.vector_type not in ("POINT", "VECTOR", "TEXTURE"):
        return None
    source, socket = follow(mapping.inputs["Vector"])
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
