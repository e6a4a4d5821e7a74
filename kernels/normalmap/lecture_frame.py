"""The lecture's tangent frame per face corner, and the angle between two frames.

The lecture (lecture 13, "3. Bump Mapping") takes at a point the tangent t along the texture's u
direction and the binormal b = n x t. Per face corner here: t is dp/du of the corner's own
triangle (the corner and its two neighbours in the face; for a triangle, the face) made
perpendicular to the corner normal, b = n x t, turned round where the UV map is mirrored so that
b runs along +v (`shading.bump.tangent_frame`, the frame the kernels' shading has used so far).
Unlike MikkTSpace nothing is averaged over a vertex's faces, so the frame jumps from face to face
on a curved low-poly mesh; `frame_angles` measures by how much the two frames differ.

Shapes: positions (V, 3) object space; corner_verts (L,); corner normals (L, 3) unit; corner UVs
(L, 2); face_starts, face_sizes (F,). Tangents are (L, 3) float32 unit vectors, signs (L,) +-1
with b = sign (n x t), the same form as `mikktspace.CornerTangents`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..shading.bump import DEGENERATE_UV_AREA, MIN_LENGTH, tangent_frame, uv_derivatives


@dataclass(frozen=True)
class LectureFrames:
    """The lecture's frames per face corner.

    | field | shape | meaning |
    |-------|-------|---------|
    | tangents | (L, 3) float32 | unit t: dp/du of the corner's triangle, perpendicular to n |
    | signs | (L,) float32 | +1, or -1 where the UV map is mirrored: b = sign (n x t) |
    | degenerate_frames | int | corners whose triangle has zero UV area: t from its first edge |
    """

    tangents: np.ndarray
    signs: np.ndarray
    degenerate_frames: int


def corner_triangles(face_starts: np.ndarray, face_sizes: np.ndarray) -> np.ndarray:
    """(L, 3) int64 corner indices (previous, this, next) of each corner within its face, in the
    face's winding, so that each corner's triangle is counter-clockwise like its face."""
    starts = np.asarray(face_starts, np.int64)
    sizes = np.asarray(face_sizes, np.int64)
    face = np.repeat(np.arange(len(sizes)), sizes)
    corner = starts[face] + (np.arange(sizes.sum()) - np.repeat(np.cumsum(sizes) - sizes, sizes))
    local = corner - starts[face]
    prev = starts[face] + (local - 1) % sizes[face]
    nxt = starts[face] + (local + 1) % sizes[face]
    out = np.empty((len(corner), 3), np.int64)
    out[corner] = np.stack([prev, corner, nxt], axis=1)
    return out


def lecture_frames(positions: np.ndarray, corner_verts: np.ndarray, corner_normals: np.ndarray,
                   corner_uvs: np.ndarray, face_starts: np.ndarray | None = None,
                   face_sizes: np.ndarray | None = None) -> LectureFrames:
    """The lecture's frame at every face corner (see the module docstring). Without face_starts
    and face_sizes the corners are consecutive triangles. Faces of any size are accepted."""
    corners = len(corner_verts)
    if face_sizes is None:
        face_sizes = np.full(corners // 3, 3, np.int64)
        face_starts = np.arange(0, corners - corners % 3, 3, dtype=np.int64)
    tri = corner_triangles(face_starts, face_sizes)  # (L, 3) corners: (prev, this, next)
    # Reordered (this, next, prev): the same triangle, its winding kept, corner 0 the corner.
    tri = tri[:, [1, 2, 0]]
    p = np.asarray(positions, np.float64)[np.asarray(corner_verts, np.int64)[tri]]  # (L, 3, 3)
    uv = np.asarray(corner_uvs, np.float64)[tri]  # (L, 3, 2)
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    degenerate = np.abs(d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]) <= DEGENERATE_UV_AREA
    dpdu, dpdv = uv_derivatives(p, uv)
    n = np.asarray(corner_normals, np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), MIN_LENGTH)
    t, b, n = tangent_frame(n, dpdu, dpdv)
    sign = np.where(np.einsum("ij,ij->i", b, np.cross(n, t)) < 0.0, -1.0, 1.0)
    return LectureFrames(tangents=t.astype(np.float32), signs=sign.astype(np.float32),
                         degenerate_frames=int(degenerate.sum()))


def frame_angles(normals: np.ndarray, tangents_a: np.ndarray, signs_a: np.ndarray,
                 tangents_b: np.ndarray, signs_b: np.ndarray) -> np.ndarray:
    """(L,) float64 angle in degrees between two tangent frames per corner (for a chart): the
    larger of the angles between their tangents and between their bitangents b = sign (n x t).
    Frames of opposite handedness differ by 180 degrees in b. Tangents are re-normalised and made
    perpendicular to n first, so a frame that is not quite in the normal's plane (MikkTSpace's
    default (1, 0, 0) at unreached corners) is compared by its direction in that plane."""
    n = np.asarray(normals, np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), MIN_LENGTH)

    def in_plane(t):
        t = np.asarray(t, np.float64)
        t = t - np.einsum("ij,ij->i", t, n)[:, None] * n
        return t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), MIN_LENGTH)

    ta, tb = in_plane(tangents_a), in_plane(tangents_b)
    ba = np.cross(n, ta) * np.asarray(signs_a, np.float64)[:, None]
    bb = np.cross(n, tb) * np.asarray(signs_b, np.float64)[:, None]
    cos_t = np.clip(np.einsum("ij,ij->i", ta, tb), -1.0, 1.0)
    cos_b = np.clip(np.einsum("ij,ij->i", ba, bb), -1.0, 1.0)
    return np.degrees(np.maximum(np.arccos(cos_t), np.arccos(cos_b)))
