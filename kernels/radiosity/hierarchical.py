"""Hierarchical radiosity: every patch gathers from a hierarchy of sources, coarse where it can.

After P. Hanrahan, D. Salzman and L. Aupperle, "A rapid hierarchical radiosity algorithm"
(SIGGRAPH 1991): energy moves along links between elements of a patch hierarchy, refined by an
error bound, instead of along the N^2 pairs of equal patches. Here only the source end of a link
is hierarchical; the receiving end is always a leaf patch. The full two-sided scheme pushes a
coarse receiver's gathered radiosity down to its leaves unchanged, and every such link's error
adds up over the tens of links of an element: measured in a closed box, leaves' row sums spread
from 0.82 to 1.34 with a per-link bound of 0.01, which a furnace at rho = 0.95 cannot survive.
With leaf receivers the links of a patch partition its view of the scene exactly, each factor is
exact over its source polygon, and only the radiosity of a coarse source is averaged.

Elements. The roots are `patches.make_patches` at 2^max_depth times the patch size; each is split
max_depth times into midpoint children (`patches.split`'s rule), and the leaves, about the patch
size, are the patches of the result (`TreeLevels`). The level loop of `solve.py` splits them as
it splits the matrix solvers' patches: before any link, leaves across a lamp's shadow edge
`shadow_splits` times and leaves in a near field `near_splits` times (`sources.shadow_edges`,
`near_field.near_field`, `refine.first_splits`); after a
solve, where a corner value is far from the leaf's own (`refine.refine_mask`), up to
`refine_levels` times, and everything is linked and solved again.

Links (p <- q: leaf p gathers from element q). Every leaf starts linked to every root that faces
it. A link is refined while it carries more than `link_epsilon`, F_pq > epsilon, by linking p to
q's four children instead; leaf sources stay. A link also splits where the first shot lights its
source unevenly: a coarse source gives its receivers its parts' mean B, so F_pq x (range of rho H
over q) must stay under LIGHT_SPLIT_SHARE x max(rho_p H_p, mean rho H) (`light_spread`).
F_pq is exact over q's polygon from n x n midpoint points of p (`point_to_polygon`), times the
visible share of q seen from p: shadow rays from those points to randomly paired points of q, each
weighted by the point-to-point kernel (see `_visible_share_steps`); a link at the bound casts one
ray per point, a fainter one fewer, in proportion to its factor (at least one, FULL_RAYS_SHARE).
Pairs that share an edge (still above the bound at the leaves) take NEAR_FIELD_SIDE times the
points per side.

Source clusters. Over more than `source_clusters.MIN_ROOTS` roots (a finely tessellated object,
whose every triangle is a root), roots far from a leaf are reached through a tree over the roots:
each still gets its own link, with the disc form of its factor, and the far ones of a group share
the group's shadow rays (`source_clusters.py`; `cluster_sources` turns this off).

Solve: Jacobi iteration of B_p = E_p + rho_p H_p + rho_p sum_{p <- q} F_pq B_q on the leaves,
each inner element's B the area-weighted mean of its children (pull), until the contraction
bound on the remaining error is below `tolerance` x the largest reflected radiosity (see
`solve_links`). E: emission (pi L); H: the lamps' direct irradiance.

Memory is bounded before any link is made (`memory_bound`).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ..geometry import threads
from ..geometry.frames import RAY_OFFSET_REL
from ..geometry.scene import Scene, geometric_normals, triangle_areas
from ..progress import Steps, scaled
from . import patches as patching
from . import source_clusters
from .form_factors.point_polygon import point_to_polygon
from .form_factors.rays import answer_rays
from .form_factors.sampling import sample_patches
from .form_factors.visibility import paired_share_steps
from .levels import LevelLight, LevelSolution
from .settings import RadiositySettings

# Links whose factors are evaluated at once: bounds point_to_polygon's (L, S, K, 3) temporaries.
LINK_CHUNK = 1 << 15
# (leaf, root) pairs a chunk of leaves walks the source tree with at once: its far roots' disc
# factors take ~80 B per (pair, point) of temporaries (counted in `memory_bound`'s work). 4x
# this: 6% less solve on shadows.blend, for 4x the memory.
FAR_LINK_CHUNK = 1 << 16
# Links a thread must have at least before `_point_factors` spreads them over the cores.
THREAD_LINKS = 2048
# Pairs still above the bound at the leaves (they meet at an edge or nearly) integrate over this
# many times more points per side: their integrand varies within the patch. 2 (4x the points)
# gives the Cornell lightmaps the same error as 3 (relMSE 0.00148 and 0.00150 at 1184 patches)
# with the points at sub-triangle centroids (`form_factors.sampling.triangle_midpoints`).
NEAR_FIELD_SIDE = 2
# A link also splits while F_pq times the range of the first shot's reflected light rho H over q
# exceeds this share of what receiver p reflects of it (at least the scene's area-weighted mean):
# a coarse source gives its receivers its parts' mean B, which is wrong where its light is uneven
# and the receiver has little light of its own (the walls around a spot's pool on a floor: 1.8%
# dark against Cycles on a generated room, 0.6% with the split, at the same bake time). Relative
# to the receiver's own light, not the brightest leaf's: directly lit receivers, which a source's
# unevenness barely changes, then keep their links (measured against the brightest leaf, a
# point-lit room split them all and baked 25% longer for no gain).
LIGHT_SPLIT_SHARE = 2e-3
# Rays per shadow-ray call (the BVH reaches its full rate from about 50k).
RAYS_PER_CALL = 1 << 18
# Leaves may number this many times the patches asked for (roots are whole scene triangles at
# least, so a deep hierarchy over a coarse mesh would over-refine it).
LEAF_SLACK = 2.0
# Jacobi sweeps at most: the error shrinks by about rho_max per sweep (rho = 0.95 to 1e-6: 270).
MAX_ITERATIONS = 5000
# Memory per link: (p, q, factor) 24 B kept, 24 B more while the chunks are joined, and a Jacobi
# sweep's gathered source B and product (2 x 24 B).
LINK_BYTES = 96
ELEMENT_BYTES = 500  # corners, barycentrics, normals, area, tree indices of one element
# Working memory per point pair of a chunk: kernels, shadow-ray origins, directions, lengths.
WORK_BYTES_PER_POINT_PAIR = 300
# Root pairs at most that `planning.hierarchical_memory` has `facing_roots` count (~40 ms per
# million); past it the bound takes every pair.
FACING_COUNT_PAIRS = 1 << 28
# `facing_roots` counts a pair as facing from this share of `_facing`'s epsilon
# (1e-9 sqrt(area_p + area_q) m) up: never fewer pairs than `_facing` finds, while coplanar
# pairs (a floor's patches, exactly 0) still count as not facing.
FACING_EPS_SHARE = 0.5
# Root pairs per block of `facing_roots` (two (rows, N) float64 tables of ~8 MB).
FACING_BLOCK = 1 << 20
# Shadow rays per chunk of links (side^2 each): ~40 MB of pairs, and BVH calls at full rate.
VISIBILITY_RAYS = 1 << 17
# Exact links from this share of link_epsilon up cast all side^2 visibility rays, fainter ones
# fewer in proportion (at least one): they carry little of any receiver's light.
FULL_RAYS_SHARE = 1.0


def hierarchy_roots(scene: Scene, patch_size: float, max_depth: int,
                    triangles: np.ndarray | None = None, wanted: int | None = None
                    ) -> tuple[patching.Patches, int, int]:
    """(roots, depth, patches asked for): the deepest hierarchy (at most max_depth) whose leaves
    are not much finer than the patches of `patch_size`; a small scene's roots cannot be coarser
    than its triangles. triangles (T,) bool: the scene triangles meshed (all when None); wanted:
    the count of those patches when the caller has them (meshed here when None)."""
    if wanted is None:
        wanted = len(patching.make_patches(scene, patch_size, triangles))
    for depth in range(max_depth, -1, -1):
        roots = patching.make_patches(scene, patch_size * 2.0**depth, triangles)
        if len(roots) * 4**depth <= LEAF_SLACK * wanted:
            break
    return roots, depth, wanted


def memory_bound(root_count: int, depth: int, link_epsilon: float, side: int = 2,
                 refine_levels: int = 0, max_patches: int = 0,
                 facing: tuple[int, int] | None = None) -> dict:
    """Bytes of links and elements, bounded before any link is made.

    Each leaf starts linked to at most every root; a link splits only while its factor exceeds
    epsilon, and the factors from one leaf to disjoint elements of one level sum to at most 1,
    so each level of sources adds at most 4 / epsilon links per leaf:
    links <= leaves x (roots + 4 levels / epsilon), with levels = depth + refine_levels and, when
    leaves are refined, leaves <= max(the first leaves, max_patches) (refine_levels counts none
    when max_patches leaves no room for a split).

    facing (`facing_roots`: the root pairs that face each other, and the most roots one root
    faces), when given, tightens the first term: a leaf faces only roots its own root faces, so
    the first leaves start with at most 4^depth x pairs links and each refined leaf with at most
    the most (a room of many small triangles: 19% of all pairs face).
    """
    first = root_count * 4**depth
    if max_patches <= first:
        refine_levels = 0  # no room for a split: the first leaves are the last
    leaves = max(first, max_patches) if refine_levels else first
    elements = root_count * sum(4**k for k in range(depth + 1)) + (leaves - first) * 4 // 3
    levels = depth + refine_levels
    start = float(leaves) * root_count
    if facing is not None:
        start = min(start, 4.0**depth * facing[0] + float(leaves - first) * facing[1])
    links = min(start + leaves * 4.0 * levels / link_epsilon, float(leaves) * elements)
    work = max(LINK_CHUNK * side**2, FAR_LINK_CHUNK * side**2, VISIBILITY_RAYS) * \
        WORK_BYTES_PER_POINT_PAIR
    return {"links": int(links * LINK_BYTES), "elements": int(elements * ELEMENT_BYTES),
            "work": int(work), "link_bound": int(links)}


class _Tree:
    """Element arrays, grown a level at a time; children always follow their parent."""

    def __init__(self, scene: Scene, roots: patching.Patches):
        self.tris = scene.triangles.astype(np.float64)
        self.bary = roots.bary.copy()
        self.tri = roots.parent.astype(np.int64)
        self.level = np.zeros(len(roots), np.int32)
        self.child = np.full(len(roots), -1, np.int64)
        self.corners = roots.corners.copy()
        self.normals = roots.normals.copy()
        self.areas = roots.areas.copy()

    def __len__(self) -> int:
        return len(self.tri)

    def leaf_patches(self, scene: Scene) -> tuple[np.ndarray, patching.Patches, patching.Patches]:
        """(leaf element ids in the patches' order (by parent triangle), every element as
        Patches, the leaves as Patches)."""
        leaves = np.flatnonzero(self.child < 0)
        leaves = leaves[np.argsort(self.tri[leaves], kind="stable")]
        elements = self.patches(scene, slice(None))
        return leaves, elements, elements.subset(leaves)

    def patches(self, scene: Scene, index) -> patching.Patches:
        """The elements `index` (indices or a slice) as Patches."""
        tri = self.tri[index]
        return patching.Patches(corners=self.corners[index], parent=tri, bary=self.bary[index],
                                level=self.level[index], normals=self.normals[index],
                                areas=self.areas[index],
                                object_ids=scene.object_ids[tri].astype(np.int32))

    def split(self, elements: np.ndarray) -> None:
        """Give `elements` (leaves) their four midpoint children."""
        kids = patching.midpoint_children(self.bary[elements])  # patches.split's rule
        self.child[elements] = len(self) + 4 * np.arange(elements.size)
        tri = np.repeat(self.tri[elements], 4)
        corners = np.einsum("nkc,ncj->nkj", kids, self.tris[tri])
        self.bary = np.concatenate([self.bary, kids])
        self.tri = np.concatenate([self.tri, tri])
        self.level = np.concatenate([self.level, np.repeat(self.level[elements] + 1, 4)])
        self.child = np.concatenate([self.child, np.full(4 * elements.size, -1, np.int64)])
        self.corners = np.concatenate([self.corners, corners])
        self.normals = np.concatenate([self.normals, geometric_normals(self.tris[tri])])
        self.areas = np.concatenate([self.areas, triangle_areas(corners)])


def facing_roots(roots: patching.Patches) -> tuple[int, int]:
    """(ordered root pairs (p, q) that face each other, the most roots one root faces), never
    fewer than `_facing` finds: its test as matrix products in row blocks, with half its
    epsilon, A[p, q] = max_k n_p . (c_qk - c_p0) > FACING_EPS_SHARE x 1e-9 sqrt(area_p) (float64
    rounding of the products, ~1e-16 of the scene, stays far below that)."""
    count = len(roots)
    corners = roots.corners.reshape(-1, 3)  # (3N, 3): root q's corners at rows 3q..3q+2
    normals = roots.normals
    level = np.einsum("nc,nc->n", normals, roots.corners[:, 0])  # n_p . c_p0
    level += FACING_EPS_SHARE * 1e-9 * np.sqrt(roots.areas)

    def ahead(p: np.ndarray, q_corners: np.ndarray) -> np.ndarray:
        """(len(p), Q) bool: the farthest corner of each q lies in front of p's plane."""
        d = (normals[p] @ q_corners.T).reshape(len(p), -1, 3)
        return np.maximum(np.maximum(d[..., 0], d[..., 1]), d[..., 2]) > level[p, None]

    per_root = np.zeros(count, np.int64)
    step = max(1, FACING_BLOCK // max(count, 1))
    every = np.arange(count)
    for a in range(0, count, step):
        rows = every[a:a + step]
        faces = ahead(rows, corners) & ahead(every, roots.corners[rows].reshape(-1, 3)).T
        per_root[rows] = faces.sum(axis=1)
    return int(per_root.sum()), int(per_root.max(initial=0))


def _facing(tree: _Tree | patching.Patches, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(L,) bool: some corner of q is in front of p's plane and some corner of p in front of q's
    (a pair failing this exchanges nothing, at any refinement); elements p, q of `tree` (or of
    any Patches: corners, normals and areas are read)."""
    c, n = tree.corners, tree.normals
    out = np.empty(len(p), bool)

    def work(a: int, b: int) -> None:
        pp, qq = p[a:b], q[a:b]
        eps = 1e-9 * np.sqrt(tree.areas[pp] + tree.areas[qq])
        in_front_of_p = np.einsum("lkc,lc->lk", c[qq] - c[pp][:, :1], n[pp]).max(axis=1)
        in_front_of_q = np.einsum("lkc,lc->lk", c[pp] - c[qq][:, :1], n[qq]).max(axis=1)
        out[a:b] = (in_front_of_p > eps) & (in_front_of_q > eps)

    threads.for_ranges(work, len(p), LINK_CHUNK, min_rows=THREAD_LINKS)
    return out


def _point_factors(tree: _Tree, p: np.ndarray, q: np.ndarray, side: int):
    """side x side midpoint points (L, S, 3) of leaves p, their weights (L, S), and the exact
    unoccluded factor (L, S) from each point to polygon q."""
    points, weights = sample_patches(tree.corners[p], side, "midpoint")
    f = np.empty(points.shape[:2])

    def factors(a: int, b: int) -> None:
        f[a:b] = point_to_polygon(points[a:b], tree.normals[p[a:b]][:, None, :],
                                  tree.corners[q[a:b]][:, None], tree.normals[q[a:b]][:, None])

    threads.for_ranges(factors, len(p), max(1, LINK_CHUNK // side**2), min_rows=THREAD_LINKS)
    return points, weights, f


def _unoccluded(tree: _Tree, p: np.ndarray, q: np.ndarray, side: int) -> np.ndarray:
    """(L,) F_pq without occlusion: side x side midpoint points of leaf p, exact over polygon q."""
    _, weights, f = _point_factors(tree, p, q, side)
    return np.einsum("ls,ls->l", weights, f)


def refine_links(tree: _Tree, p: np.ndarray, q: np.ndarray, epsilon: float, side: int,
                 spread: tuple[np.ndarray, np.ndarray] | None = None
                 ) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Refine links p <- q on the source side while F_pq > epsilon, or F_pq x range[q] > allowed[p]
    (`spread` = (range, allowed): `light_spread`); yields settled batches (p, q, unoccluded
    F_pq), the last ones being the leaf-to-leaf links above the bound."""
    while len(p):
        f = _unoccluded(tree, p, q, side)
        split = f > epsilon
        if spread is not None:
            split |= f * spread[0][q] > spread[1][p]
        split &= tree.child[q] >= 0
        keep = ~split & (f > 0.0)
        yield p[keep], q[keep], f[keep]
        new_p = np.repeat(p[split], 4)
        new_q = (tree.child[q[split]][:, None] + np.arange(4)).ravel()
        alive = _facing(tree, new_p, new_q)
        p, q = new_p[alive], new_q[alive]


def light_spread(tree: _Tree, leaves: np.ndarray, reflected: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """For `refine_links`: (range (E,), allowed (E,)) from the first shot's reflected light
    `reflected` (leaves, 3) = rho H, W/m^2 (largest channel): per element, its range over the
    leaves under it; per leaf, LIGHT_SPLIT_SHARE x its own (at least the area-weighted mean over
    the leaves; +inf for elements that are not leaves). None when nothing is lit."""
    lit = reflected.max(axis=1) if len(reflected) else np.zeros(0)
    areas = tree.areas[leaves]
    total = float(areas.sum())
    mean = float((lit * areas).sum()) / total if total > 0.0 else 0.0
    if mean <= 0.0:
        return None
    hi = np.full(len(tree), -np.inf)
    lo = np.full(len(tree), np.inf)
    hi[leaves] = lo[leaves] = lit
    for e in _levels(tree)[-2::-1]:  # bottom-up, as `_pull`
        e = e[tree.child[e] >= 0]
        kids = tree.child[e][:, None] + np.arange(4)
        hi[e], lo[e] = hi[kids].max(axis=1), lo[kids].min(axis=1)
    allowed = np.full(len(tree), np.inf)
    allowed[leaves] = LIGHT_SPLIT_SHARE * np.maximum(lit, mean)
    return np.where(np.isfinite(hi), hi - lo, 0.0), allowed


def _visible_share_steps(tree: _Tree, p: np.ndarray, q: np.ndarray, side: int,
                         ray_offset: float, shift: np.ndarray, first: np.ndarray,
                         rays: np.ndarray):
    """Generator (asks for shadow rays, see form_factors.rays.RayRequest): (L,) the visible share of
    q's projected solid angle seen from leaf p, from one ray per point of p's side x side points
    to a point of q's: point s of p to point (s + shift) mod side^2 of q, `shift` (L,) int drawn
    at random per link. Only `rays` (L,) int in [1, side^2] of each link's points cast theirs:
    points first, first + 1, ... (mod side^2), `first` (L,) drawn at random too, so the subset
    is unbiased over p as the pairing is over q.

    Each ray counts with the point-to-point kernel w_x w_y cos_x cos_y / d^2, as the matrix
    solvers' estimator weights its rays (form_factors.raycast.RayCastSettings): a target behind the
    point's horizon (a floor element running under the block it meets) carries no weight instead
    of counting as blocked. The random shift makes every (point, target) pair equally likely, so
    the estimate's expectation is the kernel-weighted share over all of p x q. Pairing matching
    points always (a thin, aligned slice of p x q) left the Cornell box 2-5% too dark against
    Cycles; every pair (4x the rays) measured about as accurate as the random pairing: Cornell
    box 1.1-2.7% against 1.2-3.2% dark, a block on a floor within 1.2% and 0.8%, for about 1.4x
    the bake time (bench/radiosity.py). Links where no ray has weight keep their factor.
    """
    points, weights = sample_patches(tree.corners[p], side, "midpoint")  # (L, S, 3), (L, S)
    targets, target_weights = sample_patches(tree.corners[q], side, "midpoint")
    count = side * side
    pick = (np.arange(count)[None, :] + shift[:, None]) % count  # (L, S): each point's target
    targets = np.take_along_axis(targets, pick[:, :, None], axis=1)
    target_weights = np.take_along_axis(target_weights, pick, axis=1)
    cast = (np.arange(count)[None, :] - first[:, None]) % count < rays[:, None]  # (L, S)
    return (yield from paired_share_steps(points, tree.normals[p][:, None, :], targets,
                                          tree.normals[q][:, None, :],
                                          weights * target_weights * cast, ray_offset))


def _levels(tree: _Tree) -> list[np.ndarray]:
    """The elements of each level of `tree`, roots first (refined leaves sit on any level)."""
    return [np.flatnonzero(tree.level == k) for k in range(int(tree.level.max()) + 1)]


def _pull(tree: _Tree, b: np.ndarray, levels: list) -> None:
    """Inner elements' B as the area-weighted mean of their four children's, bottom-up, in place
    (a parent's area is its children's sum: midpoint splits tile it)."""
    for e in levels[-2::-1]:
        e = e[tree.child[e] >= 0]  # refined leaves sit on any level
        kids = tree.child[e][:, None] + np.arange(4)  # (M, 4)
        area = tree.areas[kids]
        b[e] = np.einsum("mk,mkc->mc", area, b[kids]) / area.sum(axis=1)[:, None]


def solve_links(tree: _Tree, leaves: np.ndarray, p: np.ndarray, q: np.ndarray, factor: np.ndarray,
                source: np.ndarray, reflectance: np.ndarray, tolerance: float,
                max_iterations: int) -> tuple[np.ndarray, int, float]:
    """Jacobi iteration on the leaves with pull. source, reflectance (E, 3) per element (used on
    the leaves). Returns (B (E, 3), iterations, last error bound relative to the reflected light).

    Stopping rule (solvers.py's bound): the sweep contracts by c = max rho_p sum_q F_pq < 1
    in the max norm, so after a sweep that changed B by d the remaining error is at most
    c / (1 - c) d. It stops when that is at most `tolerance` x the largest reflected radiosity
    max |B - source|: measured against an emitter's B instead (30x brighter in the Cornell box),
    the walls stopped 1-2% short.
    """
    levels = _levels(tree)
    b = np.zeros((len(tree), 3))
    b[leaves] = source[leaves]
    _pull(tree, b, levels)
    row_sums = np.bincount(p, factor, minlength=len(tree))[leaves]
    contraction = float((reflectance[leaves] * row_sums[:, None]).max(initial=0.0))
    if contraction >= 1.0:
        raise ValueError(f"the links reflect more than they receive (rho x row sum {contraction:.3f})")
    fallback = max(float(np.abs(source).max(initial=0.0)), 1e-300)  # nothing reflects yet
    bound = np.inf
    for iteration in range(1, max_iterations + 1):
        gathered = np.stack([np.bincount(p, factor * b[q, c], minlength=len(tree))
                             for c in range(3)], axis=1)
        new = np.zeros_like(b)
        new[leaves] = source[leaves] + reflectance[leaves] * gathered[leaves]
        _pull(tree, new, levels)
        scale = float(np.abs(new[leaves] - source[leaves]).max()) or fallback
        bound = contraction / (1.0 - contraction) * float(np.abs(new - b).max()) / scale
        b = new
        if bound <= tolerance:
            return b, iteration, bound
    return b, max_iterations, bound


class TreeLevels:
    """`levels.Levels` of the hierarchical solver: the leaves of the hierarchy over `roots`
    (`hierarchy_roots` of the scene at the patch size asked for, `depth` levels below them).

    Every level links its leaves afresh (`_link`) and solves the links (`solve_links`); leaves
    are refined as the matrix solvers refine their patches (`refine.refine_splits`: a corner
    value far from the leaf's own, or a lamp's shadow edge across it). occluded: the BVH's
    shadow-ray query or None; settings: RadiositySettings (link_epsilon, samples_per_side,
    tolerance, seed, cluster_sources, max_patches); scale: m, the scene's diagonal; memory: the
    hierarchy's bound (`planning.hierarchical_memory`), for the figures."""

    def __init__(self, scene: Scene, roots: patching.Patches, depth: int, occluded,
                 settings: RadiositySettings, scale: float, memory: dict) -> None:
        self.scene, self.roots, self.depth = scene, roots, depth
        self.occluded, self.settings, self.scale, self.memory = occluded, settings, scale, memory
        self.tree = _Tree(scene, roots)
        for _ in range(depth):
            self.tree.split(np.flatnonzero(self.tree.child < 0))
        self.fresh = np.flatnonzero(self.tree.child < 0)  # leaves no shadow-edge test has seen
        self.leaves = self.fresh

    @property
    def count(self) -> int:
        return int(np.count_nonzero(self.tree.child < 0))

    def untested(self) -> patching.Patches:
        return self.tree.patches(self.scene, self.fresh)

    def split_untested(self, mask: np.ndarray) -> None:
        first_kid = len(self.tree)
        self.tree.split(self.fresh[mask])
        self.fresh = np.arange(first_kid, len(self.tree))

    def patches(self) -> patching.Patches:
        self.leaves, _, leaf_patches = self.tree.leaf_patches(self.scene)
        return leaf_patches

    def refine(self, mask: np.ndarray) -> None:
        self.tree.split(self.leaves[mask])

    def solve_steps(self, light: LevelLight) -> Steps[LevelSolution]:
        """Link and solve the leaves of `patches()` lit by `light` (per leaf)."""
        tree, leaves, settings = self.tree, self.leaves, self.settings
        spread = light_spread(tree, leaves, light.reflectance * light.direct)
        links = yield from scaled(_link(tree, len(self.roots), leaves, self.occluded, settings,
                                        self.scale, spread), 0.0, 0.9)
        source = np.zeros((len(tree), 3))  # only the leaves' are read
        source[leaves] = light.sources
        reflectance = np.zeros((len(tree), 3))
        reflectance[leaves] = light.reflectance
        b, iterations, change = solve_links(tree, leaves, links.p, links.q, links.factor, source,
                                            reflectance, settings.tolerance, MAX_ITERATIONS)
        yield 1.0
        return LevelSolution(b[leaves], {
            "leaves": int(leaves.size), "links": int(len(links.p)),
            "near_field_links": int(links.near.sum()), "clustered_links": links.clustered_links,
            "cluster_groups": links.cluster_groups, "iterations": iterations,
            "solver_error": change})

    def stats(self, levels: list[dict]) -> dict:
        last = levels[-1]
        info = {"roots": len(self.roots), "depth": self.depth, "elements": len(self.tree),
                "leaves": last["leaves"], "links": last["links"],
                "all_pairs": last["leaves"] ** 2, "near_field_links": last["near_field_links"],
                "iterations": last["iterations"], "solver_error": last["solver_error"],
                "converged": bool(last["solver_error"] <= self.settings.tolerance),
                "refinement_levels": len(levels) - 1, "per_refinement": levels}
        return {"solver": "hierarchical",
                # bounded before linking, and as made
                "memory_estimate": {**self.memory, "links_made": info["links"]},
                "method": "raycast",
                "max_patches": self.settings.max_patches,  # lowered by auto to fit the memory limit
                "hierarchy": info,
                "levels": [{"patches": level["leaves"], "solver": "hierarchical",
                            "iterations": level["iterations"],
                            "solver_error": level["solver_error"],
                            "converged": bool(level["solver_error"] <= self.settings.tolerance)}
                           for level in levels]}


@dataclass(frozen=True, eq=False)
class Links:
    """Every leaf's links p <- q (L of them): leaf p gathers from element q."""

    p: np.ndarray  # (L,) int64 receiving leaves
    q: np.ndarray  # (L,) int64 source elements
    factor: np.ndarray  # (L,) F_pq with visibility
    near: np.ndarray  # (L,) bool: leaf-to-leaf links above the bound (near field)
    clustered_links: int  # links reached through the source clusters
    cluster_groups: int  # far groups that shared their shadow rays


def _link(tree: _Tree, root_count: int, leaves: np.ndarray, occluded, settings: RadiositySettings,
          scale: float, spread: tuple[np.ndarray, np.ndarray] | None = None) -> Steps[Links]:
    """Link every leaf to the roots and refine the links (`refine_links`; `spread`:
    `light_spread`); yields progress in [0, 1], returns the `Links`.

    Over more than `source_clusters.MIN_ROOTS` roots (and `settings.cluster_sources`), roots far
    from a leaf are reached through `source_clusters`: each takes its disc factor and the
    visible share its group's rays found; the rest take the exact path below."""
    side = settings.samples_per_side
    eps = settings.link_epsilon
    sources = None
    if settings.cluster_sources and root_count > source_clusters.MIN_ROOTS:
        sources = source_clusters.build(tree.corners[:root_count], tree.normals[:root_count],
                                        tree.areas[:root_count])
        # Every leaf's points once, for the walk, the far factors and the group rays.
        leaf_points, leaf_weights = sample_patches(tree.corners[leaves], side, "midpoint")
        row = np.full(len(tree), -1, np.int64)
        row[leaves] = np.arange(len(leaves))
    settled, far = [], []  # exact batches (p, q, F); far batches (group p, node, group, root, F)
    step = max(1, (LINK_CHUNK if sources is None else FAR_LINK_CHUNK) // max(root_count, 1))
    for a in range(0, len(leaves), step):
        chunk = leaves[a : a + step]
        if sources is None:  # every leaf to every root that faces it
            pp = np.repeat(chunk, root_count)
            qq = np.tile(np.arange(root_count), len(chunk))
        else:
            group_p, group_n, pp, qq = source_clusters.far_groups(
                sources, chunk, tree.corners[chunk].mean(axis=1), leaf_points[row[chunk]],
                tree.normals[chunk])
            group, root, f, close = source_clusters.member_links(
                sources, group_p, group_n, leaf_points[row[group_p]], leaf_weights[row[group_p]],
                tree.normals[group_p], tree.areas[:root_count])
            exact = (f > eps) | close  # too bright or too near for the disc form
            pp = np.concatenate([pp, group_p[group[exact]]])
            qq = np.concatenate([qq, root[exact]])
            far.append((group_p, group_n, group[~exact], root[~exact], f[~exact]))
        alive = _facing(tree, pp, qq)
        settled.extend(refine_links(tree, pp[alive], qq[alive], eps, side, spread))
        yield 0.5 * min(a + step, len(leaves)) / len(leaves)
    none = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))  # nothing faces (a floor)
    p, q, factor = (np.concatenate([s[k] for s in settled] + [none[k]]) for k in range(3))
    near = (factor > eps) & (tree.child[q] < 0)
    if near.any():
        factor[near] = _unoccluded(tree, p[near], q[near], NEAR_FIELD_SIDE * side)
    # The far groups of every chunk together, their members' group numbers made global.
    offsets = np.cumsum([0] + [len(g[0]) for g in far])
    group_p, group_n = (np.concatenate([g[k] for g in far] + [none[0]]) for k in range(2))
    group = np.concatenate([g[2] + o for g, o in zip(far, offsets[:-1], strict=True)] + [none[0]])
    root = np.concatenate([g[3] for g in far] + [none[1]])
    far_factor = np.concatenate([g[4] for g in far] + [none[2]])
    if occluded is not None:  # a chunk of links at a time: side^2 rays and kernels per link
        draw = np.random.default_rng(settings.seed)
        shift = draw.integers(0, side * side, len(p))
        first = draw.integers(0, side * side, len(p))
        full = FULL_RAYS_SHARE * eps
        rays = np.clip(np.ceil(side * side * factor / full), 1, side * side).astype(np.int64)
        chunk = max(1, VISIBILITY_RAYS // side**2)
        total = len(p) + len(group_p)
        for a in range(0, len(p), chunk):
            b = a + chunk
            factor[a:b] *= answer_rays(_visible_share_steps(tree, p[a:b], q[a:b], side,
                                                            RAY_OFFSET_REL * scale, shift[a:b],
                                                            first[a:b], rays[a:b]),
                                       occluded, RAYS_PER_CALL)
            yield 0.5 + 0.5 * min(b, len(p)) / total
        # One visible share per far group, for all its roots (sorted by group), from as many
        # rays per point as the group carries link bounds' worth of factor (at most one per
        # root): the rays its roots' own links would have cast where they matter, few where not.
        rng = np.random.default_rng(settings.seed + 1)
        start = np.searchsorted(group, np.arange(len(group_p) + 1))
        carried = np.bincount(group, far_factor, minlength=len(group_p))
        rays = np.clip(np.ceil(carried / eps), 1, np.diff(start)).astype(np.int64)
        share = np.ones(len(group_p))
        before = np.concatenate([[0], np.cumsum(rays)])  # rays of the groups before each
        a = 0
        while a < len(group_p):  # groups of about `chunk` rays at a time
            b = max(a + 1, int(np.searchsorted(before, before[a] + chunk, side="right")) - 1)
            at = row[group_p[a:b]]
            share[a:b] = answer_rays(source_clusters.group_share_steps(
                sources, start[a:b + 1] - start[a], root[start[a]:start[b]],
                far_factor[start[a]:start[b]], leaf_points[at], leaf_weights[at],
                tree.normals[group_p[a:b]], rays[a:b], RAY_OFFSET_REL * scale, rng),
                occluded, RAYS_PER_CALL)
            yield 0.5 + 0.5 * (len(p) + b) / total
            a = b
        far_factor = far_factor * share[group]
    p, q = np.concatenate([p, group_p[group]]), np.concatenate([q, root])
    factor = np.concatenate([factor, far_factor])
    return Links(p, q, capped_rows(p, factor, len(tree)),
                 np.concatenate([near, np.zeros(len(root), bool)]), int(len(root)), int(len(group_p)))


def capped_rows(p: np.ndarray, factor: np.ndarray, count: int) -> np.ndarray:
    """(L,) the links' factors with each receiver's sum scaled down to 1 where it exceeds it.

    A receiver's exact factors to the surfaces around it sum to at most 1 (its hemisphere, seen
    once). The estimates can overshoot where a few rays stand for a link's visibility at close
    range: a 5 mm patch of a ball 2 mm from a box's side and 36 mm over a floor patch that runs
    under the box saw the side at 0.58 and the floor at 0.55 (the rays all met the floor's open
    part), and rho 0.86 times that sum left the solve no contraction. Scaling the row keeps the
    shares between its links."""
    sums = np.bincount(p, factor, minlength=count)
    return factor / np.maximum(sums[p], 1.0)
