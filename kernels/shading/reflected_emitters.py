"""What glossy lobes show of the emitters along their mirror direction, at a camera's first hit,
when no glossy bounce is left (`reflected_emitters`).

Cycles lights a glossy lobe directly from every light, the world among them, so a metal or a
specular layer shows the sky even in a render that bounces no light (the radiosity model's
glossy bounces 0, the direct model's max bounces 0); a smooth lobe's ray still collects the
emission it meets before the path ends (PATH_RAY_TERMINATE_AFTER_TRANSPARENT, Cycles'
path_state.h). The views that draw no reflections of their own (radiosity, shadow maps) add this
term; the tracer follows mirrors itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.frames import RAY_OFFSET_REL
from ..geometry.scene import Scene, geometric_normals, triangle_emission
from . import lights as light_units
from .glossy_lobe import MEAN_FACTOR, lobe_mean, lobe_points, lobe_rays
from .highlight_spread import NormalFootprint, mirror_sides, sub_normals
from .material_maps import albedo_at, emission_at, metal_f0
from .optics import fresnel_dielectric, reflect
from .specular_layer import (
    MIRROR_ROUGHNESS,
    coat_layer,
    layer_f0,
    layer_tints,
    metal_reflectance,
    metal_tables,
    tinted_albedo,
    view_factors,
    view_tables,
)
from .world_light import horizon_sky, world_lit, world_radiance, world_seen_by

# Rays across a rough lobe of reflectance 1 (`_lobe_sky`), as the tracer's default lobe_rays.
LOBE_RAYS = 8


def ray_offset(scene: Scene) -> float:
    """The rays' start off surfaces, m: RAY_OFFSET_REL of the scene's bounding-box diagonal."""
    flat = scene.triangles.reshape(-1, 3).astype(np.float64)
    return RAY_OFFSET_REL * float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))


def rays_needed(scene: Scene, area_lamps: bool = True) -> bool:
    """Whether `reflected_emitters` can draw anything in `scene`: a glossy lobe (a specular layer,
    a metal, a coat, glass) and something for it to show (the world, emissive triangles,
    `area_lamps`)."""
    glossy = any(m.metallic > 0.0 or m.coat > 0.0 or m.transmission > 0.0
                 or layer_f0(m.ior, m.specular) > 0.0 for m in scene.materials)
    lamps = area_lamps and any(light.kind == "AREA" for light in scene.lights)
    return glossy and (world_lit(scene) or lamps or bool(np.any(triangle_emission(scene) > 0.0)))


def reflected_emitters(scene: Scene, tri: np.ndarray, bary: np.ndarray, mids: np.ndarray,
                       points: np.ndarray, dirs: np.ndarray, geometric: np.ndarray,
                       normals: np.ndarray, bvh, offset: float, area_lamps: bool = True,
                       footprint: NormalFootprint | None = None) -> np.ndarray:
    """(M, 3) radiance W/(m^2 sr) the glossy lobes of surface points send toward a camera from
    what emits: rays along each point's mirror direction or across its lobe.

    | parameter  | shape / range | unit        | meaning                                        |
    |------------|---------------|-------------|------------------------------------------------|
    | tri, bary  | (M,), (M, 3)  |             | the points' triangles and barycentrics         |
    | mids       | (M,)          |             | their materials (`material_maps.hit_materials`)|
    | points     | (M, 3)        | m, world    | the points                                     |
    | dirs       | (M, 3)        | unit        | camera to point                                |
    | geometric  | (M, 3)        | unit        | face normals on the side the camera sees       |
    | normals    | (M, 3)        | unit        | shading normals on that side                   |
    | bvh        | over at least scene.triangles | | the rays' scene (`BVH.intersect`, `occluded`) |
    | offset     | > 0           | m           | the rays' start off the surface                |
    | area_lamps | bool, True    |             | smooth lobes see area lamps (False: a model    |
    |            |               |             | that shrinks them to points, `cycles.direct`)  |
    | footprint  | None          |             | how each point's normal turns across its pixel |
    |            |               |             | or cell (`highlight_spread`): a smooth lobe's  |
    |            |               |             | mirror rays then sweep it (`mirror_sides`)     |

    A rough lobe (roughness at least MIRROR_ROUGHNESS) takes the world's radiance over the lobe
    where its rays escape (`_lobe_sky`: the sky is a light, sampled directly; lamps are the
    views' own highlights). A smooth
    lobe takes what its ray meets first: the world where it escapes, an area lamp, an emissive
    surface's front (its emission texture read at the hit). Weights: the specular layer's albedo
    at the view E(mu) (weight (1 - metallic)(1 - transmission)) and a metal's reflectance at the
    view from its base colour (`specular_layer.metal_reflectance`; weight metallic), both times
    what a coat leaves them; a coat's own (`specular_layer.coat_layer`: weight x its albedo at
    the view), smooth or rough by its own roughness."""
    out = np.zeros((len(tri), 3))
    scene = world_seen_by(scene, "glossy")  # the sky glossy rays see: none where it is hidden
    mats = scene.materials
    lamps = [light for light in scene.lights if light.kind == "AREA" and light.lights_glossy
             ] if area_lamps else []
    emissive = bool(np.any(triangle_emission(scene) > 0.0))
    world = world_lit(scene)
    shown = _Shown(scene, bvh, points + offset * geometric, dirs, normals, geometric, world,
                   lamps, emissive, footprint)
    cos = np.einsum("ij,ij->i", normals, dirs)
    coat = coat_layer(mats, mids, cos)
    # The specular layer and the metal, under the coat if any.
    roughness_m = np.array([m.roughness for m in mats], np.float64)
    smooth_m = roughness_m < MIRROR_ROUGHNESS
    layer_f = np.array([layer_f0(m.ior, m.specular) for m in mats])
    layer_w = np.array([(1.0 - m.metallic) * (1.0 - m.transmission) for m in mats]) * (layer_f > 0.0)
    metal_w = np.array([m.metallic for m in mats], np.float64)
    # glass: its surface reflects by the dielectric Fresnel factor at the view, tinted as the
    # tracer's (entered from outside, n = 1 / IOR)
    glass_w = np.array([(1.0 - m.metallic) * m.transmission for m in mats])
    glass_tint = np.array([np.ones(3) if m.glass_tint is None else m.glass_tint for m in mats],
                          np.float64).reshape(-1, 3)
    glass_eta = np.array([1.0 / max(m.ior, 1.0 + 1e-6) for m in mats])
    rows = np.flatnonzero(((layer_w[mids] > 0.0) | (metal_w[mids] > 0.0) | (glass_w[mids] > 0.0))
                          & shown.sees(smooth_m[mids]))
    if rows.size:
        m = mids[rows]
        weight = layer_w[m][:, None] * tinted_albedo(
            1.0 - view_factors(view_tables(mats, tinted=False), m, cos[rows]), layer_f[m],
            layer_tints(mats)[m])
        glass = np.flatnonzero(glass_w[m] > 0.0)
        if glass.size:
            mg = m[glass]
            weight[glass] += (glass_w[mg] * fresnel_dielectric(cos[rows[glass]], glass_eta[mg])
                              )[:, None] * glass_tint[mg]
        metal = np.flatnonzero(metal_w[m] > 0.0)
        if metal.size:
            t, b = tri[rows[metal]], bary[rows[metal]]
            weight[metal] += metal_w[m[metal]][:, None] * metal_reflectance(
                metal_tables(mats), m[metal], cos[rows[metal]], metal_f0(scene, t, albedo_at(
                    scene, t, b)), roughness_m[m[metal]], smooth_m[m[metal]])
        if coat is not None:
            weight *= coat.under[rows]
        out[rows] = weight * shown.at(rows, smooth_m[m], roughness_m[m], weight)
    if coat is None:
        return out
    # The coat's own reflection, of its roughness.
    coat_rough = np.array([m.coat_roughness for m in mats], np.float64)[mids]
    smooth = coat_rough < MIRROR_ROUGHNESS
    rows = np.flatnonzero((coat.albedo > 0.0) & shown.sees(smooth))
    if rows.size:
        weight = np.repeat(coat.albedo[rows, None], 3, axis=1)
        out[rows] += weight * shown.at(rows, smooth[rows], coat_rough[rows], weight)
    return out


@dataclass(frozen=True, eq=False)
class _Shown:
    """What glossy lobes of points (origins (M, 3) already off their surfaces, camera directions
    (M, 3), shading and geometric normals (M, 3) on the seen side) find along their rays: the
    world (where `world` lights), area `lamps`, emissive surfaces (`emissive`)."""

    scene: Scene
    bvh: object
    origins: np.ndarray
    dirs: np.ndarray
    normals: np.ndarray
    geometric: np.ndarray
    world: bool
    lamps: list
    emissive: bool
    footprint: NormalFootprint | None = None

    def sees(self, smooth: np.ndarray) -> np.ndarray:
        """(K,) bool: lobes, smooth or not (K,), that can find anything."""
        return np.where(smooth, self.world or bool(self.lamps) or self.emissive, self.world)

    def at(self, rows: np.ndarray, smooth: np.ndarray, roughness: np.ndarray, weight: np.ndarray
           ) -> np.ndarray:
        """(K, 3) radiance W/(m^2 sr) the lobes of points `rows` (K,), smooth (K,) bool, of
        Blender roughness (K,) and reflectance `weight` (K, 3), find: a rough one the sky over
        its lobe (`_lobe_sky`); a smooth one what its mirror ray meets first (the world where it
        escapes, an area lamp, an emissive surface's front, its emission texture read at the
        hit)."""
        seen = np.zeros((len(rows), 3))
        rough_rows = np.flatnonzero(~smooth)
        if self.world and rough_rows.size:
            at = rows[rough_rows]
            seen[rough_rows] = _lobe_sky(self.scene, self.bvh, self.origins[at], -self.dirs[at],
                                         self.normals[at], self.geometric[at],
                                         roughness[rough_rows], weight[rough_rows])
        smooth_rows = np.flatnonzero(smooth)
        if smooth_rows.size == 0:
            return seen
        fp = None if self.footprint is None else self.footprint.at(rows[smooth_rows])
        sides = np.ones(len(smooth_rows), np.int64) if fp is None else mirror_sides(fp)
        for side in np.unique(sides):
            part = np.flatnonzero(sides == side)
            at = rows[smooth_rows[part]]
            if side == 1:
                seen[smooth_rows[part]] = self._mirrored(at, self.normals[at])
                continue
            total = np.zeros((len(part), 3))
            for normal in sub_normals(self.normals[at], fp.at(part).own_triangles(), int(side)):
                total += self._mirrored(at, normal)
            seen[smooth_rows[part]] = total / side ** 2
        return seen

    def _mirrored(self, rows: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """(K, 3) what the mirror rays of points `rows` (K,) about unit normals (K, 3) meet
        first: the world where they escape, an area lamp, an emissive surface's front (its
        emission texture read at the hit); 0 where the mirror direction enters the surface."""
        scene, seen = self.scene, np.zeros((len(rows), 3))
        r = reflect(self.dirs[rows], normals)
        up = np.flatnonzero(np.einsum("ij,ij->i", r, self.geometric[rows]) > 0.0)
        if up.size == 0:
            return seen
        origins, r = self.origins[rows[up]], r[up]
        hits = self.bvh.intersect(origins, r)
        missed = hits.tri < 0
        if self.world and missed.any():
            seen[up[missed]] = world_radiance(scene, r[missed])
        # an emissive triangle's front (a radiosity gather's BVH may hold sheets' copies past T)
        own = (hits.tri >= 0) & (hits.tri < scene.triangle_count)
        if self.emissive and own.any():
            k = np.flatnonzero(own)
            hit = hits.tri[k]
            front = np.einsum("ij,ij->i", r[k], geometric_normals(scene.triangles[hit])) < 0.0
            u, v = hits.u[k[front]].astype(np.float64), hits.v[k[front]].astype(np.float64)
            seen[up[k[front]]] += emission_at(scene, hit[front], np.stack([1.0 - u - v, u, v], 1))
        if self.lamps:
            t_hit = np.where(missed, np.inf, hits.t.astype(np.float64))
            seen[up] += light_units.area_lamps_seen(self.lamps, origins, r, t_hit)[0]
        return seen


def _lobe_sky(scene: Scene, bvh, origins: np.ndarray, wo: np.ndarray, normals: np.ndarray,
              geometric: np.ndarray, roughness: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """(N, 3) the world's radiance over rough glossy lobes less what the scene hides of it. Rays
    from origins (N, 3) toward wo (N, 3, unit, to the viewer) about shading normals (N, 3), kept
    above the geometric ones (N, 3), Blender roughness (N,); a lobe of reflectance `weight`
    (N, 3) takes ceil(max(weight) x LOBE_RAYS) rays (a faint specular layer one, a bright metal
    all: the noise left is in proportion to what the lobe shows), across it from GGX's visible
    normals at points hashed from the origins (`glossy_lobe.py`), shared by their shadowing.

    As the tracer's lobes do (`Tracer._lobe_sky_mean`): the sky's mean over the lobe from
    MEAN_FACTOR times as many directions (unoccluded; the world colour itself for a
    uniform world, a map's above the horizon only, where a scene's ground does not hide it),
    less what the rays the scene blocks would have brought of that, plus what the clear rays
    below the horizon bring."""
    count = np.clip(np.ceil(weight.max(axis=1) * LOBE_RAYS), 1, LOBE_RAYS).astype(np.int64)
    which, points = lobe_points(count, origins)
    dirs, g = lobe_rays(normals, wo, geometric, roughness, points, which)
    above = np.flatnonzero(g > 0.0)
    hit = bvh.occluded(origins[which[above]], dirs[above])
    blocked, clear = above[hit], above[~hit]

    if scene.world_texture is None:
        mean = world_radiance(scene, np.zeros((len(origins), 3)))
    else:
        mean, _ = lobe_mean(lambda d: horizon_sky(scene, d), normals, wo, geometric, roughness,
                            count * MEAN_FACTOR, origins)
    total = np.bincount(which, g, minlength=len(origins))
    share = g / np.maximum(total, 1e-300)[which]
    # Each ray's difference from the control: what it brings (the sky if clear, 0 if blocked)
    # less the control along it (0 for a clear ray above the horizon).
    rest = np.zeros((len(origins), 3))
    np.add.at(rest, which[blocked], -share[blocked, None] * horizon_sky(scene, dirs[blocked]))
    if scene.world_texture is not None:
        low = clear[dirs[clear, 2] <= 0.0]
        np.add.at(rest, which[low], share[low, None] * world_radiance(scene, dirs[low]))
    # A few rays that meet a wall before the brightest sky can take more of it away than the
    # mean holds: no light is negative.
    return np.where((total > 0.0)[:, None], np.maximum(mean + rest, 0.0), 0.0)
