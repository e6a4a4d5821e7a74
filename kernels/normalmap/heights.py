"""Height sources for normal maps: an image with a wrap mode, or a procedural pattern by name.

A source maps UVs (N, 2) to heights (N,) float64, in its own units (an image's value, usually in
[0, 1]); `from_height` differences it along u and v. Images follow the project's convention (row 0
at the top, texel (i, j) centred at u = (j + 0.5) / W, v = 1 - (i + 0.5) / H) and are looked up
bilinearly as Cycles does (`shading.textures.sample_image`), colour images by their Rec. 709
luminance, as Blender turns a colour into a Bump node's Height.

The procedural patterns (`PROCEDURAL_HEIGHTS`):

| name        | height                                                 | used for              |
|-------------|--------------------------------------------------------|-----------------------|
| orange_peel | sqrt(d / cell) capped at 1: d the distance to the      | the lecture's         |
|             | nearest dimple, one seeded point in each of `cells` x  | bump-mapped orange    |
|             | `cells` grid cells (Worley F1, tiling in u and v)      |                       |
| bricks      | running bond, `rows` x `cols` bricks per tile: 0 in    | the lecture's bricks  |
|             | the mortar, ramping to 1 over `bevel` beyond it        |                       |
| checker     | Cycles' Checker Texture over (u, v) at `scale`: 1 on   | steep steps (tests)   |
|             | colour-1 squares, 0 elsewhere                          |                       |
| ramp        | slope_u u + slope_v v                                  | a constant normal     |
| sphere      | sqrt(radius^2 - r^2) inside the disc r < radius about  | analytic normals      |
|             | (0.5, 0.5), 0 outside (UV units)                       | (u-1/2, v-1/2, h) / R |

The orange peel and bricks are the continuous forms of the sample scene's images
(`sample_blends/sample_textures.py`), so any map size samples the same relief.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from ..shading.bump import LUMINANCE
from ..shading.textures import checker, sample_image

WrapMode = Literal["REPEAT", "CLAMP", "MIRROR"]
WRAP_MODES: tuple[str, ...] = get_args(WrapMode)
# Blender's names for the same extensions (`shading.textures.sample_image`).
_EXTENSION = {"REPEAT": "REPEAT", "CLAMP": "EXTEND", "MIRROR": "MIRROR"}
# NumPy's pad modes for the same (MIRROR repeats the edge texel: index -1 reads texel 0).
_NUMPY_PAD = {"REPEAT": "wrap", "CLAMP": "edge", "MIRROR": "symmetric"}

ProceduralName = Literal["orange_peel", "bricks", "checker", "ramp", "sphere"]
PROCEDURAL_HEIGHTS: tuple[str, ...] = get_args(ProceduralName)
# Points evaluated at once by the orange peel.
_CHUNK = 1 << 16
# Cells searched either side of a point's own for its nearest dimple: the own cell's point is at
# most sqrt(2) cells away, a point three cells over at least 2, so two cells either side are exact.
_REACH = 2


@dataclass(frozen=True)
class ImageHeight:
    """Heights from an image.

    | name | range | default | unit | meaning |
    |------|-------|---------|------|---------|
    | pixels | (H, W) or (H, W, C) | | height | the image, row 0 at the top; C >= 3: luminance of RGB |
    | wrap | REPEAT, CLAMP, MIRROR | REPEAT | | what lies outside [0, 1]^2 |
    """

    pixels: np.ndarray
    wrap: WrapMode = "REPEAT"

    def __post_init__(self):
        if self.wrap not in WRAP_MODES:
            raise ValueError(f"wrap must be one of {WRAP_MODES}, not {self.wrap!r}")

    @property
    def resolution(self) -> tuple[int, int]:
        """(W, H) texels."""
        return int(self.pixels.shape[1]), int(self.pixels.shape[0])

    def texel_heights(self, pad: int = 0) -> np.ndarray:
        """(H + 2 pad, W + 2 pad) float64 heights at the texel centres (what `heights` gives
        there), with `pad` rings of texels outside the image filled by the wrap mode."""
        pixels = np.asarray(self.pixels)
        if pixels.ndim == 3:
            pixels = pixels[..., :3] @ LUMINANCE if pixels.shape[2] >= 3 else pixels[..., 0]
        return np.pad(np.asarray(pixels, np.float64), pad, mode=_NUMPY_PAD[self.wrap])

    def heights(self, uv: np.ndarray) -> np.ndarray:
        """(N,) float64 heights at (N, 2) UVs, bilinear between texel centres."""
        pixels = np.asarray(self.pixels, np.float32)
        if pixels.ndim == 2:
            pixels = pixels[..., None]
        values = sample_image(pixels, uv, _EXTENSION[self.wrap]).astype(np.float64)
        if values.shape[1] >= 3:
            return values[:, :3] @ LUMINANCE
        return values[:, 0]


@dataclass(frozen=True)
class ProceduralHeight:
    """A procedural height pattern by name (see the module docstring's table).

    | name       | range              | default | unit           | meaning                      |
    |------------|--------------------|---------|----------------|------------------------------|
    | name       | PROCEDURAL_HEIGHTS |         |                | the pattern                  |
    | scale      | > 0                | 1       | tiles per UV   | orange_peel, bricks, checker |
    |            |                    |         | unit           | (checker: the node's Scale)  |
    | cells      | >= 1               | 22      | per tile side  | orange_peel: dimple grid     |
    | rows, cols | >= 1               | 16, 8   | per tile       | bricks: rows and columns     |
    | mortar     | [0, 0.5)           | 1/256   | tile units     | bricks: half the joint       |
    | bevel      | > 0                | 3/256   | tile units     | bricks: mortar-to-face ramp  |
    | slope      | any                | (1, 0)  | height per UV  | ramp: (dh/du, dh/dv)         |
    | radius     | > 0                | 0.5     | UV units       | sphere: the cap's radius     |
    | seed       | any int            | 7       |                | orange_peel: the dimples     |
    """

    name: ProceduralName
    scale: float = 1.0
    cells: int = 22
    rows: int = 16
    cols: int = 8
    mortar: float = 1.0 / 256.0
    bevel: float = 3.0 / 256.0
    slope: tuple[float, float] = (1.0, 0.0)
    radius: float = 0.5
    seed: int = 7

    def __post_init__(self):
        if self.name not in PROCEDURAL_HEIGHTS:
            raise ValueError(f"unknown height pattern {self.name!r}: one of {PROCEDURAL_HEIGHTS}")

    @property
    def resolution(self) -> None:
        """Procedural patterns have no texels of their own."""
        return None

    def heights(self, uv: np.ndarray) -> np.ndarray:
        """(N,) float64 heights at (N, 2) UVs."""
        uv = np.asarray(uv, np.float64)
        u, v = uv[:, 0], uv[:, 1]
        if self.name == "ramp":
            return self.slope[0] * u + self.slope[1] * v
        if self.name == "sphere":
            r2 = (u - 0.5) ** 2 + (v - 0.5) ** 2
            return np.sqrt(np.maximum(self.radius**2 - r2, 0.0))
        if self.name == "checker":
            white, black = np.ones(3), np.zeros(3)
            return checker(uv, white, black, self.scale)[:, 0].astype(np.float64)
        if self.name == "bricks":
            return _bricks(uv * self.scale, self.rows, self.cols, self.mortar, self.bevel)
        return _orange_peel(uv * self.scale, self.cells, self.seed)


def _bricks(uv: np.ndarray, rows: int, cols: int, mortar: float, bevel: float) -> np.ndarray:
    """Running bond in a unit tile: odd rows shifted by half a brick; heights in [0, 1]."""
    u, v = np.mod(uv[:, 0], 1.0), np.mod(uv[:, 1], 1.0)
    y = (1.0 - v) * rows  # brick rows counted from the top, as the sample image
    row = np.floor(y)
    x = np.mod(u * cols + 0.5 * np.mod(row, 2.0), cols)
    # distance (UV units of the tile) to the nearest joint
    fy, fx = y - row, x - np.floor(x)
    edge = np.minimum(np.minimum(fy, 1.0 - fy) / rows, np.minimum(fx, 1.0 - fx) / cols)
    return np.clip((edge - mortar) / bevel, 0.0, 1.0)


def _orange_peel(uv: np.ndarray, cells: int, seed: int) -> np.ndarray:
    """Worley F1 dimples tiling the unit square, one seeded point in each of cells x cells grid
    cells: sqrt(d / cell) capped at 1 (d the distance to the nearest point)."""
    jitter = np.random.default_rng(seed).random((cells, cells, 2))  # point in its cell, [0, 1)^2
    out = np.empty(len(uv))
    for start in range(0, len(uv), _CHUNK):
        p = np.mod(uv[start:start + _CHUNK], 1.0) * cells  # cell units: distances are d / cell
        base = np.floor(p)
        nearest = np.full(len(p), np.inf)
        for dy in range(-_REACH, _REACH + 1):
            for dx in range(-_REACH, _REACH + 1):
                c = base + (dx, dy)
                ci = np.mod(c, cells).astype(np.int64)
                d = c + jitter[ci[:, 1], ci[:, 0]] - p
                nearest = np.minimum(nearest, (d * d).sum(axis=1))
        out[start:start + _CHUNK] = np.sqrt(np.minimum(np.sqrt(nearest), 1.0))
    return out


HeightSource = ImageHeight | ProceduralHeight


def height_source(source, wrap: WrapMode = "REPEAT", **params) -> HeightSource:
    """A height source from a pattern's name (with `ProceduralHeight`'s parameters) or from an
    image array (H, W) or (H, W, C) with a wrap mode."""
    if isinstance(source, (ImageHeight, ProceduralHeight)):
        return source
    if isinstance(source, str):
        return ProceduralHeight(source, **params)  # type: ignore[arg-type]
    return ImageHeight(np.asarray(source), wrap)
