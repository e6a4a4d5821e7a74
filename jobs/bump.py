"""Bump mapping: the camera's view shaded with flat, Gouraud (light at the corners), Phong
(interpolated normals) or bump-mapped normals (heights and normal maps in the tangent frame)."""

from __future__ import annotations

from dataclasses import asdict

from ..kernels.progress import Steps, scaled
from ..kernels.shading.bump import SHADING_MODES, has_bump
from ..kernels.trace.settings import TracerSettings, auto_settings
from .record import JobSummary, OperatorSpec, Option, Technique
from .trace import camera_snapshot, traced

IMAGE_NAME = "Classic Bake Shading"
MODE_LABELS = {"bump": ("Bump", "Interpolated normals perturbed by the materials' height (Bump "
                        "node) and normal maps, in the tangent frame"),
               "phong": ("Phong", "Corner normals interpolated, light per pixel"),
               "gouraud": ("Gouraud", "Light computed at the corners, interpolated"),
               "flat": ("Flat", "One normal per triangle")}


def shading_job(scene, settings: TracerSettings, resolution=None, all_modes: bool = False
                ) -> Steps[JobSummary]:
    """Trace the view with `settings.shading` into 'Classic Bake Shading'; with `all_modes` every
    other shading mode too, into the summary's files (modes/MODE.exr and .png)."""
    modes = SHADING_MODES if all_modes else (settings.shading,)
    files, image, result = {}, None, None
    for k, mode in enumerate(modes):
        mode_settings = TracerSettings(**{**asdict(settings), "shading": mode})
        name = IMAGE_NAME if mode == settings.shading else f"{IMAGE_NAME} {mode}"
        written, mode_result = yield from _scaled_trace(scene, mode_settings, name, resolution,
                                                        k, len(modes))
        if all_modes:
            files[f"modes/{mode}.exr"] = mode_result.image
            files[f"modes/{mode}.png"] = mode_result.image
        if mode == settings.shading:
            image, result = written, mode_result
    bumped = [m.name for m in scene.read_materials if has_bump(m)]
    height, width = result.image.shape[:2]
    return JobSummary(
        message=f"shaded '{image.name}' ({settings.shading}); bump and normal maps on "
                + (", ".join(bumped) if bumped else "no material"),
        scene=scene, render=result.image, images={IMAGE_NAME: image}, files=files, result=result,
        settings=asdict(settings),
        sizes={"width": width, "height": height, "triangles": scene.triangle_count,
               "bumped_materials": bumped})


def _scaled_trace(scene, settings, name, resolution, k: int, n: int):
    return (yield from scaled(traced(scene, settings, name, resolution), k / n, 1.0 / n))


OPTIONS = (
    Option("shading", TracerSettings, "Shading", "Which normals the camera view is shaded with",
           choices=tuple((m, *MODE_LABELS[m]) for m in ("bump", "phong", "gouraud", "flat"))),
    Option("adaptive", TracerSettings, "Edge Samples", "N x N samples again in pixels at edges "
           "(0: off)", minimum=0, maximum=16),
)


def settings(values: dict, scene) -> TracerSettings:
    return auto_settings(scene, shading=str(values["shading"]).lower(),
                         adaptive=int(values["adaptive"]))


def cli_extra(parser) -> None:
    parser.add_argument("--all-modes", action="store_true",
                        help="also render every shading mode into modes/MODE.exr and .png")


def start(context, values: dict, resolution=None) -> Steps[JobSummary]:
    scene = camera_snapshot(context, resolution)
    return (yield from shading_job(scene, settings(values, scene), resolution,
                                   all_modes=bool(values.get("all_modes", False))))


def cycles_model(recorded: dict):
    from ..addon.cycles import models

    return models.whitted(int(recorded.get("max_depth", 8)))


RECORD = Technique(
    name="bump", label="Bump Mapping",
    help="flat, Gouraud, Phong and bump-mapped shading of the camera view",
    options=OPTIONS, settings=settings, start=start, cycles_model=cycles_model, cli_extra=cli_extra,
    ladder=(("--shading", "flat"), ("--shading", "gouraud"), ("--shading", "phong"),
            ("--shading", "bump", "--adaptive", "0"), ("--shading", "bump")),
    operator=OperatorSpec("classic_bake.shading", "Render Shading", "MOD_NORMALEDIT",
                          needs=("camera",), undo=False),
)
