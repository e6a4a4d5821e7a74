"""The settings of a radiosity solve (`RadiositySettings`, the solvers it may name) and of its final
gather (`FinalGatherSettings`, `gather_settings`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Literal

from ..shading.world_light import WORLD_RAYS
from .elements import ELEMENT_PAIRS

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
    |                             |                     |          | lamp's shadow edge split   |
    |                             |                     |          | before the solve (-1 auto: |
    |                             |                     |          | AUTO_SHADOW_SPLITS with the|
    |                             |                     |          | final gather and a lamp    |
    |                             |                     |          | that casts shadows, else 0)|
    | near_splits                 | >= -1               | -1       | times patches that surfaces|
    |                             |                     |          | face nearer than their own |
    |                             |                     |          | size split before the solve|
    |                             |                     |          | (near_field.py; -1 auto:   |
    |                             |                     |          | AUTO_NEAR_SPLITS with the  |
    |                             |                     |          | final gather, for matrix   |
    |                             |                     |          | solvers AUTO_MATRIX_NEAR_  |
    |                             |                     |          | SPLITS, else 0)            |
    | refine_threshold            | > 0                 | 0.25     | relative corner difference |
    |                             |                     |          | that splits a patch        |
    | max_patches                 | >= 0                | 0        | splits and refinement stop |
    |                             |                     |          | here (0 auto: planning's   |
    |                             |                     |          | AUTO_MAX_PATCHES for the   |
    |                             |                     |          | hierarchy, lowered where   |
    |                             |                     |          | its bound would not fit    |
    |                             |                     |          | hierarchy_memory_limit;    |
    |                             |                     |          | AUTO_MATRIX_MAX_PATCHES for|
    |                             |                     |          | the matrix solvers)        |
    | tolerance                   | (0, 1)              | 1e-4     | solver stop (see solvers)  |
    | dense_memory_limit          | >= 0                | 512 MiB  | bytes for the dense F      |
    | hierarchy_memory_limit      | >= 0                | 2 GiB    | bytes the hierarchical     |
    |                             |                     |          | solver's worst-case bound  |
    |                             |                     |          | (links, elements, work) may|
    |                             |                     |          | reach (a worst case: rooms |
    |                             |                     |          | made 2.5-4x fewer links)   |
    | samples_per_side            | >= 0                | 0        | n x n points per patch     |
    |                             |                     |          | (ray-cast sources, hemicube|
    |                             |                     |          | positions); 0 auto: 1 when |
    |                             |                     |          | no reflectance exceeds     |
    |                             |                     |          | AUTO_ONE_POINT_RHO, else 2 |
    | visibility_samples_per_side | >= 1                | 2        | m x m ray targets per patch|
    | hemicube_resolution         | even >= 2           | 32       | hemicube top-face pixels   |
    | light_samples_per_side      | >= 1                | 3        | points per patch side for  |
    |                             |                     |          | the lights' first shot     |
    |                             |                     |          | (fewer past a budget with  |
    |                             |                     |          | the final gather: sources. |
    |                             |                     |          | LIGHT_POINT_BUDGET)        |
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
    |                             |                     |          | world lights no surface;   |
    |                             |                     |          | fewer past a budget:       |
    |                             |                     |          | sources.WORLD_RAY_BUDGET)  |
    | translucent_bounce          | bool                | False    | final gather: translucent  |
    |                             |                     |          | surfaces pass light off    |
    |                             |                     |          | other surfaces too, not    |
    |                             |                     |          | the lights' alone (a model |
    |                             |                     |          | that follows translucent   |
    |                             |                     |          | bounces: two-pass GI)      |
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
    near_splits: int = -1
    refine_threshold: float = 0.25
    max_patches: int = 0
    tolerance: float = 1e-4
    dense_memory_limit: int = 512 << 20
    hierarchy_memory_limit: int = 2 << 30
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
    translucent_bounce: bool = False
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
        if self.patch_size < 0.0 or self.patch_budget < 1 or self.max_patches < 0:
            raise ValueError("patch_size must be >= 0, patch_budget >= 1 and max_patches >= 0")
        if self.refine_levels < -1 or not self.refine_threshold > 0.0:
            raise ValueError("refine_levels must be >= -1 (auto) and refine_threshold > 0")
        if self.shadow_splits < -1 or self.near_splits < -1:
            raise ValueError("shadow_splits and near_splits must be >= -1 (auto), got "
                             f"{self.shadow_splits} and {self.near_splits}")
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
        for f in fields(self):  # nan passes every comparison above (a nan patch size: no patches)
            value = getattr(self, f.name)
            if isinstance(value, float) and not math.isfinite(value):
                raise ValueError(f"{f.name} must be finite, got {value}")


@dataclass(frozen=True)
class FinalGatherSettings:
    """| field            | range    | default | meaning                                          |
    |------------------|----------|---------|--------------------------------------------------|
    | emitter_rays     | >= 1     | 16      | shadow rays per receiver over all emissive       |
    |                  |          |         | triangles (split by their power, >= 1 each)      |
    | max_emitters     | >= 0     | 32      | emissive triangles gathered per receiver; beyond |
    |                  |          |         | this the patch solution carries emitted light    |
    |                  |          |         | (each costs every receiver an exact factor and   |
    |                  |          |         | at least one ray: an emissive sphere of 500      |
    |                  |          |         | triangles would cost 500 rays a texel)           |
    | enclosure_probes | bool     | True    | receivers inside closed solids get no light      |
    | patch_samples    | >= 1     | 2       | n x n enclosure probes per patch (midpoints)     |
    | seed             | int      | 0       | RNG seed of the stratified emitter points        |
    | world_rays       | >= 0     | 0       | rays per receiver seen from behind: the world    |
    |                  |          |         | where they escape, the patch solution where they |
    |                  |          |         | meet a surface (`back_exitance`; 0: direct light |
    |                  |          |         | only there)                                      |
    | translucent_bounce | bool   | False   | a translucent surface passes the light reflected |
    |                  |          |         | onto its far side too (`side_irradiance`)        |
    | element_pairs    | >= 0     | 50000   | element-to-patch pairs the indirect light may be |
    |                  |          |         | gathered over (`elements.py`: patches split into |
    |                  |          |         | 4^k elements while within it; 0: never)          |
    | tilt_rays        | >= 0     | 64      | rays per receiver whose smooth normal leans from |
    |                  |          |         | its face, which gather its indirect light about  |
    |                  |          |         | that normal (`final_gather`'s                    |
    |                  |          |         | `ray_gathered_irradiance`; 0: the patches',      |
    |                  |          |         | about the face)                                  |
    """

    emitter_rays: int = 16
    max_emitters: int = 32
    enclosure_probes: bool = True
    patch_samples: int = 2
    seed: int = 0
    world_rays: int = 0
    translucent_bounce: bool = False
    element_pairs: int = ELEMENT_PAIRS
    tilt_rays: int = 64

    def __post_init__(self) -> None:
        if self.emitter_rays < 1 or self.patch_samples < 1 or self.max_emitters < 0:
            raise ValueError("emitter_rays and patch_samples must be >= 1, max_emitters >= 0")
        if self.world_rays < 0 or self.element_pairs < 0 or self.tilt_rays < 0:
            raise ValueError("world_rays, element_pairs and tilt_rays must be >= 0")


def gather_settings(settings: RadiositySettings) -> FinalGatherSettings:
    """The final gather's settings, and the shot emitters', from the radiosity settings."""
    return FinalGatherSettings(emitter_rays=settings.gather_rays, seed=settings.seed,
                               patch_samples=settings.samples_per_side,
                               world_rays=settings.world_rays,
                               translucent_bounce=settings.translucent_bounce,
                               element_pairs=settings.element_pairs)
