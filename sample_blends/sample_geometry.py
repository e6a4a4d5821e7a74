"""Geometry of the sample scenes: plain (vertices, faces, per-loop UVs) built in NumPy, so no
bmesh operator defaults can differ between Blender versions."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

UV_MARGIN = 1.0 / 64.0  # UV gap around each face of an atlas: 2 texels at 128^2, for dilation

Faces = list[list[int]]


def newell_normal(points: np.ndarray) -> np.ndarray:
    """Unit normal of a polygon (k, 3), robust to slight non-planarity (Newell's method)."""
    nxt = np.roll(points, -1, axis=0)
    n = np.array(
        [
            np.sum((points[:, 1] - nxt[:, 1]) * (points[:, 2] + nxt[:, 2])),
            np.sum((points[:, 2] - nxt[:, 2]) * (points[:, 0] + nxt[:, 0])),
            np.sum((points[:, 0] - nxt[:, 0]) * (points[:, 1] + nxt[:, 1])),
        ]
    )
    return n / np.linalg.norm(n)


def orient_faces(verts: np.ndarray, faces: Faces, centre: Sequence[float], outward: bool) -> Faces:
    """Wind each face of a convex shell so its normal points away from (or towards) `centre`."""
    oriented = []
    for face in faces:
        pts = verts[face]
        away = float(np.dot(newell_normal(pts), pts.mean(axis=0) - np.asarray(centre))) > 0.0
        oriented.append(list(face) if away == outward else list(reversed(face)))
    return oriented


def box(size: Sequence[float], centre: Sequence[float] = (0.0, 0.0, 0.0)):
    """An axis-aligned box: 8 vertices (m) and 6 outward quads (-Z, +Z, -Y, +Y, -X, +X)."""
    half = np.asarray(size, float) / 2.0
    corner = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], float)
    verts = np.asarray(centre, float) + (corner * 2.0 - 1.0) * half
    faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
    return verts, orient_faces(verts, faces, centre, outward=True)


def merge(*parts):
    """Concatenate (verts, faces) pairs into one mesh."""
    verts, faces, offset = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces += [[i + offset for i in face] for face in f]
        offset += len(v)
    return np.concatenate(verts), faces


def cylinder(r_bottom: float, r_top: float, depth: float, segments: int, caps: bool = True):
    """A cylinder or cone frustum along +Z, base at z = 0: side quads and n-gon caps."""
    angle = 2.0 * np.pi * np.arange(segments) / segments
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros(segments)], axis=1)
    bottom = ring * [r_bottom, r_bottom, 1.0]
    top = ring * [r_top, r_top, 1.0] + [0.0, 0.0, depth]
    verts = np.concatenate([bottom, top])
    faces = [[j, (j + 1) % segments, segments + (j + 1) % segments, segments + j]
             for j in range(segments)]
    if caps:
        faces += [list(range(segments)), list(range(segments, 2 * segments))]
    return verts, orient_faces(verts, faces, (0.0, 0.0, depth / 2.0), outward=True)


def uv_sphere(radius: float, segments: int, rings: int):
    """A UV sphere around the origin: verts, faces (pole triangles, quads) and lat-long UVs.

    UVs are per loop, (L, 2): u = longitude / 2pi (0 at +X, increasing counter-clockwise seen
    from +Z), v = 1 at the north pole (+Z) down to 0 at the south pole.
    """
    theta = np.pi * np.arange(1, rings) / rings  # polar angle of the inner rings
    phi = 2.0 * np.pi * np.arange(segments) / segments
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    ring_verts = np.stack(
        [st * np.cos(phi), st * np.sin(phi), np.broadcast_to(ct, (rings - 1, segments))], axis=-1
    ).reshape(-1, 3)
    verts = radius * np.concatenate([[[0.0, 0.0, 1.0]], ring_verts, [[0.0, 0.0, -1.0]]])
    north, south = 0, len(verts) - 1

    def vid(i: int, j: int) -> int:  # inner ring i (0: nearest the north pole), segment j
        return 1 + i * segments + j % segments

    faces, uvs = [], []
    for j in range(segments):
        u0, u1 = j / segments, (j + 1) / segments
        v_top = 1.0 - 1.0 / rings
        faces.append([north, vid(0, j), vid(0, j + 1)])
        uvs += [((u0 + u1) / 2.0, 1.0), (u0, v_top), (u1, v_top)]
        for i in range(rings - 2):
            va, vb = 1.0 - (i + 1) / rings, 1.0 - (i + 2) / rings
            faces.append([vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)])
            uvs += [(u0, va), (u0, vb), (u1, vb), (u1, va)]
        v_bot = 1.0 / rings
        faces.append([south, vid(rings - 2, j + 1), vid(rings - 2, j)])
        uvs += [((u0 + u1) / 2.0, 0.0), (u1, v_bot), (u0, v_bot)]
    return verts, faces, np.asarray(uvs)


def grid(size_x: float, size_y: float, nx: int, ny: int):
    """A flat grid of quads in z = 0 centred on the origin, facing +Z, UVs spanning [0, 1]^2."""
    xs, ys = np.linspace(0.0, 1.0, nx + 1), np.linspace(0.0, 1.0, ny + 1)
    u, v = np.meshgrid(xs, ys)  # (ny+1, nx+1)
    verts = np.stack([(u - 0.5) * size_x, (v - 0.5) * size_y, np.zeros_like(u)], -1).reshape(-1, 3)
    faces = [[y * (nx + 1) + x, y * (nx + 1) + x + 1, (y + 1) * (nx + 1) + x + 1,
              (y + 1) * (nx + 1) + x] for y in range(ny) for x in range(nx)]
    uvs = np.concatenate([np.stack([u.ravel()[f], v.ravel()[f]], 1) for f in faces])
    return verts, faces, uvs


def planar_uvs(verts: np.ndarray, faces: Faces, margin: float = UV_MARGIN) -> np.ndarray:
    """Per-loop UVs of a (near-)planar mesh: its projection onto its own plane, fitted into
    [margin, 1 - margin]^2 with the aspect ratio kept (uniform texel density)."""
    normal = newell_normal(verts[faces[0]])
    e1 = verts[faces[0][1]] - verts[faces[0][0]]
    e1 = e1 - normal * np.dot(e1, normal)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    flat = np.stack([verts @ e1, verts @ e2], axis=1)
    flat -= flat.min(axis=0)
    flat *= (1.0 - 2.0 * margin) / flat.max()
    return np.concatenate([flat[f] for f in faces]) + margin


def atlas_uvs(verts: np.ndarray, faces: Faces, margin: float = UV_MARGIN) -> np.ndarray:
    """Per-loop UVs that never overlap: each face flattened onto its own plane and placed in its
    own cell of a square grid, one scale for all faces (uniform texel density, lightmap-ready)."""
    cols = math.ceil(math.sqrt(len(faces)))
    cell = 1.0 / cols
    flats = []
    for face in faces:
        pts = verts[face]
        normal = newell_normal(pts)
        e1 = pts[1] - pts[0]
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(normal, e1)
        flat = np.stack([pts @ e1, pts @ e2], axis=1)
        flats.append(flat - flat.min(axis=0))
    scale = (cell - 2.0 * margin) / max(float(f.max()) for f in flats)
    uvs = []
    for k, flat in enumerate(flats):
        col, row = k % cols, k // cols
        origin = np.array([col * cell + margin, 1.0 - (row + 1) * cell + margin])
        uvs.append(origin + flat * scale)
    return np.concatenate(uvs)
