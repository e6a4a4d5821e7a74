"""Normal maps made (issue 40): each mesh's relief — its materials' Bump-node heights, a named
procedural pattern or an image — turned into a tangent-space normal map over its UV charts
(float image "Normal <object>", Non-Color), or (source "high") a detailed mesh's normals baked
into each low mesh's map as Cycles' Selected to Active does (`kernels/normalmap/high_to_low.py`);
and with Wire into Material the material wired
Image Texture -> Normal Map (tangent space) -> the Principled BSDF's Normal, in place of the Bump
node the map was made from (restorable: addon/bridge/normal_maps.py)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import bpy
import numpy as np

from ..addon.bridge import normal_maps
from ..addon.bridge.images import image_pixels
from ..addon.bridge.render_state import render_state
from ..addon.bridge.request import SnapshotRequest
from ..addon.bridge.snapshot import snapshot
from ..kernels.geometry.scene import triangle_areas
from ..kernels.normalmap.dilate import FLAT, pad_normals
from ..kernels.normalmap.encode import normals_to_rgb, to_float, to_uint8
from ..kernels.normalmap.from_height import STEEP_COS, NormalMap, NormalMapSettings, normal_map_steps
from ..kernels.normalmap.heights import ImageHeight, ProceduralHeight
from ..kernels.normalmap.high_to_low import HighToLowMap, HighToLowSettings, high_to_low_steps
from ..kernels.normalmap.surface_metric import metric_normals, slope_matrices, texel_triangles
from ..kernels.normalmap.texture_height import TextureHeight
from ..kernels.progress import Steps, scaled
from .record import JobSummary, OperatorSpec, Option, Technique

IMAGE_PREFIX = "Normal"
# The relief a procedural pattern or an image stands for when the strength is automatic: a height
# of 1 lies this many metres above a height of 0 (the sample scenes' Bump nodes use 1 cm).
DEFAULT_RELIEF_M = 0.01
# Squares of the checker source along each UV unit (Cycles' Checker Texture at this Scale).
CHECKER_SQUARES = 8.0
# UV triangles with less area than this (UV units^2) carry no metric: left out of the metres per
# UV unit of an object.
MIN_UV_AREA = 1e-12


@dataclass(frozen=True)
class NormalMapTarget:
    """Where a normal map's height comes from and where the map goes.

    | field   | default    | meaning                                                         |
    |---------|------------|-----------------------------------------------------------------|
    | source  | "material" | material (each material's Bump-node height), orange_peel,      |
    |         |            | bricks, checker, or image (the image named `image`)             |
    | image   | ""         | the Blender image read as heights when source is image          |
    | uv_name | ""         | the UV layer the map covers ("": the Bump texture's, else the   |
    |         |            | active render layer)                                            |
    | wire    | False      | wire the map into the object's materials (Normal Map node)      |
    | high    | ""         | source high: the mesh whose normals are baked ("": with two     |
    |         |            | meshes selected, the one that is not active)                    |
    """

    source: str = "material"
    image: str = ""
    uv_name: str = ""
    wire: bool = False
    high: str = ""


SOURCE_CHOICES = (
    ("material", "Material Bump", "Each material's own Bump-node height (image or checker), so "
     "a procedural bump becomes a texture"),
    ("orange_peel", "Orange Peel", "The lecture's dimpled orange (Worley dimples)"),
    ("bricks", "Bricks", "The lecture's bricks: running bond with bevelled mortar"),
    ("checker", "Checker", "Steps of an 8 x 8 checker (a test pattern)"),
    ("image", "Image", "The Blender image named in Height Image"),
    ("high", "High Poly Mesh", "The normals of a detailed mesh (High Mesh, or the selected mesh "
     "that is not active) baked into each target's map, as Cycles' Selected to Active"),
)

OPTIONS = (
    Option("source", NormalMapTarget, "Height Source", "Where the relief comes from",
           choices=SOURCE_CHOICES),
    Option("image", NormalMapTarget, "Height Image", "Name of the Blender image read as heights "
           "(its luminance) when the source is Image", flag="--height-image"),
    Option("size", NormalMapSettings, "Size", "Texels along each side of the map (0: the height "
           "image's own size)", minimum=0, maximum=16384, soft_max=4096),
    Option("strength", NormalMapSettings, "Strength", "Tilt per unit of height slope, in height "
           "units per UV unit (0: from the Bump node's Distance over the object's metres per UV "
           "unit, or a 1 cm relief for the other sources)", auto=0.0, minimum=0.0,
           soft_max=10.0),
    Option("green", NormalMapSettings, "Green", "Which way the green channel points",
           choices=(("OPENGL", "OpenGL (Y+)", "Blender, glTF, Unity: green grows along +v"),
                    ("DIRECTX", "DirectX (Y-)", "Unreal, DirectX tools: green grows along -v"))),
    Option("padding", NormalMapSettings, "Padding", "Texels grown outward from the UV charts",
           minimum=0, maximum=64),
    Option("uv_name", NormalMapTarget, "UV Layer", "UV layer the map covers (empty: the Bump "
           "texture's, else the active render layer)"),
    Option("wire", NormalMapTarget, "Wire into Material", "Wire the map into the materials "
           "(Image Texture -> Normal Map -> BSDF Normal) in place of the Bump node it was made "
           "from; the Bump node stays in the tree, unlinked"),
    Option("high", NormalMapTarget, "High Mesh", "Source High Poly Mesh: the detailed mesh whose "
           "normals are baked (empty: with two meshes selected, the one that is not active; the "
           "active one gets the map)"),
    Option("cage", HighToLowSettings, "Cage", "Source High Poly Mesh: how far outside the low "
           "mesh, along its normals, the rays start, in metres (0: from the meshes' sizes)",
           auto=0.0, minimum=0.0, soft_max=1.0),
    Option("max_ray", HighToLowSettings, "Max Ray", "Source High Poly Mesh: the longest ray from "
           "the cage inward, in metres (0: twice the cage)", auto=0.0, minimum=0.0,
           soft_max=2.0),
)


@dataclass
class _Group:
    """One height over some of an object's triangles (a material's Bump, or the whole object):
    a relief of `distance` metres per unit of height on the surface, each texel through its own
    triangle's stretch (`surface_metric`), or (distance None) the given strength in UV units."""

    source: object  # a height source: heights(uv) -> (N,), resolution
    strength: float  # UV units per unit of height (with a distance: at the mean stretch)
    triangles: np.ndarray  # (T,) bool over the object's triangles
    distance: float | None = None  # metres per unit of height
    metres: float = 1.0  # the group's mean metres per UV unit


