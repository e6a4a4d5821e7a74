"""write_exr's `header` keyword (kernels/measure/exr.py): extra attributes reach the file, the
default header and the pixels stay as they were."""

import numpy as np

from classic_bake.kernels.measure.exr import read_exr, write_exr


def test_header_attributes_are_written(tmp_path):
    import OpenEXR

    pixels = np.arange(6 * 2 * 2 * 3, dtype=np.float32).reshape(12, 2, 3)
    path = tmp_path / "cube.exr"
    write_exr(path, pixels, header={"envmap": OpenEXR.ENVMAP_CUBE, "owner": "classic bake"})
    with OpenEXR.File(str(path)) as f:
        header = dict(f.header())  # the live header empties when the file closes
    assert header["envmap"] == OpenEXR.ENVMAP_CUBE
    assert header["owner"] == "classic bake"
    assert header["compression"] == OpenEXR.ZIP_COMPRESSION
    assert np.array_equal(read_exr(path), pixels)


def test_no_header_writes_no_extra_attributes(tmp_path):
    import OpenEXR

    path = tmp_path / "plain.exr"
    write_exr(path, np.ones((2, 2, 3), np.float32))
    write_exr(tmp_path / "none.exr", np.ones((2, 2, 3), np.float32), header=None)
    for name in ("plain.exr", "none.exr"):
        with OpenEXR.File(str(tmp_path / name)) as f:
            header = dict(f.header())  # the live header empties when the file closes
        assert "envmap" not in header and "owner" not in header
        assert header["compression"] == OpenEXR.ZIP_COMPRESSION


def test_header_can_override_a_default(tmp_path):
    import OpenEXR

    path = tmp_path / "piz.exr"
    pixels = np.random.default_rng(0).random((8, 8, 3)).astype(np.float32)
    write_exr(path, pixels, header={"compression": OpenEXR.PIZ_COMPRESSION})
    with OpenEXR.File(str(path)) as f:
        assert f.header()["compression"] == OpenEXR.PIZ_COMPRESSION
    assert np.array_equal(read_exr(path), pixels)
