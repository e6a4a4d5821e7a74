"""Cycles as the reference: matched settings, timed renders and bakes, a cache and a sample ladder.

Every Classic Bake technique is measured against Cycles computing the SAME quantity. This module
sets Cycles up for that (`CyclesModel`, `configure`, `matched_scene`), renders the camera or bakes
lightmaps and colour attributes with the wall time of Cycles' own work (`render_camera`,
`bake_lightmaps`, `bake_color_attributes`), caches converged references on disk (`reference`) and
runs sample ladders that can be interleaved with kernel runs (`ladder_step`, `sample_ladder`).

The four models
---------------
`whitted(depth)`, for the ray tracer: diffuse surfaces see lights directly (diffuse bounces 0),
mirrors and glass are followed up to `depth` glossy/transmission bounces, point and spot lights
are true points (radius 0), suns are parallel (angle 0), no caustics and no glossy filter (both
would change mirrors), no transparent bounces. The pixel filter is a 1-px box: each pixel is the
average over its area, the limit the tracer's n x n supersampling converges to.
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
"Bake semantics"). Remaining differences: Cycles evaluates each texel at its own surface point,
a radiosity solver holds B constant per patch (or interpolates it), so patch-sized detail
differs; a Principled specular lobe is lit directly in a camera render (the DIFFUSE bake leaves
it out).

`direct()`, for shadow maps and direct lighting: max_bounces 0, point/spot radius 0, sun angle
0, area lights shrunk to 1 mm squares of the same power (kernels/direct_light.py treats them as
points at their centre: hard shadows, intensity P cos / pi). Remaining differences: shadow maps
filter (PCF) and bias their shadow edges, Cycles' shadows are exact; emissive meshes light
surfaces in Cycles, not in that kernel.

`albedo()`, for texture mapping: the diffuse colour a surface reflects, no light at all. Bakes
take `bake_type="ALBEDO"` (Cycles' DIFFUSE bake with the colour pass alone); camera renders return
Cycles' Diffuse Color pass (`render_pass="DiffCol"`, read from a multilayer OpenEXR) instead of
the combined image, 0 where the camera sees the world (measured with a world of colour (0.3, 0.6,
0.9)). Bounces 0: the colour is the first surface's. Remaining differences: Cycles' diffuse colour
is the Principled base colour x (1 - metallic) x (1 - transmission) x (1 - the directional albedo
of its specular layer). With the default Specular IOR Level 0.5 (F0 = 0.04) it is 3.7% lower seen
along the normal at roughness 0.5 (4.0% at roughness 0, 1.4% at 1), and in renders lower still at
grazing views (5% at 45 degrees, 17% at 70 degrees, roughness 0); bakes see every texel along its
normal. The kernels model it (`kernels/specular_layer.py`): bakes to 0.11%, camera views at each
pixel's view angle, and every camera view draws the layer's lamp highlights (the tracer's
reflections of the surroundings too).

Settings every model shares (`FIXED_SETTINGS`): Cycles on the CPU, denoising and adaptive
sampling off, no sample clamping, no fast-GI approximation, no time limit, view-layer sample
counts ignored, seed fixed (`CyclesModel.seed`), film exposure scale 1, opaque film, compositor
and sequencer bypassed, one view layer, no border, no motion blur, path guiding off. The view
transform is left alone: renders are written as scene-linear OpenEXR, which no view transform or
look touches (tests/blender/test_cycles_reference.py renders with AgX and a view exposure of +2).

Bake semantics (measured, Blender 5.2.3 and 4.5.15; tests re-measure them)
---------------------------------------------------------------------------
A plane of albedo rho, Principled with Specular IOR Level 0 (exactly Lambertian), under a sun,
black world; E = sun strength x cos(incidence) is the irradiance on the plane:

| bake_type | pass filter                       | texel value             |
|-----------|-----------------------------------|-------------------------|
| DIFFUSE   | DIRECT, INDIRECT, COLOR (default) | rho E / pi   (radiance)  |
| DIFFUSE   | DIRECT, INDIRECT                  | E / pi       (radiance / albedo, i.e. irradiance / pi) |
| COMBINED  | all                               | rho E / pi   (+ emission, glossy, transmission) |
| SHADOW    | none, with max_bounces 0          | 1 lit, 0 shadowed       |
| ALBEDO    | COLOR (Blender bake type DIFFUSE) | rho = base x (1 - metallic) x (1 - transmission), no light |

ALBEDO, measured on a plane of base colour (0.2, 0.5, 0.8) with Specular IOR Level 0 under a sun
or a point light and a world of (0.3, 0.6, 0.9): metallic 0.5 bakes (0.1, 0.25, 0.4), metallic
0.5 with transmission 0.5 (0.05, 0.125, 0.2), to 6e-9, in lightmaps and colour attributes alike;
the Diffuse Color pass of a render gives the same values on the plane's pixels and exactly 0 on
the background's. (Default Specular IOR Level 0.5: (0.0963, 0.2407, 0.3850), see `albedo()`
above.) Checker and Image Textures through the UVs bake their colour per texel; a bake's samples
spread over the texel, so a texel on a texture edge may mix both sides (5.2.3: one sample of 16
on a checker edge; 4.5.15: none), while texels inside a texture's texel match it to 1.2e-7.

Baked texels get alpha 1, untouched ones keep the alpha 0 the image starts with: that alpha is
the coverage mask returned with each lightmap (with margin 0 the texels Cycles' rasteriser gives
to a UV triangle, for an axis-aligned UV square exactly those whose centres lie inside it; a
margin > 0 adds the dilated texels). A colour-attribute bake of a vertex gives the same values
at the vertex's position (a point light over a 3 x 3 grid agrees with rho I cos / (pi d^2)).

Timing
------
`seconds` is the wall time of `bpy.ops.render.render` or `bpy.ops.object.bake` alone: scene
synchronisation (BVH, shaders, images) and path tracing, not the file I/O around them. The first
Cycles render in a process pays one-off start-up costs; `warm_up()` pays them on a tiny render.
See `warm_up` for the measured figures.

Converged references
--------------------
`reference(..., samples=None)` chooses the sample count from the scene's own noise: two
independent halves (different seeds) are rendered at n samples each and the relative MSE between
them (`kernels.measure.metrics.rel_mse`, over the covered pixels or texels) is measured; while it is
above `target_rel_mse` (default 1e-4) each half gets n more samples (a render with a new seed,
averaged in) until the total reaches `max_samples`. The reference is the mean of both halves
(2n samples); its own expected relative MSE against the converged image is a quarter of the
halves' (two independent halves differ by twice the variance of one; their mean has half of it).
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import bpy
import mathutils
import numpy as np

from ..kernels.bake.lightmap_uv import LightmapUVSettings
from ..kernels.measure.exr import read_exr, read_exr_pass, write_exr
from ..kernels.measure.metrics import rel_mse
from ..kernels.shading.lights import area_of_shape
from . import bridge

BakeType = Literal["DIFFUSE", "COMBINED", "SHADOW", "ALBEDO"]
ReferenceKind = Literal["render", "bake", "attribute"]

# --- named constants ------------------------------------------------------------------------------

# Pass filters of `bpy.ops.object.bake` per bake type (the operator's enum-flag names).
PASS_FILTERS: dict[str, frozenset[str]] = {
    "DIFFUSE": frozenset({"DIRECT", "INDIRECT", "COLOR"}),
    "COMBINED": frozenset({"EMIT", "DIRECT", "INDIRECT", "DIFFUSE", "GLOSSY", "TRANSMISSION"}),
    "SHADOW": frozenset(),
    "ALBEDO": frozenset({"COLOR"}),  # the diffuse colour alone: no light at all
}
# Blender's bake type for each of ours that Blender names differently (the rest are the same):
# ALBEDO is Cycles' DIFFUSE bake with the colour pass alone.
BLENDER_BAKE_TYPES: dict[str, str] = {"ALBEDO": "DIFFUSE"}
# The camera renders a model can read besides "Combined": model name -> (the view layer property
# that turns the pass on, the pass's layer names in a multilayer OpenEXR, Blender 4.x's first:
# Blender 5 writes passes under their UI names).
COMBINED_PASS = "Combined"
RENDER_PASSES: dict[str, tuple[str, tuple[str, ...]]] = {
    "DiffCol": ("use_pass_diffuse_color", ("DiffCol", "Diffuse Color")),
}
# A baked texel has alpha 1 and an untouched one alpha 0: anything above one half is baked.
COVERED_ALPHA = 0.5
# Default relative MSE between the two independent halves at which a reference counts as converged:
# the mean of both then sits about 2.5e-5 (0.5% RMS) from the converged image.
TARGET_REL_MSE = 1e-4
# Samples per half a convergence search starts from: fewer give a too noisy noise estimate.
START_SAMPLES = 8
# Default cap on a reference's total samples (both halves): 1024 samples of the Cornell box at
# 256 x 256 take about three minutes on a 2-core machine (cycles_facts.md: 2-2.5 us/pixel-sample).
MAX_SAMPLES = 1024
# Side (m) of the square an area light is shrunk to when a model treats area lights as points:
# at 0.1 m from the receiver it differs from a point emitter by (size / distance)^2 = 1e-4.
AREA_POINT_SIZE = 1e-3
# Size of the warm-up render (pixels per side) and its sample count.
WARM_UP_PIXELS = 8
WARM_UP_SAMPLES = 1
# Bump this when what a cached reference means changes; it is part of every cache key.
CACHE_FORMAT = 1
# Prefix of every temporary datablock (images, materials, attributes) this module creates.
TEMP_PREFIX = "classic_bake_cycles"

# The render output used to read renders back: lossless float32 OpenEXR in the scene's linear
# space. `file_format` comes first: the valid depths and modes depend on it. Before it, Blender 5's
# `media_type` (4.5 has none: skipped), whose multilayer or video setting would refuse OPEN_EXR.
EXR_OUTPUT: tuple[tuple[str, str], ...] = (
    ("media_type", "IMAGE"),
    ("file_format", "OPEN_EXR"),
    ("color_depth", "32"),
    ("color_mode", "RGB"),
    ("exr_codec", "ZIP"),
    ("color_management", "FOLLOW_SCENE"),
)
# The output used to read a pass other than Combined: every pass in one multilayer float32
# OpenEXR (always scene-linear). Blender 5 writes one part per pass, 4.5 a single part:
# `read_exr_pass` reads both.
MULTILAYER_EXR_OUTPUT: tuple[tuple[str, str], ...] = (
    ("media_type", "MULTI_LAYER_IMAGE"),
    ("file_format", "OPEN_EXR_MULTILAYER"),
    ("color_depth", "32"),
    ("exr_codec", "ZIP"),
    ("color_management", "FOLLOW_SCENE"),
)
# Cycles and render settings every model uses: (owner, property, value), the owner an attribute
# path from the scene ("cycles" is scene.cycles). Properties missing in a Blender version are
# skipped.
FIXED_SETTINGS: tuple[tuple[str, str, Any], ...] = (
    ("render", "engine", "CYCLES"),
    ("cycles", "device", "CPU"),  # the kernels are CPU code; compare like with like
    ("cycles", "use_denoising", False),  # a denoiser changes values (cycles_facts.md)
    ("cycles", "use_adaptive_sampling", False),  # every pixel gets exactly `samples`
    ("cycles", "time_limit", 0.0),  # a time limit would cut the sample count
    ("cycles", "use_layer_samples", "IGNORE"),  # view-layer sample overrides would too
    ("cycles", "use_sample_subset", False),
    ("cycles", "sample_offset", 0),
    ("cycles", "use_animated_seed", False),  # the seed is the model's, not the frame's
    ("cycles", "auto_scrambling_distance", False),  # correlated samples bias low sample counts
    ("cycles", "scrambling_distance", 1.0),
    ("cycles", "sample_clamp_direct", 0.0),  # clamping removes energy: no clamp
    ("cycles", "sample_clamp_indirect", 0.0),  # (factory default 10 would clip bright bounces)
    ("cycles", "use_fast_gi", False),  # the AO approximation of indirect light
    ("cycles", "use_guiding", False),  # path guiding: training makes runs non-deterministic
    ("cycles", "film_exposure", 1.0),  # Cycles' linear film scale: 1 leaves radiance as is
    ("render", "film_transparent", False),  # the background is part of the compared image
    ("render", "use_compositing", False),  # the raw Cycles result, not a composite
    ("render", "use_sequencer", False),
    ("render", "use_single_layer", True),
    ("render", "use_border", False),  # the whole frame, as the kernels render it
    ("render", "use_motion_blur", False),  # the kernels have no shutter
)


# --- the models -----------------------------------------------------------------------------------


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
    | world_lighting       | bool         | False (default): the world is invisible to diffuse     |
    |                      |              | rays, so it lights no diffuse surface, as in every     |
    |                      |              | kernel but the radiosity solve's world light (still    |
    |                      |              | seen by the camera, mirrors and glass)                 |
    | pixel_filter         | BOX/GAUSSIAN/BLACKMAN_HARRIS | Cycles' pixel filter                   |
    | filter_width         | 0.01..10 px  | its width; BOX 1.0 = the average over the pixel        |
    | seed                 | >= 0         | Cycles' seed (convergence chunks use seed, seed+1, ...) |
    | render_pass          | "Combined" / | what `render_camera` returns: the combined image, or   |
    |                      | RENDER_PASSES| that render pass (e.g. "DiffCol", the diffuse colour)  |
    """

    name: str
    max_bounces: int
    diffuse_bounces: int
    glossy_bounces: int
    transmission_bounces: int
    transparent_bounces: int = 0
    volume_bounces: int = 0
    caustics_reflective: bool = False
    caustics_refractive: bool = False
    blur_glossy: float = 0.0
    point_radius_zero: bool = True
    sun_angle_zero: bool = True
    area_lights_as_points: bool = False
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
        "Combined", so the cache keys of models made before it existed stay the same."""
        out = dataclasses.asdict(self)
        if self.render_pass == COMBINED_PASS:
            del out["render_pass"]
        return out


def whitted(depth: int = 8, *, world_lighting: bool = False, seed: int = 0) -> CyclesModel:
    """The Whitted ray tracer's model (kernels/tracer.py): `depth` mirror/glass bounces, direct
    light on diffuse surfaces, the world seen only by rays that miss everything."""
    return CyclesModel(name="whitted", max_bounces=depth, diffuse_bounces=0, glossy_bounces=depth,
                       transmission_bounces=depth, world_lighting=world_lighting, seed=seed)


def radiosity(diffuse_bounces: int = 32, *, world_lighting: bool = False,
              seed: int = 0) -> CyclesModel:
    """Diffuse global illumination only: `diffuse_bounces` bounces, no glossy or transmission."""
    return CyclesModel(name="radiosity", max_bounces=diffuse_bounces,
                       diffuse_bounces=diffuse_bounces, glossy_bounces=0, transmission_bounces=0,
                       world_lighting=world_lighting, seed=seed)


def direct(*, area_lights_as_points: bool = True, world_lighting: bool = False,
           seed: int = 0) -> CyclesModel:
    """Direct light only (kernels/direct_light.py: shadow maps): no bounce at all, area lights
    as points at their centre (hard shadows), as that kernel treats them."""
    return CyclesModel(name="direct", max_bounces=0, diffuse_bounces=0, glossy_bounces=0,
                       transmission_bounces=0, area_lights_as_points=area_lights_as_points,
                       world_lighting=world_lighting, seed=seed)


def albedo(seed: int = 0) -> CyclesModel:
    """The texture-mapping technique's model: the diffuse albedo of each surface, no light.
    Renders return Cycles' Diffuse Color pass (0 where the camera sees the world); bake it with
    `bake_type="ALBEDO"`. No bounces: the colour is the first surface's (see "Bake semantics")."""
    return CyclesModel(name="albedo", max_bounces=0, diffuse_bounces=0, glossy_bounces=0,
                       transmission_bounces=0, seed=seed, render_pass="DiffCol")


