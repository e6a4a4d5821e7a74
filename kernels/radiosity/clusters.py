"""Clustered radiosity: the patches of finely tessellated meshes solved as a few groups.

Patches are whole scene triangles at least, so a finely tessellated mesh brings one patch per
triangle. The Cornell box with a subdivided head of 15.7k triangles has 16k patches. The matrix
solvers' cost then grows as N^2, and so does the hierarchical solver's, which starts every leaf
linked to every root. auto would hand it to progressive refinement: 115 s of solve.

Such a head needs no more unknowns than a wall of its size ("model no more than a scene needs").
`group_patches` keeps every patch, but puts those smaller than CLUSTER_AREA_SHARE of a patch of
the size asked for into groups. A group holds patches of one object, in one cell of a grid the
patch size wide, whose normals fall in the same one of 54 cube-map cells (cones of about 20
degrees, so a group never mixes the two sides of a thin part, nor a ball's lit top with its
unlit underside). Every other patch is a group of its own (a "lone"
group). The system is solved for each group's area-weighted mean B:

    B_G = S_G + rho_G sum_H F_GH B_H,    S_G, rho_G: area means of the members' S_p, rho_p

Each patch then gets its own B_p = S_p + rho_p sum_H F_GH B_H, its own emission, direct light
and reflectance, and the indirect light of its group. The final gather adds exact direct light
at every receiver (`final_gather.py`), so a cluster's shared indirect light is all it smooths.

Factors between groups, F_GH = sum_s w_s F(x_s -> H) V_s(H):
* x_s, w_s are receiver points of G. A lone patch has n x n midpoints, as in the ray-cast rows.
  A cluster has the centroids of CLUSTER_POINTS members, drawn with probability proportional to
  area. The draw is systematic sampling along the cumulative area, in mesh order, so each point
  weighs 1 / CLUSTER_POINTS and the points spread over the cluster.
* F(x -> H), unoccluded. For a lone patch it is the exact point-to-polygon factor. For a cluster
  it is the sum over its members q of Wallace's disc approximation,
  A_q cos_x cos_q / (pi d^2 + A_q) (Wallace, Elmquist and Haines, "A ray tracing algorithm for
  progressive radiosity", SIGGRAPH 1989), which stays bounded as d -> 0. Members nearer than
  NEAR_AREAS times their area (d^2) take the exact point-to-polygon factor instead.
* V_s(H) is the kernel-weighted visible share, from VISIBILITY_RAYS shadow rays from x_s to
  receiver points of H, drawn by their weights (the estimator of
  `form_factors.raycast.RayCastSettings`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..measure.metrics import REC709_LUMINANCE
from ..progress import Steps
from . import patches as patching
from .form_factors.point_polygon import point_to_polygon
from .form_factors.rays import answer_rays
from .form_factors.sampling import sample_patches
from .form_factors.visibility import paired_share_steps
from .solvers import GaussSeidelSettings, GaussSeidelSolver

# A patch whose area is under this share of size^2 (size: the patch edge asked for) is clustered.
# A patch cut from a large triangle has an area of about size^2 / 4; 1/16 of size^2 is a
# triangle about four times finer than asked for along each edge, too fine to be an unknown.
CLUSTER_AREA_SHARE = 1.0 / 16.0
# Cells per side of each cube-map face that sorts normals into groups: 54 directions, cones of
# about 20 degrees. A group shares one indirect irradiance, so its members should face alike:
# shadows.blend's ball (960 triangles, one grid cell) baked with relMSE 0.067 against Cycles at
# 24 directions (2 cells), 0.035 at 54 (3), 0.027 with every triangle a patch.
NORMAL_CELLS = 3
# Coarse groups (`group_patches(coarse=True)`, where auto has no other solver than a matrix over
# more patches than AUTO_MATRIX_MAX_PATCHES): an object less than this share of the patch size
# across (no larger than a patch cut from a large triangle, about half the size asked for) is
# grouped by the six cube faces alone, whichever grid cells its parts fall in: the solve
# resolves indirect light no finer than a patch. 240 bevelled cubes (62 triangles, 0.25 patch
# sizes across, 10k patches) made 4181 groups at 54 directions, 13 per cube, too many to
# cluster: progressive refinement ran over 7 minutes, the clustered solve 216 s. Where the
# hierarchy can run it stays: a glTF robot clustered so baked 1.48e-2 against its 9.7e-3.
SMALL_OBJECT_SHARE = 0.5
# Nor does a group mix a refinement's children (patches split across a shadow edge, level > 0)
# whose direct irradiance, known once the lamps have shot, lies in different octaves below the
# brightest patch's, down to this many; darker and unlit ones have buckets of their own
# (`light_bucket`). The splits are there to tell lit from shadowed ground, and a group that put
# them together again gave them one mean B: shadows.blend's ball, whose underside sees the
# ground around its shadow, baked 3x too bright there (relMSE 0.0068 -> 0.0020 at a 50-patch
# budget). First meshings keep their groups: a finely tessellated head under an area light,
# split by light as well, took 60% longer and baked no better.
LIGHT_OCTAVES = 12
# Receiver points of a cluster (member centroids); a lone patch has the n x n of the settings.
CLUSTER_POINTS = 8
# A member nearer to the receiver point than this many times its area (d^2 < NEAR_AREAS A_q,
# d < 4 member sizes) takes the exact point-to-polygon factor. There the disc approximation is
# off by more than ~5% (it sees the member as a disc facing the point).
NEAR_AREAS = 16.0
# Shadow rays per (receiver point, group) pair.
VISIBILITY_RAYS = 2
# (receiver point, member) pairs evaluated at once: a (pairs, 3) float64 temporary of 48 MB and a
# few (pairs,) ones of 16 MB.
PAIR_CHUNK = 1 << 21
# Shadow rays per BVH call (the BVH reaches its full rate from about 50k).
RAYS_PER_CALL = 1 << 18
# auto clusters only when that cuts the unknowns fourfold at least. Sharing a group's indirect
# light costs accuracy: shadows.blend (1834 patches, 1020 of them a ball's) clustered into 848
# groups baked with relMSE 0.0026 in 3.0 s against the hierarchical solver's 0.0021 in 3.5 s.
AUTO_MAX_GROUP_SHARE = 0.25


@dataclass(frozen=True, eq=False)
class Groups:
    """A partition of N patches into G groups.

    of_patch (N,) int64   group of each patch
    members  (N,) int64   patch indices ordered by group (then by patch index)
    starts   (G + 1,)     members[starts[g]:starts[g + 1]] are group g's patches
    """

    of_patch: np.ndarray
    members: np.ndarray
    starts: np.ndarray

    @property
    def count(self) -> int:
        return len(self.starts) - 1

    @property
    def sizes(self) -> np.ndarray:
        return np.diff(self.starts)

    @property
    def lone(self) -> np.ndarray:
        """(G,) bool: groups of a single patch."""
        return self.sizes == 1


def group_patches(patches: patching.Patches, size: float,
                  direct: np.ndarray | None = None, coarse: bool = False,
                  pooled: bool = False) -> Groups:
    """Patches under CLUSTER_AREA_SHARE x size^2 m^2 grouped by object, cell of a grid `size` m
    wide (by centroid), the cube-map cell their normal points into and, when their direct
    irradiance (N, 3) W/m^2 is given, its octave (`light_bucket`); every other patch alone
    (module docstring). `coarse`: objects under SMALL_OBJECT_SHARE x size across by the six
    cube faces alone, in one cell; `pooled` (with coarse): such objects whose centres share a
    cell share its six groups."""
    count = len(patches)
    small = patches.areas < CLUSTER_AREA_SHARE * size * size
    keys = np.zeros((count, 7), np.int64)
    keys[:, 0] = ~small  # lone patches sort after the clusters
    keys[~small, 1] = np.flatnonzero(~small)
    if small.any():
        centroid = patches.corners[small].mean(axis=1)
        object_ids = patches.object_ids[small]
        lo, hi = _object_boxes(patches)
        tiny = np.linalg.norm(hi - lo, axis=1)[object_ids] < SMALL_OBJECT_SHARE * size
        tiny &= coarse
        cells = np.floor(centroid / max(size, 1e-300)).astype(np.int64)
        # a tiny object is one cell of the grid, wherever its parts fall; pooled, the cell of its
        # centre, which other tiny objects there share (object id -1)
        own = (np.floor((lo + hi)[object_ids] * 0.5 / max(size, 1e-300)).astype(np.int64)
               if pooled else 0)
        keys[small, 1] = np.where(tiny & pooled, -1, object_ids)
        keys[small, 2:5] = np.where(tiny[:, None], own, cells)
        keys[small, 5] = np.where(tiny, normal_bucket(patches.normals[small], 1),
                                  normal_bucket(patches.normals[small]))
        keys[small, 6] = -1
        split = small & (patches.level > 0)
        if direct is not None and split.any():
            keys[split, 6] = light_bucket(direct[split])
    _, of_patch = np.unique(keys, axis=0, return_inverse=True)
    of_patch = of_patch.reshape(-1).astype(np.int64)
    members = np.argsort(of_patch, kind="stable")
    starts = np.searchsorted(of_patch[members], np.arange(of_patch.max(initial=-1) + 2))
    return Groups(of_patch, members, starts.astype(np.int64))


def light_bucket(direct: np.ndarray) -> np.ndarray:
    """(M,) int64 the octave of each patch's direct irradiance (M, 3) W/m^2 (luminance) below
    the brightest's: 0 .. LIGHT_OCTAVES, and LIGHT_OCTAVES + 1 for unlit patches."""
    lum = direct @ np.asarray(REC709_LUMINANCE)
    top = max(float(lum.max(initial=0.0)), 1e-300)
    octave = np.floor(-np.log2(np.maximum(lum / top, 2.0 ** -LIGHT_OCTAVES)))
    return np.where(lum > 0.0, octave, LIGHT_OCTAVES + 1).astype(np.int64)


