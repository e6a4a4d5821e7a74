"""The emissive triangles a receiver gathers directly (`Emitters`), and their shadowed irradiance
(`emitter_irradiance`):

    H_j(x) = pi L_j F(x -> j) V_j(x),   V_j(x) = sum_s k_s v_s / sum_s k_s,
    k_s = cos(theta_x) cos(theta_s) / d_s^2   at stratified points s of triangle j

F the exact unoccluded point-to-polygon factor, v_s one shadow ray to each stratified point
(`stratified_triangle_points`: equal areas). The first shot (`sources.first_shot`) and the final
gather (`final_gather.py`) both read it; `clear_shafts` finds the patches that see an emitter
whole, whose receivers cast no shadow ray to it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..geometry import shafts
from ..geometry.camera import Strata
from ..geometry.scene import Scene, geometric_normals, triangle_areas, triangle_emission
from ..measure.metrics import REC709_LUMINANCE
from . import patches as patching
from .form_factors.point_polygon import point_to_polygon
from .form_factors.visibility import pair_kernel
from .settings import FinalGatherSettings
from .sheets import back_probes

# Shadow rays to points ON an emitter stop this fraction short of it; the target itself is lifted
# off the emitter by the ray offset along its normal (the BVH's float32 hit distances differ from
# the float64 length by up to ~4e-6 relative, so ending the ray at the surface would hit it).
SHADOW_END_REL = 1e-6
LUMINANCE = np.array(REC709_LUMINANCE)
# What a receiver's rays found about one emitter triangle (`Visibility.emitters`): nothing known
# (or a penumbra), all of it hidden, all of it seen, or it lies behind the receiver's plane.
UNKNOWN, HIDDEN, CLEAR, AWAY = -1, 0, 1, 2


@dataclass(frozen=True, eq=False)
class Emitters:
    """The emissive triangles gathered per receiver."""

    index: np.ndarray  # (K,) int64 scene triangle indices
    triangles: np.ndarray  # (K, 3, 3) float64 world m
    normals: np.ndarray  # (K, 3) float64 unit front normals
    radiance: np.ndarray  # (K, 3) float64 emitted radiance L_e, W/(m^2 sr)
    per_side: np.ndarray  # (K,) int64 n: n x n stratified visibility points each

    def covers(self, triangles: np.ndarray) -> np.ndarray:
        """(M,) bool: which of scene `triangles` (M,) are these emitters (their light reaches
        receivers through `emitter_irradiance`, not through the patches)."""
        return np.isin(triangles, self.index)

    def thinned(self, k: int) -> Emitters:
        """These emitters with ceil(n / k) points per side each: for receivers averaged k x k
        to one value (a lightmap texel's sub-texel points, `bake_targets.box_filter`), whose
        mean then rests on about the n x n rays one receiver casts."""
        return replace(self, per_side=thinned_side(self.per_side, k))


def thinned_side(n, k: int):
    """ceil(n / k): the points per side of n x n shared among k x k receivers averaged to one."""
    return -(-n // max(k, 1))


# An emitter's back side lights the scene only where it faces open space: its probe ray meets
# nothing, or another object farther than this fraction of the emitting object's size
# (sqrt of its emitting area). Nearer (a lamp flush under a ceiling, the Cornell box's 0.1 mm) the
# light is caught in the gap, which patches cannot resolve: lit as open, the ceiling above a lamp
# 2 cm under it made a room 27% too bright; left dark, 12% too dark (Cycles emits both sides).
# Inside a closed emissive mesh the back faces its own object: that light stays inside.
OPEN_BACK_GAP = 0.1


def open_backs(scene: Scene, bvh, offset: float) -> np.ndarray:
    """(T,) bool: emissive triangles whose back side faces open space (OPEN_BACK_GAP): one probe
    ray from each centroid along the back normal, leaving `offset` m off the surface."""
    out = np.zeros(scene.triangle_count, bool)
    emissive = np.flatnonzero(np.any(triangle_emission(scene) > 0.0, axis=1))
    if not len(emissive):
        return out
    tri, t = back_probes(scene, emissive, bvh, offset)
    objects = scene.object_ids[emissive]
    area = np.bincount(objects, weights=triangle_areas(scene.triangles[emissive]),
                       minlength=len(scene.objects))
    size = np.sqrt(area[objects])
    missed = tri < 0
    far = ~missed & (scene.object_ids[np.maximum(tri, 0)] != objects) & (t > OPEN_BACK_GAP * size)
    out[emissive] = missed | far
    return out


def emitters_of(scene: Scene, settings: FinalGatherSettings,
                open_back: np.ndarray | None = None) -> Emitters:
    """Emissive triangles with their share of `emitter_rays` (by power: area x luminance of L_e);
    none when there are more than `max_emitters`.

    open_back (T,) bool (`open_backs`): triangles that also emit from their back side, as Cycles'
    emission does (a lamp quad hanging under a ceiling lights the ceiling with its back), as a
    second emitter: the triangle turned over (corners reversed, normal negated). None: front
    sides only."""
    radiance = triangle_emission(scene)
    tris = scene.triangles.astype(np.float64)
    normals = geometric_normals(scene.triangles)
    power = triangle_areas(scene.triangles) * (radiance @ LUMINANCE)
    keep = np.flatnonzero((power > 0.0) & (np.linalg.norm(normals, axis=1) > 0.0))
    if len(keep) > settings.max_emitters:
        keep = keep[:0]
    share = power[keep] / max(float(power[keep].sum()), 1e-300)
    per_side = np.maximum(1, np.rint(np.sqrt(settings.emitter_rays * share))).astype(np.int64)
    # A back side takes its front's rays: a receiver sees one side of a flat emitter, so the
    # budget per receiver stays `emitter_rays`.
    back = open_back[keep] if open_back is not None else np.zeros(len(keep), bool)
    backs = keep[back]
    return Emitters(np.concatenate([keep, backs]),
                    np.concatenate([tris[keep], tris[backs][:, ::-1]]),
                    np.concatenate([normals[keep], -normals[backs]]),
                    radiance[np.concatenate([keep, backs])],
                    np.concatenate([per_side, per_side[back]]))


def stratified_triangle_points(poly: np.ndarray, m: int, n: int, rng: np.random.Generator
                               ) -> np.ndarray:
    """(m, n^2, 3) points on triangle `poly` (3, 3): m independent sets, one uniform point in each
    cell of an n x n grid on the unit square, mapped by the area-preserving
    (u, v) -> (1 - sqrt u) p0 + sqrt u (1 - v) p1 + sqrt u v p2 (Shirley; every cell maps to an
    equal area, so the points weigh the same and stay stratified)."""
    cell = np.arange(n * n)
    u = (cell // n + rng.random((m, n * n))) / n
    v = (cell % n + rng.random((m, n * n))) / n
    root = np.sqrt(u)[..., None]
    return (1.0 - root) * poly[0] + root * (1.0 - v[..., None]) * poly[1] + root * v[..., None] * poly[2]


def _kernel_sums(jobs: list, occluded, offset: float, rng: np.random.Generator
                 ) -> list[tuple[np.ndarray, np.ndarray]]:
    """For each job (points (m, 3), normals (m, 3), lift (m, 3), triangle `poly` (3, 3), its
    normal nj, n, and None or a (m, n^2) bool mask of the points each receiver takes), rays
    leaving `offset` m along `lift` (the geometric normals; `normals` may be shading normals):
    (seen, total) (m,), the sums of the point-to-point kernel k_s over n x n stratified points s
    of the triangle (those the mask keeps), over the visible ones and over all, for each
    receiver. Every job's shadow rays go to the BVH in one call (a call costs ~2 ms besides its
    rays)."""
    starts, ends, lengths, found = [], [], [], []
    for points, normals, lift, poly, nj, n, mask in jobs:
        y = stratified_triangle_points(poly, len(points), n, rng)
        kernel = pair_kernel(y - points[:, None, :], normals[:, None, :], nj)  # (m, S)
        if mask is not None:
            kernel *= mask
        rays = kernel > 0.0
        origins = points + offset * lift
        seg = ((y + offset * nj) - origins[:, None, :])[rays]  # (R, 3)
        starts.append(np.broadcast_to(origins[:, None, :], y.shape)[rays])
        ends.append(seg)
        lengths.append(np.sqrt(np.einsum("rc,rc->r", seg, seg)))
        found.append((kernel, rays))
    length = np.concatenate(lengths) if jobs else np.zeros(0)
    blocked = np.zeros(len(length), bool)
    if length.size:
        dirs = np.concatenate(ends) / np.maximum(length, 1e-300)[:, None]
        blocked = np.asarray(occluded(np.ascontiguousarray(np.concatenate(starts)),
                                      np.ascontiguousarray(dirs), 0.0,
                                      length * (1.0 - SHADOW_END_REL)), bool)
    out, at = [], 0
    for kernel, rays in found:
        seen = kernel.copy()
        count = int(rays.sum())
        seen[rays] = np.where(blocked[at:at + count], 0.0, kernel[rays])
        at += count
        out.append((seen.sum(axis=1), kernel.sum(axis=1)))
    return out


def _pilot_side(n: int) -> int:
    """The pilot's points per side for a triangle of n x n (`emitter_irradiance`): (n - 1)^2
    from n = 3 on; below that the full set at once, since a pilot of one ray finds every receiver
    wholly lit or wholly hidden and would never send a penumbra on to its n x n."""
    return n - 1 if n >= 3 else n


def emitter_irradiance(emitters: Emitters, points: np.ndarray, normals: np.ndarray, occluded,
                       offset: float, rng: np.random.Generator,
                       share_out: np.ndarray | None = None,
                       clear: np.ndarray | None = None, known: np.ndarray | None = None,
                       states_out: np.ndarray | None = None, lift: np.ndarray | None = None,
                       strata: Strata | None = None) -> np.ndarray:
    """(M, 3) irradiance W/m^2 at points (M, 3) m with unit normals (M, 3) from the emitters,
    shadowed: pi L_j F(x -> j) V_j(x) summed over j (module docstring). share_out (M,), when
    given, receives the visible share of the unshadowed irradiance (luminance; 1 where none
    arrives), from which the first shot finds the patches across an emitter's shadow edge.

    occluded(origins, directions, t_min, t_max) -> (R,) bool is the BVH's shadow-ray query;
    `offset` m lifts ray ends off both surfaces. Adaptive: a pilot of (n - 1)^2 rays per triangle
    first; only receivers that find the triangle partly hidden (a penumbra) get the n x n rays
    as well, so fully lit and fully shadowed receivers cost about half the rays. The pilot can
    miss an occluder thinner than its point spacing seen from the receiver: it takes the light
    as unblocked there.

    clear (M, K) bool, when given: receivers known to see emitter triangle k whole (their patch's
    shaft to it is empty, `clear_shafts`), which take share 1 without rays. known (M, K) int8
    (`Visibility.emitters`) likewise: CLEAR takes share 1, HIDDEN share 0, without rays.
    states_out (M, K) int8, when given, receives what was found (CLEAR, HIDDEN, AWAY, UNKNOWN for
    a penumbra). lift (M, 3), when given: the unit directions the rays leave the points along
    (the faces' geometric normals where `normals` are shading normals); `normals` otherwise.

    strata (stratum (M,) int, m = a^2): the receivers are a x a sub-samples of pixels (a camera
    view's edge pass), which share out each triangle's points: its n x n grid grows to the next
    multiple of a, n' = a ceil(n / a), and a receiver in stratum k takes the points s = k (mod m),
    n'^2 / m of them and no pilot, so a pixel's m sub-samples together cast about one receiver's
    rays (as `Tracer._area_direct` shares an area lamp's). A receiver's own estimate is coarser;
    the pixel's mean holds all n'^2 >= n^2 points.
    """
    lift = normals if lift is None else lift
    out = np.zeros((len(points), 3))
    unshadowed = np.zeros(len(points)) if share_out is not None else None
    states = np.full((len(points), len(emitters.triangles)), UNKNOWN, np.int8)
    if known is not None:
        states[...] = known
    if clear is not None:
        states[clear] = CLEAR
    factors, todo = [], []  # per emitter triangle: its exact factors, the receivers to trace
    for j in range(len(emitters.triangles)):
        poly, nj = emitters.triangles[j], emitters.normals[j]
        factor = point_to_polygon(points, normals, poly[None], nj[None])  # (M,) exact, unoccluded
        factors.append(factor)
        live = np.flatnonzero(factor > 0.0)
        if unshadowed is not None:
            unshadowed[live] += np.pi * factor[live] * (emitters.radiance[j] @ LUMINANCE)
        state = states[live, j]
        seen_whole = live[state == CLEAR]
        out[seen_whole] += np.pi * factor[seen_whole, None] * emitters.radiance[j]
        states[factor <= 0.0, j] = AWAY
        live = live[(state != CLEAR) & (state != HIDDEN)]
        if live.size:
            todo.append((j, live))
    # The pilot of every triangle in one BVH call, then the penumbrae's full sets in another.
    side = 0 if strata is None else math.isqrt(int(strata[1]))  # a of the a x a sub-samples
    if side < 2 or side * side != strata[1]:
        side = 0
    pilots = []
    for j, live in todo:
        n = int(emitters.per_side[j])
        if side:  # shared out: n' x n' points, n' a multiple of a; no pilot
            n = side * -(-n // side)
            mask = np.arange(n * n)[None, :] % strata[1] == strata[0][live, None] % strata[1]
            pilots.append((points[live], normals[live], lift[live], emitters.triangles[j],
                           emitters.normals[j], n, mask))
        else:
            pilots.append((points[live], normals[live], lift[live], emitters.triangles[j],
                           emitters.normals[j], _pilot_side(n), None))
    sums = _kernel_sums(pilots, occluded, offset, rng)
    more, mixed_of = [], []
    for (j, live), (seen, total) in zip(todo, sums, strict=True):
        n = int(emitters.per_side[j])
        mixed = np.flatnonzero((seen > 0.0) & (seen < total)) if not side and \
            _pilot_side(n) < n else np.zeros(0, np.int64)
        mixed_of.append(mixed)
        if mixed.size:
            more.append((points[live[mixed]], normals[live[mixed]], lift[live[mixed]],
                         emitters.triangles[j], emitters.normals[j], n, None))
    extra = iter(_kernel_sums(more, occluded, offset, rng))
    for (j, live), (seen, total), mixed in zip(todo, sums, mixed_of, strict=True):
        if mixed.size:
            more_seen, more_total = next(extra)
            seen[mixed] += more_seen
            total[mixed] += more_total
        share = np.divide(seen, total, out=np.zeros_like(total), where=total > 0.0)
        out[live] += (np.pi * factors[j][live] * share)[:, None] * emitters.radiance[j]
        # A shared-out subset of the points tells no neighbour the triangle's whole visibility.
        states[live, j] = UNKNOWN if side else np.where(
            total <= 0.0, UNKNOWN, np.where(seen >= total, CLEAR,
                                            np.where(seen <= 0.0, HIDDEN, UNKNOWN)))
    if states_out is not None:
        states_out[...] = states
    if share_out is not None:
        np.divide(out @ LUMINANCE, unshadowed, out=share_out, where=unshadowed > 0.0)
        share_out[unshadowed <= 0.0] = 1.0
    return out


def clear_shafts(patches: patching.Patches, emitters: Emitters, bvh, offset: float,
                 min_area: float = 0.0) -> np.ndarray:
    """(N, K) bool: patch i sees emitter triangle k whole, nothing in the shaft between them
    (`shafts.clear_pairs`; slack: the rays' `offset` m). Patches under `min_area` m^2 are not
    tested (False): a shaft costs about as much as the rays of the few receivers such a patch
    holds (a mesh of 16k tiny triangles: 4.8 s of shafts)."""
    n, k = len(patches), len(emitters.triangles)
    out = np.zeros((n, k), bool)
    tested = np.flatnonzero(patches.areas >= min_area)
    if tested.size == 0 or k == 0:
        return out
    a = np.repeat(patches.corners[tested], k, axis=0)
    b = np.tile(emitters.triangles, (tested.size, 1, 1))
    out[tested] = shafts.clear_pairs(a, b, bvh, offset).reshape(tested.size, k)
    return out
