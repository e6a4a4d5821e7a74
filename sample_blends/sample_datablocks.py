"""Blender data of the sample scenes: mesh objects, materials, packed images and texture nodes,
lights, cameras, worlds, and the render settings every scene shares."""

from __future__ import annotations

from collections.abc import Sequence

import bpy
import numpy as np
from mathutils import Vector
from sample_geometry import Faces

# Render settings shared by every scene
RESOLUTION = (320, 240)  # pixels; small on purpose (previews and reference renders)
SAMPLES = 64  # Cycles samples per pixel, fixed (adaptive sampling off)


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
