"""The lamps' light with shadow rays: point, spot, sun and area lamps' direct irradiance at surface
points times their visible fraction (BVH shadow rays; area lamps over a grid of emitter points)."""

from __future__ import annotations

import numpy as np

from ..geometry.camera import Strata, strata_rows
from ..geometry.scene import Scene
from ..shading import lights as light_units
from ..shading.bump import relief_shadowing

# Shadow rays stop this fraction short of a point light (it has no surface to hit).
LIGHT_END_REL = 1e-6


class LampShadows:
    """The lamps' shadow-ray query (origins, directions, t_min, t_max) -> (R,) bool: `bvh`'s (an
    object with `occluded`), and for a lamp under shadow linking its own (`own`: Light -> such
    an object, which meets that lamp's blockers alone; `for_light`)."""

    def __init__(self, bvh, own: dict | None = None):
        self.bvh, self.own = bvh, own or {}

    def __call__(self, origins, directions, t_min, t_max) -> np.ndarray:
        return self.bvh.occluded(origins, directions, t_min, t_max)

    def for_light(self, light):
        """The query `light`'s shadow rays take."""
        own = self.own.get(light)
        return self if own is None else own.occluded


def light_query(occluded, light):
    """`occluded` as `light`'s shadow rays take it (`LampShadows.for_light`); itself where it
    is a plain query or None."""
    return occluded.for_light(light) if isinstance(occluded, LampShadows) else occluded


