"""The snapshot: the evaluated depsgraph (modifiers applied, instances expanded) read into one
kernel `Scene`: geometry, the scene's material table, lights, camera and world."""

from __future__ import annotations

from dataclasses import fields, replace

import bpy
import numpy as np

from ...kernels.geometry.scene import Light, Material, ObjectInfo, Scene, Texture
from ...kernels.shading.material_maps import resolve_material_maps
from .attributes import material_attribute
from .camera import read_camera
from .light_linking import linked_lights, linking_of, mesh_linking_notes
from .lights import is_portal, read_light
from .materials import DEFAULT_MATERIAL, MaterialReader
from .mesh import MeshChunk, mesh_chunk, triangles_problem
from .ray_visibility import hidden_from, visibility_notes
from .render_state import render_state
from .request import SnapshotRequest
from .socket_fallback import BakeTarget
from .transforms import matrix_array
from .world import (
    read_camera_world,
    read_world,
    read_world_texture,
    world_env_mapping,
    world_hidden_from,
    world_volume_notes,
)

# What `snapshot` reads unless told otherwise: everything (a frozen dataclass, shared safely).
DEFAULT_REQUEST = SnapshotRequest()
# From this Blender version on, Cycles' Normal Map node builds its tangent frame on the unit
# interpolated normal (measured in 5.2; 4.5 uses it as interpolated): `Scene.normal_map_unit_normal`.
UNIT_NORMAL_MAP_VERSION = (5, 0, 0)


def snapshot(context=None, request: SnapshotRequest = DEFAULT_REQUEST,
             resolution: tuple[int, int] | None = None) -> Scene:
    """Read the evaluated scene of `context` (default: bpy.context) into a kernel `Scene`, as
    Cycles renders it: with the render settings of modifiers, subdivision levels, curves,
    particles and objects disabled in viewports (`render_state`; the file is left as it was)."""
    context = context or bpy.context
    with render_state(context.scene, context.view_layer) as unswitched:
        return _snapshot(context, request, resolution, list(unswitched))


# Object types Cycles renders that are not meshes, nor turned into one by the depsgraph (as
# curves, surfaces, text and metaballs are).
UNMODELLED_GEOMETRY = {"CURVES": "hair curves", "POINTCLOUD": "a point cloud",
                       "VOLUME": "a volume"}


