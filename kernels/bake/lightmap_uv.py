"""Lightmap UVs: unwrap and pack a triangle mesh into [0, 1]^2 with xatlas, for a given resolution.

Every texel of a lightmap belongs to at most one chart: charts are packed `padding` texels apart at
`resolution`, so bilinear filtering and dilation never mix two surfaces.
"""

from __future__ import annotations

import faulthandler
import math
import os
import pickle
import signal
import warnings
from collections import deque
from dataclasses import dataclass

import numpy as np

from ..geometry.scene import triangle_areas

# xatlas (0.0.11) ends the whole process with a segmentation fault on some dense closed meshes: a
# UV sphere of 250 or more segments (125k triangles; 200 segments pass), whatever the chart and
# pack options (jpcy/xatlas#146 describes one chart grown over a whole icosphere). Inside Blender
# that would close the session. Where the platform can fork, meshes of at least this many
# triangles are charted in a child process, so that a crash becomes an error naming the mesh;
# smaller ones (none seen to crash) skip the fork's few milliseconds.
ISOLATE_TRIANGLES = 10_000


# xatlas (0.0.11) can hang for ever destroying an atlas: its task scheduler's destructor sets each
# worker thread's wake-up flag and notifies it without taking the worker's mutex, so a worker
# between testing the flag and going to sleep misses the call and the destructor's join waits for
# it (a lost wake-up: 2 hangs, both in the destructor, in ~42,000 two-triangle atlases made and
# dropped at once). Atlases are kept until this many later ones were made: by then the worker has
# long been asleep, and the destructor wakes it (no hang in 100,000 so). They are small: a large
# mesh's atlases are made in a child process (`ISOLATE_TRIANGLES`), which ends without destroying
# them.
RETIRED_ATLASES = 4
_retired: deque = deque(maxlen=RETIRED_ATLASES)
_orphaned: list = []  # a forked child's inherited atlases: never destroyed there


def _orphan_retired() -> None:
    # A forked child has none of the parent's threads: destroying an atlas it inherited would
    # join a worker that does not exist in it, for ever.
    _orphaned.extend(_retired)
    _retired.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_orphan_retired)


class UnwrapCrash(ValueError):
    """xatlas ended the child process that charted a mesh (`ISOLATE_TRIANGLES`); a larger
    lightmap does not help."""


# xatlas flattens each chart as a whole, in time that grows much faster than the chart's size: a
# smooth 62.5k-triangle sphere grown into 6 charts took 26 s a pass (one charting pass per unwrap), a
# gently rolling 20k-triangle terrain as one chart 42 s. Meshes of more triangles than this get
# charts of at most (their area x this / their triangle count), about this many triangles each:
# 49 charts and 2.5 s a pass on that sphere, 19 charts and 1 s on that terrain; flat regions stay
# one chart whatever their size (xatlas projects them without flattening).
CHART_TRIANGLES = 2000

# Density fitting: start a little under xatlas' own estimate, shrink by 10% until one atlas holds
# every chart; 12 tries cover a 3.5x over-estimate.
FIT_MARGIN = 0.98
SHRINK_PER_ATTEMPT = 0.9
MAX_FIT_ATTEMPTS = 12


@dataclass(frozen=True)
class LightmapUVSettings:
    """| field        | range     | default | unit / meaning                                          |
    |--------------|-----------|---------|---------------------------------------------------------|
    | resolution   | 16..16384 | 256     | texels along each side of the square lightmap           |
    | padding      | 0..64     | 2       | texels kept free between charts (and from the border)   |
    | max_chart_area | >= 0    | 0       | xatlas chart area limit, in the mesh's own units scaled |
    |              |           |         | to unit size; 0 = automatic (CHART_TRIANGLES)           |
    | seed_bilinear| bool      | True    | xatlas `bilinear`: pad for bilinear filtering           |
    """

    resolution: int = 256
    padding: int = 2
    max_chart_area: float = 0.0
    seed_bilinear: bool = True

    def __post_init__(self):
        if not 16 <= self.resolution <= 16384:
            raise ValueError(f"lightmap resolution must be in [16, 16384], got {self.resolution}")
        if not 0 <= self.padding <= 64:
            raise ValueError(f"lightmap padding must be in [0, 64] texels, got {self.padding}")
        if not (math.isfinite(self.max_chart_area) and self.max_chart_area >= 0.0):
            raise ValueError(f"max_chart_area must be finite and >= 0, got {self.max_chart_area}")