def shadowed_irradiance(light, points: np.ndarray, normals: np.ndarray, origins: np.ndarray,
                        occluded, area_samples_per_side: int,
                        strata: Strata | None = None, direction_weight=None,
                        objects: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(M, 3) direct irradiance W/m^2 of `light` at points with unit normals, times its visible
    fraction from `origins` (the points lifted off their surface), and that fraction (M,): 1 where
    the light does not reach, casts no shadow, or `occluded` is None (no shadows; a
    `LampShadows` takes the light's own query). strata: as `light_visibility`'s;
    direction_weight: as `lights.direct_irradiance`'s; objects (M,): the points' objects, for
    the light's light linking (None: it reaches every point)."""
    e = light_units.direct_irradiance(light, points, normals, direction_weight)
    reach = light_units.receiving(light, objects)
    if reach is not None:
        e *= reach[:, None]
    lit = np.flatnonzero(e.max(axis=1) > 0.0)
    vis = np.ones(len(points))
    if occluded is not None and light.cast_shadow and lit.size:
        vis[lit] = light_visibility(light, origins[lit], light_query(occluded, light),
                                    area_samples_per_side, strata=strata_rows(strata, lit))
    e *= vis[:, None]
    return e, vis


def light_visibility(light, origins: np.ndarray, occluded, area_samples_per_side: int,
                     per_target: bool = False, strata: Strata | None = None
                     ) -> np.ndarray:
    """(R,) visible fraction of `light` from `origins` (area lights: over an n x n emitter grid);
    with `per_target`, (K, R) float: each grid point's own (`area_light_samples` order).

    strata (stratum (R,), m): the origins are m sub-samples of pixels, which share out an area
    light's grid as the tracer's do (`Tracer._area_direct`): where m divides n^2, an origin in
    stratum k sees the points j = k (mod m) only, and the pixel's m sub-samples all of them."""
    if light.kind == "SUN":
        dirs = np.broadcast_to(-np.asarray(light.direction, np.float64), origins.shape)
        return 1.0 - np.asarray(occluded(origins, np.ascontiguousarray(dirs), 0.0, np.inf), float)
    if light.kind == "AREA":
        targets = light_units.area_light_samples(light, area_samples_per_side)
    else:
        targets = np.asarray(light.position, np.float64)[None]
    if (strata is not None and not per_target and light.kind == "AREA"
            and len(targets) % strata[1] == 0):
        m = int(strata[1])  # each origin's own K / m targets, (K / m, R) rows
        targets = targets[strata[0] % m + m * np.arange(len(targets) // m)[:, None]]
    else:
        targets = np.broadcast_to(targets[:, None, :], (len(targets),) + origins.shape)
    # Every (target, origin) ray in one BVH call: a call costs ~2 ms besides its rays, and an
    # area light has n^2 targets.
    delta = (targets - origins[None, :, :]).reshape(-1, 3)  # (K R, 3), target-major
    dist = np.linalg.norm(delta, axis=1)
    dirs = delta / np.maximum(dist, 1e-300)[:, None]
    starts = np.ascontiguousarray(np.broadcast_to(origins, (len(targets),) + origins.shape)
                                  .reshape(-1, 3))
    blocked = np.asarray(occluded(starts, dirs, 0.0, dist * (1.0 - LIGHT_END_REL)), bool)
    seen = (~blocked).reshape(len(targets), -1).astype(np.float64)
    return seen if per_target else seen.mean(axis=0)


def triangle_solid_angles(point: np.ndarray, corners: np.ndarray) -> np.ndarray:
    """(N,) solid angle, sr, of triangles corners (N, 3, 3) world m seen from `point` (3,)
    (Van Oosterom and Strackee 1983: tan(omega / 2) = a.(b x c) / (|a||b||c| + (a.b)|c| +
    (a.c)|b| + (b.c)|a|), a, b, c the corners relative to the point); either side, unsigned."""
    a, b, c = (corners[:, k] - point for k in range(3))
    la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
    triple = np.einsum("ij,ij->i", a, np.cross(b, c))
    den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", a, c) * lb
           + np.einsum("ij,ij->i", b, c) * la)
    return np.abs(2.0 * np.arctan2(triple, den))


def near_lamp_scale(light, corners: np.ndarray, normals: np.ndarray, areas: np.ndarray,
                    weights: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N,) factors that make a point or spot lamp's sampled irradiance over each patch integrate
    exactly: the mean of cos / d^2 over a planar patch is its solid angle from the lamp over its
    area, where n x n sample points of a patch much wider than its distance to the lamp miss the
    peak under the lamp or straddle it (5 cm under 0.5 m patches, 3 x 3 points: -11% or +11% of
    the flux). Shadows and the spot's cone stay those of the samples.

    corners (N, 3, 3) m and normals (N, 3) of the patches, areas (N,) m^2; weights (N, S) of
    their samples (summing to 1), points (N S, 3) m. 1 where the lamp is behind a patch."""
    position = np.asarray(light.position, np.float64)
    delta = (position - points).reshape(len(corners), -1, 3)  # (N, S, 3) towards the lamp
    dist2 = np.maximum(np.einsum("nsj,nsj->ns", delta, delta), light_units.MIN_LIGHT_DISTANCE ** 2)
    cos = np.clip(np.einsum("nsj,nj->ns", delta, normals), 0.0, None) / np.sqrt(dist2)
    sampled = np.einsum("ns,ns->n", weights, cos / dist2)  # mean cos / d^2 by the samples
    in_front = np.einsum("nj,nj->n", position - corners[:, 0], normals) > 0.0
    exact = triangle_solid_angles(position, corners) / np.maximum(areas, 1e-300)
    return np.where(in_front & (sampled > 0.0), exact / np.where(sampled > 0.0, sampled, 1.0),
                    1.0)


def hard_lamps(scene: Scene) -> list:
    """The point, spot and sun lamps that cast shadows on diffuse surfaces: steps, not ramps."""
    return [light for light in shadowing_lamps(scene) if light.kind != "AREA"]


def shadowing_lamps(scene: Scene) -> list:
    """The lamps of every kind (point, spot, sun, area) that cast shadows on diffuse surfaces
    (those that light them: `Light.lights_diffuse`)."""
    return [light for light in diffuse_lamps(scene) if light.cast_shadow]


def diffuse_lamps(scene: Scene) -> list:
    """The lamps that light diffuse surfaces (Cycles' ray visibility: `Light.hidden_from`)."""
    return [light for light in scene.lights if light.lights_diffuse]


def lamp_irradiance(scene: Scene, points: np.ndarray, normals: np.ndarray, occluded, offset: float,
                    area_samples_per_side: int, lift: np.ndarray | None = None,
                    strata: Strata | None = None, smooth: np.ndarray | None = None,
                    objects: np.ndarray | None = None) -> np.ndarray:
    """(M, 3) irradiance W/m^2 of the scene's lamps (point, spot, sun, area) with shadow rays, as
    the radiosity first shot computes it for patch points; rays leave along `lift` (M, 3) when
    given (`emitters.emitter_irradiance`); strata: pixels' sub-samples that share out the area
    lamps' points (`light_visibility`). smooth (M, 3): the normals before a relief tilted them
    to `normals`, whose facets then hide part of a low lamp (`bump.bump_shadowing`, as Cycles
    weighs diffuse light under a Bump or Normal Map). objects (M,): the points' objects, for the
    lamps' light linking."""
    out = np.zeros((len(points), 3))
    origins = points + offset * (normals if lift is None else lift)
    weight = None if smooth is None else relief_shadowing(smooth, normals)
    for light in diffuse_lamps(scene):
        out += shadowed_irradiance(light, points, normals, origins, occluded,
                                   area_samples_per_side, strata, weight, objects)[0]
    return out
