"""The Whitted tracer's settings, the automatic choice of them, and what a trace returns."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ..geometry.scene import Scene
from ..shading.bump import SHADING_MODES, ShadingMode
from ..shading.specular_layer import MIRROR_ROUGHNESS

# A new ray starts this fraction of the scene's size off its surface, along the geometric normal:
# float32 triangles locate a hit to ~1e-7 of the coordinates' magnitude, so 1e-5 clears the surface
# with two orders of magnitude to spare while staying invisible (0.1 mm in a 10 m scene).
DEFAULT_OFFSET_SCALE = 1e-5
# Default branch weight below which the ray tree stops: a cut branch changes its pixel by < 1%.
MIN_WEIGHT = 1e-2
# Texture boxes per side over each camera sample's cell of the image (the pixel / n): the box
# filter the pixel applies to the image, applied to the base colour seen directly at the cost of
# texture look-ups instead of rays. On the ray-tracing sample 3 x 3 boxes reach the error of 4 x 4
# in less time; 2 x 2 raised the error by 12% with edges.
TEXTURE_FILTER = 3
# Rays a rough lobe that is all a hit reflects (a metal) takes from a camera hit; a faint layer
# over a light base takes one. 8 against 4: 7-10% less error against Cycles on glTF test assets
# of rough lobes, for about a third more time on them.
LOBE_RAYS = 8


@dataclass(frozen=True)
class TracerSettings:
    """| field            | range    | default | meaning                                              |
    |------------------|----------|---------|------------------------------------------------------|
    | max_depth        | 0..64    | 8       | bounces (Cycles' Max Bounces): lamps light the hits  |
    |                  |          |         | of up to max_depth mirror or glass bounces; the rays |
    |                  |          |         | one bounce further see only what shines (emitters,   |
    |                  |          |         | area lamps, the world)                               |
    | supersample      | 1..16    | 1       | n: n x n stratified samples in every pixel           |
    | adaptive         | 0..16    | 4       | n x n samples again in pixels at edges (0: off)      |
    | min_weight       | 0..1     | 1e-2    | a branch whose throughput falls below stops          |
    | offset_scale     | >= 0     | 1e-5    | ray offset, fraction of the scene's size (0: acne)   |
    | area_samples     | 1..16    | 4       | per side of an area light / emissive triangle grid   |
    | point_like_ratio | >= 0     | 0.05    | emitters smaller than this x distance act as points   |
    | mirror_roughness | 0..1     | 0.1     | rougher metals, layers and glass get lamp highlights |
    |                  |          |         | and one reflected (and refracted) ray for the lobe   |
    | lobe_rays        | 1..64    | 8       | rays a camera hit's rough glossy lobe (roughness at  |
    |                  |          |         | least mirror_roughness) reflects its surroundings    |
    |                  |          |         | along: ceil(share x lobe_rays), share the lobe's     |
    |                  |          |         | part of the light the hit reflects in its strongest  |
    |                  |          |         | channel, directions from GGX's visible normals       |
    |                  |          |         | (`glossy_lobe.py`); 1: the mirror direction alone    |
    | shading          | flat, gouraud, | bump | normals: the triangles' own (flat); light at the  |
    |                  | phong, bump |      | corners, interpolated (gouraud); the corners'        |
    |                  |          |         | normals interpolated (phong); those perturbed by     |
    |                  |          |         | normal and height maps (bump, `bump.py`)             |
    | texture_filter   | 1..16    | 3       | g: the base colour is averaged over each sample's    |
    |                  |          |         | pixel cell in k x k boxes, k = g/n rounded up (edge   |
    |                  |          |         | sub-samples: g/a rounded up), seen directly           |
    |                  |          |         | or in mirrors and glass (ray differentials);          |
    |                  |          |         | 1: point sampling, no filter                          |
    | output           | radiance,| radiance| what a camera ray returns: the light it carries, or  |
    |                  | albedo   |         | the diffuse albedo it sees first, textures filtered  |
    |                  |          |         | over the pixel (0 where it misses: Cycles' Diffuse   |
    |                  |          |         | Color pass; texture mapping's view)                   |
    """

    max_depth: int = 8
    supersample: int = 1
    adaptive: int = 4
    # 1%: on the ray-tracing sample scene 1e-3 cost 52% more time for 2% less relative MSE.
    min_weight: float = MIN_WEIGHT
    offset_scale: float = DEFAULT_OFFSET_SCALE
    area_samples: int = 4
    point_like_ratio: float = 0.05
    mirror_roughness: float = MIRROR_ROUGHNESS
    lobe_rays: int = LOBE_RAYS
    texture_filter: int = TEXTURE_FILTER
    shading: ShadingMode = "bump"
    output: Literal["radiance", "albedo"] = "radiance"

    def __post_init__(self):
        if self.output not in ("radiance", "albedo"):
            raise ValueError(f"output must be 'radiance' or 'albedo', got {self.output!r}")
        if self.shading not in SHADING_MODES:
            raise ValueError(f"shading must be one of {SHADING_MODES}, got {self.shading!r}")
        if not 0 <= self.max_depth <= 64:
            raise ValueError(f"max_depth must be in [0, 64], got {self.max_depth}")
        if not 1 <= self.supersample <= 16 or not 0 <= self.adaptive <= 16:
            raise ValueError("supersample must be in [1, 16] and adaptive in [0, 16]")
        if not 1 <= self.lobe_rays <= 64:
            raise ValueError(f"lobe_rays must be in [1, 64], got {self.lobe_rays}")
        if not 1 <= self.texture_filter <= 16:
            raise ValueError(f"texture_filter must be in [1, 16], got {self.texture_filter}")
        if self.offset_scale < 0 or self.min_weight < 0:
            raise ValueError("offset_scale and min_weight must be >= 0")
        floats = {"min_weight": self.min_weight, "offset_scale": self.offset_scale,
                  "point_like_ratio": self.point_like_ratio,
                  "mirror_roughness": self.mirror_roughness}
        for name, value in floats.items():  # nan passes every comparison above
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f"{name} must be finite and >= 0, got {value}")
        if self.min_weight > 1.0 or self.mirror_roughness > 1.0:
            raise ValueError("min_weight and mirror_roughness must be in [0, 1]")


def auto_settings(scene: Scene, **overrides) -> TracerSettings:
    """Settings chosen from the scene: a ray tree only as deep as its specular materials need.

    No mirror or glass: depth 0 (camera rays and shadow rays are all there is to trace). Mirrors
    only: 4 bounces. Glass: each transmissive object can take 4 interfaces (in and out of a
    hollow shell), plus 2 for mirrors around them, capped at 16.
    """
    used = set(np.unique(scene.material_ids).tolist()) if scene.triangle_count else set()
    for variants in scene.map_variants:  # a ray hit may take any variant of a material it meets
        family = set(variants.ids.ravel().tolist())
        if used & family:
            used |= family
    mats = [scene.materials[m] for m in used]
    glassy = {scene.objects[o].name for o in np.unique(scene.object_ids[np.isin(
        scene.material_ids, [m for m in used if scene.materials[m].transmission > 0])])}
    mirrors = any(m.metallic > 0 or m.specular > 0 for m in mats)
    if glassy:
        depth = min(16, 2 + 4 * len(glassy))
    elif mirrors:
        depth = 4
    else:
        depth = 0
    params = {"max_depth": depth}
    params.update(overrides)
    return TracerSettings(**params)


@dataclass
class TraceStats:
    """What the tracer did: rays per kind and how many branches the weight threshold cut."""

    camera_rays: int = 0
    secondary_rays: int = 0
    shadow_rays: int = 0
    clear_shadow_rays: int = 0  # shadow rays not cast: their triangle sees the light whole
    lobe_rays: int = 0  # reflected rays across rough glossy lobes (in place of mirror rays)
    pruned_branches: int = 0  # reflected/refracted rays not traced because their weight was small
    depth_limited: int = 0  # hits one bounce past max_depth that would reflect or refract further
    edge_pixels: int = 0
    hot_pixels: int = 0  # pixels traced again for a highlight smaller than themselves
    rays_per_depth: list = field(default_factory=list)
    # Seconds per phase, exclusive of nested phases, in all and per depth (`PhaseClock.as_dict`).
    phases: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass
class TraceResult:
    image: np.ndarray  # (H, W, 3) float32 linear radiance, row 0 top
    stats: TraceStats
    settings: TracerSettings