MODELS: dict[str, Callable[..., CyclesModel]] = {
    "whitted": whitted, "radiosity": radiosity, "direct": direct, "albedo": albedo,
}


# --- changing settings and putting them back ------------------------------------------------------


class SettingsLog:
    """An undo log of RNA property changes: `set` remembers the old value, `restore` puts every
    changed value back in reverse order (so a property set twice ends as it was before both)."""

    def __init__(self):
        self._changes: list[tuple[Any, str, Any]] = []

    def set(self, owner, prop: str, value) -> None:
        old = getattr(owner, prop)
        if old == value:
            return
        self._changes.append((owner, prop, old))
        setattr(owner, prop, value)

    @property
    def changed(self) -> list[tuple[str, str]]:
        """(owner description, property) of every change, in order."""
        return [(repr(owner), prop) for owner, prop, _ in self._changes]

    def restore(self) -> None:
        while self._changes:
            owner, prop, old = self._changes.pop()
            setattr(owner, prop, old)


def _owner(scene, path: str):
    owner = scene
    for part in path.split("."):
        owner = getattr(owner, part)
    return owner


def _scene_lights(scene) -> list:
    """(light datablock, first object using it) of the scene's lights, each datablock once."""
    seen: dict[int, Any] = {}
    for obj in scene.objects:
        if obj.type == "LIGHT":
            seen.setdefault(obj.data.as_pointer(), (obj.data, obj))
    return list(seen.values())


