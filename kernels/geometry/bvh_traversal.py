"""Traversal of the BVH's tables: the "lockstep pool" of rays, the breadth-first frontier of
small calls (`Frontier`), and the one-leaf brute force.

A pool of `chunk_size` ray slots advances in steps. Every ray keeps its own stack; in a step each
busy ray pops its stack if it has nothing to visit (skipping up to POP_ROUNDS entries farther than
its closest hit), then descends through up to DESCENT nodes along its nearest children, and rays
standing at leaves are tested once enough of them wait (NumPy calls cost about the same for 300
or 3000 elements). At a node the W child boxes are slab-tested, (entry distance, child) pairs are
packed into int64 keys and sorted with a sorting network, the nearest child is visited next and
the others are pushed, so a popped child farther than the closest hit so far is skipped. Leaves
run the watertight test of `intersect.py`; only the few pairs that pass it take the float64
recheck, the box clamp and the closest-hit update. Node and leaf records are fetched with one row
gather each and transposed in cache-sized blocks, so all arithmetic runs on contiguous rows.
Answered slots are refilled from a shared queue (`RayQueue`), so steps stay full until the queue
runs dry. The table layouts are described in `bvh_build.py`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator

import numpy as np

from .bvh_build import NONE, ray_frame_axes
from .intersect import (
    INT32_MAX,
    edge_functions,
    finish_candidates,
    inside,
    prepare_rays,
    raw_distance,
    ray_frame_corners,
    slab,
)

# Rays per block of the gather-and-transpose of node and leaf records: a block's records
# (512 rows of at most 80 float32) stay in the core's L1/L2 cache while they are transposed.
TRANSPOSE_BLOCK = 512
# (ray, triangle) pairs tested at once by a one-leaf (brute force) BVH: keeps the (3, S, M)
# temporaries of the test in the core's L2 cache.
BRUTE_FORCE_PAIRS = 1 << 14
# (ray, node) pairs a breadth-first round takes at most (the rest wait for a later round): its
# (7W, pairs) float32 records and (W, pairs) temporaries stay a few MB. 4096 rays grazing a
# million-triangle torus made at most 50k pairs.
FRONTIER_PAIRS = 1 << 16
# A pool refills its answered slots once this fraction of them is free.
REFILL_AT = 1.0 / 8.0
# Stack entries a ray may pop in one step while they are farther than its closest hit.
POP_ROUNDS = 4
# Node levels a ray may descend in one step (along its nearest children) before the others move.
DESCENT = 4
# Leaf steps wait until this fraction of the pool stands at leaves (or nothing else can move).
LEAF_BATCH = 0.3


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


def pack(t: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(t, tri) as one int64 whose order is (t, then tri): t >= +0 float32 bits are monotone."""
    return (t.astype(np.float32).view(np.int32).astype(np.int64) << 32) | tri.astype(np.int64)


