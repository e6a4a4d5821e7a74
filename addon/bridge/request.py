"""What a snapshot reads: `SnapshotRequest`, the switches of one bake's read of the scene."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class SocketBakeSettings:
    """How a material socket whose node graph the bridge cannot read (a Voronoi texture, a colour
    attribute, a mix of two textures) is baked by Cycles instead: once per graph, object and
    size, into a float image over the object's active render UV map (`socket_fallback`).

    | field   | range     | default | unit / meaning                                              |
    |---------|-----------|---------|-------------------------------------------------------------|
    | size    | [8, 4096] | 256     | texels per side of the square image                         |
    | samples | [1, 1024] | 4       | samples per texel, spread over its area (a texel: its mean) |
    | margin  | [0, 64]   | 2       | texels the UV charts are extended by, so that bilinear      |
    |         |           |         | look-ups at a chart's rim read no empty texels              |

    Cost against accuracy, measured on a Voronoi texture into roughness at 256 x 256 (2 cores
    shared with other work), each texel against a 64-sample bake: 4 samples 0.6 s, within 0.55%
    of the signal's largest value (mean 0.10%); 16 samples 2.1 s, within 0.27% (mean 0.025%).
    The time grows with size^2 x samples and the graph's cost.
    """

    size: int = 256
    samples: int = 4
    margin: int = 2


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
    | socket_bake  | (below) | how a material socket the bridge cannot read is baked by Cycles |
    |              |         | over the object's UVs (`socket_fallback`); None: its default    |
    |              |         | used and the socket listed in `Scene.ignored`                   |
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
    socket_bake: SocketBakeSettings | None = SocketBakeSettings()
