"""A bounding volume hierarchy for batched ray casting in NumPy: closest hits and occlusion.

The tree is a binned surface-area-heuristic tree collapsed into `width`-wide nodes, kept in flat
arrays (`bvh_build.py`); rays walk it in a lockstep pool, each with its own stack, or, in calls
of a few thousand rays, breadth-first, a tree level per round (`bvh_traversal.py`). This module
holds the settings, the `BVH` a caller builds and queries, the worker threads that share a query,
and shaft culling (`BVH.convex_clear`).

Threads: each worker thread runs its own pool on batches taken from the queue (NumPy releases the
GIL inside its loops); a call takes one thread per THREAD_RAYS rays, up to one per core, and with
the automatic thread count (`threads` 0) one thread instead when that has been faster lately on
this machine (`thread_choice.py`: under another process's load, threads lose). A ray's answer does
not depend on the batching or the thread count.

Exactness: the answer equals `intersect.intersect_all` bit for bit (same triangle, same t, u, v);
see the module docstring of `intersect.py` for why no node holding the closest hit is culled.

Memory of a query: per thread, the pool's slots (about 56 + 8 * stack depth + 40 bytes each, the
stack depth being (W - 1) * tree depth + 2, ~35 for a million triangles) and one step's
temporaries: about 16 MB per thread at 16384 slots and 53 MB at the default 65536 (tracemalloc),
for any number of rays. Larger pools pay: each NumPy call serves more rays, so fixed per-call
costs weigh less (bench/rays.py). The tree itself takes about 70 bytes per triangle (plus the
36-byte float32 copy of the triangles and their 24-byte boxes): 131 MB in all for a million
triangles.
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor, wait
from dataclasses import dataclass

import numpy as np

from ..progress import Steps, drain
from .bvh_build import NONE, WideTree, build_tables
from .bvh_traversal import BruteForce, Frontier, Pool, RayQueue, unpack
from .intersect import INT32_MAX, Hits, PreparedTriangles, prepare_triangles, ray_limits
from .thread_choice import CHOICE
from .threads import core_count

QUERY_BYTES_PER_SLOT = 810  # a pool slot's stack, state and one step's temporaries (tracemalloc)
# Rays handed to a worker at a time (the unit of work sharing between threads).
QUEUE_BATCH = 4096
# Rays a call must bring per worker thread. Below this the threads' NumPy calls are too small to
# release the GIL for long, and they mostly wait on each other: radiosity's many small calls
# (0.5k-18k rays) ran faster with one thread per 32768 rays than with one per 4096, and large
# calls (300k rays) lost nothing by it.
THREAD_RAYS = 1 << 15
# Occlusion calls walk breadth-first up to this multiple of `frontier_rays`: a ray stops at its
# first hit, so the frontier's lack of near-to-far order costs it less (12k-triangle scenes, random
# rays off surfaces: even with the pool at about 8000 closest-hit and 12000 occlusion rays).
FRONTIER_OCCLUSION_FACTOR = 2
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
    | solo_chunk_size   | >= 256     | 16384   | rays in flight when a call runs on one thread    |
    | threads           | >= 0       | 0       | worker threads; 0: one per CPU core              |
    | brute_force_below | >= 0       | 24      | at most this many triangles: one leaf, no tree   |
    | frontier_rays     | >= 0       | 4096    | calls of at most this many rays (occlusion: 2x)  |
    |                   |            |         | walk the tree breadth-first; 0: never            |

    Breadth-first (`bvh_traversal.Frontier`) takes a round of NumPy calls per tree level, where
    the pool takes a step per node its slowest ray visits: on a 12k-triangle scene 100 rays took
    1.1 ms instead of 4.5, 1000 rays 3.2 instead of 7.7.

    Pool sizes: on one thread a pool of 16384 slots (about 16 MB of stacks and step temporaries)
    traces 12-25% more rays per second than one of 65536 (53 MB) on the bench's 82k and 1M
    triangle meshes: its working set stays nearer the core (a 32 MB L3 here). Several threads
    want the larger pools: each NumPy call then runs longer without the GIL, and the threads
    wait on each other less (two threads: 64k slots 10-40% faster than 16k).
    """

    bins: int = 16
    leaf_size: int = 4
    width: int = 4
    chunk_size: int = 65536
    solo_chunk_size: int = 16384
    threads: int = 0
    brute_force_below: int = 24
    frontier_rays: int = 4096

    def __post_init__(self) -> None:
        if not 2 <= self.bins <= 256:
            raise ValueError("bins must be in 2..256")
        if not 1 <= self.leaf_size <= 64:
            raise ValueError("leaf_size must be in 1..64")
        if self.width not in (2, 4, 8):
            raise ValueError("width must be 2, 4 or 8")
        if min(self.chunk_size, self.solo_chunk_size) < 256:
            raise ValueError("chunk_size and solo_chunk_size must be >= 256")
        if self.threads < 0 or self.brute_force_below < 0 or self.frontier_rays < 0:
            raise ValueError("threads, brute_force_below and frontier_rays must be >= 0")

    @property
    def thread_count(self) -> int:
        return self.threads or core_count()

    @property
    def query_bytes(self) -> int:
        """Memory of one query in flight, all threads: ~810 B per pool slot (53 MB per thread at
        65536 slots, by tracemalloc; see the module docstring)."""
        return self.thread_count * self.chunk_size * QUERY_BYTES_PER_SLOT


