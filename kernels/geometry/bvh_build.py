"""Building the BVH's flat tables: a binned-SAH binary tree collapsed into `width`-wide nodes.

The binary tree is built level by level, vectorised over triangles: every open node of a level is
binned at once (segmented reductions). It is then collapsed into `width`-wide nodes by repeatedly
opening the child with the largest surface area. The result is two flat arrays:

* node table (N, 7W) float32: per child slot its box, [lo/hi][x/y/z][slot], then W child
  references (int32 bits): >= 0 another node, <= -2 leaf number -2 - ref, -1 an empty slot
  (NaN box, never entered);
* leaf table (L, 10S) float32: per leaf its S triangle slots' corners [corner][axis][slot], then
  S triangle indices (int32 bits). Empty slots hold NaN corners, which never hit.

A scene of at most `brute_force_below` triangles is one leaf (stored once per ray frame), tested
against every ray without a tree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .intersect import PreparedTriangles

# Child reference of an empty node slot, and the "pop the stack next" marker of a ray.
NONE = -1


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


def _build_binary(lo: np.ndarray, hi: np.ndarray, settings) -> _BinaryTree:
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
class WideTree:
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


def build_tables(
    prepared: PreparedTriangles, valid_ids: np.ndarray, settings
) -> WideTree:
    """The node and leaf tables of the triangles `valid_ids` (all with non-zero area)."""
    width = settings.width
    n = valid_ids.size
    if n == 0:
        return WideTree(
            np.zeros((0, 7 * width), np.float32),
            np.zeros((0, 10), np.float32),
            0,
            NONE,
            0,
        )
    if n <= max(settings.brute_force_below, settings.leaf_size):
        # One leaf holding everything: the brute force, through the same leaf code.
        leaves = _leaf_table(prepared, valid_ids[None, :], n, frames=True)
        return WideTree(np.zeros((0, 7 * width), np.float32), leaves, 1, -2, 0)
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
    return WideTree(nodes, leaves, leaf_nodes.size, 0, depth)


def ray_frame_axes(kz: int) -> list[int]:
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
    orders = [ray_frame_axes(kz) for kz in range(3)] if frames else [[0, 1, 2]]
    table = np.empty((len(orders), n_leaves, 10 * size), np.float32)
    for k, axes in enumerate(orders):
        permuted = v[:, :, :, axes]  # (L, S, corner, axis)
        table[k, :, : 9 * size] = permuted.transpose(0, 2, 3, 1).reshape(n_leaves, 9 * size)
        table[k, :, 9 * size :] = members.astype(np.int32).view(np.float32)
    return table.reshape(len(orders) * n_leaves, 10 * size)
