"""A cube map prefiltered for GGX roughness: the mip chain a reflection probe holds.

Split-sum prefilter (Karis 2013, "Real Shading in Unreal Engine 4"), with the usual assumption
n = v = r (the lobe is centred on the look-up direction and does not stretch at grazing angles):

    L_k(r) = sum_i L_i D(h_i) max(r . l_i, 0) Omega_i / sum_i D(h_i) max(r . l_i, 0) Omega_i

over source texels i (direction l_i, solid angle Omega_i, radiance L_i), h_i = normalize(r + l_i),
with the GGX (Trowbridge-Reitz) distribution D(h) = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2).
With n = r, (n . h)^2 = (1 + r . l) / 2, so the weight depends on r . l alone (a zonal kernel) and
one level is a matrix product: weights (out texels x source texels) times radiance. The weights
carry pdf(l) = D(h) (n.h) / (4 v.h) = D(h) / 4 of GGX importance sampling times n . l; this is the
quantity Karis' sampler estimates, computed here by quadrature instead of sampling (no noise).

Level k of `levels` has roughness k / (levels - 1) and alpha = roughness^2 (Blender's Principled
BSDF and Karis' remapping); its faces are max(N >> k, min_size) texels. Level 0 (roughness 0, a
mirror) is the source itself. A rough lobe is wide, so its quadrature runs over a smaller source:
the source's mip (solid-angle-weighted 2 x 2 averages, exact partitions of the parent texel) whose
texels are at most `alpha / source_texels_per_alpha` radians wide, never smaller than the level.

Cost. A level's quadrature is 36 M_k^2 S_k^2 kernel evaluations (M_k output, S_k source face
size). Narrow lobes need fine sources, so for them (`two_scale_pays`) the sum is split: source
texels within a few alphas of the look-up direction one by one, the rest of the sphere through a
coarse mip (`prefilter_level_two_scale`), where GGX's tail is smooth. Measured on 2 cores: six
levels of a 64 map in 0.5 s, of a 128 map in 1.2 s (the 128 map's level 1 alone takes 57 s by
full quadrature, at a relMSE between the two of 3e-8).

Faces are (6, S, S, C) float32 radiance in the OpenGL table of `cubemap.py`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..progress import Steps, drain, scaled
from .cubemap import texel_directions

# Smallest face of a level: the roughest lobes are tens of degrees wide (roughness 1: a cosine
# lobe, 120 degrees at half maximum), 8 texels (11 degrees) per face resolve them.
MIN_LEVEL_SIZE = 8
# Source texels (angular width, at a face centre, pi / (2 S)) per alpha of the lobe: GGX's lobe
# in l falls to half its peak ~1.3 alpha from r, so 4 texels per alpha put ~10 across its core.
SOURCE_TEXELS_PER_ALPHA = 4.0
# The two-scale quadrature (narrow lobes on large faces): the coarse mip is the source / 8 per
# side (64 fine texels per coarse one), at least 8 texels per face; sources are summed one by one
# within 6 alphas of r (GGX's share beyond an angle 2 T from r is alpha^2 / (alpha^2 + T^2), 10%
# beyond 6 alphas, in a tail that changes slowly) and at least 3 coarse texels (the far sum's
# error is second order in a coarse texel's width over its distance: ~1/9 of a small share).
COARSE_FACTOR = 8
MIN_COARSE_SIZE = 8
NEAR_ALPHAS = 6.0
NEAR_COARSE_TEXELS = 3.0
# Weights per block of the quadrature (out texels x source texels, float32): 32 MB at a time.
BLOCK_ELEMENTS = 1 << 23


@dataclass(frozen=True)
class PrefilterSettings:
    """The mip chain of a GGX-prefiltered cube map.

    | name                    | range    | default | unit    | meaning                                |
    |-------------------------|----------|---------|---------|----------------------------------------|
    | levels                  | 1..16    | 6       | -       | mip levels; level k has roughness      |
    |                         |          |         |         | k / (levels - 1), alpha = roughness^2  |
    | min_size                | 1..64    | 8       | texels  | smallest face side of a level          |
    | source_texels_per_alpha | 0.25..64 | 4.0     | -       | source resolution of a level's         |
    |                         |          |         |         | quadrature: texel width <= alpha / this|
    """

    levels: int = 6
    min_size: int = MIN_LEVEL_SIZE
    source_texels_per_alpha: float = SOURCE_TEXELS_PER_ALPHA

    def __post_init__(self):
        if not 1 <= self.levels <= 16:
            raise ValueError(f"levels must be in 1..16, got {self.levels}")
        if not 1 <= self.min_size <= 64:
            raise ValueError(f"min_size must be in 1..64, got {self.min_size}")
        if not 0.25 <= self.source_texels_per_alpha <= 64.0:
            raise ValueError(f"source_texels_per_alpha must be in 0.25..64, got "
                             f"{self.source_texels_per_alpha}")


@dataclass(frozen=True)
class PrefilteredCube:
    """The prefiltered chain: levels[k] is (6, M_k, M_k, C) float32 radiance, OpenGL face table."""

    levels: tuple[np.ndarray, ...]
    roughness: tuple[float, ...]        # per level, k / (levels - 1)
    alpha: tuple[float, ...]            # per level, roughness^2
    source_sizes: tuple[int, ...]       # per level, the face size its quadrature summed over


def level_roughness(level: int, levels: int) -> float:
    """Roughness of mip `level` of `levels`: level / (levels - 1) (0 for a single level)."""
    return 0.0 if levels <= 1 else float(level) / float(levels - 1)


def level_size(face_size: int, level: int, min_size: int = MIN_LEVEL_SIZE) -> int:
    """Face side of mip `level`: face_size >> level, at least min(min_size, face_size)."""
    return max(face_size >> level, min(min_size, face_size))


def texel_solid_angles(size: int) -> np.ndarray:
    """(S, S) float64 sr: the exact solid angle of each texel of an S x S face (the same on every
    face); the six faces sum to 4 pi.

    The face plane at distance 1, texel [x0, x1] x [y0, y1] in [-1, 1]^2: with
    A(x, y) = atan2(x y, sqrt(x^2 + y^2 + 1)), Omega = A(x0, y0) - A(x0, y1) - A(x1, y0) + A(x1, y1).
    """
    edges = np.linspace(-1.0, 1.0, size + 1)
    x, y = np.meshgrid(edges, edges, indexing="xy")
    a = np.arctan2(x * y, np.sqrt(x * x + y * y + 1.0))
    return a[:-1, :-1] - a[1:, :-1] - a[:-1, 1:] + a[1:, 1:]


def downsample(faces: np.ndarray) -> np.ndarray:
    """(6, S, S, C) -> (6, S/2, S/2, C) float32: each parent texel the solid-angle-weighted mean
    of its 2 x 2 children (which partition it exactly). S must be even."""
    size = faces.shape[1]
    if size % 2:
        raise ValueError(f"downsample needs an even face size, got {size}")
    omega = texel_solid_angles(size)[None, :, :, None]  # (1, S, S, 1) sr
    weighted = (np.asarray(faces, np.float64) * omega).reshape(6, size // 2, 2, size // 2, 2, -1)
    total = omega.reshape(1, size // 2, 2, size // 2, 2, 1).sum(axis=(2, 4))
    return (weighted.sum(axis=(2, 4)) / total).astype(np.float32)


def _source_size(face_size: int, out_size: int, alpha: float, per_alpha: float) -> int:
    """Face size of the mip a level sums over: the coarsest whose texel (pi / (2 S) rad) is at most
    alpha / per_alpha wide, not coarser than the level itself, not finer than the source."""
    size = face_size
    while size % 2 == 0 and size // 2 >= out_size and np.pi / size <= alpha / per_alpha:
        size //= 2  # pi / size is the half-size mip's texel width, pi / (2 (size / 2))
    return size


def _weighted_sum(out_dirs: np.ndarray, src_dirs: np.ndarray, src: np.ndarray, alpha: float
                  ) -> np.ndarray:
    """(b, 3) look-up directions, (Q, 3) source directions, (Q, C + 1) source [L Omega, Omega] ->
    (b, C + 1) float64 sums of the GGX weights times `src` (float32 arithmetic, float64 result).

    With (n.h)^2 = (1 + c) / 2, D's denominator root is c (a2 - 1) / 2 + (a2 + 1) / 2; a2 and
    1/pi are common to every weight and cancel in the normalisation."""
    a2 = alpha * alpha
    k1, k0 = np.float32(0.5 * (a2 - 1.0)), np.float32(0.5 * (a2 + 1.0))
    c = out_dirs @ src_dirs.T                                                   # (b, Q) r . l
    denom = c * k1
    denom += k0
    denom *= denom
    np.maximum(c, 0.0, out=c)
    c /= denom                                                                  # (b, Q) weights
    return (c @ src).astype(np.float64)


def _source_terms(source: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(6, S, S, C) faces -> directions (6 S S, 3) float32 and [L Omega, Omega] (6 S S, C + 1)
    float32, texels in face, row, column order."""
    s, channels = source.shape[1], source.shape[3]
    dirs = texel_directions(s).reshape(-1, 3).astype(np.float32)                # (Q, 3) world
    omega = np.tile(texel_solid_angles(s).reshape(-1), 6)                       # (Q,) sr
    terms = np.concatenate([source.reshape(-1, channels) * omega[:, None], omega[:, None]], axis=1)
    return dirs, terms.astype(np.float32)


