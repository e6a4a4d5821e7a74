"""Texture mapping: image and procedural (checkerboard) textures looked up through UVs.

The lecture's two sources of texture images: "computer programs (e.g. checkerboard)" and "digital
cameras (image files)". Both are sampled the way Cycles samples them, so a kernel render and a
Cycles render of the same material agree texel for texel:

* image lookup: texel centres sit at ((i + 0.5) / W, (j + 0.5) / H) in UV; bilinear weights between
  the four nearest centres (Cycles' `kernel_tex_image_interp` with `INTERPOLATION_LINEAR`);
* wrap modes: REPEAT (periodic), EXTEND (clamp to the edge texel), CLIP (outside [0, 1] is
  transparent black, and bilinear lookups near the border blend towards it), MIRROR;
* 8-bit sRGB images: interpolated in their sRGB encoding and decoded after the look-up (Cycles'
  byte textures with `compress_as_srgb`; measured against its colour bake, bench/texture.py);
* UDIM tiles: (u, v) reads tile 1001 + tx + 10 ty at (u - tx, v - ty), with tx, ty the integer
  parts truncated towards zero (so u in (-1, 0) reads tile 1001 through its extension); a tile
  the image lacks, or tx outside [0, 10), reads magenta (measured in Cycles renders);
* checker: Cycles' `svm_checker` on (u, v, 0) or on Generated coordinates (x, y, z): colour1
  where floor(x s) + floor(y s) + floor(z s) is odd. Coordinates are (N, 2) (z = 0) or (N, 3).

Box means (`sample_texture_box`, the tracer's pixel filter): exact for the checker; an image box
of more than a texel reads a mip pyramid of 2 x 2 means (trilinear between its two nearest levels),
a box of a texel or less the image at the box's centre.
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import replace

import numpy as np

from ..geometry.scene import Texture

# What Cycles reads where an image has no pixels (a missing file, or a UDIM tile the image lacks):
# colour (1, 0, 1), alpha 1 (measured: a plane of that base colour renders magenta, opaque).
MISSING_TEXEL = (1.0, 0.0, 1.0, 1.0)

# Tiles per UDIM row: tile 1001 + tx + UDIM_ROW * ty.
UDIM_ROW = 10

# A texture's mean (`texture_mean`) reads at most this many texels per image (a regular subset
# of a larger one): a bound on work for a value that stands in for the whole image.
MEAN_TEXELS = 65536

# Cycles nudges checker coordinates by (p + 1e-6) * 0.999999 so that integer lattice points fall
# on a definite side; the same nudge keeps our squares aligned with its squares.
CHECKER_NUDGE_ADD = 1e-6
CHECKER_NUDGE_MUL = 0.999999


def _wrap_index(i: np.ndarray, n: int, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """Integer texel indices wrapped by `mode`: (index in [0, n), valid mask for CLIP)."""
    if mode == "REPEAT":
        return np.mod(i, n), np.ones(i.shape, bool)
    if mode == "MIRROR":
        period = np.mod(i, 2 * n)
        return np.where(period < n, period, 2 * n - 1 - period), np.ones(i.shape, bool)
    valid = (i >= 0) & (i < n)
    return np.clip(i, 0, n - 1), (valid if mode == "CLIP" else np.ones(i.shape, bool))


def sample_image(
    pixels: np.ndarray,
    uv: np.ndarray,
    extension: str = "REPEAT",
    interpolation: str = "LINEAR",
    out: np.ndarray | None = None,
) -> np.ndarray:
    """Look up (N, 2) UVs in an (H, W, C) image (row 0 top). Returns (N, C) float32.

    | parameter     | values                        | default | meaning                         |
    |---------------|-------------------------------|---------|---------------------------------|
    | extension     | REPEAT, EXTEND, CLIP, MIRROR  | REPEAT  | what lies outside [0, 1]^2      |
    | interpolation | LINEAR, CLOSEST               | LINEAR  | bilinear or nearest texel       |
    """
    height, width, channels = pixels.shape
    uv = np.asarray(uv, np.float64)
    # Continuous texel coordinates: x grows with u, y with v; image row = H - 1 - y.
    x = uv[:, 0] * width - 0.5
    y = uv[:, 1] * height - 0.5
    if out is None:
        out = np.empty((uv.shape[0], channels), np.float32)
    if interpolation == "CLOSEST":
        ix, vx = _wrap_index(np.floor(x + 0.5).astype(np.int64), width, extension)
        iy, vy = _wrap_index(np.floor(y + 0.5).astype(np.int64), height, extension)
        np.multiply(pixels[height - 1 - iy, ix], (vx & vy)[:, None], out=out)
        return out
    x0 = np.floor(x)
    y0 = np.floor(y)
    fx, fy = x - x0, y - y0
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    ix0, vx0 = _wrap_index(x0, width, extension)
    ix1, vx1 = _wrap_index(x0 + 1, width, extension)
    iy0, vy0 = _wrap_index(y0, height, extension)
    iy1, vy1 = _wrap_index(y0 + 1, height, extension)
    # Rows of the flattened image: one gather of whole texels each (faster than 2-D indexing).
    flat = pixels.reshape(-1, channels)
    r0, r1 = (height - 1 - iy0) * width, (height - 1 - iy1) * width
    gx, gy = 1.0 - fx, 1.0 - fy
    corners = ((r0 + ix0, gx * gy * (vx0 & vy0)), (r0 + ix1, fx * gy * (vx1 & vy0)),
               (r1 + ix0, gx * fy * (vx0 & vy1)), (r1 + ix1, fx * fy * (vx1 & vy1)))
    acc = None
    for index, weight in corners:
        term = np.take(flat, index, axis=0) * weight[:, None]
        acc = term if acc is None else np.add(acc, term, out=acc)
    out[...] = acc
    return out


def udim_tiles(uv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(tile numbers (N,) int64, -1 where no tile can hold them; (N, 2) the tile's corner) of
    (N, 2+) UVs: Cycles' integer parts, truncated towards zero, and rows of UDIM_ROW tiles."""
    corner = np.trunc(np.asarray(uv, np.float64)[:, :2])
    valid = (corner[:, 0] >= 0) & (corner[:, 1] >= 0) & (corner[:, 0] < UDIM_ROW)
    number = 1001 + corner[:, 0] + UDIM_ROW * corner[:, 1]
    return np.where(valid, number, -1).astype(np.int64), corner


