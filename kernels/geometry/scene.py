"""The kernel-side scene: everything a bake reads, as plain NumPy arrays.

`addon/bridge/` is the only producer (a snapshot of Blender's evaluated depsgraph); every kernel
is a consumer. Nothing here knows Blender: a test can build a `Scene` by hand.

Conventions, shared by every kernel
-----------------------------------
* Space: world space, metres (Blender units), right-handed, +Z up. Triangles are wound
  counter-clockwise around their geometric normal (Blender's face order).
* Colours: linear scene-referred Rec.709 RGB, float32. Images never carry a transfer curve.
* Radiometry: watts. Point and spot lights carry radiant intensity I (W/sr), suns irradiance
  E (W/m^2) on a surface facing them, area lights and emissive surfaces radiance L (W/(m^2 sr)).
  `lights.py` holds the conversions from Blender's light power and what Cycles does with them.
* Images: (H, W, C) float32, row 0 is the TOP row (as in every image file). A UV-space image
  (lightmap) maps texel (i, j) centre to u = (j + 0.5) / W, v = 1 - (i + 0.5) / H.
* Triangles of one object are contiguous: object k owns rows
  `objects[k].tri_start : objects[k].tri_start + objects[k].tri_count`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Literal

import numpy as np

TextureKind = Literal["IMAGE", "CHECKER", "ATTRIBUTE"]
LightKind = Literal["POINT", "SPOT", "SUN", "AREA"]
AreaShape = Literal["SQUARE", "RECTANGLE", "DISK", "ELLIPSE"]
CameraKind = Literal["PERSP", "ORTHO"]


@dataclass(frozen=True, eq=False)
class Texture:
    """A colour or height source sampled through UVs.

    IMAGE: `pixels` (H, W, 4) float32, linear (sRGB images are decoded by the bridge), row 0 top.
    CHECKER: Blender's Checker Texture: `color1` where floor(x*scale) + floor(y*scale) +
    floor(z*scale) is odd, `color2` where even (Cycles' `svm_checker`), on (u, v, 0) or on the
    Generated coordinates (`coordinates`; measured in renders by tests/blender/test_sample_scenes.py's
    author: on UVs at scale 2 the top-left quadrant u < 0.5, v > 0.5 is color1).
    ATTRIBUTE: a mesh attribute read by a Color Attribute or Attribute node (vertex colours):
    `name` the attribute's ("" the object's default colour attribute); its linear RGB per corner
    (`Scene.corner_colors`) is interpolated across each triangle, as Cycles does, and is the
    look-up's colour (`coordinates` "ATTRIBUTE": the coordinates ARE the colour).
    """

    kind: TextureKind
    name: str = ""
    pixels: np.ndarray | None = None  # (H, W, 4) float32, linear, row 0 top
    extension: Literal["REPEAT", "CLIP", "EXTEND", "MIRROR"] = "REPEAT"
    interpolation: Literal["LINEAR", "CLOSEST"] = "LINEAR"
    color1: np.ndarray = field(default_factory=lambda: np.ones(3, np.float32))  # (3,) linear
    color2: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # (3,) linear
    scale: float = 1.0  # checker squares per UV unit
    uv_layer: str | None = None  # None: the object's active render UV layer
    # What it is read along: "UV" (u, v, 0), "GENERATED" (`Scene.generated`: the object's
    # texture space mapped to the unit cube; an image reads its x and y), or "ATTRIBUTE"
    # (`Scene.corner_colors`, an ATTRIBUTE texture's own colour).
    coordinates: Literal["UV", "GENERATED", "ATTRIBUTE"] = "UV"
    # "sRGB": `pixels` hold sRGB-encoded colour, decoded after interpolation. Cycles keeps 8-bit
    # sRGB images so and decodes each look-up after filtering; decoding the texels first gives
    # brighter transitions (env_room's tiled floor baked: 2.5% bright, relMSE 1.4e-2 -> 7e-5).
    encoding: Literal["linear", "sRGB"] = "linear"
    # What a node chain makes of the decoded colour (the bridge folds Separate Color, Math, Mix and
    # Invert nodes of constants into these): `weights` (4,) turn (R, G, B, A) into one value for
    # all three outputs (a channel: (0, 0, 1, 0); a colour read as a number: its luminance; None:
    # the colour itself), then value * gain + offset per output, then a clamp to [0, 1] where a
    # node clamps its result.
    weights: np.ndarray | None = None
    gain: np.ndarray = field(default_factory=lambda: np.ones(3, np.float32))  # (3,)
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))  # (3,)
    clamp: bool = False
    # (2, 3) affine [A | t] applied to (u, v) before the look-up (a Mapping node of type Point
    # turning, scaling and moving the UVs, e.g. glTF's KHR_texture_transform); None: none
    uv_transform: np.ndarray | None = None
    # A tiled (UDIM) image: {tile number: (H, W, 4) pixels as `pixels` holds them}; (u, v) reads
    # tile 1001 + tx + 10 ty at (u - tx, v - ty), tx and ty the integer parts (`sample_tiles`).
    # `pixels` is then the largest tile (it sizes sampling densities); None: one image.
    udim: dict[int, np.ndarray] | None = None

    @property
    def transformed(self) -> bool:
        """True when the look-up's colour is not the texture's own (a channel, gain or clamp)."""
        return (self.weights is not None or self.clamp or not np.all(self.gain == 1.0)
                or np.any(self.offset != 0.0))


@dataclass(frozen=True, eq=False)
class Material:
    """What the kernels model of a surface: the Principled BSDF reduced to its classic parts.

    | field              | range     | default | unit / meaning                                 |
    |--------------------|-----------|---------|------------------------------------------------|
    | base_color         | [0, 1]^3  | 0.8     | diffuse albedo, or specular tint when metallic |
    | base_color_texture | Texture   | None    | replaces base_color when present               |
    | metallic           | [0, 1]    | 0       | 1: perfect (tinted) mirror when roughness ~ 0  |
    | roughness          | [0, 1]    | 0.5     | Blender's perceptual roughness                 |
    | ior                | > 0       | 1.5     | index of refraction (dielectric); below 1 the  |
    |                    |           |         | specular layer reflects as 1 / ior does        |
    | transmission       | [0, 1]    | 0       | 1: glass                                       |
    | specular           | [0, inf)  | 0.5     | Principled "Specular IOR Level"; 0: Lambertian |
    | emission           | [0, inf)^3| 0       | radiance W/(m^2 sr): colour x strength         |
    | normal_texture     | Texture   | None    | tangent-space normal map (bump mapping)        |
    | normal_strength    | [0, inf)  | 1       | the Normal Map node's strength                 |
    | height_texture     | Texture   | None    | height map feeding a Bump node; with a normal  |
    |                    |           |         | map too, the Bump node's Normal is the mapped  |
    |                    |           |         | normal (a Normal Map into a Bump node)         |
    | bump_strength      | [0, 1]    | 1       | the Bump node's strength                       |
    | bump_distance      | [0, inf)  | 1       | the Bump node's distance, metres               |
    | metal_color        | [0, 1]^3  | None    | the metal part's tint where it is not the base |
    |                    |           |         | colour (a Glossy BSDF mixed over a Diffuse     |
    |                    |           |         | one); None: the base colour                    |
    | metal_edge         | [0, 1]^3  | None    | the metal's F82 tint (a Metallic BSDF's Edge   |
    |                    |           |         | Tint, a Principled metal's Specular Tint): its |
    |                    |           |         | reflectance near 82 degrees is Schlick's times |
    |                    |           |         | this (`optics.fresnel_f82`); None: white       |
    | specular_tint      | [0, 1]^3  | None    | the dielectric specular layer's F0 tint (a     |
    |                    |           |         | Principled's Specular Tint): F0 x this head on,|
    |                    |           |         | white at grazing                               |
    |                    |           |         | (`specular_layer.tinted_albedo`); None: white  |
    | glass_tint         | [0, 1]^3  | None    | what a glass's reflection is tinted by (a      |
    |                    |           |         | Glass BSDF's colour); None: white, as the      |
    |                    |           |         | Principled reflects                            |
    | emission_texture   | Texture   | None    | emitted radiance W/(m^2 sr) per texel (colour  |
    |                    |           |         | x strength folded into its gain); replaces     |
    |                    |           |         | `emission`                                     |
    | metallic_texture   | Texture   | None    | metallic per texel (its first channel)         |
    | roughness_texture  | Texture   | None    | roughness per texel (its first channel)        |
    | coat               | [0, 1]    | 0       | Principled Coat Weight: a clear dielectric     |
    |                    |           |         | layer over everything else                     |
    | coat_roughness     | [0, 1]    | 0.03    | the coat's roughness                           |
    | coat_ior           | >= 1      | 1.5     | the coat's index of refraction                 |
    | coat_tint          | [0, 1]^3  | 1       | what the coat lets through at normal incidence |
    | translucent        | [0, 1]^3  | 0       | diffuse transmission (a Translucent BSDF's     |
    |                    |           |         | colour x weight): light from behind the        |
    |                    |           |         | surface, colour / pi (traced views, lamps)     |
    | sheen              | [0, inf)  | 0       | sheen weight (`shading/sheen.py`): cloth's rim |
    | sheen_tint         | [0, inf)^3| 1       | the sheen's colour                             |
    | sheen_roughness    | [0, 1]    | 0.5     | microfiber roughness, or the velvet's sigma    |
    | sheen_tint_texture | Texture   | None    | the sheen's colour per texel, replaces         |
    |                    |           |         | `sheen_tint` (traced views read it per hit)    |
    | sheen_roughness_.. | Texture   | None    | sheen_roughness_texture: roughness per texel   |
    |                    |           |         | (its first channel), replaces the constant     |
    | sheen_model        | str       | MICRO.. | "MICROFIBER" (Zeltner 2022) or "ASHIKHMIN"     |
    |                    |           |         | (velvet)                                       |
    | sheen_layer        | bool      | True    | True: a Principled layer, what lies under it   |
    |                    |           |         | dimmed by its albedo; False: a Sheen BSDF      |
    |                    |           |         | added beside the surface                       |
    | fallbacks          | dicts     | ()      | sockets read from a Cycles bake of their graph |
    |                    |           |         | (the bridge's general fallback): socket,       |
    |                    |           |         | read_as, seconds, cached, object               |
    | alpha              | [0, 1]    | 1       | coverage: 0 a hole every ray passes, 1 opaque  |
    | alpha_texture      | Texture   | None    | coverage per texel (its first channel),        |
    |                    |           |         | replaces `alpha` (leaves, fences, decals)      |
    | absorption         | [0, inf)^3| 0       | 1/m: the medium inside the closed mesh (a      |
    |                    |           |         | Volume Absorption); a ray crossing d metres of |
    |                    |           |         | it keeps exp(-absorption d) (Beer-Lambert)     |
    | camera_only        | bool      | False   | seen by camera rays alone, every other ray     |
    |                    |           |         | passes it: an unlit surface (glTF's            |
    |                    |           |         | KHR_materials_unlit import), whose emission    |
    |                    |           |         | lights nothing (`triangle_emission` holds 0)   |
    | shadowless         | bool      | False   | shadow rays pass it: it casts no shadow (a     |
    |                    |           |         | Light Path's Is Shadow Ray choosing a          |
    |                    |           |         | Transparent BSDF: architectural glass)         |

    The per-texel textures other than the base colour's are resolved per triangle by
    `shading/material_maps.py` before a kernel runs (a snapshot does it): metallic and roughness
    into material variants of constant values, emission into `Scene.triangle_radiance`.
    """

    name: str
    base_color: np.ndarray = field(default_factory=lambda: np.full(3, 0.8, np.float32))
    base_color_texture: Texture | None = None
    metallic: float = 0.0
    roughness: float = 0.5
    ior: float = 1.5
    transmission: float = 0.0
    specular: float = 0.5
    emission: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    normal_texture: Texture | None = None
    normal_strength: float = 1.0
    height_texture: Texture | None = None
    bump_strength: float = 1.0
    bump_distance: float = 1.0
    metal_color: np.ndarray | None = None
    metal_edge: np.ndarray | None = None
    specular_tint: np.ndarray | None = None
    glass_tint: np.ndarray | None = None
    emission_texture: Texture | None = None
    metallic_texture: Texture | None = None
    roughness_texture: Texture | None = None
    coat: float = 0.0
    coat_roughness: float = 0.03
    coat_ior: float = 1.5
    coat_tint: np.ndarray = field(default_factory=lambda: np.ones(3, np.float32))
    translucent: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    sheen: float = 0.0
    sheen_tint: np.ndarray = field(default_factory=lambda: np.ones(3, np.float32))
    sheen_roughness: float = 0.5
    sheen_tint_texture: Texture | None = None
    sheen_roughness_texture: Texture | None = None
    sheen_model: Literal["MICROFIBER", "ASHIKHMIN"] = "MICROFIBER"
    sheen_layer: bool = True
    # Coverage (Principled Alpha): what a ray meets of this surface; shadow and visibility rays
    # pass with weight 1 - alpha (`shading/alpha.py`, `geometry/alpha_occlusion.py`).
    alpha: float = 1.0
    alpha_texture: Texture | None = None
    # The medium inside the mesh: what glass holds (coloured glass, water). Only rays that refract
    # in meet it; a ray's weight drops on its way to the back face it leaves through.
    absorption: np.ndarray = field(default_factory=lambda: np.zeros(3, np.float32))
    # Unlit: only camera rays see the surface (a Light Path's Is Camera Ray choosing it over a
    # Transparent BSDF); shadow, mirror and diffuse rays pass, and it lights nothing.
    camera_only: bool = False
    # Shadow rays pass it (a Light Path's Is Shadow Ray choosing a Transparent BSDF); every other
    # ray meets it.
    shadowless: bool = False
    # What the bridge could not model on this material, one reason per entry.
    ignored: tuple[str, ...] = ()
    # Sockets the bridge read through a Cycles bake of their node graph, one dict each.
    fallbacks: tuple[dict, ...] = ()

    @property
    def has_alpha(self) -> bool:
        """True when some ray may pass through this surface (alpha < 1 or an alpha texture)."""
        return self.alpha_texture is not None or self.alpha < 1.0

    @property
    def is_emissive(self) -> bool:
        return self.emission_texture is not None or bool(np.any(self.emission > 0.0))


@dataclass(frozen=True, eq=False)
class Light:
    """A Blender light in radiometric units (see `lights.py` for the conversions).

    Exactly one of `intensity` (POINT, SPOT), `irradiance` (SUN) and `radiance` (AREA) is set.

    | field       | unit                     | meaning                                           |
    |-------------|--------------------------|---------------------------------------------------|
    | position    | m, world                 | the light's origin (area: centre of the emitter)  |
    | direction   | unit, world              | where the light points: the object's local -Z     |
    | axis_x/y    | unit, world              | the object's local X and Y (area extents, spot)   |
    | intensity   | W/sr, RGB                | point and spot: radiant intensity (cone inside)   |
    | irradiance  | W/m^2, RGB               | sun: irradiance on a surface facing it            |
    | radiance    | W/(m^2 sr), RGB          | area: radiance of the front face (one-sided)      |
    | radius      | m                        | point/spot soft size (0: a true point)            |
    | angle       | rad                      | sun: angular diameter                             |
    | spot_size   | rad                      | spot: full cone angle                             |
    | spot_blend  | [0, 1]                   | spot: smooth fraction of the cone edge            |
    | size_x/y    | m, world                 | area: extents along axis_x and axis_y (scaled)    |
    | receivers   | (O,) bool over objects   | light linking: the objects it lights (None: all)  |
    | blockers    | (O,) bool over objects   | shadow linking: those that shadow it (None: all)  |
    | hidden_from | ray kinds                | Cycles' ray visibility: "diffuse", "glossy"       |
    """

    name: str
    kind: LightKind
    position: np.ndarray  # (3,) float64, world, m
    direction: np.ndarray  # (3,) float64, world, unit
    axis_x: np.ndarray  # (3,) float64, world, unit
    axis_y: np.ndarray  # (3,) float64, world, unit
    intensity: np.ndarray | None = None  # (3,) W/sr
    irradiance: np.ndarray | None = None  # (3,) W/m^2
    radiance: np.ndarray | None = None  # (3,) W/(m^2 sr)
    radius: float = 0.0
    angle: float = 0.0
    spot_size: float = np.pi
    spot_blend: float = 0.0
    spot_square: bool = False
    shape: AreaShape = "SQUARE"
    size_x: float = 0.0
    size_y: float = 0.0
    cast_shadow: bool = True
    # Cycles' light and shadow linking, over `Scene.objects`: the objects that take this light's
    # light, and those whose surfaces its shadow rays meet (`Scene.shadow_passing`).
    receivers: np.ndarray | None = None
    blockers: np.ndarray | None = None
    # The lobes it does not light (Object > Visibility > Ray Visibility of the lamp): "diffuse"
    # (diffuse bases, sheens, translucency), "glossy" (highlights, mirror images)
    hidden_from: tuple[str, ...] = ()

    @property
    def lights_diffuse(self) -> bool:
        return "diffuse" not in self.hidden_from

    @property
    def lights_glossy(self) -> bool:
        return "glossy" not in self.hidden_from


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole (PERSP) or orthographic (ORTHO) camera, reduced to its image plane.

    The camera looks down its local -Z with +Y up (Blender's convention). The image plane is
    described at distance 1 in front of the eye (PERSP) or in metres (ORTHO): pixel (i, j) centre,
    row 0 at the top, lies at
        x = plane_min[0] + (j + 0.5) / W * (plane_max[0] - plane_min[0])
        y = plane_max[1] - (i + 0.5) / H * (plane_max[1] - plane_min[1])
    with sensor fit and lens shift already applied. `kernels/camera.py` turns this into rays.
    """

    kind: CameraKind
    matrix_world: np.ndarray  # (4, 4) float64, camera to world, rigid (scale removed)
    plane_min: np.ndarray  # (2,) float64, image-plane (x, y) of the bottom-left corner
    plane_max: np.ndarray  # (2,) float64, image-plane (x, y) of the top-right corner
    resolution: tuple[int, int]  # (W, H) pixels, render percentage applied
    clip_start: float = 0.1  # m
    clip_end: float = 1000.0  # m

    @property
    def position(self) -> np.ndarray:
        return self.matrix_world[:3, 3]


@dataclass(frozen=True, eq=False)
class ObjectInfo:
    """One evaluated mesh instance and where its triangles sit in the scene arrays."""

    name: str  # unique within the snapshot; instances get "parent/child#k"
    source_name: str  # the original bpy.types.Object name (what write-back targets)
    tri_start: int
    tri_count: int
    has_uv: bool  # whether `Scene.uv` rows of this object come from a real UV layer
    has_lightmap_uv: bool
    # The evaluated mesh has the original's corners (no topology-changing modifier): per-corner
    # results can be written back onto the original mesh.
    topology_matches_original: bool
    is_instance: bool = False
    # Cycles' ray visibility turned off for this object: "camera", "shadow" (rays the traced
    # views honour), "diffuse", "glossy", "transmission" (listed, not modelled)
    hidden_from: tuple[str, ...] = ()


@dataclass(frozen=True, eq=False)
class MapVariants:
    """A material whose metallic or roughness comes from a texture, and its variants of constant
    values: `ids[i, j]` is the index in `Scene.materials` of the variant with metallic
    `metallic[i]` and roughness `roughness[j]`, the quantised values its maps can take."""

    source: Material  # the material as read, its metallic / roughness textures on it
    metallic: np.ndarray  # (I,) float64 levels, ascending (`material_maps._levels`)
    roughness: np.ndarray  # (J,) float64 levels, ascending
    ids: np.ndarray  # (I, J) int32


@dataclass(frozen=True, eq=False)
class Scene:
    """A snapshot of what one bake needs. Unrequested parts are empty arrays or None.

    Arrays (T triangles):
        triangles       (T, 3, 3) float32  world-space corner positions, m
        normals         (T, 3, 3) float32  world-space unit corner normals (custom normals honoured)
        uv              (T, 3, 2) float32  active render UV per corner (zeros where has_uv is False)
        lightmap_uv     (T, 3, 2) float32  the requested lightmap UV layer, or None
        material_ids    (T,) int32         index into `materials`
        object_ids      (T,) int32         index into `objects`
        corner_loops    (T, 3) int32       loop (corner) index within the object's evaluated mesh
        corner_verts    (T, 3) int32       vertex index within the object's evaluated mesh
        generated       (T, 3, 3) float32  Blender's Generated texture coordinates per corner
                                           (object-space position in the mesh's texture space,
                                           the unit cube over its box), or None
    """

    triangles: np.ndarray
    normals: np.ndarray
    uv: np.ndarray
    lightmap_uv: np.ndarray | None
    material_ids: np.ndarray
    object_ids: np.ndarray
    corner_loops: np.ndarray
    corner_verts: np.ndarray
    objects: tuple[ObjectInfo, ...]
    materials: tuple[Material, ...]
    lights: tuple[Light, ...]
    camera: Camera | None
    world_color: np.ndarray  # (3,) float32, radiance W/(m^2 sr) of the uniform background
    # What the snapshot met but does not model, one human-readable reason per entry.
    ignored: tuple[str, ...] = ()
    # The world's equirectangular map of radiance W/(m^2 sr) (an Environment Texture times the
    # Background's strength; `world_light.world_radiance` reads it), world_color its mean over
    # the sphere; None: the world is world_color everywhere.
    world_texture: Texture | None = None
    # (3, 4) affine [A | t]: the map is read along normalize(A d + t) for a world direction d (a
    # Mapping node turning it); None: along d
    world_transform: np.ndarray | None = None
    # The rays Cycles hides the world from (World > Settings > Ray Visibility): "camera" (the
    # background is black), "glossy" (reflections show no sky), "transmission" (nor refractions),
    # "diffuse" (the world lights no surface)
    world_hidden_from: tuple[str, ...] = ()
    # The world as camera rays see it where that differs from `world_texture` (a Light Path node
    # in the world showing the camera a backdrop): an equirectangular map; None: the same
    camera_world: Texture | None = None
    generated: np.ndarray | None = None
    # (T, 3) float64 emitted radiance W/(m^2 sr) per triangle where a material's emission comes
    # from a texture (its mean over the triangle, `shading/material_maps.py`); None: per material
    triangle_radiance: np.ndarray | None = None
    # MikkTSpace frames per corner on the UV layer of the objects' Normal Map nodes, what Blender
    # reads tangent-space normal maps in (`shading/bump.py`): (T, 3, 3) float32 world unit
    # tangents, zero on objects without such a node, and (T, 3) float32 bitangent signs
    # (b = sign (n x t)); None: no object has one.
    corner_tangents: np.ndarray | None = None
    corner_signs: np.ndarray | None = None
    # (T, 3, 2) float32 UVs per corner that normal-map textures are looked up on (the layer a
    # UV Map node into the Image Texture names, where that is not the active render layer;
    # elsewhere equal to `uv`); None: `uv`.
    normal_map_uv: np.ndarray | None = None
    # Whether the Normal Map node builds its frame on the interpolated normal made unit (Cycles
    # in Blender 5.2) or as interpolated (4.5); the bridge sets it from Blender's version.
    normal_map_unit_normal: bool = True
    # (T, 3, 3) float32 linear RGB per corner of the attribute each triangle's material reads
    # through ATTRIBUTE textures (vertex colours; 0 where the mesh lacks it, as Cycles reads a
    # missing attribute); None: no material reads one.
    corner_colors: np.ndarray | None = None
    # Materials whose metallic or roughness comes from a texture, each with its variants of
    # constant values (`MapVariants`): triangles carry the variant of the maps' mean over them,
    # ray hits the variant of the maps' values at the hit (`shading/material_maps.py`).
    map_variants: tuple[MapVariants, ...] = ()

    @property
    def read_materials(self) -> tuple[Material, ...]:
        """The materials as the snapshot read them, each counted once: a material's metallic /
        roughness variants (`map_variants`) stand for it by their first, which keeps its index
        and name. What reports and job summaries list."""
        others = {int(k) for variants in self.map_variants for k in variants.ids.ravel()[1:]}
        return tuple(m for k, m in enumerate(self.materials) if k not in others)

    @cached_property
    def variant_family(self) -> np.ndarray:
        """(M,) int64 per material: the index in `map_variants` of the family it is a variant
        of, -1 for none."""
        family = np.full(len(self.materials), -1, np.int64)
        for f, variants in enumerate(self.map_variants):
            family[variants.ids.ravel()] = f
        return family

    @cached_property
    def texture_coords(self) -> np.ndarray:
        """(T, 3, 3) float64 per-corner coordinates that each triangle's base-colour texture is
        read along: (u, v, 0), `generated` where that texture reads Generated coordinates, or
        `corner_colors` where it is a colour attribute."""
        out = np.zeros((self.triangle_count, 3, 3))
        out[..., :2] = self.uv
        for kind, corners in (("GENERATED", self.generated), ("ATTRIBUTE", self.corner_colors)):
            if corners is None:
                continue
            reads = np.array([m.base_color_texture is not None
                              and m.base_color_texture.coordinates == kind
                              for m in self.materials], bool)
            rows = np.flatnonzero(reads[self.material_ids])
            out[rows] = corners[rows]
        return out

    @cached_property
    def texture_seams(self) -> np.ndarray:
        """(T, 3) bool: the edge opposite each corner is where the texture coordinates
        (`texture_coords`) jump, no other triangle of the object meeting it at the same two
        points with the same coordinates there (a UV seam, or the mesh's border); False on
        triangles whose material has no base-colour texture. Points, not
        vertex indices: importers split vertices along hard edges whose coordinates go on. A
        look-up extrapolated past such an edge reads another island of the atlas: filters stop
        there."""
        out = np.zeros((self.triangle_count, 3), bool)
        textured = np.array([m.base_color_texture is not None for m in self.materials], bool)
        rows = np.flatnonzero(textured[self.material_ids])  # only textures are filtered
        if rows.size == 0:
            return out
        first, second = np.array([1, 2, 0]), np.array([2, 0, 1])  # the edge opposite corner k
        # float32 holds every input exactly (corners, UVs); + 0.0 turns -0.0 into 0.0
        points = self.triangles[rows].astype(np.float32) + np.float32(0.0)
        coords = self.texture_coords[rows].astype(np.float32) + np.float32(0.0)
        pa, pb, ca, cb = points[:, first], points[:, second], coords[:, first], coords[:, second]
        step = pa - pb  # each edge keyed by its ends in lexicographic order
        swap = np.where(step[..., 0] != 0.0, step[..., 0] > 0.0,
                        np.where(step[..., 1] != 0.0, step[..., 1] > 0.0, step[..., 2] > 0.0))
        swap = swap[..., None]
        owner = np.repeat(self.object_ids[rows, None, None].astype(np.float32), 3, axis=1)
        keys = np.ascontiguousarray(np.concatenate(
            [owner, np.where(swap, pb, pa), np.where(swap, pa, pb), np.where(swap, cb, ca),
             np.where(swap, ca, cb)], axis=2).reshape(3 * rows.size, -1))
        flat = keys.view(np.dtype((np.void, keys.shape[1] * keys.itemsize))).ravel()
        _, inverse, counts = np.unique(flat, return_inverse=True, return_counts=True)
        out[rows] = (counts[inverse] < 2).reshape(rows.size, 3)
        return out

    @property
    def triangle_count(self) -> int:
        return int(self.triangles.shape[0])

    def ray_hidden(self, kind: str) -> np.ndarray | None:
        """(T,) bool: the triangles of objects Cycles hides from rays of `kind` ("camera",
        "shadow", ...: `ObjectInfo.hidden_from`), for every kind but the camera's the unlit
        surfaces (`camera_only`), and for shadow rays the `shadowless` ones; None when no
        triangle is."""
        owners = [o for o in self.objects if kind in o.hidden_from]
        unlit = None if kind == "camera" else self.camera_only()
        if kind == "shadow":
            unlit = self.shadowless(unlit)
        if not owners:
            return unlit
        out = np.zeros(self.triangle_count, bool) if unlit is None else unlit.copy()
        for o in owners:
            out[o.tri_start:o.tri_start + o.tri_count] = True
        return out

    def shadow_passing(self, light: Light) -> np.ndarray | None:
        """(T,) bool: the triangles `light`'s shadow rays pass: those every shadow ray passes
        (`ray_hidden`) and, under shadow linking, the objects outside its blockers; None when
        they meet every triangle."""
        hidden = self.ray_hidden("shadow")
        if light.blockers is None:
            return hidden
        outside = ~light.blockers[self.object_ids]
        return outside if hidden is None else outside | hidden

    def camera_only(self) -> np.ndarray | None:
        """(T,) bool: the triangles only camera rays see (`Material.camera_only`: unlit
        surfaces, which every other ray passes); None when there are none."""
        flags = np.array([m.camera_only for m in self.materials], bool)
        if not flags.any():
            return None
        return flags[self.material_ids]

    def shadowless(self, hidden: np.ndarray | None = None) -> np.ndarray | None:
        """(T,) bool: the triangles shadow rays pass (`Material.shadowless`), or-ed with `hidden`
        (T,) bool when given; None when there are none."""
        flags = np.array([m.shadowless for m in self.materials], bool)
        if not flags.any():
            return hidden
        return flags[self.material_ids] | (False if hidden is None else hidden)

    def object_slice(self, index: int) -> slice:
        info = self.objects[index]
        return slice(info.tri_start, info.tri_start + info.tri_count)


def triangle_emission(scene: Scene) -> np.ndarray:
    """(T, 3) float64 radiance L_e each triangle emits into the scene, W/(m^2 sr): its
    material's, or the mean of its emission texture over the triangle
    (`Scene.triangle_radiance`); 0 on unlit surfaces (`Material.camera_only`: Cycles' other
    rays pass them, so they light nothing; the camera sees them through `emission_at`)."""
    if scene.triangle_radiance is not None:
        out = scene.triangle_radiance
    else:
        table = np.array([np.asarray(m.emission, np.float64) for m in scene.materials]
                         ).reshape(-1, 3)
        out = table[scene.material_ids]
    unlit = scene.camera_only()
    return out if unlit is None else np.where(unlit[:, None], 0.0, out)


def triangle_areas(triangles: np.ndarray) -> np.ndarray:
    """Areas of (T, 3, 3) triangles, m^2, computed in float64. Returns (T,) float64."""
    t = triangles.astype(np.float64, copy=False)
    cross = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    return 0.5 * np.linalg.norm(cross, axis=1)


def geometric_normals(triangles: np.ndarray) -> np.ndarray:
    """Unit geometric normals (counter-clockwise winding) of (T, 3, 3) triangles, (T, 3) float64.

    Zero-area triangles get a zero vector rather than NaN.
    """
    t = triangles.astype(np.float64, copy=False)
    cross = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    length = np.linalg.norm(cross, axis=1, keepdims=True)
    return np.divide(cross, length, out=np.zeros_like(cross), where=length > 0.0)


def interpolated_normals(scene: Scene, tri: np.ndarray, bary: np.ndarray,
                         fallback: np.ndarray | None = None) -> np.ndarray:
    """(M, 3) float64 unit shading normals at points given as scene triangles (M,) and
    barycentrics (M, 3): the corner normals interpolated and normalised. Where they cancel
    (length <= 1e-12), `fallback` (M, 3) when given, else the near-zero vector as it is."""
    normals = np.einsum("mk,mkc->mc", bary, scene.normals[tri].astype(np.float64))
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    unit = normals / np.maximum(length, 1e-12)
    return unit if fallback is None else np.where(length > 1e-12, unit, fallback)


def empty_scene() -> Scene:
    """A scene with nothing in it: the neutral element tests and kernels can start from."""
    return Scene(
        triangles=np.zeros((0, 3, 3), np.float32),
        normals=np.zeros((0, 3, 3), np.float32),
        uv=np.zeros((0, 3, 2), np.float32),
        lightmap_uv=None,
        material_ids=np.zeros(0, np.int32),
        object_ids=np.zeros(0, np.int32),
        corner_loops=np.zeros((0, 3), np.int32),
        corner_verts=np.zeros((0, 3), np.int32),
        objects=(),
        materials=(),
        lights=(),
        camera=None,
        world_color=np.zeros(3, np.float32),
    )
