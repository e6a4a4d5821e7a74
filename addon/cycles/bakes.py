"""Cycles bakes under a model: float lightmaps (`bake_lightmaps`) and float colour attributes
(`bake_color_attributes`), with the wall time of the bake operator alone.

Bake semantics (measured, Blender 5.2.3 and 4.5.15; tests re-measure them)
---------------------------------------------------------------------------
A plane of albedo rho, Principled with Specular IOR Level 0 (exactly Lambertian), under a sun,
black world; E = sun strength x cos(incidence) is the irradiance on the plane:

| bake_type | pass filter                       | texel value             |
|-----------|-----------------------------------|-------------------------|
| DIFFUSE   | DIRECT, INDIRECT, COLOR (default) | rho E / pi   (radiance)  |
| DIFFUSE   | DIRECT, INDIRECT                  | E / pi       (radiance / albedo, i.e. irradiance / pi) |
| COMBINED  | all                               | rho E / pi   (+ emission, glossy, transmission) |
| SHADOW    | none, with max_bounces 0          | 1 lit, 0 shadowed       |
| ALBEDO    | COLOR (Blender bake type DIFFUSE) | rho = base x (1 - metallic) x (1 - transmission), no light |
| EMIT      | none                              | the emission closure's radiance (colour x strength) |

ALBEDO, measured on a plane of base colour (0.2, 0.5, 0.8) with Specular IOR Level 0 under a sun
or a point light and a world of (0.3, 0.6, 0.9): metallic 0.5 bakes (0.1, 0.25, 0.4), metallic
0.5 with transmission 0.5 (0.05, 0.125, 0.2), to 6e-9, in lightmaps and colour attributes alike;
the Diffuse Color pass of a render gives the same values on the plane's pixels and exactly 0 on
the background's. (Default Specular IOR Level 0.5: (0.0963, 0.2407, 0.3850), see
`models.albedo`.) Checker and Image Textures through the UVs bake their colour per texel; a bake's samples
spread over the texel, so a texel on a texture edge may mix both sides (5.2.3: one sample of 16
on a checker edge; 4.5.15: none), while texels inside a texture's texel match it to 1.2e-7.

Baked texels get alpha 1, untouched ones keep the alpha 0 the image starts with: that alpha is
the coverage mask returned with each lightmap (with margin 0 the texels Cycles' rasteriser gives
to a UV triangle, for an axis-aligned UV square exactly those whose centres lie inside it; a
margin > 0 adds the dilated texels). A colour-attribute bake of a vertex gives the same values
at the vertex's position (a point light over a 3 x 3 grid agrees with rho I cos / (pi d^2)).
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterable, Iterator, Sequence
from typing import Literal

import bpy
import numpy as np

from ..bridge.images import image_pixels
from ..bridge.write_back import read_color_attribute
from .models import CyclesModel
from .settings import TEMP_PREFIX, SettingsLog, matched_scene

BakeType = Literal["DIFFUSE", "COMBINED", "SHADOW", "ALBEDO", "EMIT"]


# Pass filters of `bpy.ops.object.bake` per bake type (the operator's enum-flag names).
PASS_FILTERS: dict[str, frozenset[str]] = {
    "DIFFUSE": frozenset({"DIRECT", "INDIRECT", "COLOR"}),
    "COMBINED": frozenset({"EMIT", "DIRECT", "INDIRECT", "DIFFUSE", "GLOSSY", "TRANSMISSION"}),
    "SHADOW": frozenset(),
    "ALBEDO": frozenset({"COLOR"}),  # the diffuse colour alone: no light at all
    "EMIT": frozenset(),  # the emitted radiance alone (colour x strength)
}
# Blender's bake type for each of ours that Blender names differently (the rest are the same):
# ALBEDO is Cycles' DIFFUSE bake with the colour pass alone.
BLENDER_BAKE_TYPES: dict[str, str] = {"ALBEDO": "DIFFUSE"}


# A baked texel has alpha 1 and an untouched one alpha 0: anything above one half is baked.
COVERED_ALPHA = 0.5


def _mesh_objects(scene, objects: Iterable) -> list:
    """Objects (names or bpy objects) as a list of mesh objects of `scene`, in the order given."""
    found = []
    for item in objects:
        obj = scene.objects.get(item) if isinstance(item, str) else item
        if obj is None:
            raise ValueError(f"no object '{item}' in scene '{scene.name}'")
        if obj.type != "MESH":
            raise ValueError(f"object '{obj.name}' is a {obj.type}: only meshes can be baked")
        found.append(obj)
    if not found:
        raise ValueError("nothing to bake: no objects given")
    return found


@contextlib.contextmanager
def _selection(scene, objects: Sequence) -> Iterator[None]:
    """Exactly `objects` selected and the first one active; the selection restored afterwards."""
    view_layer = bpy.context.view_layer
    before = [obj for obj in scene.objects if obj.select_get()]
    active = view_layer.objects.active
    try:
        for obj in before:
            obj.select_set(False)
        for obj in objects:
            if not obj.visible_get():
                raise ValueError(f"object '{obj.name}' is hidden: Cycles cannot bake it")
            obj.select_set(True)
        view_layer.objects.active = objects[0]
        yield
    finally:
        for obj in scene.objects:
            obj.select_set(False)
        for obj in before:
            obj.select_set(True)
        view_layer.objects.active = active


def _new_float_image(name: str, width: int, height: int):
    """A float image, linear, cleared to (0, 0, 0, 0) so that alpha marks what the bake writes."""
    image = bpy.data.images.new(name, width, height, alpha=True, float_buffer=True)
    image.pixels.foreach_set(np.zeros(width * height * 4, np.float32))
    return image


def _default_surface():
    """A temporary material equal to Cycles' surface for faces without one: diffuse 0.8 grey."""
    mat = bpy.data.materials.new(f"{TEMP_PREFIX}_default")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(diffuse.outputs["BSDF"], output.inputs["Surface"])
    return mat