def sample_tiles(tiles: dict[int, np.ndarray], uv: np.ndarray, extension: str = "REPEAT",
                 interpolation: str = "LINEAR") -> np.ndarray:
    """Look up (N, 2) UVs in a tiled (UDIM) image {number: (H, W, C)}: each tile read as
    `sample_image` reads one image at the UVs less its corner (so the extension and the bilinear
    filter act within a tile); MISSING_TEXEL where no tile holds a UV. Returns (N, C) float32."""
    channels = next(iter(tiles.values())).shape[2]
    out = np.empty((len(uv), channels), np.float32)
    out[:] = MISSING_TEXEL[:channels]
    number, corner = udim_tiles(uv)
    for n in np.unique(number):
        pixels = tiles.get(int(n))
        if pixels is not None:
            rows = np.flatnonzero(number == n)
            out[rows] = sample_image(pixels, uv[rows, :2] - corner[rows], extension, interpolation)
    return out


def checker(uv: np.ndarray, color1: np.ndarray, color2: np.ndarray, scale: float) -> np.ndarray:
    """Cycles' Checker Texture at coordinates uv (N, 2) (z = 0) or (N, 3) -> (N, 3) float32.
    Cycles' z = 0 nudges to floor 0, so (u, v) and (u, v, 0) agree."""
    p = (np.asarray(uv, np.float64) * scale + CHECKER_NUDGE_ADD) * CHECKER_NUDGE_MUL
    parity = np.floor(p).astype(np.int64).sum(axis=1) % 2
    # An odd sum (with z = 0: x and y of different parity) -> colour 1, even -> colour 2.
    return np.where(parity[:, None] == 1, np.asarray(color1, np.float32)[None],
                    np.asarray(color2, np.float32)[None]).astype(np.float32)


# Below this width (in checker squares) a box is a point: its mean is the value at its centre.
MIN_BOX_WIDTH = 1e-9


def _triangle_wave(x: np.ndarray) -> np.ndarray:
    """S(x) = 1 - |(x mod 2) - 1|, the integral of the square wave s(x) = (-1)^floor(x).
    x - 2 floor(x / 2) is x mod 2 exactly (Sterbenz: x and the even integer are within 2x), and
    several times faster than np.mod."""
    return 1.0 - np.abs(x - 2.0 * np.floor(0.5 * x) - 1.0)


