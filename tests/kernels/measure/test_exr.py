"""OpenEXR round trips (kernels/exr.py): float32 data comes back bit-exact, channels named."""

import numpy as np
import pytest

from classic_bake.kernels.measure.exr import read_exr, write_exr


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_round_trip_is_bit_exact(tmp_path, channels):
    rng = np.random.default_rng(7)
    pixels = (rng.standard_normal((17, 23, channels)) * 1e3).astype(np.float32)
    pixels[0, 0, 0] = np.float32(1e-40)  # a denormal survives too
    pixels[1, 1, 0] = np.float32(3.4e38)
    path = tmp_path / "x.exr"
    write_exr(path, pixels)
    back = read_exr(path)
    assert back.dtype == np.float32 and back.shape == pixels.shape
    assert np.array_equal(back.view(np.uint32), pixels.view(np.uint32))


def test_channel_names_follow_the_convention(tmp_path):
    import OpenEXR

    path = tmp_path / "rgb.exr"
    write_exr(path, np.zeros((2, 2, 3), np.float32))
    with OpenEXR.File(str(path), separate_channels=True) as f:
        assert sorted(f.channels()) == ["B", "G", "R"]
    write_exr(path, np.zeros((2, 2), np.float32))
    with OpenEXR.File(str(path), separate_channels=True) as f:
        assert sorted(f.channels()) == ["Y"]


def test_row_zero_is_the_first_scanline(tmp_path):
    import OpenEXR

    pixels = np.zeros((3, 2, 3), np.float32)
    pixels[0] = 1.0
    write_exr(tmp_path / "t.exr", pixels)
    with OpenEXR.File(str(tmp_path / "t.exr"), separate_channels=True) as f:
        assert f.channels()["R"].pixels[0, 0] == 1.0


def test_bad_shapes_are_refused(tmp_path):
    with pytest.raises(ValueError, match="expected"):
        write_exr(tmp_path / "x.exr", np.zeros((2, 2, 2), np.float32))