@dataclass
class _Plan:
    """One object's map, read from Blender before anything is computed."""

    name: str
    uv_name: str
    uv: np.ndarray  # (T, 3, 2) float64
    world: np.ndarray  # (T, 3, 3) float64, metres
    groups: list
    from_material: bool


def settings(values: dict, scene=None) -> NormalMapSettings:
    return NormalMapSettings(size=int(values["size"]), strength=float(values["strength"]),
                             green=str(values["green"]), padding=int(values["padding"]))


def target(values: dict) -> NormalMapTarget:
    return NormalMapTarget(source=str(values["source"]), image=str(values["image"]).strip(),
                           uv_name=str(values["uv_name"]).strip(), wire=bool(values["wire"]),
                           high=str(values.get("high", "")).strip())


def high_settings(values: dict) -> HighToLowSettings:
    return HighToLowSettings(cage=float(values.get("cage", 0.0)),
                             max_ray=float(values.get("max_ray", 0.0)))


def metres_per_uv(uv: np.ndarray, world: np.ndarray) -> float | None:
    """sqrt(world area / UV area) of triangles (T, 3, 2) and (T, 3, 3): the mean metres one UV
    unit spans on the surface (None: no UV area)."""
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    uv_area = 0.5 * np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    used = uv_area > MIN_UV_AREA
    if not used.any():
        return None
    return float(np.sqrt(triangle_areas(world[used]).sum() / uv_area[used].sum()))


