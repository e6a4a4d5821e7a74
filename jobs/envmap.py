"""Environment mapping: the eye at the centre of each mirror (the object hidden), six cube faces
rendered, then the camera's view with each mirror reading its map along the reflected ray (rough
surfaces of a mapped object its GGX mips by roughness, and with Diffuse from SH its diffuse parts
the SH9 irradiance: kernels/envmap/probe_lookup.py).

Beside the camera view the job writes, per mapped object, what other tools read
(kernels/envmap/cube_files.py, docs/techniques/envmap.md): the OpenEXR standard cube
(`cube/OBJECT.exr`), the lat-long map Blender's Environment Texture reads
(`cube/OBJECT_latlong.exr`), a labelled cross preview (`cube/OBJECT_cross.png`), the GGX mip
chain (`cube/OBJECT_mip{k}.exr`) and the probe's record (`cube/OBJECT_probe.json`: position, room
box, face order, mip levels, SH9 irradiance), every one with the area lamps the centre sees
(kernels/envmap/probe_lamps.py); with Show in Materials (`wire`) each object gets a material
that reads the lat-long map along the reflection vector (addon/bridge/envmap_material.py).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from pathlib import Path

import bpy
import numpy as np

from ..addon.bridge import envmap_material, write_back
from ..kernels.envmap.cube_files import (
    OPENEXR_Y_UP,
    cross_preview,
    equirect_steps,
    probe_json,
    stored_face_order,
    write_equirect_exr,
    write_openexr_cube,
)
from ..kernels.envmap.cubemap import FACE_NAMES
from ..kernels.envmap.envmap import (
    CapturedFaces,
    EnvironmentMap,
    EnvMapSettings,
    capture_faces_steps,
    capture_plan,
    face_tracer_settings,
    object_bounds,
    render_steps,
    strip_image,
    view_steps,
)
from ..kernels.envmap.prefilter import PrefilterSettings, prefilter_steps
from ..kernels.envmap.probe_lamps import lamp_faces
from ..kernels.envmap.sh_irradiance import sh_coefficients
from ..kernels.geometry.bvh import BVH
from ..kernels.geometry.scene import Scene
from ..kernels.progress import Steps, scaled
from ..kernels.trace.settings import TracerSettings, auto_settings
from .record import JobSummary, OperatorSpec, Option, Technique
from .tiles import Tile, load_solution, save_solution
from .trace import camera_snapshot

IMAGE_NAME = "Classic Bake Environment"
CUBE_PREFIX = "Classic Bake Cube "  # + object name: the six faces side by side
LATLONG_PREFIX = "Classic Bake Env "  # + object name: the lat-long map the wired material reads
# The OpenEXR cube files are written in OpenEXR's y-up frame, (x, y, z)_file = (y, z, x)_world:
# with it the cube and the lat-long file are the same environment to OpenEXR's tools
# (cube_files.py); the probe's `face_order` says which world direction each stored face holds.
CUBE_AXES = OPENEXR_Y_UP
# Lat-long height per face texel: a 4N x 2N map has the face centre's texel angle (pi / 2N) per
# pixel, and 2 x 2 look-ups per pixel (a box filter: near the poles a pixel spans many texels).
LATLONG_PER_FACE = 2
LATLONG_SUPERSAMPLE = 2
# Share of the progress bar for the outputs (lat-long, mips, SH) after the capture and the view.
OUTPUT_SHARE = 0.15


@dataclass(frozen=True)
class EnvMapOutputs:
    """What the job makes of each map besides the files.

    | field          | range | default | meaning                                                  |
    |----------------|-------|---------|----------------------------------------------------------|
    | wire           | bool  | True    | give each mapped object a material showing its map       |
    |                |       |         | (Emission of the lat-long map along the reflection       |
    |                |       |         | vector; the original material kept with a fake user)     |
    | box_projection | bool  | True    | the wired material corrects the look-up for parallax     |
    |                |       |         | with the room's box (the scene's bounds around the       |
    |                |       |         | object); off, or without a box: the look-up along r alone|
    """

    wire: bool = True
    box_projection: bool = True


@dataclass
class ProbeOutputs:
    """One mapped object's outputs, computed before anything is written."""

    name: str
    env: EnvironmentMap  # the captured map with the area lamps its centre sees
    latlong: np.ndarray  # (2N, 4N, 3) float32, Blender's equirectangular mapping
    mips: tuple[np.ndarray, ...]  # (6, M_k, M_k, 3) float32, GGX-prefiltered, OpenGL face table
    sh: np.ndarray  # (9, 3) float64 radiance SH coefficients
    box: tuple[np.ndarray, np.ndarray] | None  # (3,) min, (3,) max world m: the room around it
    record: dict  # the probe's JSON


