"""Build Classic Bake's sample scenes, deterministically, with bpy (Blender as a Python module).

    python sample_blends/make_samples.py [--only NAME ...] [--out DIR]

Each scene starts from Blender's factory settings (never the user's preferences), is made from
arithmetic and seeded NumPy images (packed into the file), and is saved, compressed, as
`DIR/NAME.blend` (default DIR: the folder of this script). The same script runs unchanged under
Blender 4.5 LTS and 5.x; re-running it reproduces the same scene content.

| scene       | shows                   | technique it feeds                                     |
|-------------|-------------------------|--------------------------------------------------------|
| cornell_box | the published box       | radiosity (closed diffuse walls, emissive quad)        |
| env_room    | chrome sphere in a room | environment (cube) mapping                             |
| bump        | orange and brick floor  | bump mapping (packed height images via Bump nodes)     |
| shadows     | objects on a plane      | shadow mapping (sun, spot and point light)             |
| raytrace    | mirror and glass sphere | Whitted ray tracing (checker plane, point light)       |

Conventions (as in `kernels/geometry/scene.py`): metres, +Z up, counter-clockwise faces seen from the
side their normal points to, linear Rec.709 colours. Light powers are Blender's: point and spot
lights in W (radiant intensity P / 4pi W/sr), suns in W/m^2 (irradiance on a facing surface),
area lights in W (radiance P / (pi A)), emission strength as radiance W/(m^2 sr); see
tests/data/cycles_facts.md.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

import bpy
import numpy as np

HERE = Path(__file__).resolve().parent
# The published Cornell box data, kept with the tests' reference data (sources in tests/data/README.md).
CORNELL_JSON = HERE.parent / "tests" / "data" / "cornell_box.json"

MM = 0.001  # metres per millimetre

# The helpers live next to this script; loaded from its file path (as the tests do) its folder is
# not on sys.path yet.
if str(HERE) not in sys.path:
    sys.path.insert(0, str(HERE))

from sample_datablocks import (  # noqa: E402
    bump_map,
    camera,
    checker_texture,
    image_texture,
    light,
    material,
    mesh_object,
    packed_image,
    render_settings,
    reset,
    world,
)
from sample_geometry import (  # noqa: E402
    atlas_uvs,
    box,
    cylinder,
    grid,
    merge,
    orient_faces,
    planar_uvs,
    uv_sphere,
)
from sample_textures import brick_images, checkerboard_image, orange_peel_height  # noqa: E402

# ---------------------------------------------------------------------------------------------
# Scenes
# ---------------------------------------------------------------------------------------------


def cornell_to_blender(points_mm) -> np.ndarray:
    """Cornell data (mm, right-handed, y up) -> Blender (m, z up): the ROTATION
    (x, y, z) -> (-x, z, y) (det +1, so windings and handedness survive), then mm -> m."""
    p = np.asarray(points_mm, float)
    return np.stack([-p[..., 0], p[..., 2], p[..., 1]], axis=-1) * MM


def build_cornell_box() -> None:
    """The Cornell box as published (Cornell Program of Computer Graphics), in metres.

    Geometry, camera and reflectances come from tests/data/cornell_box.json. Every
    wall is its own object with the published quad; shared corners are the same points, so the
    five walls form one watertight shell open only at the front, where the camera looks in
    (as in the real box). The light fills a 130 x 105 mm hole cut in the ceiling at the
    published position (y = 548.8 mm), so nothing is coplanar and no light leaks.
    """
    scene = reset("CornellBox")
    data = json.loads(CORNELL_JSON.read_text())["cornell_original"]
    surfaces = data["surfaces"]
    # Reflectances: RGB renditions of the published spectra under D65 ("rgb_derived_here"),
    # paired with a white (D65) emitter.
    rgb = data["rgb_derived_here"]["under_D65"]
    white = material("White", rgb["white"])
    red = material("Red", rgb["red"])
    green = material("Green", rgb["green"])
    # The emitter: radiance L = 30 W/(m^2 sr) white, i.e. pi * L * A = 1.29 W per channel into
    # the box from the 0.01365 m^2 quad. (Cycles emission is two-sided; the upper side faces out
    # through the hole, into the black world.) Base colour: the usual 0.78 (McGuire's MTL).
    emitter = material("LightEmitter", (0.78, 0.78, 0.78), emission=(1.0, 1.0, 1.0),
                       emission_strength=30.0)
    box_centre = cornell_to_blender([278.0, 274.4, 279.6])

    def quads(key: str):
        pts = cornell_to_blender(surfaces[key]["quads"])  # (Q, 4, 3) m
        return pts.reshape(-1, 3), [list(range(4 * q, 4 * q + 4)) for q in range(len(pts))]

    walls = {"Floor": ("floor", white), "BackWall": ("back_wall", white),
             "LeftWall": ("left_wall", red), "RightWall": ("right_wall", green)}
    for name, (key, mat) in walls.items():
        verts, faces = quads(key)
        faces = orient_faces(verts, faces, box_centre, outward=False)  # facing into the box
        mesh_object(name, verts, faces, planar_uvs(verts, faces), [mat])

    # Ceiling: the published quad with the light's rectangle cut out, as four quads around it.
    outer, _ = quads("ceiling")
    hole, _ = quads("light")
    order = np.argsort(np.arctan2(outer[:, 1] - hole[:, 1].mean(), outer[:, 0] - hole[:, 0].mean()))
    outer = outer[order]
    hole = hole[np.argsort(np.arctan2(hole[:, 1] - hole[:, 1].mean(),
                                      hole[:, 0] - hole[:, 0].mean()))]
    verts = np.concatenate([outer, hole])  # both rings counter-clockwise around the light
    faces = [[k, (k + 1) % 4, 4 + (k + 1) % 4, 4 + k] for k in range(4)]
    faces = orient_faces(verts, faces, box_centre, outward=False)
    mesh_object("Ceiling", verts, faces, planar_uvs(verts, faces), [white])

    verts, faces = quads("light")
    faces = orient_faces(verts, faces, box_centre, outward=False)  # emitting downwards
    mesh_object("Light", verts, faces, planar_uvs(verts, faces), [emitter])

    for name, key in (("ShortBlock", "short_block"), ("TallBlock", "tall_block")):
        verts, faces = quads(key)  # top and four sides; the bottom rests on the floor
        # Weld the corners shared by the published quads (exact same values in the data).
        unique, inverse = np.unique(np.round(verts, 9), axis=0, return_inverse=True)
        inverse = inverse.ravel()
        faces = [[int(inverse[i]) for i in face] for face in faces]
        faces = orient_faces(unique, faces, unique.mean(axis=0), outward=True)
        mesh_object(name, unique, faces, atlas_uvs(unique, faces), [white])

    # The published pinhole camera: at (278, 273, -800) mm looking along +z with +y up, i.e. in
    # Blender along +Y with +Z up: Euler X = 90 deg. Focal length 35 mm, film 25 x 25 mm.
    cam = data["camera"]
    camera(cornell_to_blender(cam["position"]), rotation=(math.pi / 2.0, 0.0, 0.0),
           lens=cam["focal_length_m"] * 1000.0,
           sensor=tuple(s * 1000.0 for s in cam["film_width_height_m"]))
    world("Black", (0.0, 0.0, 0.0), 0.0)
    # Square film -> square image. Full diffuse inter-reflection for radiosity comparisons.
    render_settings(scene, resolution=(256, 256), max_bounces=8, diffuse=8, glossy=0,
                    transmission=0)


def build_env_room() -> None:
    """A chrome sphere on a pedestal in the middle of a furnished 6 x 5 x 3 m room.

    Environment-mapping scene: the sphere (metallic 1, roughness 0) reflects four walls of
    different colours, a checkerboard floor (packed image), a table made of five boxes, two
    stacked crates, a cabinet and a floor lamp. Lit by a hanging bulb (point light) and a
    ceiling panel (area light).
    """
    scene = reset("EnvRoom")
    chrome = material("Chrome", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0)
    ceiling = material("CeilingWhite", (0.8, 0.8, 0.78))
    wall_colours = {
        "WallTerracotta": (0.55, 0.2, 0.12),
        "WallSky": (0.2, 0.35, 0.6),
        "WallSage": (0.3, 0.45, 0.25),
        "WallSand": (0.7, 0.6, 0.35),
    }
    walls = [material(name, rgb) for name, rgb in wall_colours.items()]
    wood = material("Wood", (0.4, 0.22, 0.1))
    cardboard = material("Cardboard", (0.55, 0.4, 0.22))
    cabinet_paint = material("CabinetPaint", (0.15, 0.15, 0.2))
    stone = material("Stone", (0.6, 0.6, 0.6))
    lamp_metal = material("LampMetal", (0.05, 0.05, 0.05))
    lamp_shade = material("LampShade", (0.85, 0.8, 0.6))
    tiles = material("FloorTiles")
    image_texture(tiles, packed_image("FloorTiles", checkerboard_image(
        240, 200, 20, (0.85, 0.83, 0.78), (0.15, 0.15, 0.17)), color=True))

    # Room shell: ceiling and four walls facing inwards, one material slot each (5 slots).
    room_size = (6.0, 5.0, 3.0)
    verts, faces = box(room_size, (0.0, 0.0, 1.5))
    faces = orient_faces(verts, faces[1:], (0.0, 0.0, 1.5), outward=False)  # drop the floor
    mesh_object("Room", verts, faces, atlas_uvs(verts, faces), [ceiling, *walls],
                material_indices=[0, 1, 2, 3, 4])
    # Floor: 12 x 10 squares of 0.5 m from an image spanning UV [0, 1]^2.
    verts, faces, uvs = grid(6.0, 5.0, 6, 5)
    mesh_object("Floor", verts, faces, uvs, [tiles])

    verts, faces = box((0.5, 0.5, 0.5), (0.0, 0.0, 0.25))
    mesh_object("Pedestal", verts, faces, atlas_uvs(verts, faces), [stone])
    verts, faces, uvs = uv_sphere(0.5, 48, 24)
    mesh_object("MirrorSphere", verts, faces, uvs, [chrome], smooth=True,
                location=(0.0, 0.0, 1.0))

    # Table: a 1.4 x 0.8 m top on four legs, one mesh of five boxes, 0.75 m tall.
    legs = [box((0.06, 0.06, 0.71), (sx * 0.62, sy * 0.32, 0.355))
            for sx in (-1, 1) for sy in (-1, 1)]
    verts, faces = merge(box((1.4, 0.8, 0.04), (0.0, 0.0, 0.73)), *legs)
    mesh_object("Table", verts, faces, atlas_uvs(verts, faces), [wood],
                location=(-0.2, 1.9, 0.0), rotation=(0.0, 0.0, math.radians(10.0)))
    # Crates: a unit cube scaled non-uniformly (the bridge must transform normals properly),
    # and a smaller one stacked on it at an angle.
    verts, faces = box((1.0, 1.0, 1.0), (0.0, 0.0, 0.5))
    mesh_object("CrateLarge", verts, faces, atlas_uvs(verts, faces), [cardboard],
                location=(1.3, 1.6, 0.0), scale=(0.8, 0.6, 0.5))
    verts, faces = box((0.4, 0.4, 0.4), (0.0, 0.0, 0.2))
    mesh_object("CrateSmall", verts, faces, atlas_uvs(verts, faces), [cardboard],
                location=(1.25, 1.55, 0.5), rotation=(0.0, 0.0, math.radians(25.0)))
    verts, faces = box((0.5, 1.2, 1.8), (0.0, 0.0, 0.9))
    mesh_object("Cabinet", verts, faces, atlas_uvs(verts, faces), [cabinet_paint],
                location=(-2.72, -0.2, 0.0))

    # Floor lamp: base disc and pole (LampMetal, flat caps, sharp rims) and an open shade
    # (LampShade, smooth): one mesh with two material slots, and custom sharp edges.
    # Heights: base 0 - 0.03 m, pole 0.02 - 1.2 m (its foot inside the base, no coplanar
    # faces), shade 1.2 - 1.5 m.
    base = cylinder(0.18, 0.18, 0.03, 24)
    pole = cylinder(0.015, 0.015, 1.18, 12)
    pole = (pole[0] + [0.0, 0.0, 0.02], pole[1])
    shade = cylinder(0.25, 0.15, 0.3, 24, caps=False)
    shade = (shade[0] + [0.0, 0.0, 1.2], shade[1])
    verts, faces = merge(base, pole, shade)
    n_metal = len(base[1]) + len(pole[1])
    lamp = mesh_object("Lamp", verts, faces, atlas_uvs(verts, faces), [lamp_metal, lamp_shade],
                       material_indices=[0] * n_metal + [1] * len(shade[1]), smooth=True,
                       location=(-2.3, -1.8, 0.0))
    mark_sharp_edges(lamp.data, math.radians(30.0))

    # Lights. A bare bulb hanging 0.6 m below the ceiling, 80 W point light: I = 80 / 4pi =
    # 6.4 W/sr. (Not inside the lamp's shade: light bounced off a surface centimetres from a
    # point light makes fireflies in every Cycles reference render.)
    light("PointLight", "POINT", 80.0, (-1.0, -1.0, 2.4))
    # Ceiling panel: 1.2 x 0.6 m area light, 100 W: radiance 100 / (pi * 0.72) = 44 W/(m^2 sr).
    light("CeilingPanel", "AREA", 100.0, (0.3, 0.4, 2.98), target=(0.3, 0.4, 0.0),
          shape="RECTANGLE", size=1.2, size_y=0.6)

    camera((2.75, -2.3, 1.7), target=(-0.2, 0.2, 0.9), lens=24.0)
    world("Black", (0.0, 0.0, 0.0), 0.0)  # the room is closed: nothing comes from outside
    render_settings(scene, max_bounces=8, diffuse=3, glossy=4, transmission=0)


def mark_sharp_edges(mesh: bpy.types.Mesh, angle: float) -> None:
    """Mark edges whose faces meet at more than `angle` (rad) sharp, keeping faces smooth: the
    "sharp_edge" attribute of Blender 4.1+, written by hand so it is the same in every version."""
    normals = np.empty(len(mesh.polygons) * 3, np.float32)
    mesh.polygons.foreach_get("normal", normals)
    normals = normals.reshape(-1, 3)
    edge_faces: dict[tuple[int, int], list[int]] = {}
    for poly in mesh.polygons:
        for key in poly.edge_keys:
            edge_faces.setdefault(key, []).append(poly.index)
    sharp = np.zeros(len(mesh.edges), bool)
    cos_limit = math.cos(angle)
    for edge in mesh.edges:
        polys = edge_faces.get(edge.key, [])
        if len(polys) == 2 and float(normals[polys[0]] @ normals[polys[1]]) < cos_limit:
            sharp[edge.index] = True
    attribute = mesh.attributes.get("sharp_edge") or mesh.attributes.new(
        "sharp_edge", "BOOLEAN", "EDGE")
    attribute.data.foreach_set("value", sharp)
    mesh.update()


def build_bump() -> None:
    """Bump mapping: a dimpled orange (Subdivision Surface + height image) on a brick floor
    (height and colour images), under a low sun so the relief catches the light."""
    scene = reset("Bump")
    orange = material("OrangePeel", (0.8, 0.22, 0.01), roughness=0.4)
    bump_map(orange, packed_image("OrangePeelHeight", orange_peel_height(), color=False),
             strength=1.0, distance=0.01)
    heights, colours = brick_images()
    bricks = material("Bricks")
    image_texture(bricks, packed_image("BrickColor", colours, color=True))
    bump_map(bricks, packed_image("BrickHeight", heights, color=False),
             strength=1.0, distance=0.01)

    # Floor 4 x 4 m: the 256^2 brick image spans it once (16 rows of 25 cm bricks).
    verts, faces, uvs = grid(4.0, 4.0, 4, 4)
    mesh_object("BrickFloor", verts, faces, uvs, [bricks])
    # Orange: a 32 x 16 UV sphere smoothed by one level of Subdivision Surface (applied in the
    # evaluated mesh the bake reads). Subdivided, its bottom pole is 0.4988 m from the centre,
    # so at z = 0.498 m it rests on the floor (0.8 mm deep).
    verts, faces, uvs = uv_sphere(0.5, 32, 16)
    obj = mesh_object("Orange", verts, faces, uvs, [orange], smooth=True,
                      location=(0.0, 0.0, 0.498))
    subsurf = obj.modifiers.new("Subdivision", "SUBSURF")
    subsurf.levels = subsurf.render_levels = 1

    # Sun at 30 deg elevation from the -X, -Y side: 3 W/m^2 on a surface facing it.
    elevation, azimuth = math.radians(30.0), math.radians(-120.0)
    sun_dir = (math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
               math.sin(elevation))
    light("Sun", "SUN", 3.0, [5.0 * c for c in sun_dir], target=(0.0, 0.0, 0.0))
    camera((2.2, -2.4, 1.6), target=(0.0, 0.0, 0.35), lens=35.0)
    world("DimSky", (0.05, 0.06, 0.08))  # faint sky so sun-facing-away sides are not black
    render_settings(scene, max_bounces=4, diffuse=2, glossy=2, transmission=0)


def build_shadows() -> None:
    """Shadow mapping: a cube, a sphere, a thin pole and a floating square plate on a 20 x 20 m
    plane, lit by a sun, a spot and a point light; each light throws its own shadows."""
    scene = reset("Shadows")
    ground = material("Ground", (0.7, 0.7, 0.7))
    red = material("RedPaint", (0.6, 0.08, 0.05))
    blue = material("BluePaint", (0.08, 0.15, 0.6))
    yellow = material("YellowPaint", (0.7, 0.55, 0.05))
    steel = material("PoleGrey", (0.3, 0.3, 0.3))

    verts, faces, uvs = grid(20.0, 20.0, 10, 10)
    mesh_object("Ground", verts, faces, uvs, [ground])
    verts, faces = box((1.0, 1.0, 1.0), (0.0, 0.0, 0.5))
    mesh_object("Cube", verts, faces, atlas_uvs(verts, faces), [red],
                location=(-1.6, 0.6, 0.0), rotation=(0.0, 0.0, math.radians(20.0)))
    verts, faces, uvs = uv_sphere(0.6, 32, 16)
    mesh_object("Sphere", verts, faces, uvs, [blue], smooth=True, location=(1.4, 1.1, 0.6))
    # Pole: 2 m tall, 4 cm radius; smooth sides with exact radial custom normals, flat n-gon caps.
    verts, faces = cylinder(0.04, 0.04, 2.0, 16)
    pole = mesh_object("Pole", verts, faces, atlas_uvs(verts, faces), [steel], smooth=True,
                       location=(0.4, -1.3, 0.0))
    set_cylinder_normals(pole.data)
    # Plate: a single 1 x 1 m quad floating 1.2 m above the ground (peter-panning test).
    verts, faces, uvs = grid(1.0, 1.0, 1, 1)
    mesh_object("Plate", verts, faces, uvs, [yellow], location=(-0.3, -0.2, 1.2),
                rotation=(0.0, 0.0, math.radians(35.0)))

    # Sun: 1 W/m^2 at 50 deg elevation from the +X, -Y side.
    elevation, azimuth = math.radians(50.0), math.radians(-40.0)
    sun_dir = (math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth),
               math.sin(elevation))
    light("Sun", "SUN", 1.0, [6.0 * c for c in sun_dir], target=(0.0, 0.0, 0.0))
    # Spot: 1500 W (I = 119 W/sr inside the 60 deg cone), 7.4 m from the centre: E = 1.5 W/m^2
    # on the ground there.
    light("Spot", "SPOT", 1500.0, (-3.0, -4.5, 5.0), target=(0.0, 0.0, 0.0),
          spot_size=math.radians(60.0), spot_blend=0.15)
    # Point: 600 W (I = 48 W/sr) at 4 m height: E = 3.0 W/m^2 on the ground right below it.
    light("Point", "POINT", 600.0, (-2.5, 3.0, 4.0))

    camera((5.0, -6.0, 8.0), target=(-0.2, 0.2, 0.2), lens=38.0)
    world("Black", (0.0, 0.0, 0.0), 0.0)
    render_settings(scene, max_bounces=4, diffuse=2, glossy=2, transmission=0)


def set_cylinder_normals(mesh: bpy.types.Mesh) -> None:
    """Custom split normals of an upright cylinder around the object's Z axis: the exact radial
    normal on the sides, +-Z on the caps (what the geometry approximates)."""
    positions = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", positions)
    positions = positions.reshape(-1, 3)
    loop_normals = np.zeros((len(mesh.loops), 3))
    for poly in mesh.polygons:
        cap = abs(poly.normal.z) > 0.5
        for li in poly.loop_indices:
            if cap:
                loop_normals[li] = (0.0, 0.0, math.copysign(1.0, poly.normal.z))
            else:
                x, y, _ = positions[mesh.loops[li].vertex_index]
                loop_normals[li] = np.array([x, y, 0.0]) / math.hypot(x, y)
    mesh.normals_split_custom_set(loop_normals.tolist())
    mesh.update()


def build_raytrace() -> None:
    """Whitted ray tracing: a mirror sphere and a hollow glass sphere over a red and yellow
    checkerboard (Checker Texture on UVs), one point light, a constant sky-blue world."""
    scene = reset("Raytrace")
    mirror = material("Mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0)
    glass = material("Glass", (1.0, 1.0, 1.0), roughness=0.0, specular=0.5, transmission=1.0,
                     ior=1.5)
    board = material("Checkerboard")
    # 16 squares per UV unit on an 8 m plane: 0.5 m squares.
    checker_texture(board, (0.8, 0.7, 0.1), (0.6, 0.05, 0.04), 16.0)

    verts, faces, uvs = grid(8.0, 8.0, 1, 1)
    mesh_object("CheckerPlane", verts, faces, uvs, [board])
    verts, faces, uvs = uv_sphere(0.5, 48, 24)
    mesh_object("MirrorSphere", verts, faces, uvs, [mirror], smooth=True,
                location=(-0.7, 0.4, 0.5))
    # Hollow glass sphere: outer shell r = 0.5 m facing out, inner shell r = 0.45 m with flipped
    # normals (facing the centre), so the glass is a 5 cm thick closed solid.
    outer_v, outer_f, outer_uv = uv_sphere(0.5, 48, 24)
    inner_v, inner_f, inner_uv = uv_sphere(0.45, 48, 24)
    inner_f = [list(reversed(f)) for f in inner_f]
    inner_uv = np.concatenate([uv[::-1] for uv in np.split(inner_uv, np.cumsum(
        [len(f) for f in inner_f])[:-1])])
    verts, faces = merge((outer_v, outer_f), (inner_v, inner_f))
    mesh_object("HollowGlassSphere", verts, faces, np.concatenate([outer_uv, inner_uv]),
                [glass], smooth=True, location=(0.75, -0.3, 0.5))

    # Point light, radius 0: 1500 W, I = 119 W/sr; 6.2 m from the origin: E = 3.1 W/m^2 there
    # on a surface facing it.
    light("Point", "POINT", 1500.0, (2.0, -3.0, 5.0))
    camera((0.2, -4.6, 1.7), target=(0.0, 0.0, 0.45), lens=35.0)
    world("SkyBlue", (0.1, 0.15, 0.25))
    # Whitted: diffuse surfaces see lights directly only; specular chains long enough for glass.
    render_settings(scene, max_bounces=16, diffuse=0, glossy=8, transmission=16)


SCENES: dict[str, Callable[[], None]] = {
    "cornell_box": build_cornell_box,
    "env_room": build_env_room,
    "bump": build_bump,
    "shadows": build_shadows,
    "raytrace": build_raytrace,
}


def save(path: Path) -> None:
    """Save the current file compressed, overwriting without leaving a `.blend1` backup."""
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.context.preferences.filepaths.save_version = 0  # session only: preferences not saved
    bpy.context.view_layer.update()  # store evaluated world matrices with the objects
    bpy.ops.wm.save_as_mainfile(filepath=str(path), compress=True, check_existing=False,
                                relative_remap=False)


def main(argv: Sequence[str] | None = None) -> list[Path]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", action="append", choices=sorted(SCENES), metavar="NAME",
                        help=f"build only this scene (repeatable): {', '.join(SCENES)}")
    parser.add_argument("--out", type=Path, default=HERE, help="output folder (default: %(default)s)")
    args = parser.parse_args(argv)
    written = []
    for name in args.only or SCENES:
        SCENES[name]()
        path = args.out / f"{name}.blend"
        save(path)
        written.append(path)
        print(f"wrote {path} ({path.stat().st_size / 1024:.0f} KiB)")
    return written


if __name__ == "__main__":
    main(sys.argv[1:])
