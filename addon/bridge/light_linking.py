"""Cycles' light and shadow linking as the kernels read it: per light, the objects it lights
(`Light.receivers`) and the objects whose surfaces its shadow rays meet (`Light.blockers`).

A light's receiver (or blocker) collection lists objects and child collections, each entry
included or excluded (Object > Shading > Light Linking). Blender's depsgraph resolves them so
(`depsgraph_light_linking.cc`): an entry's state holds for every object under it, child
collections are visited before the collection's own objects and the last visit wins; where any
object is included, only the included ones take part, otherwise every object but the excluded.
An object is matched by its original (its instances share its links).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from ...kernels.geometry.scene import Light, ObjectInfo
from .mesh import MeshChunk

# Which collection of `Object.light_linking` sets which `Light` field.
LINKS = (("receiver_collection", "receivers"), ("blocker_collection", "blockers"))


def link_states(collection) -> dict[str, bool]:
    """Object name -> True (included) or False (excluded) in a light or shadow linking
    `collection`, resolved as the depsgraph does (see the module); {} for None or an empty one."""
    states: dict[str, bool] = {}
    if collection is None:
        return states
    for child, entry in zip(collection.children, collection.collection_children, strict=True):
        included = entry.light_linking.link_state == "INCLUDE"
        for obj in child.all_objects:
            states[obj.name] = included
    for obj, entry in zip(collection.objects, collection.collection_objects, strict=True):
        states[obj.name] = entry.light_linking.link_state == "INCLUDE"
    return states


def linking_of(obj) -> dict[str, dict[str, bool]]:
    """`Light` field -> `link_states` of `obj`'s receiver and blocker collections, for those it
    has and that list objects; {} without linking."""
    linking = getattr(obj, "light_linking", None)
    if linking is None:
        return {}
    out = {}
    for attr, field_name in LINKS:
        states = link_states(getattr(linking, attr, None))
        if states:
            out[field_name] = states
    return out


def takes_part(states: dict[str, bool], objects: Sequence[ObjectInfo | MeshChunk]) -> np.ndarray:
    """(O,) bool over `objects` (the scene's, or the chunks they are made of, in order): the
    ones a light's resolved `states` let take part (lit, or casting its shadows): the included
    ones where any is, else all but the excluded."""
    default = not any(states.values())
    return np.array([states.get(o.source_name, default) for o in objects], bool)


def linked_lights(lights: list[Light], linking: dict[str, dict],
                  objects: Sequence[ObjectInfo | MeshChunk]) -> list[Light]:
    """`lights` with their `receivers` and `blockers` set from `linking` (light name ->
    `linking_of` its object) over the scene's `objects`."""
    return [replace(light, **{field_name: takes_part(states, objects)
                              for field_name, states in linking[light.name].items()})
            if light.name in linking else light for light in lights]


def mesh_linking_notes(obj) -> list[str]:
    """Notes for an emissive mesh's light and shadow linking (Object > Shading > Light Linking),
    which the kernels do not model (a lamp's they do); [] where `obj` is a
    lamp or has none."""
    if obj.type == "LIGHT":
        return []
    return [f"object '{obj.name}': {'light' if field_name == 'receivers' else 'shadow'} linking "
            f"of an emissive mesh in Cycles; not modelled, its light reaches every object and "
            f"every object shadows it" for field_name in linking_of(obj)]
