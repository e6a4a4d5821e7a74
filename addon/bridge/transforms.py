"""Blender transforms as NumPy: matrices and unit vectors."""

from __future__ import annotations

import numpy as np


def matrix_array(m) -> np.ndarray:
    """A mathutils.Matrix as a (4, 4) float64 array."""
    return np.array([list(row) for row in m], dtype=np.float64)


def unit(v: np.ndarray) -> np.ndarray:
    """`v` scaled to length 1; a zero vector stays zero."""
    n = np.linalg.norm(v)
    return v / n if n > 0 else v
