"""Blender images read as kernel pixel arrays (H, W, 4) float32, row 0 at the top.

Blender stores rows bottom-up, kernels top-down (`flip_rows`). Byte images in sRGB are decoded to
linear on reading, except where a texture keeps its encoding and decodes each look-up after
interpolation, as Cycles does (`Texture.encoding`, `stored_srgb`).
"""

from __future__ import annotations

import os
import tempfile

import bpy
import numpy as np

from ...kernels.shading.textures import UDIM_ROW

# Blender's tokens for a UDIM tile in an image's path: <UDIM> is the tile number (1001 ...),
# <UVTILE> u{tx + 1}_v{ty + 1}.
UDIM_TOKEN, UVTILE_TOKEN = "<UDIM>", "<UVTILE>"


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


def tile_path(image, number: int) -> str:
    """The absolute path of tile `number` of a tiled image (its tokens filled in)."""
    path = bpy.path.abspath(image.filepath, library=image.library)
    tx, ty = (number - 1001) % UDIM_ROW, (number - 1001) // UDIM_ROW
    return path.replace(UDIM_TOKEN, str(number)).replace(UVTILE_TOKEN, f"u{tx + 1}_v{ty + 1}")


def tile_pixels(image, decode: bool = True) -> dict[int, np.ndarray]:
    """A tiled (UDIM) image's tiles {number: (H, W, 4) float32, as `image_pixels` reads them}.

    `Image.pixels` holds one tile only, so each tile's file (or packed data) is loaded as an image
    of its own in the tiled image's colour space, read, and removed. Tiles that do not load are
    left out: Cycles reads them magenta, as the kernels do (`sample_tiles`)."""
    packed = {p.tile_number: p.packed_file for p in image.packed_files}
    tiles = {}
    for tile in image.tiles:
        path = tile_path(image, tile.number)
        if tile.number in packed:  # written out to be loaded as a file
            with tempfile.TemporaryDirectory(prefix="classic_bake_tile_") as folder:
                copy = os.path.join(folder, f"tile{os.path.splitext(path)[1]}")
                with open(copy, "wb") as f:
                    f.write(packed[tile.number].data)
                pixels = _file_pixels(copy, image, decode)
        else:
            pixels = _file_pixels(path, image, decode) if os.path.isfile(path) else None
        if pixels is not None:
            tiles[tile.number] = pixels
    return tiles


def _file_pixels(path: str, like, decode: bool) -> np.ndarray | None:
    """An image file's pixels read as `image_pixels` reads them, in the colour space and alpha
    mode of the image `like`; None if Blender cannot read it. Nothing is left in bpy.data."""
    try:
        loaded = bpy.data.images.load(path, check_existing=False)
    except RuntimeError:  # not an image Blender reads
        return None
    try:
        loaded.colorspace_settings.name = like.colorspace_settings.name
        loaded.alpha_mode = like.alpha_mode
        return image_pixels(loaded, decode)
    finally:
        bpy.data.images.remove(loaded)
