"""Source clusters for the hierarchical solver: far groups of small roots share their shadow rays.

The hierarchical solver's roots are whole scene triangles at least, so a finely tessellated
object brings one root per triangle, and every leaf starts linked to every root that faces it:
shadows.blend (a ball of 960 triangles among 1834 roots, 2659 leaves) made 1.13M links, each with
its facing test, its exact point-to-polygon factor and its shadow ray (3.2 of its 3.6 s of
solve, profiled). Seen from a leaf far away, a bundle of small triangles is blocked or not almost as one
(the observation behind B. Smits, J. Arvo and D. Greenberg, "A clustering algorithm for radiosity
in complex environments", SIGGRAPH 1994). Here only the visibility and the factor's integration
are clustered: every root keeps its own link, its own factor and its own B, so the solve, and its
row sums in a closed box, are those of the solver without clusters.

Tree (`build`). A binary tree over the roots' centroids, each run split at its median along its
widest axis down to single roots. A node holds the roots order[lo:hi], their area-weighted centre
and the radius of a sphere about it holding every corner.

Links (`far_groups`, `member_links`). A pair (leaf p, node C) is "far" when C's radius is at most
SEPARATION of the distance from its centre to the nearest of p's points; then every root m of C
links to p with the disc approximation of its factor (Wallace, Elmquist and Haines 1989, as
`clusters.py` uses),

    F_pm = sum_s w_s A_m cos_s cos_m / (pi d_sm^2 + A_m),

over p's n x n midpoint points s, 0 where either cosine is negative. A root whose factor exceeds
the link bound, or that lies within 8 of its own sizes of a point (NEAR_AREAS), takes the exact
path instead (its link is refined as any other). Near nodes are opened into their two children;
a single root takes the exact path. Nodes wholly behind p's plane are dropped.

Visibility (`group_share_steps`). All of a group's links share one visible share,
sum_m F_m V_m / sum_m F_m, from rays to the centroids of its roots drawn with probability
F_m / F_g: the solver gives a group as many rays per point as it carries link bounds' worth of
factor (at most one per root), so the rays go where the light is.

Measured with the default settings, relMSE against Cycles unchanged:
shadows.blend's solve 3.55 -> 2.02 s (0.00068), env_room.blend's 7.74 -> 7.15 s (0.0239 -> 0.0240;
most of its far roots lie within 8 sizes of the leaves and take the exact path).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .form_factors.closed_forms import disc_form
from .form_factors.visibility import SHADOW_END_REL

# A node is far from a leaf when its radius is at most this share of its centre's distance to
# the leaf's nearest point: its roots then lie within 15 degrees of that direction, and rays to
# a few of them stand for all. (The factors' accuracy rests on the link bound and NEAR_AREAS.)
# shadows.blend: relMSE 0.00068 in 1.82 s of solve; 0.0007 in 1.65 s at 0.5 and 1.61 s at 1
# (the rays follow the factors, so wider groups save little), 0.00068 in 3.44 s without
# (256k-pair chunks of the walk; 2.02 s against 3.55 s at the 64k of FAR_LINK_CHUNK).
SEPARATION = 0.25
# A far root nearer to a leaf's point than this many times its area (d^2 < NEAR_AREAS A: within
# 8 sizes of its own) takes the exact path. In a closed box of 1728 triangles the disc form was
# off by up to 17% for roots on a wall meeting the leaf's, seen at grazing angles, and the row
# sums came out 0.21% low on average (B 2.4% low at rho = 0.9); within 4 sizes: 0.14% (1.5%);
# within 8: 0.03% (0.36%, as without clusters), for 13% more solve on shadows.blend.
NEAR_AREAS = 64.0
# Trees are built only over more roots than this: below it every leaf-root pair takes the exact
# path at a cost no tree saves (the Cornell box has 36 roots).
MIN_ROOTS = 256


@dataclass(frozen=True, eq=False)
class SourceTree:
    """Binary trees over the roots, one per normal cell; node k holds roots order[lo[k]:hi[k]].

    order   (R,) int64    root ids, each node's a contiguous run
    lo, hi  (K,) int64    the node's run in `order`
    left, right (K,) int64  child nodes (-1 for a single root)
    centre  (K, 3) m      area-weighted centroid of the node's roots
    radius  (K,) m        sphere about `centre` holding every corner of its roots
    tops    (1,) int64    the node holding every root, where walks start
    cumulative (R + 1,) m^2  running sum of the roots' areas in `order` (area-weighted picks)
    centroids, normals (R, 3)  the roots' centroids and unit normals, by root id
    """

    order: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    left: np.ndarray
    right: np.ndarray
    centre: np.ndarray
    radius: np.ndarray
    tops: np.ndarray
    cumulative: np.ndarray
    centroids: np.ndarray
    normals: np.ndarray

    def __len__(self) -> int:
        return len(self.lo)


def _runs(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(run number, position) of every position of the runs [lo[k], hi[k]) (K,), run by run."""
    sizes = hi - lo
    run = np.repeat(np.arange(len(lo)), sizes)
    return run, np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes) + lo[run]