@dataclass(frozen=True)
class LightmapUV:
    """The result of an unwrap, per triangle corner of the input.

    corner_uv   (T, 3, 2) float32  UV of each triangle corner, in [0, 1]
    chart_ids   (T,) int32         chart of each triangle; -1 for zero-area triangles, which
                                   xatlas leaves out (their corners sit at UV (0, 0), or on the
                                   edge they share in their polygon's chart: no texels either way)
    """

    corner_uv: np.ndarray
    chart_ids: np.ndarray
    chart_count: int
    utilization: float  # fraction of the atlas covered by charts
    resolution: int = 0  # texels per side the charts were packed for (0: no charts)


def unwrap(
    positions: np.ndarray, triangles: np.ndarray, settings: LightmapUVSettings = LightmapUVSettings(),
    polygons: np.ndarray | None = None, largest: int | None = None,
) -> LightmapUV:
    """Unwrap and pack one mesh.

    largest: texels per side the lightmap may grow to (doubling from `settings.resolution`) when
    the charts do not fit at that resolution with their padding; None: no growth (ValueError).
    The charts are made once and packed again at each size (`LightmapUV.resolution` says which
    held them): charting is the slow part, 20 s on a 250k-triangle mesh against 0.4 s a packing.

    positions (V, 3) float, object or world space, m (only ratios matter); triangles (T, 3) vertex ids.
    Zero-area triangles get no chart (chart id -1) and UV (0, 0) (with `polygons`: zero area on
    the edge they share with their polygon); they cover no texel; a mesh with no area at all gets
    no chart. Raises ValueError for nan or inf positions (never handed to xatlas).

    polygons (T,) int, when given: the polygon each triangle was cut from. A mesh stores one UV per
    polygon corner, so a polygon must lie in one chart; xatlas charts triangles and may cut a
    quad along its diagonal (448 of subdivided Suzanne's 7872 quads), and the corner both halves
    share would then take one chart's UV while the other half's own corner kept the other's: a
    sliver across the atlas, over other charts (944 of its 3865 texels claimed twice at 128^2).
    Such polygons are kept whole (`_polygons_whole`) and the charts packed again.
    """
    positions = np.asarray(positions, np.float64)
    triangles = np.ascontiguousarray(triangles, np.uint32)
    if not np.isfinite(positions).all():  # xatlas loops for minutes on nan or inf
        raise ValueError("lightmap UVs: vertex coordinates are not finite (nan or inf)")
    count = triangles.shape[0]
    largest = max(settings.resolution, largest or settings.resolution)
    if count < ISOLATE_TRIANGLES or not hasattr(os, "fork"):
        return _unwrap(positions, triangles, settings, polygons, largest)
    try:
        return _in_child(_unwrap, positions, triangles, settings, polygons, largest)
    except UnwrapCrash as exc:
        raise UnwrapCrash(f"lightmap UVs: xatlas crashed ({exc}) charting this mesh of "
                          f"{count:,} triangles (an xatlas defect on some dense closed meshes); "
                          "give the mesh a lightmap UV layer of its own (e.g. Blender's "
                          "Lightmap Pack) under the name the bake uses") from None


