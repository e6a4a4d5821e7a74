"""Tangent-space normals <-> normal-map colours, and 8-bit / float arrays for image files.

A tangent-space normal n = (x, y, z) (x along the tangent t, y along the bitangent b = s (n x t),
z along the surface normal; unit, z > 0) is stored as rgb = n / 2 + 1/2, so the flat normal
(0, 0, 1) is (0.5, 0.5, 1.0). Blender's Normal Map node (and Cycles, EEVEE, glTF, Unity) read the
OpenGL convention: green grows with +y, along +v. DirectX tools (Unreal, Substance's "DirectX")
store -y: green flipped. The files are Non-Color data: no sRGB curve on the way in or out.

Arrays: normals (..., 3) float, rgb (..., 3) float32 in [0, 1], bytes (..., 3) uint8.
"""

from __future__ import annotations

from typing import Literal, get_args

import numpy as np

GreenConvention = Literal["OPENGL", "DIRECTX"]
GREEN_CONVENTIONS: tuple[str, ...] = get_args(GreenConvention)
# Normals shorter than this are not normalised when decoding (a black texel has no direction).
MIN_LENGTH = 1e-12


def normals_to_rgb(normals: np.ndarray, green: GreenConvention = "OPENGL") -> np.ndarray:
    """(..., 3) float32 colours in [0, 1] of tangent-space unit normals (..., 3): n / 2 + 1/2,
    green flipped for DirectX."""
    n = np.asarray(normals, np.float64)
    if green == "DIRECTX":
        n = n * np.array([1.0, -1.0, 1.0])
    return np.clip(0.5 * n + 0.5, 0.0, 1.0).astype(np.float32)


def rgb_to_normals(rgb: np.ndarray, green: GreenConvention = "OPENGL") -> np.ndarray:
    """(..., 3) float64 unit tangent-space normals of colours (..., 3+) in [0, 1] (or uint8):
    2 rgb - 1, green flipped back for DirectX, normalised."""
    rgb = np.asarray(rgb)
    values = rgb[..., :3].astype(np.float64)
    if rgb.dtype == np.uint8:
        values = values / 255.0
    n = 2.0 * values - 1.0
    if green == "DIRECTX":
        n = n * np.array([1.0, -1.0, 1.0])
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), MIN_LENGTH)


def to_uint8(rgb: np.ndarray) -> np.ndarray:
    """(..., C) uint8 of colours in [0, 1], rounded to nearest (8-bit PNG, Non-Color): 0.5 ->
    128, as Blender's byte images store it (128 / 255 = 0.50196, a tilt of 0.22 degrees that every
    8-bit normal map shares)."""
    return np.clip(np.rint(np.asarray(rgb, np.float64) * 255.0), 0, 255).astype(np.uint8)


def to_float(rgb: np.ndarray) -> np.ndarray:
    """(..., C) float32 colours for a float image (EXR, Non-Color): the values as they are."""
    return np.ascontiguousarray(rgb, np.float32)


def with_alpha(rgb: np.ndarray, alpha: float = 1.0) -> np.ndarray:
    """(H, W, 4) of (H, W, 3) colours with a constant alpha, in rgb's dtype (uint8: alpha 255)."""
    rgb = np.asarray(rgb)
    a = 255 if rgb.dtype == np.uint8 else alpha
    out = np.empty(rgb.shape[:-1] + (4,), rgb.dtype)
    out[..., :3] = rgb
    out[..., 3] = a
    return out