def room_box(scene: Scene, index: int, centre: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray] | None:
    """The enclosing box of every object but `index` (world m), or None when there are none or
    the probe's centre is not strictly inside it (no room around the probe)."""
    keep = scene.object_ids != index
    if not keep.any():
        return None
    points = scene.triangles[keep].reshape(-1, 3).astype(np.float64)
    lo, hi = points.min(axis=0), points.max(axis=0)
    if not (np.all(centre > lo) and np.all(centre < hi)):
        return None
    return lo, hi


def probe_steps(scene: Scene, env: EnvironmentMap, mips: int) -> Steps[ProbeOutputs]:
    """The map as it leaves the kernels (the area lamps the centre sees added to its faces,
    `probe_lamps.py`: the kernels' own look-up adds them exactly instead), its lat-long map, the
    GGX mip chain (mips levels; 0: none), the SH9 coefficients (of the surfaces alone) and the
    probe record. Yields progress, returns ProbeOutputs."""
    name = scene.objects[env.object_index].source_name
    # Diffuse light from the surfaces alone: the scene's lamps light directly where the probe is
    # used, and nine coefficients cannot hold a small bright source (on env_room the ceiling lamp
    # puts E off by 5% of its peak, by 70% on normals facing away from it).
    sh = sh_coefficients(env.face_images())
    env = replace(env, faces=env.faces + lamp_faces(env, scene.lights))
    faces = env.face_images()
    latlong = yield from scaled(equirect_steps(env.faces, LATLONG_PER_FACE * env.size,
                                               LATLONG_SUPERSAMPLE, env.border), 0.0, 0.4)
    chain = ()
    if mips > 0:
        chain = (yield from scaled(prefilter_steps(faces, PrefilterSettings(levels=mips)),
                                   0.4, 0.6)).levels
    box = room_box(scene, env.object_index, env.centre)
    record = probe_json(env.centre, None if box is None else box[0],
                        None if box is None else box[1], env.size,
                        stored_face_order(CUBE_AXES), levels=max(mips, 1), sh=sh)
    record["object"] = name
    record["lamps"] = ("area lamps the centre sees are in the cube, lat-long and mips; the SH "
                       "holds the surfaces' light alone (the lamps light directly)")
    record["file_axes"] = "OpenEXR y-up: (x, y, z) of the file = (y, z, x) of the world"
    # Suffixes, not names: the command line makes object names safe for the disk, the same way
    # for the JSON's own name ("OBJECT_probe.json") and for the files beside it.
    record["file_suffixes"] = {"cube": ".exr", "latlong": "_latlong.exr", "cross": "_cross.png",
                               "mips": [f"_mip{k}.exr" for k in range(len(chain))]}
    return ProbeOutputs(name, env, latlong, tuple(chain), sh, box, record)


def _cube_writer(faces: np.ndarray):
    """A writer of `faces` as an OpenEXR standard cube (pipeline/commands/technique.py calls it
    with the path)."""
    return lambda path: write_openexr_cube(path, faces, world_to_file=CUBE_AXES)


def _latlong_writer(image: np.ndarray):
    return lambda path: write_equirect_exr(path, image)