def configure(scene, model: CyclesModel, log: SettingsLog | None = None) -> SettingsLog:
    """Set `scene` up so that Cycles computes what `model` describes. Returns the undo log
    (`log.restore()` puts everything back); prefer `matched_scene`, which always restores.

    Changes `FIXED_SETTINGS`, the bounce, caustics, filter and seed settings of scene.cycles, the
    radius of point/spot lights and the angle of suns of the scene (per the model), and with
    `world_lighting` off the world's diffuse ray visibility. The view transform is not touched.
    """
    log = log if log is not None else SettingsLog()
    for path, prop, value in FIXED_SETTINGS:
        owner = _owner(scene, path)
        if hasattr(owner, prop):  # a few properties exist in one Blender version only
            log.set(owner, prop, value)
    cycles = scene.cycles
    log.set(cycles, "max_bounces", model.max_bounces)
    log.set(cycles, "diffuse_bounces", model.diffuse_bounces)
    log.set(cycles, "glossy_bounces", model.glossy_bounces)
    log.set(cycles, "transmission_bounces", model.transmission_bounces)
    log.set(cycles, "transparent_max_bounces", model.transparent_bounces)
    log.set(cycles, "volume_bounces", model.volume_bounces)
    log.set(cycles, "caustics_reflective", model.caustics_reflective)
    log.set(cycles, "caustics_refractive", model.caustics_refractive)
    log.set(cycles, "blur_glossy", model.blur_glossy)
    log.set(cycles, "pixel_filter_type", model.pixel_filter)
    log.set(cycles, "filter_width", model.filter_width)
    log.set(cycles, "seed", model.seed)
    for light, obj in _scene_lights(scene):
        if model.point_radius_zero and light.type in ("POINT", "SPOT"):
            log.set(light, "shadow_soft_size", 0.0)
        if model.sun_angle_zero and light.type == "SUN":
            log.set(light, "angle", 0.0)
        if model.area_lights_as_points and light.type == "AREA":
            _shrink_area_light(log, light, obj)
    if scene.world is not None and not model.world_lighting:
        log.set(scene.world.cycles_visibility, "diffuse", False)
    return log


def _shrink_area_light(log: SettingsLog, light, obj) -> None:
    """Make an area light an `AREA_POINT_SIZE` square emitting the same power (one-sided)."""
    if not getattr(light, "normalize", True):
        # Unnormalised, radiance is P / (pi * 1 m^2) whatever the size, so the emitted power is
        # P * A (A in m^2, object scale included: kernels/lights.py area_radiance); keep it by
        # normalising with that power. A datablock shared at several scales uses the first's.
        scale = obj.matrix_world.to_scale()
        size_y = light.size_y if light.shape in ("RECTANGLE", "ELLIPSE") else light.size
        area = area_of_shape(light.shape, light.size * abs(scale.x), size_y * abs(scale.y))
        log.set(light, "energy", float(light.energy) * area)
        log.set(light, "normalize", True)
    log.set(light, "shape", "SQUARE")
    log.set(light, "size", AREA_POINT_SIZE)


@contextlib.contextmanager
def matched_scene(model: CyclesModel, scene=None) -> Iterator[SettingsLog]:
    """`with matched_scene(model) as log:` the scene is configured for `model` inside the block
    and exactly as before after it, whatever happens inside. Changes made through `log.set`
    inside the block are undone too."""
    scene = scene or bpy.context.scene
    log = SettingsLog()
    try:
        configure(scene, model, log)
        yield log
    finally:
        log.restore()


# --- camera renders -------------------------------------------------------------------------------


def _render_result():
    for image in bpy.data.images:
        if image.type == "RENDER_RESULT":
            return image
    raise RuntimeError("Cycles produced no Render Result")


