"""Height -> tangent-space normal map.

The lecture (lecture 13, "3. Bump Mapping"): in the tangent frame (t, b, n) the flat normal is
(0, 0, 1) and the perturbed one n* = normalize((x, y, 1)), x and y from the height's slopes. Here

    n* = normalize(-s dh/du, -s dh/dv, 1)     (tangent space: x along t, y along b, z along n)

with dh/du, dh/dv the height's slopes per UV unit (central differences one texel either side) and
s the strength. Signs, so that Cycles agrees: Blender's Bump node bends the normal against the
height's surface gradient, n* ~ n - D grad h (Cycles' `svm_node_set_bump`); on a surface whose UV
map is orthonormal with L metres per UV unit, grad h = (dh/du t + dh/dv b) / L, so the node's
normal in the frame is (-D/L dh/du, -D/L dh/dv, 1): this map with s = D / L, read by a Normal Map
node (tangent space, OpenGL green: x along the MikkTSpace tangent, y along b = sign (n x t), which
runs along +v), gives the Bump node's normal. A height rising towards +u therefore tilts the
normal towards -u (red below 0.5), rising towards +v tilts it towards -v (green below 0.5).

Texel (i, j) of the (size x size) map sits at u = (j + 0.5) / size, v = 1 - (i + 0.5) / size
(row 0 at the top). The map is made in bands of rows, yielding progress after each
(`kernels/progress.py`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..progress import Steps, drain
from .dilate import pad_normals
from .encode import GREEN_CONVENTIONS, GreenConvention, normals_to_rgb
from .heights import HeightSource, ImageHeight

# Rows of the map made between two progress yields (about 4 M texel evaluations at 4096 wide).
BAND_ROWS = 256
# Beyond this tilt from the flat normal a texel counts as steep: 89 degrees, where an 8-bit map's
# z (0.5 + cos/2) rounds to its lowest non-flat codes and a Normal Map node's result is no longer
# trustworthy (reported, not changed).
STEEP_COS = float(np.cos(np.radians(89.0)))


@dataclass(frozen=True)
class NormalMapSettings:
    """How a height becomes a tangent-space normal map.

    | name     | range           | default | unit      | meaning                                  |
    |----------|-----------------|---------|-----------|------------------------------------------|
    | size     | 0, 1 .. 16384   | 1024    | texels    | width and height of the map; 0: the      |
    |          |                 |         |           | height image's own size                  |
    | strength | >= 0            | 1.0     | UV units  | s in n* = normalize(-s h_u, -s h_v, 1);  |
    |          |                 |         | per height| a Bump node's Distance D on L metres per |
    |          |                 |         | unit      | UV unit is s = D / L                     |
    | green    | OPENGL, DIRECTX | OPENGL  |           | +y (Blender, glTF, Unity) or -y          |
    |          |                 |         |           | (DirectX, Unreal) in the green channel   |
    | padding  | 0 .. 64         | 8       | texels    | rings grown outward from the charts'     |
    |          |                 |         |           | texels when a chart mask is given        |
    """

    size: int = 1024
    strength: float = 1.0
    green: GreenConvention = "OPENGL"
    padding: int = 8

    def __post_init__(self):
        if self.green not in GREEN_CONVENTIONS:
            raise ValueError(f"green must be one of {GREEN_CONVENTIONS}, not {self.green!r}")
        if self.size < 0 or self.strength < 0 or self.padding < 0:
            raise ValueError("size, strength and padding must not be negative")
        if not math.isfinite(self.strength):  # nan slipped past the test above: nan normals
            raise ValueError(f"strength must be finite, got {self.strength}")


@dataclass(frozen=True)
class NormalMap:
    """A tangent-space normal map and its figures.

    | field             | shape             | meaning                                         |
    |-------------------|-------------------|-------------------------------------------------|
    | normals           | (H, W, 3) float32 | unit tangent-space normals, +y along +v         |
    |                   |                   | (OpenGL) whatever the green setting             |
    | rgb               | (H, W, 3) float32 | colours in [0, 1], green as settings.green      |
    |                   |                   | (`encode.to_uint8` for a PNG)                   |
    | mask              | (H, W) bool       | texels with a value: the chart mask grown by    |
    |                   |                   | the padding (all True without a mask)           |
    | degenerate_texels | int               | texels whose slope was not finite: set flat     |
    | steep_texels      | int               | texels tilted beyond 89 degrees (finite, unit)  |
    | settings          | NormalMapSettings | what made it                                    |
    """

    normals: np.ndarray
    rgb: np.ndarray
    mask: np.ndarray
    degenerate_texels: int
    steep_texels: int
    settings: NormalMapSettings


def texel_uvs(rows: np.ndarray, cols: np.ndarray, width: int, height: int) -> np.ndarray:
    """(R, C, 2) float64 UVs of texel centres at row indices rows (R,) and columns cols (C,)."""
    u = (np.asarray(cols, np.float64) + 0.5) / width
    v = 1.0 - (np.asarray(rows, np.float64) + 0.5) / height
    return np.stack(np.broadcast_arrays(u[None, :], v[:, None]), axis=-1)


def slope_normals(slope_u: np.ndarray, slope_v: np.ndarray, strength: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """(unit normals (..., 3) float64 tangent space, non-finite mask (...)) of slopes dh/du and
    dh/dv (...) per UV unit: normalize(-s dh/du, -s dh/dv, 1). Non-finite slopes give the flat
    normal. Scaled by the largest component before squaring, so any finite slope and strength
    give a finite unit normal."""
    a = np.asarray(slope_u, np.float64)
    b = np.asarray(slope_v, np.float64)
    bad = ~(np.isfinite(a) & np.isfinite(b))
    a, b = np.where(bad, 0.0, a), np.where(bad, 0.0, b)
    m = np.maximum(np.abs(a), np.abs(b))
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        sm = strength * m  # may overflow to inf: then z below is 0
        tilted = sm > 1.0
        # tilted: (-a/m, -b/m, 1/(s m)); otherwise (-s a, -s b, 1): both finite, largest part <= 1
        safe_m = np.where(tilted, m, 1.0)
        n = np.stack([np.where(tilted, -a / safe_m, -strength * a),
                      np.where(tilted, -b / safe_m, -strength * b),
                      np.where(tilted, 1.0 / np.where(tilted, sm, 1.0), 1.0)], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True), bad


def normal_map_steps(source: HeightSource, settings: NormalMapSettings = NormalMapSettings(),
                     mask: np.ndarray | None = None) -> Steps[NormalMap]:
    """Make the tangent-space normal map of a height source; yields progress, returns `NormalMap`.

    mask: optional (size, size) bool, the texels the mesh's UV charts cover; the others are filled
    by padding (`dilate.pad_normals`) and flat beyond it.
    """
    size = settings.size
    if size == 0:
        if source.resolution is None:
            raise ValueError("size 0 (the image's own) needs an image height source")
        width, height = source.resolution
    else:
        width = height = size
    normals = np.empty((height, width, 3), np.float32)
    du, dv = 1.0 / width, 1.0 / height  # one texel, UV units
    cols = np.arange(-1, width + 1)  # with a ring of texels outside: the source's own wrap
    degenerate = steep = 0
    grid = None
    if isinstance(source, ImageHeight) and source.resolution == (width, height):
        grid = source.texel_heights(pad=1)  # (H + 2, W + 2): one ring of wrapped texels
    for r0 in range(0, height, BAND_ROWS):
        rows = np.arange(r0, min(r0 + BAND_ROWS, height))
        halo = np.arange(rows[0] - 1, rows[-1] + 2)
        with np.errstate(invalid="ignore", over="ignore"):
            if grid is not None:  # an image at its own size: its texels, no interpolation
                h = grid[rows[0]:rows[-1] + 3]  # (R + 2, W + 2), padded rows start at -1
            else:
                uv = texel_uvs(halo, cols, width, height).reshape(-1, 2)
                h = source.heights(uv).reshape(len(halo), width + 2)  # (R + 2, W + 2)
            slope_u = (h[1:-1, 2:] - h[1:-1, :-2]).ravel() / (2.0 * du)  # height per UV unit
            slope_v = (h[:-2, 1:-1] - h[2:, 1:-1]).ravel() / (2.0 * dv)  # row above: higher v
        n, bad = slope_normals(slope_u, slope_v, settings.strength)
        degenerate += int(bad.sum())
        steep += int((n[:, 2] < STEEP_COS).sum())
        normals[rows] = n.reshape(len(rows), width, 3)
        yield float(rows[-1] + 1) / height * (0.95 if mask is not None else 1.0)
    filled = np.ones((height, width), bool)
    if mask is not None:
        normals, filled = pad_normals(normals, np.asarray(mask, bool), settings.padding)
        yield 1.0
    return NormalMap(normals=normals, rgb=normals_to_rgb(normals, settings.green), mask=filled,
                     degenerate_texels=degenerate, steep_texels=steep, settings=settings)


def normal_map(source: HeightSource, settings: NormalMapSettings = NormalMapSettings(),
               mask: np.ndarray | None = None) -> NormalMap:
    """`normal_map_steps` run to its end (for scripts and tests)."""
    return drain(normal_map_steps(source, settings, mask))
