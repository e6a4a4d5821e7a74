"""Camera renders with Cycles under a model (`render_camera`, `warm_up`), read back through a
lossless float32 OpenEXR output (`exr_output`, `render_once`).

Timing
------
`seconds` is the wall time of `bpy.ops.render.render` or `bpy.ops.object.bake` alone: scene
synchronisation (BVH, shaders, images) and path tracing, not the file I/O around them. The first
Cycles render in a process pays one-off start-up costs; `warm_up()` pays them on a tiny render.
See `warm_up` for the measured figures.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import time
from collections.abc import Iterator

import bpy
import numpy as np

from ...kernels.measure.exr import read_exr, read_exr_pass
from .models import COMBINED_PASS, RENDER_PASSES, CyclesModel, direct
from .settings import SettingsLog, lost_enum_value, matched_scene

# Size of the warm-up render (pixels per side) and its sample count.
WARM_UP_PIXELS = 8
WARM_UP_SAMPLES = 1


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


def _render_result():
    for image in bpy.data.images:
        if image.type == "RENDER_RESULT":
            return image
    raise RuntimeError("Cycles produced no Render Result")


def render_once(scene, log: SettingsLog, samples: int, seed: int, folder: str,
                 render_pass: str = COMBINED_PASS):
    """One render under already-matched settings, output set up by `exr_output` for the same
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
def exr_output(scene, log: SettingsLog, resolution,
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
            if not lost_enum_value(settings, prop, value):
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
          exr_output(scene, log, resolution, model.render_pass) as folder):
        return render_once(scene, log, samples, model.seed if seed is None else seed, folder,
                            model.render_pass)


def warm_up(scene=None) -> float:
    """Pay Cycles' one-off start-up costs with an 8 x 8, 1-sample render; returns its seconds.

    Measured on a 2-core machine, 8 x 8 px at 1 sample, first render of a fresh process
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
    with matched_scene(model, scene) as log, exr_output(scene, log, size) as folder:
        return render_once(scene, log, WARM_UP_SAMPLES, model.seed, folder)[1]
