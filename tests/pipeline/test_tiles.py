"""Tiles without Blender (jobs/tiles.py): `--tile` parsing, the share of items each tile takes,
and the solution file, which builds only kernel types and arrays."""

from __future__ import annotations

import os
import pickle

import numpy as np
import pytest

from classic_bake.jobs.tiles import Tile, load_solution, parse_tile, save_solution, share
from classic_bake.kernels.radiosity.patches import Patches


def test_parse_tile():
    assert parse_tile("2/3") == Tile(2, 3) and parse_tile(" 1/1 ") == Tile(1, 1)
    assert parse_tile("prepare").prepare and parse_tile("3/4").name == "3-of-4"
    for bad in ("0/2", "3/2", "1/0", "a/b", "2", "", "1/2/3", "1/2000"):
        with pytest.raises(ValueError):
            parse_tile(bad)


@pytest.mark.parametrize("count", [1, 2, 3, 7])
def test_every_item_in_exactly_one_tile(count):
    weights = [float(w) for w in np.random.default_rng(count).integers(0, 100, 11)]
    taken = [share(weights, Tile(k, count)) for k in range(1, count + 1)]
    assert sorted(sum(taken, [])) == list(range(len(weights)))
    loads = [sum(weights[i] for i in t) for t in taken]
    assert max(loads) - min(loads) <= max(weights)  # largest first, each to the lightest tile


class Shell:  # pickles as a call of os.system: not data
    def __reduce__(self):
        return (os.system, ("echo never",))


def test_solution_round_trip_and_refusals(tmp_path):
    path = tmp_path / "solution.pickle"
    fields = {name: np.arange(6.0).reshape(2, 3) for name in Patches.__dataclass_fields__}
    try:
        value = Patches(**fields)
    except TypeError:
        pytest.skip("Patches takes more than arrays")
    save_solution(path, value)
    back = load_solution(path)
    assert type(back) is Patches
    path.write_bytes(pickle.dumps(Shell()))
    with pytest.raises(ValueError, match="may not hold"):
        load_solution(path)
    with pytest.raises(ValueError, match="run --tile prepare"):
        load_solution(tmp_path / "missing.pickle")
