"""What the solver starts from, per patch: reflectance, emission, the lamps' and the shot emitters'
first shot, the world's light, and the patches that take part in the exchange at all.

E_i = pi L_e (emissive materials: radiance L_e, front face only) plus the lights' first shot
rho_i H_i, with H_i the direct irradiance of point, spot, sun and area lights
(`lights.direct_irradiance`) averaged over n x n points of the patch, each point's contribution
multiplied by its visibility (`lamps.py`). Emissive triangles (up to the final gather's
`max_emitters`) shoot first too (`first_shot`: exact point-to-polygon factor times the gather's
visible share); the solver then carries B - E_shot only, and adds E_shot back, so their light is
not counted twice.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..geometry.frames import RAY_OFFSET_REL
from ..geometry.scene import Scene, triangle_emission
from ..shading.alpha import surface_alpha
from ..shading.direct_light import diffuse_at, diffuse_weight
from ..shading.specular_layer import diffuse_factor
from ..shading.world_light import extract_suns, world_irradiance, world_lit, world_source
from . import patches as patching
from .emitters import Emitters, emitter_irradiance, emitters_of, open_backs
from .form_factors.sampling import sample_patches
from .lamps import diffuse_lamps, near_lamp_scale, shadowed_irradiance, shadowing_lamps
from .settings import RadiositySettings, gather_settings

# The largest diffuse reflectance the solve takes. At 1 a patch keeps back none of the light it
# receives and the iteration need not converge (a closed room of such walls never does); Cycles
# renders a base colour of 1 as given (its bounces stop at a count), so the solve takes it at
# this, 0.1% less per bounce, and names the material (`capped_materials`).
MAX_REFLECTANCE = 0.999
# Points per side of the grid a partly covered patch is sampled on for its reflectance
# (`patch_reflectance`): 16 look-ups of its colour and alpha.
COVERAGE_SAMPLES = 4


def patch_reflectance(scene: Scene, patches: patching.Patches) -> np.ndarray:
    """(N, 3) diffuse reflectance at each patch centre (`direct_light.diffuse_at`: base colour,
    textures sampled there, times the diffuse weight; metals and glass reflect nothing diffusely).

    The solver's reflectance leaves out the Principled specular layer (`specular_layer.py`):
    what the layer takes from the base it reflects itself, and Cycles follows that light at the
    last bounce before a light (its glossy lobe is lit directly even with no glossy bounces).
    Measured: the Cornell box with every surface at Specular IOR Level 0.5, roughness 0.5,
    against a 512-sample Cycles bake: relMSE 0.00218 without the layer anywhere (texels 3% too
    bright), 0.00319 with it in the solve and the texels (3.5% too dark), 0.00179 with it in the
    texels alone, as at level 0 (0.00184). Only the texels (`RadiosityResult.radiance_at`) show
    the base under the layer.

    A partly covered patch (alpha: a leaf card, a fence) reflects with its coverage: the mean
    of alpha x colour over COVERAGE_SAMPLES^2 points of it. The exchange's rays that end on it
    count it whole, so its holes must reflect nothing there (a red card of square holes over a
    floor sent it twice the red light Cycles' floor takes).

    Channels at or above 1 (a white base colour, a texture's white texels) are taken at
    `MAX_REFLECTANCE`, which the solvers need below 1."""
    rho = diffuse_at(scene, patches.parent, patches.bary.mean(axis=1), under_layer=False)
    rho = rho.astype(np.float64)
    covered = np.array([m.has_alpha for m in scene.materials], bool)
    rows = np.flatnonzero(covered[scene.material_ids[patches.parent]]) if covered.any() else []
    if len(rows):
        # the samples' barycentrics in the parent: the patch's corners taken as points
        bary, weights = sample_patches(patches.bary[rows], COVERAGE_SAMPLES, "midpoint")
        tri = np.repeat(patches.parent[rows], bary.shape[1])
        flat = bary.reshape(-1, 3)
        colours = diffuse_at(scene, tri, flat, under_layer=False).reshape(bary.shape)
        cover = surface_alpha(scene, tri, flat).reshape(weights.shape) * weights
        rho[rows] = np.einsum("rs,rsc->rc", cover, colours)
    return np.minimum(rho, MAX_REFLECTANCE)


def capped_materials(scene: Scene, patches: patching.Patches, rho: np.ndarray) -> list[str]:
    """Names of the materials whose patches' reflectance (N, 3) `patch_reflectance` capped."""
    capped = np.any(rho >= MAX_REFLECTANCE, axis=1)
    ids = np.unique(scene.material_ids[patches.parent[capped]])
    return [scene.materials[int(k)].name for k in ids] if scene.materials else []


def layer_factors(scene: Scene) -> np.ndarray:
    """(M,) per material: the share of its diffuse base the specular layer leaves a texel
    (`specular_layer.diffuse_factor`, seen along the normal); 1 without a layer."""
    return np.array([diffuse_factor(m) for m in scene.materials] or [1.0], np.float64)


def exchanging_triangles(scene: Scene) -> np.ndarray:
    """(T,) bool: triangles that take part in the exchange, reflecting diffusely (a diffuse
    weight and a base colour above 0, or a texture) or emitting. The others (a chrome ball, a
    glass, black paint) send nothing and their B is 0: they are solved without, one idle patch
    per triangle, and stay occluders (all of them when none exchanges)."""
    mats = scene.materials
    emits = np.any(triangle_emission(scene) > 0.0, axis=1)  # (T,): a texture's black parts do not
    coloured = [m.base_color_texture is not None or np.any(np.asarray(m.base_color) > 0.0)
                for m in mats]
    reflects = np.array([diffuse_weight(m) > 0.0 and c for m, c in zip(mats, coloured, strict=True)],
                        bool)
    out = emits | reflects[scene.material_ids] if mats else np.ones(scene.triangle_count, bool)
    return out if out.any() else np.ones(scene.triangle_count, bool)


def with_idle(scene: Scene, patches: patching.Patches, exchanging: np.ndarray,
              *per_patch: np.ndarray) -> tuple[patching.Patches, list[np.ndarray]]:
    """`patches` of the exchanging triangles joined by one idle patch per other triangle
    (`exchanging_triangles`), and each (N, ...) array of `per_patch` with zero rows for the idle
    ones, all in the joined order."""
    idle = patching.make_patches(scene, np.inf, ~exchanging) if not exchanging.all() else None
    if idle is None or len(idle) == 0:
        return patches, list(per_patch)
    joined, order = patching.merged(scene, patches, idle)
    out = []
    for values in per_patch:
        padded = np.concatenate([values, np.zeros((len(idle),) + values.shape[1:], values.dtype)])
        out.append(padded[order])
    return joined, out


def patch_emission(scene: Scene, patches: patching.Patches) -> np.ndarray:
    """(N, 3) emitted radiosity pi L_e, W/m^2 (front face)."""
    return np.pi * triangle_emission(scene)[patches.parent]


def shot_emitters(scene: Scene, settings: RadiositySettings, bvh=None,
                  offset: float = 0.0) -> Emitters:
    """The emissive triangles that shoot their light first, as lamps do (`first_shot`): the ones
    the final gather reads per receiver (`emitters.emitters_of`; none past its
    `max_emitters`, whose light the solver then carries as emission), with the back sides that
    face open space (`emitters.open_backs`, given the scene's `bvh`)."""
    open_back = None if bvh is None else open_backs(scene, bvh, offset)
    return emitters_of(scene, gather_settings(settings), open_back)


def shot_emission(scene: Scene, patches: patching.Patches,
                  emitters: Emitters) -> np.ndarray:
    """(N, 3) the part of `patch_emission` that `emitters` shoot in the first shot, W/m^2: the
    solver must not carry it a second time."""
    return patch_emission(scene, patches) * emitters.covers(patches.parent)[:, None]


# With the final gather, what the camera and the bakes show is lit at their own points; the
# first shot's points per patch only feed the light the patches pass on. Past this many points
# in all, a patch takes fewer (`light_points_per_side`): a dense mesh's patches are small. On a
# 68k-patch subdivided head, one point a patch instead of 3 x 3: the view's relMSE against
# Cycles 2.37e-3 (2.61e-3), the solve and bake 76 s (99 s).
LIGHT_POINT_BUDGET = 9 * 8192


def light_points_per_side(settings: RadiositySettings, patches: int) -> int:
    """Points per side of each of `patches` patches the first shot lights: the setting's
    (`light_samples_per_side`), fewer with the final gather where that would pass
    LIGHT_POINT_BUDGET points in all (not under 1)."""
    n = settings.light_samples_per_side
    while settings.final_gather and n > 1 and patches * n * n > LIGHT_POINT_BUDGET:
        n -= 1
    return n


def first_shot(scene: Scene, patches: patching.Patches, occluded, settings: RadiositySettings,
               scale: float, emitters: Emitters | None = None,
               clear: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Direct irradiance of the scene's lights, and of `emitters` (`shot_emitters`: exact
    point-to-polygon factors times the visible share, `emitters.emitter_irradiance`), on
    every patch, with shadows.

    occluded: the BVH callback (origins, directions, t_min, t_max) -> (R,) bool, or None (no
    shadows); clear (N, K) bool: the patches that see emitter k whole
    (`emitters.clear_shafts`), whose points cast no shadow rays to it. Returns H (N, 3) W/m^2,
    the mean over n x n midpoint samples of each patch, and boundary (N,) bool: patches with
    some samples lit and some shadowed by one light (or by the emitters together).
    """
    count = len(patches)
    irradiance = np.zeros((count, 3))
    boundary = np.zeros(count, bool)
    shooting = emitters is not None and len(emitters.triangles) > 0
    if not (scene.lights or shooting) or count == 0:
        return irradiance, boundary
    weights, flat, normals, origins = lifted_samples(
        patches, light_points_per_side(settings, count), scale)
    samples = weights.shape[1]
    offset = RAY_OFFSET_REL * scale

    def add(e: np.ndarray, vis: np.ndarray) -> None:
        irradiance[:] += np.einsum("ns,nsc->nc", weights, e.reshape(count, samples, 3))
        v = vis.reshape(count, samples)
        reached = (e.max(axis=1) > 0.0).reshape(count, samples) | (v < 1.0)
        some_lit = np.any(reached & (v > 0.0), axis=1)
        some_dark = np.any(reached & (v < 1.0), axis=1)
        boundary[:] |= some_lit & some_dark

    objects = np.repeat(scene.object_ids[patches.parent], samples)  # the samples' (light linking)
    for light in diffuse_lamps(scene):
        e, vis = shadowed_irradiance(light, flat, normals, origins, occluded,
                                     settings.area_light_samples_per_side,
                                     objects=objects)  # (N S, 3), (N S,)
        if light.kind in ("POINT", "SPOT"):  # the samples' mean made the exact patch integral
            e *= np.repeat(near_lamp_scale(light, patches.corners, patches.normals,
                                           patches.areas, weights, flat), samples)[:, None]
        add(e, vis)
    if shooting:
        share = np.ones(len(flat))
        e = emitter_irradiance(
            emitters, flat, normals, occluded or _never_occluded, offset,
            np.random.default_rng(settings.seed + 2), share_out=share,
            clear=None if clear is None else np.repeat(clear, samples, axis=0))
        add(e, share)
    return irradiance, boundary


def with_world_suns(scene: Scene) -> Scene:
    """The scene as the solve lights it: a world map's suns (`world_light.extract_suns`: spots far
    brighter than the sky, which cosine rays would find on a few patches only) as sun lamps,
    which the first shot and the final gather light with shadow rays like any sun, and the map
    without them for the sky rays. Scenes without such a map are returned as they are."""
    if scene.world_texture is None:
        return scene
    suns, residual = extract_suns(scene.world_texture, scene.world_transform)
    if not suns:
        return scene
    return replace(scene, lights=tuple(scene.lights) + suns, world_texture=residual)


# A dense mesh's patches are small, their share of open sky changes little from one to the next,
# and the final gather reads it at the patches' corners, averaged over the patches around them:
# past this many sky rays in all, each patch takes fewer (`world_rays_per_patch`), and the
# second casts of the patches that see sky in part share as many again (`world_irradiance`). On a
# subdivided head of 68k patches under a white world, 8 rays a patch gave the view's relMSE
# against Cycles of 64 (2.61e-3 and 2.63e-3) in 114 s instead of 189 s.
WORLD_RAY_BUDGET = 64 * 8192
# Fewest sky rays a patch takes under the budget.
MIN_WORLD_RAYS = 8


def world_rays_per_patch(settings: RadiositySettings, patches: int) -> int:
    """Sky rays each of `patches` patches takes: `world_rays`, fewer (not under MIN_WORLD_RAYS)
    where that would pass WORLD_RAY_BUDGET rays in all; 0 with `world_rays` 0."""
    if settings.world_rays == 0:
        return 0
    return min(settings.world_rays, max(MIN_WORLD_RAYS, WORLD_RAY_BUDGET // max(patches, 1)))


def world_shot(scene: Scene, patches: patching.Patches, bvh, settings: RadiositySettings,
               scale: float) -> np.ndarray:
    """(N, 3) W/m^2: the world's irradiance on every patch, pi L_w times its share of open sky
    (`world_light.py`, `world_rays_per_patch` rays each). The solver carries it as it carries
    the first shot, but the final gather counts it as indirect light, so it stays out of
    `direct`. Zero for a black world or `world_rays` 0. bvh: `kernels.geometry.bvh.BVH` over the
    scene's triangles."""
    if not world_lit(scene):
        return np.zeros((len(patches), 3))
    return world_irradiance(world_source(scene), patches.corners, patches.normals,
                            patches.parent, bvh.occluded, scale,
                            world_rays_per_patch(settings, len(patches)),
                            np.random.default_rng(settings.seed + 3), budget=WORLD_RAY_BUDGET)


# A patch is split across a shadow edge when a lamp's visible fraction at its samples spans this
# much: 1 for a point, spot or sun lamp's step; an area lamp's penumbra narrower than the patch
# also spans most of it, a wide ramp (the lamp large against the occluder's distance) does not.
SHADOW_STEP = 0.5


def shadow_edges(scene: Scene, patches: patching.Patches, occluded,
                 settings: RadiositySettings, scale: float) -> np.ndarray:
    """(N,) bool: patches across a shadow edge, the lamp's visible fraction at their n x n
    midpoint samples (`light_samples_per_side`, among those facing it) spanning SHADOW_STEP or
    more: a point, spot or sun lamp's samples lit and shadowed, an area lamp's mostly seen and
    mostly hidden.

    Such a shadow is a step (or a ramp narrower than the patch), and one patch value cannot
    stand for both sides of it in the light the patch sends on. Emissive triangles are left out:
    their penumbrae are wide ramps that the patches follow (on the Cornell box, splitting at its
    ceiling light's shadow edges cost more seconds than the error it removed, at every patch
    count). occluded: the BVH callback, or None (no shadows, no edges)."""
    edges = np.zeros(len(patches), bool)
    lamps = shadowing_lamps(scene)
    if occluded is None or not lamps or len(patches) == 0:
        return edges
    weights, flat, normals, origins = lifted_samples(patches, settings.light_samples_per_side,
                                                     scale)
    count, samples = weights.shape
    objects = np.repeat(scene.object_ids[patches.parent], samples)
    for light in lamps:
        e, vis = shadowed_irradiance(light, flat, normals, origins, occluded,
                                     settings.area_light_samples_per_side, objects=objects)
        v = vis.reshape(count, samples)  # 1 where the sample faces away
        # The most seen of the lit samples against the least seen of all (those facing away
        # are 1, never below a facing one's).
        hi = np.where((e.max(axis=1) > 0.0).reshape(count, samples), v, 0.0).max(axis=1)
        edges |= hi - v.min(axis=1) >= SHADOW_STEP
    return edges


def lifted_samples(patches: patching.Patches, per_side: int, scale: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """n x n midpoint samples of every patch (n = `per_side`; the lights' first shot takes
    `light_samples_per_side`): weights (N, S), points (N S, 3) world m, their normals (N S, 3)
    and the shadow rays' origins, lifted RAY_OFFSET_REL x scale (m) off the surface (N S, 3)."""
    points, weights = sample_patches(patches.corners, per_side, "midpoint")
    flat = points.reshape(-1, 3)
    normals = np.repeat(patches.normals, points.shape[1], axis=0)
    return weights, flat, normals, flat + RAY_OFFSET_REL * scale * normals


def _never_occluded(origins, directions, t_min, t_max) -> np.ndarray:
    return np.zeros(len(origins), bool)
