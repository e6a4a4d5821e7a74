"""A bounding volume hierarchy for batched ray casting in NumPy: closest hits and occlusion.

Build (vectorised over triangles): a binary tree by the binned surface-area heuristic, built level
by level with every open node of a level binned at once (segmented reductions), then collapsed
into `width`-wide nodes by repeatedly opening the child with the largest surface area. Flat arrays:

* node table (N, 7W) float32: per child slot its box, [lo/hi][x/y/z][slot], then W child
  references (int32 bits): >= 0 another node, <= -2 leaf number -2 - ref, -1 an empty slot
  (NaN box, never entered);
* leaf table (L, 10S) float32: per leaf its S triangle slots' corners [corner][axis][slot], then
  S triangle indices (int32 bits). Empty slots hold NaN corners, which never hit.

Traversal ("lockstep pool"): a pool of `chunk_size` ray slots advances in steps. Every ray keeps
its own stack; in a step each busy ray pops its stack if it has nothing to visit (skipping up to
POP_ROUNDS entries farther than its closest hit), then descends through up to DESCENT nodes along
its nearest children, and rays standing at leaves are tested once enough of them wait (NumPy
calls cost about the same for 300 or 3000 elements). At a node the
W child boxes are slab-tested, (entry distance, child) pairs are packed into int64 keys and sorted
with a sorting network, the nearest child is visited next and the others are pushed, so a popped
child farther than the closest hit so far is skipped. Leaves run the watertight test of
`intersect.py`; only the few pairs that pass it take the float64 recheck, the box clamp and the
closest-hit update. Node and leaf records are fetched with one row gather each and transposed in
cache-sized blocks, so all arithmetic runs on contiguous rows. Answered slots are refilled from a
shared queue, so steps stay full until the queue runs dry. A scene of at most
`brute_force_below` triangles is one leaf, tested against every ray without a tree.

Threads: each worker thread runs its own pool on batches taken from the queue (NumPy releases the
GIL inside its loops); a call takes one thread per THREAD_RAYS rays, up to one per core. A ray's
answer does not depend on the batching or the thread count.

Exactness: the answer equals `intersect.intersect_all` bit for bit (same triangle, same t, u, v);
see the module docstring of `intersect.py` for why no node holding the closest hit is culled.

Memory of a query: per thread, the pool's slots (about 56 + 8 * stack depth + 40 bytes each, the
stack depth being (W - 1) * tree depth + 2, ~35 for a million triangles) and one step's
temporaries: about 16 MB per thread at 16384 slots and 53 MB at the default 65536, measured with
tracemalloc, for any number of rays. Larger pools pay: each NumPy call serves more rays, so fixed
per-call costs weigh less (bench/rays.py, 1M-triangle camera rays: 0.66 M/s at 16384 slots, 0.81
at 65536). The tree itself takes about 70 bytes per triangle (plus the 36-byte float32 copy of the
triangles and their 24-byte boxes): 131 MB in all for a million triangles.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import dataclass

import numpy as np

from .intersect import (
    INT32_MAX,
    Hits,
    PreparedTriangles,
    edge_functions,
    finish_candidates,
    inside,
    prepare_rays,
    prepare_triangles,
    raw_distance,
    ray_frame_corners,
    ray_limits,
    slab,
)

__all__ = ["BVH", "BVHSettings", "Hits"]

# Child reference of an empty node slot, and the "pop the stack next" marker of a ray.
NONE = -1
# Rays per block of the gather-and-transpose of node and leaf records: a block's records
# (512 rows of at most 80 float32) stay in the core's L1/L2 cache while they are transposed.
TRANSPOSE_BLOCK = 512
# (ray, triangle) pairs tested at once by a one-leaf (brute force) BVH: keeps the (3, S, M)
# temporaries of the test in the core's L2 cache.
BRUTE_FORCE_PAIRS = 1 << 14
QUERY_BYTES_PER_SLOT = 810  # a pool slot's stack, state and one step's temporaries (measured)
# Rays handed to a worker at a time (the unit of work sharing between threads).
QUEUE_BATCH = 4096
# Rays a call must bring per worker thread. Below this the threads' NumPy calls are too small to
# release the GIL for long, and they mostly wait on each other: on the 2-core machine, radiosity
# solve + bake of the Cornell box at 74 patches (calls of 0.5k-18k rays) 0.185 s with a thread
# per 4096 rays, 0.158 s with one per 32768; a lamp-lit room (calls up to 300k rays) 1.38 -> 1.37
# s, 1.47 s with one thread throughout (medians of 5, alternated).
THREAD_RAYS = 1 << 15
# A pool refills its answered slots once this fraction of them is free.
REFILL_AT = 1.0 / 8.0
# Stack entries a ray may pop in one step while they are farther than its closest hit.
POP_ROUNDS = 4
# Node levels a ray may descend in one step (along its nearest children) before the others move.
DESCENT = 4
# Leaf steps wait until this fraction of the pool stands at leaves (or nothing else can move).
LEAF_BATCH = 0.3
# Seconds between progress reports of the *_steps generators.
PROGRESS_SECONDS = 0.05
# (region, node) pairs `convex_clear` tests at once: its (pairs, planes, width) temporaries stay
# at a few MB.
SHAFT_PAIRS = 1 << 13


@dataclass(frozen=True)
class BVHSettings:
    """How the BVH is built and queried.

    | field             | range      | default | meaning                                          |
    |-------------------|------------|---------|--------------------------------------------------|
    | bins              | 2..256     | 16      | SAH bins per axis per node                       |
    | leaf_size         | 1..64      | 4       | most triangles per leaf (leaves padded to it)    |
    | width             | 2, 4, 8    | 4       | children per node                                |
    | chunk_size        | >= 256     | 65536   | rays in flight per thread (bounds query memory)  |
    | threads           | >= 0       | 0       | worker threads; 0: one per CPU core              |
    | brute_force_below | >= 0       | 24      | at most this many triangles: one leaf, no tree   |
    """

    bins: int = 16
    leaf_size: int = 4
    width: int = 4
    chunk_size: int = 65536
    threads: int = 0
    brute_force_below: int = 24

    def __post_init__(self) -> None:
        if not 2 <= self.bins <= 256:
            raise ValueError("bins must be in 2..256")
        if not 1 <= self.leaf_size <= 64:
            raise ValueError("leaf_size must be in 1..64")
        if self.width not in (2, 4, 8):
            raise ValueError("width must be 2, 4 or 8")
        if self.chunk_size < 256:
            raise ValueError("chunk_size must be >= 256")
        if self.threads < 0 or self.brute_force_below < 0:
            raise ValueError("threads and brute_force_below must be >= 0")

    @property
    def thread_count(self) -> int:
        return self.threads or os.cpu_count() or 1

    @property
    def query_bytes(self) -> int:
        """Memory of one query in flight, all threads: ~810 B per pool slot (53 MB per thread at
        65536 slots, measured with tracemalloc; see the module docstring)."""
        return self.thread_count * self.chunk_size * QUERY_BYTES_PER_SLOT


# --------------------------------------------------------------------------------------------
# Build: binned SAH, level by level
# --------------------------------------------------------------------------------------------


def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Half the surface area of boxes (3, ...) lo/hi; empty boxes (lo > hi) give garbage."""
    e = hi - lo
    return e[0] * e[1] + e[1] * e[2] + e[2] * e[0]