def build(corners: np.ndarray, normals: np.ndarray, areas: np.ndarray) -> SourceTree:
    """The tree over roots with corners (R, 3, 3) m, unit normals (R, 3), areas (R,) m^2."""
    count = len(corners)
    centroids = corners.mean(axis=1)
    order = np.arange(count)
    # A binary tree over R roots with single roots at its ends has 2R - 1 nodes.
    size = max(2 * count - 1, 1)
    lo, hi = np.zeros(size, np.int64), np.zeros(size, np.int64)
    left, right = np.full(size, -1, np.int64), np.full(size, -1, np.int64)
    hi[0] = count
    made = 1
    level = np.zeros(1, np.int64)
    while level.size:
        # Split every run of two roots or more at its median along its centroids' widest axis.
        level = level[hi[level] - lo[level] >= 2]
        if not level.size:
            break
        run, at = _runs(lo[level], hi[level])
        c = centroids[order[at]]
        low = np.full((level.size, 3), np.inf)
        high = np.full((level.size, 3), -np.inf)
        np.minimum.at(low, run, c)
        np.maximum.at(high, run, c)
        axis = (high - low).argmax(axis=1)
        key = c[np.arange(len(at)), axis[run]]
        order[at] = order[at][np.lexsort((key, run))]
        mid = (lo[level] + hi[level]) // 2
        kids = made + np.arange(level.size)
        lo[kids], hi[kids] = lo[level], mid
        lo[kids + level.size], hi[kids + level.size] = mid, hi[level]
        left[level], right[level] = kids, kids + level.size
        made += 2 * level.size
        level = np.concatenate([kids, kids + level.size])
    lo, hi, left, right = lo[:made], hi[:made], left[:made], right[:made]
    weighted = np.concatenate([[np.zeros(3)], np.cumsum(areas[order, None] * centroids[order],
                                                        axis=0)])
    cumulative = np.concatenate([[0.0], np.cumsum(areas[order])])
    area = cumulative[hi] - cumulative[lo]
    plain = np.concatenate([[np.zeros(3)], np.cumsum(centroids[order], axis=0)])
    centre = np.where((area > 0.0)[:, None],
                      (weighted[hi] - weighted[lo]) / np.maximum(area, 1e-300)[:, None],
                      (plain[hi] - plain[lo]) / np.maximum(hi - lo, 1)[:, None])
    # Radius: the farthest corner of the node's roots from its centre, every node at once.
    radius = np.zeros(len(lo))
    run, at = _runs(lo, hi)
    reach = np.linalg.norm(corners[order[at]] - centre[run][:, None, :], axis=2).max(axis=1)
    np.maximum.at(radius, run, reach)
    return SourceTree(order, lo, hi, left, right, centre, radius, np.zeros(1, np.int64),
                      cumulative, centroids, normals)