def _snapshot(context, request: SnapshotRequest, resolution: tuple[int, int] | None,
              ignored: list[str]) -> Scene:
    scene = context.scene
    depsgraph = context.evaluated_depsgraph_get()
    chunks: list[MeshChunk] = []
    lights: list[Light] = []
    instance_counts: dict[str, int] = {}
    hidden: dict[str, tuple[str, ...]] = {}  # source object -> the rays Cycles hides it from
    skipped: set[str] = set()  # objects of geometry the kernels do not read, noted once
    linking: dict[str, dict] = {}  # light name -> its light and shadow linking (`linking_of`)

    for inst in depsgraph.object_instances:
        obj = inst.object
        source = obj.original
        holder = inst.parent.original if inst.is_instance and inst.parent else source
        if source.hide_render or holder.hide_render or not inst.show_self:
            continue  # show_self: an instancer shown or not (`render_state`: as in renders)
        # The depsgraph lists a curve, surface, text or metaball object twice: as itself and as
        # a MESH instance of its evaluated geometry parented to itself (4.5 and 5.2; the same
        # triangles, which Cycles renders once). Only MESH entries are read, and that instance
        # stands for the object itself.
        if obj.type in UNMODELLED_GEOMETRY and source.name not in skipped:
            skipped.add(source.name)  # once, however many times it is instanced
            ignored.append(f"object '{source.name}' ({UNMODELLED_GEOMETRY[obj.type]}): Cycles "
                           f"renders it, the kernels read meshes only; skipped")
        if obj.type not in ("MESH", "LIGHT"):
            continue
        if source.name_full not in hidden:
            hidden[source.name_full] = hidden_from(source)
            ignored.extend(visibility_notes(source, hidden[source.name_full])
                           + mesh_linking_notes(source) + _particle_hair(source))
        is_instance = inst.is_instance and not (holder == source and source.type != "MESH")
        matrix = matrix_array(inst.matrix_world)
        base = source.name if not is_instance else f"{holder.name}/{source.name}"
        k = instance_counts.get(base, 0)
        instance_counts[base] = k + 1
        name = base if k == 0 else f"{base}#{k}"
        if obj.type == "LIGHT":
            if request.lights and not is_portal(obj.data):
                light, why = read_light(name, obj.data, matrix)
                lights.append(replace(light, hidden_from=hidden[source.name_full]))
                linking[name] = linking_of(source)
                ignored.extend(why)
            continue
        if request.objects is not None and source.name not in request.objects:
            continue
        slot_materials = [slot.material for slot in obj.material_slots]
        original_mesh = source.data if source.type == "MESH" and not is_instance else None
        # An object in Edit Mode (a file saved so): its evaluated data is the edit mesh's
        # wrapper, whose arrays read empty; Cycles renders its mesh, which to_mesh gives.
        editing = source.mode == "EDIT" and obj.type == "MESH"
        try:
            with np.errstate(over="ignore", invalid="ignore"):  # judged just below
                chunk = mesh_chunk(name, source.name, is_instance,
                                   obj.to_mesh() if editing else obj.data, matrix, request,
                                   original_mesh, slot_materials,
                                   source.data if source.type == "MESH" else None)
        finally:
            if editing:
                obj.to_mesh_clear()
        chunk.hidden_from = hidden[source.name_full]
        why = triangles_problem(chunk.triangles)
        if why is not None:  # a partly usable scene: the object is left out, by name
            ignored.append(f"object '{name}' {why}; skipped")
            continue
        chunks.append(chunk)

    # Materials: one table for the whole scene, in first-seen order; index 0 is the default surface.
    reader = MaterialReader(request)
    materials: list[Material] = [DEFAULT_MATERIAL]
    material_index: dict[str, int] = {}
    per_object: set[str] = set()  # materials read per object (a bake over it, or its scale)
    for chunk in chunks:
        table = np.zeros(max(1, len(chunk.slot_materials)), np.int32)
        source = bpy.data.objects.get(chunk.source_name)
        target = None if source is None else BakeTarget(source, depsgraph, chunk)
        for slot, mat in enumerate(chunk.slot_materials):
            if mat is None:
                continue
            key = mat.name_full
            if key in per_object:  # read again for each object (its UVs' bake, its scale)
                key = (key, chunk.source_name)
            if key not in material_index:
                material_index[key] = len(materials)
                materials.append(reader.read(mat, target))
                if reader.object_dependent:
                    per_object.add(mat.name_full)
                    material_index[(mat.name_full, chunk.source_name)] = material_index[key]
            table[slot] = material_index[key]
        # Out-of-range slots render with the default surface in Cycles; do the same.
        in_range = chunk.slot_ids < len(chunk.slot_materials)
        chunk.slot_ids = np.where(in_range, table[np.minimum(chunk.slot_ids, table.size - 1)], 0)
    attribute_of = [material_attribute(mat, ignored) for mat in materials]
    for chunk in chunks:
        chunk.colors = _corner_colors(chunk, attribute_of)
    for mat in materials:
        ignored.extend(f"material '{mat.name}': {why}" for why in mat.ignored)
    materials = [_checked_emission(mat, ignored) for mat in materials]
    lights = [light for light in (_checked_light(light, ignored) for light in lights) if light]

    camera = None
    if request.camera:
        if scene.camera is None:
            ignored.append("the scene has no camera")
        else:
            camera = read_camera(scene, scene.camera, resolution)
            if scene.camera.type == "CAMERA" and scene.camera.data.dof.use_dof:
                ignored.append(f"camera '{scene.camera.name}': depth of field is not modelled (a "
                               f"pinhole camera; the Cycles models turn it off)")
    texture = read_world_texture(scene, render=request.world_render)
    world, why = read_world(scene, texture)
    ignored.extend(why + world_volume_notes(scene) + _layer_notes(context.view_layer))
    # Emission, metallic and roughness textures are resolved per triangle once, here, so that
    # every kernel reads them as constants (kernels/shading/material_maps.py).
    lights = linked_lights(lights, linking, chunks)  # chunks: the scene's objects, in order
    ignored.extend(f"light '{light.name}': its light linking holds for the light it casts; its "
                   f"image in mirrors and glass shows in every object" for light in lights
                   if light.kind == "AREA" and light.receivers is not None)
    return resolve_material_maps(replace(
        _assemble(chunks, materials, lights, camera, world, request, ignored),
        world_texture=texture, world_hidden_from=world_hidden_from(scene),
        camera_world=read_camera_world(scene, render=request.world_render),
        world_transform=None if texture is None else world_env_mapping(scene)))


