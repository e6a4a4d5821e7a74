"""One Cycles run of any kind, a camera render or a lightmap or colour-attribute bake
(`run_cycles`), what it bakes (`BakeSpec`) and what it returns (`CyclesRun`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Literal

import bpy
import numpy as np

from ...kernels.bake.lightmap_uv import LightmapUVSettings
from .bakes import BakeType, bake_color_attributes, bake_lightmaps
from .models import CyclesModel
from .runner import render_camera

ReferenceKind = Literal["render", "bake", "attribute"]


@dataclass(frozen=True)
class BakeSpec:
    """What a bake reference or ladder bakes.

    | field        | default    | meaning                                                      |
    |--------------|------------|--------------------------------------------------------------|
    | objects      | required   | object names, in order                                       |
    | bake_type    | "DIFFUSE"  | DIFFUSE, COMBINED, SHADOW or ALBEDO (see `bake_lightmaps`)   |
    | use_color    | True       | DIFFUSE only: multiply by the albedo (radiance)              |
    | uv_layer     | "Lightmap" | lightmap UV layer (kind "bake")                              |
    | size         | 256        | lightmap texels per side, or (W, H) (kind "bake")            |
    | margin       | 0          | texels dilated around charts (kind "bake")                   |
    | attribute    | "Cycles"   | colour attribute name (kind "attribute")                     |
    | lightmap_uv  | None       | make missing `uv_layer`s with these xatlas settings          |
    """

    objects: tuple[str, ...]
    bake_type: BakeType = "DIFFUSE"
    use_color: bool = True
    uv_layer: str = "Lightmap"
    size: int | tuple[int, int] = 256
    margin: int = 0
    attribute: str = "Cycles"
    lightmap_uv: LightmapUVSettings | None = None

    def fields(self) -> dict[str, Any]:
        out = dataclasses.asdict(self)
        out["objects"] = list(self.objects)
        out["size"] = list(self.size) if isinstance(self.size, tuple) else self.size
        return out


@dataclass(frozen=True, eq=False)
class CyclesRun:
    """The result of one Cycles render or bake.

    images: {"render": (H, W, 3)} for kind "render"; {object: (H, W, 3)} for "bake";
    {object: (V, 3)} for "attribute"; all float32 linear. masks: {object: (H, W) bool} for
    "bake", else empty. seconds: wall time of Cycles' work (sum over chunks for a reference).
    """

    kind: ReferenceKind
    samples: int
    seconds: float
    images: dict[str, np.ndarray]
    masks: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def image(self) -> np.ndarray:
        """The camera image of a render run."""
        return self.images["render"]


def run_cycles(scene, model: CyclesModel, kind: ReferenceKind, samples: int, *,
               resolution: tuple[int, int] | None = None, bake: BakeSpec | None = None,
               seed: int | None = None) -> CyclesRun:
    """One Cycles render ("render") or bake ("bake": lightmaps, "attribute": colour attributes)."""
    scene = scene or bpy.context.scene
    if kind == "render":
        pixels, seconds = render_camera(scene, model, samples, resolution, seed=seed)
        return CyclesRun(kind, samples, seconds, {"render": pixels})
    if bake is None:
        raise ValueError(f"kind '{kind}' needs a BakeSpec")
    if kind == "bake":
        images, seconds, masks = bake_lightmaps(
            scene, model, samples, bake.objects, bake.uv_layer, bake.size, bake.bake_type,
            use_color=bake.use_color, margin=bake.margin, seed=seed)
        return CyclesRun(kind, samples, seconds, images, masks)
    if kind == "attribute":
        images, seconds = bake_color_attributes(
            scene, model, samples, bake.objects, bake.attribute, bake.bake_type,
            use_color=bake.use_color, seed=seed)
        return CyclesRun(kind, samples, seconds, images)
    raise ValueError(f"kind must be 'render', 'bake' or 'attribute', got {kind!r}")
