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
from mathutils import Vector

HERE = Path(__file__).resolve().parent
# The published Cornell box data, kept with the tests' reference data (sources in tests/data/README.md).
CORNELL_JSON = HERE.parent / "tests" / "data" / "cornell_box.json"

# ---------------------------------------------------------------------------------------------
# Render settings shared by every scene
# ---------------------------------------------------------------------------------------------

RESOLUTION = (320, 240)  # pixels; small on purpose (previews and reference renders)
SAMPLES = 64  # Cycles samples per pixel, fixed (adaptive sampling off)
UV_MARGIN = 1.0 / 64.0  # UV gap around each face of an atlas: 2 texels at 128^2, for dilation
MM = 0.001  # metres per millimetre


# ---------------------------------------------------------------------------------------------
# Geometry: plain (vertices, faces, per-loop UVs) built in NumPy, so no bmesh operator defaults
# can differ between Blender versions.
# ---------------------------------------------------------------------------------------------

Faces = list[list[int]]


def newell_normal(points: np.ndarray) -> np.ndarray:
    """Unit normal of a polygon (k, 3), robust to slight non-planarity (Newell's method)."""
    nxt = np.roll(points, -1, axis=0)
    n = np.array(
        [
            np.sum((points[:, 1] - nxt[:, 1]) * (points[:, 2] + nxt[:, 2])),
            np.sum((points[:, 2] - nxt[:, 2]) * (points[:, 0] + nxt[:, 0])),
            np.sum((points[:, 0] - nxt[:, 0]) * (points[:, 1] + nxt[:, 1])),
        ]
    )
    return n / np.linalg.norm(n)


def orient_faces(verts: np.ndarray, faces: Faces, centre: Sequence[float], outward: bool) -> Faces:
    """Wind each face of a convex shell so its normal points away from (or towards) `centre`."""
    oriented = []
    for face in faces:
        pts = verts[face]
        away = float(np.dot(newell_normal(pts), pts.mean(axis=0) - np.asarray(centre))) > 0.0
        oriented.append(list(face) if away == outward else list(reversed(face)))
    return oriented


def box(size: Sequence[float], centre: Sequence[float] = (0.0, 0.0, 0.0)):
    """An axis-aligned box: 8 vertices (m) and 6 outward quads (-Z, +Z, -Y, +Y, -X, +X)."""
    half = np.asarray(size, float) / 2.0
    corner = np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)], float)
    verts = np.asarray(centre, float) + (corner * 2.0 - 1.0) * half
    faces = [[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]]
    return verts, orient_faces(verts, faces, centre, outward=True)


def merge(*parts):
    """Concatenate (verts, faces) pairs into one mesh."""
    verts, faces, offset = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces += [[i + offset for i in face] for face in f]
        offset += len(v)
    return np.concatenate(verts), faces


def cylinder(r_bottom: float, r_top: float, depth: float, segments: int, caps: bool = True):
    """A cylinder or cone frustum along +Z, base at z = 0: side quads and n-gon caps."""
    angle = 2.0 * np.pi * np.arange(segments) / segments
    ring = np.stack([np.cos(angle), np.sin(angle), np.zeros(segments)], axis=1)
    bottom = ring * [r_bottom, r_bottom, 1.0]
    top = ring * [r_top, r_top, 1.0] + [0.0, 0.0, depth]
    verts = np.concatenate([bottom, top])
    faces = [[j, (j + 1) % segments, segments + (j + 1) % segments, segments + j]
             for j in range(segments)]
    if caps:
        faces += [list(range(segments)), list(range(segments, 2 * segments))]
    return verts, orient_faces(verts, faces, (0.0, 0.0, depth / 2.0), outward=True)


