"""Which pixels show an object (`interior_pixels`): against a square whose pixels are known."""

import numpy as np

from classic_bake.kernels.measure.object_mask import interior_pixels
from tests.support.scene_builder import build, grey, ortho_camera, quad


def test_interior_pixels_are_the_square_without_its_rim():
    """An orthographic 10 x 10 px view, 1 m wide, looking down at a floor and, 1 cm above it, a
    square over pixel columns 2-6 and rows 3-8 (edges between pixel centres): the square's
    pixels less its one-pixel rim are interior; the floor fills the view, so its interior is
    the whole image less the square, the pixels beside it (left, right, above, below) and the
    image's border."""
    camera = ortho_camera([0.5, 0.5, 2.0], [0, 0, -1], [0, 1, 0], 1.0, (10, 10))
    floor = quad([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    # Pixel k spans [k, k + 1) / 10 m; rows count down from y = 1.
    square = quad([[0.2, 0.1, 0.01], [0.7, 0.1, 0.01], [0.7, 0.7, 0.01], [0.2, 0.7, 0.01]])
    scene = build([(floor, grey(0.5)), (square, grey(0.5, name="square"))], camera=camera)
    shown = np.zeros((10, 10), bool)
    shown[3:9, 2:7] = True
    inner = interior_pixels(scene, (10, 10), 1)
    expected = np.zeros_like(shown)
    expected[4:8, 3:6] = True
    np.testing.assert_array_equal(inner, expected)
    floor_inner = interior_pixels(scene, (10, 10), 0)
    rim = shown.copy()  # the square and the floor pixels beside it (not diagonally)
    rim[2:10, 2:7] = True
    rim[3:9, 1:8] = True
    border = np.ones_like(shown)
    border[1:-1, 1:-1] = False
    np.testing.assert_array_equal(floor_inner, ~rim & ~border)