def _object_boxes(patches: patching.Patches) -> tuple[np.ndarray, np.ndarray]:
    """(objects, 3) twice: the low and high corners (m) of each object's patches' bounding box,
    by object id (an id no patch has: a point box at the origin)."""
    count = int(patches.object_ids.max(initial=-1)) + 1
    lo = np.full((count, 3), np.inf)
    hi = np.full((count, 3), -np.inf)
    np.minimum.at(lo, patches.object_ids, patches.corners.min(axis=1))
    np.maximum.at(hi, patches.object_ids, patches.corners.max(axis=1))
    empty = lo[:, 0] > hi[:, 0]
    lo[empty] = hi[empty] = 0.0
    return lo, hi


def normal_bucket(normals: np.ndarray, cells: int = NORMAL_CELLS) -> np.ndarray:
    """(M,) int64 the cube-map cell unit normals (M, 3) point into: the face of their largest
    component (six), then cells x cells cells of that face's (s, t) square (ids below
    6 x NORMAL_CELLS^2 at any cells up to NORMAL_CELLS)."""
    axis = np.abs(normals).argmax(axis=1)
    rows = np.arange(len(axis))
    major = normals[rows, axis]
    face = 2 * axis + (major < 0.0)
    s = normals[rows, (axis + 1) % 3] / np.abs(major)  # in [-1, 1]
    t = normals[rows, (axis + 2) % 3] / np.abs(major)
    cell = lambda c: np.minimum(((c + 1.0) * 0.5 * cells).astype(np.int64),  # noqa: E731
                                cells - 1)
    return (face * cells + cell(s)) * cells + cell(t)