def probe_files(probe: ProbeOutputs) -> dict:
    """The files of one probe by relative path: writers (OpenEXR with the envmap attribute),
    a uint8 PNG and a JSON record."""
    name = probe.name
    files = {f"cube/{name}.exr": _cube_writer(probe.env.face_images()),
             f"cube/{name}_latlong.exr": _latlong_writer(probe.latlong),
             f"cube/{name}_cross.png": cross_preview(probe.env.face_images()),
             f"cube/{name}_probe.json": probe.record}
    for k, level in enumerate(probe.mips):
        files[f"cube/{name}_mip{k}.exr"] = _cube_writer(level)
    return files


def outputs_steps(scene, settings: EnvMapSettings, tracer: TracerSettings, result, mips: int,
                  outputs: EnvMapOutputs, start: float = 1.0 - OUTPUT_SHARE
                  ) -> Steps[tuple[list[ProbeOutputs], JobSummary]]:
    """Each map's outputs (`probe_steps`) after the capture and the view (`result`), and the
    summary of the run without what it writes into Blender (images, wired materials): the files,
    settings, sizes and statistics, the same for one run and for `merge` of its tiles."""
    probes = []
    share = (1.0 - start) / max(len(result.maps), 1)
    for number, env in enumerate(result.maps):
        probes.append((yield from scaled(probe_steps(scene, env, mips),
                                         start + number * share, share)))
    files, maps = {}, {}
    for probe in probes:
        files.update(probe_files(probe))
        maps[probe.name] = {"face_size": probe.env.size,
                            "face_samples": [settings.face_supersample,
                                             settings.face_edge_samples],
                            "face_rays": probe.env.rays,
                            "centre": [float(c) for c in probe.env.centre],
                            "latlong": list(probe.latlong.shape[1::-1]),
                            "mip_sizes": [int(level.shape[1]) for level in probe.mips],
                            "box": probe.record["box"]}
    height, width = result.image.shape[:2]
    listed = ", ".join(f"{n} ({m['face_size']} texels per face)" for n, m in maps.items())
    summary = JobSummary(
        message=f"cube maps of {listed}: {result.face_rays} face rays in "
                f"{result.seconds.get('capture', 0.0):.2f} s; camera view {width}x{height} in "
                f"{result.seconds['render']:.2f} s",
        scene=scene, render=result.image, files=files, result=result,
        settings={**asdict(settings), "tracer": asdict(tracer), "mips": int(mips),
                  **asdict(outputs)},
        sizes={"width": width, "height": height, "triangles": scene.triangle_count, "maps": maps,
               "face_rays": result.face_rays},
        # Not "seconds": metrics.json keeps that key for the phases and the total.
        extra={"stage_seconds": result.seconds, "stats": result.trace.stats.as_dict(),
               "wired_materials": []})
    return probes, summary


def envmap_job(scene, settings: EnvMapSettings, tracer: TracerSettings, resolution=None,
               mips: int = PrefilterSettings().levels, outputs: EnvMapOutputs | None = None
               ) -> Steps[JobSummary]:
    """Capture the maps and render the view, then compute each map's files (lat-long, mips,
    SH9), then write the images (the view, a strip of six faces and the lat-long map per object)
    and, with outputs.wire, the materials: closed before its end, it has changed nothing."""
    outputs = outputs or EnvMapOutputs()
    result = yield from scaled(render_steps(scene, settings, tracer, resolution=resolution),
                               0.0, 1.0 - OUTPUT_SHARE)
    probes, summary = yield from outputs_steps(scene, settings, tracer, result, mips, outputs)
    # --- write back: everything computed ---------------------------------------------------------
    image = write_back.write_image(IMAGE_NAME, result.image, image=bpy.data.images.get(IMAGE_NAME))
    images, wired = {IMAGE_NAME: image}, []
    for probe in probes:
        name, env = probe.name, probe.env
        images[name] = write_back.write_image(CUBE_PREFIX + name, strip_image(env),
                                              image=bpy.data.images.get(CUBE_PREFIX + name))
        latlong = write_back.write_image(LATLONG_PREFIX + name, probe.latlong,
                                         image=bpy.data.images.get(LATLONG_PREFIX + name))
        images[LATLONG_PREFIX + name] = latlong
        obj = bpy.data.objects.get(name)
        if outputs.wire and obj is not None and obj.type == "MESH":
            box = probe.box if outputs.box_projection else None
            materials = envmap_material.wire_environment_material(
                obj, latlong, centre=env.centre, box=box,
                tints=envmap_material.mirror_tints(scene, env.object_index))
            wired += [m.name for m in materials]
    summary.images = images
    summary.extra["wired_materials"] = wired
    if wired:
        summary.message += f"; materials {', '.join(wired)}"
    return summary


