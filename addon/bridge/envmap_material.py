"""A material that Blender renders from a baked environment map: the lat-long map looked up
along the reflection vector, as an Emission, so Cycles and EEVEE show the environment-mapped
object (the environment-mapping job's Show in Materials).

Each of the object's material slots gets a new material, "<material> (env map)", whose surface is

    Emission(strength 1, colour = tint x EnvironmentTexture(image, vector = d))

* d is Texture Coordinate's Reflection output: in Cycles the view direction mirrored about the
  shading normal in world space (svm `NODE_TEXCO_REFLECTION`: 2 (N . I) N - I, no object
  transform; the test renders it against the kernels' view), which is what the Environment
  Texture's equirectangular mapping reads (`kernels/envmap/cube_files.py`).
* With a room box (`box`), d is box-projected (parallax-corrected, "local cubemaps"): the ray
  from the shaded point P along r meets the box at P + t r, t = min over axes of
  max((box_max - P) / r, (box_min - P) / r), and d = P + t r - c from the probe's centre c.
  Right for the room's walls; things inside the room slide as in the plain look-up.
* tint: the mirror's Schlick weight, as the kernels' tracer weights a metal's reflection:
  metallic (F0 + (1 - F0) (1 - |N . I|)^5), F0 the metal's colour (Layer Weight's Facing at
  blend 1/2 is 1 - |N . I|). A constant per material (a base colour texture is not followed);
  a material that is not metal at all (an object named with --objects) is shown untinted.

The original material stays in the file with a fake user (so saving never drops it) and its name
on the new one (`ORIGINAL_PROP`); `unwire_environment_material` puts it back, and a later run
replaces its own material rather than wrapping it. Blender data is written only here, after a
job's last yield; the operator's UNDO flag makes the run one undo step.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import bpy
import numpy as np

ENV_SUFFIX = " (env map)"
ORIGINAL_PROP = "classic_bake_env_original"  # on the env-map material: the material it replaced
WIRING_TAG = "classic_bake"  # on every node made here
# Schlick's exponent of the grazing term (the tracer's metal weight).
SCHLICK_POWER = 5.0
# Node columns, left to right (x in the node editor).
COLUMNS = {"input": -1400, "box1": -1200, "box2": -1000, "box3": -800, "box4": -600,
           "texture": -400, "tint": -200, "emission": 0, "output": 200}


def mirror_tints(scene, object_index: int) -> dict[str, tuple[np.ndarray, float]]:
    """{material name: (F0 (3,) linear, metallic)} of the materials on one snapshot object, as
    the tracer weights their mirror reflection (metal colour, else base colour)."""
    used = np.unique(scene.material_ids[scene.object_slice(object_index)])
    tints = {}
    for m in used:
        mat = scene.materials[int(m)]
        colour = mat.base_color if getattr(mat, "metal_color", None) is None else mat.metal_color
        tints[mat.name] = (np.asarray(colour, np.float64)[:3], float(mat.metallic))
    return tints


def _node(tree, kind: str, column: str, row: int, **settings):
    node = tree.nodes.new(kind)
    node[WIRING_TAG] = True
    node.location = (COLUMNS[column], -180 * row)
    for key, value in settings.items():
        setattr(node, key, value)
    return node


def _vector_math(tree, operation: str, column: str, row: int):
    return _node(tree, "ShaderNodeVectorMath", column, row, operation=operation)


def _box_projected(tree, reflection, centre, box, row: int):
    """The socket of d = P + t r - c (module docstring), P from Geometry.Position (world)."""
    links = tree.links
    position = _node(tree, "ShaderNodeNewGeometry", "input", row + 1).outputs["Position"]
    t_far = []
    for k, corner in enumerate(box):
        to_wall = _vector_math(tree, "SUBTRACT", "box1", row + k)
        to_wall.inputs[0].default_value = [float(v) for v in corner]
        links.new(position, to_wall.inputs[1])
        ratio = _vector_math(tree, "DIVIDE", "box2", row + k)
        links.new(to_wall.outputs["Vector"], ratio.inputs[0])
        links.new(reflection, ratio.inputs[1])
        t_far.append(ratio.outputs["Vector"])
    farther = _vector_math(tree, "MAXIMUM", "box3", row)
    links.new(t_far[0], farther.inputs[0])
    links.new(t_far[1], farther.inputs[1])
    axes = _node(tree, "ShaderNodeSeparateXYZ", "box3", row + 1)
    links.new(farther.outputs["Vector"], axes.inputs[0])
    xy = _node(tree, "ShaderNodeMath", "box4", row, operation="MINIMUM")
    links.new(axes.outputs["X"], xy.inputs[0])
    links.new(axes.outputs["Y"], xy.inputs[1])
    t = _node(tree, "ShaderNodeMath", "box4", row + 1, operation="MINIMUM")
    links.new(xy.outputs[0], t.inputs[0])
    links.new(axes.outputs["Z"], t.inputs[1])
    step = _vector_math(tree, "SCALE", "box4", row + 2)
    links.new(reflection, step.inputs[0])
    links.new(t.outputs[0], step.inputs["Scale"])
    hit = _vector_math(tree, "ADD", "box4", row + 3)
    links.new(position, hit.inputs[0])
    links.new(step.outputs["Vector"], hit.inputs[1])
    direction = _vector_math(tree, "SUBTRACT", "texture", row + 2)
    links.new(hit.outputs["Vector"], direction.inputs[0])
    direction.inputs[1].default_value = [float(v) for v in centre]
    return direction.outputs["Vector"]


def _tint(tree, colour, f0: np.ndarray, metallic: float):
    """colour x metallic (F0 + (1 - F0) g), g = (1 - |N . I|)^5: a MULTIPLY_ADD on Facing^5."""
    links = tree.links
    weight = _node(tree, "ShaderNodeLayerWeight", "texture", 4)
    weight.inputs["Blend"].default_value = 0.5  # Facing = 1 - |N . I| exactly
    grazing = _node(tree, "ShaderNodeMath", "tint", 4, operation="POWER")
    links.new(weight.outputs["Facing"], grazing.inputs[0])
    grazing.inputs[1].default_value = SCHLICK_POWER
    schlick = _vector_math(tree, "MULTIPLY_ADD", "tint", 2)
    schlick.inputs[0].default_value = [float(metallic * (1.0 - c)) for c in f0]
    links.new(grazing.outputs[0], schlick.inputs[1])
    schlick.inputs[2].default_value = [float(metallic * c) for c in f0]
    product = _vector_math(tree, "MULTIPLY", "emission", 2)
    links.new(colour, product.inputs[0])
    links.new(schlick.outputs["Vector"], product.inputs[1])
    return product.outputs["Vector"]


def build_environment_material(name: str, image, *, centre=None, box=None,
                               tint: tuple[np.ndarray, float] | None = None):
    """A new material `name` showing `image` (a lat-long map, Blender's equirectangular mapping)
    along the reflection vector, box-projected when `box` ((3,) min, (3,) max world m) and
    `centre` ((3,) world m, the probe) are given, weighted by `tint` (F0, metallic) if given."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    tree.nodes.clear()
    links = tree.links
    coords = _node(tree, "ShaderNodeTexCoord", "input", 0)
    vector = coords.outputs["Reflection"]
    if box is not None and centre is not None:
        vector = _box_projected(tree, vector, centre, box, 1)
    texture = _node(tree, "ShaderNodeTexEnvironment", "texture", 0, image=image,
                    interpolation="Linear", projection="EQUIRECTANGULAR")
    links.new(vector, texture.inputs["Vector"])
    colour = texture.outputs["Color"]
    if tint is not None and not (tint[1] == 1.0 and np.all(np.asarray(tint[0]) == 1.0)):
        colour = _tint(tree, colour, np.asarray(tint[0], np.float64), float(tint[1]))
    emission = _node(tree, "ShaderNodeEmission", "emission", 0)
    emission.inputs["Strength"].default_value = 1.0
    links.new(colour, emission.inputs["Color"])
    output = _node(tree, "ShaderNodeOutputMaterial", "output", 0, target="ALL")
    links.new(emission.outputs["Emission"], output.inputs["Surface"])
    output.is_active_output = True
    return mat


def _original(mat):
    """The material an env-map material replaced (None: `mat` is not one, or it is gone)."""
    if mat is None or ORIGINAL_PROP not in mat:
        return None
    return bpy.data.materials.get(mat[ORIGINAL_PROP])


def wire_environment_material(obj, image, *, centre=None, box=None,
                              tints: dict[str, tuple[np.ndarray, float]] | None = None) -> list:
    """Point every material slot of `obj` at a new env-map material (module docstring); the
    originals keep a fake user. A slot already showing an env map is rebuilt from its original.
    Returns the new materials."""
    if len(obj.material_slots) == 0:
        obj.data.materials.append(None)
    made = []
    for slot in obj.material_slots:
        current = slot.material
        original = current
        if current is not None and ORIGINAL_PROP in current:  # an earlier run's material
            original = slot.material = _original(current)
            if current.users == 0:
                bpy.data.materials.remove(current)  # (its name is free for the new one)
        base = original.name if original is not None else obj.name
        tint = (tints or {}).get(original.name) if original is not None else None
        if tint is not None and tint[1] <= 0.0:
            tint = None  # not a metal (named with --objects): shown untinted, a full mirror
        mat = build_environment_material(base + ENV_SUFFIX, image, centre=centre, box=box,
                                         tint=tint)
        if original is not None:
            original.use_fake_user = True
        mat[ORIGINAL_PROP] = original.name if original is not None else ""
        slot.material = mat
        made.append(mat)
    return made


def unwire_environment_material(obj) -> None:
    """Point `obj`'s slots back at the materials the env-map materials replaced."""
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None or ORIGINAL_PROP not in mat:
            continue
        slot.material = _original(mat)
        if mat.users == 0:
            bpy.data.materials.remove(mat)


@contextlib.contextmanager
def originals_shown(scene) -> Iterator[None]:
    """Within the block, every slot showing an env-map material shows its original instead (what
    a snapshot must read: the mirror, not an emitter); afterwards the slots are as they were."""
    swapped = []
    for obj in scene.objects:
        for slot in getattr(obj, "material_slots", ()):
            mat = slot.material
            if mat is not None and ORIGINAL_PROP in mat:
                swapped.append((slot, mat))
                slot.material = _original(mat)
    try:
        yield
    finally:
        for slot, mat in swapped:
            slot.material = mat