def _render_once(scene, log: SettingsLog, samples: int, seed: int, folder: str,
                 render_pass: str = COMBINED_PASS):
    """One render under already-matched settings, output set up by `_exr_output` for the same
    `render_pass`: ((H, W, 3) float32 linear of that pass, row 0 top, seconds). A pass is read
    from `_pass_view_layer`'s layer."""
    log.set(scene.cycles, "samples", int(samples))
    log.set(scene.cycles, "seed", int(seed))
    start = time.perf_counter()
    bpy.ops.render.render(write_still=False, scene=scene.name)
    seconds = time.perf_counter() - start
    path = os.path.join(folder, "render.exr")
    _render_result().save_render(path, scene=scene)
    if render_pass == COMBINED_PASS:
        pixels = read_exr(path)
    else:
        pixels = read_exr_pass(path, RENDER_PASSES[render_pass][1], _pass_view_layer(scene).name)
    return pixels[:, :, :3].copy(), seconds


def _pass_view_layer(scene):
    """The view layer a pass is rendered in: the context's when it is `scene`'s (the layer
    `use_single_layer` means), else the scene's first."""
    layer = bpy.context.view_layer
    if layer is not None and scene.view_layers.get(layer.name) == layer:
        return layer
    return scene.view_layers[0]


@contextlib.contextmanager
def _exr_output(scene, log: SettingsLog, resolution,
                render_pass: str = COMBINED_PASS) -> Iterator[str]:
    """Render size and a lossless float32 OpenEXR output holding `render_pass` (any pass but
    Combined: multilayer, the pass on in `_pass_view_layer` and that layer alone rendered);
    yields a temporary folder."""
    if resolution is not None:
        width, height = (int(v) for v in resolution)
        log.set(scene.render, "resolution_x", width)
        log.set(scene.render, "resolution_y", height)
        log.set(scene.render, "resolution_percentage", 100)
    output = EXR_OUTPUT
    if render_pass != COMBINED_PASS:
        output = MULTILAYER_EXR_OUTPUT
        chosen = _pass_view_layer(scene)
        # Background renders ignore `use_single_layer` (measured): switch the others off.
        for view_layer in scene.view_layers:
            log.set(view_layer, "use", view_layer == chosen)
        log.set(chosen, RENDER_PASSES[render_pass][0], True)
    # The output format is restored by hand: which colour depths and modes are valid depends on
    # the file format, so it must be put back first and its dependents after it.
    settings = scene.render.image_settings
    output = [(prop, value) for prop, value in output if hasattr(settings, prop)]
    saved = [(prop, getattr(settings, prop)) for prop, _ in output]
    try:
        for prop, value in output:
            setattr(settings, prop, value)
        with tempfile.TemporaryDirectory(prefix="classic_bake_render_") as folder:
            yield folder
    finally:
        for prop, value in saved:
            setattr(settings, prop, value)


def render_camera(scene, model: CyclesModel, samples: int,
                  resolution: tuple[int, int] | None = None, *,
                  seed: int | None = None) -> tuple[np.ndarray, float]:
    """Render the scene camera with Cycles under `model`.

    Returns (pixels (H, W, 3) float32 linear Rec.709, row 0 top; seconds of the render alone).
    The pixels are the combined image, or the pass `model.render_pass` names (turned on for the
    render). `resolution` (W, H) overrides the scene's render size (percentage 100); `seed`
    overrides `model.seed`. The image goes through a float32 OpenEXR (lossless, exact; multilayer
    for a pass) in a temporary folder; the scene is left as it was.
    """
    scene = scene or bpy.context.scene
    if scene.camera is None:
        raise ValueError(f"scene '{scene.name}' has no camera to render")
    with (matched_scene(model, scene) as log,
          _exr_output(scene, log, resolution, model.render_pass) as folder):
        return _render_once(scene, log, samples, model.seed if seed is None else seed, folder,
                            model.render_pass)


# The world rendered alone into a map (`render_world_map`): a panoramic camera sees the sky the
# way Cycles' Environment Texture is read (kernels/world_light.equirect_uv): the image centre along
# world +x, its top +z, u = 1/4 along +y. Cycles' equirectangular camera looks down its own -z
# with +y up and -x at u = 1/4 (measured with a world that shows its direction as colour), so its
# axes in the world are x_cam = -y, y_cam = +z, z_cam = -x.
WORLD_CAMERA_MATRIX = ((0.0, 0.0, -1.0, 0.0), (-1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0),
                       (0.0, 0.0, 0.0, 1.0))
# (W, H) of the map: texels of 0.47 degrees; the default sky's sun disc (0.545 degrees) covers a
# few. Measured on a Multiple Scattering sky, sun 30 degrees up, as the irradiance of an upward
# plane summed over the map (red), at 256 samples: 768 x 384 81.42 in 1.2 s on the 2-core
# machine, 1024 x 512 81.52 in 1.9 s (4096 samples 81.64), 2048 x 1024 81.55 in 6.9 s,
# 512 x 256 79.0 in 0.6 s (its sun texels too coarse).
WORLD_MAP_SIZE = (768, 384)
# Samples a texel at most: the sun disc's rim texels need them (1024 x 512 at 64: 80.1, 2% low,
# as the disc's coverage of a texel is sampled); adaptive sampling stops the smooth sky's early.
# A 1-px box filter: each texel is its area's mean, so the texels' sum keeps a sun's power.
WORLD_MAP_SAMPLES = 256
WORLD_MAP_MIN_SAMPLES = 8
WORLD_MAP_NOISE = 0.002
# What a Light Path node reads on a diffuse bounce ray that escapes to the world, the rays that
# light surfaces (`render_world_map(lighting=True)`): the flags of a first diffuse bounce, an
# unbounded length. Outputs not named here read 0.
DIFFUSE_RAY_PATH = {"Is Diffuse Ray": 1.0, "Is Reflection Ray": 1.0, "Ray Length": 1e30,
                    "Ray Depth": 1.0, "Diffuse Depth": 1.0}


