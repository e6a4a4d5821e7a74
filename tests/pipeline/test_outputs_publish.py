"""Output names and the publish of a run's files as one set (pipeline/outputs.py), without Blender."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from classic_bake.pipeline import outputs
from classic_bake.pipeline.outputs import (
    MAX_NAME_LENGTH,
    Staging,
    UsageError,
    name_hash,
    safe_name,
    unique_stems,
)

HOSTILE = [".", "..", "a/b", "a_b", "Würfel", "W rfel", "Cube", "cube", "CON", "x" * 130,
           "x" * 120 + "y" * 10, "", "ünïcødé", "a\\b"]


def files(folder: Path) -> dict:
    return {p.relative_to(folder).as_posix(): p.read_bytes()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_unique_stems_are_safe_distinct_and_stable():
    stems = unique_stems(HOSTILE, reserve=len("_albedo.exr"))
    assert list(stems) == list(dict.fromkeys(HOSTILE))
    assert len({s.casefold() for s in stems.values()}) == len(stems)
    for name, stem in stems.items():
        assert len(stem) <= MAX_NAME_LENGTH - len("_albedo.exr")
        assert safe_name(stem) == stem  # already safe: staging keeps it as it is
        if safe_name(name) != name:  # cleaning changed it: the original's hash says which
            assert stem.endswith("-" + name_hash(name))
    assert stems["a_b"] == "a_b" and stems["Cube"] == "Cube"
    # The same names in another order get the same stems.
    assert unique_stems(list(reversed(HOSTILE)), reserve=11) == stems


def test_staged_names_keep_their_extension_and_never_collide(tmp_path):
    staging = Staging(tmp_path)
    names = [f"cube/{n}.exr" for n in HOSTILE] + ["x" * 300 + "_albedo.exr", "render.exr",
                                                  "render.png"]
    paths = [staging.file(n) for n in names]
    assert len({p.as_posix().casefold() for p in paths}) == len(names)
    for name, path in zip(names, paths, strict=True):
        assert path.suffix == Path(name).suffix and len(path.name) <= MAX_NAME_LENGTH
        assert staging.file(name) == path  # asked again: the same file
    assert staging.renamed["cube/W rfel.exr"].startswith("cube/W_rfel-")
    staging.discard()


def _stage(out: Path, contents: dict) -> Staging:
    staging = Staging(out)
    for name, data in contents.items():
        staging.file(name).write_bytes(data)
    return staging


def test_publish_swaps_the_set_and_leaves_no_hidden_folder(tmp_path):
    _stage(tmp_path, {"render.exr": b"1", "lightmaps/a_x.exr": b"1"}).publish()
    _stage(tmp_path, {"render.exr": b"2", "metrics.json": b"2"}).publish()
    assert files(tmp_path) == {"render.exr": b"2", "metrics.json": b"2", "lightmaps/a_x.exr": b"1"}
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


def test_a_folder_where_a_file_belongs_fails_before_anything_is_replaced(tmp_path):
    _stage(tmp_path, {"render.exr": b"old", "metrics.json": b"old"}).publish()
    (tmp_path / "render.png").mkdir()
    before = files(tmp_path)
    staging = _stage(tmp_path, {"render.exr": b"new", "render.png": b"new", "metrics.json": b"new"})
    with pytest.raises(UsageError, match="render.png"):
        staging.publish()
    staging.discard()
    assert files(tmp_path) == before and (tmp_path / "render.png").is_dir()


def test_a_failure_part_way_puts_the_previous_set_back(tmp_path, monkeypatch):
    _stage(tmp_path, {"a.exr": b"old", "b.exr": b"old", "c.exr": b"old"}).publish()
    before = files(tmp_path)
    staging = _stage(tmp_path, {"a.exr": b"new", "b.exr": b"new", "c.exr": b"new",
                                "new/d.exr": b"new"})
    real, calls = os.replace, []

    def failing(src, dst):
        calls.append(dst)
        if len(calls) == 5:  # a.exr aside, a.exr in, b.exr aside, b.exr in, then: disk trouble
            raise OSError(28, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(outputs.os, "replace", failing)
    with pytest.raises(OSError):
        staging.publish()
    monkeypatch.setattr(outputs.os, "replace", real)
    staging.discard()
    assert files(tmp_path) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.exr", "b.exr", "c.exr"]


def test_a_folder_symlink_is_never_written_through(tmp_path):
    out, elsewhere = tmp_path / "out", tmp_path / "elsewhere"
    out.mkdir()
    elsewhere.mkdir()
    (out / "lightmaps").symlink_to(elsewhere, target_is_directory=True)
    staging = _stage(out, {"lightmaps/x.exr": b"new"})
    with pytest.raises(UsageError, match="symbolic link"):
        staging.publish()
    staging.discard()
    assert list(elsewhere.iterdir()) == []


def test_a_file_symlink_is_replaced_not_written_through(tmp_path):
    target = tmp_path / "target.txt"
    target.write_bytes(b"keep")
    out = tmp_path / "out"
    out.mkdir()
    (out / "render.exr").symlink_to(target)
    _stage(out, {"render.exr": b"new"}).publish()
    assert target.read_bytes() == b"keep"
    assert not (out / "render.exr").is_symlink() and (out / "render.exr").read_bytes() == b"new"