def unpack(key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Inverse of `pack`: (t float32, tri int32)."""
    t = (key >> 32).astype(np.int32).view(np.float32)
    return t, (key & 0xFFFFFFFF).astype(np.int32)


def _leaf_records(table: np.ndarray, leaf: np.ndarray, kz: np.ndarray,
                  size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The records of leaves `leaf` (M,) for rays whose ray-frame axes are `kz` (M,).

    Returns (order (M,): the rays sorted by kz, corners (3, 3, S, M) [corner, ray-frame axis,
    slot, ray] in that order, triangle ids (S, M) int32).
    """
    order = np.argsort(kz, kind="stable")
    kz = kz[order]
    block = _gather_columns(table, leaf[order])  # (10S, M), world axis order
    corners = block[: 9 * size].reshape(3, 3, size, order.size)
    edges = np.searchsorted(kz, [0, 1, 2, 3])
    for frame in range(2):  # frame 2 (kz = z) is the world order already
        cols = slice(edges[frame], edges[frame + 1])
        if cols.start < cols.stop:
            corners[:, :, :, cols] = corners[:, ray_frame_axes(frame), :, cols]
    return order, corners, block[9 * size :].view(np.int32)


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
    key = pack(t, tri)
    np.minimum.at(best, pos, key)  # several hits of one ray: the closest, then the lowest index
    won = best[pos] == key
    pos = pos[won]
    t_best[pos] = t[won]
    u[pos] = bu[won]
    v[pos] = bv[won]


def _no_answers(table: np.ndarray) -> tuple[np.ndarray, ...]:
    """A batch's answers before any hit, from its (14, R) ray table: (best (R,) int64 packed
    (t_max, no triangle), u, v (R,) float32 zeros, occluded (R,) False)."""
    n = table.shape[1]
    return (pack(table[_T_BEST], np.full(n, INT32_MAX)), np.zeros(n, np.float32),
            np.zeros(n, np.float32), np.zeros(n, bool))


class BruteForce:
    """A one-leaf BVH (a tiny scene): every ray against every triangle, block by block.

    Same answers as the pool (the same leaf test), without stacks or lockstep steps.
    """

    def __init__(self, bvh, any_hit: bool):
        self.bvh = bvh
        self.any_hit = any_hit

    def run(self, queue: RayQueue, sink) -> Iterator[None]:
        tree = self.bvh._tree
        size = self.bvh._leaf_slots
        block = max(1, BRUTE_FORCE_PAIRS // size)
        while (batch := queue.take()) is not None:
            ids, table, kz = batch
            n = ids.size
            best, u, v, occluded = _no_answers(table)
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


class Frontier:
    """Breadth-first traversal for small batches: every (ray, node) pair of a level at once.

    A pool step costs a few hundred NumPy calls whatever its size, and a pool needs a step per
    node or leaf its slowest ray visits: 100 rays took 15 steps (4.5 ms) on a 12k-triangle scene.
    Here a round takes the whole frontier of (ray, node) pairs: the child boxes each ray enters
    make the next frontier, the leaves among them are tested at once, and pairs farther than
    their ray's closest hit so far are dropped. A batch takes as many rounds as the tree has
    levels (1.1 ms for those 100 rays). Without near-to-far order it tests more leaves, so the
    pool wins on large batches (`BVHSettings.frontier_rays`). Same answers as the pool (the same tests).
    """

    def __init__(self, bvh, any_hit: bool):
        self.bvh = bvh
        self.tree = bvh._tree
        self.any_hit = any_hit
        self.width = bvh.settings.width
        self.leaf_slots = bvh._leaf_slots

    def run(self, queue: RayQueue, sink) -> Iterator[None]:
        while (batch := queue.take()) is not None:
            ids, table, kz = batch
            n = ids.size
            best, u, v, occluded = _no_answers(table)
            skip = None if queue.skip is None else queue.skip[ids]
            # Rounds still to run, as (ray, node or leaf reference) pairs; the last one runs next.
            rounds = [(np.arange(n), np.full(n, self.tree.root, np.int64))]
            while rounds:
                ray, ref = rounds.pop()
                if ray.size > FRONTIER_PAIRS:  # the rest waits: memory stays bounded
                    rounds.append((ray[FRONTIER_PAIRS:], ref[FRONTIER_PAIRS:]))
                    ray, ref = ray[:FRONTIER_PAIRS], ref[:FRONTIER_PAIRS]
                leaf = ref <= -2
                if leaf.any():
                    hit = self._leaves(table, kz, skip, ray[leaf], -2 - ref[leaf])
                    if self.any_hit:
                        occluded[hit[0]] = True
                    else:
                        _keep_closest(*hit, best, u, v, table[_T_BEST])
                    ray, ref = ray[~leaf], ref[~leaf]
                if self.any_hit:
                    live = ~occluded[ray]
                    ray, ref = ray[live], ref[live]
                if ray.size:
                    rounds.append(self._nodes(table, ray, ref))
            sink(ids, best, u, v, occluded)
            queue.report(n)
            yield

    def _nodes(self, table: np.ndarray, ray: np.ndarray,
               node: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The (ray, child) pairs whose boxes rays `ray` enter before their closest hit so far."""
        width = self.width
        block = _gather_columns(self.tree.nodes, node)  # (7W, M)
        box = block[: 6 * width].reshape(2, 3, width, ray.size)
        child = block[6 * width :].view(np.int32)  # (W, M)
        rows = np.take(table[_NODE_ROWS], ray, axis=1)  # (8, M)
        near, far = slab(box, rows[_ORIGIN, None, :], rows[_INV_DIR, None, :])
        near = np.maximum(near, rows[_T_MIN])
        far = np.minimum(far, rows[_T_BEST])
        k, pos = np.nonzero(near <= far)
        return ray[pos], child[k, pos].astype(np.int64)

    def _leaves(self, table: np.ndarray, kz: np.ndarray, skip: np.ndarray | None,
                ray: np.ndarray, leaf: np.ndarray) -> tuple[np.ndarray, ...]:
        """Hits (ray, tri, t, u, v) of rays `ray` with the triangles of leaves `leaf`."""
        order, corners, ids = _leaf_records(self.tree.leaves, leaf, kz[ray], self.leaf_slots)
        ray = ray[order]
        pos, tri, t, bu, bv = _leaf_hits(
            corners,
            ids,
            np.take(table[_LEAF_ROWS], ray, axis=1),
            lambda p: np.take(table[_NODE_ROWS], ray[p], axis=1),
            self.bvh._prepared.boxes,
            None,
        )
        if skip is not None:
            keep = tri != skip[ray[pos]]
            pos, tri, t, bu, bv = pos[keep], tri[keep], t[keep], bu[keep], bv[keep]
        return ray[pos], tri, t, bu, bv


class RayQueue:
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


class Pool:
    """`size` rays in flight: the lockstep traversal state, one slot per ray.

    Each step every busy slot pops its stack (if it has no node to visit), then visits one node
    or one leaf. Leaf visits wait until enough rays stand at leaves (NumPy calls cost the same
    for 100 or 5000 elements). Slots whose ray is answered are refilled from the queue, so the
    steps stay full until the queue runs dry.
    """

    def __init__(self, bvh, size: int, any_hit: bool):
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
        self.best = np.zeros(size, np.int64)  # pack(t, tri) of the closest hit so far
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

    def _refill(self, free: np.ndarray, queue: RayQueue) -> tuple[np.ndarray, bool]:
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
            self.best[dst] = pack(table[_T_BEST, src], np.full(k, INT32_MAX))
            self.occluded[dst] = False
            self.ray[dst] = ids[src]
            self.cur[dst] = self.tree.root
            self.sp[dst] = 0
            filled.append(dst)
        dry = self._pending is None
        return (np.concatenate(filled) if filled else np.zeros(0, np.int64)), dry

    def run(self, queue: RayQueue, sink) -> Iterator[None]:
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
        self.cur[slot] = NONE
        order, corners, ids = _leaf_records(self.tree.leaves, leaf, self.kz[slot], self.leaf_slots)
        self._test(slot[order], corners, ids)

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