def _square_wave_mean(x0: np.ndarray, x1: np.ndarray) -> np.ndarray:
    """Mean of s(x) = (-1)^floor(x) over [x0, x1] (N,), via its integral, the triangle wave
    S(x) (S rises on [0, 1), falls on [1, 2))."""
    width = x1 - x0
    wide = width > MIN_BOX_WIDTH
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (_triangle_wave(x1) - _triangle_wave(x0)) / np.where(wide, width, 1.0)
    if wide.all():
        return mean
    point = np.where(np.floor(0.5 * (x0 + x1)) % 2.0 == 0.0, 1.0, -1.0)
    return np.where(wide, mean, point)


def checker_box(lo: np.ndarray, hi: np.ndarray, color1: np.ndarray, color2: np.ndarray,
                scale: float) -> np.ndarray:
    """Cycles' Checker Texture averaged over boxes [lo, hi] (N, 2) or (N, 3) -> (N, 3) float64.

    Exact: with s(x) = (-1)^floor(x), the parity sign is the product of s over the coordinates,
    and its mean over a box is the product of the square waves' means (separable); colour 1
    covers (1 - mean) / 2. A coordinate whose boxes are all one point (z = 0 of UV coordinates)
    contributes one sign, computed once.
    """
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    sign = np.ones(lo.shape[0])
    for c in range(lo.shape[1]):
        a, b = lo[:, c], hi[:, c]
        if a.size and (a == a[0]).all() and (b == a[0]).all():
            a, b = a[:1], b[:1]
        p0 = (a * scale + CHECKER_NUDGE_ADD) * CHECKER_NUDGE_MUL
        p1 = (b * scale + CHECKER_NUDGE_ADD) * CHECKER_NUDGE_MUL
        sign *= _square_wave_mean(p0, p1)
    share1 = (0.5 * (1.0 - sign))[:, None]
    return share1 * np.asarray(color1, np.float64) + (1.0 - share1) * np.asarray(color2, np.float64)


# An image box wider than this many texels (its longer side) is read from the mip pyramid; up to
# it, at its centre: a texel's worth of box is what bilinear interpolation already spans.
MIP_MIN_TEXELS = 1.0
# Mip pyramids kept (the most recently used): one per image texture in use, 1/3 of its size.
PYRAMID_CACHE = 8
_pyramids: OrderedDict = OrderedDict()
# Image rows decoded at a time while the pyramid's first level is built (even: whole 2 x 2 blocks);
# a 4096-wide image's band of float32 colour stays 25 MB.
PYRAMID_BAND = 512


