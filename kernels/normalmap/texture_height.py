"""A material's own Bump-node height as a height source for normal maps.

The bridge reads a Bump node's Height as a kernel `Texture` (`Material.height_texture`: an image
or a checker, with its encoding, node chain and UV transform); `TextureHeight` looks it up exactly
as the shading kernels do (`shading.textures.sample_texture`, bilinear between texel centres, the
colour turned into a height by its Rec. 709 luminance, `shading.bump.LUMINANCE`), times a signed
factor (an inverted Bump node's heights point inwards: factor -1). So a procedural bump becomes a
texture an engine can use.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.scene import Texture
from ..shading.bump import LUMINANCE
from ..shading.textures import sample_texture

# UVs evaluated per call of `sample_texture` (bounds the temporaries of a 4096^2 map's band).
_CHUNK = 1 << 18


@dataclass(frozen=True, eq=False)
class TextureHeight:
    """Heights of a kernel `Texture` (a Bump node's Height input).

    | name    | range   | default | unit   | meaning                                        |
    |---------|---------|---------|--------|------------------------------------------------|
    | texture | Texture |         |        | the image or checker feeding the Bump's Height |
    | factor  | any     | 1.0     |        | heights times this (-1: an inverted Bump node) |
    """

    texture: Texture
    factor: float = 1.0

    @property
    def resolution(self) -> tuple[int, int] | None:
        """(W, H) texels of an image; None for a checker (no texels of its own)."""
        if self.texture.kind == "IMAGE" and self.texture.pixels is not None:
            return int(self.texture.pixels.shape[1]), int(self.texture.pixels.shape[0])
        return None

    def heights(self, uv: np.ndarray) -> np.ndarray:
        """(N,) float64 heights at (N, 2) UVs."""
        uv = np.asarray(uv, np.float64)
        out = np.empty(len(uv))
        for start in range(0, len(uv), _CHUNK):
            rgb = sample_texture(self.texture, uv[start:start + _CHUNK])
            out[start:start + _CHUNK] = rgb.astype(np.float64) @ LUMINANCE
        return out * self.factor
