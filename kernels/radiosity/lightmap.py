"""The solution baked: outgoing radiance B / pi on lightmap texels and mesh corners (`bake_steps`).

Lightmap texels come from a lattice where the light is smooth (`bake_targets.lattice_plan`), and
the later passes reuse what the earlier passes' rays found around a point
(`final_gather.Visibility`)."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ..bake.bake_targets import (
    TexelFilterSettings,
    apply_box_filter,
    corner_targets,
    dilate,
    filter_samples,
    lattice_fill,
    lattice_plan,
    lightmap_targets,
)
from ..geometry.scene import Scene, triangle_emission
from ..progress import Steps, scaled
from ..shading.direct_light import diffuse_at
from . import final_gather
from .lamps import hard_lamps
from .result import RadiosityResult


@dataclass(frozen=True, eq=False)
class ObjectRadiosityBake:
    """One object's baked outgoing radiance B / pi (W/(m^2 sr), linear RGB)."""

    lightmap: np.ndarray | None  # (S, S, 3) float32, row 0 top, dilated over the padding
    lightmap_mask: np.ndarray | None  # (S, S) bool: texels baked (before dilation)
    corners: np.ndarray  # (T * 3, 3) float32, per triangle corner, scene corner order
    filtered_texels: int = 0  # lightmap texels averaged over sub-texel points (edges)


def gather_groups(scene: Scene, objects, lightmap_sizes: dict) -> list[list[int]]:
    """`objects` (indices into scene.objects) in runs whose points the bake's gather evaluates
    together (`bake_steps`): consecutive objects while their estimated points (lightmap texels
    and corners) stay within `final_gather.GATHER_CHUNK`; a larger object is a run of its own.
    Made from the geometry alone, so a share of the runs (a tile) is baked as the whole bake
    bakes it."""
    groups, points = [], 0
    for k in objects:
        size = lightmap_sizes.get(k, 0) if scene.objects[k].has_lightmap_uv else 0
        need = size * size + 3 * scene.objects[k].tri_count
        if not groups or points + need > final_gather.GATHER_CHUNK:
            groups.append([])
            points = 0
        groups[-1].append(k)
        points += need
    return groups


