"""PNG previews of linear HDR images and error maps, for reports. Pure functions, no Blender.

Images follow the kernel convention: (H, W, C) float, linear Rec. 709, row 0 at the top (as in PNG
files), C = 1, 3 or 4; a (H, W) array is a single channel. Previews apply an exposure in stops,
clamp to [0, 1] and encode with the sRGB transfer curve (IEC 61966-2-1), 8 bits per channel.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

# sRGB transfer curve (IEC 61966-2-1): linear segment below this linear value, power curve above.
SRGB_LINEAR_CUTOFF = 0.0031308


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Encode linear values with the sRGB curve after clamping to [0, 1]; NaN becomes 0.

    Returns float32 of the same shape, in [0, 1].
    """
    x = np.nan_to_num(np.asarray(linear, dtype=np.float32), nan=0.0, posinf=1.0, neginf=0.0)
    x = np.clip(x, 0.0, 1.0)
    low = 12.92 * x
    high = 1.055 * np.power(x, 1.0 / 2.4, dtype=np.float32) - 0.055
    return np.where(x <= SRGB_LINEAR_CUTOFF, low, high).astype(np.float32)


def _as_hwc(image: np.ndarray) -> np.ndarray:
    array = np.asarray(image)
    if array.ndim == 2:
        array = array[:, :, None]
    if array.ndim != 3 or array.shape[2] not in (1, 3, 4):
        raise ValueError(f"expected a (H, W) or (H, W, 1|3|4) image, got {array.shape}")
    return array


def preview_rgb8(
    image: np.ndarray, exposure_stops: float = 0.0, keep_alpha: bool = False
) -> np.ndarray:
    """(H, W, 3) uint8 sRGB preview of a linear image (or (H, W, 4) with `keep_alpha`).

    Colour is scaled by 2**exposure_stops, clamped and sRGB-encoded; one channel becomes grey;
    alpha (when kept) is clamped to [0, 1] and stored linearly, as PNG expects.
    """
    hwc = _as_hwc(image).astype(np.float32)
    colour = hwc[:, :, :3] if hwc.shape[2] >= 3 else np.repeat(hwc, 3, axis=2)
    encoded = linear_to_srgb(colour * np.float32(2.0**exposure_stops))  # (H, W, 3), [0, 1]
    if keep_alpha and hwc.shape[2] == 4:
        alpha = np.clip(np.nan_to_num(hwc[:, :, 3:4], nan=0.0), 0.0, 1.0)
        encoded = np.concatenate([encoded, alpha], axis=2)
    return np.round(encoded * 255.0).astype(np.uint8)


def error_rgb8(
    error: np.ndarray, vmax: float | None = None, cmap: str = "magma"
) -> np.ndarray:
    """(H, W, 3) uint8 false-colour image of a (H, W) non-negative error map.

    0 maps to the colour map's low end and `vmax` (default: the map's largest finite value, or
    1 if that is 0) to its high end; values above are clamped. FLIP maps use vmax = 1.
    """
    import matplotlib

    values = np.asarray(error, dtype=np.float64)
    if values.ndim == 3 and values.shape[2] == 1:
        values = values[:, :, 0]
    if values.ndim != 2:
        raise ValueError(f"expected a (H, W) error map, got {values.shape}")
    values = np.nan_to_num(values, nan=0.0, posinf=np.inf, neginf=0.0)
    if vmax is None:
        finite = values[np.isfinite(values)]
        vmax = float(finite.max()) if finite.size else 0.0
        vmax = vmax if vmax > 0.0 else 1.0
    if not vmax > 0.0:
        raise ValueError(f"vmax must be > 0, got {vmax}")
    scaled = np.clip(values / vmax, 0.0, 1.0)
    rgba = matplotlib.colormaps[cmap](scaled)  # (H, W, 4) float in [0, 1]
    return np.round(rgba[:, :, :3] * 255.0).astype(np.uint8)


def encode_png(rgb8: np.ndarray) -> bytes:
    """PNG bytes of a (H, W), (H, W, 3) or (H, W, 4) uint8 array, row 0 at the top.

    A plain encoder (zlib + the PNG chunk layout of RFC 2083, filter type 0 on every row), so
    previews need no imaging library: Blender's Python has none.
    """
    import struct
    import zlib

    array = np.ascontiguousarray(rgb8)
    if array.dtype != np.uint8:
        raise ValueError(f"write_png takes uint8 pixels, got {array.dtype}")
    if array.ndim == 3 and array.shape[2] == 1:
        array = array[:, :, 0]
    height, width = array.shape[:2]
    # PNG colour types: 0 greyscale, 2 RGB, 6 RGBA.
    colour_type = 0 if array.ndim == 2 else {3: 2, 4: 6}[array.shape[2]]
    rows = array.reshape(height, -1)
    raw = np.concatenate([np.zeros((height, 1), np.uint8), rows], axis=1).tobytes()

    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))

    header = struct.pack(">IIBBBBB", width, height, 8, colour_type, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header)
            + chunk(b"IDAT", zlib.compress(raw, 6)) + chunk(b"IEND", b""))


def write_png(path: str | Path, rgb8: np.ndarray) -> Path:
    """Write a (H, W, 3|4) or (H, W) uint8 array as PNG (row 0 at the top). Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(encode_png(rgb8))
    return path


def write_preview_png(
    path: str | Path, image: np.ndarray, exposure_stops: float = 0.0, keep_alpha: bool = False
) -> Path:
    """`preview_rgb8` written as PNG. Returns the path."""
    return write_png(path, preview_rgb8(image, exposure_stops, keep_alpha))


def write_error_png(
    path: str | Path, error: np.ndarray, vmax: float | None = None, cmap: str = "magma"
) -> Path:
    """`error_rgb8` written as PNG. Returns the path."""
    return write_png(path, error_rgb8(error, vmax, cmap))