def _use_temporary_material(stack: contextlib.ExitStack, obj, index: int, mat) -> None:
    """Show `mat` in slot `index` of `obj` through an object link (the mesh is not touched)."""
    slot = obj.material_slots[index]
    stack.callback(setattr, obj.material_slots[index], "link", slot.link)
    slot.link = "OBJECT"
    stack.callback(setattr, obj.material_slots[index], "material", slot.material)
    slot.material = mat


def _bake_materials(stack: contextlib.ExitStack, objects: Sequence, images: dict) -> None:
    """Give every material of every object an active Image Texture node on that object's image.

    A material used by several baked objects (or a slot without one) is replaced, for the bake,
    by a temporary per-object material through an object-linked slot, so every object bakes into
    its own image and meshes shared with other objects are not touched. `stack` undoes it all.
    """
    claimed: set[int] = set()
    for obj in objects:
        if len(obj.material_slots) == 0:  # Cycles' default surface, as a removable material
            temp = _default_surface()
            stack.callback(bpy.data.materials.remove, temp)
            obj.data.materials.append(temp)
            # The mesh had no material: clear() empties it again (pop() would leave the object
            # an empty slot behind, as measured in Blender 5.2).
            stack.callback(obj.data.materials.clear)
        for index, slot in enumerate(obj.material_slots):
            mat = slot.material
            if mat is None or mat.as_pointer() in claimed:
                mat = _default_surface() if mat is None else mat.copy()
                stack.callback(bpy.data.materials.remove, mat)
                _use_temporary_material(stack, obj, index, mat)
            claimed.add(mat.as_pointer())
            if bpy.app.version < (5, 0, 0) and not mat.use_nodes:
                stack.callback(setattr, mat, "use_nodes", False)
                mat.use_nodes = True
            tree = mat.node_tree
            previous = tree.nodes.active
            node = tree.nodes.new("ShaderNodeTexImage")
            node.name = node.label = TEMP_PREFIX
            node.image = images[obj.name]
            node.location = (-1200.0, 600.0)
            stack.callback(tree.nodes.remove, node)
            stack.callback(setattr, tree.nodes, "active", previous)
            tree.nodes.active = node


def _blender_bake_type(bake_type: str) -> str:
    """The `bpy.ops.object.bake` type that bakes our `bake_type` (see `BLENDER_BAKE_TYPES`)."""
    return BLENDER_BAKE_TYPES.get(bake_type, bake_type)


def _bake_settings(log: SettingsLog, scene, samples: int, seed: int, bake_type: str) -> None:
    log.set(scene.cycles, "samples", int(samples))
    log.set(scene.cycles, "seed", int(seed))
    log.set(scene.cycles, "bake_type", _blender_bake_type(bake_type))
    if bake_type == "SHADOW":
        # tests/data/cycles_facts.md: with bounces a SHADOW bake is no 0-1 map (values up to 1.7-4.0).
        log.set(scene.cycles, "max_bounces", 0)


def _pass_filter(bake_type: str, use_color: bool) -> set[str]:
    if bake_type not in PASS_FILTERS:
        raise ValueError(f"bake_type must be one of {sorted(PASS_FILTERS)}, got {bake_type!r}")
    flags = set(PASS_FILTERS[bake_type])
    if bake_type == "DIFFUSE" and not use_color:
        flags.discard("COLOR")
    return flags


def _image_size(size) -> tuple[int, int]:
    width, height = (size, size) if isinstance(size, int) else (int(size[0]), int(size[1]))
    if width < 1 or height < 1:
        raise ValueError(f"lightmap size must be positive, got {size}")
    return width, height


