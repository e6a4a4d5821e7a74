"""Radiosity of a whole scene: patches, lights' first shot, form factors with BVH visibility, a
solver chosen by memory, adaptive refinement, and the solution evaluated anywhere on the surface.

Pipeline (`radiosity_steps`):

1. Patches: the scene's triangles cut into sub-triangles of about `patch_size` (`patches.py`;
   "auto" aims at `patch_budget` patches over the scene's area).
2. Sources, per patch: E_i = pi L_e (emissive materials: radiance L_e, front face only) plus the
   lights' first shot rho_i H_i, with H_i the direct irradiance of point, spot, sun and area
   lights (`lights.direct_irradiance`) averaged over n x n points of the patch, each point's
   contribution multiplied by its visibility (BVH shadow rays; area lights: the visible fraction
   of a grid of points on the emitter). Area lights are not geometry: they only shoot.
   Emissive triangles (up to the final gather's `max_emitters`) shoot first too (`first_shot`:
   exact point-to-polygon factor times the gather's visible share); the solver then carries
   B - E_shot only, and adds E_shot back, so their light is not counted twice.
3. Form factors, one row at a time (`form_factors.py`): "raycast" (exact point-to-polygon factor
   times the visible share by BVH shadow rays over the scene's triangles) or "hemicube" (rays
   from hemicubes through a BVH over the patches).
4. Solve B = E + rho F B in RGB (`radiosity_solvers.py`): Gauss-Seidel on the dense matrix when
   it fits `dense_memory_limit`, else progressive refinement (one row per shot, never N x N).
   "auto" hands scenes of more than AUTO_DENSE_PATCHES patches to the hierarchical solver
   (`hierarchical.py`: its own linking, solve and leaf refinement) when its up-front memory bound
   fits the limit.
5. Refine: patches whose interpolated corner values differ from their own B by more than
   `refine_threshold` (relative), or that straddle a light's shadow boundary (some of their
   points see the light, others do not), are split in four and the system is solved again, up
   to `refine_levels` times and `max_patches` patches. With the final gather, patches across a
   point, spot or sun lamp's shadow edge are instead split before the first solve
   (`shadow_splits`, `hard_shadow_edges`): receivers gather their own direct light, but such a
   patch still sends one mean to its neighbours.

Display: `RadiosityResult.exitance_at(tri, bary)` gives B anywhere on the surface. With
`final_gather` (the default, `final_gather.py`) each receiver gets its exact direct light (lamps
and emissive triangles, with shadow rays) and the indirect part interpolated from the patches;
without it, B itself is interpolated smoothly inside objects (`patches.fitted_corner_values`,
`interpolate`). Outgoing radiance is B / pi, what Cycles' DIFFUSE bake (with colour) gives plus
the emission. `bake_steps` evaluates lightmap texels and mesh corners, `render_steps` the scene
camera's view.

Materials: every surface is treated as Lambertian with the Principled BSDF's diffuse part, base
colour x (1 - metallic) x (1 - transmission) (textures sampled at the patch centre); the
specular paths of metals, glossy coats and glass are not modelled (listed in `ignored`), so a
chrome ball or a glass is black to the solution, as in Cycles' DIFFUSE bake.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from ..bake.bake_targets import TexelFilterSettings
from ..bake.camera_view import EDGE_SAMPLES
from ..geometry.scene import Scene, triangle_emission
from ..measure.metrics import REC709_LUMINANCE
from ..shading import lights as light_units
from ..shading.world_light import (
    WORLD_RAYS,
    WORLD_SUN_NAME,
    extract_suns,
    sky_ray_bytes,
    world_irradiance,
    world_lit,
    world_radiance,
    world_source,
)
from . import clusters, final_gather
from . import patches as patching
from .final_gather import ELEMENT_PAIRS, FinalGather, FinalGatherSettings
from .form_factors import (
    RAY_OFFSET_REL,
    HemicubeFormFactors,
    HemicubeSettings,
    RayCastFormFactors,
    RayCastSettings,
    enforce_reciprocity,
    iter_matrix,
    sample_patches,
)
from .hierarchical import FACING_COUNT_PAIRS, facing_roots, hierarchy_roots, memory_bound
from .radiosity_solvers import (
    GaussSeidelSettings,
    GaussSeidelSolver,
    ProgressiveSettings,
    ProgressiveSolver,
)

# Below this luminance fraction of the scene's mean radiosity a patch counts as dark: relative
# differences are measured against it, so noise in black corners does not trigger refinement.
REFINE_FLOOR_REL = 0.05
# The quick unoccluded-pair test of method B keeps (T, N) bool tables and a (T, N, 3) float64
# temporary; it is used only while that stays under this many bytes.
QUICK_TEST_BYTES = 256 << 20
# Bytes per (point, patch) element of the ray-cast row temporaries (factors, clipped polygons,
# visibility kernels; measured order of magnitude, for the up-front estimate).
ROW_BYTES_PER_ELEMENT = 400
# Shadow rays stop this fraction short of a point light (it has no surface to hit).
LIGHT_END_REL = 1e-6
LUMINANCE = np.array(REC709_LUMINANCE)
SOLVERS = ("auto", "gauss_seidel", "progressive", "hierarchical", "clustered")


@dataclass(frozen=True)
class RadiositySettings:
    """| field                       | range               | default  | unit / meaning             |
    |-----------------------------|---------------------|----------|----------------------------|
    | method                      | raycast / hemicube  | raycast  | form factor estimator      |
    | solver                      | auto / gauss_seidel | auto     | auto: the clustered solver |
    |                             | / progressive /     |          | when grouping the patches  |
    |                             | hierarchical /      |          | of fine meshes cuts the    |
    |                             | clustered           |          | unknowns fourfold; else    |
    |                             |                     |          | above AUTO_DENSE_PATCHES   |
    |                             |                     |          | patches the hierarchical   |
    |                             |                     |          | solver if its bound fits   |
    |                             |                     |          | the memory limit (raycast);|
    |                             |                     |          | else Gauss-Seidel when the |
    |                             |                     |          | dense F fits, else         |
    |                             |                     |          | progressive                |
    | patch_size                  | >= 0                | 0        | m, longest patch edge; 0:  |
    |                             |                     |          | from patch_budget          |
    | patch_budget                | >= 1                | 400      | patches aimed at (auto)    |
    | refine_levels               | >= -1               | -1       | adaptive splits (0: none;  |
    |                             |                     |          | -1 auto: 0 with the final  |
    |                             |                     |          | gather, 1 without it)      |
    | shadow_splits               | >= -1               | -1       | times patches across a     |
    |                             |                     |          | lamp's hard shadow edge    |
    |                             |                     |          | split before the solve (-1 |
    |                             |                     |          | auto:                      |
    |                             |                     |          | AUTO_SHADOW_SPLITS with the|
    |                             |                     |          | final gather and a point,  |
    |                             |                     |          | spot or sun lamp, else 0)  |
    | refine_threshold            | > 0                 | 0.25     | relative corner difference |
    |                             |                     |          | that splits a patch        |
    | max_patches                 | >= 1                | 3000     | refinement stops here      |
    |                             |                     |          | (auto lowers it where the  |
    |                             |                     |          | hierarchy's bound would    |
    |                             |                     |          | not fit the memory limit)  |
    | tolerance                   | (0, 1)              | 1e-4     | solver stop (see solvers)  |
    | dense_memory_limit          | >= 0                | 512 MiB  | bytes for the dense F      |
    | samples_per_side            | >= 0                | 0        | n x n points per patch     |
    |                             |                     |          | (ray-cast sources, hemicube|
    |                             |                     |          | positions); 0 auto: 1 when |
    |                             |                     |          | no reflectance exceeds     |
    |                             |                     |          | AUTO_ONE_POINT_RHO, else 2 |
    | visibility_samples_per_side | >= 1                | 2        | m x m ray targets per patch|
    | hemicube_resolution         | even >= 2           | 32       | hemicube top-face pixels   |
    | light_samples_per_side      | >= 1                | 3        | points per patch side for  |
    |                             |                     |          | the lights' first shot     |
    | area_light_samples_per_side | >= 1                | 4        | emitter grid for area-light|
    |                             |                     |          | shadow rays                |
    | smooth_angle                | [0, pi]             | 0.5236   | rad; corners average the   |
    |                             |                     |          | patches within this angle  |
    | link_epsilon                | > 0                 | 0.01     | hierarchical: a link's     |
    |                             |                     |          | source splits while its    |
    |                             |                     |          | factor exceeds this        |
    | max_depth                   | >= 0                | 3        | hierarchical: source levels|
    |                             |                     |          | above the patches (roots:  |
    |                             |                     |          | 2^max_depth x patch size)  |
    | max_shots                   | >= 0                | 0        | progressive: stop after    |
    |                             |                     |          | this many shots, the       |
    |                             |                     |          | ambient term covering the  |
    |                             |                     |          | rest (0: until tolerance)  |
    | final_gather                | bool                | True     | read the solution out with |
    |                             |                     |          | exact direct light at each |
    |                             |                     |          | receiver (final_gather.py) |
    | gather_rays                 | >= 1                | 16       | final gather: shadow rays  |
    |                             |                     |          | per receiver to emissive   |
    |                             |                     |          | triangles                  |
    | element_pairs               | >= 0                | 50000    | final gather: element-to-  |
    |                             |                     |          | patch pairs the indirect   |
    |                             |                     |          | light may be gathered over |
    |                             |                     |          | (elements.py; 0: patches)  |
    | world_rays                  | >= 0                | 64       | rays per patch that find   |
    |                             |                     |          | its share of open sky, lit |
    |                             |                     |          | by the world colour        |
    |                             |                     |          | (world_light.py; 0: the    |
    |                             |                     |          | world lights no surface)   |
    | seed                        | int                 | 0        | RNG seed of the estimators |
    | clusters                    | bool                | True     | auto may solve the patches |
    |                             |                     |          | of finely tessellated      |
    |                             |                     |          | meshes as groups           |
    |                             |                     |          | (clusters.py)              |
    | cluster_sources             | bool                | True     | hierarchical: far groups of|
    |                             |                     |          | many small roots share     |
    |                             |                     |          | their shadow rays          |
    |                             |                     |          | (source_clusters.py)       |
    """

    method: Literal["raycast", "hemicube"] = "raycast"
    solver: Literal["auto", "gauss_seidel", "progressive", "hierarchical", "clustered"] = "auto"
    patch_size: float = 0.0
    patch_budget: int = 400
    refine_levels: int = -1
    shadow_splits: int = -1
    refine_threshold: float = 0.25
    max_patches: int = 3000
    tolerance: float = 1e-4
    dense_memory_limit: int = 512 << 20
    samples_per_side: int = 0
    visibility_samples_per_side: int = 2
    hemicube_resolution: int = 32
    light_samples_per_side: int = 3
    area_light_samples_per_side: int = 4
    smooth_angle: float = math.radians(30.0)
    link_epsilon: float = 0.01
    max_depth: int = 3
    max_shots: int = 0
    final_gather: bool = True
    gather_rays: int = 16
    element_pairs: int = ELEMENT_PAIRS
    world_rays: int = WORLD_RAYS
    seed: int = 0
    clusters: bool = True
    cluster_sources: bool = True

    def __post_init__(self) -> None:
        if self.method not in ("raycast", "hemicube"):
            raise ValueError(f"method must be 'raycast' or 'hemicube', got {self.method!r}")
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {', '.join(SOLVERS)}, got {self.solver!r}")
        if self.solver == "clustered" and self.method != "raycast":
            raise ValueError("the clustered solver estimates its own ray-cast factors: "
                             "use method 'raycast'")
        if not self.link_epsilon > 0.0 or self.max_depth < 0:
            raise ValueError("link_epsilon must be > 0 and max_depth >= 0")
        if self.patch_size < 0.0 or self.patch_budget < 1 or self.max_patches < 1:
            raise ValueError("patch_size must be >= 0, patch_budget and max_patches >= 1")
        if self.refine_levels < -1 or not self.refine_threshold > 0.0:
            raise ValueError("refine_levels must be >= -1 (auto) and refine_threshold > 0")
        if self.shadow_splits < -1:
            raise ValueError(f"shadow_splits must be >= -1 (auto), got {self.shadow_splits}")
        if not 0.0 < self.tolerance < 1.0:
            raise ValueError(f"tolerance must be in (0, 1), got {self.tolerance}")
        if min(self.visibility_samples_per_side, self.light_samples_per_side,
               self.area_light_samples_per_side) < 1 or self.samples_per_side < 0:
            raise ValueError("sample counts must be >= 1 (samples_per_side >= 0, 0: auto)")
        if self.gather_rays < 1:
            raise ValueError(f"gather_rays must be >= 1, got {self.gather_rays}")
        if self.world_rays < 0 or self.element_pairs < 0:
            raise ValueError("world_rays and element_pairs must be >= 0")
        if self.max_shots < 0:
            raise ValueError(f"max_shots must be >= 0, got {self.max_shots}")
        if self.hemicube_resolution < 2 or self.hemicube_resolution % 2:
            raise ValueError("hemicube_resolution must be even and >= 2")


@dataclass(frozen=True, eq=False)
class RadiosityResult:
    """The solved scene.

    patches     `Patches` (N of them)
    radiosity   (N, 3) float64  B, W/m^2 (exitance; outgoing radiance is B / pi)
    emitted     (N, 3) float64  pi x emission radiance, W/m^2
    direct      (N, 3) float64  the lights' direct irradiance H (first shot), W/m^2
    reflectance (N, 3) float64  rho
    corner_b    (N, 3, 3)       B at each patch corner (`patches.fitted_corner_values`),
                                its reflected part under the specular layer (`layer_factors`)
    corner_e    (N, 3, 3)       the same for `emitted`
    stats       dict            patch counts per level, solver, memory estimate, seconds
    gather      FinalGather     what the final gather reads at receivers; None: interpolate B
    """

    patches: patching.Patches
    radiosity: np.ndarray
    emitted: np.ndarray
    direct: np.ndarray
    reflectance: np.ndarray
    corner_b: np.ndarray
    corner_e: np.ndarray
    stats: dict = field(default_factory=dict)
    gather: FinalGather | None = None

    def exitance_at(self, tri: np.ndarray, bary: np.ndarray, reflected_only: bool = False,
                    interpolated: bool = False, known: final_gather.Visibility | None = None,
                    visibility_out: final_gather.Visibility | None = None) -> np.ndarray:
        """(M, 3) B at points given as scene triangles (M,) and barycentrics (M, 3): the final
        gather's when the result has one (`final_gather.py`, which also takes `known` and fills
        `visibility_out`), else (or with `interpolated`) B interpolated from the patch corners.
        `reflected_only`: B minus the emission (what Cycles' DIFFUSE bake sees, times pi)."""
        if self.gather is not None and not interpolated:
            return final_gather.exitance(self.gather, tri, bary, reflected_only, known,
                                         visibility_out)
        patch, local = patching.locate(self.patches, tri, bary)
        values = patching.interpolate(self.corner_b, patch, local)
        if reflected_only:
            values -= patching.interpolate(self.corner_e, patch, local)
        return values

    def radiance_at(self, tri: np.ndarray, bary: np.ndarray, reflected_only: bool = False,
                    interpolated: bool = False, known: final_gather.Visibility | None = None,
                    visibility_out: final_gather.Visibility | None = None) -> np.ndarray:
        """(M, 3) outgoing radiance B / pi, W/(m^2 sr) (see `exitance_at`)."""
        return self.exitance_at(tri, bary, reflected_only, interpolated, known,
                                visibility_out) / np.pi

    def back_radiance_at(self, scene: Scene, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """(M, 3) outgoing radiance W/(m^2 sr) of the back side of surface points of `scene`
        (triangles, barycentrics): the emission and, with the final gather, the direct light
        that reaches the back and one bounce of this solution's light off the surfaces the back
        faces (`final_gather.back_exitance`). The solution itself is one-sided: without the
        gather a back side shows its emission only."""
        if self.gather is not None:
            return final_gather.back_exitance(self.gather, tri, bary, lambda t, b: self.exitance_at(
                t, b, reflected_only=True, interpolated=True)) / np.pi
        return triangle_emission(scene)[np.asarray(tri, np.int64)]


# --- sources ------------------------------------------------------------------------------------


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

    Raises ValueError naming the material when any channel is >= 1 (no convergence)."""
    from ..shading.direct_light import diffuse_at, diffuse_weight

    for mat in scene.materials:
        weight = diffuse_weight(mat, under_layer=False)
        if mat.base_color_texture is None and np.any(weight * np.asarray(mat.base_color) >= 1.0):
            raise ValueError(
                f"material '{mat.name}' has a diffuse reflectance of "
                f"{weight * np.max(mat.base_color):.3g} >= 1: radiosity needs reflectance < 1 in "
                "every channel (a surface reflecting all light never lets a closed scene converge)")
    rho = diffuse_at(scene, patches.parent, patches.bary.mean(axis=1), under_layer=False)
    if np.any(rho >= 1.0):
        bad = scene.materials[int(scene.material_ids[patches.parent[np.argmax(rho.max(1))]])]
        raise ValueError(f"material '{bad.name}': its texture reaches reflectance >= 1; "
                         "radiosity needs reflectance < 1 in every channel")
    return rho.astype(np.float64)


def layer_factors(scene: Scene) -> np.ndarray:
    """(M,) per material: the share of its diffuse base the specular layer leaves a texel
    (`specular_layer.diffuse_factor`, seen along the normal); 1 without a layer."""
    from ..shading.specular_layer import diffuse_factor

    return np.array([diffuse_factor(m) for m in scene.materials] or [1.0], np.float64)


def exchanging_triangles(scene: Scene) -> np.ndarray:
    """(T,) bool: triangles that take part in the exchange, reflecting diffusely (a diffuse
    weight and a base colour above 0, or a texture) or emitting. The others (a chrome ball, a
    glass, black paint) send nothing and their B is 0: they are solved without, one idle patch
    per triangle, and stay occluders (all of them when none exchanges)."""
    from ..shading.direct_light import diffuse_weight

    mats = scene.materials
    emits = np.array([np.any(np.asarray(m.emission) > 0.0) for m in mats], bool)
    coloured = [m.base_color_texture is not None or np.any(np.asarray(m.base_color) > 0.0)
                for m in mats]
    reflects = np.array([diffuse_weight(m) > 0.0 and c for m, c in zip(mats, coloured, strict=True)],
                        bool)
    out = (emits | reflects)[scene.material_ids] if mats else np.ones(scene.triangle_count, bool)
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


def shot_emitters(scene: Scene, settings: RadiositySettings) -> final_gather.Emitters:
    """The emissive triangles that shoot their light first, as lamps do (`first_shot`): the ones
    the final gather reads per receiver (`final_gather.emitters_of`; none past its
    `max_emitters`, whose light the solver then carries as emission)."""
    return final_gather.emitters_of(scene, gather_settings(settings))


def gather_settings(settings: RadiositySettings) -> FinalGatherSettings:
    """The final gather's settings, and the shot emitters', from the radiosity settings."""
    return FinalGatherSettings(emitter_rays=settings.gather_rays, seed=settings.seed,
                               patch_samples=settings.samples_per_side,
                               world_rays=settings.world_rays,
                               element_pairs=settings.element_pairs)


def shot_emission(scene: Scene, patches: patching.Patches,
                  emitters: final_gather.Emitters) -> np.ndarray:
    """(N, 3) the part of `patch_emission` that `emitters` shoot in the first shot, W/m^2: the
    solver must not carry it a second time."""
    return patch_emission(scene, patches) * emitters.covers(patches.parent)[:, None]


def first_shot(scene: Scene, patches: patching.Patches, occluded, settings: RadiositySettings,
               scale: float, emitters: final_gather.Emitters | None = None,
               clear: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Direct irradiance of the scene's lights, and of `emitters` (`shot_emitters`: exact
    point-to-polygon factors times the visible share, `final_gather.emitter_irradiance`), on
    every patch, with shadows.

    occluded: the BVH callback (origins, directions, t_min, t_max) -> (R,) bool, or None (no
    shadows); clear (N, K) bool: the patches that see emitter k whole
    (`final_gather.clear_shafts`), whose points cast no shadow rays to it. Returns H (N, 3) W/m^2,
    the mean over n x n midpoint samples of each patch, and boundary (N,) bool: patches with
    some samples lit and some shadowed by one light (or by the emitters together).
    """
    count = len(patches)
    irradiance = np.zeros((count, 3))
    boundary = np.zeros(count, bool)
    shooting = emitters is not None and len(emitters.triangles) > 0
    if not (scene.lights or shooting) or count == 0:
        return irradiance, boundary
    weights, flat, normals, origins = _light_samples(patches, settings, scale)
    samples = weights.shape[1]
    offset = RAY_OFFSET_REL * scale

    def add(e: np.ndarray, vis: np.ndarray) -> None:
        irradiance[:] += np.einsum("ns,nsc->nc", weights, e.reshape(count, samples, 3))
        v = vis.reshape(count, samples)
        reached = (e.max(axis=1) > 0.0).reshape(count, samples) | (v < 1.0)
        some_lit = np.any(reached & (v > 0.0), axis=1)
        some_dark = np.any(reached & (v < 1.0), axis=1)
        boundary[:] |= some_lit & some_dark

    for light in scene.lights:
        add(*shadowed_irradiance(light, flat, normals, origins, occluded,
                                 settings.area_light_samples_per_side))  # (N S, 3), (N S,)
    if shooting:
        share = np.ones(len(flat))
        e = final_gather.emitter_irradiance(
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


def world_shot(scene: Scene, patches: patching.Patches, bvh, settings: RadiositySettings,
               scale: float) -> np.ndarray:
    """(N, 3) W/m^2: the world's irradiance on every patch, pi L_w times its share of open sky
    (`world_light.py`, `world_rays` rays each). The solver carries it as it carries the first
    shot, but the final gather counts it as indirect light, so it stays out of `direct`. Zero
    for a black world or `world_rays` 0. bvh: `kernels.geometry.bvh.BVH` over the scene's triangles."""
    if not world_lit(scene):
        return np.zeros((len(patches), 3))
    return world_irradiance(world_source(scene), patches.corners, patches.normals,
                            patches.parent, bvh.occluded, scale, settings.world_rays,
                            np.random.default_rng(settings.seed + 3))


def hard_shadow_edges(scene: Scene, patches: patching.Patches, occluded,
                      settings: RadiositySettings, scale: float) -> np.ndarray:
    """(N,) bool: patches across a hard shadow edge, some of their n x n midpoint samples
    (`light_samples_per_side`) lit by a point, spot or sun lamp and some shadowed from it.

    Such a lamp's shadow is a step, and one patch value cannot stand for both sides of it in
    the light the patch sends on. Area lamps and emissive triangles are left out: their
    penumbrae are ramps that the patches follow (on the Cornell box, splitting at its ceiling
    light's shadow edges cost more seconds than the error it removed, at every patch count).
    occluded: the BVH callback, or None (no shadows, no edges)."""
    edges = np.zeros(len(patches), bool)
    hard = hard_lamps(scene)
    if occluded is None or not hard or len(patches) == 0:
        return edges
    weights, flat, normals, origins = _light_samples(patches, settings, scale)
    count, samples = weights.shape
    for light in hard:
        e, vis = shadowed_irradiance(light, flat, normals, origins, occluded, 1)
        v = vis.reshape(count, samples)
        lit = (e.max(axis=1) > 0.0).reshape(count, samples)
        edges |= np.any(lit, axis=1) & np.any(v < 1.0, axis=1)
    return edges


def hard_lamps(scene: Scene) -> list:
    """The point, spot and sun lamps that cast shadows: steps, not ramps."""
    return [light for light in scene.lights if light.kind != "AREA" and light.cast_shadow]


def _light_samples(patches: patching.Patches, settings: RadiositySettings, scale: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The lights' n x n midpoint samples of every patch (`light_samples_per_side`): weights
    (N, S), points (N S, 3) world m, their normals (N S, 3) and the shadow rays' origins, lifted
    RAY_OFFSET_REL x scale off the surface (N S, 3)."""
    points, weights = sample_patches(patches.corners, settings.light_samples_per_side, "midpoint")
    flat = points.reshape(-1, 3)
    normals = np.repeat(patches.normals, points.shape[1], axis=0)
    return weights, flat, normals, flat + RAY_OFFSET_REL * scale * normals


def _never_occluded(origins, directions, t_min, t_max) -> np.ndarray:
    return np.zeros(len(origins), bool)


def shadowed_irradiance(light, points: np.ndarray, normals: np.ndarray, origins: np.ndarray,
                        occluded, area_samples_per_side: int) -> tuple[np.ndarray, np.ndarray]:
    """(M, 3) direct irradiance W/m^2 of `light` at points with unit normals, times its visible
    fraction from `origins` (the points lifted off their surface), and that fraction (M,): 1 where
    the light does not reach, casts no shadow, or `occluded` is None (no shadows)."""
    e = light_units.direct_irradiance(light, points, normals)
    lit = np.flatnonzero(e.max(axis=1) > 0.0)
    vis = np.ones(len(points))
    if occluded is not None and light.cast_shadow and lit.size:
        vis[lit] = light_visibility(light, origins[lit], occluded, area_samples_per_side)
    e *= vis[:, None]
    return e, vis


def light_visibility(light, origins: np.ndarray, occluded, area_samples_per_side: int,
                     per_target: bool = False) -> np.ndarray:
    """(R,) visible fraction of `light` from `origins` (area lights: over an n x n emitter grid);
    with `per_target`, (K, R) float: each grid point's own (`area_light_samples` order)."""
    if light.kind == "SUN":
        dirs = np.broadcast_to(-np.asarray(light.direction, np.float64), origins.shape)
        return 1.0 - np.asarray(occluded(origins, np.ascontiguousarray(dirs), 0.0, np.inf), float)
    if light.kind == "AREA":
        targets = light_units.area_light_samples(light, area_samples_per_side)
    else:
        targets = np.asarray(light.position, np.float64)[None]
    # Every (target, origin) ray in one BVH call: a call costs ~2 ms besides its rays, and an
    # area light has n^2 targets.
    delta = (targets[:, None, :] - origins[None, :, :]).reshape(-1, 3)  # (K R, 3), target-major
    dist = np.linalg.norm(delta, axis=1)
    dirs = delta / np.maximum(dist, 1e-300)[:, None]
    starts = np.ascontiguousarray(np.broadcast_to(origins, (len(targets),) + origins.shape)
                                  .reshape(-1, 3))
    blocked = np.asarray(occluded(starts, dirs, 0.0, dist * (1.0 - LIGHT_END_REL)), bool)
    seen = (~blocked).reshape(len(targets), -1).astype(np.float64)
    return seen if per_target else seen.mean(axis=0)


# samples_per_side "auto" takes one point per patch (its centre) for the hierarchical solver when
# no surface reflects more than this, else 2 x 2. One point's form factors miss a closed box's row
# sum by ~0.1-0.3%, which the solution multiplies by rho / (1 - rho): furnace (closed cube,
# hierarchical, 60 and 400 patch budgets) mean error 0.47-0.82% at rho 0.8 with one point, 2.1%
# at 0.9, 4.8% at 0.95 (2 x 2 points: 0.12-0.22%, 0.55%, 1.2%). At 0.8 one point keeps the issue's
# 1% furnace bound and costs a quarter of the rays (Cornell box, 600 patches: solve 0.38 s against
# 1.0 s, the same error against Cycles). The matrix solvers keep 2 x 2: their rows do not refine
# the near field, and one point misses the row sums by ~0.8% (furnace 1.3% at rho 0.6).
AUTO_ONE_POINT_RHO = 0.8
# Shadow-edge splits before the solve with the final gather. The gather gives every receiver its
# own direct light, but a patch lit on one part and shadowed on the other still sends its mean
# to its neighbours: under a ball over a ground whose 2.8 m patches straddle the ball's shadow,
# the bounce light came out 8% too bright. shadows.blend against a 256-sample Cycles bake:
# 50-patch budget (hierarchical) relMSE 0.0076 -> 0.0014; defaults 0.0021 -> 0.0010, 2.2 -> 3.5 s.
AUTO_SHADOW_SPLITS = 2


def resolve_auto(scene: Scene, settings: RadiositySettings, hierarchical: bool
                 ) -> RadiositySettings:
    """`settings` with its "auto" fields chosen for `scene` and the solver that runs:
    samples_per_side from the largest reflectance of any triangle (base colour and textures at
    the centroid, AUTO_ONE_POINT_RHO; 2 unless `hierarchical`),
    refine_levels from the final gather (which gathers direct light and its shadows at every
    receiver, so the patches carry only smooth indirect light: a refinement level costs a second
    link-and-solve for ~15% less error on the Cornell box, where twice the patches give ~40%),
    shadow_splits from the final gather and the lamps (AUTO_SHADOW_SPLITS where a point, spot or
    sun lamp casts shadows: `hard_shadow_edges`)."""
    from ..shading.direct_light import diffuse_at

    changes = {}
    if settings.samples_per_side == 0:
        count = scene.triangle_count
        rho = diffuse_at(scene, np.arange(count), np.full((count, 3), 1.0 / 3.0),
                         under_layer=False)
        one = hierarchical and float(np.max(rho, initial=0.0)) <= AUTO_ONE_POINT_RHO
        changes["samples_per_side"] = 1 if one else 2
    if settings.refine_levels == -1:
        changes["refine_levels"] = 0 if settings.final_gather else 1
    if settings.shadow_splits == -1:
        hard = settings.final_gather and hard_lamps(scene)
        changes["shadow_splits"] = AUTO_SHADOW_SPLITS if hard else 0
    return replace(settings, **changes) if changes else settings


# --- memory -------------------------------------------------------------------------------------


def memory_estimate(patch_count: int, triangle_count: int, settings: RadiositySettings,
                    solver: str, group_count: int = 0, world_lit: bool = False) -> dict:
    """Bytes each part of a solve needs, and their sum ("total").

    dense_f: N^2 x 8 (Gauss-Seidel only; the clustered solver: G^2 x 8 over `group_count`
    groups, and its (points, groups) factor table); rows: the per-row temporaries of the estimator;
    row_cache: progressive refinement's cached rows; quick_test: method B's pair tables;
    bvh: about 200 bytes per triangle (nodes, leaves, prepared triangles); patches: ~400 B each;
    world_rays: the sky rays' chunk when the world lights the scene (`world_lit`).
    """
    n, t = patch_count, triangle_count
    s = settings.samples_per_side ** 2
    parts = {
        "dense_f": n * n * 8 if solver == "gauss_seidel" else 0,
        "groups": clustered_bytes(group_count) if solver == "clustered" else 0,
        "rows": ROW_BYTES_PER_ELEMENT * s * n * (4 if settings.method == "raycast" else 1),
        "row_cache": min(n * n * 8, settings.dense_memory_limit) if solver == "progressive" else 0,
        "quick_test": quick_test_bytes(n, t) if quick_test_bytes(n, t) <= QUICK_TEST_BYTES else 0,
        "bvh": 200 * (t + (n if settings.method == "hemicube" else 0)),
        "patches": 400 * n,
        "world_rays": sky_ray_bytes(n, settings.world_rays) if world_lit else 0,
    }
    if settings.method == "hemicube":
        parts["rows"] += 3 * settings.hemicube_resolution ** 2 * s * 64
    parts["total"] = int(sum(parts.values()))
    return parts


def clustered_bytes(group_count: int) -> int:
    """The clustered solver's G x G factors and its (receiver points, groups) table."""
    return group_count * group_count * 8 * (1 + max(clusters.CLUSTER_POINTS, 4))


def quick_test_bytes(patch_count: int, triangle_count: int) -> int:
    """Method B's quick unoccluded-pair test: two (T, N) bool tables and a (T, N, 3) float64."""
    return triangle_count * patch_count * (2 + 24)


# auto hands scenes of more patches than this to the hierarchical solver. Measured (Cornell box,
# ~300 patches, refinement on): against Cycles' DIFFUSE bake its mean texel error was 9.1% in
# 6.7 s of test time, Gauss-Seidel's 10.2% in 18.6 s; at 96 patches Gauss-Seidel takes 0.6 s.
AUTO_DENSE_PATCHES = 200


def choose_solver(patch_count: int, settings: RadiositySettings,
                  groups: clusters.Groups | None = None) -> str:
    """The solver "auto" runs over `patch_count` patches (the hierarchical solver aside, which
    `_hierarchical_plan` chooses first): the clustered solver when `groups`
    (`clusters.group_patches`) has at most AUTO_MAX_GROUP_SHARE as many unknowns and fits the
    memory limit; else Gauss-Seidel when the dense matrix fits it, else progressive."""
    if settings.solver != "auto":
        return settings.solver
    if _clustering_pays(patch_count, groups, settings):
        return "clustered"
    return "gauss_seidel" if patch_count ** 2 * 8 <= settings.dense_memory_limit else "progressive"


def _clustering_pays(patch_count: int, groups: clusters.Groups | None,
                     settings: RadiositySettings) -> bool:
    return (settings.clusters and settings.method == "raycast" and groups is not None
            and groups.count <= clusters.AUTO_MAX_GROUP_SHARE * patch_count
            and clustered_bytes(groups.count) <= settings.dense_memory_limit)


# --- one level: form factors and solve ------------------------------------------------------------


def _rows(scene: Scene, patches: patching.Patches, bvh, settings: RadiositySettings):
    corners = patches.corners
    if settings.method == "hemicube":
        from ..geometry.bvh import BVH

        patch_bvh = BVH.build(corners.astype(np.float32))
        hemi = HemicubeSettings(resolution=settings.hemicube_resolution,
                                points_per_side=settings.samples_per_side, seed=settings.seed)
        return HemicubeFormFactors(
            corners, lambda o, d, t0, t1: patch_bvh.intersect(o, d, t0, t1),
            np.arange(len(patches)), hemi)
    ray = RayCastSettings(samples_per_side=settings.samples_per_side,
                          visibility_samples_per_side=settings.visibility_samples_per_side,
                          seed=settings.seed)
    quick = quick_test_bytes(len(patches), scene.triangle_count) <= QUICK_TEST_BYTES
    return RayCastFormFactors(
        corners, lambda o, d, t0, t1: bvh.occluded(o, d, t0, t1),
        triangles=scene.triangles if quick else None, settings=ray)


def _groups(patches: patching.Patches, size: float, settings: RadiositySettings,
            direct: np.ndarray | None = None) -> clusters.Groups | None:
    """`clusters.group_patches` where auto or the clustered solver may use them, else None."""
    if settings.method == "raycast" and settings.solver in ("auto", "clustered"):
        return clusters.group_patches(patches, size, direct)
    return None


def _solve_level(scene, patches, rho, sources, bvh, settings, stats, size: float,
                 scale: float, groups: clusters.Groups | None) -> Iterator[float]:
    """Form factors and solve of one level (patches about `size` m, scene diagonal `scale` m,
    `_groups` of them); yields progress, leaves B in stats["_b"]."""
    count = len(patches)
    solver = choose_solver(count, settings, groups)
    stats["solver"] = solver
    stats["memory_estimate"] = memory_estimate(count, scene.triangle_count, settings, solver,
                                               groups.count if groups is not None else 0,
                                               world_lit(scene))
    start = time.perf_counter()
    if solver == "clustered":
        b, solution = yield from _solve_clustered(patches, groups, rho, sources, bvh, settings,
                                                  stats, RAY_OFFSET_REL * scale)
    elif solver == "gauss_seidel":
        rows = _rows(scene, patches, bvh, settings)
        matrix = np.empty((count, count))
        for p in iter_matrix(rows, matrix):
            yield 0.9 * p
        if settings.method == "hemicube":  # estimated rows: make the pairs agree
            enforce_reciprocity(matrix, patches.areas, out=matrix)
        stats["form_factor_seconds"] = time.perf_counter() - start
        gs = GaussSeidelSolver(matrix, sources, rho,
                               GaussSeidelSettings(tolerance=settings.tolerance))
        for p in gs.run():
            yield 0.9 + 0.1 * p
        solution = gs.solution()
        b = solution.radiosity
    else:
        rows = _rows(scene, patches, bvh, settings)
        # Keep as many rows as the memory limit allows: a patch is shot again and again when
        # rho is high, and a row costs O(N) form factors with rays.
        cache = int(min(count, settings.dense_memory_limit // (8 * count)))
        prog = ProgressiveSolver(rows, sources, rho, patches.areas,
                                 ProgressiveSettings(tolerance=settings.tolerance,
                                                     row_cache=cache,
                                                     max_shots=settings.max_shots or 1_000_000))
        for p in prog.run():
            yield max(p, prog.shots / settings.max_shots) if settings.max_shots else p
        solution = prog.solution()
        b = solution.radiosity
    stats["solve_seconds"] = time.perf_counter() - start
    stats["iterations"] = solution.iterations
    stats["converged"] = bool(solution.converged)
    stats["solver_error"] = float(solution.error)
    stats["_b"] = b


def _solve_clustered(patches, groups, rho, sources, bvh, settings, stats, offset: float):
    """Generator: `_solve_level`'s clustered solver (`clusters.py`, shadow rays lifted `offset`
    m); yields progress, returns (B per patch (N, 3), the solution over the groups)."""
    start = time.perf_counter()
    factors = yield from _scaled(clusters.factor_steps(
        patches, groups, settings.samples_per_side, offset,
        lambda o, d, t0, t1: bvh.occluded(o, d, t0, t1), np.random.default_rng(settings.seed)),
        0.0, 0.9)
    stats["form_factor_seconds"] = time.perf_counter() - start
    stats["groups"] = groups.count
    stats["clustered_patches"] = int(groups.sizes[~groups.lone].sum())
    return (yield from _scaled(clusters.solve_steps(patches, groups, sources, rho, factors,
                                                    settings.tolerance), 0.9, 0.1))


def _scaled(steps, start: float, span: float):
    """Yield from a progress generator with its [0, 1] mapped to [start, start + span]; its
    return value."""
    try:
        while True:
            yield start + span * next(steps)
    except StopIteration as stop:
        return stop.value


def refine_mask(patches: patching.Patches, radiosity: np.ndarray, corner: np.ndarray,
                boundary: np.ndarray, emitted: np.ndarray, threshold: float,
                level: np.ndarray | None = None) -> np.ndarray:
    """(N,) bool: patches to split. A patch is split when a corner's smoothed value differs from
    its own value `radiosity` (N, 3) by more than `threshold` x max(its level's luminance,
    REFINE_FLOOR_REL x the area-weighted mean level), or when it straddles a light's shadow
    boundary. `level` (N, 3): what the difference is measured against (default the value itself).
    Emitters are never split."""
    y = radiosity @ LUMINANCE  # (N,)
    yc = corner @ LUMINANCE  # (N, 3)
    lev = y if level is None else level @ LUMINANCE
    mean = float(np.sum(lev * patches.areas) / max(patches.areas.sum(), 1e-300))
    floor = np.maximum(lev, REFINE_FLOOR_REL * mean)
    deviation = np.abs(yc - y[:, None]).max(axis=1) / np.maximum(floor, 1e-300)
    return ((deviation > threshold) | boundary) & ~np.any(emitted > 0.0, axis=1)


def shadow_edge_splits(edges: np.ndarray, emitted: np.ndarray, areas: np.ndarray,
                       room: int) -> np.ndarray:
    """(N,) bool: the patches a shadow-edge split takes before the solve: those across a hard
    shadow edge (`hard_shadow_edges`), never an emitter, the largest first when there is
    room for fewer splits than that (`room`: (max_patches - patches) // 3, each split adding
    three). emitted (N, 3); areas (N,) m^2."""
    mask = edges & ~np.any(emitted > 0.0, axis=1)
    room = max(room, 0)
    if room >= mask.sum():
        return mask
    keep = np.argsort(-np.where(mask, areas, -np.inf), kind="stable")[:room]
    out = np.zeros_like(mask)
    out[keep] = True
    return out


def refine_splits(patches: patching.Patches, b: np.ndarray, emitted: np.ndarray, rho: np.ndarray,
                  direct: np.ndarray, boundary: np.ndarray, settings: RadiositySettings,
                  scale: float) -> np.ndarray:
    """(N,) bool: the patches the next level splits (`refine_mask` within `max_patches`).

    Without the final gather the patches are what is shown, and they are refined where B is not
    smooth and across shadow boundaries. With it every receiver gathers its own direct light, and
    the patches carry only the indirect part, rho x (what arrived - the first shot): that is the
    field refined, against the patch's whole B (a steep indirect gradient under a bright direct
    light does not show), and shadow boundaries of the direct light need no split."""
    if settings.final_gather:
        field = np.maximum(b - emitted - rho * direct, 0.0)
        boundary = np.zeros_like(boundary)
    else:
        field = b
    corner = patching.corner_values(patches, field, settings.smooth_angle, scale)
    mask = refine_mask(patches, field, corner, boundary, emitted, settings.refine_threshold,
                       level=b)
    return within_budget(mask, field, corner, settings.max_patches)


def split_levels(settings: RadiositySettings) -> int:
    """Levels of leaf splits the hierarchy may make below its first leaves (refinement and
    shadow-edge splits), for its memory bound."""
    return max(settings.refine_levels, 0) + max(settings.shadow_splits, 0)


def hierarchical_memory(scene: Scene, roots: patching.Patches, depth: int, bvh,
                        settings: RadiositySettings, facing: tuple[int, int] | None = None
                        ) -> dict:
    """The hierarchical solver's memory (bytes by part, "total") over `hierarchy_roots`' roots
    and depth, bounded before it links. facing: `facing_roots(roots)` when the caller has it;
    when counted here or given, the result keeps it as "facing" (pairs, most)."""
    def memory(facing=None) -> dict:
        bound = memory_bound(len(roots), depth, settings.link_epsilon,
                             settings.samples_per_side, split_levels(settings),
                             settings.max_patches, facing)
        out = {"links": bound["links"], "patches": bound["elements"], "work": bound["work"],
               "bvh": 200 * scene.triangle_count, "bvh_queries": bvh.settings.query_bytes,
               "world_rays": sky_ray_bytes(settings.max_patches, settings.world_rays)
               if world_lit(scene) else 0}
        out["total"] = int(sum(out.values()))
        out["link_bound"] = bound["link_bound"]
        if facing is not None:
            out["facing"] = tuple(facing)
        return out

    if facing is not None:
        return memory(facing)
    found = memory()
    if found["total"] > settings.dense_memory_limit and len(roots) ** 2 <= FACING_COUNT_PAIRS:
        # Many roots (a room of many small triangles): count the root pairs that can exchange
        # light at all, which only then costs more than a few ms (0.4 s at 3k roots).
        found = memory(facing_roots(roots))
    return found


def _hierarchical_plan(scene: Scene, size: float, bvh, settings: RadiositySettings,
                       exchanging: np.ndarray, patches: patching.Patches,
                       groups: clusters.Groups | None
                       ) -> tuple[RadiositySettings, patching.Patches, int, dict] | None:
    """(settings, roots, depth, memory) of the hierarchical solver when it is the one to run,
    else None. auto picks it for all but small scenes (more than AUTO_DENSE_PATCHES patches)
    when its bound fits `dense_memory_limit` and factors are ray-cast; where only refinement
    breaks the bound, auto lowers `max_patches` (the refined leaves' cap) until it fits
    (`capped_refinement`) rather than hand the scene to a matrix solver. exchanging:
    `exchanging_triangles`; patches: theirs at `size`, what the other solvers would start from;
    groups: their `_groups`."""
    if settings.solver not in ("hierarchical", "auto"):
        return None
    if settings.solver == "auto" and settings.method != "raycast":
        return None
    if settings.solver == "auto":
        # Finely tessellated meshes: their patches solved as groups (`clusters.py`) are far
        # fewer unknowns than the hierarchy's leaves, one or more per triangle.
        if _clustering_pays(len(patches), groups, settings):
            return None
    roots, depth, wanted = hierarchy_roots(scene, size, settings.max_depth, exchanging,
                                           wanted=len(patches))
    memory = hierarchical_memory(scene, roots, depth, bvh, settings)
    if settings.solver == "auto" and memory["total"] > settings.dense_memory_limit:
        settings, memory = capped_refinement(scene, roots, depth, bvh, settings, memory)
    if settings.solver == "auto" and (wanted <= AUTO_DENSE_PATCHES
                                      or memory["total"] > settings.dense_memory_limit):
        return None
    return settings, roots, depth, memory


def capped_refinement(scene: Scene, roots: patching.Patches, depth: int, bvh,
                      settings: RadiositySettings, memory: dict) -> tuple[RadiositySettings, dict]:
    """`settings` with the largest `max_patches` (refined leaves) whose hierarchical bound fits
    `dense_memory_limit`, and that bound; `settings` and `memory` as they are when refinement
    is off or the unrefined leaves alone break it. The fallback would be Gauss-Seidel over the
    refined patches' dense matrix, O(N^2) ray-cast factors: shadows.blend with refine_levels 2
    took 671 s there against 10 s hierarchical."""
    first = len(roots) * 4**depth
    if split_levels(settings) < 1 or settings.max_patches <= first:
        return settings, memory

    facing = memory.get("facing")  # counted by the bound that broke the limit, if at all

    def bound(cap: int) -> dict:
        return hierarchical_memory(scene, roots, depth, bvh, replace(settings, max_patches=cap),
                                   facing)

    low, high = first, settings.max_patches  # bound(low) may fit, bound(high) does not
    if bound(low)["total"] > settings.dense_memory_limit:
        return settings, memory
    while high - low > max(1, first // 100):  # the bound grows with the cap: bisect
        mid = (low + high) // 2
        if bound(mid)["total"] <= settings.dense_memory_limit:
            low = mid
        else:
            high = mid
    return replace(settings, max_patches=low), bound(low)


def within_budget(mask: np.ndarray, radiosity: np.ndarray, corner: np.ndarray,
                  max_patches: int) -> np.ndarray:
    """`mask` (N,) cut to the splits that keep the patches at most `max_patches` (each split adds
    three), keeping those whose corners differ most from their own B (relative)."""
    room = max(max_patches - len(mask), 0) // 3
    if room >= mask.sum():
        return mask
    y = radiosity @ LUMINANCE
    score = np.abs(corner @ LUMINANCE - y[:, None]).max(axis=1) / np.maximum(y, 1e-300)
    keep = np.argsort(-np.where(mask, score, -np.inf))[:room]
    out = np.zeros_like(mask)
    out[keep] = True
    return out


def radiosity_steps(scene: Scene, settings: RadiositySettings = RadiositySettings(),  # noqa: B008
                    bvh=None) -> Iterator[float | RadiosityResult]:
    """Solve the scene's radiosity; yields progress in [0, 1], then a `RadiosityResult`.

    bvh: a `kernels.geometry.bvh.BVH` over `scene.triangles` (built here when None)."""
    from ..geometry.bvh import BVH

    if scene.triangle_count == 0:
        raise ValueError("the scene has no triangles")
    t0 = time.perf_counter()
    scene = with_world_suns(scene)
    flat = scene.triangles.reshape(-1, 3).astype(np.float64)
    scale = float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))
    size = settings.patch_size or patching.auto_patch_size(scene, settings.patch_budget)
    if bvh is None:
        bvh = BVH.build(scene.triangles)
    exchanging = exchanging_triangles(scene)
    # The first patches: auto's test for clusters, the hierarchy's count, the other solvers' mesh.
    patches = patching.make_patches(scene, size, exchanging)
    groups = _groups(patches, size, settings)  # for auto's test; each level regroups
    tree_settings = resolve_auto(scene, settings, hierarchical=True)
    plan = _hierarchical_plan(scene, size, bvh, tree_settings, exchanging, patches, groups)
    if plan is not None:
        tree_settings, roots, depth, memory = plan
        yield from _hierarchical(scene, size, bvh, tree_settings, scale, t0, exchanging, roots,
                                 depth, memory)
        return
    settings = resolve_auto(scene, settings, hierarchical=False)
    if settings.solver == "auto" and _clustering_pays(len(patches), groups, settings):
        # Decided on the first patches, for every level: splits and light octaves add groups,
        # and a dense matrix over the patches they would hand on to costs O(N^2) factors
        # (shadows.blend at a 50-patch budget: 200 s of Gauss-Seidel against 0.7 s clustered).
        settings = replace(settings, solver="clustered")
    yield 0.02
    levels = settings.refine_levels + 1
    stats: dict = {"patch_size_m": size, "levels": []}

    def occluded(o, d, t_min, t_max):
        return bvh.occluded(o, d, t_min, t_max)

    emitters = shot_emitters(scene, settings)
    # Patches across a lamp's hard shadow edge split before the first solve (`shadow_splits`).
    fresh = np.ones(len(patches), bool)  # the patches no shadow-edge test has seen
    for _ in range(settings.shadow_splits):
        tested = patches.subset(fresh)
        mask = np.zeros(len(patches), bool)
        mask[fresh] = shadow_edge_splits(
            hard_shadow_edges(scene, tested, occluded, settings, scale),
            patch_emission(scene, tested), tested.areas, (settings.max_patches - len(patches)) // 3)
        if not mask.any():
            break
        patches, fresh = patching.split_children(scene, patches, mask)
    for level in range(levels):
        rho = patch_reflectance(scene, patches)
        emitted = patch_emission(scene, patches)
        shot = shot_emission(scene, patches, emitters)
        clear = final_gather.clear_shafts(patches, emitters, bvh, RAY_OFFSET_REL * scale,
                                          clusters.CLUSTER_AREA_SHARE * size * size)
        direct, boundary = first_shot(scene, patches, occluded, settings, scale, emitters, clear)
        world = world_shot(scene, patches, bvh, settings, scale)
        sources = emitted - shot + rho * (direct + world)
        if groups is not None and (patches.level > 0).any():
            # Split children, known lit or shadowed now, group apart (`clusters.light_bucket`);
            # without any, these are the first patches and their groups as they were.
            groups = _groups(patches, size, settings, direct)
        level_stats: dict = {"patches": len(patches), "per_level": patches.level_counts()}
        base = 0.02 + 0.96 * level / levels
        for p in _solve_level(scene, patches, rho, sources, bvh, settings, level_stats, size,
                              scale, groups):
            yield base + 0.96 / levels * p
        b = level_stats.pop("_b") + shot
        stats["levels"].append(level_stats)
        if level == levels - 1:
            break
        mask = refine_splits(patches, b, emitted, rho, direct, boundary, settings, scale)
        if not mask.any():
            break
        patches = patching.split(scene, patches, mask)
    last = stats["levels"][-1]
    solved = len(patches)
    patches, (b, emitted, rho, direct, clear, world) = with_idle(
        scene, patches, exchanging, b, emitted, rho, direct, clear, world)
    stats.update(patches=len(patches), idle_patches=len(patches) - solved,
                 per_level=patches.level_counts(), solver=last["solver"],
                 memory_estimate=last["memory_estimate"], method=settings.method)
    result = _result(scene, patches, b, emitted, rho, direct, bvh, settings, scale, stats, t0,
                     emitters, clear, world)
    yield 1.0
    yield result


def _result(scene, patches, b, emitted, rho, direct, bvh, settings: RadiositySettings,
            scale: float, stats: dict, t0: float, emitters, clear, world) -> RadiosityResult:
    """The solved scene, with the final gather prepared when the settings ask for it (clear:
    the patches' `final_gather.clear_shafts`, from the first shot; world: `world_shot`)."""
    # What the patches show: their reflected light under the specular layer (`patch_reflectance`).
    shown = emitted + (b - emitted) * layer_factors(scene)[scene.material_ids[patches.parent]][:, None]
    # One fit for both (their corner groups and CG iterations shared; channels are independent).
    corners = patching.fitted_corner_values(patches, np.hstack([shown, emitted]),
                                            settings.smooth_angle, scale)
    corner_b, corner_e = corners[..., :3], corners[..., 3:]
    # What "auto" chose, for metrics.json.
    stats.update(samples_per_side=settings.samples_per_side, refine_levels=settings.refine_levels,
                 shadow_splits=settings.shadow_splits)
    # The world as a light: its rays per patch (0: black or off) and the suns taken from its map.
    lit_by_world = settings.world_rays if world_lit(scene) else 0
    stats["world"] = {"rays_per_patch": int(lit_by_world),
                      "map_suns": sum(light.name.startswith(WORLD_SUN_NAME)
                                      for light in scene.lights)}
    gather = _prepare_gather(scene, patches, b, emitted, rho, direct, emitters, bvh, settings,
                             stats, clear, world)
    stats["seconds"] = time.perf_counter() - t0
    return RadiosityResult(patches=patches, radiosity=b, emitted=emitted, direct=direct,
                           reflectance=rho, corner_b=corner_b, corner_e=corner_e, stats=stats,
                           gather=gather)


def _prepare_gather(scene, patches, b, emitted, rho, direct, emitters, bvh,
                    settings: RadiositySettings, stats: dict, clear, world) -> FinalGather | None:
    """The final gather's patch-level half, when the settings ask for it (stats: its figures)."""
    if not settings.final_gather:
        return None
    start = time.perf_counter()
    gather = final_gather.prepare(
        scene, patches, b, emitted, rho, direct, emitters, bvh, settings.smooth_angle,
        settings.area_light_samples_per_side, gather_settings(settings), clear, world)
    stats["final_gather"] = {**gather.stats, "prepare_seconds": time.perf_counter() - start}
    return gather


def _hierarchical(scene, size, bvh, settings, scale, t0, exchanging, roots, depth,
                  memory: dict) -> Iterator:
    """`radiosity_steps` with the hierarchical solver (`hierarchical.py`): its patches are the
    leaves of the hierarchy, about `size`, refined as the other solvers refine theirs."""
    from .hierarchical import hierarchical_steps

    def occluded(o, d, t_min, t_max):
        return bvh.occluded(o, d, t_min, t_max)

    emitters = shot_emitters(scene, settings)
    last_clear = {}  # the last level's clear shafts, which the final gather reads again

    def lamps(leaves):
        clear = final_gather.clear_shafts(leaves, emitters, bvh, RAY_OFFSET_REL * scale,
                                          clusters.CLUSTER_AREA_SHARE * size * size)
        last_clear["leaves"] = clear
        return first_shot(scene, leaves, occluded, settings, scale, emitters, clear)

    def world(leaves):
        return world_shot(scene, leaves, bvh, settings, scale)

    for step in hierarchical_steps(scene, roots, depth, occluded, settings, scale, lamps,
                                   emitters, world):
        if isinstance(step, tuple):
            leaves, b, emitted, rho, direct, world, info = step
        else:
            yield 0.02 + 0.96 * step
    memory = {**memory, "links_made": info["links"]}  # bounded before linking, and as made
    solved = len(leaves)
    leaves, (b, emitted, rho, direct, clear, world) = with_idle(
        scene, leaves, exchanging, b, emitted, rho, direct, last_clear["leaves"], world)
    stats = {"patch_size_m": size, "patches": len(leaves), "idle_patches": len(leaves) - solved,
             "per_level": leaves.level_counts(),
             "solver": "hierarchical", "memory_estimate": memory, "method": "raycast",
             "max_patches": settings.max_patches,  # lowered by auto to fit the memory limit
             "hierarchy": info,
             "levels": [{"patches": level["leaves"], "solver": "hierarchical",
                         "iterations": level["iterations"], "solver_error": level["solver_error"],
                         "converged": bool(level["solver_error"] <= settings.tolerance)}
                        for level in info["per_refinement"]]}
    result = _result(scene, leaves, b, emitted, rho, direct, bvh, settings, scale, stats, t0,
                     emitters, clear, world)
    yield 1.0
    yield result


def solve_radiosity(scene: Scene, settings: RadiositySettings = RadiositySettings(),  # noqa: B008
                    bvh=None) -> RadiosityResult:
    """`radiosity_steps` run to the end."""
    result = None
    for step in radiosity_steps(scene, settings, bvh):
        result = step
    return result


# --- outputs: bake targets and the camera view -----------------------------------------------------


@dataclass(frozen=True, eq=False)
class ObjectRadiosityBake:
    """One object's baked outgoing radiance B / pi (W/(m^2 sr), linear RGB)."""

    lightmap: np.ndarray | None  # (S, S, 3) float32, row 0 top, dilated over the padding
    lightmap_mask: np.ndarray | None  # (S, S) bool: texels baked (before dilation)
    corners: np.ndarray  # (T * 3, 3) float32, per triangle corner, scene corner order
    filtered_texels: int = 0  # lightmap texels averaged over sub-texel points (edges)


def bake_steps(scene: Scene, result: RadiosityResult, objects, lightmap_sizes: dict, padding: int,
               texel_filter: TexelFilterSettings = TexelFilterSettings()  # noqa: B008
               ) -> Iterator[float | dict]:
    """Radiance B / pi of `objects` (indices into scene.objects) on their lightmap texels (when
    the scene carries lightmap UVs; sizes {object index: texels per side}), box-filtered over the
    texels an edge crosses as Cycles' bake filters them (`bake_targets.box_filter`), and at their
    corners. Yields progress, then {object index: ObjectRadiosityBake}.

    Every object's points are evaluated together, in three passes: the lightmaps' lattice texels
    and the corners; the texels the lattice cannot give (`bake_targets.lattice_fill`); the edge
    texels' sub-texel points. The later passes reuse what the earlier ones' rays found around a
    point (`final_gather.Visibility`: 10-12% of the bake's seconds on the Cornell box). The
    gather's shadow rays reach the BVH in large batches, and a BVH call costs ~2 ms besides its
    rays (0.6 M rays/s in calls of 2k rays, 1.0 M at 128k on the Cornell box)."""
    from ..bake.bake_targets import (
        apply_box_filter,
        corner_targets,
        dilate,
        filter_samples,
        lattice_plan,
        lightmap_targets,
    )

    lightmaps = {k: lightmap_targets(scene, k, lightmap_sizes[k]) for k in objects
                 if scene.lightmap_uv is not None and scene.objects[k].has_lightmap_uv}
    corners = {k: corner_targets(scene, k) for k in objects}
    plans = {k: lattice_plan(t) if texel_filter.lattice_threshold > 0.0 else None
             for k, t in lightmaps.items()}

    def first_of(k):  # the lightmap positions the first pass evaluates
        return np.arange(len(lightmaps[k])) if plans[k] is None else plans[k].first

    parts = [(lightmaps[k].triangles[first_of(k)], lightmaps[k].bary[first_of(k)])
             for k in lightmaps]
    values, seen = yield from _radiance_steps(result, parts + [(c.triangles, c.bary)
                                                               for c in corners.values()], 0.0, 0.5)
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
    rest, seen = yield from _radiance_steps(
        result, [(lightmaps[k].triangles[todo[k]], lightmaps[k].bary[todo[k]]) for k in lightmaps],
        0.5, 0.3, [texel_seen[k].take(todo[k]) for k in lightmaps])
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
    sampled, _ = yield from _radiance_steps(
        thinned, [(s.triangles, s.bary) for s in samples.values()], 0.8, 0.2,
        [_texel_neighbourhood(lightmaps[k], texel_seen[k], s.which).take(s.owner)
         for k, s in samples.items()])
    out = {}
    for k, corner_values in zip(corners, values[len(lightmaps):], strict=True):
        lightmap = mask = None
        filtered = 0
        if k in lightmaps:
            texels, filtered = apply_box_filter(centre[k], samples[k], sampled.pop(0))
            mask = lightmaps[k].mask
            lightmap = dilate(lightmaps[k].to_image(texels), mask, padding)
        out[k] = ObjectRadiosityBake(lightmap, mask, corner_values.astype(np.float32), filtered)
    yield out


def _lattice_radiance(scene: Scene, result: RadiosityResult, targets, plan, first: np.ndarray,
                      threshold: float) -> tuple[np.ndarray, np.ndarray]:
    """`bake_targets.lattice_fill` of radiance (N, 3) from the lattice's, first (L, 3); returns
    the values and the texels still to evaluate. With the final gather a texel's radiance is
    L_e + rho(x) H(x) / pi, rho sampled at the texel (textures): the lattice interpolates the
    smooth part H / pi and each texel multiplies by its own reflectance, so texture detail between
    lattice texels is kept (irradiance caching caches irradiance, not radiance). Without the
    gather the patches' B is already smooth and is interpolated as it is."""
    from ..bake.bake_targets import lattice_fill

    if result.gather is None:
        return lattice_fill(plan, first, threshold)
    from ..shading.direct_light import diffuse_at

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


def _at_view(scene: Scene, tri: np.ndarray, bary: np.ndarray, dirs: np.ndarray,
             radiance: np.ndarray) -> np.ndarray:
    """(M, 3) radiance (M, 3) W/(m^2 sr) of surface points (triangles, barycentrics) as a
    camera looking along dirs (M, 3) sees it: the reflected part, which the texels show under
    the specular layer along the normal (`layer_factors`), rescaled to the layer at the view
    angle (`specular_layer.view_factors`), as Cycles' diffuse lobe darkens towards grazing.
    The layer's own highlights are not drawn."""
    from ..geometry.scene import interpolated_normals
    from ..shading.specular_layer import view_factors, view_tables

    mids = scene.material_ids[tri]
    tables = view_tables(scene.materials)
    if not (tables < 1.0).any():  # no layer anywhere
        return radiance
    normals = interpolated_normals(scene, tri, bary)
    ratio = view_factors(tables, mids, np.einsum("ij,ij->i", normals, dirs)) / tables[mids, -1]
    emitted = triangle_emission(scene)[tri]
    return emitted + (radiance - emitted) * ratio[:, None]


def _front_frame(scene: Scene, result: RadiosityResult, tri: np.ndarray, bary: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, object, float]:
    """What the view's highlights need of front-facing surface points (triangles, barycentrics):
    their face normals (M, 3), interpolated shading normals turned to the face's side (M, 3),
    the BVH for their rays (the gather's, else built) and the rays' offset off surfaces, m."""
    from ..geometry.bvh import BVH
    from ..geometry.scene import geometric_normals, interpolated_normals

    geometric = geometric_normals(scene.triangles[tri])
    normals = interpolated_normals(scene, tri, bary, geometric)
    normals[np.einsum("ij,ij->i", normals, geometric) < 0.0] *= -1.0
    if result.gather is not None:
        return geometric, normals, result.gather.bvh, result.gather.offset
    flat = scene.triangles.reshape(-1, 3).astype(np.float64)
    offset = RAY_OFFSET_REL * float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))
    return geometric, normals, BVH.build(scene.triangles), offset


def _lamp_highlights(scene: Scene, result: RadiosityResult, tri: np.ndarray, bary: np.ndarray,
                     points: np.ndarray, dirs: np.ndarray, frame: tuple) -> np.ndarray:
    """(M, 3) radiance W/(m^2 sr) the lamps' light leaves toward a camera looking along dirs
    (M, 3) by the rough glossy lobes (specular layers, metals) of surface points (triangles,
    barycentrics, world points (M, 3)): each lamp's shadowed irradiance (an area lamp's grid
    point by point, `_area_lamp_points`) times the GGX lobes
    (`specular_layer.lamp_highlights`), as Cycles lights the glossy lobes directly at the
    camera's first hit. Emissive meshes draw none. frame: `_front_frame` of the points."""
    from ..shading.direct_light import albedo_at, metal_f0
    from ..shading.specular_layer import MIRROR_ROUGHNESS, lamp_highlights, layer_f0

    out = np.zeros((len(tri), 3))
    shiny = [m.roughness >= MIRROR_ROUGHNESS and (m.metallic > 0.0 or (
        layer_f0(m.ior, m.specular) > 0.0 and m.transmission < 1.0)) for m in scene.materials]
    if not scene.lights or not any(shiny) or not len(tri):
        return out
    geometric, normals, bvh, offset = frame
    samples = result.gather.area_samples_per_side if result.gather is not None else 4
    base = metal_f0(scene, tri, albedo_at(scene, tri, bary))
    mids = scene.material_ids[tri]
    for light in scene.lights:
        if light.kind == "AREA":  # its highlight spread over the emitter, point by point
            for to_light, e in _area_lamp_points(light, points, normals,
                                                 points + offset * geometric, bvh.occluded,
                                                 samples):
                out += lamp_highlights(scene.materials, mids, normals, -dirs, to_light, e, base)
            continue
        e, _ = shadowed_irradiance(light, points, normals, points + offset * geometric,
                                   bvh.occluded, samples)
        to_light, _ = light_units.light_vectors(light, points)
        out += lamp_highlights(scene.materials, mids, normals, -dirs, to_light, e, base)
    return out


def _area_lamp_points(light, points: np.ndarray, normals: np.ndarray, origins: np.ndarray,
                      occluded, samples: int):
    """Yields (unit directions (M, 3) to one of the area lamp's n x n grid points, the shadowed
    irradiance W/m^2 (M, 3) that point brings): the lamp's `direct_irradiance` split over its
    grid points in proportion to cos_receiver cos_lamp / d^2, each times its own shadow ray's
    visibility from `origins`. A glossy lobe lit this way draws the emitter's whole extent, not
    a highlight aimed at its centre."""
    targets = light_units.area_light_samples(light, samples)  # (K, 3)
    total = light_units.direct_irradiance(light, points, normals)  # (M, 3)
    delta = targets[:, None, :] - points[None, :, :]  # (K, M, 3)
    dist = np.linalg.norm(delta, axis=2)
    to = delta / np.maximum(dist, 1e-300)[..., None]
    cos_r = np.clip(np.einsum("mj,kmj->km", normals, to), 0.0, None)
    cos_l = np.clip(-to @ np.asarray(light.direction, np.float64), 0.0, None)
    weight = cos_r * cos_l / np.maximum(dist, 1e-300) ** 2  # (K, M)
    share = np.divide(weight, weight.sum(axis=0), out=np.zeros_like(weight),
                      where=weight.sum(axis=0) > 0.0)
    visible = np.ones_like(share)
    if occluded is not None and light.cast_shadow and len(points):
        visible = light_visibility(light, origins, occluded, samples, per_target=True)
    for k in range(len(targets)):
        yield to[k], total * (share[k] * visible[k])[:, None]


def _world_highlights(scene: Scene, tri: np.ndarray, bary: np.ndarray, points: np.ndarray,
                      dirs: np.ndarray, frame: tuple) -> np.ndarray:
    """(M, 3) radiance W/(m^2 sr) the world leaves toward a camera looking along dirs (M, 3) by
    the rough glossy lobes of surface points (triangles, barycentrics, world points (M, 3)), as
    Cycles lights them directly from the world at the camera's first hit (the sky is a light; no
    glossy bounce is needed): one ray along each point's mirror direction stands for the lobe,
    the world's radiance there if it escapes, times the lobe's reflectance at the view: the
    specular layer's directional albedo E(mu) (weight (1 - metallic)(1 - transmission)) and a
    metal's base colour (weight metallic; its Fresnel rise at grazing views left out). Smooth
    lobes (roughness below MIRROR_ROUGHNESS) reflect the world only along a glossy bounce, which
    this model does not follow, as `_lamp_highlights` leaves them out. frame: `_front_frame`."""
    from ..shading.direct_light import albedo_at, metal_f0
    from ..shading.optics import reflect
    from ..shading.specular_layer import MIRROR_ROUGHNESS, layer_f0, view_factors, view_tables

    out = np.zeros((len(tri), 3))
    mats = scene.materials
    layer_w = np.array([(1.0 - m.metallic) * (1.0 - m.transmission)
                        if m.roughness >= MIRROR_ROUGHNESS and layer_f0(m.ior, m.specular) > 0.0
                        else 0.0 for m in mats])
    metal_w = np.array([m.metallic if m.roughness >= MIRROR_ROUGHNESS else 0.0 for m in mats])
    mids = scene.material_ids[tri]
    rows = np.flatnonzero((layer_w[mids] > 0.0) | (metal_w[mids] > 0.0))
    if not world_lit(scene) or rows.size == 0:
        return out
    t, b, d, m = tri[rows], bary[rows], dirs[rows], mids[rows]
    geometric, normals, bvh, offset = frame
    geometric, normals = geometric[rows], normals[rows]
    r = reflect(d, normals)
    up = np.einsum("ij,ij->i", r, geometric) > 0.0  # a mirror direction into the surface: none
    sky = np.zeros(len(rows), bool)
    sky[up] = ~bvh.occluded(points[rows][up] + offset * geometric[up], r[up])
    if not sky.any():
        return out
    albedo = 1.0 - view_factors(view_tables(mats), m, np.einsum("ij,ij->i", normals, d))
    weight = (layer_w[m] * albedo)[:, None] + metal_w[m][:, None] * metal_f0(
        scene, t, albedo_at(scene, t, b))
    out[rows[sky]] = weight[sky] * world_radiance(scene, r[sky])
    return out


def _radiance_steps(result: RadiosityResult, parts: list, start: float, span: float,
                    known: list | None = None):
    """Generator: yields progress in [start, start + span] while it evaluates B / pi at every
    part (triangles (M,), bary (M, 3)) in chunks of `final_gather.GATHER_CHUNK` points, then
    returns the parts' values [(M, 3)] and what the final gather's rays found there
    [`final_gather.Visibility`] (all UNKNOWN without a gather). known: a `Visibility` per part
    that the gather takes without rays, or None."""
    sizes = [len(t) for t, _ in parts]
    tri = np.concatenate([t for t, _ in parts]) if parts else np.zeros(0, np.int64)
    bary = np.concatenate([b for _, b in parts]) if parts else np.zeros((0, 3))
    emitters = 0 if result.gather is None else len(result.gather.emitters.triangles)
    found = final_gather.Visibility.unknown(len(tri), emitters)
    given = final_gather.Visibility.joined(known) if known is not None and parts else None
    values = np.zeros((len(tri), 3))
    chunk = final_gather.GATHER_CHUNK
    for a in range(0, len(tri), chunk):
        rows = slice(a, a + chunk)
        values[rows] = result.radiance_at(
            tri[rows], bary[rows], known=None if given is None else given.take(rows),
            visibility_out=found.take(rows))  # views: the gather writes into `found`
        yield start + span * min(a + chunk, len(tri)) / len(tri)
    bounds = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    return ([values[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)],
            [found.take(slice(a, b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)])


def render_steps(scene: Scene, result: RadiosityResult, resolution=None,
                 out: np.ndarray | None = None, edge_samples: int = EDGE_SAMPLES
                 ) -> Iterator[float | np.ndarray]:
    """The scene camera's view of the solution: outgoing radiance B / pi at the surface each
    pixel centre sees (rasterised), the world colour elsewhere; a surface seen from behind shows
    its back (`RadiosityResult.back_radiance_at`). Edge pixels (silhouettes, folds, hard shadow
    edges: `camera_view.edge_pixels`) are then the mean of edge_samples x edge_samples rays
    through them (`camera_view.supersample_edges`), as Cycles' 1-px box filter averages a pixel
    (0 or 1: the centres only). Yields progress, then (H, W, 3)."""
    from ..bake.camera_view import background_and_fragments, supersample_edges

    image, f = background_and_fragments(scene, resolution, out)
    yield 0.3
    # As the solve lit it: a world map's suns are lamps there, and gone from its map.
    lit = result.gather.scene if result.gather is not None else with_world_suns(scene)

    def shade(f) -> np.ndarray:
        values = np.empty((len(f), 3))
        # Cycles shades a surface on the side it is seen from; the solution is the front's.
        front, back = ~f.back, f.back
        if front.any():
            t, b = f.tri[front], f.bary[front]
            frame = _front_frame(scene, result, t, b)
            values[front] = _at_view(scene, t, b, f.dirs[front], result.radiance_at(t, b))
            values[front] += _lamp_highlights(lit, result, t, b, f.points[front], f.dirs[front],
                                              frame)
            values[front] += _world_highlights(lit, t, b, f.points[front], f.dirs[front], frame)
        if back.any():
            values[back] = result.back_radiance_at(scene, f.tri[back], f.bary[back])
        return values

    if len(f):
        image[f.rows, f.cols] = shade(f)
    yield 0.6
    if edge_samples > 1 and len(f):
        bvh = result.gather.bvh if result.gather is not None else None
        if bvh is None:
            from ..geometry.bvh import BVH

            bvh = BVH.build(scene.triangles)
        supersample_edges(scene, image, f, shade, bvh, edge_samples)
    yield image