def bake_steps(scene: Scene, result: RadiosityResult, objects, lightmap_sizes: dict, padding: int,
               texel_filter: TexelFilterSettings = TexelFilterSettings(),  # noqa: B008
               groups: list[list[int]] | None = None) -> Steps[dict[int, ObjectRadiosityBake]]:
    """Radiance B / pi of `objects` (indices into scene.objects) on their lightmap texels (when
    the scene carries lightmap UVs; sizes {object index: texels per side}), box-filtered over the
    texels an edge crosses as Cycles' bake filters them (`bake_targets.box_filter`), and at their
    corners. Yields progress, returns {object index: ObjectRadiosityBake}.

    Every object's points are evaluated together, in three passes: the lightmaps' lattice texels
    and the corners; the texels the lattice cannot give (`bake_targets.lattice_fill`); the edge
    texels' sub-texel points. The later passes reuse what the earlier ones' rays found around a
    point (`final_gather.Visibility`: 10-12% of the bake's seconds on the Cornell box). The
    gather's shadow rays reach the BVH in large batches, and a BVH call costs ~2 ms besides its
    rays (0.6 M rays/s in calls of 2k rays, 1.0 M at 128k on the Cornell box).

    groups: the objects in runs whose points are evaluated together (default `gather_groups`);
    an object's values depend on its run's points only, so a bake of some of the runs (a tile,
    jobs/radiosity.py) gives their objects exactly what the bake of all of them gives."""
    group = {k: g for g, run in enumerate(groups or gather_groups(scene, objects, lightmap_sizes))
             for k in run}
    lightmaps = {k: lightmap_targets(scene, k, lightmap_sizes[k]) for k in objects
                 if scene.lightmap_uv is not None and scene.objects[k].has_lightmap_uv}
    corners = {k: corner_targets(scene, k) for k in objects}
    plans = {k: lattice_plan(t) if texel_filter.lattice_threshold > 0.0 else None
             for k, t in lightmaps.items()}

    def first_of(k):  # the lightmap positions the first pass evaluates
        return np.arange(len(lightmaps[k])) if plans[k] is None else plans[k].first

    parts = [(lightmaps[k].triangles[first_of(k)], lightmaps[k].bary[first_of(k)])
             for k in lightmaps]
    values, seen = yield from scaled(
        _radiance_steps(result, parts + [(c.triangles, c.bary) for c in corners.values()],
                        groups=[group[k] for k in lightmaps] + [group[k] for k in corners]),
        0.0, 0.5)
    centre, todo, texel_seen = {}, {}, {}
    for k, first, found in zip(lightmaps, values[:len(lightmaps)], seen[:len(lightmaps)],
                               strict=True):
        texel_seen[k] = final_gather.Visibility.unknown(len(lightmaps[k]),
                                                        found.emitters.shape[1])
        texel_seen[k].put(first_of(k), found)
        if plans[k] is None:
            centre[k], todo[k] = first, np.zeros(0, np.int64)
        else:
            centre[k], todo[k] = _lattice_radiance(scene, result, lightmaps[k], plans[k], first,
                                                   texel_filter.lattice_threshold)
            _lattice_visibility(plans[k], texel_seen[k])
    rest, seen = yield from scaled(_radiance_steps(
        result, [(lightmaps[k].triangles[todo[k]], lightmaps[k].bary[todo[k]]) for k in lightmaps],
        [texel_seen[k].take(todo[k]) for k in lightmaps], [group[k] for k in lightmaps]), 0.5, 0.3)
    for k, got, found in zip(lightmaps, rest, seen, strict=True):
        centre[k][todo[k]] = got
        texel_seen[k].put(todo[k], found)
    # Hard lamp shadows are steps through texels, which take more points than soft ramps.
    lit = result.gather.scene if result.gather is not None else scene  # with a map's suns
    texel_filter = texel_filter.resolved(hard_edges=bool(hard_lamps(lit)))
    samples = {k: filter_samples(scene, lightmaps[k], centre[k], texel_filter) for k in lightmaps}
    # A texel averages its k x k sub-texel points: each casts about 1 / k^2 of a receiver's
    # shadow rays, and their mean rests on as many as a texel centre's.
    side = texel_filter.samples_per_side
    thinned = result if result.gather is None else replace(result,
                                                           gather=result.gather.thinned(side))
    sampled, _ = yield from scaled(_radiance_steps(
        thinned, [(s.triangles, s.bary) for s in samples.values()],
        [_texel_neighbourhood(lightmaps[k], texel_seen[k], s.which).take(s.owner)
         for k, s in samples.items()], [group[k] for k in samples]), 0.8, 0.2)
    out = {}
    for k, corner_values in zip(corners, values[len(lightmaps):], strict=True):
        lightmap = mask = None
        filtered = 0
        if k in lightmaps:
            texels, filtered = apply_box_filter(centre[k], samples[k], sampled.pop(0))
            mask = lightmaps[k].mask
            lightmap = dilate(lightmaps[k].to_image(texels), mask, padding)
        out[k] = ObjectRadiosityBake(lightmap, mask, corner_values.astype(np.float32), filtered)
    return out