def uv_sphere(radius: float, segments: int, rings: int):
    """A UV sphere around the origin: verts, faces (pole triangles, quads) and lat-long UVs.

    UVs are per loop, (L, 2): u = longitude / 2pi (0 at +X, increasing counter-clockwise seen
    from +Z), v = 1 at the north pole (+Z) down to 0 at the south pole.
    """
    theta = np.pi * np.arange(1, rings) / rings  # polar angle of the inner rings
    phi = 2.0 * np.pi * np.arange(segments) / segments
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    ring_verts = np.stack(
        [st * np.cos(phi), st * np.sin(phi), np.broadcast_to(ct, (rings - 1, segments))], axis=-1
    ).reshape(-1, 3)
    verts = radius * np.concatenate([[[0.0, 0.0, 1.0]], ring_verts, [[0.0, 0.0, -1.0]]])
    north, south = 0, len(verts) - 1

    def vid(i: int, j: int) -> int:  # inner ring i (0: nearest the north pole), segment j
        return 1 + i * segments + j % segments

    faces, uvs = [], []
    for j in range(segments):
        u0, u1 = j / segments, (j + 1) / segments
        v_top = 1.0 - 1.0 / rings
        faces.append([north, vid(0, j), vid(0, j + 1)])
        uvs += [((u0 + u1) / 2.0, 1.0), (u0, v_top), (u1, v_top)]
        for i in range(rings - 2):
            va, vb = 1.0 - (i + 1) / rings, 1.0 - (i + 2) / rings
            faces.append([vid(i, j), vid(i + 1, j), vid(i + 1, j + 1), vid(i, j + 1)])
            uvs += [(u0, va), (u0, vb), (u1, vb), (u1, va)]
        v_bot = 1.0 / rings
        faces.append([south, vid(rings - 2, j + 1), vid(rings - 2, j)])
        uvs += [((u0 + u1) / 2.0, 0.0), (u1, v_bot), (u0, v_bot)]
    return verts, faces, np.asarray(uvs)


def grid(size_x: float, size_y: float, nx: int, ny: int):
    """A flat grid of quads in z = 0 centred on the origin, facing +Z, UVs spanning [0, 1]^2."""
    xs, ys = np.linspace(0.0, 1.0, nx + 1), np.linspace(0.0, 1.0, ny + 1)
    u, v = np.meshgrid(xs, ys)  # (ny+1, nx+1)
    verts = np.stack([(u - 0.5) * size_x, (v - 0.5) * size_y, np.zeros_like(u)], -1).reshape(-1, 3)
    faces = [[y * (nx + 1) + x, y * (nx + 1) + x + 1, (y + 1) * (nx + 1) + x + 1,
              (y + 1) * (nx + 1) + x] for y in range(ny) for x in range(nx)]
    uvs = np.concatenate([np.stack([u.ravel()[f], v.ravel()[f]], 1) for f in faces])
    return verts, faces, uvs


def planar_uvs(verts: np.ndarray, faces: Faces, margin: float = UV_MARGIN) -> np.ndarray:
    """Per-loop UVs of a (near-)planar mesh: its projection onto its own plane, fitted into
    [margin, 1 - margin]^2 with the aspect ratio kept (uniform texel density)."""
    normal = newell_normal(verts[faces[0]])
    e1 = verts[faces[0][1]] - verts[faces[0][0]]
    e1 = e1 - normal * np.dot(e1, normal)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    flat = np.stack([verts @ e1, verts @ e2], axis=1)
    flat -= flat.min(axis=0)
    flat *= (1.0 - 2.0 * margin) / flat.max()
    return np.concatenate([flat[f] for f in faces]) + margin


def atlas_uvs(verts: np.ndarray, faces: Faces, margin: float = UV_MARGIN) -> np.ndarray:
    """Per-loop UVs that never overlap: each face flattened onto its own plane and placed in its
    own cell of a square grid, one scale for all faces (uniform texel density, lightmap-ready)."""
    cols = math.ceil(math.sqrt(len(faces)))
    cell = 1.0 / cols
    flats = []
    for face in faces:
        pts = verts[face]
        normal = newell_normal(pts)
        e1 = pts[1] - pts[0]
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(normal, e1)
        flat = np.stack([pts @ e1, pts @ e2], axis=1)
        flats.append(flat - flat.min(axis=0))
    scale = (cell - 2.0 * margin) / max(float(f.max()) for f in flats)
    uvs = []
    for k, flat in enumerate(flats):
        col, row = k % cols, k // cols
        origin = np.array([col * cell + margin, 1.0 - (row + 1) * cell + margin])
        uvs.append(origin + flat * scale)
    return np.concatenate(uvs)


# ---------------------------------------------------------------------------------------------
# Blender data
# ---------------------------------------------------------------------------------------------


def _ensure_node_tree(idblock) -> bpy.types.NodeTree:
    """Blender 4.5 creates materials and worlds without nodes; 5.x always has them (and
    deprecates `use_nodes`), so only switch them on where they are missing."""
    if idblock.node_tree is None:
        idblock.use_nodes = True
    return idblock.node_tree