def _pattern_source(tgt: NormalMapTarget):
    if tgt.source == "image":
        image = bpy.data.images.get(tgt.image)
        if image is None:
            raise ValueError(f"no image named '{tgt.image}' to read heights from")
        pixels = image_pixels(image)
        if pixels is None:
            raise ValueError(f"image '{tgt.image}' has no pixels")
        return ImageHeight(pixels, "REPEAT")
    if tgt.source == "checker":
        return ProceduralHeight("checker", scale=CHECKER_SQUARES)
    return ProceduralHeight(tgt.source)


def _slot_material(obj, slot: int, materials: dict):
    """The kernel `Material` of `obj`'s material slot (None: an empty slot)."""
    mat = obj.material_slots[slot].material if slot < len(obj.material_slots) else None
    return None if mat is None else materials.get(mat.name)


def _height_uv_layer(obj, slots, materials: dict) -> str | None:
    """The UV layer the first Bump-node height of `obj`'s materials names (None: the active
    render layer)."""
    for slot in np.unique(slots):
        material = _slot_material(obj, int(slot), materials)
        if material is not None and material.height_texture is not None:
            return material.height_texture.uv_layer
    return None


def _material_groups(obj, slots, uv, world, materials: dict, strength: float) -> list[_Group]:
    """One group per material of `obj` with a Bump-node height: its triangles, its height and its
    relief (automatic: the Bump's Distance x Strength in metres, each texel through its triangle's
    stretch; else the given strength in UV units)."""
    groups = []
    for slot in np.unique(slots):
        material = _slot_material(obj, int(slot), materials)
        if material is None or material.height_texture is None:
            continue
        # A Mapping node's UV transform is read through (`TextureHeight`): the map lies on the
        # mesh's UVs and holds the moved height, slopes by the chain rule.
        texture = material.height_texture
        rows = slots == slot
        metres = metres_per_uv(uv[rows], world[rows])
        if metres is None:
            continue
        distance = material.bump_distance * material.bump_strength
        source = TextureHeight(texture, -1.0 if distance < 0 else 1.0)
        if strength > 0.0:
            groups.append(_Group(source, strength, rows, metres=metres))
        else:
            groups.append(_Group(source, abs(distance) / metres, rows, abs(distance), metres))
    return groups


def plan_objects(context, values: dict, tgt: NormalMapTarget, base: NormalMapSettings
                 ) -> tuple[list[_Plan], list[str]]:
    """Each target object's plan (read from Blender, nothing written) and the skipped ones."""
    names = values.get("objects") or [o.name for o in context.selected_objects if o.type == "MESH"]
    objects = [o for o in context.scene.objects if o.type == "MESH" and not o.hide_render
               and (not names or o.name in names)]
    if not objects:
        raise ValueError("the scene has no mesh objects to make normal maps for")
    chosen = bool(names)
    depsgraph = context.evaluated_depsgraph_get()
    materials = {}
    if tgt.source == "material":
        scene = snapshot(context, SnapshotRequest(objects=tuple(o.name for o in objects),
                                                  lights=False, camera=False, world_render=False))
        # A material wired before is read as it was: the Bump node its map replaced.
        materials = {m.name: normal_maps.material_before_wiring(bpy.data.materials.get(m.name), m)
                     for m in scene.read_materials}
    pattern = None if tgt.source == "material" else _pattern_source(tgt)
    plans, skipped = [], []
    for obj in objects:
        read = normal_maps.object_uv_triangles(obj, depsgraph, tgt.uv_name or None)
        if tgt.source == "material" and read is not None and not tgt.uv_name:
            layer = _height_uv_layer(obj, read[2], materials)  # the Bump texture's own layer
            if layer is not None and layer != read[3]:
                read = normal_maps.object_uv_triangles(obj, depsgraph, layer)
        if read is None:
            if chosen:
                skipped.append(f"{obj.name}: no UV layer '{tgt.uv_name or '(active render)'}'")
            continue
        uv, world, slots, layer = read
        if tgt.source == "material":
            groups = _material_groups(obj, slots, uv, world, materials, base.strength)
            if not groups:
                if chosen:
                    skipped.append(f"{obj.name}: no material with a Bump-node height")
                continue
        else:
            metres = metres_per_uv(uv, world)
            if metres is None:
                skipped.append(f"{obj.name}: its UV layer '{layer}' has no area")
                continue
            rows = np.ones(len(uv), bool)
            if base.strength > 0.0:
                groups = [_Group(pattern, base.strength, rows, metres=metres)]
            else:
                groups = [_Group(pattern, DEFAULT_RELIEF_M / metres, rows, DEFAULT_RELIEF_M,
                                 metres)]
        plans.append(_Plan(obj.name, layer, uv, world, groups, tgt.source == "material"))
    return plans, skipped