def far_groups(tree: SourceTree, p: np.ndarray, centre: np.ndarray, points: np.ndarray,
               normals: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Walk leaves p (L,) (their centroids (L, 3), the n x n points (L, S, 3) their factors
    integrate over, normals (L, 3)) down the tree from its tops. Returns (group leaves, group
    nodes): the far (leaf, node) pairs, a node far when its radius is at most SEPARATION of its
    centre's distance to the nearest of the leaf's points (whose rays the group shares); and
    (near leaves, near roots): the pairs that reached a single root while near, for the exact
    path. Nodes wholly behind a leaf's plane are dropped."""
    pp = np.repeat(p, len(tree.tops))
    nn = np.tile(tree.tops, len(p))
    row = np.repeat(np.arange(len(p)), len(tree.tops))
    far_p, far_n, near_p, near_q = [], [], [], []
    while pp.size:
        between = tree.centre[nn] - centre[row]
        ahead = np.einsum("lc,lc->l", between, normals[row]) > -tree.radius[nn]
        pp, nn, row, between = pp[ahead], nn[ahead], row[ahead], between[ahead]
        single = tree.hi[nn] - tree.lo[nn] == 1
        near_p.append(pp[single])
        near_q.append(tree.order[tree.lo[nn[single]]])
        pp, nn, row, between = pp[~single], nn[~single], row[~single], between[~single]
        to_points = tree.centre[nn][:, None, :] - points[row]  # (l, S, 3)
        gap = np.sqrt(np.einsum("lsc,lsc->ls", to_points, to_points).min(axis=1))
        far = tree.radius[nn] <= SEPARATION * gap
        far_p.append(pp[far])
        far_n.append(nn[far])
        pp, nn, row = pp[~far], nn[~far], row[~far]
        pp, row = np.tile(pp, 2), np.tile(row, 2)
        nn = np.concatenate([tree.left[nn], tree.right[nn]])
    empty = np.zeros(0, np.int64)
    return (np.concatenate(far_p + [empty]), np.concatenate(far_n + [empty]),
            np.concatenate(near_p + [empty]), np.concatenate(near_q + [empty]))


def member_links(tree: SourceTree, group_p: np.ndarray, group_n: np.ndarray, points: np.ndarray,
                 weights: np.ndarray, normals: np.ndarray, areas: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every root of each far group's node: (group index (M,), root id (M,), disc factor (M,),
    close (M,) bool: the root is nearer to one of the points than NEAR_AREAS times its area
    (d^2): it takes the exact path instead).

    points (L, S, 3), weights (L, S), normals (L, 3): the group leaves' n x n midpoint points
    (L = len(group_p), row g for group g); areas (R,) the roots' areas. Roots of factor 0 (facing
    away, or behind the leaf's points) are left out."""
    sizes = tree.hi[group_n] - tree.lo[group_n]
    group = np.repeat(np.arange(len(group_p)), sizes)
    start = np.repeat(tree.lo[group_n] - np.cumsum(sizes) + sizes, sizes)
    root = tree.order[start + np.arange(sizes.sum())]
    between = tree.centroids[root][:, None, :] - points[group]  # (M, S, 3)
    dist2 = np.einsum("msc,msc->ms", between, between)
    cos_s = np.einsum("msc,mc->ms", between, normals[group])  # times d
    cos_m = -np.einsum("msc,mc->ms", between, tree.normals[root])  # times d
    a = areas[root][:, None]
    factor = np.einsum("ms,ms->m", disc_form(dist2, cos_s, cos_m, a), weights[group])
    close = (dist2 < NEAR_AREAS * a).any(axis=1)
    keep = factor > 0.0
    return group[keep], root[keep], factor[keep], close[keep]


def group_share_steps(tree: SourceTree, start: np.ndarray, root: np.ndarray, factor: np.ndarray,
                      points: np.ndarray, weights: np.ndarray, normals: np.ndarray,
                      rays: np.ndarray, ray_offset: float, rng: np.random.Generator):
    """Generator (asks for shadow rays, `form_factors.rays.RayRequest`): (G,) the visible share of
    each far group seen from its leaf, sum_m F_m V_m / sum_m F_m over its roots m.

    start (G + 1,): group g's roots are root[start[g]:start[g + 1]] with their factors `factor`
    (`member_links`, sorted by group). Each of the leaf's points (G, S, 3) (weights (G, S),
    normals (G, 3)) casts rays[g] rays, each to the centroid of a root drawn with probability
    F_m / F_g, so the mean of the rays' visibility (weighted by w_s) estimates the share; a ray
    whose ends face away from each other (a root partly behind the leaf's horizon) does not
    count."""
    count, side2 = weights.shape
    per_group = rays * side2
    group = np.repeat(np.arange(count), per_group)  # (R,) every ray's group and point
    point = (np.arange(per_group.sum()) - np.repeat(np.cumsum(per_group) - per_group,
                                                    per_group)) % side2
    cumulative = np.concatenate([[0.0], np.cumsum(factor)])
    lo, hi = start[:-1][group], start[1:][group]
    pick = cumulative[lo] + rng.random(len(group)) * (cumulative[hi] - cumulative[lo])
    at = np.clip(np.searchsorted(cumulative, pick, side="right") - 1, lo, np.maximum(hi - 1, lo))
    target = root[np.minimum(at, len(root) - 1)]
    x, nx = points[group, point], normals[group]
    y, ny = tree.centroids[target], tree.normals[target]
    between = y - x
    counts = (np.einsum("rc,rc->r", between, nx) > 0.0) & \
        (np.einsum("rc,rc->r", between, ny) < 0.0) & (hi > lo)
    origin = (x + ray_offset * nx)[counts]
    seg = (y + ray_offset * ny)[counts] - origin
    length = np.sqrt(np.einsum("rc,rc->r", seg, seg))
    seen = np.zeros(len(group))
    if seg.size:
        blocked = yield (origin, seg / np.maximum(length, 1e-300)[:, None],
                         length * (1.0 - SHADOW_END_REL))
        seen[counts] = ~np.asarray(blocked, bool)
    weight = weights[group, point] * counts
    total = np.bincount(group, weight, minlength=count)
    return np.divide(np.bincount(group, weight * seen, minlength=count), total,
                     out=np.ones(count), where=total > 0.0)
