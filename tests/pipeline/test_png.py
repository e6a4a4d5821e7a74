"""The dependency-free PNG encoder (pipeline/images.py) decodes to the same pixels in Pillow."""

import numpy as np
import pytest
from PIL import Image

from classic_bake.pipeline.images import write_png


@pytest.mark.parametrize("shape", [(5, 7), (5, 7, 1), (5, 7, 3), (5, 7, 4), (1, 1, 3)])
def test_png_round_trip(tmp_path, shape):
    pixels = (np.random.default_rng(0).random(shape) * 256).astype(np.uint8)
    path = write_png(tmp_path / "x.png", pixels)
    back = np.array(Image.open(path))
    assert np.array_equal(back, pixels.reshape(back.shape))


def test_png_refuses_floats(tmp_path):
    with pytest.raises(ValueError, match="uint8"):
        write_png(tmp_path / "x.png", np.zeros((2, 2, 3), np.float32))
