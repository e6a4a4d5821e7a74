"""Environment mapping: the eye at the centre of each mirror (the object hidden), six cube faces
rendered, then the camera's view with each mirror reading its map along the reflected ray."""

from __future__ import annotations

from dataclasses import asdict

import bpy

from ..addon.bridge import write_back
from ..kernels.envmap.envmap import EnvMapSettings, render_steps, strip_image
from ..kernels.progress import Steps, scaled
from ..kernels.trace.settings import TracerSettings, auto_settings
from .record import JobSummary, OperatorSpec, Option, Technique
from .trace import camera_snapshot

IMAGE_NAME = "Classic Bake Environment"
CUBE_PREFIX = "Classic Bake Cube "  # + object name: the six faces side by side


def envmap_job(scene, settings: EnvMapSettings, tracer: TracerSettings, resolution=None
               ) -> Steps[JobSummary]:
    """Capture the maps and render the view, then write the images (the view and a strip of six
    faces per object): closed before its end, it has changed nothing."""
    result = yield from scaled(render_steps(scene, settings, tracer, resolution=resolution))
    image = write_back.write_image(IMAGE_NAME, result.image, image=bpy.data.images.get(IMAGE_NAME))
    images, files, maps = {IMAGE_NAME: image}, {}, {}
    for env in result.maps:
        name = scene.objects[env.object_index].source_name
        strip = strip_image(env)
        images[name] = write_back.write_image(CUBE_PREFIX + name, strip,
                                              image=bpy.data.images.get(CUBE_PREFIX + name))
        files[f"cube/{name}.exr"] = strip
        files[f"cube/{name}.png"] = strip
        maps[name] = {"face_size": env.size, "centre": [float(c) for c in env.centre]}
    height, width = result.image.shape[:2]
    listed = ", ".join(f"{n} ({m['face_size']} texels per face)" for n, m in maps.items())
    return JobSummary(
        message=f"cube maps of {listed}: {result.face_rays} face rays in "
                f"{result.seconds['capture']:.2f} s; camera view {width}x{height} in "
                f"{result.seconds['render']:.2f} s",
        scene=scene, render=result.image, images=images, files=files, result=result,
        settings={**asdict(settings), "tracer": asdict(tracer)},
        sizes={"width": width, "height": height, "triangles": scene.triangle_count, "maps": maps,
               "face_rays": result.face_rays},
        # Not "seconds": metrics.json keeps that key for the phases and the total.
        extra={"stage_seconds": result.seconds, "stats": result.trace.stats.as_dict()})


OPTIONS = (
    Option("face_size", EnvMapSettings, "Face Size", "Texels per cube-map face side; 0 chooses it "
           "per object from its size on screen", minimum=0, maximum=4096),
    Option("face_samples", EnvMapSettings, "Face Samples", "N x N rays per face texel, averaged",
           field="face_supersample", minimum=1, maximum=8),
    Option("parallax_steps", EnvMapSettings, "Parallax Steps", "Refinements of the search along "
           "each reflected ray for the surface it meets (0: the lecture's look-up along the "
           "reflected direction alone)", minimum=0, maximum=16),
    Option("face_depth", EnvMapSettings, "Face Depth", "Ray-tree depth of the face renders (-1: "
           "from the scene)", minimum=-1, maximum=64),
    Option("adaptive", TracerSettings, "Edge Samples", "N x N camera samples again in pixels at "
           "edges (0: off)", minimum=0, maximum=16),
    Option("selected_only", EnvMapSettings, "Selected Only", "Map the selected objects; off: "
           "every mirror (smooth metal)", field="objects", auto=False, cli=False),
)


def settings(values: dict, scene=None) -> EnvMapSettings:
    objects = tuple(values.get("objects") or ())
    return EnvMapSettings(face_size=int(values["face_size"]),
                          face_supersample=int(values["face_samples"]), objects=objects,
                          face_depth=int(values["face_depth"]),
                          parallax_steps=int(values["parallax_steps"]))


def cli_extra(parser) -> None:
    parser.add_argument("--objects", nargs="+", default=[], metavar="NAME",
                        help="objects to map (default: every mirror, i.e. smooth metal)")


def start(context, values: dict, resolution=None) -> Steps[JobSummary]:
    if values.get("selected_only"):
        selected = [o.name for o in context.selected_objects if o.type == "MESH"]
        if not selected:
            raise ValueError("Select the objects to environment-map (or turn off Selected Only)")
        values = {**values, "objects": selected}
    scene = camera_snapshot(context, resolution)
    tracer = auto_settings(scene, adaptive=int(values["adaptive"]))
    return (yield from envmap_job(scene, settings(values), tracer, resolution))


def cycles_model(recorded: dict):
    from ..addon.cycles import models

    return models.whitted(int(recorded["tracer"].get("max_depth", 8)))  # true reflections


RECORD = Technique(
    name="envmap", label="Environment Mapping", help="environment (cube) mapping of the scene's mirrors",
    options=OPTIONS, settings=settings, start=start, cycles_model=cycles_model, cli_extra=cli_extra,
    ladder=(("--parallax-steps", "0"), ("--face-size", "32"), ("--face-size", "0"),
            ("--face-size", "128")),
    operator=OperatorSpec("classic_bake.envmap", "Environment Map Mirrors", "MAT_SPHERE_SKY",
                          needs=("camera", "mesh"), undo=False),
)
