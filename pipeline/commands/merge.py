"""`merge OUT`: the tiles of a bake (`TECHNIQUE SCENE --out OUT --tile K/N`, jobs/tiles.py) put
together into the outputs one untiled run writes into OUT: its images and EXR files, and a
metrics.json whose seconds are the sums over the prepare step, the tiles and the merge (per phase,
and `tiles` lists each part's). The tiles' folder (OUT/tiles/) stays, so a merge can run again.

What a tile holds, by the technique's record (`Technique.tiles`):

* "lightmaps": its objects' finished lightmap files, copied as they are; render.exr and
  render.png come from the prepare step (radiosity) or tile 1 (texture);
* "rows": render.exr of its rows (metrics.json `tile_rows`), stacked in order into render.exr and
  render.png; the rays in `stats` are summed (an edge pass traces the rows next to a tile too);
* "faces": its share of the cube maps' faces (envmap): the technique's `tile_merge` puts the cube
  maps together and computes from them what one run writes (the camera's view, each map's
  lat-long, cross, mips and probe record), its sizes and statistics replacing the tiles'.
"""

from __future__ import annotations

import copy
import json
import shutil
from pathlib import Path

import numpy as np

from ..command import Command, RunContext
from ..outputs import Staging, UsageError

RECORD = "metrics.json"
KEEP_IN_TILES = {"solution.pickle", "view.pickle"}  # what a tile writes for the other tiles, not an output


def read_tiles(out: Path) -> tuple[dict | None, list[dict]]:
    """(the prepare step's metrics.json or None, the tiles' in order), checked: one technique,
    scene and settings, one N, every tile 1..N present. UsageError (one line) otherwise."""
    from ...jobs.tiles import PREPARE, TILE_FOLDER

    folder = out / TILE_FOLDER
    records = {}
    for path in sorted(folder.glob(f"*/{RECORD}")) if folder.is_dir() else []:
        try:
            records[path.parent.name] = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise UsageError(f"cannot read {path}: {exc}") from exc
    prepare = records.pop(PREPARE, None)
    if not records:
        raise UsageError(f"no tiles in {folder}: run `TECHNIQUE SCENE --out {out} --tile K/N` "
                         "for K = 1..N first")
    counts = sorted({r.get("tile", {}).get("count") for r in records.values()}, key=str)
    if len(counts) != 1 or not isinstance(counts[0], int):
        raise UsageError(f"{folder} holds tiles of different splits ({', '.join(sorted(records))}); "
                         "remove the old ones")
    n = counts[0]
    missing = [f"{k}-of-{n}" for k in range(1, n + 1) if f"{k}-of-{n}" not in records]
    if missing:
        raise UsageError(f"{folder}: tiles missing: {', '.join(missing)}")
    tiles = [records[f"{k}-of-{n}"] for k in range(1, n + 1)]
    first = tiles[0]
    for record in tiles[1:] + ([prepare] if prepare else []):
        for key in ("technique", "scene", "settings"):
            if record.get(key) != first.get(key):
                name = record.get("tile", {}).get("name", "?")
                raise UsageError(f"{folder}: tile {name} ran with another {key} than tile 1-of-{n}")
    return prepare, tiles


def summed(values: list):
    """Numbers summed, dicts summed key by key, lists joined; anything else: the first."""
    if all(isinstance(v, bool) for v in values) or not values:
        return values[0] if values else None
    if all(isinstance(v, int | float) for v in values):
        return sum(values)
    if all(isinstance(v, dict) for v in values):
        keys = list(dict.fromkeys(k for v in values for k in v))
        return {k: summed([v[k] for v in values if k in v]) for k in keys}
    if all(isinstance(v, list) for v in values):
        return [x for v in values for x in v]
    return values[0]


def merged_record(technique, prepare: dict | None, tiles: list[dict]) -> dict:
    """metrics.json of the whole bake from the parts' (see the module docstring)."""
    parts = ([prepare] if prepare else []) + tiles
    record = copy.deepcopy(prepare if prepare else tiles[0])
    for key in ("tile", "file_names", "tile_objects", "outputs"):
        record.pop(key, None)
    if technique.tiles == "lightmaps":
        for key in ("baked_texels", "filtered_texels", "objects", "look_ups"):
            if key in record.get("sizes", {}):
                record["sizes"][key] = sum(t["sizes"].get(key, 0) for t in tiles)
        if "texels_per_cells_per_side" in record:  # texture: texels by cells per side
            counts = summed([t.get("texels_per_cells_per_side", {}) for t in tiles])
            record["texels_per_cells_per_side"] = {k: counts[k] for k in sorted(counts, key=int)}
        files = {k: v for t in tiles for k, v in t.get("lightmap_files", {}).items()}
        order = tiles[0].get("lightmap_order", list(files))  # the whole bake's
        record["lightmap_files"] = {k: files[k] for k in sorted(files, key=order.index)}
        skipped = [why for t in tiles for why in t.get("skipped", ())]
        if skipped:
            record["skipped"] = skipped
    elif technique.tiles == "rows" and "stats" in record:
        record["stats"] = summed([t.get("stats", {}) for t in tiles])
    for key in ("lightmap_order", "tile_rows", "tile_faces"):
        record.pop(key, None)
    record["seconds"] = {k: round(v, 6) for k, v in
                         summed([p.get("seconds", {}) for p in parts]).items()}
    record["tiles"] = {"count": len(tiles), "prepare": prepare is not None,
                       "seconds": {p["tile"]["name"]: p.get("seconds", {}).get("total", 0.0)
                                   for p in parts}}
    return record


