"""Tiles: one large bake split into parts that run as separate processes (a render farm's tasks)
and merge into the same outputs as one process writes (`pipeline/commands/merge.py`).

`--tile K/N` runs part K of N (1-based); `--tile prepare` runs the part every tile needs first,
where a technique has one (radiosity: the solve, saved once, and the camera's view). What a tile
splits is named by its record (`Technique.tiles`):

* "lightmaps": the objects' lightmaps, shared among the tiles by texel count (`share`):
  radiosity's in the runs of objects the bake gathers together
  (`kernels/radiosity/lightmap.gather_groups`), texture's one by one; a run's (an object's)
  values depend on its own points only, so a tile's objects come out exactly as in one process;
* "rows": the camera view's rows (`row_range`), each pixel traced as the whole view traces it
  (`kernels/trace/tracer.trace_steps`, `rows`);
* "faces": the cube maps' faces (envmap: `jobs/envmap.face_list`, every mapped object's six in
  a fixed order, split by count like rows), each texel traced as the whole cube traces it
  (`kernels/envmap/envmap.capture_faces_steps`); `merge` renders the view from the assembled
  maps (the technique's `tile_merge`).

A tile writes into OUT/tiles/: its part's files (`tile_folder`) and a record of its run
(metrics.json there); `merge OUT` puts them together.
"""

from __future__ import annotations

import io
import pickle
from dataclasses import dataclass
from pathlib import Path

TILE_FOLDER = "tiles"
PREPARE = "prepare"
SOLUTION = "solution.pickle"
MAX_TILES = 1024


@dataclass(frozen=True)
class Tile:
    """Part `index` (1-based) of `count`; index 0: the prepare step."""

    index: int
    count: int

    @property
    def prepare(self) -> bool:
        return self.index == 0

    @property
    def name(self) -> str:
        return PREPARE if self.prepare else f"{self.index}-of-{self.count}"

    @property
    def folder(self) -> str:
        """Where in the output folder this tile's files go."""
        return f"{TILE_FOLDER}/{self.name}"


def parse_tile(text: str) -> Tile:
    """`K/N` (1 <= K <= N <= MAX_TILES) or `prepare`; ValueError with one line otherwise."""
    value = text.strip()
    if value == PREPARE:
        return Tile(0, 0)
    k, slash, n = value.partition("/")
    if not slash or not k.strip().isdigit() or not n.strip().isdigit():
        raise ValueError(f"--tile must be K/N (part K of N, e.g. 2/4) or 'prepare', got {text!r}")
    k, n = int(k), int(n)
    if not 1 <= n <= MAX_TILES:
        raise ValueError(f"--tile {text}: N must be in [1, {MAX_TILES}]")
    if not 1 <= k <= n:
        raise ValueError(f"--tile {text}: K must be in [1, {n}]")
    return Tile(k, n)


def share(weights: list[float], tile: Tile) -> list[int]:
    """The items (indices into `weights`) tile K of N takes: largest first, each to the tile with
    the least weight so far (ties: the lower tile). The same on every tile, so the tiles take
    every item exactly once."""
    loads = [0.0] * tile.count
    mine = []
    for item in sorted(range(len(weights)), key=lambda i: (-weights[i], i)):
        least = min(range(tile.count), key=lambda t: (loads[t], t))
        loads[least] += weights[item]
        if least == tile.index - 1:
            mine.append(item)
    return sorted(mine)


def row_range(height: int, tile: Tile) -> tuple[int, int]:
    """Rows [a, b) of an image `height` rows tall that tile K of N takes: contiguous, in order,
    their sizes differing by at most one. ValueError when there are more tiles than rows."""
    if tile.count > height:
        raise ValueError(f"--tile {tile.index}/{tile.count}: more tiles than the view's "
                         f"{height} rows")
    return (height * (tile.index - 1)) // tile.count, (height * tile.index) // tile.count


# --- a solution saved by `--tile prepare` and read by the tiles ------------------------------------

_NUMPY = {("numpy", "ndarray"), ("numpy", "dtype"), ("numpy._core.multiarray", "_reconstruct"),
          ("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "scalar"),
          ("numpy.core.multiarray", "scalar"), ("numpy._core.numeric", "_frombuffer"),
          ("numpy.core.numeric", "_frombuffer"), ("builtins", "frozenset"), ("builtins", "set"),
          ("builtins", "slice"), ("builtins", "complex")}


class _KernelUnpickler(pickle.Unpickler):
    """Builds only NumPy arrays and this package's kernel types (frozen dataclasses of arrays),
    never an arbitrary callable: a solution file is data, whoever wrote it."""

    def find_class(self, module, name):
        kernels = __package__.rpartition(".")[0] + ".kernels."
        if (module, name) in _NUMPY or (module.startswith(kernels) and not name.startswith("_")):
            found = super().find_class(module, name)
            if isinstance(found, type):
                return found
            if (module, name) in _NUMPY:
                return found
        raise pickle.UnpicklingError(f"a solution file may not hold {module}.{name}")


def save_solution(path: Path, result) -> None:
    """The kernel result `result` (arrays and kernel dataclasses) into `path`."""
    Path(path).write_bytes(pickle.dumps(result, protocol=pickle.HIGHEST_PROTOCOL))


def load_solution(path: Path):
    """The kernel result `save_solution` wrote; ValueError (one line) when it is missing or is not
    one."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise ValueError(f"no solution at {path} ({exc.strerror}): run --tile prepare into the "
                         "same --out first") from exc
    try:
        return _KernelUnpickler(io.BytesIO(data)).load()
    except (pickle.UnpicklingError, EOFError, AttributeError, ImportError, TypeError) as exc:
        raise ValueError(f"{path} is not a solution --tile prepare wrote: {exc}") from exc
