"""The matched Cycles models: what Cycles is set up to compute for each Classic Bake technique.

The four models
---------------
`whitted(depth)`, for the ray tracer: diffuse surfaces see lights directly (diffuse bounces 0),
mirrors and glass are followed up to `depth` glossy/transmission bounces, point and spot lights
are true points (radius 0), suns are parallel (angle 0), no caustics and no glossy filter (both
would change mirrors); alpha surfaces let rays through (up to 8 transparent bounces, Cycles' own
default), as the kernels' seeing and shadow rays do (`geometry/alpha_occlusion.py`). The pixel filter is a
1-px box: each pixel is the average over its area, the limit the tracer's n x n supersampling
converges to.
Remaining differences: Cycles' glass picks reflection or refraction at random with the Fresnel
weight where a Whitted tracer follows both rays weighted: the same expectation, only noise.
Cycles' shadow rays stop at glass as Whitted's do. The world lights no diffuse surface (it is
hidden from diffuse rays, `world_lighting=False`, the default of every model: only the radiosity
solve uses the sky as a light, `radiosity(world_lighting=True)`) and stays visible to the camera,
mirrors and glass, as the tracer returns the world colour for rays that miss. Area lights keep
their size (the tracer samples them on a grid). Cycles lights the Principled specular lobe of
non-mirror surfaces directly (the sample scenes set Specular IOR Level 0 on diffuse surfaces,
which is exactly Lambertian).

`radiosity(diffuse_bounces)`, for diffuse global illumination: glossy and transmission bounces 0,
`diffuse_bounces` diffuse bounces (default 32: a closed box of albedo 0.8 keeps 0.8^32 < 0.1% of
the light), point and spot radius 0, area lights kept (they are the radiosity emitters). Bake
with `bake_type="DIFFUSE"` and the colour pass on: the result is the radiance a Lambertian surface
sends out, L = rho E / pi, so the kernel's radiosity (exitance, W/m^2) is B = pi * L (see
`bakes`, "Bake semantics"). Remaining differences: Cycles evaluates each texel at its own surface point,
a radiosity solver holds B constant per patch (or interpolates it), so patch-sized detail
differs; a Principled specular lobe is lit directly in a camera render (the DIFFUSE bake leaves
it out).

`direct()`, for shadow maps and direct lighting: max_bounces 0, point/spot radius 0, sun angle
0, area lights shrunk to 1 mm squares of the same power (kernels/shading/direct_light.py treats them as
points at their centre: hard shadows, intensity P cos / pi). Remaining differences: shadow maps
filter (PCF) and bias their shadow edges, Cycles' shadows are exact. Lamps are the only lights,
as a real-time engine's shadow-mapped lights are: emissive surfaces glow, and show in mirrors, but
light no diffuse surface (`mesh_lights` off: objects hidden from diffuse rays).

`albedo()`, for texture mapping: the diffuse colour a surface reflects, no light at all. Bakes
take `bake_type="ALBEDO"` (Cycles' DIFFUSE bake with the colour pass alone); camera renders return
Cycles' Diffuse Color pass (`render_pass="DiffCol"`, read from a multilayer OpenEXR) instead of
the combined image, 0 where the camera sees the world (measured with a world of colour (0.3, 0.6,
0.9)). Bounces 0: the colour is the first surface's. Remaining differences: Cycles' diffuse colour
is the Principled base colour x (1 - metallic) x (1 - transmission) x (1 - the directional albedo
of its specular layer). With the default Specular IOR Level 0.5 (F0 = 0.04) it is 3.7% lower seen
along the normal at roughness 0.5 (4.0% at roughness 0, 1.4% at 1), and in renders lower still at
grazing views (5% at 45 degrees, 17% at 70 degrees, roughness 0); bakes see every texel along its
normal. The kernels model it (`kernels/shading/specular_layer.py`): bakes to 0.11%, camera views at each
pixel's view angle, and every camera view draws the layer's lamp highlights (the tracer's
reflections of the surroundings too).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

# The camera renders a model can read besides "Combined": model name -> (the view layer property
# that turns the pass on, the pass's layer names in a multilayer OpenEXR, Blender 4.x's first:
# Blender 5 writes passes under their UI names).
COMBINED_PASS = "Combined"
RENDER_PASSES: dict[str, tuple[str, tuple[str, ...]]] = {
    "DiffCol": ("use_pass_diffuse_color", ("DiffCol", "Diffuse Color")),
    # The shading normal (world space, after Bump and Normal Map nodes): normal maps' checks.
    "Normal": ("use_pass_normal", ("Normal",)),
}


@dataclass(frozen=True)
class CyclesModel:
    """What Cycles is set up to compute for one technique (see the module docstring).

    | field                | range        | meaning                                                |
    |----------------------|--------------|--------------------------------------------------------|
    | name                 | str          | the technique: "whitted", "radiosity" or "direct"      |
    | max_bounces          | >= 0         | Cycles' total bounce limit                             |
    | diffuse_bounces      | >= 0         | diffuse bounces (0: diffuse surfaces see lights only)  |
    | glossy_bounces       | >= 0         | glossy (mirror) bounces                                |
    | transmission_bounces | >= 0         | transmission (glass) bounces                           |
    | transparent_bounces  | >= 0         | transparent-BSDF (alpha) bounces; 0: rays stop there   |
    | volume_bounces       | >= 0         | volume scattering bounces                              |
    | caustics_reflective  | bool         | follow glossy bounces after a diffuse one              |
    | caustics_refractive  | bool         | follow transmission bounces after a diffuse one        |
    | blur_glossy          | >= 0         | Cycles' "Filter Glossy" (0: off; blurs mirrors)        |
    | point_radius_zero    | bool         | point/spot soft size set to 0 m (true point lights)    |
    | sun_angle_zero       | bool         | sun angular diameter set to 0 rad (parallel light)     |
    | area_lights_as_points| bool         | area lights shrunk to AREA_POINT_SIZE squares of the   |
    |                      |              | same power: one-sided points of intensity P cos / pi   |
    | mesh_lights          | bool         | False: emissive surfaces glow but light no diffuse     |
    |                      |              | surface (objects hidden from diffuse rays): lamps      |
    |                      |              | alone light the scene                                  |
    | world_lighting       | bool         | False (default): the world is invisible to diffuse     |
    |                      |              | rays, so it lights no diffuse surface, as in every     |
    |                      |              | kernel but the radiosity solve's world light (still    |
    |                      |              | seen by the camera, mirrors and glass)                 |
    | pixel_filter         | BOX/GAUSSIAN/BLACKMAN_HARRIS | Cycles' pixel filter                   |
    | filter_width         | 0.01..10 px  | its width; BOX 1.0 = the average over the pixel        |
    | seed                 | >= 0         | Cycles' seed (convergence chunks use seed, seed+1, ...) |
    | render_pass          | "Combined" / | what `render_camera` returns: the combined image, or   |
    |                      | RENDER_PASSES| that render pass (e.g. "DiffCol", the diffuse colour;  |
    |                      |              | "Normal", the world-space shading normal)              |
    """

    name: str
    max_bounces: int
    diffuse_bounces: int
    glossy_bounces: int
    transmission_bounces: int
    transparent_bounces: int = 8
    volume_bounces: int = 0
    caustics_reflective: bool = False
    caustics_refractive: bool = False
    blur_glossy: float = 0.0
    point_radius_zero: bool = True
    sun_angle_zero: bool = True
    area_lights_as_points: bool = False
    mesh_lights: bool = True
    world_lighting: bool = False
    pixel_filter: str = "BOX"
    filter_width: float = 1.0
    seed: int = 0
    render_pass: str = COMBINED_PASS

    def __post_init__(self):
        counts = (self.max_bounces, self.diffuse_bounces, self.glossy_bounces,
                  self.transmission_bounces, self.transparent_bounces, self.volume_bounces)
        if min(counts) < 0:
            raise ValueError(f"CyclesModel '{self.name}': bounce counts must be >= 0, got {counts}")
        if self.pixel_filter not in ("BOX", "GAUSSIAN", "BLACKMAN_HARRIS"):
            raise ValueError(f"CyclesModel '{self.name}': unknown pixel filter {self.pixel_filter}")
        if self.render_pass != COMBINED_PASS and self.render_pass not in RENDER_PASSES:
            raise ValueError(f"CyclesModel '{self.name}': unknown render pass {self.render_pass}")

    def fields(self) -> dict[str, Any]:
        """The model as a plain dict (JSON, cache keys). `render_pass` is left out when it is
        "Combined" and `mesh_lights` when true, so the cache keys of models made before they
        existed stay the same."""
        out = dataclasses.asdict(self)
        if self.render_pass == COMBINED_PASS:
            del out["render_pass"]
        if self.mesh_lights:
            del out["mesh_lights"]
        return out


def whitted(depth: int = 8, *, world_lighting: bool = False, seed: int = 0) -> CyclesModel:
    """The Whitted ray tracer's model (kernels/trace/tracer.py): `depth` mirror/glass bounces, direct
    light on diffuse surfaces, the world seen only by rays that miss everything."""
    return CyclesModel(name="whitted", max_bounces=depth, diffuse_bounces=0, glossy_bounces=depth,
                       transmission_bounces=depth, world_lighting=world_lighting, seed=seed)


def radiosity(diffuse_bounces: int = 32, *, world_lighting: bool = False,
              seed: int = 0) -> CyclesModel:
    """Diffuse global illumination only: `diffuse_bounces` bounces, no glossy or transmission."""
    return CyclesModel(name="radiosity", max_bounces=diffuse_bounces,
                       diffuse_bounces=diffuse_bounces, glossy_bounces=0, transmission_bounces=0,
                       world_lighting=world_lighting, seed=seed)


def global_illumination(depth: int = 16, *, caustics: bool = False, world_lighting: bool = False,
                        seed: int = 0) -> CyclesModel:
    """Full global illumination: diffuse, glossy and transmission bounces to `depth`, the
    two-pass renderer's reference (kernels/hybrid/). `caustics` on adds the paths neither pass
    carries (lamp -> mirror or glass -> diffuse), to measure their share."""
    return CyclesModel(name="global_illumination", max_bounces=depth, diffuse_bounces=depth,
                       glossy_bounces=depth, transmission_bounces=depth,
                       caustics_reflective=caustics, caustics_refractive=caustics,
                       world_lighting=world_lighting, seed=seed)


def direct(*, area_lights_as_points: bool = True, world_lighting: bool = False,
           seed: int = 0) -> CyclesModel:
    """Direct light only (kernels/shading/direct_light.py: shadow maps): no bounce at all, area lights
    as points at their centre (hard shadows), lamps the only lights, as that kernel treats them."""
    return CyclesModel(name="direct", max_bounces=0, diffuse_bounces=0, glossy_bounces=0,
                       transmission_bounces=0, area_lights_as_points=area_lights_as_points,
                       mesh_lights=False,
                       world_lighting=world_lighting, seed=seed)


def albedo(seed: int = 0) -> CyclesModel:
    """The texture-mapping technique's model: the diffuse albedo of each surface, no light.
    Renders return Cycles' Diffuse Color pass (0 where the camera sees the world); bake it with
    `bake_type="ALBEDO"`. No bounces: the colour is the first surface's (`bakes`, "Bake semantics")."""
    return CyclesModel(name="albedo", max_bounces=0, diffuse_bounces=0, glossy_bounces=0,
                       transmission_bounces=0, seed=seed, render_pass="DiffCol")


MODELS: dict[str, Callable[..., CyclesModel]] = {
    "whitted": whitted, "radiosity": radiosity, "direct": direct, "albedo": albedo,
    "global_illumination": global_illumination,
}