def part_outputs(folder: Path, record: dict) -> list[tuple[str, Path]]:
    """(name in the merged set, file) of every output a part lists (in its folder)."""
    prefix = f"{folder.parent.name}/{folder.name}/"
    out = []
    for name in record.get("outputs", []):
        rel = name[len(prefix):] if name.startswith(prefix) else name
        if rel not in KEEP_IN_TILES and rel != RECORD:
            out.append((rel, folder / rel))
    return out


def merge_rows(staging: Staging, out: Path, tiles: list[dict]) -> None:
    """render.exr and render.png from the tiles' rows, in order."""
    from ...jobs.tiles import TILE_FOLDER
    from ...kernels.measure.exr import read_exr, write_exr
    from ..images import write_preview_png

    bands, end = [], 0
    for record in tiles:
        name = record["tile"]["name"]
        a, b = record.get("tile_rows", (None, None))
        band = read_exr(out / TILE_FOLDER / name / "render.exr")
        if a != end or band.shape[0] != b - a:
            raise UsageError(f"tile {name} does not hold the rows after the tile before it")
        bands.append(band)
        end = b
    image = np.concatenate(bands, axis=0)
    if image.shape[0] != tiles[0]["sizes"].get("height", image.shape[0]):
        raise UsageError(f"the tiles hold {image.shape[0]} rows, not the view's "
                         f"{tiles[0]['sizes']['height']}")
    write_exr(staging.file("render.exr"), image)
    write_preview_png(staging.file("render.png"), image)


def merge_computed(technique, staging: Staging, out: Path, tiles: list[dict], record: dict) -> None:
    """The files the technique's `tile_merge` computes from the tiles (envmap: the view and the
    maps' files from the faces), written as one run writes them; their sizes and statistics
    replace the tiles' in `record`."""
    from ...jobs.tiles import TILE_FOLDER
    from .technique import write_outputs

    try:
        summary = technique.tile_merge(out / TILE_FOLDER, tiles)
    except ValueError as exc:
        raise UsageError(f"merge: {exc}") from exc
    write_outputs(staging, summary)
    record["settings"] = summary.settings
    record["sizes"] = summary.sizes
    record.update(summary.extra)
    if staging.renamed:
        record["file_names"] = dict(staging.renamed)


def add_arguments(parser) -> None:
    parser.add_argument("out", type=Path, metavar="OUT",
                        help="the --out folder the tiles ran into (OUT/tiles/)")


def run(ctx: RunContext) -> None:
    from ...jobs.techniques import BY_NAME
    from ...jobs.tiles import TILE_FOLDER
    from ..outputs import PhaseTimer
    from ..run import interrupts_deferred

    out: Path = ctx.args.out
    timer = PhaseTimer()
    prepare, tiles = read_tiles(out)
    technique = BY_NAME.get(tiles[0].get("technique"))
    if technique is None or not technique.tiles:
        raise UsageError(f"{out}: technique {tiles[0].get('technique')!r} has no tiles to merge")
    if technique.tile_prepare and prepare is None:
        raise UsageError(f"{out / TILE_FOLDER}: the prepare step's folder is missing: run "
                         f"`{technique.name} SCENE --out {out} --tile prepare`")
    staging = Staging(out)
    try:
        with timer.phase("merge"):
            record = merged_record(technique, prepare, tiles)
            # In the order one run writes them: the prepare step's, then the lightmaps'.
            if technique.tiles == "rows":
                merge_rows(staging, out, tiles)
            elif technique.tile_merge is not None:
                merge_computed(technique, staging, out, tiles, record)
            else:
                # A lightmap's preview (texture: .png) beside its .exr, as one run writes them.
                rank = {f.rpartition(".")[0]: k
                        for k, f in enumerate(record.get("lightmap_files", {}).values())}
                found = [pair for part in ([prepare] if prepare else []) + tiles
                         for pair in part_outputs(out / TILE_FOLDER / part["tile"]["name"], part)]
                for rel, source in sorted(found,
                                          key=lambda pair: rank.get(pair[0].rpartition(".")[0], -1)):
                    shutil.copyfile(source, staging.file(rel))
        own = timer.totals()
        record["seconds"]["merge"] = own["merge"]
        record["seconds"]["total"] = record["seconds"].get("total", 0.0) + own["total"]
        record["outputs"] = [f for f in staging.files if f != RECORD]
        staging.write_json(RECORD, record)
        with interrupts_deferred():
            published = staging.publish()
    except OSError as exc:
        staging.discard()
        raise UsageError(f"cannot merge into {out}: {exc.strerror or exc} ({exc.filename})") from exc
    except BaseException:
        staging.discard()
        raise
    ctx.say(f"merged {len(tiles)} tiles{' and the prepare step' if prepare else ''} of "
            f"{technique.name} into {len(published)} files in {out}")


COMMAND = Command(name="merge", help="put the tiles of a bake (--tile K/N) together into the "
                  "outputs one untiled run writes", run=run, add_arguments=add_arguments,
                  needs_scene=False)