def render_world_map(world, size: tuple[int, int] = WORLD_MAP_SIZE,
                     samples: int = WORLD_MAP_SAMPLES, lighting: bool = False
                     ) -> tuple[np.ndarray, float]:
    """The world's radiance over all directions as an equirectangular map, rendered by Cycles:
    ((H, W, 3) float32 linear, row 0 top, laid out as an Environment Texture's image; seconds).

    For world shaders the bridge cannot read itself (a Sky Texture, procedural textures, mixes
    of shaders). A temporary scene holds the world and a panoramic camera (`WORLD_CAMERA_MATRIX`)
    and nothing else; it is removed afterwards, the world untouched. A camera sees the world as a
    camera ray does; with `lighting`, a copy of the world whose Light Path nodes (in its own tree)
    read as a diffuse bounce ray's (`DIFFUSE_RAY_PATH`) is rendered instead: the world that
    lights surfaces (a common set-up shows the camera a backdrop and lights with a map)."""
    width, height = (int(v) for v in size)
    # Every temporary datablock is removed on the way out, in reverse order of making.
    with contextlib.ExitStack() as stack:
        if lighting:
            world = _diffuse_ray_world(world)
            stack.callback(bpy.data.worlds.remove, world)
        temp = bpy.data.scenes.new(f"{TEMP_PREFIX}_world")
        stack.callback(bpy.data.scenes.remove, temp)
        camera = bpy.data.cameras.new(f"{TEMP_PREFIX}_world")
        stack.callback(bpy.data.cameras.remove, camera)
        camera.type = "PANO"
        camera.panorama_type = "EQUIRECTANGULAR"
        obj = bpy.data.objects.new(f"{TEMP_PREFIX}_world", camera)
        stack.callback(bpy.data.objects.remove, obj)
        temp.world = world
        temp.collection.objects.link(obj)
        temp.camera = obj
        obj.matrix_world = mathutils.Matrix(WORLD_CAMERA_MATRIX)  # rows as written
        log = SettingsLog()
        stack.callback(log.restore)
        # world_lighting: the model leaves the (shared) world's ray visibility alone.
        configure(temp, direct(world_lighting=True), log)
        log.set(temp.cycles, "pixel_filter_type", "BOX")
        log.set(temp.cycles, "filter_width", 1.0)
        log.set(temp.cycles, "use_adaptive_sampling", True)
        log.set(temp.cycles, "adaptive_min_samples", WORLD_MAP_MIN_SAMPLES)
        log.set(temp.cycles, "adaptive_threshold", WORLD_MAP_NOISE)
        with _exr_output(temp, log, (width, height)) as folder:
            return _render_once(temp, log, samples, 0, folder)


def _diffuse_ray_world(world):
    """A temporary copy of `world` whose Light Path nodes' links come from Value nodes holding
    what a diffuse bounce ray reads (`DIFFUSE_RAY_PATH`; the caller removes the copy)."""
    copy = world.copy()
    copy.name = f"{TEMP_PREFIX}_world"
    tree = copy.node_tree
    for node in [n for n in tree.nodes if n.type == "LIGHT_PATH"]:
        for output in node.outputs:
            for link in list(output.links):
                value = tree.nodes.new("ShaderNodeValue")
                value.outputs[0].default_value = DIFFUSE_RAY_PATH.get(output.name, 0.0)
                tree.links.new(value.outputs[0], link.to_socket)
    return copy


def warm_up(scene=None) -> float:
    """Pay Cycles' one-off start-up costs with an 8 x 8, 1-sample render; returns its seconds.

    Measured on the shared 2-core machine, 8 x 8 px at 1 sample, first render of a fresh process
    against the median of the next five (3 processes per scene): Cornell box and ray-tracing
    scenes +1 to +3 ms (Blender 5.2.3) and +1 to +2 ms (4.5.15) on 3-10 ms renders; the
    environment room +60 ms (5.2.3) and +17 ms (4.5.15): its packed floor image is decoded on
    the first render and cached by Blender afterwards. So the one-off cost is mostly image
    loading, and it is paid by a render of the scene itself: `sample_ladder` and `reference`
    call this before timing anything. (`import bpy` itself, 0.5-0.75 s, is outside every timing.)
    """
    scene = scene or bpy.context.scene
    if scene.camera is None:
        return 0.0
    model = direct()
    size = (WARM_UP_PIXELS, WARM_UP_PIXELS)
    with matched_scene(model, scene) as log, _exr_output(scene, log, size) as folder:
        return _render_once(scene, log, WARM_UP_SAMPLES, model.seed, folder)[1]


# --- bakes ----------------------------------------------------------------------------------------


def _mesh_objects(scene, objects: Iterable) -> list:
    """Objects (names or bpy objects) as a list of mesh objects of `scene`, in the order given."""
    found = []
    for item in objects:
        obj = scene.objects.get(item) if isinstance(item, str) else item
        if obj is None:
            raise ValueError(f"no object '{item}' in scene '{scene.name}'")
        if obj.type != "MESH":
            raise ValueError(f"object '{obj.name}' is a {obj.type}: only meshes can be baked")
        found.append(obj)
    if not found:
        raise ValueError("nothing to bake: no objects given")
    return found


@contextlib.contextmanager
def _selection(scene, objects: Sequence) -> Iterator[None]:
    """Exactly `objects` selected and the first one active; the selection restored afterwards."""
    view_layer = bpy.context.view_layer
    before = [obj for obj in scene.objects if obj.select_get()]
    active = view_layer.objects.active
    try:
        for obj in before:
            obj.select_set(False)
        for obj in objects:
            if not obj.visible_get():
                raise ValueError(f"object '{obj.name}' is hidden: Cycles cannot bake it")
            obj.select_set(True)
        view_layer.objects.active = objects[0]
        yield
    finally:
        for obj in scene.objects:
            obj.select_set(False)
        for obj in before:
            obj.select_set(True)
        view_layer.objects.active = active


def _new_float_image(name: str, width: int, height: int):
    """A float image, linear, cleared to (0, 0, 0, 0) so that alpha marks what the bake writes."""
    image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    image.pixels.foreach_set(np.zeros(width * height * 4, np.float32))
    return image


def _default_surface():
    """A temporary material equal to Cycles' surface for faces without one: diffuse 0.8 grey."""
    mat = bpy.data.materials.new(f"{TEMP_PREFIX}_default")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    return mat


def _use_temporary_material(stack: contextlib.ExitStack, obj, index: int, mat) -> None:
    """Show `mat` in slot `index` of `obj` through an object link (the mesh is not touched)."""
    slot = obj.material_slots[index]
    stack.callback(setattr, obj.material_slots[index], "link", slot.link)
    slot.link = "OBJECT"
    stack.callback(setattr, obj.material_slots[index], "material", slot.material)
    slot.material = mat


def _bake_materials(stack: contextlib.ExitStack, objects: Sequence, images: dict) -> None:
    """Give every material of every object an active Image Texture node on that object's image.

    A material used by several baked objects (or a slot without one) is replaced, for the bake,
    by a temporary per-object material through an object-linked slot, so every object bakes into
    its own image and meshes shared with other objects are not touched. `stack` undoes it all.
    """
    claimed: set[int] = set()
    for obj in objects:
        if len(obj.material_slots) == 0:  # Cycles' default surface, as a removable material
            temp = _default_surface()
            stack.callback(bpy.data.materials.remove, temp)
            obj.data.materials.append(temp)
            # The mesh had no material: clear() empties it again (pop() would leave the object
            # an empty slot behind, as measured in Blender 5.2).
            stack.callback(obj.data.materials.clear)
        for index, slot in enumerate(obj.material_slots):
            mat = slot.material
            if mat is None or mat.as_pointer() in claimed:
                mat = _default_surface() if mat is None else mat.copy()
                stack.callback(bpy.data.materials.remove, mat)
                _use_temporary_material(stack, obj, index, mat)
            claimed.add(mat.as_pointer())
            if bpy.app.version < (5, 0, 0) and not mat.use_nodes:
                stack.callback(setattr, mat, "use_nodes", False)
                mat.use_nodes = True
            tree = mat.node_tree
            previous = tree.nodes.active
            node = tree.nodes.new("ShaderNodeTexImage")
            node.name = node.label = TEMP_PREFIX
            node.image = images[obj.name]
            node.location = (-1200.0, 600.0)
            stack.callback(tree.nodes.remove, node)
            stack.callback(setattr, tree.nodes, "active", previous)
            tree.nodes.active = node