def _in_child(function, *args):
    """function(*args) computed in a forked child process and sent back pickled: a crash of the
    child (xatlas' segmentation faults) raises UnwrapCrash(the signal's name) here instead of
    ending this process. The child's exceptions are raised here as they were."""
    read, write = os.pipe()
    with warnings.catch_warnings():  # fork() in a process with threads warns (3.12+); the
        warnings.simplefilter("ignore", DeprecationWarning)  # child only computes and exits
        pid = os.fork()
    if pid == 0:  # the child: compute, send, exit without running the parent's clean-up
        code = 0
        try:
            faulthandler.disable()  # a crash here is reported by the parent, in one line
            os.close(read)
            try:
                payload = pickle.dumps((True, function(*args)), pickle.HIGHEST_PROTOCOL)
            except Exception as exc:  # noqa: BLE001 - sent back and raised in the parent
                payload = pickle.dumps((False, exc), pickle.HIGHEST_PROTOCOL)
            with os.fdopen(write, "wb") as pipe:
                pipe.write(payload)
        except BaseException:  # noqa: BLE001 - a child must never return into the caller
            code = 1
        finally:
            os._exit(code)
    os.close(write)
    try:
        with os.fdopen(read, "rb") as pipe:
            payload = pipe.read()
    finally:
        _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        raise UnwrapCrash(signal.Signals(os.WTERMSIG(status)).name)
    if not payload:
        raise UnwrapCrash(f"exit {os.WEXITSTATUS(status)}")
    ok, value = pickle.loads(payload)  # noqa: S301 - our own child's bytes
    if not ok:
        raise value
    return value


def _unwrap(positions: np.ndarray, triangles: np.ndarray, settings: LightmapUVSettings,
            polygons: np.ndarray | None, largest: int) -> LightmapUV:
    """`unwrap` past its checks: positions (V, 3) float64 finite, triangles (T, 3) uint32."""
    import xatlas

    count = triangles.shape[0]
    no_charts = LightmapUV(np.zeros((count, 3, 2), np.float32), np.full(count, -1, np.int32), 0,
                           0.0)
    if count == 0:
        return no_charts
    # Only ratios matter: at unit size xatlas' own area and length epsilons neither drop a tiny
    # object's faces (scale 1e-9) nor lose precision on a huge one.
    low = positions.min(axis=0)
    extent = float((positions.max(axis=0) - low).max())
    if extent <= 0.0:
        return no_charts
    positions = np.ascontiguousarray((positions - low) / extent, np.float32)
    max_chart_area = settings.max_chart_area
    if max_chart_area <= 0.0 and count > CHART_TRIANGLES:
        corners = positions[triangles].astype(np.float64)
        area = float(triangle_areas(corners).sum())
        max_chart_area = area * CHART_TRIANGLES / count

    def generate(add, texels_per_unit: float, resolution: int = settings.resolution):
        atlas = xatlas.Atlas()
        add(atlas)
        chart_options = xatlas.ChartOptions()
        if max_chart_area > 0:
            chart_options.max_chart_area = float(max_chart_area)
        pack = xatlas.PackOptions()
        pack.resolution = int(resolution)
        pack.padding = int(settings.padding)
        pack.bilinear = bool(settings.seed_bilinear)
        pack.texels_per_unit = float(texels_per_unit)
        atlas.generate(chart_options, pack)
        _retired.append(atlas)  # destroyed RETIRED_ATLASES atlases later, not when dropped
        return atlas

    def fitted(add, resolution: int):
        # With texels_per_unit = 0 xatlas only estimates a density and may overshoot the
        # resolution. Fixing the density makes it pack into atlases of exactly `resolution`;
        # shrink it until everything fits in one, so padding is in texels of the real lightmap.
        # None where the charts do not fit one atlas of `resolution` even so; the estimate's
        # atlas where it holds no chart (every UV triangle of zero area).
        atlas = generate(add, 0.0, resolution)
        if atlas.chart_count == 0 or max(atlas.width, atlas.height) == 0:
            return atlas
        density = atlas.texels_per_unit * FIT_MARGIN * resolution / max(atlas.width, atlas.height)
        for _ in range(MAX_FIT_ATTEMPTS):
            atlas = generate(add, density, resolution)
            if atlas.atlas_count == 1:
                return atlas
            density *= SHRINK_PER_ATTEMPT
        return None

    # Chart once; every packing after that (the density fit, polygons made whole) packs the
    # charts as a UV mesh, which xatlas does not chart or flatten again: 0.1 s a packing against
    # 5 s a full pass on a 63k-triangle subdivided head.
    charted = generate(lambda a: a.add_mesh(positions, triangles), 0.0)
    if charted.chart_count == 0 or max(charted.width, charted.height) == 0:
        return no_charts  # every triangle has zero area: nothing to chart
    corner_uv, chart_ids = _corners(charted)
    degenerate = chart_ids < 0
    # In m (atlas texels / density): the charts' own scale, for packing them again.
    metres = (corner_uv * np.array([charted.width, charted.height]) / charted.texels_per_unit
              ).astype(np.float64)
    polygons = None if polygons is None else np.asarray(polygons, np.int64)
    whole = polygons is not None and _moved(positions, triangles, polygons, chart_ids)[0].any()
    if whole:
        metres = _polygons_whole(positions, triangles, polygons, chart_ids, metres)
    # Corners of one vertex at one UV are one vertex of the UV mesh: its islands are the charts
    # again (whole polygons where they were cut).
    key = np.concatenate([triangles.reshape(-1, 1).astype(np.float64), metres.reshape(-1, 2)],
                         axis=1)
    _, shared = np.unique(key, axis=0, return_inverse=True)
    island_uv = np.zeros((int(shared.max()) + 1, 2), np.float32)
    island_uv[shared.ravel()] = metres.reshape(-1, 2)
    island_tris = np.ascontiguousarray(shared.reshape(-1, 3), np.uint32)
    resolution = settings.resolution
    while (atlas := fitted(lambda a: a.add_uv_mesh(island_uv, island_tris), resolution)) is None:
        if 2 * resolution > largest:
            raise ValueError(
                f"lightmap UVs: {charted.chart_count} charts do not fit one {resolution}^2 atlas "
                f"with {settings.padding} texels of padding; raise the resolution or lower the "
                f"padding")
        resolution *= 2
    if atlas.chart_count == 0 or max(atlas.width, atlas.height) == 0:
        return no_charts
    corner_uv, chart_ids = _corners(atlas)
    # xatlas packs a zero-area UV triangle's lone corner anywhere: back at (0, 0), or unfolded
    # again onto the packed edge it shares (zero area in UV too, no texel); chart -1 either way.
    chart_ids[degenerate] = -1
    corner_uv[degenerate] = 0.0
    if whole:
        corner_uv = _polygons_whole(positions, triangles, polygons, chart_ids,
                                    corner_uv).astype(np.float32)
    return LightmapUV(corner_uv, chart_ids, int(atlas.chart_count), float(atlas.utilization),
                      resolution)