def mesh_object(
    name: str,
    verts: np.ndarray,
    faces: Faces,
    uvs: np.ndarray,
    materials: Sequence[bpy.types.Material],
    *,
    material_indices: Sequence[int] | None = None,
    smooth: bool = False,
    location: Sequence[float] = (0.0, 0.0, 0.0),
    rotation: Sequence[float] = (0.0, 0.0, 0.0),
    scale: Sequence[float] = (1.0, 1.0, 1.0),
) -> bpy.types.Object:
    """A mesh object linked to the scene; mesh and object share `name`.

    verts (V, 3) m, object space; faces CCW; uvs (L, 2) per loop in face order, stored as the
    mesh's only UV layer "UVMap"; rotation is XYZ Euler, radians.
    """
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(np.asarray(verts, float).tolist(), [], [list(f) for f in faces])
    uv_layer = mesh.uv_layers.new(name="UVMap")
    uv_layer.data.foreach_set("uv", np.asarray(uvs, np.float32).ravel())
    for material in materials:
        mesh.materials.append(material)
    if material_indices is not None:
        mesh.polygons.foreach_set("material_index", np.asarray(material_indices, np.int32))
    mesh.polygons.foreach_set("use_smooth", np.full(len(faces), smooth, bool))
    mesh.update()
    if mesh.validate(verbose=False):
        raise RuntimeError(f"mesh {name!r} needed repairs: fix its construction")
    obj = bpy.data.objects.new(name, mesh)
    obj.location, obj.rotation_euler, obj.scale = location, rotation, scale
    bpy.context.scene.collection.objects.link(obj)
    return obj


def material(
    name: str,
    base_color: Sequence[float] = (0.8, 0.8, 0.8),
    *,
    metallic: float = 0.0,
    roughness: float = 0.5,
    specular: float = 0.0,
    transmission: float = 0.0,
    ior: float = 1.5,
    emission: Sequence[float] = (0.0, 0.0, 0.0),
    emission_strength: float = 0.0,
) -> bpy.types.Material:
    """A Principled BSDF material. The default `specular` ("Specular IOR Level") of 0 makes a
    dielectric exactly Lambertian in Cycles; mirrors and glass pass their own values."""
    mat = bpy.data.materials.new(name)
    tree = _ensure_node_tree(mat)
    tree.nodes.clear()
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    bsdf = tree.nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.name = bsdf.label = "Principled BSDF"
    bsdf.location, out.location = (0.0, 0.0), (300.0, 0.0)
    tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    inputs = bsdf.inputs
    inputs["Base Color"].default_value = (*base_color, 1.0)
    inputs["Metallic"].default_value = metallic
    inputs["Roughness"].default_value = roughness
    inputs["Specular IOR Level"].default_value = specular
    inputs["Transmission Weight"].default_value = transmission
    inputs["IOR"].default_value = ior
    inputs["Emission Color"].default_value = (*emission, 1.0)
    inputs["Emission Strength"].default_value = emission_strength
    mat.diffuse_color = (*base_color, 1.0)  # solid-view colour only
    return mat


def _principled(mat: bpy.types.Material) -> bpy.types.Node:
    return mat.node_tree.nodes["Principled BSDF"]


def _uv_node(mat: bpy.types.Material) -> bpy.types.Node:
    node = mat.node_tree.nodes.new("ShaderNodeUVMap")
    node.uv_map = "UVMap"
    node.location = (-900.0, 0.0)
    return node


def packed_image(name: str, pixels: np.ndarray, *, color: bool) -> bpy.types.Image:
    """An 8-bit image packed into the .blend (stored as PNG).

    pixels (H, W, 3) in [0, 1], row 0 at the TOP; already sRGB-encoded when `color`, else
    linear data (heights), tagged Non-Color. Values are rounded to 8 bits here so the stored
    bytes are exactly what we computed.
    """
    h, w, _ = pixels.shape
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = np.round(np.clip(pixels, 0.0, 1.0) * 255.0) / 255.0
    image = bpy.data.images.new(name, w, h, alpha=False, float_buffer=False)
    image.colorspace_settings.name = "sRGB" if color else "Non-Color"
    image.pixels.foreach_set(np.flipud(rgba).ravel())  # Blender stores the bottom row first
    image.pack()
    return image