def _blender_bake_type(bake_type: str) -> str:
    """The `bpy.ops.object.bake` type that bakes our `bake_type` (see `BLENDER_BAKE_TYPES`)."""
    return BLENDER_BAKE_TYPES.get(bake_type, bake_type)


def _bake_settings(log: SettingsLog, scene, samples: int, seed: int, bake_type: str) -> None:
    log.set(scene.cycles, "samples", int(samples))
    log.set(scene.cycles, "seed", int(seed))
    log.set(scene.cycles, "bake_type", _blender_bake_type(bake_type))
    if bake_type == "SHADOW":
        # cycles_facts.md: with bounces a SHADOW bake is no 0-1 map (values up to 1.7-4.0).
        log.set(scene.cycles, "max_bounces", 0)


def _pass_filter(bake_type: str, use_color: bool) -> set[str]:
    if bake_type not in PASS_FILTERS:
        raise ValueError(f"bake_type must be one of {sorted(PASS_FILTERS)}, got {bake_type!r}")
    flags = set(PASS_FILTERS[bake_type])
    if bake_type == "DIFFUSE" and not use_color:
        flags.discard("COLOR")
    return flags


def _image_size(size) -> tuple[int, int]:
    width, height = (size, size) if isinstance(size, int) else (int(size[0]), int(size[1]))
    if width < 1 or height < 1:
        raise ValueError(f"lightmap size must be positive, got {size}")
    return width, height


def bake_lightmaps(scene, model: CyclesModel, samples: int, objects: Iterable, uv_layer: str,
                   size: int | tuple[int, int], bake_type: BakeType = "DIFFUSE", *,
                   use_color: bool = True, margin: int = 0, seed: int | None = None,
                   ) -> tuple[dict[str, np.ndarray], float, dict[str, np.ndarray]]:
    """Bake `objects` with Cycles into one float lightmap each, through UV layer `uv_layer`.

    Returns ({object name: (H, W, 3) float32 linear, row 0 top}, seconds of the bake operator,
    {object name: (H, W) bool, True on texels the bake wrote}). `size` is W = H or (W, H);
    `margin` texels are dilated around the charts (0: none; the mask then is the UV coverage).
    bake_type DIFFUSE bakes direct + indirect diffuse light, times the albedo with `use_color`
    (radiance rho E / pi), without it E / pi; COMBINED everything; SHADOW a 0-1 visibility map
    (max_bounces forced to 0); ALBEDO the diffuse colour alone, no light (`use_color` ignored).
    See the module docstring for the measured semantics. Temporary images, Image Texture nodes
    and materials are removed afterwards; the scene is left as it was.
    """
    scene = scene or bpy.context.scene
    objs = _mesh_objects(scene, objects)
    width, height = _image_size(size)
    flags = _pass_filter(bake_type, use_color)
    for obj in objs:
        if obj.data.uv_layers.get(uv_layer) is None:
            raise ValueError(f"object '{obj.name}' has no UV layer '{uv_layer}'")
    with contextlib.ExitStack() as stack:
        log = stack.enter_context(matched_scene(model, scene))
        _bake_settings(log, scene, samples, model.seed if seed is None else seed, bake_type)
        images = {}
        for obj in objs:
            image = _new_float_image(f"{TEMP_PREFIX}_{obj.name}", width, height)
            stack.callback(bpy.data.images.remove, image)
            images[obj.name] = image
        _bake_materials(stack, objs, images)
        stack.enter_context(_selection(scene, objs))
        start = time.perf_counter()
        bpy.ops.object.bake(type=_blender_bake_type(bake_type), pass_filter=flags, target="IMAGE_TEXTURES",
                            uv_layer=uv_layer, margin=margin, margin_type="EXTEND",
                            use_clear=False, use_selected_to_active=False, save_mode="INTERNAL",
                            use_split_materials=False, use_automatic_name=False)
        seconds = time.perf_counter() - start
        result, masks = {}, {}
        for name, image in images.items():
            pixels = bridge.image_pixels(image)  # (H, W, 4) float32, row 0 top
            result[name] = pixels[:, :, :3].copy()
            masks[name] = pixels[:, :, 3] > COVERED_ALPHA
    return result, seconds, masks


def bake_color_attributes(scene, model: CyclesModel, samples: int, objects: Iterable,
                          attribute: str, bake_type: BakeType = "DIFFUSE", *,
                          use_color: bool = True, seed: int | None = None, keep: bool = False,
                          ) -> tuple[dict[str, np.ndarray], float]:
    """Bake `objects` with Cycles into float per-vertex colour attributes named `attribute`.

    Returns ({object name: (V, 3) float32 linear, one row per mesh vertex}, seconds of the bake
    operator). Cycles evaluates each corner and averages the corners of a vertex. Bake types as
    in `bake_lightmaps`. The attribute is temporary unless `keep` (an existing attribute of that
    name is replaced only when `keep`); the active colour attribute is restored either way.
    Meshes shared by several baked objects are refused (they would bake into one attribute).
    """
    scene = scene or bpy.context.scene
    objs = _mesh_objects(scene, objects)
    flags = _pass_filter(bake_type, use_color)
    meshes = [obj.data.as_pointer() for obj in objs]
    if len(set(meshes)) != len(meshes):
        raise ValueError("bake_color_attributes: two of the objects share one mesh")
    with contextlib.ExitStack() as stack:
        log = stack.enter_context(matched_scene(model, scene))
        _bake_settings(log, scene, samples, model.seed if seed is None else seed, bake_type)
        for obj in objs:
            attrs = obj.data.color_attributes
            previous = attrs.active_color_name if attrs.active_color is not None else None
            name = attribute if keep else f"{TEMP_PREFIX}_{attribute}"
            if attrs.get(name) is not None:
                attrs.remove(attrs[name])
            attr = attrs.new(name=name, type="FLOAT_COLOR", domain="POINT")
            if not keep:
                stack.callback(_remove_attribute, obj.data, name)
            stack.callback(_set_active_color, obj.data, previous)
            attrs.active_color = attr
        stack.enter_context(_selection(scene, objs))
        start = time.perf_counter()
        bpy.ops.object.bake(type=_blender_bake_type(bake_type), pass_filter=flags, target="VERTEX_COLORS",
                            use_clear=False, use_selected_to_active=False)
        seconds = time.perf_counter() - start
        result = {}
        for obj in objs:
            name = obj.data.color_attributes.active_color_name
            result[obj.name] = bridge.read_color_attribute(obj.data, name)[:, :3].copy()
    return result, seconds


def _remove_attribute(mesh, name: str) -> None:
    attr = mesh.color_attributes.get(name)
    if attr is not None:
        mesh.color_attributes.remove(attr)