# Radiometric values above this are taken as broken: Blender stores an inf strength as FLT_MAX
# (3.4e38), whose products overflow float32 to inf in every buffer it reaches. 1e15 is eight
# orders above the sun's radiance (~1.5e7 W/(m^2 sr)) and leaves float32 sums room.
MAX_RADIOMETRIC = 1e15
# The radiometric value of each kind of light (exactly one is set).
_LIGHT_VALUES = ("intensity", "irradiance", "radiance")


def _checked_light(light: Light, ignored: list) -> Light | None:
    """`light` as the kernels can use it: left out (None) when its place or its value is not
    finite, negative channels clamped to 0; each change noted in `ignored` (metrics.json)."""
    for name in _LIGHT_VALUES:
        value = getattr(light, name)
        if value is None:
            continue
        if not (np.isfinite(value).all() and np.all(np.abs(value) <= MAX_RADIOMETRIC)
                and np.isfinite(light.position).all() and np.isfinite(light.direction).all()):
            ignored.append(f"light '{light.name}': its power or placement is not finite (or "
                           f"above {MAX_RADIOMETRIC:.0e}); left out")
            return None
        if np.any(np.asarray(value) < 0.0):
            ignored.append(f"light '{light.name}': negative power clamped to 0 (a light cannot "
                           "take light away)")
            light = replace(light, **{name: np.maximum(value, 0.0)})
    return light


def _checked_emission(mat: Material, ignored: list) -> Material:
    """`mat` with emission channels that are negative, not finite or above MAX_RADIOMETRIC
    (an inf strength in the file) taken as 0, noted in `ignored`."""
    emission = np.asarray(mat.emission)
    good = np.isfinite(emission) & (emission >= 0.0) & (emission <= MAX_RADIOMETRIC)
    if good.all():
        return mat
    ignored.append(f"material '{mat.name}': emission {[float(f'{e:.3g}') for e in emission]} is "
                   f"not a radiance in [0, {MAX_RADIOMETRIC:.0e}]; those channels are taken as 0")
    fixed = np.where(good, emission, 0.0)
    return replace(mat, emission=fixed.astype(emission.dtype))


def _corner_colors(chunk, attribute_of: list) -> np.ndarray | None:
    """(T, 3, 3) float32: per triangle of `chunk` the attribute its material reads
    (`attribute_of[material index]`, 0 where the mesh lacks it); None: no material reads one."""
    names = {m: attribute_of[m] for m in np.unique(chunk.slot_ids) if attribute_of[m] is not None}
    if not names:
        return None
    colors = np.zeros((len(chunk.slot_ids), 3, 3), np.float32)
    for m, name in names.items():
        values = chunk.attributes.get(name)
        if values is not None:
            rows = chunk.slot_ids == m
            colors[rows] = values[rows]
    return colors


def _particle_hair(obj) -> list[str]:
    """Notes for `obj`'s hair particle systems drawn as strands (Particles > Render As Path),
    which Cycles renders as curves and the kernels, reading meshes only, leave out."""
    notes = []
    for mod in getattr(obj, "modifiers", ()):
        if mod.type != "PARTICLE_SYSTEM" or not mod.show_render:
            continue
        settings = mod.particle_system.settings
        if settings.type == "HAIR" and settings.render_type == "PATH":
            notes.append(f"object '{obj.name}': hair particles '{mod.particle_system.name}' render "
                         f"as strands in Cycles; the kernels read meshes only, left out")
    return notes


