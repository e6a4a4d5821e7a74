"""Cube maps in the layouts other tools read: OpenEXR's standard cube, the lat-long (equirectangular)
map of Blender's Environment Texture, a labelled cross preview, and the probe's JSON record.

The kernels keep a cube map as (6, N, N, C) float32 in OpenGL's face table (`cubemap.py`). Files
re-arrange those texels; nothing here changes a value except the lat-long resampling and the
preview's tone curve.

OpenEXR's cube (ImfEnvmap.h, "Cube Map"; ImfEnvmap.cpp, `CubeMap::pixelPosition` and `direction`).
An N x 6N image (width x height), the faces stacked from the top in the order +X, -X, +Y, -Y, +Z,
-Z, and the header attribute `envmap` = ENVMAP_CUBE. Face f covers rows [f N, (f + 1) N); within it
a texel at row r (0 at the top) and column c looks along

    d = F + a R + b U,   a = 2 (c + 1/2) / N - 1,   b = 1 - 2 (r + 1/2) / N

with the face's forward F, its image right R and its image up U (in the file's axes):

    face  F    R (columns grow)   U (rows shrink)   OpenGL's (cubemap.py) R = U_gl, U = V_gl
    +X    +x   +z                 +y                -z, -y   (rotated 180 degrees)
    -X    -x   -z                 +y                +z, -y   (rotated 180 degrees)
    +Y    +y   +x                 +z                +x, +z   (the same)
    -Y    -y   +x                 -z                +x, -z   (the same)
    +Z    +z   -x                 +y                +x, -y   (rotated 180 degrees)
    -Z    -z   +x                 +y                -x, -y   (rotated 180 degrees)

(from `pixelPosition`: +X puts the in-face position's y (the direction's z) along columns and its
x (the direction's y) upwards, and so on; the header's ASCII drawing shows the same axes). The
table is `OPENEXR_RIGHT` / `OPENEXR_UP`; the tests check it against ImfEnvmap.cpp's formulas.

Two conventions of the spec that this module states rather than copies:
* texel centres. ImfEnvmap's helpers map in-face pixel positions 0 .. N-1 onto -1 .. 1, i.e. they
  put the outermost texels' centres on the cube's edges; here (and in OpenGL) a texel is a cell of
  the face and its centre lies half a texel inside. The file holds the same N x N cells either way;
  a reader using ImfEnvmap's helpers sees each texel at most half a texel off (at the edges), and
  the re-arrangement stays lossless (a permutation of texels).
* axes. OpenEXR names faces after its own axes, and its lat-long map is y-up (latitude +pi/2 is +y).
  `world_to_file` (a signed permutation matrix, file = M world) says which world axis each file
  axis is. The default (identity) keeps world axes: the file's +X face holds the world's +X.
  `OPENEXR_Y_UP` maps Blender's z-up world onto OpenEXR's y-up frame so that a cube written with
  it and the lat-long file below are the same environment to OpenEXR's tools (exrenvmap turns one
  into a resampling of the other): OpenEXR's LatLongMap at longitude atan2(x, z) and latitude asin(y) equals
  Blender's equirectangular mapping exactly when (x, y, z)_file = (y, z, x)_world.

Lat-long (equirectangular), as Blender's Environment Texture reads it (Cycles'
`direction_to_equirectangular` in intern/cycles/kernel/camera/projection.h, range
(-2 pi, pi, -pi, pi); EEVEE's `node_tex_environment_equirectangular` the same):

    u = 1/2 - atan2(d_y, d_x) / (2 pi),   v = 1/2 + atan2(d_z, hypot(d_x, d_y)) / pi

u runs left to right, v bottom to top (a 2H x H image, row 0 at the top has v near 1): the image's
centre column looks along +X, u = 1/4 along +Y, the top row at +Z. Checked once by rendering with
Cycles (bpy 5.2) an environment image that stores its own (u, v): five directions agreed within the
image's texel size. (A formula sometimes quoted, u = atan2(d_y, -d_x) / (2 pi) + 1/2, is this one
turned 180 degrees about z: it puts -X at the centre, which Blender does not.)

Cross preview: a 4 x 3 horizontal cross unfolded around a z-up viewer, so that neighbouring faces
meet along their shared edges:

            [+Z]
    [+Y]    [+X]    [-Y]    [-X]       the horizon row turns clockwise seen from above
            [-Z]

each face seen from inside the cube with +Z up (+Z and -Z: the side towards +X at the seam with
+X), tone-mapped (`PreviewSettings`) and labelled with its name in a 5 x 7 bitmap font.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..measure.exr import read_exr, write_exr
from ..progress import Steps, drain
from .cubemap import (
    FACE_FORWARD,
    FACE_NAMES,
    direction_to_face,
    sample_bordered,
    sample_cubemap,
    texel_directions,
)
from .prefilter import level_roughness, level_size

# ---------------------------------------------------------------------------------------------
# OpenEXR's cube layout
# ---------------------------------------------------------------------------------------------

# (6, 3) float64, file axes: image right R and image up U of each stacked face (table above).
OPENEXR_RIGHT = np.array(
    [[0, 0, 1], [0, 0, -1], [1, 0, 0], [1, 0, 0], [-1, 0, 0], [1, 0, 0]], np.float64
)
OPENEXR_UP = np.array(
    [[0, 1, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1], [0, 1, 0], [0, 1, 0]], np.float64
)
# (3, 3) file = M world: the file's axes are the world's (the default).
WORLD_AXES = np.eye(3)
# (3, 3) file = M world: (x, y, z)_file = (y, z, x)_world, Blender's z-up world in OpenEXR's y-up
# frame, the frame in which the lat-long image of this module is OpenEXR's LatLongMap.
OPENEXR_Y_UP = np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]], np.float64)

# Look-ups per block of the lat-long resampling: ~50 MB of float64 directions and values at a time.
EQUIRECT_BLOCK = 1 << 20

# ---------------------------------------------------------------------------------------------
# The cross preview
# ---------------------------------------------------------------------------------------------

# (cell row, cell column, forward, right, up) of each face in the 4 x 3 cross, world axes, in
# FACE_NAMES order. Side faces: up +Z, right = forward x Z; +Z and -Z join +X along their edges.
CROSS_CELLS = (
    (1, 1, (1, 0, 0), (0, -1, 0), (0, 0, 1)),    # +X
    (1, 3, (-1, 0, 0), (0, 1, 0), (0, 0, 1)),    # -X
    (1, 0, (0, 1, 0), (1, 0, 0), (0, 0, 1)),     # +Y
    (1, 2, (0, -1, 0), (-1, 0, 0), (0, 0, 1)),   # -Y
    (0, 1, (0, 0, 1), (0, -1, 0), (-1, 0, 0)),   # +Z
    (2, 1, (0, 0, -1), (0, -1, 0), (1, 0, 0)),   # -Z
)
# sRGB transfer curve (IEC 61966-2-1): linear segment below this linear value, power curve above.
SRGB_LINEAR_CUTOFF = 0.0031308
# What +inf radiance becomes before the tone curve: white under either curve (Reinhard's x / (1 + x)
# of it is 1.0 in float64), where inf itself would give inf / inf = NaN.
TONE_INFINITY = 1e30
# uint8 grey of the cross's six empty cells: dark, but apart from a black face.
CROSS_BACKGROUND = 40
# 5 x 7 glyphs of the face labels, one string per row, '#' lit.
GLYPHS = {
    "+": ("     ", "  #  ", "  #  ", "#####", "  #  ", "  #  ", "     "),
    "-": ("     ", "     ", "     ", "#####", "     ", "     ", "     "),
    "X": ("#   #", "#   #", " # # ", "  #  ", " # # ", "#   #", "#   #"),
    "Y": ("#   #", "#   #", " # # ", "  #  ", "  #  ", "  #  ", "  #  "),
    "Z": ("#####", "    #", "   # ", "  #  ", " #   ", "#    ", "#####"),
}
# Face texels per glyph pixel of the labels: a label (11 glyph pixels) about 1/4 of the face wide.
LABEL_TEXELS_PER_PIXEL = 40


def _as_faces(faces: np.ndarray) -> np.ndarray:
    """(6, N, N) or (6, N, N, C) -> (6, N, N, C), checked."""
    faces = np.asarray(faces)
    if faces.ndim == 3:
        faces = faces[..., None]
    if faces.ndim != 4 or faces.shape[0] != 6 or faces.shape[1] != faces.shape[2]:
        raise ValueError(f"cube faces must be (6, N, N, C), got {faces.shape}")
    return faces


def _signed_permutation(matrix: np.ndarray | None) -> np.ndarray:
    """(3, 3) float64, checked to be a signed permutation (what keeps texels on texels)."""
    m = WORLD_AXES if matrix is None else np.asarray(matrix, np.float64)
    if m.shape != (3, 3) or not (np.all(np.isin(m, (-1.0, 0.0, 1.0)))
                                 and np.all(np.abs(m).sum(axis=0) == 1)
                                 and np.all(np.abs(m).sum(axis=1) == 1)):
        raise ValueError(f"world_to_file must be a 3 x 3 signed permutation, got {m.tolist()}")
    return m


def _gather(size: int, forward: np.ndarray, right: np.ndarray, up: np.ndarray,
            world_to_file: np.ndarray) -> np.ndarray:
    """(K, N, N) int64: for K faces given by forward/right/up (K, 3) in file axes, the index into a
    flattened (6 N N) OpenGL cube of the texel each of their texels shows.

    Texel (r, c) looks along F + a R + b U (a, b at its centre); with axis-aligned faces its centre
    direction is an OpenGL texel centre, found by `direction_to_face` (s N = j + 1/2 up to
    rounding, so floor gives j).
    """
    centres = 2.0 * (np.arange(size) + 0.5) / size - 1.0
    a = centres[None, None, :, None]            # (1, 1, N, 1) along columns
    b = -centres[None, :, None, None]           # (1, N, 1, 1) rows run downwards
    d_file = forward[:, None, None, :] + a * right[:, None, None, :] + b * up[:, None, None, :]
    d_world = d_file.reshape(-1, 3) @ world_to_file  # world = M^T file; as rows: file_row @ M
    face, s, t = direction_to_face(d_world)
    j = np.clip(np.floor(s * size), 0, size - 1).astype(np.int64)
    i = np.clip(np.floor((1.0 - t) * size), 0, size - 1).astype(np.int64)
    return ((face * size + i) * size + j).reshape(len(forward), size, size)


def openexr_cube_image(faces: np.ndarray, world_to_file: np.ndarray | None = None) -> np.ndarray:
    """(6, N, N, C) OpenGL-table faces -> (6N, N, C) OpenEXR cube image (faces stacked, each in
    OpenEXR's orientation; `world_to_file` as in the module docstring). Lossless: a permutation."""
    faces = _as_faces(faces)
    n = faces.shape[1]
    idx = _gather(n, FACE_FORWARD, OPENEXR_RIGHT, OPENEXR_UP, _signed_permutation(world_to_file))
    return faces.reshape(6 * n * n, -1)[idx.reshape(-1)].reshape(6 * n, n, faces.shape[3])


def faces_from_openexr_cube(image: np.ndarray, world_to_file: np.ndarray | None = None
                            ) -> np.ndarray:
    """Inverse of `openexr_cube_image`: (6N, N, C) (or (6N, N)) -> (6, N, N, C) OpenGL faces."""
    image = np.asarray(image)
    if image.ndim == 2:
        image = image[..., None]
    n = image.shape[1]
    if image.ndim != 3 or image.shape[0] != 6 * n:
        raise ValueError(f"an OpenEXR cube image is (6N, N, C), got {image.shape}")
    idx = _gather(n, FACE_FORWARD, OPENEXR_RIGHT, OPENEXR_UP, _signed_permutation(world_to_file))
    faces = np.empty((6 * n * n, image.shape[2]), image.dtype)
    faces[idx.reshape(-1)] = image.reshape(6 * n * n, -1)
    return faces.reshape(6, n, n, image.shape[2])


def write_openexr_cube(path: str | os.PathLike, faces: np.ndarray, *,
                       world_to_file: np.ndarray | None = None, half: bool = False) -> None:
    """Write (6, N, N, C) faces (C = 1, 3 or 4) as an OpenEXR standard cube map: the N x 6N image
    of `openexr_cube_image` with the header attribute envmap = ENVMAP_CUBE."""
    import OpenEXR

    write_exr(path, openexr_cube_image(faces, world_to_file), half=half,
              header={"envmap": OpenEXR.ENVMAP_CUBE})


def stored_face_order(world_to_file: np.ndarray | None = None) -> tuple[str, ...]:
    """The world direction each face of an OpenEXR cube written with `world_to_file` looks along,
    in stacking order (the identity: +X -X +Y -Y +Z -Z; OPENEXR_Y_UP: +Y -Y +Z -Z +X -X): the
    `face_order` of `probe_json`."""
    m = _signed_permutation(world_to_file)
    face, _s, _t = direction_to_face(FACE_FORWARD @ m)  # rows: M^T of each file axis
    return tuple(FACE_NAMES[f] for f in face)


def read_envmap_attribute(path: str | os.PathLike) -> str | None:
    """The `envmap` header attribute of an EXR file: "CUBE", "LATLONG" or None when absent."""
    import OpenEXR

    with OpenEXR.File(os.fspath(path)) as f:
        value = f.header().get("envmap")
    if value is None:
        return None
    return {OpenEXR.ENVMAP_CUBE: "CUBE", OpenEXR.ENVMAP_LATLONG: "LATLONG"}.get(value, str(value))


def read_openexr_cube(path: str | os.PathLike, *, world_to_file: np.ndarray | None = None
                      ) -> np.ndarray:
    """Read an OpenEXR cube map into (6, N, N, C) float32 OpenGL-table faces. Raises ValueError
    when the file's envmap attribute is not CUBE."""
    kind = read_envmap_attribute(path)
    if kind != "CUBE":
        raise ValueError(f"{path}: envmap attribute is {kind!r}, not a cube map")
    return faces_from_openexr_cube(read_exr(path), world_to_file)


# ---------------------------------------------------------------------------------------------
# Lat-long (equirectangular), Blender's mapping
# ---------------------------------------------------------------------------------------------

def equirect_to_direction(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(...) u, v in [0, 1] (v = 1 at the top) -> (..., 3) float64 unit world directions.

    Cycles' `equirectangular_to_direction`: phi = pi - 2 pi u, theta = pi (1 - v) from +Z."""
    phi = np.pi - 2.0 * np.pi * np.asarray(u, np.float64)
    theta = np.pi * (1.0 - np.asarray(v, np.float64))
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


def direction_to_equirect(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(..., 3) directions (any length) -> u in [0, 1), v in [0, 1], Blender's mapping."""
    d = np.asarray(directions, np.float64)
    u = 0.5 - np.arctan2(d[..., 1], d[..., 0]) / (2.0 * np.pi)
    u = np.where(u >= 1.0, u - 1.0, u)  # atan2 = -pi exactly gives u = 1: the same column as 0
    v = 0.5 + np.arctan2(d[..., 2], np.hypot(d[..., 0], d[..., 1])) / np.pi
    return u, v


def equirect_directions(height: int, supersample: int = 1, rows: slice | None = None
                        ) -> np.ndarray:
    """(H', 2H, n*n, 3) float64 unit directions of an n x n grid of points inside every pixel of
    the rows `rows` (all: H' = H) of a 2H x H lat-long image (n = supersample; 1: pixel centres)."""
    width = 2 * height
    rows = rows or slice(0, height)
    row_ids = np.arange(height)[rows]
    sub = (np.arange(supersample) + 0.5) / supersample
    x = (np.arange(width)[:, None] + sub[None, :]).reshape(-1) / width   # (W n,) u
    y = (row_ids[:, None] + sub[None, :]).reshape(-1) / height            # (H' n,) 1 - v
    u = np.broadcast_to(x[None, :], (len(y), len(x)))
    v = np.broadcast_to(1.0 - y[:, None], (len(y), len(x)))
    dirs = equirect_to_direction(u, v)  # (H' n, W n, 3)
    dirs = dirs.reshape(len(row_ids), supersample, width, supersample, 3).transpose(0, 2, 1, 3, 4)
    return dirs.reshape(len(row_ids), width, supersample * supersample, 3)


def equirect_steps(faces: np.ndarray, height: int, supersample: int = 2, border: int = 0
                   ) -> Steps[np.ndarray]:
    """(6, N(+2B), N(+2B), C) faces -> (H, 2H, C) float32 lat-long image in Blender's mapping;
    yields progress in [0, 1] per block of rows.

    Each pixel averages n x n bilinear cube look-ups (n = supersample; a box filter, which matters
    near the poles where a pixel spans many texels). With `border` > 0 the faces carry that many
    border texels (`envmap.EnvironmentMap.faces`) and look-ups blend across seams
    (`cubemap.sample_bordered`); with 0 they clamp within a face (`cubemap.sample_cubemap`, at
    most half a texel off at the seams).
    """
    faces = _as_faces(faces)
    if border > 0:
        def look_up(dirs):
            return sample_bordered(faces, border, dirs)
    else:
        def look_up(dirs):
            return sample_cubemap(faces, dirs)
    width, per_pixel = 2 * height, supersample * supersample
    out = np.empty((height, width, faces.shape[3]), np.float32)
    block = max(1, EQUIRECT_BLOCK // (width * per_pixel))  # rows per block
    for start in range(0, height, block):
        rows = slice(start, min(start + block, height))
        dirs = equirect_directions(height, supersample, rows).reshape(-1, 3)
        values = look_up(dirs).reshape(rows.stop - start, width, per_pixel, -1)
        out[rows] = values.mean(axis=2, dtype=np.float64)
        yield rows.stop / height
    return out


def equirect_image(faces: np.ndarray, height: int, supersample: int = 2, border: int = 0
                   ) -> np.ndarray:
    """`equirect_steps` run to its end: (H, 2H, C) float32."""
    return drain(equirect_steps(faces, height, supersample, border))


def sample_equirect(image: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Bilinear look-up of a (H, W, C) lat-long image along (M, 3) directions -> (M, C) float32.
    Columns wrap around (u = 0 meets u = 1); rows clamp at the poles."""
    image = np.asarray(image)
    height, width = image.shape[:2]
    u, v = direction_to_equirect(np.asarray(directions).reshape(-1, 3))
    x = u * width - 0.5                                        # continuous column
    y = np.clip((1.0 - v) * height - 0.5, 0.0, height - 1.0)   # continuous row, 0 at the top
    x0 = np.floor(x).astype(np.int64)
    y0 = np.minimum(np.floor(y).astype(np.int64), max(height - 2, 0))
    fx = (x - x0)[:, None]
    fy = (y - y0)[:, None]
    x0 %= width
    x1 = (x0 + 1) % width
    y1 = np.minimum(y0 + 1, height - 1)
    top = image[y0, x0] * (1.0 - fx) + image[y0, x1] * fx
    bottom = image[y1, x0] * (1.0 - fx) + image[y1, x1] * fx
    return (top * (1.0 - fy) + bottom * fy).astype(np.float32)


def cube_from_equirect(image: np.ndarray, size: int) -> np.ndarray:
    """(H, W, C) lat-long image -> (6, N, N, C) float32 OpenGL faces (bilinear, texel centres)."""
    image = np.asarray(image)
    if image.ndim == 2:
        image = image[..., None]
    dirs = texel_directions(size).reshape(-1, 3)
    return sample_equirect(image, dirs).reshape(6, size, size, image.shape[2])


def write_equirect_exr(path: str | os.PathLike, image: np.ndarray, *, half: bool = False) -> None:
    """Write a (H, 2H, C) lat-long image with envmap = ENVMAP_LATLONG: Blender's Environment
    Texture reads it as is; OpenEXR's tools read it in `OPENEXR_Y_UP` axes (module docstring)."""
    import OpenEXR

    write_exr(path, image, half=half, header={"envmap": OpenEXR.ENVMAP_LATLONG})


# ---------------------------------------------------------------------------------------------
# Cross preview
# ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PreviewSettings:
    """Tone mapping and labels of the cross preview.

    | name           | range              | default    | unit  | meaning                              |
    |----------------|--------------------|------------|-------|--------------------------------------|
    | exposure       | -16..16            | 0.0        | stops | radiance is scaled by 2^exposure     |
    | tone           | reinhard, clamp    | reinhard   | -     | reinhard: x / (1 + x) per channel    |
    |                |                    |            |       | (no highlight clips); clamp: to [0,1]|
    | labels         | bool               | True       | -     | write each face's name (+X .. -Z)    |
    | label_scale    | 0, 1..16           | 0          | texel | glyph pixel size; 0: from face size  |

    Either curve is followed by the sRGB transfer curve (IEC 61966-2-1) and rounding to 8 bits.
    """

    exposure: float = 0.0
    tone: str = "reinhard"
    labels: bool = True
    label_scale: int = 0

    def __post_init__(self):
        if self.tone not in ("reinhard", "clamp"):
            raise ValueError(f"tone must be 'reinhard' or 'clamp', got {self.tone!r}")
        if not -16.0 <= self.exposure <= 16.0:
            raise ValueError(f"exposure must be in -16..16 stops, got {self.exposure}")
        if not 0 <= self.label_scale <= 16:
            raise ValueError(f"label_scale must be in 0..16, got {self.label_scale}")


def tone_map_rgb8(linear: np.ndarray, settings: PreviewSettings | None = None) -> np.ndarray:
    """(..., C) linear radiance -> (..., C) uint8 sRGB-encoded, by `settings`' exposure and curve.
    NaN and negative values become 0."""
    settings = settings or PreviewSettings()
    x = np.nan_to_num(np.asarray(linear, np.float64), nan=0.0, posinf=TONE_INFINITY, neginf=0.0)
    x = np.maximum(x, 0.0) * 2.0 ** settings.exposure
    x = x / (1.0 + x) if settings.tone == "reinhard" else np.minimum(x, 1.0)
    encoded = np.where(x <= SRGB_LINEAR_CUTOFF, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.round(np.clip(encoded, 0.0, 1.0) * 255.0).astype(np.uint8)


def label_mask(text: str, scale: int = 1) -> np.ndarray:
    """(7 s, 6 s len(text) - s) bool: `text` in the 5 x 7 font, one blank column between glyphs,
    each glyph pixel an s x s block."""
    rows = []
    for r in range(7):
        rows.append(" ".join(GLYPHS[ch][r] for ch in text))
    mask = np.array([[c == "#" for c in row] for row in rows], bool)
    return np.kron(mask, np.ones((scale, scale), bool))


def _draw_label(image: np.ndarray, text: str, top: int, left: int, scale: int) -> None:
    """Draw `text` into (H, W, 3) uint8 `image` at (top, left): white glyphs with a black outline
    one glyph pixel wide (readable on any face)."""
    mask = label_mask(text, scale)
    h, w = mask.shape
    pad = scale
    outline = np.zeros((h + 2 * pad, w + 2 * pad), bool)
    for dy in range(2 * pad + 1):
        for dx in range(2 * pad + 1):
            outline[dy:dy + h, dx:dx + w] |= mask
    region = image[top - pad:top + h + pad, left - pad:left + w + pad]
    region[outline[:region.shape[0], :region.shape[1]]] = 0
    region = image[top:top + h, left:left + w]
    region[mask[:region.shape[0], :region.shape[1]]] = 255


def cross_preview(faces: np.ndarray, settings: PreviewSettings | None = None) -> np.ndarray:
    """(6, N, N, C) OpenGL faces (C = 1, 3 or 4; alpha dropped) -> (3N, 4N, 3) uint8 sRGB preview:
    the horizontal cross of the module docstring, tone-mapped, each face labelled at its top left.
    """
    settings = settings or PreviewSettings()
    faces = _as_faces(faces)
    n = faces.shape[1]
    colour = faces[..., :3] if faces.shape[3] >= 3 else np.repeat(faces[..., :1], 3, axis=3)
    cells = np.array([c[2:] for c in CROSS_CELLS], np.float64)  # (6, 3 vectors, 3)
    idx = _gather(n, cells[:, 0], cells[:, 1], cells[:, 2], WORLD_AXES)
    shown = tone_map_rgb8(colour.reshape(6 * n * n, 3)[idx.reshape(-1)], settings)
    shown = shown.reshape(6, n, n, 3)
    image = np.full((3 * n, 4 * n, 3), CROSS_BACKGROUND, np.uint8)
    scale = settings.label_scale or max(1, n // LABEL_TEXELS_PER_PIXEL)
    for f, (row, col, *_axes) in enumerate(CROSS_CELLS):
        cell = image[row * n:(row + 1) * n, col * n:(col + 1) * n]
        cell[...] = shown[f]
        fits = 2 * scale + 7 * scale <= n and 2 * scale + 11 * scale <= n
        if settings.labels and fits:
            _draw_label(cell, FACE_NAMES[f], 2 * scale, 2 * scale, scale)
    return image


# ---------------------------------------------------------------------------------------------
# The probe's record
# ---------------------------------------------------------------------------------------------

def probe_json(position: Sequence[float], box_min: Sequence[float] | None,
               box_max: Sequence[float] | None, face_size: int,
               face_order: Sequence[str] = FACE_NAMES, levels: int = 1,
               sh: np.ndarray | None = None) -> dict:
    """A JSON-ready dict describing one reflection probe (what an engine needs beside the files).

    position (3,) m world; box_min/box_max (3,) m world, the box of a box-projected (parallax-
    corrected) look-up, or None; face_size texels of level 0; face_order the world direction of each
    stored face; levels the prefiltered mip count (level k: roughness k / (levels - 1), face size
    `prefilter.level_size`); sh (9, C) radiance SH coefficients (`sh_irradiance.sh_coefficients`).
    """
    if len(face_order) != 6 or set(face_order) != set(FACE_NAMES):
        raise ValueError(f"face_order must list the six faces {FACE_NAMES}, got {face_order}")
    record: dict = {
        "position": [float(v) for v in position],
        "axes": "world, metres, +Z up (Blender)",
        "face_order": list(face_order),
        "face_size": int(face_size),
        "mip_levels": [
            {"level": k, "roughness": level_roughness(k, levels),
             "face_size": level_size(int(face_size), k)}
            for k in range(int(levels))
        ],
    }
    if box_min is not None and box_max is not None:
        record["box"] = {"min": [float(v) for v in box_min], "max": [float(v) for v in box_max]}
    else:
        record["box"] = None
    if sh is not None:
        coeffs = np.asarray(sh, np.float64).reshape(9, -1)
        record["sh"] = {
            "basis": "real spherical harmonics l <= 2, order (0,0) (1,-1) (1,0) (1,1) (2,-2) "
                     "(2,-1) (2,0) (2,1) (2,2) of (x, y, z) world; coefficients of radiance",
            "coefficients": coeffs.tolist(),
        }
    return record