def _lattice_radiance(scene: Scene, result: RadiosityResult, targets, plan, first: np.ndarray,
                      threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """`bake_targets.lattice_fill` of radiance (N, 3) from the lattice's, first (L, 3); returns
    the values and the texels still to evaluate. With the final gather a texel's radiance is
    L_e + rho(x) H(x) / pi, rho sampled at the texel (textures): the lattice interpolates the
    smooth part H / pi and each texel multiplies by its own reflectance, so texture detail between
    lattice texels is kept (irradiance caching caches irradiance, not radiance). Without the
    gather the patches' B is already smooth and is interpolated as it is."""
    if result.gather is None:
        return lattice_fill(plan, first, threshold)
    rho = diffuse_at(scene, targets.triangles, targets.bary)  # (N, 3)
    emitted = triangle_emission(scene)[targets.triangles]  # (N, 3) L_e, W/(m^2 sr)
    f = plan.first
    # Where a lattice texel reflects nothing its H is unknown: 0, which no smooth test passes
    # next to a lit neighbour, so the texels around it are evaluated.
    h = np.divide(first - emitted[f], rho[f], out=np.zeros_like(first), where=rho[f] > 0.0)
    h, todo = lattice_fill(plan, h, threshold)
    values = emitted + rho * h
    values[f] = first
    return values, todo


def _lattice_visibility(plan, seen: final_gather.Visibility) -> None:
    """In place: the `Visibility` of the lattice's other texels (`plan.rest`) from what their
    lattice sources agree on (`Visibility.agreed`; UNKNOWN where the sources are not all on one
    flat piece with the texel, `plan.affine`). seen: every texel's, the lattice's set."""
    sources = np.where(plan.affine[:, None], plan.sources, -1)
    seen.put(plan.rest, seen.agreed(sources))


def _texel_neighbourhood(targets, seen: final_gather.Visibility, which: np.ndarray
                         ) -> final_gather.Visibility:
    """For lightmap texels `which` (positions into `targets`): what the texel and its four
    neighbours in the image agree on (`Visibility.agreed`; a neighbour the image lacks counts as
    the texel itself). A point inside the texel lies among their centres."""
    height, width = targets.mask.shape
    index = np.full((height + 2, width + 2), -1, np.int64)  # a border of -1 around the image
    index[targets.rows + 1, targets.cols + 1] = np.arange(len(targets))
    r, c = targets.rows[which] + 1, targets.cols[which] + 1
    sources = np.stack([index[r, c], index[r - 1, c], index[r + 1, c], index[r, c - 1],
                        index[r, c + 1]], axis=1)
    sources = np.where(sources >= 0, sources, sources[:, :1])
    return seen.agreed(sources)


def _radiance_steps(result: RadiosityResult, parts: list, known: list | None = None,
                    groups: list[int] | None = None) -> Steps[tuple[list, list]]:
    """B / pi at every part (triangles (M,), bary (M, 3)), the parts of one group (`groups`, a
    number per part; default one group) concatenated and evaluated in chunks of
    `final_gather.GATHER_CHUNK` points; yields progress, returns the parts' values [(M, 3)] and
    what the final gather's rays found there [`final_gather.Visibility`] (all UNKNOWN without a
    gather). known: a `Visibility` per part that the gather takes without rays, or None.

    A chunk never spans two groups, and the gather draws its random numbers afresh per chunk: a
    group's values depend on its own points only, so they are the same whichever other groups
    are evaluated beside it (a tiled bake, `jobs/radiosity.py`, bakes a share of them)."""
    groups = [0] * len(parts) if groups is None else list(groups)
    emitters = 0 if result.gather is None else len(result.gather.emitters.triangles)
    total = sum(len(t) for t, _ in parts)
    chunk = final_gather.GATHER_CHUNK
    values, found_all, done = [None] * len(parts), [None] * len(parts), 0
    for g in dict.fromkeys(groups):
        members = [p for p in range(len(parts)) if groups[p] == g]
        tri = np.concatenate([parts[p][0] for p in members])
        bary = np.concatenate([parts[p][1] for p in members])
        given = (final_gather.Visibility.joined([known[p] for p in members])
                 if known is not None else None)
        found = final_gather.Visibility.unknown(len(tri), emitters)
        out = np.zeros((len(tri), 3))
        for a in range(0, len(tri), chunk):
            rows = slice(a, a + chunk)
            out[rows] = result.radiance_at(
                tri[rows], bary[rows], known=None if given is None else given.take(rows),
                visibility_out=found.take(rows))  # views: the gather writes into `found`
            done += len(tri[rows])
            yield done / total
        bounds = np.cumsum([0] + [len(parts[p][0]) for p in members])
        for p, a, b in zip(members, bounds[:-1], bounds[1:], strict=True):
            values[p], found_all[p] = out[a:b], found.take(slice(a, b))
    return values, found_all
