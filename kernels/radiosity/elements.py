"""Elements: the indirect light of a coarse radiosity solution gathered at a finer mesh.

Cohen, Greenberg, Immel and Brock ("An efficient radiosity approach for realistic image
synthesis", IEEE CG&A 1986) solve for B on coarse patches and then read the light out on finer
elements: B_e = E_e + rho_e sum_q F_eq B_q, with element-to-patch factors F_eq. The patches'
B already holds every interreflection; one more gather at the elements costs E x N factors
and no solve, and places the light inside each patch where the patch's own value cannot:

    H(x) = sum_q F(x -> q) V(p, q) R_q            (W/m^2, RGB)

at every vertex x of a patch's elements: F the unoccluded point-to-polygon factor
(`element_factors`: exact near q, the disc form far from it), V(p, q) the visible share between
x's patch p and q (`patch_visibility`: VISIBILITY_SIDE^2 shadow rays per pair, patch to patch:
the elements of one patch share it), R_q the radiosity q sends on (the solution's B less the
emission the final gather takes per receiver). The values at the vertices are the elements'
corners: nothing is averaged within a patch, so a corner at a patch's border (a floor's edge
against a wall) takes what it sees there, not the mean of the elements beside it.

It pays where patches are large against how the light varies: the Cornell box at 74 patches
(each block face one quad of two triangles, whose linear interpolation shows the diagonal) goes
from relMSE 0.0101 to 0.0063 against Cycles with 4 elements per patch. What it cannot place is
a source's own variation: q sends its mean B, which a receiver right beside it (a block's foot on
a floor half in its shadow) sees at close range.
Its cost grows as E x N, so `element_levels` splits only while the pairs stay within a budget:
a fine solution takes no elements, and there the patches are small already.
"""

from __future__ import annotations

import numpy as np

from ..geometry.scene import Scene
from . import patches as patching
from .form_factors.closed_forms import disc_form
from .form_factors.point_polygon import point_to_polygon
from .form_factors.rays import RAYS_PER_BATCH, answer_rays
from .form_factors.sampling import sample_patches
from .form_factors.visibility import paired_share_steps

# Element-to-patch pairs the indirect light is gathered over at most (elements times the patches
# that send light). The Cornell box (solve and bake seconds times relMSE against Cycles, which
# Cycles' bake seconds to the same error divide the speed-up by): 74 patches in 4 elements each
# (22k pairs) 1.65 -> 1.08 (relMSE 0.0101 -> 0.0063 for 0.01 s); 176 patches (124k pairs) 1.14 ->
# 1.19, none there: the patches are small enough already.
ELEMENT_PAIRS = 50_000
# Shadow rays per side of the point grids the patch-to-patch visibility pairs: 2 x 2 pairs a patch
# pair. One ray per pair leaves each share 0 or 1: the Cornell box's elements then gather at
# relMSE 0.0102 against 0.0078 with four.
VISIBILITY_SIDE = 2
# Beyond this many times a patch's corner radius (from its centroid) a receiver takes the disc
# form of the factor to it, A cos cos / (d^2 (pi d^2 + A)) (Wallace, Elmquist and Haines 1989;
# exact for a disc of the patch's area seen head on), nearer the exact polygon factor. Random
# well-shaped triangles at 2 radii: the disc form is within 1.6% of the head-on factor at the
# median, 8% at the 99th percentile (tests/kernels/test_elements.py); 3 radii changed the
# Cornell box's relMSE by 0.00008 for twice the factors' seconds.
DISC_FORM_RADII = 2.0
# Element vertices are gathered this fraction of the way in towards their patch's centroid (as
# `final_gather.RECEIVER_INSET` moves receivers): far above the factor's PLANE_EPS, far below any
# detail an element holds.
VERTEX_INSET = 1e-4
# Splits per patch at most: 4 elements, 6 vertices. The Cornell box at 74 patches
# (relMSE against Cycles, and solve + bake seconds): 4 elements 0.00631 in 0.171 s, 16 0.00597
# in 0.188 s, 64 (centroid values) 0.0058 for 0.1 s more: Cycles' bake takes ~1 / error, so 4
# reach each error level soonest.
MAX_LEVELS = 1


def element_levels(receivers: int, sources: int, pair_budget: int) -> int:
    """How many times (at most MAX_LEVELS) to split each of `receivers` patches (4^k elements
    each) so that the element-to-source pairs stay within `pair_budget`; 0: no elements (the
    patches themselves)."""
    k = 0
    while k < MAX_LEVELS and receivers * sources * 4 ** (k + 1) <= pair_budget:
        k += 1
    return k


def patch_visibility(patches: patching.Patches, index: np.ndarray, occluded, offset: float,
                     rng: np.random.Generator) -> np.ndarray:
    """(K, K) symmetric kernel-weighted visible share between the patches `index` (K,): the
    midpoints of a VISIBILITY_SIDE^2 grid on each of a pair, paired at random, one shadow ray a
    pair (`paired_share_steps`, rays lifted `offset` m off both), each pair once. 1 where no
    pair of points faces (nothing to hide). occluded(origins, directions, t_min, t_max) -> (R,)
    bool."""
    points, weights = sample_patches(patches.corners[index], VISIBILITY_SIDE, "midpoint")
    normals = patches.normals[index]
    s = points.shape[1]
    p, q = np.triu_indices(len(index), 1)
    # Each pair ties the first patch's points to a shuffle of the second's.
    shuffle = np.argsort(rng.random((len(p), s)), axis=1)
    y = points[q[:, None], shuffle]
    w = weights[p] * weights[q[:, None], shuffle]
    share = answer_rays(paired_share_steps(points[p], normals[p][:, None], y,
                                           normals[q][:, None], w, offset),
                        occluded, RAYS_PER_BATCH)
    out = np.ones((len(index), len(index)))
    out[p, q] = out[q, p] = share
    return out


