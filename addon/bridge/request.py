"""What a snapshot reads: `SnapshotRequest`, the switches of one bake's read of the scene."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SnapshotRequest:
    """What one bake needs from the scene; everything else is not read at all.

    | field        | default | meaning                                                         |
    |--------------|---------|-----------------------------------------------------------------|
    | normals      | True    | corner normals (custom normals honoured)                        |
    | uv           | True    | the active render UV layer                                      |
    | lightmap_uv  | None    | name of a UV layer to read as `Scene.lightmap_uv`               |
    | textures     | True    | image and checker textures (a shadow bake reads none)           |
    | materials    | True    | materials beyond ids (False: every triangle gets the default)   |
    | lights       | True    |                                                                 |
    | camera       | True    |                                                                 |
    | objects      | None    | restrict geometry to these object names (None: all renderable)  |
    | world_render | True    | render a world shader the bridge cannot read into a map         |
    |              |         | (`read_world_texture`: Cycles, ~1.2 s); False: black or its     |
    |              |         | socket's colour                                                 |
    """

    normals: bool = True
    uv: bool = True
    lightmap_uv: str | None = None
    textures: bool = True
    materials: bool = True
    lights: bool = True
    camera: bool = True
    objects: tuple[str, ...] | None = None
    world_render: bool = True
