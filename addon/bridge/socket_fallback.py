"""The general fallback for a material socket whose node graph the bridge cannot read
(`SocketFallback`): Cycles bakes the socket's value over the object's UVs
(`cycles.socket_bake`), and the kernels read that image as the socket's texture.

So no socket the kernels model as a texture (base colour, emission colour, metallic, roughness)
is silently replaced by its default: it is read as Cycles shades it, at the bake's resolution,
and the bake and its cost are named in the material's `fallbacks`. Bakes are cached (in memory,
for the session) by a digest of the node tree, the socket, the object's geometry and UVs and
the bake settings, so a second snapshot of the same scene does not bake again.
"""

from __future__ import annotations

import hashlib
from collections import OrderedDict
from dataclasses import dataclass, field

import bpy
import numpy as np

from ...kernels.geometry.scene import Texture
from ..cycles.socket_bake import bake_socket
from .mesh import MeshChunk
from .request import SocketBakeSettings
from .tree_digest import tree_digest

# Bakes kept for reuse, least recently used dropped first: each holds size^2 x 16 bytes
# (1 MiB at the default 256), so the cache stays below ~64 MiB at that size.
CACHE_ENTRIES = 64
_CACHE: OrderedDict[str, tuple[np.ndarray, float]] = OrderedDict()


def clear_cache() -> None:
    """Forget every cached bake (the next snapshot bakes again)."""
    _CACHE.clear()


@dataclass
class BakeTarget:
    """The object a material is read for: its original object, the depsgraph it is evaluated in
    and its mesh chunk (whose geometry and UVs the cache key covers, digested once)."""

    source: object
    depsgraph: object
    chunk: MeshChunk
    _digest: str | None = field(default=None, repr=False)

    @property
    def digest(self) -> str:
        if self._digest is None:
            h = hashlib.sha256(self.source.name_full.encode())
            for array in (self.chunk.triangles, self.chunk.uv, self.chunk.generated,
                          self.chunk.slot_ids):
                h.update(b"-" if array is None else np.ascontiguousarray(array).tobytes())
            self._digest = h.hexdigest()
        return self._digest


class SocketFallback:
    """Bakes sockets the `SocketReader` cannot read, under one `SocketBakeSettings`."""

    def __init__(self, settings: SocketBakeSettings):
        self.settings = settings

    def texture(self, material, socket, as_number: bool, target: BakeTarget | None,
                strength=None, blend: tuple | None = None) -> tuple[Texture | None, dict | str]:
        """(the socket's texture, its report entry {socket, read_as, seconds, cached, object}),
        or (None, why it cannot be baked). With `strength` (an emission's strength socket of the
        same node), the texture is the colour times the strength: the emitted radiance. With
        `blend` (a factor socket, another socket), it is the two sockets' values mixed by the
        factor's (`bake_socket`)."""
        if target is None:
            return None, "no object to bake it over"
        if target.chunk.uv is None:
            return None, f"object '{target.source.name}' has no UV map to bake it over"
        sockets = [socket, *(blend or ())]
        if any(s.node.id_data != material.node_tree for s in sockets):
            return None, "the socket is inside a node group"
        uv_layer = _render_uv_layer(target.source.evaluated_get(target.depsgraph).data)
        blend_ids = None if blend is None else tuple((b.node.name, b.identifier) for b in blend)
        s = self.settings
        key = hashlib.sha256(repr((
            tree_digest(material.node_tree), socket.node.name, socket.identifier, as_number,
            None if strength is None else strength.identifier,
            blend_ids, target.digest, uv_layer,
            s.size, s.samples, s.margin, bpy.app.version,
        )).encode()).hexdigest()
        cached = key in _CACHE
        if cached:
            _CACHE.move_to_end(key)
            pixels, seconds = _CACHE[key]
        else:
            pixels, seconds = bake_socket(target.source, target.depsgraph, material,
                                          socket.node.name, socket.identifier, as_number,
                                          uv_layer, s.size, s.samples, s.margin,
                                          None if strength is None else strength.identifier,
                                          blend_ids)
            _CACHE[key] = (pixels, seconds)
            while len(_CACHE) > CACHE_ENTRIES:
                _CACHE.popitem(last=False)
        texture = Texture(kind="IMAGE", name=f"{material.name}: {socket.name} (Cycles bake)",
                          pixels=pixels, extension="EXTEND", interpolation="LINEAR",
                          encoding="linear")
        name = socket.name if strength is None else f"{socket.name} x {strength.name}"
        if blend is not None:
            name = f"{socket.name} mixed by {blend[0].node.name}"
        entry = {"socket": name, "read_as": f"Cycles bake {s.size}x{s.size}",
                 "seconds": round(float(seconds), 4), "cached": cached,
                 "object": target.source.name}
        return texture, entry


def _render_uv_layer(mesh) -> str:
    """The name of the UV layer Cycles renders with (the one the kernels' `Scene.uv` holds)."""
    layers = mesh.uv_layers
    return next((layer.name for layer in layers if layer.active_render), layers[0].name)
