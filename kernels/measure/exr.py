"""Linear float images to and from OpenEXR files (the `OpenEXR` package), bit-exact.

Images are (H, W, C) float32 with row 0 at the top (the file's first scanline). Channel names follow
the OpenEXR convention: 1 channel "Y", 3 "R", "G", "B", 4 "R", "G", "B", "A". No transfer curve is
applied: what is written is scene-linear data, as Cycles writes its renders.

`read_exr_pass` reads one render pass of a multilayer file as Blender writes them: channels named
"<view layer>.<pass>.<channel>", in one part (Blender 4.x, and 5.x's "Interleave" option) or in
one part per pass (Blender 5.x's default multi-part files).
"""

from __future__ import annotations

import os

import numpy as np

CHANNEL_NAMES = {1: ("Y",), 3: ("R", "G", "B"), 4: ("R", "G", "B", "A")}


def write_exr(path: str | os.PathLike, pixels: np.ndarray, *, half: bool = False,
              header: dict | None = None) -> None:
    """Write (H, W), (H, W, 1), (H, W, 3) or (H, W, 4) pixels to `path` (ZIP compression).

    `half` stores 16-bit floats (smaller files, lossy); the default float32 round-trips bit-exactly.
    `header` adds (or overrides) header attributes as the `OpenEXR` package spells them, e.g.
    {"envmap": OpenEXR.ENVMAP_CUBE}; None writes the default header alone.
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
    attributes = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    attributes.update(header or {})
    with OpenEXR.File(attributes, channels) as f:
        f.write(os.fspath(path))


def _ordered(names) -> list[str]:
    """Channel names in `CHANNEL_NAMES` order when they are Y / RGB / RGBA, else alphabetical."""
    names = sorted(names)
    for known in CHANNEL_NAMES.values():
        if sorted(known) == names:
            return list(known)
    return names


def read_exr(path: str | os.PathLike) -> np.ndarray:
    """Read an OpenEXR file into (H, W, C) float32, channels ordered as `CHANNEL_NAMES` when they
    match (Y / RGB / RGBA), otherwise alphabetically. Half-float files are widened to float32."""
    import OpenEXR

    with OpenEXR.File(os.fspath(path), separate_channels=True) as f:
        channels = {name: ch.pixels for name, ch in f.channels().items()}
    return np.stack([channels[n].astype(np.float32, copy=False) for n in _ordered(channels)],
                    axis=-1)


def read_exr_pass(path: str | os.PathLike, pass_names: str | tuple[str, ...],
                  layer: str | None = None) -> np.ndarray:
    """Read one pass of a multilayer OpenEXR file into (H, W, C) float32, channels ordered as in
    `read_exr`. The pass is the first of `pass_names` present (a pass's name can differ between
    Blender versions, e.g. "DiffCol" in 4.x, "Diffuse Color" in 5.x), in view layer `layer`
    (None: whichever layer holds it, which must be one). Raises KeyError when the pass is missing,
    ValueError when `layer` is None and several layers hold it.
    """
    import OpenEXR

    names = (pass_names,) if isinstance(pass_names, str) else tuple(pass_names)
    found: dict[str, dict[str, dict[str, np.ndarray]]] = {}  # pass -> layer -> channel -> pixels
    with OpenEXR.File(os.fspath(path), separate_channels=True) as f:
        for part in f.parts:
            for full, channel in part.channels.items():
                prefix, _, suffix = full.rpartition(".")
                in_layer, _, pass_name = prefix.rpartition(".")
                if pass_name in names and layer in (None, in_layer):
                    found.setdefault(pass_name, {}).setdefault(in_layer, {})[suffix] = channel.pixels
    for name in names:
        layers = found.get(name, {})
        if len(layers) > 1:
            raise ValueError(f"read_exr_pass: pass '{name}' is in layers {sorted(layers)} of {path}")
        if layers:
            channels = next(iter(layers.values()))
            return np.stack([channels[n].astype(np.float32, copy=False) for n in _ordered(channels)],
                            axis=-1)
    raise KeyError(f"read_exr_pass: no pass {names} in layer {layer!r} of {path}")