class BVH:
    """A BVH over world-space triangles; build with `BVH.build`.

    triangle_count: the number of triangles of the build input (degenerate ones included).
    """

    def __init__(self, prepared: PreparedTriangles, tree: WideTree, settings: BVHSettings):
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
        return cls(prepared, build_tables(prepared, valid_ids, settings), settings)

    @property
    def node_count(self) -> int:
        return int(self._tree.nodes.shape[0])

    @property
    def leaf_count(self) -> int:
        return int(self._tree.leaf_count)

    # ---------------------------------------------------------------------------------------

    def _run(self, origins, directions, t_min, t_max, any_hit: bool, sink,
             skip=None) -> Steps[None]:
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
        # Automatic thread count: one thread or several, whichever has been faster lately on
        # this machine under its current load (`thread_choice.py`).
        measured = threads > 1 and settings.threads == 0
        if measured and not CHOICE.threaded():
            threads = 1
        began = time.perf_counter()
        slots = settings.chunk_size if threads > 1 else min(settings.chunk_size, settings.solo_chunk_size)
        pool_size = min(slots, -(-count // threads))
        if skip is not None:
            skip = np.asarray(skip, np.int64)
            if skip.shape != (count,):
                raise ValueError(f"skip must be ({count},), got {skip.shape}")
        brute = self._tree.leaf_count == 1 and self._tree.nodes.shape[0] == 0
        most = settings.frontier_rays * (FRONTIER_OCCLUSION_FACTOR if any_hit else 1)
        frontier = not brute and count <= most
        batch = count if frontier else min(QUEUE_BATCH, pool_size)
        queue = RayQueue(origins, directions, lo, hi, batch, skip)

        def runner():
            if brute:
                return BruteForce(self, any_hit)
            if frontier:
                return Frontier(self, any_hit)
            return Pool(self, pool_size, any_hit)

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
            if measured:
                CHOICE.record(False, count, time.perf_counter() - began)
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
        CHOICE.record(True, count, time.perf_counter() - began)
        yield 1.0

    def intersect_steps(
        self, origins, directions, t_min=0.0, t_max=np.inf, out: Hits | None = None
    ) -> Steps[Hits]:
        """`intersect` as a step: yields progress in [0, 1] while tracing, fills and returns `out`.

        Closing the generator early stops the work (the rays not yet traced read as misses).
        """
        count = np.asarray(origins).shape[0]
        hits = out if out is not None else Hits.empty(count)
        hits.t[:] = np.inf
        hits.tri[:] = -1
        hits.u[:] = 0.0
        hits.v[:] = 0.0

        def sink(ray, best, u, v, occluded) -> None:
            t, tri = unpack(best)
            found = tri != INT32_MAX
            ray = ray[found]
            hits.t[ray] = t[found]
            hits.tri[ray] = tri[found]
            hits.u[ray] = u[found]
            hits.v[ray] = v[found]

        yield from self._run(origins, directions, t_min, t_max, False, sink)
        return hits

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
        return drain(self.intersect_steps(origins, directions, t_min, t_max, out))

    def occluded_steps(
        self, origins, directions, t_min=0.0, t_max=np.inf, out: np.ndarray | None = None,
        skip: np.ndarray | None = None,
    ) -> Steps[np.ndarray]:
        """`occluded` as a step: yields progress in [0, 1] while tracing, fills and returns `out`."""
        count = np.asarray(origins).shape[0]
        result = out if out is not None else np.zeros(count, bool)
        result[:] = False

        def sink(ray, best, u, v, occluded) -> None:
            result[ray] = occluded

        yield from self._run(origins, directions, t_min, t_max, True, sink, skip)
        return result

    def occluded(self, origins, directions, t_min=0.0, t_max=np.inf, out=None,
                 skip=None) -> np.ndarray:
        """(R,) bool: whether anything is hit on [t_min, t_max] (shadow and visibility rays).

        Same parameters as `intersect`; `out` may be a caller-owned (R,) bool array. A ray stops
        at the first hit it finds. skip (R,) int, when given: one triangle per ray that it
        passes through (-1: none), so a ray may start on its own surface, or just behind it,
        and still meet a surface lying flat against that one (`world_light.py`).
        """
        return drain(self.occluded_steps(origins, directions, t_min, t_max, out, skip))

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