def _scan(op: np.ufunc, a: np.ndarray) -> np.ndarray:
    """Inclusive prefix `op` along axis 0 (a loop over rows: ufunc.accumulate walks the
    other axes one element at a time, which is much slower for short scans)."""
    out = np.empty_like(a)
    out[0] = a[0]
    for i in range(1, a.shape[0]):
        op(out[i - 1], a[i], out=out[i])
    return out


@dataclass(frozen=True)
class _BinaryTree:
    lo: np.ndarray  # (3, N) float32 node boxes, world, m
    hi: np.ndarray  # (3, N)
    child: np.ndarray  # (N, 2) int64, -1 for leaves
    start: np.ndarray  # (N,) int64, leaf triangle range in `order`
    count: np.ndarray  # (N,) int64
    order: np.ndarray  # (T,) int64, triangle numbers (into the valid list) grouped by leaf


def _build_binary(lo: np.ndarray, hi: np.ndarray, settings: BVHSettings) -> _BinaryTree:
    """Binned-SAH binary tree over boxes lo, hi (3, T) float32. T >= 1.

    Level by level: the triangles of all open nodes sit in one set of arrays, grouped by node
    (segments), and every per-node quantity is a segmented reduction. Splitting a node reorders
    its segment in place (left part first), so a node's triangles are always contiguous and a
    leaf's final position in `order` is known when it is made.
    """
    n_tri = lo.shape[1]
    bins = settings.bins
    order = np.empty(n_tri, np.int64)
    cap = 2 * n_tri
    node_lo = np.empty((3, cap), np.float32)
    node_hi = np.empty((3, cap), np.float32)
    child = np.full((cap, 2), -1, np.int64)
    start = np.zeros(cap, np.int64)
    count = np.zeros(cap, np.int64)
    # The open nodes (ids, their ranges in `order`) and their triangles, grouped by node.
    ids = np.array([0])
    starts = np.array([0])
    counts = np.array([n_tri])
    t_lo, t_hi = lo, hi  # (3, n) float32 boxes of the open nodes' triangles
    t_id = np.arange(n_tri)  # (n,) their numbers
    n_nodes = 1
    while ids.size:
        first = np.cumsum(counts) - counts  # segment starts in the open arrays
        node_lo[:, ids] = np.minimum.reduceat(t_lo, first, axis=1)
        node_hi[:, ids] = np.maximum.reduceat(t_hi, first, axis=1)
        start[ids] = starts
        count[ids] = counts
        split = counts > settings.leaf_size
        leaf = ~split
        if leaf.any():
            # Leaves are final: their triangles go to their place in `order`.
            in_leaf = np.repeat(leaf, counts)
            order[np.repeat(starts[leaf] - first[leaf], counts[leaf]) + np.flatnonzero(in_leaf)] = (
                t_id[in_leaf]
            )
            if not split.any():
                break
            keep = ~in_leaf
            t_lo, t_hi, t_id = t_lo[:, keep], t_hi[:, keep], t_id[keep]
            ids, starts, counts = ids[split], starts[split], counts[split]
            first = np.cumsum(counts) - counts
        k_open = ids.size
        seg = np.repeat(np.arange(k_open), counts)
        c = (t_lo + t_hi) * np.float32(0.5)  # (3, n) centroids
        cmin = np.minimum.reduceat(c, first, axis=1)  # (3, K)
        extent = np.maximum.reduceat(c, first, axis=1) - cmin
        with np.errstate(divide="ignore"):
            scale = np.where(extent > 0.0, np.float32(bins) / extent, np.float32(0.0))
        b = ((c - np.repeat(cmin, counts, axis=1)) * np.repeat(scale, counts, axis=1)).astype(
            np.int64
        )  # (3, n) bin per axis
        np.clip(b, 0, bins - 1, out=b)
        best_cost = np.full(k_open, np.inf)
        best_axis = np.zeros(k_open, np.int64)
        best_bin = np.zeros(k_open, np.int64)
        base = seg * bins
        for axis in range(3):
            key = base + b[axis]
            cnt = np.bincount(key, minlength=k_open * bins).reshape(k_open, bins).T  # (B, K)
            blo = np.full((3, k_open * bins), np.inf, np.float32)
            bhi = np.full((3, k_open * bins), -np.inf, np.float32)
            for dim in range(3):
                np.minimum.at(blo[dim], key, t_lo[dim])
                np.maximum.at(bhi[dim], key, t_hi[dim])
            # Bins first, so the prefix scans below run over whole rows of nodes.
            blo = blo.reshape(3, k_open, bins).transpose(2, 0, 1).copy()  # (B, 3, K)
            bhi = bhi.reshape(3, k_open, bins).transpose(2, 0, 1).copy()
            n_left = np.cumsum(cnt, axis=0)[:-1]  # (B-1, K): split after bin i
            n_right = counts - n_left
            a_left = _half_area(
                _scan(np.minimum, blo).transpose(1, 0, 2), _scan(np.maximum, bhi).transpose(1, 0, 2)
            )[:-1]
            a_right = _half_area(
                _scan(np.minimum, blo[::-1])[::-1].transpose(1, 0, 2),
                _scan(np.maximum, bhi[::-1])[::-1].transpose(1, 0, 2),
            )[1:]
            with np.errstate(invalid="ignore", over="ignore"):
                cost = a_left * n_left + a_right * n_right
            cost = np.where((n_left > 0) & (n_right > 0), cost, np.inf)
            i = np.argmin(cost, axis=0)
            c_best = cost[i, np.arange(k_open)]
            better = c_best < best_cost
            best_cost = np.where(better, c_best, best_cost)
            best_axis = np.where(better, axis, best_axis)
            best_bin = np.where(better, i, best_bin)
        # Partition: left where the bin is at or below the split; no valid split (all centroids
        # in one bin on every axis): the first half of the range goes left.
        axis_of = np.repeat(best_axis, counts)
        chosen = np.where(axis_of == 0, b[0], np.where(axis_of == 1, b[1], b[2]))
        left = chosen <= np.repeat(best_bin, counts)
        rank = np.arange(seg.size) - np.repeat(first, counts)
        fallback = ~np.isfinite(best_cost)
        if fallback.any():
            left = np.where(np.repeat(fallback, counts), rank < np.repeat(counts // 2, counts), left)
        n_left = np.bincount(seg, weights=left, minlength=k_open).astype(np.int64)
        excl = np.cumsum(left) - left
        left_rank = excl - np.repeat(excl[first], counts)
        dest = np.repeat(first, counts) + np.where(
            left, left_rank, np.repeat(n_left, counts) + rank - left_rank
        )
        src = np.empty_like(dest)
        src[dest] = np.arange(dest.size)
        t_lo = np.take(t_lo, src, axis=1)
        t_hi = np.take(t_hi, src, axis=1)
        t_id = t_id[src]
        kids = n_nodes + 2 * np.arange(k_open)
        child[ids, 0] = kids
        child[ids, 1] = kids + 1
        n_nodes += 2 * k_open
        ids = np.stack([kids, kids + 1], axis=1).ravel()
        starts = np.stack([starts, starts + n_left], axis=1).ravel()
        counts = np.stack([n_left, counts - n_left], axis=1).ravel()
    return _BinaryTree(
        lo=node_lo[:, :n_nodes],
        hi=node_hi[:, :n_nodes],
        child=child[:n_nodes],
        start=start[:n_nodes],
        count=count[:n_nodes],
        order=order,
    )


@dataclass(frozen=True)
class _WideTree:
    nodes: np.ndarray  # (N, 7W) float32 node table (see module docstring)
    leaves: np.ndarray  # (3 * L, 10S) float32 leaf table
    leaf_count: int
    root: int  # reference of the root: 0 (a node), <= -2 (a single leaf) or NONE (empty)
    depth: int  # levels of wide nodes


def _collapse(tree: _BinaryTree, width: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Collapse a binary tree into `width`-wide nodes by opening the largest child first.

    Returns (slots (N, W) binary node per child slot or -1, leaf binary nodes (L,), the wide
    reference of every binary node that became a slot (dict-like array), depth).
    """
    is_leaf = tree.child[:, 0] < 0
    area = _half_area(tree.lo, tree.hi)
    ref = np.full(is_leaf.size, NONE, np.int64)  # wide reference of each binary node
    leaves = np.flatnonzero(is_leaf)
    ref[leaves] = -2 - np.arange(leaves.size)
    all_slots = []
    roots = np.array([0])
    n_wide = 0
    depth = 0
    while roots.size:
        ref[roots] = n_wide + np.arange(roots.size)
        n_wide += roots.size
        depth += 1
        rows = np.arange(roots.size)
        slots = np.full((roots.size, width), -1, np.int64)
        slots[:, 0] = roots
        for step in range(1, width):
            used = slots >= 0
            openable = used & ~is_leaf[np.where(used, slots, 0)]
            score = np.where(openable, area[np.where(used, slots, 0)], -1.0)
            j = np.argmax(score, axis=1)
            can = score[rows, j] >= 0.0
            r, jj = rows[can], j[can]
            b = slots[r, jj]
            slots[r, jj] = tree.child[b, 0]
            slots[r, step] = tree.child[b, 1]
        all_slots.append(slots)
        kids = slots[slots >= 0]
        roots = kids[~is_leaf[kids]]
    return np.concatenate(all_slots), leaves, ref, depth


def _build_tables(
    prepared: PreparedTriangles, valid_ids: np.ndarray, settings: BVHSettings
) -> _WideTree:
    """The node and leaf tables of the triangles `valid_ids` (all with non-zero area)."""
    width = settings.width
    n = valid_ids.size
    if n == 0:
        return _WideTree(
            np.zeros((0, 7 * width), np.float32),
            np.zeros((0, 10), np.float32),
            0,
            NONE,
            0,
        )
    if n <= max(settings.brute_force_below, settings.leaf_size):
        # One leaf holding everything: the brute force, through the same leaf code.
        leaves = _leaf_table(prepared, valid_ids[None, :], n, frames=True)
        return _WideTree(np.zeros((0, 7 * width), np.float32), leaves, 1, -2, 0)
    lo = np.ascontiguousarray(prepared.boxes[0][:, valid_ids])
    hi = np.ascontiguousarray(prepared.boxes[1][:, valid_ids])
    tree = _build_binary(lo, hi, settings)
    slots, leaf_nodes, ref, depth = _collapse(tree, width)
    # Leaf slots: triangle ids padded with -1 to leaf_size.
    size = settings.leaf_size
    members = np.full((leaf_nodes.size, size), -1, np.int64)
    cnt = tree.count[leaf_nodes]
    col = np.arange(size)
    fill = col[None, :] < cnt[:, None]
    src = tree.start[leaf_nodes][:, None] + col[None, :]
    members[fill] = valid_ids[tree.order[src[fill]]]
    leaves = _leaf_table(prepared, members, size, frames=False)
    # Node table: per slot the binary node's box; empty slots NaN.
    used = slots >= 0
    safe = np.where(used, slots, 0)
    box = np.stack([tree.lo[:, safe], tree.hi[:, safe]])  # (2, 3, N, W)
    box[:, :, ~used] = np.nan
    child = np.where(used, ref[safe], NONE).astype(np.int32)  # (N, W)
    n_nodes = slots.shape[0]
    nodes = np.empty((n_nodes, 7 * width), np.float32)
    nodes[:, : 6 * width] = box.transpose(2, 0, 1, 3).reshape(n_nodes, 6 * width)
    nodes[:, 6 * width :] = child.view(np.float32)
    return _WideTree(nodes, leaves, leaf_nodes.size, 0, depth)


def _ray_frame_axes(kz: int) -> list[int]:
    """World axes in the order of a ray frame whose z axis is `kz`: (kx, ky, kz)."""
    return [(kz + 1) % 3, (kz + 2) % 3, kz]


def _leaf_table(
    prepared: PreparedTriangles, members: np.ndarray, size: int, frames: bool
) -> np.ndarray:
    """Leaf records for members (L, size) triangle ids (-1: empty slot).

    frames=False: (L, 10 * size), corners in world axis order (x, y, z);
    frames=True:  (3 * L, 10 * size), one copy per ray frame kz (rows kz * L + leaf), corners in
    that frame's axis order (used by the one-leaf brute force, where the copies cost nothing).
    """
    n_leaves = members.shape[0]
    empty = members < 0
    v = prepared.vertices[np.where(empty, 0, members)]  # (L, S, corner, axis)
    v[empty] = np.nan
    orders = [_ray_frame_axes(kz) for kz in range(3)] if frames else [[0, 1, 2]]
    table = np.empty((len(orders), n_leaves, 10 * size), np.float32)
    for k, axes in enumerate(orders):
        permuted = v[:, :, :, axes]  # (L, S, corner, axis)
        table[k, :, : 9 * size] = permuted.transpose(0, 2, 3, 1).reshape(n_leaves, 9 * size)
        table[k, :, 9 * size :] = members.astype(np.int32).view(np.float32)
    return table.reshape(len(orders) * n_leaves, 10 * size)


# --------------------------------------------------------------------------------------------
# Traversal
# --------------------------------------------------------------------------------------------


def _gather_columns(table: np.ndarray, index: np.ndarray) -> np.ndarray:
    """table[index].T as a C-contiguous (K, M) array, gathered and transposed block by block."""
    m = index.size
    out = np.empty((table.shape[1], m), table.dtype)
    for s in range(0, m, TRANSPOSE_BLOCK):
        out[:, s : s + TRANSPOSE_BLOCK] = np.take(table, index[s : s + TRANSPOSE_BLOCK], axis=0).T
    return out


def _sort_network(width: int) -> tuple[tuple[int, int], ...]:
    """Compare-exchange pairs that sort `width` keys ascending (optimal networks)."""
    if width == 2:
        return ((0, 1),)
    if width == 4:
        return ((0, 1), (2, 3), (0, 2), (1, 3), (1, 2))
    return (
        (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7), (0, 1), (2, 3),
        (4, 5), (6, 7), (2, 4), (3, 5), (1, 4), (3, 6), (1, 2), (3, 4), (5, 6),
    )  # fmt: skip


# Rows of a pool's float32 ray table (one column per ray slot): t_min, t_best, then the 12 rows
# of `intersect.Rays.table`. The node step reads rows 0..7, the leaf step rows 8..13, each with
# one gather.
_T_MIN = 0
_T_BEST = 1  # closest accepted distance so far (t_max at first)
_ORIGIN = slice(2, 5)  # world, m
_INV_DIR = slice(5, 8)  # 1 / direction, near-zero components replaced
_ORIGIN_K = slice(8, 11)  # origin in ray-frame axis order
_SHEAR = slice(11, 14)  # Woop's Sx, Sy, Sz
_NODE_ROWS = slice(0, 8)
_LEAF_ROWS = slice(8, 14)
_RAY_ROWS = 14
# Stack keys: the low half holds a node reference; a missed child's key sorts after all others.
_LOW = np.int64(0xFFFFFFFF)
_MISS = np.int64(np.iinfo(np.int64).max)


def _pack(t: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(t, tri) as one int64 whose order is (t, then tri): t >= +0 float32 bits are monotone."""
    return (t.astype(np.float32).view(np.int32).astype(np.int64) << 32) | tri.astype(np.int64)


def _unpack(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of `_pack`: (t float32, tri int32)."""
    t = (key >> 32).astype(np.int32).view(np.float32)
    return t, (key & 0xFFFFFFFF).astype(np.int32)


def _leaf_hits(
    corners: np.ndarray,
    ids: np.ndarray,
    leaf_rows: np.ndarray,
    node_rows: Callable[[np.ndarray], np.ndarray],
    boxes: np.ndarray,
    t_min: np.ndarray | None,
) -> tuple[np.ndarray, ...]:
    """Watertight test of M rays against S triangle slots each; the hits within [t_min, t_best].

    corners:   (3, 3, S, M or 1) float32 [corner, ray-frame axis, slot, ray] (NaN: empty slot)
    ids:       (S, M) int32 triangle indices
    leaf_rows: (6, M) float32 the rays' origin_k and shear rows
    node_rows: pos -> (8, K) float32 t_min, t_best, origin, inv_dir rows of rays `pos`
    boxes:     (2, 3, T) float32 padded triangle boxes
    t_min:     (M,) when given, candidates with T / det < t_min are dropped before the gather (the
               same test, on the same bits, as finish_candidates makes: only faster)
    Returns (pos (K,), tri, t, u, v) for the accepted (ray, triangle) pairs, rays by position.
    """
    shear = leaf_rows[3:6]
    x, y, az = ray_frame_corners(corners, leaf_rows[0:3, None, :], shear[:, None, :])  # (3, S, M)
    u, v, w = edge_functions(x, y)  # (S, M)
    hit = inside(u, v, w)
    if t_min is not None:
        hit &= raw_distance(u, v, w, az, shear[2])[1] >= t_min
    k, pos = np.nonzero(hit)
    if k.size == 0:
        return (pos,) * 5
    flat = k * u.shape[1] + pos  # candidates in the flattened (S, M) arrays
    tri = ids[k, pos]
    rows = node_rows(pos)
    ok, t, bu, bv = finish_candidates(
        u.ravel()[flat],
        v.ravel()[flat],
        w.ravel()[flat],
        np.take(az.reshape(3, -1), flat, axis=1),
        shear[2, pos],
        boxes[:, :, tri],
        rows[_ORIGIN],
        rows[_INV_DIR],
        rows[_T_MIN],
        lambda i: (x.reshape(3, -1)[:, flat[i]], y.reshape(3, -1)[:, flat[i]]),
    )
    ok &= t <= rows[_T_BEST]
    return pos[ok], tri[ok], t[ok], bu[ok], bv[ok]


def _keep_closest(
    pos: np.ndarray,
    tri: np.ndarray,
    t: np.ndarray,
    bu: np.ndarray,
    bv: np.ndarray,
    best: np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    t_best: np.ndarray,
) -> None:
    """Merge hits (rays by position) into best (packed keys), u, v and t_best, in place."""
    key = _pack(t, tri)
    np.minimum.at(best, pos, key)  # several hits of one ray: the closest, then the lowest index
    won = best[pos] == key
    pos = pos[won]
    t_best[pos] = t[won]
    u[pos] = bu[won]
    v[pos] = bv[won]


class _BruteForce:
    """A one-leaf BVH (a tiny scene): every ray against every triangle, block by block.

    Same answers as the pool (the same leaf test), without stacks or lockstep steps.
    """

    def __init__(self, bvh: BVH, any_hit: bool):
        self.bvh = bvh
        self.any_hit = any_hit

    def run(self, queue: _RayQueue, sink) -> Iterator[None]:
        tree = self.bvh._tree
        size = self.bvh._leaf_slots
        block = max(1, BRUTE_FORCE_PAIRS // size)
        while (batch := queue.take()) is not None:
            ids, table, kz = batch
            n = ids.size
            best = _pack(table[_T_BEST], np.full(n, INT32_MAX))
            u = np.zeros(n, np.float32)
            v = np.zeros(n, np.float32)
            occluded = np.zeros(n, bool)
            for axis in range(3):
                record = tree.leaves[axis][:, None]  # (10S, 1): the leaf in this ray frame
                corners = record[: 9 * size].reshape(3, 3, size, 1)
                tri_ids = record[9 * size :].view(np.int32)
                group = np.flatnonzero(kz == axis)
                for s in range(0, group.size, block):
                    rows = group[s : s + block]
                    sub = table[:, rows]
                    pos, tri, t, bu, bv = _leaf_hits(
                        corners,
                        np.broadcast_to(tri_ids, (size, rows.size)),
                        sub[_LEAF_ROWS],
                        lambda p, sub=sub: sub[_NODE_ROWS][:, p],
                        self.bvh._prepared.boxes,
                        sub[_T_MIN],
                    )
                    if queue.skip is not None:
                        keep = tri != queue.skip[ids[rows[pos]]]
                        pos, tri, t, bu, bv = pos[keep], tri[keep], t[keep], bu[keep], bv[keep]
                    if self.any_hit:
                        occluded[rows[pos]] = True
                    else:
                        _keep_closest(rows[pos], tri, t, bu, bv, best, u, v, table[_T_BEST])
            sink(ids, best, u, v, occluded)
            queue.report(n)
            yield


class _RayQueue:
    """Hands out batches of rays to the worker pools (thread-safe) and counts answered rays."""

    def __init__(self, origins, directions, t_min, t_max, batch: int,
                 skip: np.ndarray | None = None):
        self.origins = origins
        self.directions = directions
        self.t_min = t_min
        self.t_max = t_max
        self.skip = skip  # (R,) int: a triangle each ray does not see (its own surface), or None
        self.count = int(origins.shape[0])
        self.batch = batch
        self.answered = 0
        self.cancelled = False
        self._next = 0
        self._lock = threading.Lock()

    def take(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The next batch: (ray indices (k,), ray table (14, k) float32, kz (k,)), or None.

        Rays that cannot hit anything (invalid, or t_min > t_max) are answered at once (the
        output already holds "miss") and left out.
        """
        with self._lock:
            start = self._next
            if start >= self.count:
                return None
            stop = self._next = min(start + self.batch, self.count)
        table = np.empty((_RAY_ROWS, stop - start), np.float32)
        rays = prepare_rays(self.origins[start:stop], self.directions[start:stop], table[2:])
        lo, hi = self.t_min[start:stop], self.t_max[start:stop]
        live = rays.valid & (lo <= hi)
        table[_T_MIN] = lo
        table[_T_BEST] = hi
        ids = np.arange(start, stop)
        kz = rays.kz.astype(np.int64)
        if not live.all():
            self.report(int(live.size - np.count_nonzero(live)))
            ids, table, kz = ids[live], table[:, live], kz[live]
        return ids, table, kz

    def report(self, answered: int) -> None:
        with self._lock:
            self.answered += answered


class _Pool:
    """`size` rays in flight: the lockstep traversal state, one slot per ray.

    Each step every busy slot pops its stack (if it has no node to visit), then visits one node
    or one leaf. Leaf visits wait until enough rays stand at leaves (NumPy calls cost the same
    for 100 or 5000 elements). Slots whose ray is answered are refilled from the queue, so the
    steps stay full until the queue runs dry.
    """

    def __init__(self, bvh: BVH, size: int, any_hit: bool):
        self.bvh = bvh
        self.tree = bvh._tree
        self.size = size
        self.any_hit = any_hit
        self.width = bvh.settings.width
        self.leaf_slots = bvh._leaf_slots
        self.depth = bvh._stack_size
        self.leaf_batch = max(1, int(size * LEAF_BATCH))
        self.skip: np.ndarray | None = None  # the query's triangle per ray to pass through
        self.rays = np.zeros((_RAY_ROWS, size), np.float32)  # see the _ORIGIN... row names
        self.rays[_INV_DIR] = 1.0
        self.kz = np.zeros(size, np.int64)
        self.best = np.zeros(size, np.int64)  # _pack(t, tri) of the closest hit so far
        self.u = np.zeros(size, np.float32)
        self.v = np.zeros(size, np.float32)
        self.occluded = np.zeros(size, bool)
        self.ray = np.full(size, -1, np.int64)  # index of the ray in the query
        self.cur = np.full(size, NONE, np.int32)  # node (>= 0) or leaf (<= -2) to visit next
        self.sp = np.zeros(size, np.int64)
        # Per slot [depth] pushed children: (entry distance bits << 32) | node reference.
        self.stack = np.zeros(size * self.depth, np.int64)
        self._pending: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._pending_at = 0

    # -- slots ---------------------------------------------------------------------------------

    def _refill(self, free: np.ndarray, queue: _RayQueue) -> tuple[np.ndarray, bool]:
        """Load rays into `free` slots. Returns (the slots filled, whether the queue is dry)."""
        filled = []
        while free.size:
            if self._pending is None or self._pending_at >= self._pending[0].size:
                self._pending = queue.take()
                self._pending_at = 0
                if self._pending is None:
                    break
                continue
            ids, table, kz = self._pending
            k = min(free.size, ids.size - self._pending_at)
            src = slice(self._pending_at, self._pending_at + k)
            dst, free = free[:k], free[k:]
            self._pending_at += k
            self.rays[:, dst] = table[:, src]
            self.kz[dst] = kz[src]
            self.best[dst] = _pack(table[_T_BEST, src], np.full(k, INT32_MAX))
            self.occluded[dst] = False
            self.ray[dst] = ids[src]
            self.cur[dst] = self.tree.root
            self.sp[dst] = 0
            filled.append(dst)
        dry = self._pending is None
        return (np.concatenate(filled) if filled else np.zeros(0, np.int64)), dry

    def run(self, queue: _RayQueue, sink) -> Iterator[None]:
        """Trace until the queue is dry; `sink(pool, slots)` receives every answered slot."""
        self.skip = queue.skip
        free = np.arange(self.size)
        act = np.zeros(0, np.int64)
        low_water = max(1, int(self.size * REFILL_AT))
        dry = False
        while True:
            if not dry and free.size >= (low_water if act.size else 1):
                filled, dry = self._refill(free, queue)
                free = free[filled.size :]
                act = np.concatenate([act, filled])
            if act.size == 0:
                return
            act, done = self._step(act, dry)
            if done.size:
                sink(self.ray[done], self.best[done], self.u[done], self.v[done], self.occluded[done])
                queue.report(done.size)
                free = np.concatenate([free, done])
            yield

    # -- one lockstep step ---------------------------------------------------------------------

    def _step(self, act: np.ndarray, dry: bool) -> tuple[np.ndarray, np.ndarray]:
        """Advance the busy slots by one node or leaf each. Returns (busy slots, answered slots)."""
        cur, sp = self.cur, self.sp
        c = cur[act]
        done = act[:0]
        popping = c == NONE
        if popping.any():
            at = np.flatnonzero(popping)
            slot = act[at]
            # Skip entries farther than the closest hit: compare (t, node) keys with (t_best, max).
            bound = (self.rays[_T_BEST, slot].view(np.int32).astype(np.int64) << 32) | _LOW
            finished = []
            for _ in range(POP_ROUNDS):  # pop again where the entry was skipped
                s = sp[slot] - 1
                live = s >= 0
                if not live.all():
                    finished.append(at[~live])
                    at, slot, s, bound = at[live], slot[live], s[live], bound[live]
                entry = self.stack[slot * self.depth + s]
                near_enough = entry <= bound
                node = np.where(near_enough, entry.astype(np.int32), NONE)
                sp[slot] = s
                cur[slot] = node
                c[at] = node
                if near_enough.all():
                    break
                far = ~near_enough
                at, slot, bound = at[far], slot[far], bound[far]
            if finished:
                gone = np.concatenate(finished)
                done = act[gone]
                keep = np.ones(act.size, bool)
                keep[gone] = False
                act, c = act[keep], c[keep]
        at_node = c >= 0
        n_node = np.count_nonzero(at_node)
        if n_node:
            # Descend: rays whose nearest child is a node go on at once, up to DESCENT levels.
            slot, node = act[at_node], c[at_node]
            for _ in range(DESCENT):
                self._nodes(slot, node)
                node = cur[slot]
                deeper = node >= 0
                if not deeper.any():
                    break
                slot, node = slot[deeper], node[deeper]
            c = cur[act]
        at_leaf = c <= -2
        n_leaf = np.count_nonzero(at_leaf)
        if n_leaf and (n_leaf >= self.leaf_batch or n_node < self.leaf_batch):
            self._leaves(act[at_leaf], -2 - c[at_leaf])
        return act, done

    def _nodes(self, slot: np.ndarray, node: np.ndarray) -> None:
        """Slab-test the children of `node` for rays `slot`; go to the nearest, push the rest."""
        width = self.width
        block = _gather_columns(self.tree.nodes, node)  # (7W, M)
        m = slot.size
        box = block[: 6 * width].reshape(2, 3, width, m)
        child = block[6 * width :].view(np.int32)  # (W, M)
        ray = np.take(self.rays[_NODE_ROWS], slot, axis=1)  # (8, M)
        near, far = slab(box, ray[_ORIGIN, None, :], ray[_INV_DIR, None, :])  # (W, M)
        near = np.maximum(near, ray[_T_MIN])
        far = np.minimum(far, ray[_T_BEST])
        # (entry distance, child) packed into sortable int64 keys; missed children sort last.
        key = (near.view(np.int32).astype(np.int64) << 32) | child.view(np.uint32)
        self._push(slot, np.where(near <= far, key, _MISS))

    def _push(self, slot: np.ndarray, key: np.ndarray) -> None:
        """Sort the (W, M) child keys; visit the nearest next, push the others far to near."""
        width = self.width
        keys = list(key)
        for a, b in _sort_network(width):
            keys[a], keys[b] = np.minimum(keys[a], keys[b]), np.maximum(keys[a], keys[b])
        sp = self.sp[slot]
        base = slot * self.depth
        for k in range(width - 1, 0, -1):
            self.stack[base + sp] = keys[k]
            sp += keys[k] != _MISS
        self.sp[slot] = sp
        self.cur[slot] = np.where(keys[0] != _MISS, keys[0].astype(np.int32), NONE)

    def _leaves(self, slot: np.ndarray, leaf: np.ndarray) -> None:
        """Run the watertight test on the triangles of `leaf` for rays `slot`; keep the best."""
        size = self.leaf_slots
        self.cur[slot] = NONE
        # Group the rays by ray frame, then permute each group's corner axes into its frame.
        kz = self.kz[slot]
        order = np.argsort(kz, kind="stable")
        slot, leaf, kz = slot[order], leaf[order], kz[order]
        block = _gather_columns(self.tree.leaves, leaf)  # (10S, M), world axis order
        corners = block[: 9 * size].reshape(3, 3, size, slot.size)  # [corner, axis, slot, ray]
        edges = np.searchsorted(kz, [0, 1, 2, 3])
        for frame in range(2):  # frame 2 (kz = z) is the world order already
            cols = slice(edges[frame], edges[frame + 1])
            if cols.start < cols.stop:
                corners[:, :, :, cols] = corners[:, _ray_frame_axes(frame), :, cols]
        self._test(slot, corners, block[9 * size :].view(np.int32))

    def _test(self, slot: np.ndarray, corners: np.ndarray, ids: np.ndarray) -> None:
        """Watertight test of rays `slot` against corners (3, 3, S, M) of triangles ids (S, M)."""
        pos, tri, t, bu, bv = _leaf_hits(
            corners,
            ids,
            np.take(self.rays[_LEAF_ROWS], slot, axis=1),
            lambda p: np.take(self.rays[_NODE_ROWS], slot[p], axis=1),
            self.bvh._prepared.boxes,
            None,
        )
        if self.skip is not None:
            keep = tri != self.skip[self.ray[slot[pos]]]
            pos, tri, t, bu, bv = pos[keep], tri[keep], t[keep], bu[keep], bv[keep]
        r = slot[pos]
        if self.any_hit:
            self.occluded[r] = True
            self.sp[r] = 0
            return
        _keep_closest(r, tri, t, bu, bv, self.best, self.u, self.v, self.rays[_T_BEST])


class BVH:
    """A BVH over world-space triangles; build with `BVH.build`.

    triangle_count: the number of triangles of the build input (degenerate ones included).
    """

    def __init__(self, prepared: PreparedTriangles, tree: _WideTree, settings: BVHSettings):
        self._prepared = prepared
        self._tree = tree
        self.settings = settings
        self.triangle_count = prepared.count
        self._leaf_slots = tree.leaves.shape[1] // 10 if tree.leaves.size else 0
        self._stack_size = max(1, tree.depth * (settings.width - 1) + 2)

    @classmethod
    def build(cls, triangles: np.ndarray, settings: BVHSettings = BVHSettings()) -> BVH:  # noqa: B008
        """Build over (T, 3, 3) float32/float64 world-space triangles (T may be 0).

        Degenerate (zero-area) and non-finite triangles are left out: they are never hit.
        """
        prepared = prepare_triangles(triangles)
        valid_ids = np.flatnonzero(prepared.valid)
        return cls(prepared, _build_tables(prepared, valid_ids, settings), settings)

    @property
    def node_count(self) -> int:
        return int(self._tree.nodes.shape[0])

    @property
    def leaf_count(self) -> int:
        return int(self._tree.leaf_count)

    # ---------------------------------------------------------------------------------------

    def _run(self, origins, directions, t_min, t_max, any_hit: bool, sink,
             skip=None) -> Iterator[float]:
        """Trace every ray through worker pools; yields progress in [0, 1] while they run.
        skip (R,) int, when given: a triangle index each ray passes through (-1: none)."""
        origins = np.asarray(origins)
        directions = np.asarray(directions)
        if origins.shape != directions.shape or origins.ndim != 2 or origins.shape[1] != 3:
            raise ValueError("origins and directions must both be (R, 3)")
        count = origins.shape[0]
        lo, hi = ray_limits(t_min, t_max, count)
        if count == 0 or self._tree.root == NONE:
            yield 1.0
            return
        settings = self.settings
        threads = max(1, min(settings.thread_count, -(-count // THREAD_RAYS)))
        pool_size = min(settings.chunk_size, -(-count // threads))
        if skip is not None:
            skip = np.asarray(skip, np.int64)
            if skip.shape != (count,):
                raise ValueError(f"skip must be ({count},), got {skip.shape}")
        queue = _RayQueue(origins, directions, lo, hi, min(QUEUE_BATCH, pool_size), skip)

        def runner():
            if self._tree.leaf_count == 1 and self._tree.nodes.shape[0] == 0:
                return _BruteForce(self, any_hit)
            return _Pool(self, pool_size, any_hit)

        def work() -> None:
            for _ in runner().run(queue, sink):
                if queue.cancelled:
                    return

        if threads == 1:
            last = time.perf_counter()
            for _ in runner().run(queue, sink):
                now = time.perf_counter()
                if now - last > PROGRESS_SECONDS:
                    last = now
                    yield queue.answered / count
            yield 1.0
            return
        with ThreadPoolExecutor(threads) as executor:
            futures = [executor.submit(work) for _ in range(threads)]
            try:
                while not wait(futures, timeout=PROGRESS_SECONDS).not_done == set():
                    yield queue.answered / count
            finally:
                queue.cancelled = True  # a generator closed early stops its workers
            for future in futures:
                future.result()
        yield 1.0

    def intersect_steps(
        self, origins, directions, t_min=0.0, t_max=np.inf, out: Hits | None = None
    ) -> Iterator[float]:
        """`intersect` as a generator: yields progress in [0, 1] while tracing; fills `out`.

        Closing the generator early stops the work (the rays not yet traced read as misses).
        """
        count = np.asarray(origins).shape[0]
        hits = out if out is not None else Hits.empty(count)
        hits.t[:] = np.inf
        hits.tri[:] = -1
        hits.u[:] = 0.0
        hits.v[:] = 0.0

        def sink(ray, best, u, v, occluded) -> None:
            t, tri = _unpack(best)
            found = tri != INT32_MAX
            ray = ray[found]
            hits.t[ray] = t[found]
            hits.tri[ray] = tri[found]
            hits.u[ray] = u[found]
            hits.v[ray] = v[found]

        yield from self._run(origins, directions, t_min, t_max, False, sink)

    def intersect(self, origins, directions, t_min=0.0, t_max=np.inf, out: Hits | None = None) -> Hits:
        """Closest hits of rays origin + t * direction, t in [t_min, t_max].

        | parameter  | shape / range              | unit                                    |
        |------------|----------------------------|-----------------------------------------|
        | origins    | (R, 3) float32/64          | world, m                                |
        | directions | (R, 3) float32/64, nonzero | world; need not be unit length          |
        | t_min      | scalar or (R,), >= 0       | units of |direction|; 0 by default      |
        | t_max      | scalar or (R,)             | units of |direction|; inf by default    |
        | out        | Hits of R rays, or None    | filled and returned when given          |

        Ties go to the lower triangle index. Rays with a zero or non-finite direction miss.
        """
        count = np.asarray(origins).shape[0]
        hits = out if out is not None else Hits.empty(count)
        for _ in self.intersect_steps(origins, directions, t_min, t_max, hits):
            pass
        return hits

    def occluded_steps(
        self, origins, directions, t_min=0.0, t_max=np.inf, out: np.ndarray | None = None,
        skip: np.ndarray | None = None,
    ) -> Iterator[float]:
        """`occluded` as a generator: yields progress in [0, 1] while tracing; fills `out`."""
        count = np.asarray(origins).shape[0]
        result = out if out is not None else np.zeros(count, bool)
        result[:] = False

        def sink(ray, best, u, v, occluded) -> None:
            result[ray] = occluded

        yield from self._run(origins, directions, t_min, t_max, True, sink, skip)

    def occluded(self, origins, directions, t_min=0.0, t_max=np.inf, out=None,
                 skip=None) -> np.ndarray:
        """(R,) bool: whether anything is hit on [t_min, t_max] (shadow and visibility rays).

        Same parameters as `intersect`; `out` may be a caller-owned (R,) bool array. A ray stops
        at the first hit it finds. skip (R,) int, when given: one triangle per ray that it
        passes through (-1: none), so a ray may start on its own surface, or just behind it,
        and still meet a surface lying flat against that one (`world_light.py`).
        """
        count = np.asarray(origins).shape[0]
        result = out if out is not None else np.zeros(count, bool)
        for _ in self.occluded_steps(origins, directions, t_min, t_max, result, skip):
            pass
        return result

    # ---------------------------------------------------------------------------------------

    def convex_clear(self, normals: np.ndarray, offsets: np.ndarray, corners: np.ndarray,
                     slack: float, facing: np.ndarray | None = None) -> np.ndarray:
        """(P,) bool: which of P convex regions no triangle enters (shaft culling).

        Region p is the convex hull of corners[p] (P, V, 3), bounded by the K half-spaces
        n . x <= d of normals (P, K, 3) and offsets (P, K), float64 world m (a row with a zero
        normal and d = +inf bounds nothing). A box or triangle stays out when all of it lies at
        n . x - d >= -slack for some plane, or (a triangle) when all the corners lie on one side
        of its own plane within slack (slack m, >= 0: touching the region's boundary, as a floor
        touches the shaft it is the base of, is not entering it). What passes neither test counts
        as entering, so the answer is conservative (the corners' bounding box planes are added
        to the K, which catches most of what only an edge-edge axis would separate). Degenerate
        triangles never enter (they are never hit either). facing (P, 3), when given: only
        triangles whose front normal has a positive component along facing[p] count for region p
        (the back faces a ray along it would meet).

        The tree is walked level by level for all regions at once: (region, node) pairs whose box
        a plane keeps out are dropped, regions found entered stop, and the leaves' triangles are
        tested.
        """
        corners = np.asarray(corners, np.float64)
        # The region's bounding box faces support it too: they separate what lies beyond a
        # corner of the region along an axis, which no face plane of a slanted region does.
        box_normals = np.broadcast_to(np.concatenate([np.eye(3), -np.eye(3)]),
                                      (corners.shape[0], 6, 3))
        box_offsets = np.concatenate([corners.max(axis=1), -corners.min(axis=1)], axis=1)
        normals = np.concatenate([np.asarray(normals, np.float64), box_normals], axis=1)
        offsets = np.concatenate([np.asarray(offsets, np.float64), box_offsets], axis=1)
        clear = np.ones(normals.shape[0], bool)
        tree = self._tree
        if tree.root == NONE or clear.size == 0:
            return clear
        size, width = self._leaf_slots, self.settings.width
        # The one-leaf tree keeps a copy per ray frame; frame kz = 2 has the world axis order.
        leaf_row = 2 * tree.leaf_count if tree.root <= -2 else 0
        absn = np.abs(normals)

        def enter_boxes(region: np.ndarray, node: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """The children (region, child reference) of `node` (F,) some plane does not keep
            out."""
            record = tree.nodes[node]
            box = record[:, : 6 * width].reshape(-1, 2, 3, width).astype(np.float64)
            child = record[:, 6 * width :].view(np.int32)  # (F, W)
            centre, half = 0.5 * (box[:, 0] + box[:, 1]), 0.5 * (box[:, 1] - box[:, 0])
            n, a = normals[region], absn[region]  # (F, K, 3)
            gap = -offsets[region][:, :, None]  # (F, K, W): n . centre - |n| . half - d
            for c in range(3):  # three multiply-adds beat einsum's generic loop here
                gap = gap + (n[:, :, c, None] * centre[:, None, c]
                             - a[:, :, c, None] * half[:, None, c])
            f, w = np.nonzero((child != NONE) & ~(gap >= -slack).any(axis=1))
            return region[f], child[f, w].astype(np.int64)

        def test_leaves(region: np.ndarray, leaf: np.ndarray) -> None:
            record = tree.leaves[leaf_row + leaf]  # (F, 10 S)
            tri = record[:, : 9 * size].reshape(-1, 3, 3, size).astype(np.float64)  # f v c s
            filled = record[:, 9 * size :].view(np.int32) >= 0  # (F, S)
            n = normals[region]  # (F, K, 3)
            gap = None  # (F, K, S): the least n . v - d over the triangle's corners v
            for v in range(3):
                dist = -offsets[region][:, :, None]
                for c in range(3):
                    dist = dist + n[:, :, c, None] * tri[:, None, v, c]
                gap = dist if gap is None else np.minimum(gap, dist)
            out = (gap >= -slack).any(axis=1)
            # The triangle's own plane, scaled to metres by its normal's length.
            edge1, edge2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]  # (F, 3, S)
            m = np.cross(edge1, edge2, axis=1)
            m_len = np.maximum(np.linalg.norm(m, axis=1), 1e-300)  # (F, S)
            pts = corners[region]  # (F, V, 3)
            side = sum(m[:, None, c] * (pts[:, :, c, None] - tri[:, None, 0, c])
                       for c in range(3))  # (F, V, S)
            tol = slack * m_len[:, None, :]
            out |= (side >= -tol).all(axis=1) | (side <= tol).all(axis=1)
            if facing is not None:
                out |= np.einsum("fcs,fc->fs", m, facing[region]) <= 0.0
            clear[region[(filled & ~out).any(axis=1)]] = False

        region, node = np.arange(clear.size), np.zeros(clear.size, np.int64)
        if tree.root <= -2:
            node = np.full(clear.size, -2, np.int64)  # every region at the one leaf
        while region.size:
            next_region, next_node = [], []
            for a in range(0, region.size, SHAFT_PAIRS):  # bounds the (F, K, W) temporaries
                r, nd = region[a : a + SHAFT_PAIRS], node[a : a + SHAFT_PAIRS]
                live = clear[r]
                r, nd = r[live], nd[live]
                at_leaf = nd <= -2
                if at_leaf.any():
                    test_leaves(r[at_leaf], -2 - nd[at_leaf])
                if (~at_leaf).any():
                    rr, nn = enter_boxes(r[~at_leaf], nd[~at_leaf])
                    next_region.append(rr)
                    next_node.append(nn)
            region = np.concatenate(next_region) if next_region else np.zeros(0, np.int64)
            node = np.concatenate(next_node) if next_node else np.zeros(0, np.int64)
        return clear