def _set_active_color(mesh, name: str | None) -> None:
    attrs = mesh.color_attributes
    if name is not None and attrs.get(name) is not None:
        attrs.active_color = attrs[name]


# --- one run of any kind, ladders ----------------------------------------------------------------


@dataclass(frozen=True)
class BakeSpec:
    """What a bake reference or ladder bakes.

    | field        | default    | meaning                                                      |
    |--------------|------------|--------------------------------------------------------------|
    | objects      | required   | object names, in order                                       |
    | bake_type    | "DIFFUSE"  | DIFFUSE, COMBINED, SHADOW or ALBEDO (see `bake_lightmaps`)   |
    | use_color    | True       | DIFFUSE only: multiply by the albedo (radiance)              |
    | uv_layer     | "Lightmap" | lightmap UV layer (kind "bake")                              |
    | size         | 256        | lightmap texels per side, or (W, H) (kind "bake")            |
    | margin       | 0          | texels dilated around charts (kind "bake")                   |
    | attribute    | "Cycles"   | colour attribute name (kind "attribute")                     |
    | lightmap_uv  | None       | make missing `uv_layer`s with these xatlas settings          |
    """

    objects: tuple[str, ...]
    bake_type: BakeType = "DIFFUSE"
    use_color: bool = True
    uv_layer: str = "Lightmap"
    size: int | tuple[int, int] = 256
    margin: int = 0
    attribute: str = "Cycles"
    lightmap_uv: LightmapUVSettings | None = None

    def fields(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["objects"] = list(self.objects)
        out["size"] = list(self.size) if isinstance(self.size, tuple) else self.size
        return out


@dataclass(frozen=True, eq=False)
class CyclesRun:
    """The result of one Cycles render or bake.

    images: {"render": (H, W, 3)} for kind "render"; {object: (H, W, 3)} for "bake";
    {object: (V, 3)} for "attribute"; all float32 linear. masks: {object: (H, W) bool} for
    "bake", else empty. seconds: wall time of Cycles' work (sum over chunks for a reference).
    """

    kind: ReferenceKind
    samples: int
    seconds: float
    images: dict[str, np.ndarray]
    masks: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def image(self) -> np.ndarray:
        """The camera image of a render run."""
        return self.images["render"]


def run_cycles(scene, model: CyclesModel, kind: ReferenceKind, samples: int, *,
               resolution: tuple[int, int] | None = None, bake: BakeSpec | None = None,
               seed: int | None = None) -> CyclesRun:
    """One Cycles render ("render") or bake ("bake": lightmaps, "attribute": colour attributes)."""
    scene = scene or bpy.context.scene
    if kind == "render":
        pixels, seconds = render_camera(scene, model, samples, resolution, seed=seed)
        return CyclesRun(kind, samples, seconds, {"render": pixels})
    if bake is None:
        raise ValueError(f"kind '{kind}' needs a BakeSpec")
    if kind == "bake":
        images, seconds, masks = bake_lightmaps(
            scene, model, samples, bake.objects, bake.uv_layer, bake.size, bake.bake_type,
            use_color=bake.use_color, margin=bake.margin, seed=seed)
        return CyclesRun(kind, samples, seconds, images, masks)
    if kind == "attribute":
        images, seconds = bake_color_attributes(
            scene, model, samples, bake.objects, bake.attribute, bake.bake_type,
            use_color=bake.use_color, seed=seed)
        return CyclesRun(kind, samples, seconds, images)
    raise ValueError(f"kind must be 'render', 'bake' or 'attribute', got {kind!r}")


def ladder_step(scene, model: CyclesModel, kind: ReferenceKind, samples: int, **kwargs) -> dict:
    """One rung of a sample ladder: {"samples", "seconds", "image" | "images", "masks"}.

    Each call is independent (same seed, nothing kept between calls), so callers can interleave
    rungs with kernel runs and machine-load drift falls on both alike.
    """
    run = run_cycles(scene, model, kind, samples, **kwargs)
    entry: dict[str, Any] = {"samples": run.samples, "seconds": run.seconds}
    if kind == "render":
        entry["image"] = run.image
    else:
        entry["images"] = run.images
        entry["masks"] = run.masks
    return entry


def sample_ladder(scene, model: CyclesModel, sample_counts: Sequence[int],
                  kind: ReferenceKind = "render", *, warm: bool = True, **kwargs) -> list[dict]:
    """`ladder_step` for each sample count in order (e.g. 1, 2, 4, ... N), after `warm_up`.

    Returns [{"samples", "seconds", "image"} ...] ("images"/"masks" for bakes), the shape the
    speed-accuracy chart and metrics.json's comparison.ladder.cycles take once an error is added.
    """
    scene = scene or bpy.context.scene
    if warm:
        warm_up(scene)
    return [ladder_step(scene, model, kind, int(n), **kwargs) for n in sample_counts]


def doubling_counts(max_samples: int, start: int = 1) -> list[int]:
    """1, 2, 4, ... up to `max_samples` (included even when it is not a power of two)."""
    counts, n = [], max(1, start)
    while n < max_samples:
        counts.append(n)
        n *= 2
    counts.append(max_samples)
    return counts


# --- convergence ----------------------------------------------------------------------------------


def _stack_valid(run: CyclesRun) -> np.ndarray:
    """Every valid value of a run as one (N, 1, C) image for the error metrics."""
    parts = []
    for name, image in sorted(run.images.items()):
        mask = run.masks.get(name)
        values = image[mask] if mask is not None else image.reshape(-1, image.shape[-1])
        parts.append(values.reshape(-1, image.shape[-1]))
    return np.concatenate(parts)[:, None, :]


def _average(a: CyclesRun, b: CyclesRun) -> CyclesRun:
    """The sample-weighted mean of two runs of the same kind (their masks: a's)."""
    wa, wb = a.samples / (a.samples + b.samples), b.samples / (a.samples + b.samples)
    images = {k: (wa * a.images[k] + wb * b.images[k]).astype(np.float32) for k in a.images}
    return CyclesRun(a.kind, a.samples + b.samples, a.seconds + b.seconds, images, a.masks)


def converged_run(run: Callable[[int, int], CyclesRun], *, first_seed: int = 0,
                  target_rel_mse: float = TARGET_REL_MSE, start_samples: int = START_SAMPLES,
                  max_samples: int = MAX_SAMPLES) -> tuple[CyclesRun, float]:
    """Render two independent halves until they agree (see the module docstring).

    `run(samples, seed)` makes one render or bake. Returns (the mean of both halves, its
    estimated relative MSE against the converged result: a quarter of the halves').
    """
    if max_samples < 2:
        raise ValueError(f"max_samples must be >= 2, got {max_samples}")
    n = max(1, min(start_samples, max_samples // 2))
    seed = first_seed
    halves = []
    for _ in range(2):
        halves.append(run(n, seed))
        seed += 1
    while True:
        a, b = halves
        half_error = rel_mse(_stack_valid(a), _stack_valid(b))
        if half_error <= target_rel_mse or 2 * (a.samples + b.samples) > max_samples:
            break
        for k in range(2):  # each half doubles: n more samples with a fresh seed, averaged in
            halves[k] = _average(halves[k], run(halves[k].samples, seed))
            seed += 1
    return _average(*halves), 0.25 * half_error


# --- the reference cache --------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Reference:
    """A converged (or fixed-sample) Cycles result and where it came from.

    run: the images, masks, samples and seconds (the seconds of the renders that made it, also
    on a cache hit); cache_hit: True when read from the cache; noise_rel_mse: estimated relative
    MSE against the converged result (None when `samples` was fixed); path: the cache folder.
    """

    run: CyclesRun
    cache_hit: bool
    noise_rel_mse: float | None
    key: str
    path: Path
    settings: dict[str, Any]

    @property
    def image(self) -> np.ndarray:
        return self.run.image

    @property
    def images(self) -> dict[str, np.ndarray]:
        return self.run.images

    @property
    def masks(self) -> dict[str, np.ndarray]:
        return self.run.masks

    @property
    def samples(self) -> int:
        return self.run.samples

    @property
    def seconds(self) -> float:
        return self.run.seconds


def file_sha256(path: str | os.PathLike) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def cache_key(blend_sha256: str, model: CyclesModel, kind: str, *, samples: int | None,
              resolution: tuple[int, int] | None, bake: BakeSpec | None,
              target_rel_mse: float, max_samples: int) -> tuple[str, dict[str, Any]]:
    """(SHA-256 hex, the settings it hashes): the .blend's bytes, the model, the kind, the size,
    the sample count (or the convergence target and cap), the bake and Blender's version."""
    settings = {
        "format": CACHE_FORMAT,
        "blend_sha256": blend_sha256,
        "blender": bpy.app.version_string,
        "model": model.fields(),
        "kind": kind,
        "resolution": list(resolution) if resolution is not None else None,
        "samples": samples if samples is not None else {
            "auto": True, "target_rel_mse": target_rel_mse, "max_samples": max_samples,
            "start_samples": START_SAMPLES},
        "bake": bake.fields() if bake is not None and kind != "render" else None,
    }
    text = json.dumps(settings, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest(), settings


def _open_blend(path: Path) -> None:
    """Open a .blend as the CLI does: no UI, script auto-execution off."""
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)


def _prepare_bake(scene, bake: BakeSpec) -> None:
    if bake.lightmap_uv is None:
        return
    for name in bake.objects:
        obj = scene.objects.get(name)
        if obj is not None and obj.type == "MESH":
            bridge.ensure_lightmap_uv(obj, bake.uv_layer, bake.lightmap_uv)


def _write_cached(folder: Path, run: CyclesRun, meta: dict[str, Any]) -> None:
    """Write the run (one OpenEXR per image, masks as alpha) and meta.json into `folder`."""
    files = {}
    for index, (name, image) in enumerate(run.images.items()):
        file = "render.exr" if run.kind == "render" else f"{index:03d}.exr"
        pixels = image if image.ndim == 3 else image[:, None, :]  # attributes: (V, 1, 3)
        if name in run.masks:
            pixels = np.concatenate([pixels, run.masks[name][:, :, None].astype(np.float32)], -1)
        write_exr(folder / file, pixels)
        files[name] = file
    meta = dict(meta, files=files, samples=run.samples, seconds=run.seconds, kind=run.kind)
    (folder / "meta.json").write_text(json.dumps(meta, indent=1, sort_keys=True, default=str))


def _read_cached(folder: Path) -> tuple[CyclesRun, dict[str, Any]]:
    meta = json.loads((folder / "meta.json").read_text())
    images, masks = {}, {}
    for name, file in meta["files"].items():
        pixels = read_exr(folder / file)
        if meta["kind"] == "bake":
            masks[name] = pixels[:, :, 3] > COVERED_ALPHA
        pixels = pixels[:, :, :3]
        images[name] = pixels[:, 0, :].copy() if meta["kind"] == "attribute" else pixels.copy()
    run = CyclesRun(meta["kind"], int(meta["samples"]), float(meta["seconds"]), images, masks)
    return run, meta


def reference(scene_path: str | os.PathLike, model: CyclesModel, kind: ReferenceKind = "render",
              samples: int | None = None, cache_dir: str | os.PathLike = Path("out/cache"), *,
              resolution: tuple[int, int] | None = None, bake: BakeSpec | None = None,
              target_rel_mse: float = TARGET_REL_MSE, max_samples: int = MAX_SAMPLES,
              ) -> Reference:
    """The Cycles reference of `scene_path` under `model`, from the cache or made and cached.

    `samples` fixed renders that many samples once; None chooses the count from the scene's noise
    (`converged_run`, `target_rel_mse`, `max_samples`). The cache folder `cache_dir/<key>` holds
    one float32 OpenEXR per image (lightmaps carry their coverage mask as alpha, colour attributes
    are (V, 1) images) and `meta.json` (settings, samples, seconds, noise). The key is the SHA-256
    of `cache_key`'s settings, so a changed .blend, model, kind, size, sample count, bake or
    Blender version is a miss. On a miss the file is opened (replacing the open one, scripts off);
    on a hit nothing is opened or rendered.
    """
    scene_path = Path(scene_path)
    key, settings = cache_key(file_sha256(scene_path), model, kind, samples=samples,
                              resolution=resolution, bake=bake, target_rel_mse=target_rel_mse,
                              max_samples=max_samples)
    folder = Path(cache_dir) / key
    if (folder / "meta.json").is_file():
        run, meta = _read_cached(folder)
        if meta.get("key") == key:
            return Reference(run, True, meta.get("noise_rel_mse"), key, folder, settings)

    _open_blend(scene_path)
    scene = bpy.context.scene
    if bake is not None and kind != "render":
        _prepare_bake(scene, bake)
    warm_up(scene)

    def one(n: int, seed: int) -> CyclesRun:
        return run_cycles(scene, model, kind, n, resolution=resolution, bake=bake, seed=seed)

    if samples is not None:
        run, noise = one(int(samples), model.seed), None
    else:
        run, noise = converged_run(one, first_seed=model.seed, target_rel_mse=target_rel_mse,
                                   max_samples=max_samples)
    Path(cache_dir).mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{key[:12]}-", dir=cache_dir))
    try:
        _write_cached(staging, run, {"key": key, "settings": settings, "noise_rel_mse": noise,
                                     "scene": str(scene_path)})
        if folder.exists():  # an unreadable leftover: replace it
            shutil.rmtree(folder)
        os.replace(staging, folder)
    finally:
        if staging.exists():
            shutil.rmtree(staging, ignore_errors=True)
    return Reference(run, False, noise, key, folder, settings)


__all__ = [
    "BakeSpec", "CyclesModel", "CyclesRun", "MODELS", "Reference", "SettingsLog", "albedo",
    "bake_color_attributes", "bake_lightmaps", "cache_key", "configure", "converged_run",
    "direct", "doubling_counts", "ladder_step", "matched_scene", "radiosity", "reference",
    "render_camera", "run_cycles", "sample_ladder", "warm_up", "whitted",
]