def image_texture(mat: bpy.types.Material, image: bpy.types.Image) -> bpy.types.Node:
    """An Image Texture node on the UV layer "UVMap" driving the Base Color."""
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation, tex.extension = image, "Linear", "REPEAT"
    tex.location = (-600.0, 200.0)
    tree.links.new(_uv_node(mat).outputs["UV"], tex.inputs["Vector"])
    tree.links.new(tex.outputs["Color"], _principled(mat).inputs["Base Color"])
    return tex


def bump_map(mat: bpy.types.Material, height: bpy.types.Image, strength: float,
             distance: float) -> bpy.types.Node:
    """Height image (Non-Color, UV layer "UVMap") -> Bump node -> the BSDF's Normal."""
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation, tex.extension = height, "Linear", "REPEAT"
    tex.location = (-600.0, -250.0)
    bump = tree.nodes.new("ShaderNodeBump")
    bump.location = (-250.0, -250.0)
    bump.inputs["Strength"].default_value = strength
    bump.inputs["Distance"].default_value = distance  # m of relief per unit of height
    tree.links.new(_uv_node(mat).outputs["UV"], tex.inputs["Vector"])
    tree.links.new(tex.outputs["Color"], bump.inputs["Height"])
    tree.links.new(bump.outputs["Normal"], _principled(mat).inputs["Normal"])
    return bump


def checker_texture(mat: bpy.types.Material, color1, color2, scale: float) -> bpy.types.Node:
    """A Checker Texture node on UV coordinates (Texture Coordinate UV output), on Base Color."""
    tree = mat.node_tree
    coords = tree.nodes.new("ShaderNodeTexCoord")
    coords.location = (-600.0, 200.0)
    checker = tree.nodes.new("ShaderNodeTexChecker")
    checker.location = (-300.0, 200.0)
    checker.inputs["Color1"].default_value = (*color1, 1.0)
    checker.inputs["Color2"].default_value = (*color2, 1.0)
    checker.inputs["Scale"].default_value = scale  # squares per UV unit
    tree.links.new(coords.outputs["UV"], checker.inputs["Vector"])
    tree.links.new(checker.outputs["Color"], _principled(mat).inputs["Base Color"])
    return checker


def light(name: str, kind: str, energy: float, location: Sequence[float], *,
          target: Sequence[float] | None = None, color=(1.0, 1.0, 1.0),
          **settings) -> bpy.types.Object:
    """A light object aimed (its local -Z) at `target`; point and spot lights get radius 0,
    suns angle 0, unless `settings` say otherwise. `energy` in Blender's units (see module doc)."""
    data = bpy.data.lights.new(name, kind)
    data.energy = energy
    data.color = color
    if kind in {"POINT", "SPOT"}:
        data.shadow_soft_size = 0.0  # a true point: sharp shadows
    if kind == "SUN":
        data.angle = 0.0
    for key, value in settings.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    if target is not None:
        aim(obj, target)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def aim(obj: bpy.types.Object, target: Sequence[float]) -> None:
    """Point the object's local -Z at `target`, local +Y as close to world +Z as possible."""
    direction = Vector(target) - Vector(obj.location)
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler("XYZ")


def camera(location: Sequence[float], *, target: Sequence[float] | None = None,
           rotation: Sequence[float] | None = None, lens: float = 35.0,
           sensor: tuple[float, float] = (36.0, 24.0)) -> bpy.types.Object:
    """The scene camera, named "Camera": lens and sensor (width, height) in mm."""
    data = bpy.data.cameras.new("Camera")
    data.lens = lens
    data.sensor_width, data.sensor_height = sensor
    data.sensor_fit = "AUTO"
    data.clip_start, data.clip_end = 0.05, 100.0
    obj = bpy.data.objects.new("Camera", data)
    obj.location = location
    if rotation is not None:
        obj.rotation_euler = rotation
    elif target is not None:
        aim(obj, target)
    scene = bpy.context.scene
    scene.collection.objects.link(obj)
    scene.camera = obj
    return obj


def world(name: str, color: Sequence[float], strength: float = 1.0) -> bpy.types.World:
    """A world of constant radiance `color` x `strength` W/(m^2 sr) (black: no ambient light)."""
    data = bpy.data.worlds.new(name)
    tree = _ensure_node_tree(data)
    tree.nodes.clear()
    background = tree.nodes.new("ShaderNodeBackground")
    output = tree.nodes.new("ShaderNodeOutputWorld")
    output.location = (300.0, 0.0)
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    tree.links.new(background.outputs["Background"], output.inputs["Surface"])
    data.color = color  # solid-view colour only
    bpy.context.scene.world = data
    return data