def _corners(atlas) -> tuple[np.ndarray, np.ndarray]:
    """(corner UVs (T, 3, 2) float32 in [0, 1] of the square atlas, chart of each triangle (T,)
    int32) of a generated one-mesh atlas."""
    _, indices, uvs = atlas[0]
    _, vertex_chart = atlas.get_mesh_vertex_assignment(0)
    return (uvs[indices].astype(np.float32),
            np.asarray(vertex_chart, np.int64)[indices[:, 0]].astype(np.int32))


def _moved(positions: np.ndarray, triangles: np.ndarray, polygons: np.ndarray,
           chart_ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """((T,) bool: triangles charted apart from their polygon's largest triangle, (T,) int: that
    largest triangle of each one's polygon). A zero-area triangle (chart -1, its corners at UV
    (0, 0)) in a polygon with area counts: the loops it shares would take (0, 0)."""
    corners = positions.astype(np.float64)[triangles]
    areas = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]),
                           axis=1)
    order = np.lexsort((-areas, polygons))  # by polygon, largest first
    head = np.ones(len(order), bool)
    head[1:] = polygons[order][1:] != polygons[order][:-1]
    largest = np.empty(len(order), np.int64)
    largest[order] = order[np.maximum.accumulate(np.where(head, np.arange(len(order)), 0))]
    owner = chart_ids[largest]
    return (chart_ids != owner) & (owner >= 0), largest


