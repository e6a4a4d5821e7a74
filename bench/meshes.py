"""Deterministic test meshes for the ray-casting benchmarks and tests (no downloads).

Every function returns triangles as a (T, 3, 3) float32 array, world space, metres, Blender's
frame (+Z up), counter-clockwise around the outward normal. The same call always returns the same
bits: the only randomness is a seeded `numpy.random.default_rng`.

| function            | triangles                 | what it is                                          |
|---------------------|---------------------------|-----------------------------------------------------|
| `cornell_box()`     | 32                        | the Cornell box from `tests/data`  , in metres  |
| `icosphere(n)`      | 20 * 4**n                 | closed unit icosphere, shared vertices (watertight) |
| `lumpy_sphere(n)`   | 20 * 4**n (n=6: 81 920)   | a displaced icosphere, like a scanned stone         |
| `lumpy_torus(u, v)` | 2 * u * v (1024x512: 1M)  | a displaced torus (genus 1: rays pass the hole)     |

Run as a script to print the sizes and bounds of the benchmark meshes.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

# The published Cornell box (sources in tests/data/README.md).
CORNELL_JSON = Path(__file__).resolve().parents[1] / "tests" / "data" / "cornell_box.json"
MM_TO_M = 1.0e-3  # the Cornell data is in millimetres, Blender units are metres


def cornell_box(path: Path | None = None) -> np.ndarray:
    """The original Cornell box (walls, light, two blocks): (32, 3, 3) float32, metres, +Z up.

    Each published quad (a, b, c, d) becomes triangles (a, b, c) and (a, c, d). The data is
    right-handed with +Y up in millimetres; Blender's frame is reached by the rotation
    (x, y, z) -> (-x, z, y) and a scale of 1/1000.
    """
    path = path or CORNELL_JSON
    data = json.loads(Path(path).read_text())
    quads = [
        quad
        for surface in data["cornell_original"]["surfaces"].values()
        for quad in surface["quads"]
    ]
    q = np.asarray(quads, np.float64)  # (Q, 4, 3) mm, Cornell frame (+Y up)
    tris = np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], axis=0)  # (2Q, 3, 3)
    blender = np.stack([-tris[..., 0], tris[..., 2], tris[..., 1]], axis=-1) * MM_TO_M
    return blender.astype(np.float32)


def icosphere_indexed(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """A unit icosphere as (V, 3) float64 vertices and (F, 3) int64 faces, F = 20 * 4**n.

    Midpoints are shared between neighbouring faces, so the mesh is closed and every edge's two
    triangles see bit-identical vertex coordinates.
    """
    phi = (1.0 + 5.0**0.5) / 2.0
    verts = np.array(
        [
            [-1, phi, 0], [1, phi, 0], [-1, -phi, 0], [1, -phi, 0],
            [0, -1, phi], [0, 1, phi], [0, -1, -phi], [0, 1, -phi],
            [phi, 0, -1], [phi, 0, 1], [-phi, 0, -1], [-phi, 0, 1],
        ],
        np.float64,
    )  # fmt: skip
    faces = np.array(
        [
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
            [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
            [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
            [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ],
        np.int64,
    )  # fmt: skip
    verts /= np.linalg.norm(verts, axis=1, keepdims=True)
    for _ in range(subdivisions):
        # The three edges of every face, each as a sorted vertex pair; one midpoint per edge.
        edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
        edges.sort(axis=1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        inverse = inverse.reshape(3, -1)
        mid = verts[unique[:, 0]] + verts[unique[:, 1]]
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        m01, m12, m20 = (len(verts) + inverse[k] for k in range(3))
        verts = np.concatenate([verts, mid])
        a, b, c = faces.T
        faces = np.concatenate(
            [
                np.stack([a, m01, m20], axis=1),
                np.stack([b, m12, m01], axis=1),
                np.stack([c, m20, m12], axis=1),
                np.stack([m01, m12, m20], axis=1),
            ]
        )
    return verts, faces


def icosphere(subdivisions: int, radius: float = 1.0) -> np.ndarray:
    """A closed icosphere centred on the origin: (20 * 4**n, 3, 3) float32, metres."""
    verts, faces = icosphere_indexed(subdivisions)
    return (verts * radius).astype(np.float32)[faces]


def _displacement(points: np.ndarray, seed: int, octaves: int = 5) -> np.ndarray:
    """A smooth scalar field on (N, 3) points: a sum of random plane waves, about [-1, 1]."""
    rng = np.random.default_rng(seed)
    field = np.zeros(len(points))
    for octave in range(octaves):
        freq = 2.0 * 2.0**octave
        dirs = rng.normal(size=(4, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        phase = rng.uniform(0.0, 2.0 * np.pi, 4)
        field += np.sin(freq * points @ dirs.T + phase).sum(axis=1) / (4.0 * 1.6**octave)
    return field


def lumpy_sphere(subdivisions: int = 6, amplitude: float = 0.25, seed: int = 7) -> np.ndarray:
    """A displaced icosphere (a scanned-stone look): (20 * 4**n, 3, 3) float32, radius ~1 m."""
    verts, faces = icosphere_indexed(subdivisions)
    verts = verts * (1.0 + amplitude * _displacement(verts, seed))[:, None]
    return verts.astype(np.float32)[faces]


def lumpy_torus(
    n_major: int = 1024, n_minor: int = 512, amplitude: float = 0.06, seed: int = 11
) -> np.ndarray:
    """A displaced torus (major radius 1 m, minor 0.35 m): (2 * n_major * n_minor, 3, 3) float32."""
    i, j = np.meshgrid(np.arange(n_major), np.arange(n_minor), indexing="ij")
    theta = 2.0 * np.pi * i.ravel() / n_major
    phi = 2.0 * np.pi * j.ravel() / n_minor
    minor = 0.35
    ring = np.stack([np.cos(theta), np.sin(theta), np.zeros_like(theta)], axis=1)
    normal = np.cos(phi)[:, None] * ring + np.sin(phi)[:, None] * np.array([0.0, 0.0, 1.0])
    base = ring + minor * normal
    verts = base + (amplitude * _displacement(base, seed))[:, None] * normal
    idx = (i * n_minor + j).ravel()
    i1 = ((i + 1) % n_major * n_minor + j).ravel()
    j1 = (i * n_minor + (j + 1) % n_minor).ravel()
    ij1 = ((i + 1) % n_major * n_minor + (j + 1) % n_minor).ravel()
    faces = np.concatenate([np.stack([idx, i1, ij1], 1), np.stack([idx, ij1, j1], 1)])
    return verts.astype(np.float32)[faces]


def benchmark_meshes(full: bool = True) -> dict[str, np.ndarray]:
    """The three benchmark scenes by name; `full=False` gives small stand-ins for quick runs."""
    if full:
        return {
            "cornell_32": cornell_box(),
            "lumpy_sphere_82k": lumpy_sphere(6),
            "lumpy_torus_1m": lumpy_torus(1024, 512),
        }
    return {
        "cornell_32": cornell_box(),
        "lumpy_sphere_5k": lumpy_sphere(4),
        "lumpy_torus_33k": lumpy_torus(128, 128),
    }


if __name__ == "__main__":
    for name, tris in benchmark_meshes(full=False).items():
        lo, hi = tris.reshape(-1, 3).min(0), tris.reshape(-1, 3).max(0)
        print(f"{name:>18}: {len(tris):>8} triangles, bounds {np.round(lo, 3)} .. {np.round(hi, 3)}")
