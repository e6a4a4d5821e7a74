"""Lightmap UVs: unwrap and pack a triangle mesh into [0, 1]^2 with xatlas, for a given resolution.

Every texel of a lightmap belongs to at most one chart: charts are packed `padding` texels apart at
`resolution`, so bilinear filtering and dilation never mix two surfaces.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# Density fitting: start a little under xatlas' own estimate, shrink by 10% until one atlas holds
# every chart; 12 tries cover a 3.5x over-estimate.
FIT_MARGIN = 0.98
SHRINK_PER_ATTEMPT = 0.9
MAX_FIT_ATTEMPTS = 12


@dataclass(frozen=True)
class LightmapUVSettings:
    """| field        | range     | default | unit / meaning                                          |
    |--------------|-----------|---------|---------------------------------------------------------|
    | resolution   | 16..16384 | 512     | texels along each side of the square lightmap           |
    | padding      | 0..64     | 2       | texels kept free between charts (and from the border)   |
    | max_chart_area | >= 0    | 0       | xatlas chart area limit, 0 = unlimited                  |
    | seed_bilinear| bool      | True    | xatlas `bilinear`: pad for bilinear filtering           |
    """

    resolution: int = 512
    padding: int = 2
    max_chart_area: float = 0.0
    seed_bilinear: bool = True

    def __post_init__(self):
        if not 16 <= self.resolution <= 16384:
            raise ValueError(f"lightmap resolution must be in [16, 16384], got {self.resolution}")
        if not 0 <= self.padding <= 64:
            raise ValueError(f"lightmap padding must be in [0, 64] texels, got {self.padding}")


@dataclass(frozen=True)
class LightmapUV:
    """The result of an unwrap, per triangle corner of the input.

    corner_uv   (T, 3, 2) float32  UV of each triangle corner, in [0, 1]
    chart_ids   (T,) int32         chart of each triangle; -1 for zero-area triangles, which
                                   xatlas leaves out (their corners sit at UV (0, 0), no texels)
    """

    corner_uv: np.ndarray
    chart_ids: np.ndarray
    chart_count: int
    utilization: float  # fraction of the atlas covered by charts


def unwrap(
    positions: np.ndarray, triangles: np.ndarray, settings: LightmapUVSettings = LightmapUVSettings()
) -> LightmapUV:
    """Unwrap and pack one mesh.

    positions (V, 3) float, object or world space, m (only ratios matter); triangles (T, 3) vertex ids.
    Zero-area triangles get no chart (chart id -1) and UV (0, 0): they cover no texel.
    """
    import xatlas

    positions = np.ascontiguousarray(positions, np.float32)
    triangles = np.ascontiguousarray(triangles, np.uint32)
    if triangles.shape[0] == 0:
        return LightmapUV(np.zeros((0, 3, 2), np.float32), np.zeros(0, np.int32), 0, 0.0)

    def generate(texels_per_unit: float):
        atlas = xatlas.Atlas()
        atlas.add_mesh(positions, triangles)
        chart_options = xatlas.ChartOptions()
        if settings.max_chart_area > 0:
            chart_options.max_chart_area = float(settings.max_chart_area)
        pack = xatlas.PackOptions()
        pack.resolution = int(settings.resolution)
        pack.padding = int(settings.padding)
        pack.bilinear = bool(settings.seed_bilinear)
        pack.texels_per_unit = float(texels_per_unit)
        atlas.generate(chart_options, pack)
        return atlas

    # With texels_per_unit = 0 xatlas only estimates a density and may overshoot the resolution.
    # Fixing the density makes it pack into atlases of exactly `resolution`; shrink the density
    # until everything fits in one, so padding is measured in texels of the real lightmap.
    atlas = generate(0.0)
    density = atlas.texels_per_unit * FIT_MARGIN * settings.resolution / max(atlas.width, atlas.height)
    for _ in range(MAX_FIT_ATTEMPTS):
        atlas = generate(density)
        if atlas.atlas_count == 1:
            break
        density *= SHRINK_PER_ATTEMPT
    else:
        raise ValueError(
            f"lightmap UVs: charts do not fit one {settings.resolution}^2 atlas with "
            f"{settings.padding} texels of padding; raise the resolution or lower the padding"
        )
    vmapping, indices, uvs = atlas[0]
    corner_uv = uvs[indices].astype(np.float32)  # (T, 3, 2) in [0, 1] of the square atlas
    _, vertex_chart = atlas.get_mesh_vertex_assignment(0)
    chart_ids = np.asarray(vertex_chart, np.int64)[indices[:, 0]].astype(np.int32)
    return LightmapUV(corner_uv, chart_ids, int(atlas.chart_count), float(atlas.utilization))


# Smallest lightmap an object gets: below 16 texels a side the padding eats the charts.
MIN_LIGHTMAP_SIZE = 16


def lightmap_sizes(areas_m2, largest_size: int) -> list[int]:
    """Per-object lightmap sizes at one texel density: the largest object gets `largest_size`
    texels per side, every other object sqrt(its area / the largest area) of it, rounded up to a
    power of two and kept in [MIN_LIGHTMAP_SIZE, largest_size]. A 1 m^2 plate beside a 400 m^2
    floor then gets 1/20 of the floor's texels per side instead of as many."""
    areas = np.maximum(np.asarray(areas_m2, np.float64), 0.0)
    if areas.size == 0:
        return []
    top = max(float(areas.max()), 1e-12)
    wanted = largest_size * np.sqrt(areas / top)
    sizes = 2 ** np.ceil(np.log2(np.maximum(wanted, 1.0)))
    return [int(s) for s in np.clip(sizes, MIN_LIGHTMAP_SIZE, largest_size)]
