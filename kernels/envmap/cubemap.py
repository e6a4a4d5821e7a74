"""The OpenGL cube-map convention, shared by environment mapping and point-light shadow maps.

Sources: the lecture's environment mapping (lecture 13, "2. Environment Mapping": pick the face of
the largest |r_i|, divide the other two components by it and map [-1, 1] to [0, 1]) and the OpenGL
specification's "Cube Map Texture Selection" (section 8.13 of the 4.6 core profile, its table of
major axis, sc and tc), as recorded in the OpenGL specification (tests/data/cubemap_gl.json):

    face  major axis  sc    tc         s = (sc / |ma| + 1) / 2
    +X    rx          -rz   -ry        t = (tc / |ma| + 1) / 2
    -X    rx          +rz   -ry
    +Y    ry          +rx   +rz
    -Y    ry          +rx   -rz
    +Z    rz          +rx   -ry
    -Z    rz          -rx   -ry

Face order is GL's: 0 +X, 1 -X, 2 +Y, 3 -Y, 4 +Z, 5 -Z. Ties between equal |r_i| go to X, then Y
(the reference's (1, 1, 1) -> +X); a zero component counts as positive (+0 and -0 alike), and the
zero vector maps to +X at (s, t) = (0.5, 0.5).

Written as vectors: face f has a forward axis F_f and unit vectors U_f, V_f with sc = U_f . r,
tc = V_f . r and |ma| = F_f . r, so the inverse is r = F_f + sc U_f + tc V_f (|ma| = 1).
The lecture's +x example takes (s, t) from (r_y, r_z) / |r_x|; which minor axis runs which way on a
face is a convention, and this module follows OpenGL's (the reference's) throughout.

Images. A face is rendered by a 90-degree camera looking along F_f with up V_f and right U_f
(= F_f x V_f, the reference's `render_to_face_lookAt_check`): s grows to the screen's right and t
grows upwards. Stored in the project's (H, W) top-row-first image convention, texel (i, j) of an
S x S face has its centre at s = (j + 0.5) / S and t = 1 - (i + 0.5) / S: columns follow s, row 0
is t near 1. (OpenGL's own texture memory puts t = 0 in its first row; ours is flipped vertically,
like every image in this project, and like `Scene`'s UV convention v = 1 - (i + 0.5) / H.)
A cube map is a (6, S, S, C) float32 array in face order.
"""

from __future__ import annotations

import numpy as np

from ..geometry.raster import Projection, look_at

# Texels rendered beyond each face's edge: one is what a bilinear lookup can reach past the
# outermost texel centre (half a texel), so the four texels it blends always exist.
BORDER = 1

FACE_NAMES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")

# (6, 3) float64, world axes: major-axis direction F, the sc axis U and the tc axis V of each face.
FACE_FORWARD = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64
)
FACE_U = np.array(
    [[0, 0, -1], [0, 0, 1], [1, 0, 0], [1, 0, 0], [1, 0, 0], [-1, 0, 0]], np.float64
)
FACE_V = np.array(
    [[0, -1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1], [0, -1, 0], [0, -1, 0]], np.float64
)
_AXIS = np.array([0, 0, 1, 1, 2, 2])  # the major axis index of each face