def sample_texture_box(texture: Texture, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """RGB (N, 3) of a texture averaged over boxes [lo, hi] (N, 2 or 3): exact for the checker;
    an image's boxes of at most MIP_MIN_TEXELS texels are read at their centre (bilinear), wider
    ones from the mip pyramid (`_mip_mean`)."""
    if texture.kind == "CHECKER" and texture.uv_transform is None:
        mean = checker_box(lo, hi, texture.color1, texture.color2, texture.scale)
        return node_chain(texture, mean).astype(np.float64) if texture.transformed else mean
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    centre = 0.5 * (lo + hi)
    # A checker under a UV transform, or a colour attribute: linear across the box, so its
    # centre holds its mean.
    if texture.kind in ("CHECKER", "ATTRIBUTE"):
        return sample_texture(texture, centre).astype(np.float64)
    extent = hi[:, :2] - lo[:, :2]  # the box's sides in UV
    if texture.uv_transform is not None:  # the sides of the box around the moved box
        extent = extent @ np.abs(np.asarray(texture.uv_transform, np.float64)[:, :2]).T
    if texture.udim is not None:
        return _tile_boxes(texture, centre, extent)
    height, width = texture.pixels.shape[:2]
    texels = np.maximum(extent[:, 0] * width, extent[:, 1] * height)
    wide = texels > MIP_MIN_TEXELS
    out = np.empty((len(centre), 3))
    out[~wide] = sample_texture(texture, centre[~wide])
    if wide.any():
        out[wide] = _mip_mean(texture, centre[wide], texels[wide])
    return out


def _tile_boxes(texture: Texture, centre: np.ndarray, extent: np.ndarray) -> np.ndarray:
    """RGB (N, 3) box means of a tiled image: each box, centre (N, 2+) and sides (N, 2) in moved
    UVs, read in the tile that holds its centre as one image's box is (a box across a tile's
    edge sees that tile's extension, as a Cycles look-up there does)."""
    moved = _moved(texture, centre)
    number, corner = udim_tiles(moved)
    out = np.empty((len(centre), 3))
    for n in np.unique(number):
        rows = np.flatnonzero(number == n)
        pixels = texture.udim.get(int(n))
        if pixels is None:  # magenta, through the node chain
            out[rows] = sample_texture(texture, centre[rows])
            continue
        tile = replace(texture, pixels=pixels, udim=None, uv_transform=None)
        local = moved[rows, :2] - corner[rows]
        half = 0.5 * extent[rows]
        out[rows] = sample_texture_box(tile, local - half, local + half)
    return out


def _mip_mean(texture: Texture, uv: np.ndarray, texels: np.ndarray) -> np.ndarray:
    """RGB (N, 3) float64: the image's mean over boxes `texels` (N,) texels wide at uv (N, 2+),
    from the pyramid level of 2^k texels, k = log2(texels), interpolated between the two nearest
    levels (trilinear). Exact for boxes of 2^k texels on the level's texel grid of an image whose
    sides are powers of two; near that elsewhere (odd sides share their texels out by area)."""
    levels = _pyramid(texture)
    if len(levels) == 1:  # a single texel: no pyramid
        return sample_texture(texture, uv).astype(np.float64)
    uv = _moved(texture, uv)
    lam = np.clip(np.log2(texels), 0.0, len(levels) - 1)
    lower = np.floor(lam).astype(np.int64)
    frac = (lam - lower)[:, None]
    rgb = np.empty((len(uv), 3))
    for k in np.unique(lower):
        rows = lower == k
        near = _read_level(texture, levels, k, uv[rows])
        if k + 1 < len(levels):
            near += frac[rows] * (_read_level(texture, levels, k + 1, uv[rows]) - near)
        rgb[rows] = near
    return node_chain(texture, rgb).astype(np.float64) if texture.transformed else rgb


def _read_level(texture: Texture, levels: list, k: int, uv: np.ndarray) -> np.ndarray:
    """Linear RGB (N, 3) float64 of pyramid level k at uv (N, 2+), bilinear; level 0 is the
    image itself, read as `sample_texture` reads it (decoded after interpolation)."""
    rgb = sample_image(levels[k], uv, texture.extension)[:, :3]
    if k == 0 and texture.encoding == "sRGB":
        rgb = srgb_to_linear(rgb)
    return rgb.astype(np.float64)


def _pyramid(texture: Texture) -> list[np.ndarray]:
    """The image's mip levels: level 0 the image as stored, then (ceil(H / 2^k), ceil(W / 2^k), 3)
    float32 linear colour (decoded from sRGB), each texel the area mean of what it covers below
    (`_halved`), down to one texel."""
    key = id(texture.pixels)
    cached = _pyramids.get(key)
    if cached is not None and cached[0] is texture.pixels and cached[1] == texture.encoding:
        _pyramids.move_to_end(key)
        return cached[2]
    levels = [texture.pixels]
    height, width = texture.pixels.shape[:2]
    if height > 1 or width > 1:
        # decoded a band of rows at a time where the rows pair up (an even height)
        band_rows = PYRAMID_BAND if height % 2 == 0 else height
        first = np.empty(((height + 1) // 2, (width + 1) // 2, 3), np.float32)
        for top in range(0, height, band_rows):
            band = np.asarray(texture.pixels[top:top + band_rows, :, :3], np.float32)
            if texture.encoding == "sRGB":
                band = srgb_to_linear(band)
            first[top // 2:(top + len(band) + 1) // 2] = _halved(band)
        levels.append(first)
    while max(levels[-1].shape[:2]) > 1:
        levels.append(_halved(levels[-1]))
    _pyramids[key] = (texture.pixels, texture.encoding, levels)
    while len(_pyramids) > PYRAMID_CACHE:
        _pyramids.popitem(last=False)
    return levels


def _halved(a: np.ndarray) -> np.ndarray:
    """The next mip level of an (H, W, C) array: (ceil(H / 2), ceil(W / 2), C), each texel the
    area mean of the texels it covers: 2 x 2 blocks where both sides are even; an odd side's n
    texels are shared out over ceil(n / 2), each spanning n / ceil(n / 2) of them."""
    for axis in (0, 1):
        a = _halved_along(a, axis)
    return a


def _halved_along(a: np.ndarray, axis: int) -> np.ndarray:
    """`_halved` along one axis of `a`."""
    n = a.shape[axis]
    if n == 1:
        return a
    a = np.moveaxis(a, axis, 0)
    if n % 2 == 0:
        return np.moveaxis(0.5 * (a[0::2] + a[1::2]), 0, axis)
    m = (n + 1) // 2
    span = n / m  # input texels per output texel, in (1, 2)
    lo = np.arange(m) * span  # output texel j covers [lo_j, lo_j + span) of the input
    first = np.floor(lo).astype(np.int64)
    out = np.zeros((m,) + a.shape[1:], np.float32)
    shape = (m,) + (1,) * (a.ndim - 1)
    for step in range(3):  # a span under 2 texels touches at most 3 of them
        i = first + step
        inside = i < n
        i = np.minimum(i, n - 1)
        overlap = np.clip(np.minimum(i + 1, lo + span) - np.maximum(i, lo), 0.0, None) * inside
        out += (overlap / span).astype(np.float32).reshape(shape) * a[i]
    return np.moveaxis(out, 0, axis)


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB EOTF (IEC 61966-2-1): encoded values in [0, 1] to linear."""
    c = np.asarray(c, np.float32)
    return np.where(c <= 0.04045, c / 12.92, np.power((np.maximum(c, 0.0) + 0.055) / 1.055, 2.4))


def sample_texture(texture: Texture, uv: np.ndarray) -> np.ndarray:
    """RGB (N, 3) float32 linear of a kernel `Texture` at coordinates (N, 2) or (N, 3) (an image
    reads the first two): an sRGB-encoded image is interpolated as stored and decoded
    afterwards, as Cycles does; then the texture's node chain (`Texture.weights`, `gain`,
    `offset`, `clamp`) applies."""
    uv = _moved(texture, np.asarray(uv))
    if texture.kind == "CHECKER":
        rgba = checker(uv, texture.color1, texture.color2, texture.scale)
    elif texture.kind == "ATTRIBUTE":  # the interpolated colour is the coordinate
        rgba = np.concatenate([uv[:, :3], np.ones((len(uv), 1))], axis=1).astype(np.float32)
    else:
        if texture.udim is None:
            rgba = sample_image(texture.pixels, uv[:, :2], texture.extension, texture.interpolation)
        else:
            rgba = sample_tiles(texture.udim, uv[:, :2], texture.extension, texture.interpolation)
        if texture.encoding == "sRGB":
            rgba[:, :3] = srgb_to_linear(rgba[:, :3])
    if not texture.transformed:
        return np.ascontiguousarray(rgba[:, :3])
    return node_chain(texture, rgba)


def texture_mean(texture: Texture) -> np.ndarray | None:
    """(3,) float32: the texture's value (node chain included) averaged over its image, every
    tile of a UDIM one (a regular subset of at most MEAN_TEXELS texels per tile), or its two
    colours' mean for a checker; None for a colour attribute (values per vertex, no image).
    What stands for a texture where a socket can only take a constant."""
    if texture.kind == "ATTRIBUTE":
        return None
    if texture.kind == "CHECKER":
        rgba = np.array([[*texture.color1[:3], 1.0], [*texture.color2[:3], 1.0]], np.float32)
    else:
        tiles = [texture.pixels] if texture.udim is None else list(texture.udim.values())
        parts = []
        for tile in tiles:
            step = max(1, int(np.ceil(np.sqrt(tile.shape[0] * tile.shape[1] / MEAN_TEXELS))))
            parts.append(tile[::step, ::step].reshape(-1, tile.shape[-1]).astype(np.float32))
        rgba = np.concatenate(parts)
        if texture.encoding == "sRGB":
            rgba[:, :3] = srgb_to_linear(rgba[:, :3])
    return node_chain(texture, rgba).mean(axis=0).astype(np.float32)


def _moved(texture: Texture, uv: np.ndarray) -> np.ndarray:
    """Coordinates (N, 2+) through the texture's affine UV transform (a Mapping node), if any."""
    if texture.uv_transform is None:
        return uv
    a = np.asarray(texture.uv_transform, np.float64)
    moved = uv.astype(np.float64, copy=True)
    moved[:, :2] = uv[:, :2] @ a[:, :2].T + a[:, 2]
    return moved


def node_chain(texture: Texture, rgba: np.ndarray) -> np.ndarray:
    """What the texture's node chain makes of looked-up colours (N, 3 or 4) (alpha 1 where
    absent): its weights, gain, offset and clamp (`Texture`). Returns (N, 3) float32."""
    if texture.weights is None:
        value = rgba[:, :3]
    else:
        w = np.asarray(texture.weights, np.float64)
        one = rgba[:, :3] @ w[:3] + (rgba[:, 3] * w[3] if rgba.shape[1] > 3 else w[3])
        value = np.repeat(one[:, None], 3, axis=1)
    value = value * texture.gain + texture.offset
    if texture.clamp:
        value = np.clip(value, 0.0, 1.0)
    return value.astype(np.float32)
