"""Setting a scene up so that Cycles computes what a model describes (`configure`,
`matched_scene`), and putting every change back (`SettingsLog`).

Settings every model shares (`FIXED_SETTINGS`): Cycles on the CPU, denoising and adaptive
sampling off, no sample clamping, no fast-GI approximation, no time limit, view-layer sample
counts ignored, seed fixed (`CyclesModel.seed`), film exposure scale 1, opaque film, compositor
and sequencer bypassed, one view layer, no border, no motion blur, no depth of field (the scene
camera's: the kernels' cameras are pinholes), path guiding off. The view transform is left
alone: renders are written as scene-linear OpenEXR, which no view transform or look touches
(tests/blender/test_cycles_reference.py renders with AgX and a view exposure of +2).
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from typing import Any

import bpy

from ...kernels.shading.lights import area_of_shape
from ..bridge.lights import unnormalized_factor
from .models import CyclesModel

# Side (m) of the square an area light is shrunk to when a model treats area lights as points:
# at 0.1 m from the receiver it differs from a point emitter by (size / distance)^2 = 1e-4.
AREA_POINT_SIZE = 1e-3


# Prefix of every temporary datablock (images, materials, attributes) this package creates.
TEMP_PREFIX = "classic_bake_cycles"


# Cycles and render settings every model uses: (owner, property, value), the owner an attribute
# path from the scene ("cycles" is scene.cycles). Properties missing in a Blender version are
# skipped.
FIXED_SETTINGS: tuple[tuple[str, str, Any], ...] = (
    ("render", "engine", "CYCLES"),
    ("cycles", "device", "CPU"),  # the kernels are CPU code; compare like with like
    ("cycles", "use_denoising", False),  # a denoiser changes values (tests/data/cycles_facts.md)
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

# scene.cycles property <- CyclesModel field, set per model.
MODEL_SETTINGS: tuple[tuple[str, str], ...] = (
    ("max_bounces", "max_bounces"), ("diffuse_bounces", "diffuse_bounces"),
    ("glossy_bounces", "glossy_bounces"), ("transmission_bounces", "transmission_bounces"),
    ("transparent_max_bounces", "transparent_bounces"), ("volume_bounces", "volume_bounces"),
    ("caustics_reflective", "caustics_reflective"), ("caustics_refractive", "caustics_refractive"),
    ("blur_glossy", "blur_glossy"), ("pixel_filter_type", "pixel_filter"),
    ("filter_width", "filter_width"), ("seed", "seed"),
)


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
            if not lost_enum_value(owner, prop, old):
                setattr(owner, prop, old)


def lost_enum_value(owner, prop: str, value) -> bool:
    """Whether `value`, read from `owner.prop`, is the "" RNA gives for an enum whose stored
    value matches none of its items (a Blender 2.7x file's JPEG output with colour mode 32): it
    cannot be set back, and setting it would raise."""
    return value == "" and owner.bl_rna.properties[prop].type == "ENUM"


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
    radius of point/spot lights and the angle of suns of the scene (per the model), with
    `world_lighting` off the world's diffuse ray visibility, and with `mesh_lights` off the
    objects' diffuse ray visibility. The view transform is not touched.
    """
    log = log if log is not None else SettingsLog()
    for path, prop, value in FIXED_SETTINGS:
        owner = _owner(scene, path)
        if hasattr(owner, prop):  # a few properties exist in one Blender version only
            log.set(owner, prop, value)
    cycles = scene.cycles
    for prop, field in MODEL_SETTINGS:
        log.set(cycles, prop, getattr(model, field))
    for light, obj in _scene_lights(scene):
        if model.point_radius_zero and light.type in ("POINT", "SPOT"):
            _keep_unnormalized_power(log, light)
            log.set(light, "shadow_soft_size", 0.0)
        if model.sun_angle_zero and light.type == "SUN":
            _keep_unnormalized_power(log, light)
            log.set(light, "angle", 0.0)
        if model.area_lights_as_points and light.type == "AREA":
            _shrink_area_light(log, light, obj)
    camera = scene.camera
    if camera is not None and camera.type == "CAMERA" and camera.data.dof.use_dof:
        log.set(camera.data.dof, "use_dof", False)  # the kernels' cameras are pinholes
    if scene.world is not None and not model.world_lighting:
        log.set(scene.world.cycles_visibility, "diffuse", False)
    if not model.mesh_lights:
        # Hidden from diffuse rays, an emissive object lights no diffuse surface: Cycles' light
        # sampling honours the visibility (measured: a glowing ball's floor as the sun alone
        # lights it; its materials' Emission Sampling None left its light, met by the rays the
        # diffuse lobe samples). Glossy rays still see it, as the kernels' mirrors do.
        for obj in scene.objects:
            if obj.type != "LIGHT" and hasattr(obj, "visible_diffuse"):
                log.set(obj, "visible_diffuse", False)


def _keep_unnormalized_power(log: SettingsLog, light) -> None:
    """Before a point's radius or a sun's angle is zeroed: an unnormalised light's power scales
    with that size (`bridge.lights.unnormalized_factor`), so normalise it and fold its
    present scale into the energy; the light then emits what the scene's light does."""
    if getattr(light, "normalize", True):
        return
    log.set(light, "energy", float(light.energy) * unnormalized_factor(light))
    log.set(light, "normalize", True)


def _shrink_area_light(log: SettingsLog, light, obj) -> None:
    """Make an area light an `AREA_POINT_SIZE` square emitting the same power (one-sided)."""
    if not getattr(light, "normalize", True):
        # Unnormalised, radiance is P / (pi * 1 m^2) whatever the size, so the emitted power is
        # P * A (A in m^2, object scale included: kernels/shading/lights.py area_radiance); keep it by
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