def _polygons_whole(positions: np.ndarray, triangles: np.ndarray, polygons: np.ndarray,
                    chart_ids: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(T, 3, 2) corner UVs (in `uv`'s units) with every polygon in the chart of its largest
    triangle. A triangle charted elsewhere is unfolded across an edge it shares with the
    polygon's triangles placed so far: its free corner goes where the UV triangle is similar to
    the 3D one (the chart's scale along that edge) and wound like the largest triangle's, so it
    lies on the far side of the edge. Rounds of this reach an n-gon's fan; a triangle that never
    shares a placed edge keeps its own chart's UVs."""
    moved, largest = _moved(positions, triangles, polygons, chart_ids)
    out = uv.astype(np.float64)
    if not moved.any():
        return out
    corners = positions.astype(np.float64)[triangles]  # (T, 3, 3)
    keys = polygons[:, None] * (int(triangles.max()) + 1) + triangles  # (T, 3): polygon corner
    e1, e2 = out[:, 1] - out[:, 0], out[:, 2] - out[:, 0]
    winding = np.where(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0] >= 0.0, 1.0, -1.0)
    # The corners placed so far (sorted keys, their UVs): those of the triangles that stay.
    stay = np.isin(polygons, polygons[moved]) & ~moved
    placed_keys, first = np.unique(keys[stay].ravel(), return_index=True)
    placed_uv = out[stay].reshape(-1, 2)[first]
    pending = np.flatnonzero(moved)
    while pending.size:
        at = np.minimum(np.searchsorted(placed_keys, keys[pending]), len(placed_keys) - 1)
        known = placed_keys[at] == keys[pending]  # (P, 3)
        ready = known.sum(axis=1) >= 2
        if not ready.any():
            break
        t, at, known = pending[ready], at[ready], known[ready]
        rows = np.arange(t.size)
        f = np.argmin(known, axis=1)  # the free corner (any, when all three are placed)
        a, b = (f + 1) % 3, (f + 2) % 3  # (f, a, b) keeps the corners' cyclic order
        ua, ub = placed_uv[at[rows, a]], placed_uv[at[rows, b]]
        edge = corners[t, b] - corners[t, a]
        length = np.maximum(np.linalg.norm(edge, axis=1), 1e-300)
        rel = corners[t, f] - corners[t, a]
        along = np.einsum("ij,ij->i", rel, edge) / length
        across = np.linalg.norm(rel - (along / length)[:, None] * edge, axis=1)
        d = ub - ua
        span = np.maximum(np.linalg.norm(d, axis=1), 1e-300)
        direction = d / span[:, None]
        normal = np.stack([-direction[:, 1], direction[:, 0]], axis=1)
        # The signed area of (f, a, b) comes out as side x scale^2 x across x length.
        side = winding[largest[t]]
        uf = ua + (span / length)[:, None] * (along[:, None] * direction
                                              + (side * across)[:, None] * normal)
        new = ~known[rows, f]
        merged_keys = np.concatenate([placed_keys, keys[t[new], f[new]]])
        merged_uv = np.concatenate([placed_uv, uf[new]])
        placed_keys, first = np.unique(merged_keys, return_index=True)  # the first UV stays
        placed_uv = merged_uv[first]
        out[t] = placed_uv[np.searchsorted(placed_keys, keys[t])]
        pending = pending[~ready]
    return out


# Smallest lightmap an object gets: below 16 texels a side the padding eats the charts.
MIN_LIGHTMAP_SIZE = 16


def lightmap_sizes(areas_m2, largest_size: int) -> list[int]:
    """Per-object lightmap sizes at one texel density: the largest object gets `largest_size`
    texels per side, every other object sqrt(its area / the largest area) of it, rounded up to a
    power of two and kept in [MIN_LIGHTMAP_SIZE, largest_size]. A 1 m^2 plate beside a 400 m^2
    floor then gets 1/20 of the floor's texels per side instead of as many."""
    areas = np.maximum(np.asarray(areas_m2, np.float64), 0.0)
    if areas.size == 0:
        return []
    top = max(float(areas.max()), 1e-12)
    wanted = largest_size * np.sqrt(areas / top)
    sizes = 2 ** np.ceil(np.log2(np.maximum(wanted, 1.0)))
    return [int(s) for s in np.clip(sizes, MIN_LIGHTMAP_SIZE, largest_size)]
