"""A tiled bake equals the untiled one: `radiosity --tile prepare`, `--tile K/3` for K = 1..3 and
`merge` write the same files as one run, bit for bit (each object's lightmap depends on its own
texels only, and the tiles read the solve the prepare step saved); so do `trace --tile K/N` (rows
of the camera view, with and without the edge pass) and `merge`, and `envmap --tile K/N` (cube
faces, merge rendering the view from the assembled maps) and `texture --tile K/N` (objects'
lightmaps, tile 1 the view); bad --tile values and an incomplete set of tiles fail with one line
(exit 2)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from classic_bake.kernels.measure.exr import read_exr
from classic_bake.pipeline.cli import main

ROOT = Path(__file__).resolve().parents[2]
SCENE = str(ROOT / "sample_blends" / "cornell_box.blend")
MIRRORS = str(ROOT / "sample_blends" / "raytrace.blend")
ENV_ROOM = str(ROOT / "sample_blends" / "env_room.blend")
SMALL = ["--resolution", "24", "18", "--lightmap-size", "48", "--patches", "60", "--quiet"]
# What differs between a tiled and an untiled run's metrics.json: the clock (the tracer's phases
# among it), and the tiles' own.
TIMED = ("seconds", "tiles", "phases")


def radiosity(out: Path, *extra, small=SMALL) -> int:
    return main(["radiosity", SCENE, "--out", str(out), *small, *extra])


def files(folder: Path) -> list[str]:
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                  if p.is_file() and "tiles" not in p.relative_to(folder).parts)


def untimed(value):
    """A metrics.json without its clock readings (the solve's own among them)."""
    if isinstance(value, dict):
        return {k: untimed(v) for k, v in value.items()
                if k not in TIMED and not k.endswith("seconds")}
    if isinstance(value, list):
        return [untimed(v) for v in value]
    return value


@pytest.mark.slow
def test_tiled_radiosity_equals_one_run(tmp_path):
    one, tiled = tmp_path / "one", tmp_path / "tiled"
    # Lightmaps large enough that the bake gathers the objects in several runs
    # (`lightmap.gather_groups`), which the tiles share.
    larger = [*SMALL, "--lightmap-size", "128"]
    assert radiosity(one, small=larger) == 0
    assert radiosity(tiled, "--tile", "prepare", small=larger) == 0
    for k in (3, 1, 2):  # in any order
        assert radiosity(tiled, "--tile", f"{k}/3", small=larger) == 0
    assert main(["merge", str(tiled), "--quiet"]) == 0
    assert files(one) == files(tiled)
    lightmaps = [f for f in files(one) if f.startswith("lightmaps/")]
    assert len(lightmaps) == 8
    for name in files(one):
        if name.endswith(".exr"):
            a, b = read_exr(one / name), read_exr(tiled / name)
            assert a.shape == b.shape and np.array_equal(a, b), name
        elif name.endswith(".png"):
            assert (one / name).read_bytes() == (tiled / name).read_bytes(), name
    single = json.loads((one / "metrics.json").read_text())
    merged = json.loads((tiled / "metrics.json").read_text())
    assert untimed(merged) == untimed(single)
    assert merged["tiles"]["count"] == 3 and merged["tiles"]["prepare"] is True
    assert set(merged["tiles"]["seconds"]) == {"prepare", "1-of-3", "2-of-3", "3-of-3"}
    assert merged["seconds"]["total"] >= sum(merged["tiles"]["seconds"].values())
    # Every object in exactly one tile.
    shares = [json.loads((tiled / "tiles" / f"{k}-of-3" / "metrics.json").read_text())
              ["tile_objects"] for k in (1, 2, 3)]
    assert sorted(sum(shares, [])) == sorted(single["lightmap_files"]) and all(shares)
    assert single["sizes"]["baked_texels"] > 3 * 16384
    # Merging again gives the same files.
    assert main(["merge", str(tiled), "--quiet"]) == 0
    assert np.array_equal(read_exr(tiled / lightmaps[0]), read_exr(one / lightmaps[0]))


@pytest.mark.parametrize("options", [("--adaptive", "0"), ("--supersample", "2", "--adaptive", "4")])
def test_tiled_trace_equals_one_run(tmp_path, options):
    one, tiled = tmp_path / "one", tmp_path / "tiled"
    size = ["--resolution", "31", "23", "--quiet", *options]  # 23 rows: tiles of 7, 8, 8
    assert main(["trace", MIRRORS, "--out", str(one), *size]) == 0
    for k in (2, 3, 1):
        assert main(["trace", MIRRORS, "--out", str(tiled), *size, "--tile", f"{k}/3"]) == 0
    assert main(["merge", str(tiled), "--quiet"]) == 0
    a, b = read_exr(one / "render.exr"), read_exr(tiled / "render.exr")
    assert a.shape == b.shape == (23, 31, 3) and np.array_equal(a, b)
    assert (one / "render.png").read_bytes() == (tiled / "render.png").read_bytes()
    single = json.loads((one / "metrics.json").read_text())
    merged = json.loads((tiled / "metrics.json").read_text())
    for key in ("technique", "settings", "sizes", "outputs"):
        assert merged[key] == single[key], key
    # Each pixel traced once for its tile, and with the edge pass the two rows either side of a
    # tile again (3 tiles x 31 columns x 4 rows x 2 x 2 samples), the nearer of them
    # edge-passed again (up to 2 rows x 4 x 4 samples), for the passes' neighbourhoods.
    rays = merged["stats"]["camera_rays"] - single["stats"]["camera_rays"]
    assert rays == 0 if options[1] == "0" else 0 <= rays <= 3 * 31 * (4 * 4 + 2 * 16)


@pytest.mark.slow
def test_tiled_envmap_equals_one_run(tmp_path):
    one, tiled = tmp_path / "one", tmp_path / "tiled"
    # Two maps, 12 faces: tile 2 of 3 holds the last two faces of one and the first two of the
    # other.
    run = ["envmap", ENV_ROOM, "--face-size", "16", "--resolution", "32", "24", "--mips", "2",
           "--objects", "MirrorSphere", "CrateSmall", "--quiet"]
    assert main([*run, "--out", str(one)]) == 0
    for k in (2, 3, 1):
        assert main([*run, "--out", str(tiled), "--tile", f"{k}/3"]) == 0
    shares = [json.loads((tiled / "tiles" / f"{k}-of-3" / "metrics.json").read_text())
              ["tile_faces"] for k in (1, 2, 3)]
    assert [len(s) for s in shares] == [4, 4, 4]
    assert shares[1] == [["MirrorSphere", 4], ["MirrorSphere", 5], ["CrateSmall", 0],
                         ["CrateSmall", 1]]
    assert not (tiled / "render.exr").exists()
    assert main(["merge", str(tiled), "--quiet"]) == 0
    assert files(one) == files(tiled)
    assert {"render.exr", "cube/MirrorSphere.exr", "cube/CrateSmall_latlong.exr",
            "cube/MirrorSphere_cross.png", "cube/CrateSmall_mip1.exr",
            "cube/MirrorSphere_probe.json"} <= set(files(one))
    for name in files(one):
        if name != "metrics.json":
            assert (one / name).read_bytes() == (tiled / name).read_bytes(), name
    single = json.loads((one / "metrics.json").read_text())
    merged = json.loads((tiled / "metrics.json").read_text())
    assert untimed(merged) == untimed(single)
    assert merged["tiles"]["count"] == 3 and merged["tiles"]["prepare"] is False


@pytest.mark.slow
def test_tiled_texture_equals_one_run(tmp_path):
    one, tiled = tmp_path / "one", tmp_path / "tiled"
    # env_room: a packed checkerboard image on the floor, nine objects shared by texel count.
    run = ["texture", ENV_ROOM, "--resolution", "24", "18", "--lightmap-size", "32", "--quiet"]
    assert main([*run, "--out", str(one)]) == 0
    for k in (3, 1, 2):
        assert main([*run, "--out", str(tiled), "--tile", f"{k}/3"]) == 0
    assert main(["merge", str(tiled), "--quiet"]) == 0
    assert files(one) == files(tiled)
    assert {"render.exr", "render.png"} < set(files(one))
    for name in files(one):
        if name != "metrics.json":
            assert (one / name).read_bytes() == (tiled / name).read_bytes(), name
    single = json.loads((one / "metrics.json").read_text())
    merged = json.loads((tiled / "metrics.json").read_text())
    assert single["sizes"]["textured_materials"]
    assert untimed(merged) == untimed(single)
    shares = [json.loads((tiled / "tiles" / f"{k}-of-3" / "metrics.json").read_text())
              ["tile_objects"] for k in (1, 2, 3)]
    assert sorted(sum(shares, [])) == sorted(single["lightmap_files"]) and all(shares)
    # The camera's view is tile 1's.
    assert (tiled / "tiles" / "1-of-3" / "render.exr").exists()
    assert not (tiled / "tiles" / "2-of-3" / "render.exr").exists()


def test_envmap_tile_refusals_are_one_line(tmp_path, capsys):
    run = ["envmap", ENV_ROOM, "--out", str(tmp_path / "out"), "--face-size", "8",
           "--resolution", "8", "6", "--quiet", "--tile"]
    for value, says in (("4/3", "K must be in [1, 3]"), ("7/7", "more tiles than the 6 cube faces"),
                        ("prepare", "its tiles need no prepare step")):
        assert main([*run, value]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and says in err, err
    assert not (tmp_path / "out").exists()
    texture = ["texture", SCENE, "--out", str(tmp_path / "texture"), "--resolution", "8", "6",
               "--lightmap-size", "16", "--quiet", "--tile", "99/99"]
    assert main(texture) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "more tiles than the scene's 8 objects" in err, err


@pytest.mark.parametrize("value, says", [
    ("0/3", "K must be in [1, 3]"), ("4/3", "K must be in [1, 3]"), ("1/0", "N must be in"),
    ("two", "--tile must be K/N"), ("1/2/3", "--tile must be K/N"), ("-1/2", "expected one argument"),
])
def test_a_bad_tile_value_is_one_line(tmp_path, capsys, value, says):
    assert radiosity(tmp_path / "out", "--tile", value) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and says in err, err
    assert not (tmp_path / "out").exists()


def test_tile_refusals_are_one_line(tmp_path, capsys):
    out = tmp_path / "out"
    # Tiles need the prepare step's solution; --save-blend has no meaning for a part.
    assert radiosity(out, "--tile", "1/2") == 2
    assert "run --tile prepare into the same --out first" in capsys.readouterr().err
    assert radiosity(out, "--tile", "1/2", "--save-blend") == 2
    assert "leave out --save-blend" in capsys.readouterr().err
    # Techniques that cannot tile have no --tile; trace's tiles need no prepare step and no more
    # tiles than rows.
    assert main(["shadowmap", SCENE, "--out", str(out), "--tile", "1/2", "--quiet"]) == 2
    assert "unrecognized arguments: --tile" in capsys.readouterr().err
    trace = ["trace", SCENE, "--out", str(tmp_path / "trace"), "--resolution", "8", "6", "--quiet"]
    assert main([*trace, "--tile", "prepare"]) == 2
    assert "its tiles need no prepare step" in capsys.readouterr().err
    assert main([*trace, "--tile", "7/7"]) == 2
    assert "more tiles than the view's 6 rows" in capsys.readouterr().err
    # merge: nothing to merge; then a tile missing.
    assert main(["merge", str(out), "--quiet"]) == 2
    assert "no tiles in" in capsys.readouterr().err
    assert radiosity(out, "--tile", "prepare") == 0
    assert radiosity(out, "--tile", "2/2") == 0
    assert main(["merge", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "tiles missing: 1-of-2" in err, err
    assert not (out / "metrics.json").exists()
