"""Linear float images to and from OpenEXR files (the `OpenEXR` package), bit-exact.

Images are (H, W, C) float32 with row 0 at the top (the file's first scanline). Channel names follow
the OpenEXR convention: 1 channel "Y", 3 "R", "G", "B", 4 "R", "G", "B", "A". No transfer curve is
applied: what is written is scene-linear data, as Cycles writes its renders.
"""

from __future__ import annotations

import os

import numpy as np

CHANNEL_NAMES = {1: ("Y",), 3: ("R", "G", "B"), 4: ("R", "G", "B", "A")}


def write_exr(path: str | os.PathLike, pixels: np.ndarray, *, half: bool = False) -> None:
    """Write (H, W), (H, W, 1), (H, W, 3) or (H, W, 4) pixels to `path` (ZIP compression).

    `half` stores 16-bit floats (smaller files, lossy); the default float32 round-trips bit-exactly.
    """
    import OpenEXR

    pixels = np.asarray(pixels)
    if pixels.ndim == 2:
        pixels = pixels[:, :, None]
    if pixels.ndim != 3 or pixels.shape[2] not in CHANNEL_NAMES:
        raise ValueError(f"write_exr: expected (H, W, 1|3|4) pixels, got shape {pixels.shape}")
    dtype = np.float16 if half else np.float32
    names = CHANNEL_NAMES[pixels.shape[2]]
    channels = {n: np.ascontiguousarray(pixels[:, :, k], dtype=dtype) for k, n in enumerate(names)}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, channels) as f:
        f.write(os.fspath(path))


def read_exr(path: str | os.PathLike) -> np.ndarray:
    """Read an OpenEXR file into (H, W, C) float32, channels ordered as `CHANNEL_NAMES` when they
    match (Y / RGB / RGBA), otherwise alphabetically. Half-float files are widened to float32."""
    import OpenEXR

    with OpenEXR.File(os.fspath(path), separate_channels=True) as f:
        channels = {name: ch.pixels for name, ch in f.channels().items()}
    names = sorted(channels)
    for known in CHANNEL_NAMES.values():
        if sorted(known) == names:
            names = list(known)
            break
    return np.stack([channels[n].astype(np.float32, copy=False) for n in names], axis=-1)
