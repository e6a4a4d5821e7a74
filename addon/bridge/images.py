"""Blender images read as kernel pixel arrays (H, W, 4) float32, row 0 at the top.

Blender stores rows bottom-up, kernels top-down (`flip_rows`). Byte images in sRGB are decoded to
linear on reading, except where a texture keeps its encoding and decodes each look-up after
interpolation, as Cycles does (`Texture.encoding`, `stored_srgb`).
"""

from __future__ import annotations

import numpy as np

# What Cycles reads from an Image or Environment Texture node whose image is missing (its file
# not found) or unset: colour (1, 0, 1), alpha 1 (measured: a plane of that base colour under a
# sun renders magenta at 3 / pi per W/m^2, and opaque; a world of it shows (1, 0, 1) x strength).
MISSING_IMAGE_TEXEL = (1.0, 0.0, 1.0, 1.0)


def flip_rows(pixels: np.ndarray) -> np.ndarray:
    """Kernel images are top row first, Blender's bottom row first; the same flip goes both ways."""
    return pixels[::-1]


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB EOTF (IEC 61966-2-1), applied to colour channels of byte images."""
    c = np.asarray(c, np.float32)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)


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
    pixels = flip_rows(buf.reshape(height, width, 4)).copy()
    if decode and stored_srgb(image):
        pixels[..., :3] = srgb_to_linear(pixels[..., :3])
    return pixels