def bake_lightmaps(scene, model: CyclesModel, samples: int, objects: Iterable, uv_layer: str,
                   size: int | tuple[int, int], bake_type: BakeType = "DIFFUSE", *,
                   use_color: bool = True, margin: int = 0, seed: int | None = None,
                   ) -> tuple[dict[str, np.ndarray], float, dict[str, np.ndarray]]:
    """Bake `objects` with Cycles into one float lightmap each, through UV layer `uv_layer`.

    Returns ({object name: (H, W, 3) float32 linear, row 0 top}, seconds of the bake operator,
    {object name: (H, W) bool, True on texels the bake wrote}). `size` is W = H or (W, H);
    `margin` texels are dilated around the charts (0: none; the mask then is the UV coverage).
    bake_type DIFFUSE bakes direct + indirect diffuse light, times the albedo with `use_color`
    (radiance rho E / pi), without it E / pi; COMBINED everything; SHADOW a 0-1 visibility map
    (max_bounces forced to 0); ALBEDO the diffuse colour alone, no light (`use_color` ignored).
    See the module docstring for the measured semantics. Temporary images, Image Texture nodes
    and materials are removed afterwards; the scene is left as it was.
    """
    scene = scene or bpy.context.scene
    objs = _mesh_objects(scene, objects)
    width, height = _image_size(size)
    flags = _pass_filter(bake_type, use_color)
    for obj in objs:
        if obj.data.uv_layers.get(uv_layer) is None:
            raise ValueError(f"object '{obj.name}' has no UV layer '{uv_layer}'")
    with contextlib.ExitStack() as stack:
        log = stack.enter_context(matched_scene(model, scene))
        _bake_settings(log, scene, samples, model.seed if seed is None else seed, bake_type)
        images = {}
        for obj in objs:
            image = _new_float_image(f"{TEMP_PREFIX}_{obj.name}", width, height)
            stack.callback(bpy.data.images.remove, image)
            images[obj.name] = image
        _bake_materials(stack, objs, images)
        stack.enter_context(_selection(scene, objs))
        start = time.perf_counter()
        bpy.ops.object.bake(type=_blender_bake_type(bake_type), pass_filter=flags, target="IMAGE_TEXTURES",
                            uv_layer=uv_layer, margin=margin, margin_type="EXTEND",
                            use_clear=False, use_selected_to_active=False, save_mode="INTERNAL",
                            use_split_materials=False, use_automatic_name=False)
        seconds = time.perf_counter() - start
        result, masks = {}, {}
        for name, image in images.items():
            pixels = image_pixels(image)  # (H, W, 4) float32, row 0 top
            result[name] = pixels[:, :, :3].copy()
            masks[name] = pixels[:, :, 3] > COVERED_ALPHA
    return result, seconds, masks


def bake_color_attributes(scene, model: CyclesModel, samples: int, objects: Iterable,
                          attribute: str, bake_type: BakeType = "DIFFUSE", *,
                          use_color: bool = True, seed: int | None = None, keep: bool = False,
                          ) -> tuple[dict[str, np.ndarray], float]:
    """Bake `objects` with Cycles into float per-vertex colour attributes named `attribute`.

    Returns ({object name: (V, 3) float32 linear, one row per mesh vertex}, seconds of the bake
    operator). Cycles evaluates each corner and averages the corners of a vertex. Bake types as
    in `bake_lightmaps`. The attribute is temporary unless `keep` (an existing attribute of that
    name is replaced only when `keep`); the active colour attribute is restored either way.
    Meshes shared by several baked objects are refused (they would bake into one attribute).
    """
    scene = scene or bpy.context.scene
    objs = _mesh_objects(scene, objects)
    flags = _pass_filter(bake_type, use_color)
    meshes = [obj.data.as_pointer() for obj in objs]
    if len(set(meshes)) != len(meshes):
        raise ValueError("bake_color_attributes: two of the objects share one mesh")
    with contextlib.ExitStack() as stack:
        log = stack.enter_context(matched_scene(model, scene))
        _bake_settings(log, scene, samples, model.seed if seed is None else seed, bake_type)
        for obj in objs:
            attrs = obj.data.color_attributes
            previous = attrs.active_color_name if attrs.active_color is not None else None
            name = attribute if keep else f"{TEMP_PREFIX}_{attribute}"
            if attrs.get(name) is not None:
                attrs.remove(attrs[name])
            attr = attrs.new(name=name, type="FLOAT_COLOR", domain="POINT")
            if not keep:
                stack.callback(_remove_attribute, obj.data, name)
            stack.callback(_set_active_color, obj.data, previous)
            attrs.active_color = attr
        stack.enter_context(_selection(scene, objs))
        start = time.perf_counter()
        bpy.ops.object.bake(type=_blender_bake_type(bake_type), pass_filter=flags, target="VERTEX_COLORS",
                            use_clear=False, use_selected_to_active=False)
        seconds = time.perf_counter() - start
        result = {}
        for obj in objs:
            name = obj.data.color_attributes.active_color_name
            result[obj.name] = read_color_attribute(obj.data, name)[:, :3].copy()
    return result, seconds


def _remove_attribute(mesh, name: str) -> None:
    attr = mesh.color_attributes.get(name)
    if attr is not None:
        mesh.color_attributes.remove(attr)


def _set_active_color(mesh, name: str | None) -> None:
    attrs = mesh.color_attributes
    if name is not None and attrs.get(name) is not None:
        attrs.active_color = attrs[name]