def _layer_notes(view_layer) -> list[str]:
    """Notes for the view layer's collections that Cycles renders as holdouts or indirect-only
    (Outliner > Holdout, Indirect Only), which the kernels read as ordinary surfaces."""
    notes, stack = [], list(view_layer.layer_collection.children)
    while stack:
        layer = stack.pop()
        if layer.exclude:
            continue
        stack.extend(layer.children)
        if not layer.collection.all_objects:
            continue
        for flag, what in (("holdout", "a holdout"), ("indirect_only", "indirect only")):
            if getattr(layer, flag, False):
                notes.append(f"collection '{layer.name}': {what} in Cycles; not modelled, read "
                             f"as ordinary surfaces")
    return notes


def _reads_uv(materials, slot_ids: np.ndarray) -> bool:
    """Whether a material of these triangles (`slot_ids` into `materials`) looks a texture up by
    UV: an object without UVs is worth a note only then."""
    values = (getattr(materials[m], f.name) for m in np.unique(slot_ids) for f in fields(Material))
    return any(isinstance(value, Texture) and value.coordinates == "UV" for value in values)


def _assemble(chunks, materials, lights, camera, world, request, ignored) -> Scene:
    counts = [c.triangles.shape[0] for c in chunks]
    starts = np.concatenate([[0], np.cumsum(counts)]).astype(int)
    objects = []
    for k, chunk in enumerate(chunks):
        if chunk.uv is None and request.uv and _reads_uv(materials, chunk.slot_ids):
            ignored.append(f"object '{chunk.name}' has no UV layer: textures read UV (0, 0)")
        objects.append(ObjectInfo(
            name=chunk.name, source_name=chunk.source_name, tri_start=int(starts[k]),
            tri_count=counts[k], has_uv=chunk.uv is not None,
            has_lightmap_uv=chunk.lightmap_uv is not None,
            topology_matches_original=chunk.topology_matches_original,
            is_instance=chunk.is_instance, hidden_from=chunk.hidden_from))

    def stack(attr, shape, dtype):
        parts = [getattr(c, attr) if getattr(c, attr) is not None else np.zeros((n,) + shape, dtype)
                 for c, n in zip(chunks, counts, strict=True)]
        return np.concatenate(parts).astype(dtype) if parts else np.zeros((0,) + shape, dtype)

    return Scene(
        triangles=stack("triangles", (3, 3), np.float32),
        normals=stack("normals", (3, 3), np.float32),
        uv=stack("uv", (3, 2), np.float32),
        lightmap_uv=stack("lightmap_uv", (3, 2), np.float32) if request.lightmap_uv else None,
        generated=stack("generated", (3, 3), np.float32) if request.uv else None,
        corner_colors=(stack("colors", (3, 3), np.float32)
                       if any(c.colors is not None for c in chunks) else None),
        corner_tangents=(stack("tangents", (3, 3), np.float32)
                         if any(c.tangents is not None for c in chunks) else None),
        corner_signs=(stack("tangent_signs", (3,), np.float32)
                      if any(c.tangents is not None for c in chunks) else None),
        normal_map_uv=(np.concatenate([
            c.normal_map_uv if c.normal_map_uv is not None
            else c.uv if c.uv is not None else np.zeros((n, 3, 2), np.float32)
            for c, n in zip(chunks, counts, strict=True)]).astype(np.float32)
            if any(c.normal_map_uv is not None for c in chunks) else None),
        normal_map_unit_normal=bpy.app.version >= UNIT_NORMAL_MAP_VERSION,
        material_ids=stack("slot_ids", (), np.int32),
        object_ids=np.repeat(np.arange(len(chunks), dtype=np.int32), counts),
        corner_loops=stack("corner_loops", (3,), np.int32),
        corner_verts=stack("corner_verts", (3,), np.int32),
        objects=tuple(objects),
        materials=tuple(materials),
        lights=tuple(lights),
        camera=camera,
        world_color=np.asarray(world, np.float32),
        ignored=tuple(ignored),
    )