def direction_to_face(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, 3) directions (any length) -> face (N,) int64, s (N,) float64, t (N,) float64.

    The largest |r_i| picks the face (ties: X before Y before Z; sign >= 0 is the + face), then
    s = (sc / |ma| + 1) / 2 and t = (tc / |ma| + 1) / 2 from the table above, both in [0, 1].
    """
    r = np.asarray(directions, np.float64).reshape(-1, 3)
    mag = np.abs(r)
    x_wins = (mag[:, 0] >= mag[:, 1]) & (mag[:, 0] >= mag[:, 2])
    axis = np.where(x_wins, 0, np.where(mag[:, 1] >= mag[:, 2], 1, 2))
    rows = np.arange(len(r))
    negative = r[rows, axis] < 0.0  # -0.0 < 0 is False: zero counts as positive
    face = 2 * axis + negative
    ma = mag[rows, axis]
    sc = np.einsum("ij,ij->i", r, FACE_U[face])
    tc = np.einsum("ij,ij->i", r, FACE_V[face])
    safe = np.where(ma > 0.0, ma, 1.0)  # the zero vector lands at the face centre
    s = np.where(ma > 0.0, 0.5 * (sc / safe + 1.0), 0.5)
    t = np.where(ma > 0.0, 0.5 * (tc / safe + 1.0), 0.5)
    return face.astype(np.int64), s, t


def face_to_direction(
    face: np.ndarray, s: np.ndarray, t: np.ndarray, normalize: bool = True
) -> np.ndarray:
    """Inverse of `direction_to_face`: (N,) face, s, t -> (N, 3) float64 directions.

    r = F + (2 s - 1) U + (2 t - 1) V, unit length when `normalize` (else |ma| = 1).
    """
    f = np.asarray(face, np.int64).reshape(-1)
    sc = 2.0 * np.asarray(s, np.float64).reshape(-1, 1) - 1.0
    tc = 2.0 * np.asarray(t, np.float64).reshape(-1, 1) - 1.0
    r = FACE_FORWARD[f] + sc * FACE_U[f] + tc * FACE_V[f]
    if normalize:
        r /= np.linalg.norm(r, axis=1, keepdims=True)
    return r


def face_camera(face: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(forward, up, right), each (3,) float64 world, of the camera that renders `face`.

    Rendering with this camera (90-degree field of view, square image) puts s along the screen's
    right and t along its up, so texel (i, j) of the top-row-first image is the lookup's
    (s, t) = ((j + 0.5) / S, 1 - (i + 0.5) / S).
    """
    return FACE_FORWARD[face].copy(), FACE_V[face].copy(), FACE_U[face].copy()


def face_projection(face: int, eye: np.ndarray, near: float, far: float) -> Projection:
    """The 90-degree perspective `Projection` of one cube face seen from `eye` (m, world).

    Its linear view depth of a point p is |ma| of p - eye, the major-axis component of the table.
    """
    forward, up, _right = face_camera(face)
    return Projection.perspective(look_at(eye, forward, up), 0.5 * np.pi, near, far)


def texel_directions(size: int) -> np.ndarray:
    """(6, S, S, 3) float64 unit directions through every texel centre, in face order."""
    centres = (np.arange(size) + 0.5) / size
    s = np.broadcast_to(centres[None, :], (size, size))
    t = np.broadcast_to(1.0 - centres[:, None], (size, size))
    faces = np.repeat(np.arange(6), size * size)
    dirs = face_to_direction(faces, np.tile(s.reshape(-1), 6), np.tile(t.reshape(-1), 6))
    return dirs.reshape(6, size, size, 3)