def map_size(plan: _Plan, base: NormalMapSettings) -> int:
    """The plan's map size: the settings', or (0) the largest side of its first height image."""
    if base.size > 0:
        return base.size
    sizes = [g.source.resolution for g in plan.groups if g.source.resolution is not None]
    if not sizes:
        raise ValueError(f"{plan.name}: size 0 (the image's own) needs an image height")
    return max(sizes[0])


def object_map_steps(plan: _Plan, base: NormalMapSettings) -> Steps[tuple[NormalMap, int]]:
    """One object's map: each group's height made into normals over the group's charts, then
    the charts padded together and encoded (`kernels/normalmap`); with the count of its UV
    triangles that have no parametrisation (zero UV or surface area: they take the mean
    stretch)."""
    size = map_size(plan, base)
    normals = np.broadcast_to(FLAT, (size, size, 3)).copy()
    covered = np.zeros((size, size), bool)
    degenerate = steep = degenerate_triangles = 0
    for k, group in enumerate(plan.groups):
        uv, world = plan.uv[group.triangles], plan.world[group.triangles]
        ids = texel_triangles(uv, size, size)  # the group's charts: ids >= 0
        mask = (ids >= 0) & ~covered
        strength = 1.0 if group.distance is not None else group.strength
        made = yield from scaled(
            normal_map_steps(group.source, replace(base, size=size, strength=strength)),
            k / len(plan.groups), 0.95 / len(plan.groups))
        if group.distance is None:
            normals[mask] = made.normals[mask]
        else:  # metres of relief: each texel through its triangle's stretch
            matrices, bad = slope_matrices(uv, world, group.metres)
            degenerate_triangles += int(bad.sum())
            normals[mask] = metric_normals(made.normals[mask], matrices[ids[mask]],
                                           group.distance)
        degenerate += made.degenerate_texels
        steep += int((made.normals[mask][:, 2] < STEEP_COS).sum())
        covered |= mask
    padded, filled = pad_normals(normals, covered, base.padding)
    yield 1.0
    made = NormalMap(normals=padded, rgb=normals_to_rgb(padded, base.green), mask=filled,
                     degenerate_texels=degenerate, steep_texels=steep,
                     settings=replace(base, size=size))
    return made, degenerate_triangles


