"""Cycles as the reference: matched settings, timed renders and bakes, a cache and a sample ladder.

Every Classic Bake technique is measured against Cycles computing the SAME quantity.

| module      | what it holds                                                              |
|-------------|----------------------------------------------------------------------------|
| models      | `CyclesModel` and the models (`whitted`, `radiosity`, `direct`, `albedo`, and  |
|             | `global_illumination`)                                                     |
| settings    | `configure`, `matched_scene`, `SettingsLog`: a scene set up for a model and put back |
| runner      | camera renders (`render_camera`, `warm_up`) read back through float32 OpenEXR |
| world_map   | the world shader rendered alone into an equirectangular map (`render_world_map`) |
| socket_bake | one material socket baked alone over an object's UVs (`bake_socket`)          |
| bakes       | lightmap and colour-attribute bakes (`bake_lightmaps`, `bake_color_attributes`) |
| runs        | one run of any kind (`run_cycles`, `BakeSpec`, `CyclesRun`)                 |
| ladder      | sample ladders (`ladder_step`, `sample_ladder`, `doubling_counts`)          |
| convergence | two independent halves rendered until they agree (`converged_run`)          |
| cache       | converged references cached on disk (`reference`)                          |

Modules depend in layers, never in a circle: `models` < `settings` < `runner` < `world_map`, which
the bridge's `world` module uses to render world shaders it cannot read (and `socket_bake`, which
its `socket_fallback` uses to bake material sockets it cannot read); `bakes` and `cache` sit
above the bridge and use its `images`, `write_back` and `mesh` modules. This facade re-exports the
public names for callers that use `cycles.<name>`; no module of this package imports it.
"""

from .bakes import (
    BLENDER_BAKE_TYPES,
    COVERED_ALPHA,
    PASS_FILTERS,
    BakeType,
    bake_color_attributes,
    bake_lightmaps,
)
from .cache import (
    CACHE_FORMAT,
    Reference,
    cache_key,
    cached_render,
    dependency_hashes,
    file_sha256,
    reference,
)
from .convergence import MAX_SAMPLES, START_SAMPLES, TARGET_REL_MSE, converged_run
from .ladder import doubling_counts, ladder_step, sample_ladder
from .models import (
    COMBINED_PASS,
    MODELS,
    RENDER_PASSES,
    CyclesModel,
    albedo,
    direct,
    global_illumination,
    radiosity,
    whitted,
)
from .runner import EXR_OUTPUT, MULTILAYER_EXR_OUTPUT, render_camera, warm_up
from .runs import BakeSpec, CyclesRun, ReferenceKind, run_cycles
from .settings import AREA_POINT_SIZE, FIXED_SETTINGS, TEMP_PREFIX, SettingsLog, configure, matched_scene
from .world_map import WORLD_MAP_SIZE, render_world_map

__all__ = [
    "AREA_POINT_SIZE", "BLENDER_BAKE_TYPES", "CACHE_FORMAT", "COMBINED_PASS", "COVERED_ALPHA",
    "EXR_OUTPUT", "FIXED_SETTINGS", "MAX_SAMPLES", "MODELS", "MULTILAYER_EXR_OUTPUT",
    "PASS_FILTERS", "RENDER_PASSES", "START_SAMPLES", "TARGET_REL_MSE", "TEMP_PREFIX",
    "WORLD_MAP_SIZE", "BakeSpec", "BakeType", "CyclesModel", "CyclesRun", "Reference",
    "ReferenceKind", "SettingsLog", "albedo", "bake_color_attributes", "bake_lightmaps",
    "cache_key", "cached_render", "configure", "converged_run", "dependency_hashes", "direct",
    "doubling_counts", "file_sha256",
    "global_illumination", "ladder_step", "matched_scene", "radiosity", "reference",
    "render_camera", "render_world_map",
    "run_cycles", "sample_ladder", "warm_up", "whitted",
]
