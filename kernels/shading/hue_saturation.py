"""Blender's Hue/Saturation/Value node on linear RGB (`hue_saturation_value`), as Cycles
computes it (`svm_node_hsv` with `rgb_to_hsv` / `hsv_to_rgb` of its colour utilities): the hue
turned by hue - 0.5, the saturation scaled and clamped to [0, 1], the value scaled, the result
mixed with the input by the factor and clamped below at 0 (over-saturation goes negative)."""

from __future__ import annotations

import numpy as np


def rgb_to_hsv(rgb: np.ndarray) -> np.ndarray:
    """(N, 3) RGB -> (N, 3) HSV, hue in [0, 1); grey (and black) has hue and saturation 0."""
    rgb = np.asarray(rgb, np.float64)
    cmax, cmin = rgb.max(axis=1), rgb.min(axis=1)
    delta = cmax - cmin
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(cmax != 0.0, delta / cmax, 0.0)
        c = (cmax[:, None] - rgb) / delta[:, None]
    r, g = rgb[:, 0] == cmax, rgb[:, 1] == cmax
    h = np.where(r, c[:, 2] - c[:, 1], np.where(g, 2.0 + c[:, 0] - c[:, 2],
                                                  4.0 + c[:, 1] - c[:, 0])) / 6.0
    h = np.where(h < 0.0, h + 1.0, h)
    h = np.where(s != 0.0, h, 0.0)
    return np.column_stack([h, s, cmax])


def hsv_to_rgb(hsv: np.ndarray) -> np.ndarray:
    """(N, 3) HSV -> (N, 3) RGB, the inverse of `rgb_to_hsv` (hue 1 is hue 0)."""
    hsv = np.asarray(hsv, np.float64)
    h, s, v = hsv[:, 0], hsv[:, 1], hsv[:, 2]
    h = np.where(h == 1.0, 0.0, h) * 6.0
    i = np.floor(h)
    f = h - i
    p, q, t = v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f))
    sextants = [(v, t, p), (q, v, p), (p, v, t), (p, q, v), (t, p, v), (v, p, q)]
    k = np.clip(i, 0, 5).astype(np.int64)
    out = np.empty_like(hsv)
    for channel in range(3):
        choices = np.stack([sextant[channel] for sextant in sextants])
        out[:, channel] = np.take_along_axis(choices, k[None], axis=0)[0]
    grey = s == 0.0
    out[grey] = v[grey, None]
    return out


def hue_saturation_value(rgb: np.ndarray, hue: float, saturation: float, value: float,
                         fac: float) -> np.ndarray:
    """(N, 3) linear RGB through the node with constant inputs (hue 0.5 leaves the hue)."""
    rgb = np.asarray(rgb, np.float64)
    hsv = rgb_to_hsv(rgb)
    hsv[:, 0] = np.mod(hsv[:, 0] + hue + 0.5, 1.0)  # Cycles' fractf
    hsv[:, 1] = np.clip(hsv[:, 1] * saturation, 0.0, 1.0)
    hsv[:, 2] *= value
    mixed = fac * hsv_to_rgb(hsv) + (1.0 - fac) * rgb
    return np.maximum(mixed, 0.0)