def receiver_points(patches: patching.Patches, groups: Groups, side: int
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(G, P, 3) points, (G, P, 3) unit normals and (G, P) weights (summing to 1 per group; 0 pads
    a group with fewer points): a lone patch's side x side midpoints, a cluster's CLUSTER_POINTS
    member centroids drawn by area (module docstring)."""
    g = groups.count
    width = max(side * side, CLUSTER_POINTS)
    points = np.zeros((g, width, 3))
    normals = np.zeros((g, width, 3))
    weights = np.zeros((g, width))
    lone = np.flatnonzero(groups.lone)
    if lone.size:
        patch = groups.members[groups.starts[lone]]
        pts, w = sample_patches(patches.corners[patch], side, "midpoint")
        points[lone, : side * side] = pts
        normals[lone, : side * side] = patches.normals[patch][:, None, :]
        weights[lone, : side * side] = w
    many = np.flatnonzero(~groups.lone)
    if many.size:
        area = patches.areas[groups.members]
        cumulative = np.cumsum(area)
        before = np.concatenate([[0.0], cumulative])[groups.starts[many]]  # (C,)
        total = cumulative[groups.starts[many + 1] - 1] - before
        at = before[:, None] + (np.arange(CLUSTER_POINTS) + 0.5) / CLUSTER_POINTS * total[:, None]
        pick = np.searchsorted(cumulative, at, side="right")
        pick = np.clip(pick, groups.starts[many, None], groups.starts[many + 1, None] - 1)
        patch = groups.members[pick]  # (C, CLUSTER_POINTS)
        points[many, :CLUSTER_POINTS] = patches.corners[patch].mean(axis=2)
        normals[many, :CLUSTER_POINTS] = patches.normals[patch]
        weights[many, :CLUSTER_POINTS] = 1.0 / CLUSTER_POINTS
    return points, normals, weights


def _unoccluded(patches: patching.Patches, groups: Groups, x: np.ndarray, nx: np.ndarray
                ) -> np.ndarray:
    """(M, G) unoccluded F(x -> H) from points x (M, 3), unit normals nx (M, 3), to every group
    (module docstring: exact for lone patches and near members, the disc approximation else)."""
    out = np.zeros((len(x), groups.count))
    lone = np.flatnonzero(groups.lone)
    if lone.size:
        patch = groups.members[groups.starts[lone]]
        step = max(1, PAIR_CHUNK // (16 * lone.size))
        for a in range(0, len(x), step):
            out[a:a + step, lone] = point_to_polygon(
                x[a:a + step, None], nx[a:a + step, None], patches.corners[patch][None],
                patches.normals[patch][None])
    many = np.flatnonzero(~groups.lone)
    if not many.size:
        return out
    # Members of clusters, in group order, and where each cluster's run of them starts.
    member = groups.members[~groups.lone[groups.of_patch[groups.members]]]
    owner = groups.of_patch[member]
    run_starts = np.flatnonzero(np.concatenate([[True], owner[1:] != owner[:-1]]))
    normal = patches.normals[member]
    area = patches.areas[member]
    # Relative to the members' mean, so the products below lose no digits to the scene's offset.
    origin = patches.corners[member].mean(axis=(0, 1))
    centroid = patches.corners[member].mean(axis=1) - origin
    c2 = np.einsum("qc,qc->q", centroid, centroid)
    cn = np.einsum("qc,qc->q", centroid, normal)
    step = max(1, PAIR_CHUNK // len(member))
    for a in range(0, len(x), step):
        xa, na = x[a:a + step] - origin, nx[a:a + step]
        # The (m, Q) dot products as matrix products: d = c_q - x, d.d = c.c - 2 x.c + x.x,
        # d.n_x = c.n_x - x.n_x, d.n_q = c.n_q - x.n_q (no (m, Q, 3) array of differences).
        d2 = c2[None] - 2.0 * (xa @ centroid.T) + np.einsum("mc,mc->m", xa, xa)[:, None]
        np.maximum(d2, 0.0, out=d2)
        # Rounding can leave a coincident pair a tiny d: its cosines are clipped (it is a near
        # pair, whose exact factor replaces this one below), a zero one gives 0.
        d = np.sqrt(d2)
        d[d == 0.0] = np.inf
        cos_x = np.clip((na @ centroid.T - np.einsum("mc,mc->m", xa, na)[:, None]) / d, -1.0, 1.0)
        cos_q = np.clip((xa @ normal.T - cn[None]) / d, -1.0, 1.0)
        f = np.where((cos_x > 0.0) & (cos_q > 0.0),
                     area * cos_x * cos_q / (np.pi * d2 + area), 0.0)
        rows, cols = np.nonzero(d2 < NEAR_AREAS * area)
        if rows.size:
            f[rows, cols] = point_to_polygon(x[a:a + step][rows], na[rows],
                                             patches.corners[member[cols]], normal[cols])
        out[a:a + step, many] = np.add.reduceat(f, run_starts, axis=1)
    return out


def factor_steps(patches: patching.Patches, groups: Groups, side: int, ray_offset: float,
                 occluded, rng: np.random.Generator, out: np.ndarray | None = None
                 ) -> Steps[np.ndarray]:
    """Generator: yields progress in [0, 1] and returns the (G, G) group factors F_GH (module
    docstring); `out` receives them when given. occluded(origins, directions, t_min, t_max) ->
    (R,) bool is the BVH's shadow-ray query (None: nothing occludes)."""
    points, normals, weights = receiver_points(patches, groups, side)
    g, width = weights.shape
    live = np.flatnonzero(weights.ravel() > 0.0)  # (M,) flat receiver points
    x, nx = points.reshape(-1, 3)[live], normals.reshape(-1, 3)[live]
    f = _unoccluded(patches, groups, x, nx)  # (M, G)
    yield 0.3
    if occluded is not None:
        # Each (point, group) pair with a factor casts VISIBILITY_RAYS rays to points of the
        # group drawn by weight, each counted with the point-to-point kernel.
        cumulative = np.cumsum(weights, axis=1)
        cumulative /= cumulative[:, -1:]
        pair_point, pair_group = np.nonzero(f > 0.0)
        step = max(1, PAIR_CHUNK // (8 * VISIBILITY_RAYS * width))
        for a in range(0, len(pair_point), step):
            pp, pg = pair_point[a:a + step], pair_group[a:a + step]
            f[pp, pg] *= _visible_share(x[pp], nx[pp], points[pg], normals[pg],
                                        cumulative[pg], ray_offset, occluded, rng)
            yield 0.3 + 0.7 * min(a + step, len(pair_point)) / len(pair_point)
    result = np.zeros((g, g)) if out is None else out
    result[...] = 0.0
    np.add.at(result, live // width, weights.ravel()[live, None] * f)
    yield 1.0
    return result


def _visible_share(x, nx, targets, target_normals, cumulative, ray_offset: float, occluded,
                   rng: np.random.Generator) -> np.ndarray:
    """(L,) kernel-weighted visible share from points x (L, 3), normals nx, to VISIBILITY_RAYS
    of each pair's target points (L, P, 3), drawn by their cumulative weights (L, P)."""
    u = rng.random((len(x), VISIBILITY_RAYS))
    pick = np.minimum((u[:, :, None] > cumulative[:, None, :]).sum(axis=2),
                      cumulative.shape[1] - 1)  # (L, R)
    y = np.take_along_axis(targets, pick[:, :, None], axis=1)
    ny = np.take_along_axis(target_normals, pick[:, :, None], axis=1)
    # Targets are drawn by weight, so each ray weighs 1 besides its kernel. A pair whose drawn
    # targets all lie behind one of the two keeps its unoccluded factor.
    return answer_rays(paired_share_steps(x[:, None, :], nx[:, None, :], y, ny, 1.0, ray_offset),
                       occluded, RAYS_PER_CALL)


def group_means(groups: Groups, areas: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(G, C) area-weighted means of per-patch `values` (N, C) over each group."""
    weighted = np.zeros((groups.count, values.shape[1]))
    np.add.at(weighted, groups.of_patch, areas[:, None] * values)
    total = np.bincount(groups.of_patch, areas, minlength=groups.count)
    return weighted / np.maximum(total, 1e-300)[:, None]


def solve_steps(patches: patching.Patches, groups: Groups, sources: np.ndarray,
                reflectance: np.ndarray, factors: np.ndarray, tolerance: float
                ) -> Steps[tuple]:
    """Generator: Gauss-Seidel on the groups' system; yields progress, returns (B per patch
    (N, 3), the solver's `RadiositySolution` over the groups). sources, reflectance (N, 3) per
    patch."""
    s = group_means(groups, patches.areas, sources)
    rho = group_means(groups, patches.areas, reflectance)
    solver = GaussSeidelSolver(factors, s, rho, GaussSeidelSettings(tolerance=tolerance))
    yield from solver.run()
    solution = solver.solution()
    gathered = factors @ solution.radiosity  # (G, 3) what reaches each group
    return sources + reflectance * gathered[groups.of_patch], solution
