"""Rooms of glowing walls for the environment-mapping tests: each wall its own colour, so a
face of a cube map that lands in the wrong place shows."""

from __future__ import annotations

import numpy as np
from scene_builder import tessellated_box

from classic_bake.kernels.geometry.scene import Material

# The six walls' emitted radiance, W/(m^2 sr): distinct colours, so a misplaced face shows.
WALL_COLOURS = np.array([[1.0, 0.2, 0.2], [0.2, 1.0, 0.2], [0.2, 0.2, 1.0],
                         [1.0, 1.0, 0.2], [0.2, 1.0, 1.0], [1.0, 0.2, 1.0]], np.float32)


def emissive(colour, name="wall"):
    """A wall that only glows: black and Lambertian (no specular layer), it reflects nothing, so
    no shadow rays are cast from it towards the other glowing walls (which would only add zero,
    slowly)."""
    return Material(name=name, base_color=np.zeros(3, np.float32), specular=0.0,
                    emission=np.asarray(colour, np.float32))


def room(half: float) -> np.ndarray:
    """(12, 3, 3) triangles of the cube [-half, half]^3, normals inward, two per wall."""
    return tessellated_box(1, 2.0 * half) - half


def coloured_room(half: float) -> list:
    """[(triangles (2, 3, 3), material)] of the six walls of `room(half)`."""
    walls = room(half)
    return [(walls[2 * k:2 * k + 2], emissive(WALL_COLOURS[k], f"wall{k}")) for k in range(6)]