def normalmap_job(context, values: dict) -> Steps[JobSummary]:
    """Make every target object's normal map, then (after the last yield) write the images and,
    with wire, the materials. Closed before its end, it has changed nothing."""
    tgt, base = target(values), settings(values)
    # the surfaces Cycles would bake (render levels: `render_state`)
    with render_state(context.scene, context.view_layer):
        plans, skipped = plan_objects(context, values, tgt, base)
    if not plans:
        raise ValueError("no mesh with a relief to make a normal map of"
                         + (f" ({'; '.join(skipped)})" if skipped else ""))
    maps = []
    for k, plan in enumerate(plans):
        maps.append((yield from scaled(object_map_steps(plan, base), k / len(plans),
                                       1.0 / len(plans))))
    # --- write back: everything computed ---------------------------------------------------------
    summary = JobSummary(message="", skipped=skipped)
    per_object, wired = {}, []
    for plan, (made, degenerate_triangles) in zip(plans, maps, strict=True):
        name = f"{IMAGE_PREFIX} {plan.name}"
        image = normal_maps.write_normal_image(name, made.rgb, image=bpy.data.images.get(name))
        summary.images[plan.name] = image
        materials = []
        if tgt.wire:
            mats, why = normal_maps.wire_normal_map(bpy.data.objects[plan.name], image,
                                                    plan.uv_name, keep_bump=not plan.from_material)
            materials = [m.name for m in mats]
            wired += materials
            summary.skipped += why
        summary.files[f"normalmap/{plan.name}.png"] = to_uint8(made.rgb)
        summary.files[f"normalmap/{plan.name}.exr"] = to_float(made.rgb)
        per_object[plan.name] = {
            "image": image.name, "uv_layer": plan.uv_name, "size": made.settings.size,
            "strength": [g.strength for g in plan.groups],
            "relief_m": [g.distance for g in plan.groups],
            "metres_per_uv": [g.metres for g in plan.groups],
            "chart_texels": int(made.mask.sum()), "degenerate_texels": made.degenerate_texels,
            "steep_texels": made.steep_texels, "degenerate_uv_triangles": degenerate_triangles,
            "wired_materials": materials}
    summary.result = {p.name: made for p, (made, _) in zip(plans, maps, strict=True)}
    summary.settings = {**asdict(base), **asdict(tgt)}
    summary.sizes = {"objects": len(plans),
                     "texels": int(sum(m.settings.size ** 2 for m, _ in maps))}
    summary.extra["normal_maps"] = per_object
    summary.message = (f"normal maps of {len(plans)} objects ({tgt.source}): "
                       + ", ".join(f"'{i.name}'" for i in summary.images.values())
                       + (f"; wired into {', '.join(wired)}" if wired else ""))
    return summary


def high_and_low_objects(context, values: dict, tgt: NormalMapTarget):
    """(the high mesh object, the low mesh objects the maps are made for) of a high -> low bake:
    the high mesh named in `tgt.high`, the targets those named in `objects`, else the selected
    meshes, else every other renderable mesh; with no name, Blender's Selected to Active (two
    meshes selected: the active one gets the map, the other is the high mesh)."""
    meshes = {o.name: o for o in context.scene.objects if o.type == "MESH" and not o.hide_render}
    selected = [o for o in context.selected_objects if o.type == "MESH"]
    names = values.get("objects") or []
    if tgt.high:
        high = meshes.get(tgt.high)
        if high is None:
            raise ValueError(f"no renderable mesh named '{tgt.high}' to bake normals from")
        chosen = ([meshes[n] for n in names if n in meshes] if names
                  else [o for o in selected if o.name in meshes] or list(meshes.values()))
        lows = [o for o in chosen if o is not high]
    else:
        active = context.view_layer.objects.active
        others = [o for o in selected if o is not active]
        if active is None or active.type != "MESH" or len(others) != 1:
            raise ValueError("name the high mesh (High Mesh), or select it and then the low mesh "
                             "(active): Selected to Active takes exactly two meshes")
        high, lows = others[0], [active]
    if not lows:
        raise ValueError(f"no low mesh besides '{high.name}' to make a map for")
    return high, lows


