"""The camera views' edge pass (`camera_view.supersample_edges`): pixel coverage of silhouettes."""

import numpy as np
import pytest
from scene_builder import build, ortho_camera, quad

from classic_bake.kernels.bake.camera_view import (
    background_and_fragments,
    edge_pixels,
    pixel_patterns,
    stratified_offsets,
    supersample_edges,
)
from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.geometry.scene import Material


def test_stratified_offsets_are_cell_centres():
    np.testing.assert_allclose(stratified_offsets(2), [[0.25, 0.25], [0.75, 0.25], [0.25, 0.75],
                                                       [0.75, 0.75]])
    assert stratified_offsets(3).shape == (9, 2)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 8])
def test_pixel_patterns_take_one_cell_each_and_distinct_rows_and_columns(n):
    """In every pixel, sample k in cell k of the n x n grid, and no two in one row or column of
    the n^2 x n^2 grid: a horizontal edge at any height between two of those rows changes the
    pixel's coverage; n a power of two, one in every box of area 1/n^2 whose sides are powers of
    two (Hammersley's net, digitally shifted). Pixels differ in their patterns."""
    pixels = np.arange(0, 4000, 37)
    patterns = pixel_patterns(n, pixels).transpose(1, 0, 2)  # (P, m, 2)
    cells = np.floor(stratified_offsets(n) * n)
    m = n * n
    for offsets in patterns:
        np.testing.assert_array_equal(np.floor(offsets * n), cells)
        for axis in (0, 1):
            assert sorted(np.floor(offsets[:, axis] * m).astype(int)) == list(range(m))
        if n & (n - 1) == 0:
            for a in (2 ** e for e in range(int(np.log2(m)) + 1)):
                boxes = np.floor(offsets[:, 0] * a) * (m // a) + np.floor(offsets[:, 1] * m / a)
                assert len(np.unique(boxes)) == m
        # Coverage of a band y >= 1 - c (an edge along the pixel grid) to 1/n^2, not 1/n.
        for c in np.linspace(0.0, 1.0, 23):
            assert abs(np.mean(offsets[:, 1] >= 1.0 - c) - c) <= 1.0 / m + 1e-9
    if n == 1:
        np.testing.assert_allclose(patterns[:, 0], 0.5)
    else:
        assert len({p.tobytes() for p in patterns}) >= 4


def test_edge_pixels_mark_both_sides_of_an_id_or_contrast_step():
    image = np.zeros((4, 6, 3))
    ids = np.zeros((4, 6), np.int64)
    ids[:, 3:] = 1  # another object from column 3
    mark = edge_pixels(image, ids)
    assert mark[:, 2:4].all() and not mark[:, [0, 1, 4, 5]].any()
    image[2:, :, :] = 1.0  # a bright lower half of one object: a contrast step between rows 1, 2
    mark = edge_pixels(image, np.zeros((4, 6), np.int64))
    assert mark[1:3].all() and not mark[[0, 3]].any()


def test_a_silhouette_pixel_takes_the_share_of_it_the_surface_covers():
    """A white quad over a black world, its left edge at x = 0.3 m under an orthographic camera
    of 8 pixels across 1 m (pixel edges at multiples of 0.125 m): the pixel from 0.25 to 0.375 m
    is 60% covered. With 5 x 5 sub-pixel rays the pass finds 3 of 5 columns inside (centres at
    0.2625, ..., 0.3625: those past 0.3), exactly 0.6; covered pixels keep 1, empty ones 0."""
    white = Material(name="w", base_color=np.ones(3, np.float32), specular=0.0)
    sheet = quad([(0.3, -2, 0), (2, -2, 0), (2, 2, 0), (0.3, 2, 0)])
    camera = ortho_camera((0.5, 0.0, 1.0), (0, 0, -1), (0, 1, 0), 1.0, resolution=(8, 8))
    scene = build([(sheet, white)], camera=camera)
    image, f = background_and_fragments(scene)
    image[f.rows, f.cols] = 1.0
    np.testing.assert_array_equal(image[:, 2, 0], 1.0)  # its centre (0.3125) is on the sheet
    count = supersample_edges(scene, image, f, lambda g: np.ones((len(g), 3)),
                              BVH.build(scene.triangles), 5)
    assert count == 16  # the two columns either side of the edge, 8 rows each
    np.testing.assert_allclose(image[:, 2], 0.6, atol=1e-12)
    np.testing.assert_array_equal(image[:, 1], 0.0)
    np.testing.assert_array_equal(image[:, 3:], 1.0)


def test_an_edge_along_the_pixel_rows_is_resolved_to_a_ninth_of_a_pixel():
    """A white sheet over a black world, its top edge at y = 0.1025 m under an orthographic camera
    of 8 pixels across 1 m: row 3 (y from 0 to 0.125 m) is 82% covered. Its 3 x 3 rays per pixel
    sit in 9 different rows of a 9 x 9 grid (`pixel_patterns`), so every pixel of the row reads
    7/9, within a ninth of 0.82; rays at the cell centres would read 2/3 in every pixel."""
    white = Material(name="w", base_color=np.ones(3, np.float32), specular=0.0)
    sheet = quad([(-2, -2, 0), (2, -2, 0), (2, 0.1025, 0), (-2, 0.1025, 0)])
    camera = ortho_camera((0.5, 0.0, 1.0), (0, 0, -1), (0, 1, 0), 1.0, resolution=(8, 8))
    scene = build([(sheet, white)], camera=camera)
    image, f = background_and_fragments(scene)
    image[f.rows, f.cols] = 1.0
    np.testing.assert_array_equal(image[3], 1.0)  # the row's centres (y = 0.0625) are covered
    count = supersample_edges(scene, image, f, lambda g: np.ones((len(g), 3)),
                              BVH.build(scene.triangles), 3)
    assert count == 16  # rows 2 and 3, 8 pixels each
    np.testing.assert_allclose(image[3], 7.0 / 9.0, atol=1e-12)
    assert np.abs(image[3] - 0.82).max() < 1.0 / 9.0 < abs(2.0 / 3.0 - 0.82)
    np.testing.assert_array_equal(image[2], 0.0)
    np.testing.assert_array_equal(image[4:], 1.0)