def sample_cubemap(
    cube: np.ndarray, directions: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """Bilinear lookup of a (6, S, S, C) cube map along (N, 3) directions -> (N, C) float32.

    Seams: the four texels are taken within the selected face; coordinates are clamped to the
    face's outermost texel centres, so the last half texel next to an edge repeats the edge texel
    instead of blending with the neighbouring face (an error of at most half a texel at seams).
    """
    cube = np.asarray(cube)
    if cube.ndim != 4 or cube.shape[0] != 6 or cube.shape[1] != cube.shape[2]:
        raise ValueError(f"cube map must be (6, S, S, C), got {cube.shape}")
    size = cube.shape[1]
    face, s, t = direction_to_face(directions)
    x = np.clip(s * size - 0.5, 0.0, size - 1.0)  # continuous column, texel centres at integers
    y = np.clip((1.0 - t) * size - 0.5, 0.0, size - 1.0)  # continuous row, row 0 at the top
    x0 = np.minimum(np.floor(x).astype(np.int64), size - 2) if size > 1 else np.zeros_like(face)
    y0 = np.minimum(np.floor(y).astype(np.int64), size - 2) if size > 1 else np.zeros_like(face)
    fx = (x - x0)[:, None]
    fy = (y - y0)[:, None]
    x1 = np.minimum(x0 + 1, size - 1)
    y1 = np.minimum(y0 + 1, size - 1)
    top = cube[face, y0, x0] * (1.0 - fx) + cube[face, y0, x1] * fx
    bottom = cube[face, y1, x0] * (1.0 - fx) + cube[face, y1, x1] * fx
    value = top * (1.0 - fy) + bottom * fy
    if out is None:
        return value.astype(np.float32)
    out[...] = value
    return out


def bordered_directions(size: int, border: int = BORDER, offset: tuple[float, float] = (0.5, 0.5)
                        ) -> np.ndarray:
    """(6, S + 2B, S + 2B, 3) float64 unit directions through every texel, borders included, at
    `offset` (x, y) within each texel ((0.5, 0.5): its centre; `bordered_texel_directions`)."""
    side = size + 2 * border
    face, i, j = np.meshgrid(np.arange(6), np.arange(side), np.arange(side), indexing="ij")
    return bordered_texel_directions(size, border, face, i, j, offset).reshape(6, side, side, 3)


def bordered_texel_directions(size: int, border: int, face: np.ndarray, i: np.ndarray,
                              j: np.ndarray, offset: tuple[float, float] = (0.5, 0.5)
                              ) -> np.ndarray:
    """(N, 3) float64 unit directions through texels (face, i, j) of bordered faces, (N,) int
    each (row i and column j of the bordered image, 0..S + 2B - 1), at `offset` (x, y) in them.

    Texel (i, j) at (x, y) has sc = 2 (j - B + x) / S - 1 and tc = 1 - 2 (i - B + y) / S: inside
    the face |sc|, |tc| < 1; the border continues the same 90-degree camera's image plane.
    """
    face = np.ravel(face)
    sc = 2.0 * (np.ravel(j) - border + offset[0]) / size - 1.0
    tc = 1.0 - 2.0 * (np.ravel(i) - border + offset[1]) / size  # rows run downwards: t falls
    dirs = FACE_FORWARD[face] + sc[:, None] * FACE_U[face] + tc[:, None] * FACE_V[face]
    return dirs / np.linalg.norm(dirs, axis=-1, keepdims=True)


def sample_bordered(faces: np.ndarray, border: int, directions: np.ndarray,
                    out: np.ndarray | None = None) -> np.ndarray:
    """Bilinear lookup of bordered faces (6, S + 2B, S + 2B, C) along (N, 3) directions -> (N, C).

    The face and (s, t) come from `cubemap.direction_to_face` (largest |r_i|); the continuous texel
    coordinate x = s S - 1/2 + B lies in [B - 1/2, S + B - 1/2], so with B >= 1 all four texels of
    the bilinear footprint exist: at an edge, the border holds the neighbouring face's directions.
    """
    faces = np.asarray(faces)
    if faces.ndim != 4 or faces.shape[0] != 6 or faces.shape[1] != faces.shape[2]:
        raise ValueError(f"bordered faces must be (6, S + 2B, S + 2B, C), got {faces.shape}")
    if border < 1:
        raise ValueError("sample_bordered needs a border of at least one texel")
    side = faces.shape[1]
    size = side - 2 * border
    face, s, t = direction_to_face(directions)
    x = s * size - 0.5 + border  # continuous column, texel centres at integers
    y = (1.0 - t) * size - 0.5 + border  # continuous row, row 0 at the top
    x0 = np.clip(np.floor(x).astype(np.int64), 0, side - 2)
    y0 = np.clip(np.floor(y).astype(np.int64), 0, side - 2)
    fx = (x - x0)[:, None]
    fy = (y - y0)[:, None]
    top = faces[face, y0, x0] * (1.0 - fx) + faces[face, y0, x0 + 1] * fx
    bottom = faces[face, y0 + 1, x0] * (1.0 - fx) + faces[face, y0 + 1, x0 + 1] * fx
    value = top * (1.0 - fy) + bottom * fy
    if out is None:
        return value.astype(np.float32)
    out[...] = value
    return out