def prefilter_level(source: np.ndarray, out_size: int, alpha: float) -> Steps[np.ndarray]:
    """One level by quadrature over every texel of `source` (6, S, S, C): yields progress, returns
    (6, M, M, C) float32 (M = out_size) prefiltered radiance."""
    channels = source.shape[3]
    src_dirs, src = _source_terms(source)
    out_dirs = texel_directions(out_size).reshape(-1, 3).astype(np.float32)     # (P, 3) world
    out = np.empty((len(out_dirs), channels), np.float32)
    block = max(1, BLOCK_ELEMENTS // len(src_dirs))
    for start in range(0, len(out_dirs), block):
        stop = min(start + block, len(out_dirs))
        acc = _weighted_sum(out_dirs[start:stop], src_dirs, src, alpha)        # (b, C + 1)
        out[start:stop] = acc[:, :channels] / acc[:, channels:]
        yield stop / len(out_dirs)
    return out.reshape(6, out_size, out_size, channels)


def _near_radius(alpha: float, coarse_size: int) -> float:
    """Angle (rad) from a look-up direction within which the two-scale quadrature sums source
    texels one by one: NEAR_ALPHAS alphas of the lobe, at least NEAR_COARSE_TEXELS coarse texels."""
    return max(NEAR_ALPHAS * alpha, NEAR_COARSE_TEXELS * 0.5 * np.pi / coarse_size)


def two_scale_pays(size: int, out_size: int, alpha: float) -> bool:
    """Whether `prefilter_level_two_scale` sums fewer terms than `prefilter_level` for a source of
    `size` (estimated from the near cone's share of the sphere, tile and texel radii included)."""
    coarse = max(size // COARSE_FACTOR, 1)
    if coarse < MIN_COARSE_SIZE or size % COARSE_FACTOR:
        return False
    # the near radius, plus a coarse texel's radius (~0.6 of its width) and a tile's (~0.75)
    reach = (_near_radius(alpha, coarse) + 0.6 * 0.5 * np.pi / coarse
             + 0.75 * 0.5 * np.pi / (out_size // _tile(out_size)))
    share = 0.5 * (1.0 - np.cos(min(reach, np.pi)))
    return share * 6 * size * size + 6 * coarse * coarse < 0.5 * 6 * size * size


def _tile(out_size: int) -> int:
    """Output texels per tile side: 8 x 8 tiles per face (1 x 1 texels below 8)."""
    return max(1, out_size // 8)


def prefilter_level_two_scale(source: np.ndarray, out_size: int, alpha: float
                              ) -> Steps[np.ndarray]:
    """One level like `prefilter_level`, in less work for narrow lobes: source texels near the
    look-up direction are summed one by one, the rest of the sphere through a coarse mip.

    The coarse mip (face size S / COARSE_FACTOR) partitions the sphere; for a tile of output
    texels, a coarse texel whose centre lies within the near radius (plus the tile's and the
    texel's own radii) of the tile's centre contributes its fine children exactly, every other
    coarse texel contributes once, at its children's solid-angle-weighted mean direction, with
    their summed L Omega and Omega. Far from the lobe GGX's weight changes slowly (its tail falls
    as angle^-4), so the far sum's error is second order in the coarse texel's angle over the
    distance; the near cone takes NEAR_ALPHAS alphas and NEAR_COARSE_TEXELS coarse texels.
    """
    size, channels = source.shape[1], source.shape[3]
    coarse = size // COARSE_FACTOR
    fine_dirs, fine = _source_terms(source)                                     # (Q, 3), (Q, C+1)
    # children of each coarse texel, (6 c c, F^2) indices into the fine arrays
    f, i, j = np.meshgrid(np.arange(6), np.arange(size), np.arange(size), indexing="ij")
    parent = ((f * coarse + i // COARSE_FACTOR) * coarse + j // COARSE_FACTOR).reshape(-1)
    children = np.argsort(parent, kind="stable").reshape(6 * coarse * coarse, -1)
    coarse_terms = fine[children].sum(axis=1)                                   # (6 c c, C + 1)
    centroid = (fine_dirs[children] * fine[children][:, :, -1:]).sum(axis=1)
    coarse_dirs = (centroid / np.linalg.norm(centroid, axis=1, keepdims=True)).astype(np.float32)
    # the widest coarse texel, seen from its centroid (its children's centres + half a fine texel)
    spread = np.einsum("pk,pck->pc", coarse_dirs, fine_dirs[children]).min()
    coarse_radius = float(np.arccos(np.clip(spread, -1.0, 1.0))) + 0.5 * np.pi / size
    tile = _tile(out_size)
    tiles = out_size // tile
    out_dirs = texel_directions(out_size).astype(np.float32)                    # (6, M, M, 3)
    out = np.empty((6, out_size, out_size, channels), np.float32)
    reach = _near_radius(alpha, coarse) + coarse_radius
    count, total = 0, 6 * tiles * tiles
    for face in range(6):
        for ti in range(tiles):
            for tj in range(tiles):
                rows = slice(ti * tile, (ti + 1) * tile)
                cols = slice(tj * tile, (tj + 1) * tile)
                dirs = out_dirs[face, rows, cols].reshape(-1, 3)                # (T T, 3)
                centre = dirs.sum(axis=0)
                centre /= np.linalg.norm(centre)
                tile_radius = float(np.arccos(np.clip((dirs @ centre).min(), -1.0, 1.0)))
                cos_reach = np.cos(min(reach + tile_radius, np.pi))
                near = coarse_dirs @ centre >= cos_reach                        # (6 c c,) bool
                picked = children[near].reshape(-1)
                src_dirs = np.concatenate([fine_dirs[picked], coarse_dirs[~near]])
                src = np.concatenate([fine[picked], coarse_terms[~near]])
                acc = _weighted_sum(dirs, src_dirs, src, alpha)
                out[face, rows, cols] = (acc[:, :channels] / acc[:, channels:]).reshape(
                    tile, tile, channels)
                count += 1
                yield count / total
    return out


def prefilter_steps(faces: np.ndarray, settings: PrefilterSettings | None = None
                    ) -> Steps[PrefilteredCube]:
    """The GGX mip chain of (6, N, N, C) faces: yields progress in [0, 1], returns PrefilteredCube.
    Progress is shared by each level's kernel evaluations (36 M^2 S^2)."""
    settings = settings or PrefilterSettings()
    faces = np.asarray(faces, np.float32)
    if faces.ndim != 4 or faces.shape[0] != 6 or faces.shape[1] != faces.shape[2]:
        raise ValueError(f"cube faces must be (6, N, N, C), got {faces.shape}")
    n = faces.shape[1]
    rough = [level_roughness(k, settings.levels) for k in range(settings.levels)]
    alphas = [r * r for r in rough]
    sizes = [level_size(n, k, settings.min_size) for k in range(settings.levels)]
    sources = [n if a == 0.0 else _source_size(n, m, a, settings.source_texels_per_alpha)
               for a, m in zip(alphas, sizes, strict=True)]
    cost = [0.0 if a == 0.0 else float(m * m) * s * s
            for a, m, s in zip(alphas, sizes, sources, strict=True)]
    total = sum(cost) or 1.0
    pyramid = {n: faces}
    while min(pyramid) % 2 == 0 and min(pyramid) > min(sources):
        pyramid[min(pyramid) // 2] = downsample(pyramid[min(pyramid)])
    levels, done = [], 0.0
    for k in range(settings.levels):
        if alphas[k] == 0.0:
            # a mirror: D is a delta at r, the level is the source (resampled if min_size made it
            # differ, which cannot happen for level 0)
            levels.append(faces.copy())
            continue
        source = pyramid[sources[k]]
        if two_scale_pays(sources[k], sizes[k], alphas[k]):
            steps = prefilter_level_two_scale(source, sizes[k], alphas[k])
        else:
            steps = prefilter_level(source, sizes[k], alphas[k])
        levels.append((yield from scaled(steps, done / total, cost[k] / total)))
        done += cost[k]
    yield 1.0
    return PrefilteredCube(tuple(levels), tuple(rough), tuple(alphas), tuple(sources))


def prefilter(faces: np.ndarray, settings: PrefilterSettings | None = None) -> PrefilteredCube:
    """`prefilter_steps` run to its end."""
    return drain(prefilter_steps(faces, settings))