def element_factors(points: np.ndarray, normals: np.ndarray, patches: patching.Patches,
                    sources: np.ndarray) -> np.ndarray:
    """(E, S) unoccluded factors F(x -> q) from points (E, 3) m with unit `normals` (E, 3) to
    patches `sources` (S,): exact (`point_to_polygon`) within DISC_FORM_RADII corner radii
    of q's centroid, the disc form beyond."""
    corners = patches.corners[sources]
    centre = corners.mean(axis=1)  # (S, 3)
    radius = np.linalg.norm(corners - centre[:, None], axis=2).max(axis=1)  # (S,) m
    area = patches.areas[sources]
    source_normals = patches.normals[sources]
    # (E, S) through products of (E, 3) and (3, S): no (E, S, 3) differences.
    dist2 = np.maximum((points * points).sum(axis=1)[:, None] + (centre * centre).sum(axis=1)
                       - 2.0 * points @ centre.T, 0.0)
    cos_e = normals @ centre.T - (normals * points).sum(axis=1)[:, None]  # times d
    cos_q = points @ source_normals.T - (source_normals * centre).sum(axis=1)  # times d
    factor = disc_form(dist2, cos_e, cos_q, area)
    e, s = np.nonzero(dist2 < (DISC_FORM_RADII * radius) ** 2)
    # Only where q lies in front of x and reaches above its horizon is the factor not 0 (most
    # near pairs are neighbours in one plane).
    rel = corners[s] - points[e][:, None]  # (P, 3, 3)
    ahead = np.einsum("pc,pc->p", rel[:, 0], source_normals[s]) < 0.0
    above = np.einsum("pkc,pc->pk", rel, normals[e]).max(axis=1) > 0.0
    factor[e, s] = 0.0
    e, s = e[ahead & above], s[ahead & above]
    if e.size:
        factor[e, s] = point_to_polygon(points[e], normals[e], corners[s], source_normals[s])
    return factor


def element_irradiance(scene: Scene, patches: patching.Patches, reflected: np.ndarray,
                       receivers: np.ndarray, levels: int, occluded, offset: float,
                       rng: np.random.Generator) -> tuple[patching.Patches, np.ndarray]:
    """The elements of `patches` and the irradiance the solution sends to their corners (module
    docstring).

    | argument  | shape / range | meaning                                                 |
    |-----------|---------------|---------------------------------------------------------|
    | reflected | (N, 3) W/m^2  | R_q: what each patch sends (B less gathered emission)   |
    | receivers | (N,) bool     | patches whose elements gather (the others' stay 0)      |
    | levels    | >= 1          | midpoint splits of each patch (`element_levels`)        |

    Returns the elements (`patches.subdivided`: 4^levels per patch, patch i's at rows
    i 4^levels ...) and H (E, 3, 3) W/m^2 at their corners: each vertex of a patch's elements is
    gathered once, (2^levels + 1)(2^levels + 2) / 2 of them (6 for 4 elements, 15 for 16),
    with no average to flatten what a corner at the patch's border sees."""
    elements = patching.subdivided(scene, patches, levels)
    per = 4 ** levels
    local = patching.subdivided_template(levels).reshape(-1, 3)  # (per 3, 3) in the patch
    vertices, slot = np.unique(np.rint(local * 2 ** levels).astype(np.int64), axis=0,
                               return_inverse=True)
    # Moved VERTEX_INSET towards the patch's centroid: a vertex on the line where a floor meets a
    # wall lies in the wall's plane, where the factor to the wall is 0, not its limit.
    vertices = (1.0 - VERTEX_INSET) * vertices / 2 ** levels + VERTEX_INSET / 3.0  # (V, 3)
    sources = np.flatnonzero(reflected.max(axis=1) > 0.0)
    rows = np.flatnonzero(receivers)
    h = np.zeros((len(patches), len(vertices), 3))
    if sources.size and rows.size:
        both = np.union1d(rows, sources)  # mostly the same patches: each pair is cast once
        visible = patch_visibility(patches, both, occluded, offset, rng)
        visible = visible[np.searchsorted(both, rows)][:, np.searchsorted(both, sources)]
        points = np.einsum("vk,nkc->nvc", vertices, patches.corners[rows]).reshape(-1, 3)
        normals = np.repeat(patches.normals[rows], len(vertices), axis=0)
        factor = element_factors(points, normals, patches, sources)
        weighted = factor * np.repeat(visible, len(vertices), axis=0)
        h[rows] = (weighted @ reflected[sources]).reshape(len(rows), len(vertices), 3)
    return elements, h[:, slot.ravel()].reshape(len(patches) * per, 3, 3)