def high_to_low_job(context, values: dict) -> Steps[JobSummary]:
    """Bake the high mesh's normals into each low mesh's tangent-space map
    (`kernels/normalmap/high_to_low.py`), then (after the last yield) write the images and, with
    wire, the materials."""
    tgt, base, cage = target(values), settings(values), high_settings(values)
    if base.size <= 0:
        raise ValueError("a high -> low bake needs a map size (Size > 0)")
    high_obj, lows = high_and_low_objects(context, values, tgt)
    plans, skipped = [], []
    # the meshes Cycles would bake: render levels (multires sculpts; `render_state`)
    with render_state(context.scene, context.view_layer):
        depsgraph = context.evaluated_depsgraph_get()
        high = normal_maps.high_mesh(high_obj, depsgraph)
        for obj in lows:
            read = normal_maps.low_mesh(obj, depsgraph, tgt.uv_name or None)
            if read is None:
                skipped.append(f"{obj.name}: no UV layer '{tgt.uv_name or '(active render)'}'")
                continue
            plans.append((obj.name, *read))
    if not plans:
        raise ValueError("no low mesh with a UV layer to bake into"
                         + (f" ({'; '.join(skipped)})" if skipped else ""))
    maps: list[HighToLowMap] = []
    for k, (_, low, _) in enumerate(plans):
        maps.append((yield from scaled(high_to_low_steps(low, high, base, cage),
                                       k / len(plans), 1.0 / len(plans))))
    # --- write back: everything computed ---------------------------------------------------------
    summary = JobSummary(message="", skipped=skipped)
    per_object, wired = {}, []
    for (name, _, layer), made in zip(plans, maps, strict=True):
        image_name = f"{IMAGE_PREFIX} {name}"
        image = normal_maps.write_normal_image(image_name, made.rgb,
                                               image=bpy.data.images.get(image_name))
        summary.images[name] = image
        materials = []
        if tgt.wire:
            mats, why = normal_maps.wire_normal_map(bpy.data.objects[name], image, layer,
                                                    keep_bump=True)
            materials = [m.name for m in mats]
            wired += materials
            summary.skipped += why
        summary.files[f"normalmap/{name}.png"] = to_uint8(made.rgb)
        summary.files[f"normalmap/{name}.exr"] = to_float(made.rgb)
        per_object[name] = {
            "image": image.name, "uv_layer": layer, "size": base.size, "high": high_obj.name,
            "cage_m": made.cage, "max_ray_m": made.max_ray, "chart_texels": made.chart_texels,
            "missed_texels": made.misses, "back_face_texels": made.back_faces,
            "wired_materials": materials}
    summary.result = {name: made for (name, _, _), made in zip(plans, maps, strict=True)}
    summary.settings = {**asdict(base), **asdict(tgt), **asdict(cage)}
    summary.sizes = {"objects": len(plans), "texels": len(plans) * base.size ** 2,
                     "high_triangles": len(high.triangles)}
    summary.extra["normal_maps"] = per_object
    misses = sum(m.misses for m in maps)
    summary.message = (f"normal maps of {len(plans)} objects from '{high_obj.name}': "
                       + ", ".join(f"'{i.name}'" for i in summary.images.values())
                       + (f"; {misses} texels missed it (flat)" if misses else "")
                       + (f"; wired into {', '.join(wired)}" if wired else ""))
    return summary


def cli_extra(parser) -> None:
    parser.add_argument("--objects", nargs="+", default=[], metavar="NAME",
                        help="objects to make maps of (default: the selected meshes, or every "
                             "mesh with a relief when none is selected)")


def start(context, values: dict, resolution=None) -> Steps[JobSummary]:
    if values["source"] == "high":
        return (yield from high_to_low_job(context, values))
    return (yield from normalmap_job(context, values))


RECORD = Technique(
    name="normalmap", label="Normal Maps",
    help="make tangent-space normal maps from heights or a high-poly mesh and wire them into "
         "the materials",
    options=OPTIONS, settings=settings, start=start, cli_extra=cli_extra, renders=False,
    # No matched Cycles model: the map is checked against Cycles rendering the Bump node it
    # replaces (tests/blender/test_normalmap.py), not against a camera view of its own.
    cycles_model=None,
    operator=OperatorSpec("classic_bake.normalmap", "Make Normal Maps", "NORMALS_FACE",
                          needs=("mesh",)),
)
