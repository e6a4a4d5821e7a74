"""Padding a normal map's charts across their UV borders (kernels/normalmap/dilate.py)."""

import numpy as np

from classic_bake.kernels.normalmap.dilate import FLAT, chart_mask, pad_normals
from classic_bake.kernels.normalmap.from_height import NormalMapSettings, normal_map
from classic_bake.kernels.normalmap.heights import ProceduralHeight

# One UV triangle covering the lower-left half of the map, away from the borders.
TRIANGLE = np.array([[[0.2, 0.2], [0.8, 0.2], [0.2, 0.8]]])


def test_chart_mask_covers_the_triangle_texel_centres():
    size = 40
    mask = chart_mask(TRIANGLE, size, size)
    rows, cols = np.indices((size, size))
    u, v = (cols + 0.5) / size, 1.0 - (rows + 0.5) / size
    inside = (u > 0.2) & (v > 0.2) & (u + v < 1.0)
    on_edge = (np.abs(u - 0.2) < 1e-9) | (np.abs(v - 0.2) < 1e-9) | (np.abs(u + v - 1.0) < 1e-9)
    assert np.array_equal(mask[~on_edge], inside[~on_edge])


def test_padding_fills_border_texels_and_leaves_the_inside_untouched():
    size, padding = 40, 3
    mask = chart_mask(TRIANGLE, size, size)
    made = normal_map(ProceduralHeight("orange_peel", scale=3.0),
                      NormalMapSettings(size=size, strength=0.05))
    padded, filled = pad_normals(made.normals, mask, padding)
    # The charts' own texels are kept bit for bit.
    assert np.array_equal(padded[mask], made.normals[mask])
    # Exactly the texels within `padding` rings (8-neighbourhood: Chebyshev distance) are filled.
    rows, cols = np.nonzero(mask)
    r, c = np.indices((size, size))
    chebyshev = np.min(np.maximum(np.abs(r[..., None] - rows), np.abs(c[..., None] - cols)), axis=2)
    assert np.array_equal(filled, chebyshev <= padding)
    ring = filled & ~mask
    assert ring.sum() > 0
    # Grown texels are unit normals and lie within the range of the chart's normals.
    assert np.allclose(np.linalg.norm(padded[ring], axis=1), 1.0, atol=1e-6)
    assert padded[ring][:, 2].min() >= made.normals[mask][:, 2].min() - 1e-6
    # A first-ring texel is the mean of its chart neighbours, normalised.
    i, j = next((i, j) for i, j in zip(*np.nonzero(ring), strict=True) if chebyshev[i, j] == 1)
    window = (slice(max(i - 1, 0), i + 2), slice(max(j - 1, 0), j + 2))
    mean = made.normals[window][mask[window]].mean(axis=0)
    np.testing.assert_allclose(padded[i, j], mean / np.linalg.norm(mean), atol=1e-6)
    # Beyond the padding: flat.
    assert np.array_equal(padded[~filled], np.broadcast_to(FLAT, (int((~filled).sum()), 3)))


def test_masked_normal_map_pads_and_keeps_chart_texels():
    size = 32
    mask = chart_mask(TRIANGLE, size, size)
    source = ProceduralHeight("bricks")
    full = normal_map(source, NormalMapSettings(size=size))
    masked = normal_map(source, NormalMapSettings(size=size, padding=2), mask=mask)
    assert np.array_equal(masked.normals[mask], full.normals[mask])
    assert masked.mask.sum() > mask.sum() and not masked.mask.all()
    assert np.array_equal(masked.rgb[~masked.mask], np.broadcast_to([0.5, 0.5, 1.0],
                                                                    (int((~masked.mask).sum()), 3)))