# --- tiles (jobs/tiles.py): the cube faces -----------------------------------------------------------

FACE_FOLDER = "faces"
VIEW = "view.pickle"  # what merge needs to render the camera's view: the snapshot and settings


def face_list(plan: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """(number in the plan, OpenGL face) of every face the run captures, in a fixed order: the
    objects in the plan's order, each one's faces +X -X +Y -Y +Z -Z."""
    return [(number, face) for number in range(len(plan)) for face in range(6)]


def face_file(number: int, face: int) -> str:
    return f"{FACE_FOLDER}/{number}_{face}.npz"


def _faces_writer(captured: CapturedFaces, k: int):
    """A writer of face `k` of `captured` (exact float32 arrays, read back without pickle)."""
    arrays = {"radiance": captured.radiance[k], "inverse_distance": captured.inverse_distance[k],
              "rays": captured.rays[k]}
    if captured.emission is not None:
        arrays["emission"] = captured.emission[k]
    return lambda path: np.savez(path, **arrays)


def envmap_tile_job(scene, settings: EnvMapSettings, tracer: TracerSettings, tile: Tile,
                    resolution=None, mips: int = PrefilterSettings().levels,
                    outputs: EnvMapOutputs | None = None) -> Steps[JobSummary]:
    """Tile K of N of `envmap_job`: its share of the faces (`face_list`, split by count), each
    captured as one run captures it, into OUT/tiles/K-of-N/faces/; tile 1 also saves the snapshot
    and settings (`VIEW`) for `merge`, which renders the view and writes the files. Nothing is
    written into Blender."""
    outputs = outputs or EnvMapOutputs()
    plan = capture_plan(scene, settings, tracer, resolution)
    every = face_list(plan)
    if tile.count > len(every):
        maps = f"{len(plan)} map" + ("s" if len(plan) > 1 else "")
        raise ValueError(f"--tile {tile.index}/{tile.count}: more tiles than the {len(every)} "
                         f"cube faces ({maps} of six)")
    first, end = (len(every) * (tile.index - 1)) // tile.count, (len(every) * tile.index) // tile.count
    mine = every[first:end]
    face_tracer = face_tracer_settings(settings, tracer)
    bvh = BVH.build(scene.triangles)
    files, names = {}, []
    for count, number in enumerate(sorted({n for n, _ in mine})):
        k, size = plan[number]
        faces = [f for n, f in mine if n == number]
        captured = yield from scaled(
            capture_faces_steps(scene, k, size, face_tracer, settings.face_supersample, bvh,
                                faces, settings.face_edge_samples),
            count / len(plan), 1.0 / len(plan))
        for j, face in enumerate(faces):
            files[face_file(number, face)] = _faces_writer(captured, j)
        names += [[scene.objects[k].source_name, face] for face in faces]
    if tile.index == 1:
        view = {"scene": scene, "settings": settings, "tracer": tracer,
                "resolution": None if resolution is None else tuple(resolution),
                "mips": int(mips), "box_projection": bool(outputs.box_projection),
                "plan": plan}
        files[VIEW] = lambda path: save_solution(path, view)
    return JobSummary(
        message=f"cube faces {first + 1}..{end} of {len(every)} (tile {tile.index} of "
                f"{tile.count}): {', '.join(f'{n} {FACE_NAMES[f]}' for n, f in names)}",
        scene=scene, files=files,
        settings={**asdict(settings), "tracer": asdict(tracer), "mips": int(mips),
                  **asdict(outputs)},
        sizes={"faces": len(every)}, extra={"tile_faces": names})


def envmap_merge(folder: Path, tiles: list[dict]) -> JobSummary:
    """The outputs of one envmap run from its tiles' faces (OUT/tiles/): the cube maps put
    together, then the camera's view and each map's files, as `envmap_job` computes them."""
    from ..kernels.progress import drain

    names = [t["tile"]["name"] for t in tiles]
    view = load_solution(folder / names[0] / VIEW)
    scene, settings, tracer = view["scene"], view["settings"], view["tracer"]
    plan = view["plan"]
    every = face_list(plan)
    where = {}
    for name in names:
        for path in (folder / name / FACE_FOLDER).glob("*.npz"):
            where[path.name] = path
    missing = [f"{n}_{f}" for n, f in every if face_file(n, f).rpartition("/")[2] not in where]
    if missing:
        raise ValueError(f"{folder}: the tiles hold no face {', '.join(missing)}")
    maps = []
    for number, (k, size) in enumerate(plan):
        parts = []
        for face in range(6):
            with np.load(where[face_file(number, face).rpartition("/")[2]],
                         allow_pickle=False) as data:
                parts.append({key: data[key] for key in data.files})
        emission = (np.stack([p["emission"] for p in parts])
                    if all("emission" in p for p in parts) else None)
        centre, _ = object_bounds(scene, k)
        maps.append(CapturedFaces(k, centre, tuple(range(6)),
                                  np.stack([p["radiance"] for p in parts]),
                                  np.stack([p["inverse_distance"] for p in parts]),
                                  emission, np.array([p.get("rays", 0) for p in parts])
                                  ).environment_map())
        if maps[-1].size != size:
            raise ValueError(f"{folder}: the faces of map {number} are not {size} texels wide")
    result = drain(view_steps(scene, settings, tracer, maps, resolution=view["resolution"]))
    outputs = EnvMapOutputs(wire=False, box_projection=view["box_projection"])
    _, summary = drain(outputs_steps(scene, settings, tracer, result, view["mips"], outputs,
                                     start=0.0))
    # The settings as the tiles recorded them (--wire among them: it changes no file).
    summary.settings = tiles[0].get("settings", summary.settings)
    summary.message = f"{len(maps)} cube maps of {len(every)} faces; " + summary.message
    return summary


OPTIONS = (
    Option("face_size", EnvMapSettings, "Face Size", "Texels per cube-map face side; 0 chooses it "
           "per object from its size on screen", minimum=0, maximum=4096),
    Option("face_samples", EnvMapSettings, "Face Samples", "N x N rays per face texel, averaged",
           field="face_supersample", minimum=1, maximum=8),
    Option("face_edge_samples", EnvMapSettings, "Face Edge Samples", "N x N rays again in face "
           "texels at edges (silhouettes, shadow edges), replacing them (1: off)", minimum=1,
           maximum=8),
    Option("parallax_steps", EnvMapSettings, "Parallax Steps", "Refinements of the search along "
           "each reflected ray for the surface it meets (0: the lecture's look-up along the "
           "reflected direction alone)", minimum=0, maximum=16),
    Option("rough_mips", EnvMapSettings, "Rough Look-up Mips", "GGX mip levels a mapped "
           "object's rough surfaces read in the view, by roughness (0: the sharp look-up along "
           "the reflected ray at every roughness)", minimum=0, maximum=16),
    Option("diffuse_sh", EnvMapSettings, "Diffuse from SH", "A mapped object's diffuse part "
           "also reflects its map's SH9 irradiance (light from the surroundings; Cycles' Whitted "
           "model has none)"),
    Option("face_depth", EnvMapSettings, "Face Depth", "Mirror and glass bounces of the face "
           "renders, counted as Cycles' Max Bounces (-1: from the scene)", minimum=-1, maximum=64),
    Option("adaptive", TracerSettings, "Edge Samples", "N x N camera samples again in pixels at "
           "edges (0: off)", minimum=0, maximum=16),
    Option("mips", PrefilterSettings, "Rough Mips", "GGX-prefiltered mip levels written beside "
           "each cube (level k: roughness k / (levels - 1); 0: none)", field="levels",
           minimum=0, maximum=16),
    # On in the panel; the command line wires only when asked (`--wire`, `cli_extra`): a
    # command's run must leave the scene's materials to the Cycles renders that may follow it
    # in the same process (`compare`).
    Option("wire", EnvMapOutputs, "Show in Materials", "Give each mapped object a material that "
           "reads its map along the reflection vector (the original kept, with a fake user)",
           cli=False),
    Option("box_projection", EnvMapOutputs, "Box Projection", "The material corrects its look-up "
           "for parallax with the room's box (the scene's bounds around the object)"),
    Option("selected_only", EnvMapSettings, "Selected Only", "Map the selected objects; off: "
           "every mirror (smooth metal)", field="objects", auto=False, cli=False),
)


def settings(values: dict, scene=None) -> EnvMapSettings:
    objects = tuple(values.get("objects") or ())
    return EnvMapSettings(face_size=int(values["face_size"]),
                          face_supersample=int(values["face_samples"]),
                          face_edge_samples=int(values.get("face_edge_samples",
                                                           EnvMapSettings.face_edge_samples)),
                          objects=objects,
                          face_depth=int(values["face_depth"]),
                          parallax_steps=int(values["parallax_steps"]),
                          rough_mips=int(values.get("rough_mips", EnvMapSettings.rough_mips)),
                          diffuse_sh=bool(values.get("diffuse_sh", EnvMapSettings.diffuse_sh)))


def output_settings(values: dict) -> tuple[int, EnvMapOutputs]:
    """(mip levels, EnvMapOutputs) from option values; checked like the kernel settings."""
    mips = int(values.get("mips", PrefilterSettings().levels))
    if mips:
        PrefilterSettings(levels=mips)  # raises ValueError outside 1..16
    wire = values["wire_cli"] if "wire_cli" in values else values.get("wire", EnvMapOutputs.wire)
    return mips, EnvMapOutputs(wire=bool(wire),
                               box_projection=bool(values.get("box_projection",
                                                              EnvMapOutputs.box_projection)))


def cli_extra(parser) -> None:
    parser.add_argument("--objects", nargs="+", default=[], metavar="NAME",
                        help="objects to map (default: every mirror, i.e. smooth metal)")
    parser.add_argument("--wire", dest="wire_cli", action="store_true",
                        help="give each mapped object a material that reads its map along the "
                             "reflection vector, saved with --save-blend (the panel's default)")


def start(context, values: dict, resolution=None) -> Steps[JobSummary]:
    if values.get("selected_only"):
        selected = [o.name for o in context.selected_objects if o.type == "MESH"]
        if not selected:
            raise ValueError("Select the objects to environment-map (or turn off Selected Only)")
        values = {**values, "objects": selected}
    mips, outputs = output_settings(values)
    # A material wired by an earlier run is read as the original it replaced (the snapshot sees
    # the mirror, not an emitter); the slots are put back before the first yield.
    with envmap_material.originals_shown(context.scene):
        scene = camera_snapshot(context, resolution)
    tracer = auto_settings(scene, adaptive=int(values["adaptive"]))
    if values.get("tile") is not None:
        return (yield from envmap_tile_job(scene, settings(values), tracer, values["tile"],
                                           resolution, mips, outputs))
    return (yield from envmap_job(scene, settings(values), tracer, resolution, mips, outputs))


def cycles_model(recorded: dict):
    from ..addon.cycles import models

    return models.whitted(int(recorded["tracer"].get("max_depth", 8)))  # true reflections


RECORD = Technique(
    name="envmap", label="Environment Mapping", help="environment (cube) mapping of the scene's mirrors",
    options=OPTIONS, settings=settings, start=start, cycles_model=cycles_model, cli_extra=cli_extra,
    ladder=(("--parallax-steps", "0"), ("--face-size", "32"), ("--face-size", "0"),
            ("--face-size", "128")),
    operator=OperatorSpec("classic_bake.envmap", "Environment Map Mirrors", "MAT_SPHERE_SKY",
                          needs=("camera", "mesh"), undo=True),
    tiles="faces", tile_merge=envmap_merge,
)