def reset(scene_name: str) -> bpy.types.Scene:
    """Factory settings with an empty scene: nothing from the user's preferences or startup."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.name = scene_name
    return scene


def render_settings(scene: bpy.types.Scene, *, resolution=RESOLUTION, samples=SAMPLES,
                    max_bounces: int, diffuse: int, glossy: int, transmission: int) -> None:
    """Cycles on the CPU, fixed seed and sample count, no denoising, plain "Standard" view."""
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = samples
    cycles.preview_samples = 16
    cycles.use_adaptive_sampling = False  # the same samples everywhere: comparable noise
    cycles.use_denoising = False
    cycles.use_preview_denoising = False
    cycles.seed = 0
    cycles.use_animated_seed = False
    cycles.max_bounces = max_bounces
    cycles.diffuse_bounces = diffuse
    cycles.glossy_bounces = glossy
    cycles.transmission_bounces = transmission
    cycles.transparent_max_bounces = 8
    cycles.volume_bounces = 0
    render = scene.render
    render.resolution_x, render.resolution_y = resolution
    render.resolution_percentage = 100
    render.film_transparent = False
    scene.display_settings.display_device = "sRGB"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0


# ---------------------------------------------------------------------------------------------
# Images, generated in NumPy from fixed seeds (only `Generator.random`, whose stream is stable)
# ---------------------------------------------------------------------------------------------


def checkerboard_image(width: int, height: int, square: int, light_rgb, dark_rgb) -> np.ndarray:
    """(H, W, 3) sRGB-encoded floor tiles: square size in pixels, the top-left square light."""
    rows, cols = np.indices((height, width)) // square
    light_tile = ((rows + cols) % 2 == 0)[..., None]
    return np.where(light_tile, np.asarray(light_rgb, float), np.asarray(dark_rgb, float))


def orange_peel_height(width: int = 256, height: int = 128, dimples: int = 500,
                       seed: int = 7) -> np.ndarray:
    """(H, W, 3) heights in [0, 1]: shallow round dimples (a Worley F1 pattern) that tile in u.

    The lat-long UV of a sphere stretches u by 2 (2pi around vs pi pole to pole), so distances
    are measured with u scaled by width/height to keep the dimples round on the sphere.
    """
    rng = np.random.default_rng(seed)
    centres = rng.random((dimples, 2)) * [width, height]  # pixels
    py, px = np.mgrid[0:height, 0:width] + 0.5
    nearest = np.full((height, width), np.inf)
    for cx, cy in centres:
        dx = np.abs(px - cx)
        dx = np.minimum(dx, width - dx)  # wrap around the seam in u
        nearest = np.minimum(nearest, dx * dx + (py - cy) ** 2)
    dist = np.sqrt(nearest)
    heights = np.sqrt(dist / dist.max())  # 0 at dimple centres, flat rims between them
    return np.repeat(heights[..., None], 3, axis=2)


def brick_images(size: int = 256, rows: int = 16, cols: int = 8, mortar: int = 1,
                 bevel: int = 3, seed: int = 11) -> tuple[np.ndarray, np.ndarray]:
    """A running-bond brick wall that tiles: (H, W, 3) heights in [0, 1] (mortar 0, brick
    faces 1, `bevel` px ramps at brick edges) and (H, W, 3) sRGB-encoded colours, one slightly
    varied colour per brick."""
    rng = np.random.default_rng(seed)
    brick_h, brick_w = size // rows, size // cols
    y, x = np.mgrid[0:size, 0:size]
    row = y // brick_h
    xs = (x + (row % 2) * (brick_w // 2)) % size  # odd rows offset by half a brick
    col = xs // brick_w
    # distance (px) from each pixel to the nearest mortar line, inside its brick
    edge = np.minimum.reduce([y % brick_h, brick_h - 1 - y % brick_h,
                              xs % brick_w, brick_w - 1 - xs % brick_w]).astype(float)
    heights = np.clip((edge - mortar + 1.0) / bevel, 0.0, 1.0)
    shade = rng.random((rows, cols))  # per-brick colour variation
    brick_rgb = np.array([0.62, 0.27, 0.18]) + (shade[row, col, None] - 0.5) * [0.16, 0.08, 0.06]
    mortar_rgb = np.array([0.72, 0.70, 0.66])
    colours = np.where((heights > 0.0)[..., None], brick_rgb, mortar_rgb)
    return np.repeat(heights[..., None], 3, axis=2), colours


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
