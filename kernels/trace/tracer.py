"""Whitted ray tracing: backward from the eye through pixel centres, to a fixed depth.

The lecture: "cast rays from the centre of projection through each pixel centre into the scene";
diffuse surfaces are not traced further (their reflected rays go everywhere), highly specular ones
spawn "a single reflected ray", and the ray tree has a "pre-fixed number of bounces".

At every hit this kernel adds
* emission of emissive surfaces (what the eye sees of a light);
* direct light from every light by shadow rays: Lambert diffuse rho/pi * E (the base under a
  Principled specular layer darkened by the layer's albedo at the view, `specular_layer.py`),
  plus GGX highlights of rough glossy lobes (a specular layer's, a metal's) from lamps and area
  lights; area lights and emissive triangles on a fixed stratified pattern (soft shadows; an
  emissive mesh of many triangles is one light of a fixed number of points), or as points where
  they are small against their distance;
and spawns
* a mirror ray for metals (Schlick weight) and for dielectric specular layers (the layer's
  albedo at the view: exact Fresnel when smooth); on a rough surface the one ray stands for its
  lobe (the energy right; escaping, it reads the world's map averaged over the lobe,
  `world_lobes.py`; the surfaces it meets are drawn sharp);
* for glass, a reflected and a refracted ray weighted by the exact Fresnel reflectance, with
  total internal reflection.
Escaping rays see the world colour. A branch whose weight (throughput) falls below `min_weight`
stops early ("model no more than a scene needs"); the statistics count how many rays that saved.

The whole tree is traced as a wavefront: all rays of one depth at once through the BVH.

The settings and result types are in `settings.py`, the lights' samples in `emitters.py`, the
surface at a hit in `surface.py`; this module holds the wavefront (`Tracer`) and `trace_steps`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace

import numpy as np

from ..bake.camera_view import edge_pixels, stratified_offsets
from ..geometry.alpha_occlusion import Layers, layered_hits, transmittance
from ..geometry.bvh import BVH
from ..geometry.camera import (
    Strata,
    camera_rays,
    camera_reach,
    pixel_rays,
    plane_transfer,
    strata_rows,
)
from ..geometry.frames import tangent_frames
from ..geometry.intersect import Hits
from ..geometry.scene import Scene, geometric_normals
from ..geometry.vec import max_of_three, row_dot
from ..measure.metrics import REC709_LUMINANCE
from ..measure.phase_clock import PhaseClock
from ..progress import Steps, drain, scaled
from ..shading import lights as light_units
from ..shading.alpha import HiddenCoverage, lighting_coverage, ray_coverage, scene_alpha
from ..shading.bump import bump_shadowing, valid_reflection
from ..shading.glossy_lobe import (
    MEAN_FACTOR,
    ggx_microfacets,
    lobe_mean,
    lobe_points,
    lobe_rays,
    lobe_refractions,
)
from ..shading.highlight_spread import sample_roughness
from ..shading.material_maps import emission_at, material_values, translucent_colours
from ..shading.optics import fresnel_dielectric, reflect, refract
from ..shading.pixel_texture import Footprint, filtered_albedo, footprint_albedo
from ..shading.sheen import Fabric
from ..shading.specular_layer import (
    coat_attenuation,
    coat_tables,
    ggx_highlight,
    layer_f0,
    layer_tints,
    metal_reflectance,
    metal_tables,
    tinted_albedo,
    view_factors,
    view_tables,
)
from ..shading.world_light import (
    cosine_lift,
    extract_suns,
    horizon_sky,
    world_radiance,
    world_seen_by,
)
from . import differentials as rd
from .emitters import FINE_SPLIT, REFINE_REACH, emitter_reach, lamp_hull, scene_emitters
from .settings import TraceResult, TracerSettings, TraceStats, auto_settings
from .shadow_shafts import ClearShafts
from .surface import MIN_NORMAL_LENGTH, SurfaceHits, surface_at
from .world_lobes import WorldLobes

# Emitter samples handled together in area lighting: B x hits arrays stay a few MB per block for
# a typical wavefront of ~100k hits.
EMITTER_BLOCK = 8
# Below this base colour a hit's white-base diffuse share (edge detection only) is not divided out.
ALBEDO_FLOOR = 1e-3
# Edge sub-samples traced per wavefront: large enough to amortise per-call work, small enough that
# a wavefront's hit records (~1 KB per ray over its depths) stay a few hundred MB at most.
EDGE_WAVEFRONT = 1 << 18
# An isolated pixel this many times brighter (luminance) than the median of its 3 x 3
# neighbourhood, and above HOT_FLOOR W/(m^2 sr), holds a highlight smaller than itself met by a
# point sample (`hot_pixels`): it is traced again with HOT_SAMPLES x HOT_SAMPLES rays, so its
# value is the highlight's share of the pixel, as Cycles' many samples average it.
HOT_RATIO = 4.0
HOT_FLOOR = 1.0
HOT_SAMPLES = 8
# The sub-samples of a pixel (an edge's a x a) together draw about this many times the rays a
# whole pixel's rough lobe takes, from one stratified set, each its part (`_lobe_rays`,
# `lobe_points`). The blurred panel of test_trace.py against Cycles: relMSE 0.0060 with 8, 0.0107
# with 4, 0.0045 with 16; a roughness-1 metal dice under a photographed studio 1.9e-3 in 4.4 s,
# 3.9e-3 in 3.5 s, 9.1e-4 in 6.3 s.
SUBSAMPLE_LOBE_SHARE = 8
# Rays a translucent camera hit gathers the light behind it with (`_translucent_gather`). A
# back-lit leaf card over a sunlit floor against Cycles: relMSE 9.4e-4 with 4, 3.7e-4 with 8,
# 3.1e-4 with 16 (the leaf's mean within 1.3%, 0.2%, 0.1%).
TRANSLUCENT_RAYS = 8
# `Tracer._visible`'s cover when none is given: the scene's shadow rays' (`shadow_cover`, which
# may itself be None: every surface opaque to them).
DEFAULT_COVER = object()
# An environment map read for reflected rays: (N, 3) world points, (N, 3) unit directions, (N,)
# the surfaces' roughness -> (N, 3) radiance W/(m^2 sr) arriving at the points along the
# directions (over a rough surface's lobe). A look-up with an `irradiance` attribute that is not
# None (envmap.py's `MapLookup`) also lights the diffuse part: (N, 3) points, (N, 3) unit normals
# -> (N, 3) irradiance W/m^2 from the mapped surroundings, reflected as albedo / pi times it.
EnvironmentLookup = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]
# Diffuse light from elsewhere (the two-pass renderer's radiosity solution): (N,) triangles,
# (N, 3) barycentrics, (N, 3) unit ray directions towards the points, (N,) bool front side,
# (N,) bool seen from the camera's side (the ray left every solid it refracted into, through
# its back faces, and met no back face from outside: no closed mesh's surface lies between the
# point and the camera), and the hits' strata (None, or (stratum (N,), m) when they are m
# sub-samples of pixels, which may share out light samples as `Tracer._area_direct` does)
# -> (N, 3) radiance W/(m^2 sr) the points reflect diffusely toward the ray, shadows included.
DiffuseLookup = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                          Strata | None], np.ndarray]


def _scene_scale(scene: Scene) -> float:
    if scene.triangle_count == 0:
        return 1.0
    lo = scene.triangles.reshape(-1, 3).min(0).astype(np.float64)
    hi = scene.triangles.reshape(-1, 3).max(0).astype(np.float64)
    return float(max(np.linalg.norm(hi - lo), np.abs(lo).max(), np.abs(hi).max(), 1e-6))


def _emitter_geometry(delta: np.ndarray, ns: np.ndarray, normals: np.ndarray, two_sided: np.ndarray,
                      da: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Hits against emitter samples, arrays broadcast to one shape (...): delta (..., 3) from
    hit to sample (m), the hits' shading normals (..., 3), the samples' normals (..., 3), whether
    they emit both ways (...) and the areas they stand for (..., m^2). Returns the unit
    directions to the samples (..., 3), distances (...), their squares and the geometry terms
    (1/m^2).

    Each sample stands for its share a of the emitter, taken as a disc facing the hit (Wallace,
    Elmquist and Haines 1989; `closed_forms.disc_form`): cos cos / (d^2 + a / pi), the point's
    cos cos / d^2 far away, and bounded where the hit lies closer to the emitter than its
    samples are apart (a surface it touches), where 1 / d^2 made single pixels hundreds of
    times too bright."""
    d2 = np.einsum("...j,...j->...", delta, delta)
    dist = np.sqrt(d2)
    to_l = delta / np.maximum(dist, 1e-12)[..., None]
    cos_r = np.einsum("...j,...j->...", ns, to_l)
    cos_e = -np.einsum("...j,...j->...", to_l, normals)
    cos_e = np.where(two_sided, np.abs(cos_e), cos_e)
    g = np.clip(cos_r, 0, None) * np.clip(cos_e, 0, None) / np.maximum(d2 + da / np.pi, 1e-12)
    return to_l, dist, d2, g


def _scatter_add(out: np.ndarray, index: np.ndarray, values: np.ndarray) -> None:
    """out[index] += values, repeated indices summed: out (M, C), index (N,) int, values (N, C).
    What np.add.at does, by one np.bincount per channel: 2.5x quicker on 10^5 rays (5.9 ms
    against 14.8 ms for (10^5, 3) values, NumPy 2.5)."""
    index = np.asarray(index)
    if index.size == 0:
        return
    values = np.asarray(values, np.float64)
    for c in range(out.shape[1]):
        out[:, c] += np.bincount(index, weights=values[:, c], minlength=len(out))


class Tracer:
    """The wavefront tracer over one scene and BVH: `radiance` of any rays (camera rays, or the
    faces of a cube map in `envmap.py`), with statistics gathered in `stats`."""

    def __init__(self, scene: Scene, bvh: BVH, settings: TracerSettings,
                 environment: Mapping[int, EnvironmentLookup] | None = None,
                 shadow_bvh: BVH | None = None, diffuse: DiffuseLookup | None = None,
                 view_pixels: int | None = None):
        self.scene = scene
        self.bvh = bvh
        # Shadow rays may test other geometry than the rays that see: a cube map's faces see
        # past the hidden object, whose shadow still falls on its surroundings.
        self.shadow_bvh = shadow_bvh or bvh
        self.settings = settings
        # Environment mapping: object index -> lookup(points, directions) -> radiance, each (N, 3).
        # Mirror reflections off those objects read the lookup instead of spawning rays.
        self.environment = dict(environment or {})
        # Two-pass rendering: the diffuse reflection at every hit read from `diffuse` (a
        # radiosity solution, kernels/hybrid/) instead of lit by shadow rays; the glossy lobes'
        # highlights and the mirror and glass rays stay the tracer's.
        self.diffuse = diffuse
        self.offset = settings.offset_scale * _scene_scale(scene)
        # Surfaces with alpha (leaf cards): shadow rays pass them with weight 1 - alpha; None
        # when every surface is opaque (shadow rays are then a plain any-hit test).
        self.alpha = scene_alpha(scene)
        # What mirror and glass rays meet: the alpha, unlit surfaces transparent to them.
        self.bounce_cover = lighting_coverage(scene)
        # What camera and shadow rays meet: the alpha, with the objects Cycles hides from such
        # rays (Object > Visibility > Ray Visibility) fully transparent to them.
        self.camera_cover = ray_coverage(scene, "camera")
        self.shadow_cover = ray_coverage(scene, "shadow")
        # Where some object is hidden from glossy or transmission rays: what the reflected and
        # the refracted rays meet (`_kind_hits`); None: both meet `bounce_cover`.
        self.kind_covers = None
        if any(kind in o.hidden_from for o in scene.objects for kind in ("glossy", "transmission")):
            self.kind_covers = (ray_coverage(scene, "glossy"), ray_coverage(scene, "transmission"))
        # Shadow linking: the lights whose shadow rays pass the objects outside their blockers,
        # each with its own coverage (`link_covers[light_cover[light]]`).
        self.link_covers, self.light_cover = [], {}
        for light in scene.lights:
            if light.blockers is not None:
                self.light_cover[light] = len(self.link_covers)
                self.link_covers.append(HiddenCoverage(self.alpha, scene.shadow_passing(light)))
        self.tri_normals = geometric_normals(scene.triangles)
        self.emitters = scene_emitters(scene, settings)
        # Hits whose triangle (or part of it) sees an area emitter or a lamp whole cast no shadow
        # rays to it: the area emitters' shafts, then the lamps' (a sun's reach twice the scene's
        # size: past all of it).
        reach = 2.0 * _scene_scale(scene)
        em = self.emitters
        self.shafts = ClearShafts(
            scene.triangles, em.hulls + [lamp_hull(li, reach) for li in em.lights],
            np.concatenate([np.bincount(em.area_emitter, minlength=len(em.hulls)),
                            np.ones(len(em.lights))]),  # shadow rays a hit casts to each
            self.shadow_bvh, self.offset, view_pixels)
        self.area_lamps = [li for li in scene.lights if li.kind == "AREA"]
        # What each area emitter reaches (its lamp's linking and ray visibility), and the area
        # lamps mirrors show (those glossy rays see).
        self.reach = emitter_reach(self.area_lamps, len(em.hulls), len(scene.objects),
                                   self.light_cover)
        self.mirror_lamps = [li for li in self.area_lamps if li.lights_glossy]
        # A world map's suns (`world_light.extract_suns`): highlights of the rough lobes, and
        # the map without them for those lobes' rays (sky_scene); neither where Cycles hides the
        # world from glossy rays.
        self.map_suns, self.sky_scene = (), world_seen_by(scene, "glossy")
        if self.sky_scene.world_texture is not None:
            sky = self.sky_scene
            self.map_suns, residual = extract_suns(sky.world_texture, sky.world_transform)
            self.sky_scene = replace(sky, world_texture=residual)
        # That map averaged over rough lobes, for the rays that stand for one (`world_lobes.py`).
        self.world_lobes = (None if self.sky_scene.world_texture is None
                            else WorldLobes(self.sky_scene))
        # What the primary rays are to the world's ray visibility: the camera's; a cube map's
        # faces are what glossy rays see (`envmap.py`).
        self.primary_kind = "camera"
        self.stats = TraceStats()
        # Seconds per phase and per depth (`PhaseClock`), for the profile benches print.
        self.clock = PhaseClock()
        self.pass_name = "rays"  # the profile's label for what `radiance` traces now
        mats = scene.materials
        self.metallic = np.array([m.metallic for m in mats])
        # A metal part's own tint where it is not the base colour (`Material.metal_color`).
        self.tinted = np.array([m.metal_color is not None for m in mats])
        self.metal_color = np.array([m.base_color if m.metal_color is None else m.metal_color
                                     for m in mats], np.float64).reshape(-1, 3)
        self.transmission = np.array([m.transmission for m in mats])
        self.glass_tint = np.array([np.ones(3) if m.glass_tint is None else m.glass_tint
                                    for m in mats], np.float64).reshape(-1, 3)
        self.roughness = np.array([m.roughness for m in mats])
        self.ior = np.array([max(m.ior, 1.0 + 1e-6) for m in mats])
        # The specular layer's F0 from the material's own IOR, as its albedo tables take it (an
        # IOR below 1 reflects as its inverse does; 0: F0 = 1, as Cycles shows it).
        self.layer_f0 = np.array([layer_f0(m.ior, m.specular) for m in mats])
        self.layer_tint = layer_tints(mats)
        self.specular = np.array([m.specular for m in mats])
        self.layer_tables = view_tables(mats)
        self.layer_untinted = view_tables(mats, tinted=False)  # the tint's own: `tinted_albedo`
        self.metal_tables = metal_tables(mats)
        # The Principled coat: a clear layer over everything else (`specular_layer.coat_*`).
        self.coat = np.array([m.coat for m in mats], np.float64)
        self.coat_roughness = np.array([m.coat_roughness for m in mats], np.float64)
        self.coat_ior = np.array([m.coat_ior for m in mats], np.float64)
        self.coat_f0 = np.array([layer_f0(m.coat_ior, 0.5) for m in mats], np.float64)
        self.coat_tint = np.array([m.coat_tint for m in mats], np.float64).reshape(-1, 3)
        self.coat_tables = coat_tables(mats) if self.coat.any() else None
        # Sheen (`shading/sheen.py`): per material, its weight, model and layering (colour and
        # roughness per hit, `_fabric`).
        self.sheen_weight = np.array([m.sheen for m in mats], np.float64)
        self.has_sheen = self.sheen_weight > 0.0
        self.translucent = translucent_colours(mats)
        self.velvet = np.array([m.sheen_model == "ASHIKHMIN" for m in mats], bool)
        self.sheen_layer = np.array([m.sheen_layer for m in mats], bool)
        # The media inside closed meshes (1/m); None when no material holds one.
        absorption = np.array([m.absorption for m in mats], np.float64).reshape(-1, 3)
        self.absorption = absorption if absorption.any() else None
        self.textured = np.array([m.base_color_texture is not None for m in mats], bool)
        self._frames: rd.TriangleFrames | None = None  # built when differentials are first carried
        self.black = np.array([m.base_color_texture is None and not np.any(m.base_color > 0)
                               for m in mats], bool)
        # Base colours from colour attributes change across triangle edges (per-face or
        # per-corner values) with nothing filtering them: the edge-detection image keeps them.
        self.attribute_base = np.array([m.base_color_texture is not None
                                        and m.base_color_texture.kind == "ATTRIBUTE"
                                        for m in mats], bool)

    # --- direct light ---------------------------------------------------------------------------

    def _visible(self, origins, directions, t_max, cover=DEFAULT_COVER) -> np.ndarray:
        """(N,) what of each shadow ray arrives (1 or 0; a transmittance through partly covered
        surfaces) through `cover` (default: every shadow ray's, `shadow_cover`)."""
        self.stats.shadow_rays += len(origins)
        with self.clock("shadow traversal"):
            cover = self.shadow_cover if cover is DEFAULT_COVER else cover
            if cover is not None:  # (N,) float transmittance
                return transmittance(self.shadow_bvh, origins, directions, 0.0, t_max,
                                     cover, self.offset, cover.opaque)
            return ~self.shadow_bvh.occluded(origins, directions, 0.0, t_max)

    def _visible_linked(self, origins, directions, t_max, group: np.ndarray | None
                        ) -> np.ndarray:
        """`_visible` of shadow rays towards lights of different shadow linking: group (N,)
        int, each ray's light's coverage in `link_covers` (-1: the scene's `shadow_cover`);
        None: every ray the scene's. One BVH call per coverage."""
        if group is None or not self.link_covers:
            return self._visible(origins, directions, t_max)
        out = np.empty(len(origins))
        for g in np.unique(group):
            rows = np.flatnonzero(group == g)
            cover = self.shadow_cover if g < 0 else self.link_covers[g]
            out[rows] = self._visible(origins[rows], directions[rows], t_max[rows], cover)
        return out

    def _hits(self, origins, dirs, t_min, camera: bool, t_max=np.inf,
              refracted: np.ndarray | None = None) -> tuple[Hits, Layers | None]:
        """Closest hits of the rays that see (`camera`: the camera's), and None; in scenes with
        alpha (or objects hidden from the camera), the layers each ray sees through partly
        covered surfaces (`layered_hits`: a surface of coverage a shows a S + (1 - a) T, as
        Cycles blends it) and, as the hits, each ray's front one. refracted (N,) bool, for
        rays past the camera's: which are transmission rays (the others glossy), for objects
        Cycles hides from either (`kind_covers`)."""
        if not camera and refracted is not None and self.kind_covers is not None:
            return self._kind_hits(origins, dirs, t_min, t_max, refracted)
        cover = self.camera_cover if camera else self.bounce_cover
        if cover is None:
            return self.bvh.intersect(origins, dirs, t_min, t_max), None
        layers = layered_hits(self.bvh, origins, dirs, t_min, t_max, cover, self.offset,
                              cover.opaque)
        return layers.front_hits(len(origins)), layers

    def _kind_hits(self, origins, dirs, t_min, t_max, refracted: np.ndarray
                   ) -> tuple[Hits, Layers]:
        """`_hits` of glossy and transmission rays (refracted (N,) bool), each kind through its
        own coverage (`kind_covers`), joined: the front hits of all N and their layers."""
        count = len(origins)
        t_min = np.broadcast_to(np.asarray(t_min, np.float64), (count,))
        t_max = np.broadcast_to(np.asarray(t_max, np.float64), (count,))
        ray, weight, parts = [], [], []
        for flag, cover in zip((False, True), self.kind_covers, strict=True):
            rows = np.flatnonzero(refracted == flag)
            if not rows.size:
                continue
            args = (origins[rows], dirs[rows], t_min[rows], t_max[rows])
            if cover is None:
                hits = self.bvh.intersect(*args)
                ray.append(rows)
                weight.append(np.ones(len(rows)))
            else:
                layers = layered_hits(self.bvh, *args, cover, self.offset, cover.opaque)
                hits = layers.hits
                ray.append(rows[layers.ray])
                weight.append(layers.weight)
            parts.append(hits)
        joined = Hits(*(np.concatenate([getattr(h, name) for h in parts])
                        for name in ("t", "tri", "u", "v")))
        layers = Layers(ray=np.concatenate(ray), weight=np.concatenate(weight), hits=joined)
        return layers.front_hits(count), layers

    def direct(self, h: SurfaceHits, wo: np.ndarray, diffuse_w: np.ndarray, lobes: list,
               strata: Strata | None = None, where: tuple | None = None,
               fabric: Fabric | None = None, sheen: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
        """Light from every light at the hits, shadow rays included: (radiance, lambert), each (N, 3).

        radiance = albedo * lambert + highlights; lambert is the diffuse part for a white base
        colour (diffuse weight (N,) or (N, 3) / pi * sum of shadowed irradiance). lobes: the
        rough glossy lobes lit directly, [(F0 (N, 3), weight (N, 3), roughness (N,))] (a
        specular layer's, a metal's, a coat's), GGX: lamps' and area lights' highlights
        (emissive meshes are met by the lobe's mirror ray instead). strata: each hit's stratum
        and their count m, for area lights (`_area_direct`). where: each hit's triangle (N,) and
        barycentrics (N, 3), when known: a hit whose part of its triangle sees a light whole
        casts no shadow rays to it (`shadow_shafts.py`). fabric: the hits' sheen, lit by lamps
        and emitters as the diffuse base is, its light added to `sheen` (N, 3) (a layer the
        caller weighs on its own).
        """
        out = np.zeros_like(h.p)
        lambert = np.zeros_like(h.p)
        sheen_at = fabric.present if fabric is not None else np.zeros(len(h.p), bool)
        diffuse_w = np.broadcast_to(np.asarray(diffuse_w, np.float64).reshape(len(h.p), -1),
                                    (len(h.p), 3))
        shading = (max_of_three(diffuse_w) > 0) | sheen_at
        for _, weight, _ in lobes:
            shading |= max_of_three(weight) > 0
        if not shading.any():
            return out, lambert
        idx = np.nonzero(shading)[0]
        p, ng, ns, gn = h.p[idx], h.ng[idx], h.ns[idx], h.glossy_normal[idx]
        origin = p + ng * self.offset
        brdf_w = diffuse_w[idx] / np.pi  # white base colour
        smooth = None if h.smooth is None else h.smooth[idx]
        # The lamps light the diffuse base and the lobes that their ray visibility lets them; a
        # world map's suns only the lobes (the world is hidden from diffuse rays in this model,
        # but glossy ones see it).
        lamps = [(light, light.lights_diffuse) for light in self.emitters.lights
                 if light.lights_diffuse or (lobes and light.lights_glossy)]
        lamps += [(sun, False) for sun in self.map_suns] if lobes else []
        tri, bary = (None, None) if where is None else (where[0][idx], where[1][idx])
        areas = len(self.emitters.hulls)  # the shafts' emitters: area emitters, then lamps
        # Every lamp's lit hits first, then all their shadow rays in one BVH call: a call's
        # fixed cost (pool set-up, the traversal's steps) is paid once per depth, not per lamp.
        lit_sets = []  # (light, diffuse, sub (k,), cast (k,) bool, to_l (n, 3), e (n, 3))
        shadow_o, shadow_d, shadow_t, shadow_g = [], [], [], []
        objects = None if h.objects is None else h.objects[idx]
        for k, (light, diffuse) in enumerate(lamps):
            to_l, dist = light_units.light_vectors(light, p)
            e = light_units.direct_irradiance(light, p, ns)  # (n, 3), includes cos and falloff
            reach = light_units.receiving(light, objects)  # light linking
            if reach is not None:
                e *= reach[:, None]
            sub = np.flatnonzero(max_of_three(e) > 0)
            if not len(sub):
                continue
            cast = np.full(len(sub), light.cast_shadow)
            if light.cast_shadow and tri is not None and k < len(self.emitters.lights):
                with self.clock("shafts"):
                    cast &= ~self.shafts.clear(areas + k, tri[sub], bary[sub])
                self.stats.clear_shadow_rays += int(len(sub) - cast.sum())
            lit_sets.append((light, diffuse, sub, cast, to_l, e))
            rays = sub[cast]
            shadow_o.append(origin[rays])
            shadow_d.append(to_l[rays])
            shadow_t.append(np.where(np.isinf(dist[rays]), np.inf, dist[rays] - self.offset))
            shadow_g.append(np.full(len(rays), self.light_cover.get(light, -1)))
        if sum(len(o) for o in shadow_o):
            seen = self._visible_linked(np.concatenate(shadow_o), np.concatenate(shadow_d),
                                        np.concatenate(shadow_t), np.concatenate(shadow_g))
            seen_at = np.cumsum([0] + [len(o) for o in shadow_o])
        for k, (light, diffuse, sub, cast, to_l, e) in enumerate(lit_sets):
            vis = np.ones(len(sub))
            if cast.any():
                vis[cast] = seen[seen_at[k]:seen_at[k + 1]]
            if diffuse:
                # The relief's facets hide part of a low light from the diffuse base (Cycles),
                # taken along each direction a lamp's light comes from (an area lamp whose
                # centre is under the tilted normal's horizon still lights it by its rest); a
                # sheen takes it along the lamp's one direction.
                relief = None
                if smooth is not None and (light.kind != "AREA" or sheen_at[idx[sub]].any()):
                    relief = bump_shadowing(smooth[sub], ns[sub], to_l[sub])[:, None]
                lit_e = e[sub]
                if smooth is not None and light.kind == "AREA":  # per grid sample of the lamp
                    s_sub, n_sub = smooth[sub], ns[sub]
                    lit_e = light_units.direct_irradiance(
                        light, p[sub], n_sub,
                        lambda to, s_sub=s_sub, n_sub=n_sub: bump_shadowing(s_sub, n_sub, to))
                elif smooth is not None:  # one direction: the lamp's
                    lit_e = lit_e * relief
                lambert[idx[sub]] += brdf_w[sub] * lit_e * vis[:, None]
            rows = idx[sub]
            cos_i = np.maximum(np.einsum("ij,ij->i", ns[sub], to_l[sub]), 1e-6)  # e's cosine
            if diffuse and sheen_at[rows].any():
                pick = np.flatnonzero(sheen_at[rows])
                fuzz = fabric.brdf_cos(rows[pick], ns[sub[pick]], to_l[sub[pick]], wo[rows[pick]])
                if relief is not None:
                    fuzz = fuzz * relief[pick]
                sheen[rows[pick]] += fuzz * e[sub[pick]] * (vis[pick] / cos_i[pick])[:, None]
            for f0, weight, rough in (lobes if light.lights_glossy else ()):
                shine = ggx_highlight(gn[sub], to_l[sub], wo[rows], rough[rows], f0[rows])
                out[rows] += shine * e[sub] * weight[rows] * (vis / cos_i)[:, None]
        if len(self.emitters.area_points):
            whole = None  # (n, E) bool: the hit sees area emitter e whole
            if tri is not None:
                with self.clock("shafts"):
                    whole = np.stack([self.shafts.clear(e, tri, bary) for e in range(areas)], 1)
            sub_strata = strata_rows(strata, idx)
            area_lobes = [(f0[idx], weight[idx], rough[idx]) for f0, weight, rough in lobes]
            cloth = (fabric.take(idx), np.zeros((len(idx), 3))) if sheen_at.any() else None
            diffuse, shine = self._area_direct(origin, ns, brdf_w, sub_strata, wo[idx], area_lobes,
                                               smooth, whole, gn, cloth, objects)
            lambert[idx] += diffuse
            out[idx] += shine
            if cloth is not None:
                sheen[idx] += cloth[1]
        out += h.albedo * lambert
        return out, lambert

    def _translucent_direct(self, h: SurfaceHits, wo: np.ndarray, material: np.ndarray,
                            under: np.ndarray | None) -> np.ndarray:
        """(N, 3) light from behind the surface a Translucent BSDF passes (diffuse transmission,
        colour / pi): `direct` of the hits turned around, normals and shadow rays' origins on
        the far side, no lobes; under a coat, what the coat lets through. 0 where no hit is
        translucent."""
        colour = self.translucent[material]
        out = np.zeros_like(h.p)
        on = np.flatnonzero(max_of_three(colour) > 0.0)
        if not len(on):
            return out
        back = SurfaceHits(h.p[on], -h.ng[on], -h.ns[on], ~h.front[on], h.material[on],
                           colour[on], np.zeros((len(on), 3)),
                           objects=None if h.objects is None else h.objects[on])
        light, _ = self.direct(back, wo[on], np.ones(len(on)), [])
        out[on] = light if under is None else light * under[on]
        return out

    def _translucent_gather(self, h: SurfaceHits, material: np.ndarray,
                            under: np.ndarray | None, seeds: np.ndarray) -> np.ndarray:
        """(N, 3) what a Translucent BSDF passes of the light the surfaces behind it reflect:
        TRANSLUCENT_RAYS cosine-distributed rays from each translucent hit's back (a lattice
        per hit, shifted by a hash of seeds (N, 3): its pixel), each meeting a surface whose
        diffuse part the lamps light (`direct`), times colour / rays; under a coat, what the
        coat lets through. Cycles' Whitted model follows a translucent bounce (a transmission
        bounce): it sees what the lamps light behind a leaf (a floor), not the world (hidden
        from diffuse-type rays) nor emitters (met by light sampling: `_translucent_direct`)."""
        colour = self.translucent[material]
        out = np.zeros_like(h.p)
        on = np.flatnonzero(max_of_three(colour) > 0.0)
        if not len(on):
            return out
        which, points = lobe_points(np.full(len(on), TRANSLUCENT_RAYS), seeds[on])
        back = -h.ns[on]
        t1, t2 = tangent_frames(back)
        dirs = cosine_lift((t1[which], t2[which], back[which]), points[:, 0], points[:, 1])
        rows = np.flatnonzero(np.einsum("ij,ij->i", dirs, h.ng[on][which]) < 0.0)  # behind it
        origins = h.p[on][which[rows]] - h.ng[on][which[rows]] * self.offset
        hits, _ = self._hits(origins, dirs[rows], 0.0, camera=False)
        met = np.flatnonzero(hits.tri >= 0)
        if not len(met):
            return out
        hits = type(hits)(t=hits.t[met], tri=hits.tri[met], u=hits.u[met], v=hits.v[met])
        seen = surface_at(self.scene, self.tri_normals, origins[met], dirs[rows[met]], hits,
                          self.settings.shading)
        mm = seen.material
        dielectric = (1.0 - self.metallic[mm]) * (1.0 - self.transmission[mm])
        wo = -dirs[rows[met]]
        diffuse_w = dielectric * view_factors(self.layer_tables, mm,
                                              np.einsum("ij,ij->i", wo, seen.ns))
        light, _ = self.direct(seen, wo, diffuse_w, [])
        gathered = np.zeros((len(on), 3))
        _scatter_add(gathered, which[rows[met]], light)
        out[on] = colour[on] * gathered / TRANSLUCENT_RAYS
        return out if under is None else out * under

    def _fabric(self, tri: np.ndarray, bary: np.ndarray, material: np.ndarray) -> Fabric | None:
        """The sheen at hits (triangles (N,), barycentrics (N, 3), materials (N,)): colour and
        roughness from the materials' textures where they have them (`material_values`), else
        their constants; None where no hit has a sheen."""
        if not self.has_sheen[material].any():
            return None
        tint = material_values(self.scene, tri, bary, lambda m: m.sheen_tint_texture,
                               lambda m: m.sheen_tint)
        rough = material_values(self.scene, tri, bary, lambda m: m.sheen_roughness_texture,
                                lambda m: np.full(3, m.sheen_roughness))[:, 0]
        return Fabric(color=self.sheen_weight[material][:, None] * np.clip(tint, 0.0, None),
                      roughness=np.clip(rough, 0.0, 1.0), velvet=self.velvet[material],
                      layer=self.sheen_layer[material])

    def gouraud_direct(self, h: SurfaceHits, hits, eye: np.ndarray, diffuse_w, lobes,
                       strata: Strata | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Gouraud (per-vertex) shading: `direct` evaluated at the hit triangle's three corners,
        with their own normals, shadow rays and view directions (towards `eye`, each ray's
        origin), then interpolated with the hit's barycentrics. The base colour stays per
        fragment (a texture modulates the interpolated light), as in fixed-function OpenGL."""
        corners = self.scene.triangles[hits.tri].astype(np.float64)  # (N, 3, 3)
        normals = self.scene.normals[hits.tri].astype(np.float64)
        side = np.where(h.front, 1.0, -1.0)[:, None]
        u = hits.u.astype(np.float64)
        v = hits.v.astype(np.float64)
        weights = (1.0 - u - v, u, v)
        lit, lambert = np.zeros_like(h.p), np.zeros_like(h.p)
        for k, w in enumerate(weights):
            p = corners[:, k]
            n = normals[:, k] * side
            n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), MIN_NORMAL_LENGTH)
            wo = eye - p
            wo /= np.maximum(np.linalg.norm(wo, axis=1, keepdims=True), 1e-12)
            corner = SurfaceHits(p, h.ng, n, h.front, h.material, h.albedo, h.emission,
                                 objects=h.objects)
            lit_k, lambert_k = self.direct(corner, wo, diffuse_w, lobes, strata,
                                           (hits.tri, np.broadcast_to(np.eye(3)[k], (len(p), 3))))
            lit += w[:, None] * lit_k
            lambert += w[:, None] * lambert_k
        return lit, lambert

    def _area_direct(self, origin, ns, brdf_d, strata: Strata | None = None, wo=None,
                     lobes: tuple | list = (), smooth=None, whole=None,
                     glossy=None, sheen: tuple | None = None, objects: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
        """Light from area lights and emissive triangles: every emitter sample against every hit,
        EMITTER_BLOCK samples at a time, with one batch of shadow rays per block. Returns the
        diffuse part (N, 3) (brdf_d weighted) and the area lights' highlights in the glossy
        `lobes` (as `direct`'s; view directions wo (N, 3)). smooth (N, 3), when
        given: the normals before the relief, for the diffuse part's bump shadowing.

        strata (stratum (N,), m): the hits are m sub-samples of their pixels, and a hit in
        stratum k takes only its emitters' samples j with j = k (mod m), weighted m: the pixel's
        m sub-samples share out each emitter's stratified samples instead of each casting all
        of them (m times fewer shadow rays for the same samples per pixel). Emitters whose
        sample count m does not divide keep every sample for every hit. whole (N, E) bool, when
        given: hit n sees emitter e whole (`shadow_shafts.py`) and casts no shadow rays to it.
        glossy (N, 3): the normals the lobes turn about (`SurfaceHits.spec`); None: ns.
        sheen: (Fabric of the N hits, out (N, 3)): the sheen's light is added to out.
        objects (N,): the hits' objects, for the area lamps' light linking (None: unknown).

        A hit closer to a mesh light's sample than REFINE_REACH x its patch's size takes the
        sample's FINE_SPLIT finer ones instead (`emitters.mesh_light_samples`).
        """
        em = self.emitters
        glossy = ns if glossy is None else glossy
        out = np.zeros_like(origin)
        shine = np.zeros_like(origin)
        if strata is not None and strata[1] > 1:
            stratum, m = strata
            shared = em.area_count % m == 0  # (S,)
            keep = ~shared[:, None] | (em.area_local[:, None] % m == stratum[None, :] % m)
            scale = np.where(shared, float(m), 1.0)  # (S,)
        else:
            keep, scale = None, None

        def light(n_idx, to_l, dist, g, radiance_da, emitter, lamp, spread=None) -> None:
            """Adds the light of emitter samples to hits n_idx (P,): the pairs' unit directions
            (P, 3) and distances (P,) to the sample, geometry terms g (P,), the samples'
            radiance x area (P, 3), emitters (P,) and whether each is an area lamp (P,);
            spread (P,) rad: the samples' angular radii, which widen the lamps' highlights
            (`highlight_spread.sample_roughness`)."""
            if self.reach.objects is not None and objects is not None:  # light linking
                keep = np.flatnonzero(self.reach.objects[emitter, objects[n_idx]])
                n_idx, to_l, dist, g, radiance_da, emitter, lamp = (
                    x[keep] for x in (n_idx, to_l, dist, g, radiance_da, emitter, lamp))
                spread = None if spread is None else spread[keep]
            vis = np.ones(len(n_idx))
            cast = np.arange(len(n_idx)) if whole is None else np.flatnonzero(
                ~whole[n_idx, emitter])
            self.stats.clear_shadow_rays += len(n_idx) - len(cast)
            if len(cast):
                vis[cast] = self._visible_linked(origin[n_idx[cast]], to_l[cast],
                                                 dist[cast] * (1.0 - 1e-4) - self.offset,
                                                 self.reach.cover[emitter[cast]])
            weight = radiance_da * (g * vis)[:, None]
            relief = 1.0 if smooth is None else bump_shadowing(smooth[n_idx], ns[n_idx], to_l)[:, None]
            diffuse_on = self.reach.diffuse[emitter][:, None]  # the lamp's ray visibility
            _scatter_add(out, n_idx, brdf_d[n_idx] * weight * relief * diffuse_on)
            if sheen is not None:  # every emitter lights a sheen, as it does the base
                fabric, sheen_out = sheen
                pick = np.flatnonzero(fabric.present[n_idx])
                if pick.size:
                    rows, l_dir = n_idx[pick], to_l[pick]
                    cos_r = np.maximum(np.einsum("ij,ij->i", ns[rows], l_dir), 1e-6)
                    fuzz = fabric.brdf_cos(rows, ns[rows], l_dir, wo[rows])
                    fuzz = fuzz * (relief if np.isscalar(relief) else relief[pick])
                    _scatter_add(sheen_out, rows,
                                 fuzz * weight[pick] * diffuse_on[pick] / cos_r[:, None])
            for f0, w, rough in lobes:  # area lamps only: no rough lobe's ray meets them
                pick = np.flatnonzero(lamp & self.reach.glossy[emitter]
                                      & (max_of_three(w[n_idx]) > 0.0))
                if pick.size:
                    rows, l_dir = n_idx[pick], to_l[pick]
                    r = sample_roughness(rough[rows], None if spread is None else spread[pick])
                    brdf_cos = ggx_highlight(glossy[rows], l_dir, wo[rows], r, f0[rows])
                    cos_r = np.maximum(np.einsum("ij,ij->i", ns[rows], l_dir), 1e-6)
                    _scatter_add(shine, rows, brdf_cos * weight[pick] * w[rows] / cos_r[:, None])

        refined = []  # (sample (P,), hit (P,)): the pairs that take the sample's finer ones
        for first in range(0, len(em.area_points), EMITTER_BLOCK):
            block = slice(first, first + EMITTER_BLOCK)
            delta = em.area_points[block][:, None, :] - origin[None, :, :]  # (B, N, 3)
            to_l, dist, d2, g = _emitter_geometry(delta, ns, em.area_normals[block][:, None],
                                                  em.area_two_sided[block][:, None],
                                                  em.area_da[block][:, None])
            if keep is not None:
                g = g * keep[block] * scale[block][:, None]
            near = ((d2 < REFINE_REACH ** 2 * em.area_da[block][:, None])
                    & (em.fine_count[block] > 0)[:, None])
            if near.any():
                if keep is not None:
                    near &= keep[block]
                g = np.where(near, 0.0, g)
                b_near, n_near = np.nonzero(near)
                refined.append((first + b_near, n_near))
            b_idx, n_idx = np.nonzero(g > 0)
            if len(n_idx):
                l_dir, reach = to_l[b_idx, n_idx], dist[b_idx, n_idx]
                light(n_idx, l_dir, reach, g[b_idx, n_idx], em.area_radiance_da[block][b_idx],
                      em.area_emitter[block][b_idx], ~em.area_two_sided[block][b_idx],
                      light_units.sample_radius(em.area_da[block][b_idx],
                                                row_dot(l_dir, em.area_normals[block][b_idx]),
                                                reach))
        if refined:  # each sample's finer ones, FINE_SPLIT a pair, for the hits near it
            parent = np.repeat(np.concatenate([r[0] for r in refined]), FINE_SPLIT)
            n_idx = np.repeat(np.concatenate([r[1] for r in refined]), FINE_SPLIT)
            kids = em.fine_first[parent] + np.tile(np.arange(FINE_SPLIT), len(parent) // FINE_SPLIT)
            to_l, dist, _, g = _emitter_geometry(em.fine_points[kids] - origin[n_idx], ns[n_idx],
                                                 em.fine_normals[kids], em.area_two_sided[parent],
                                                 em.fine_da[kids])
            if scale is not None:
                g = g * scale[parent]
            lit = np.flatnonzero(g > 0)
            light(n_idx[lit], to_l[lit], dist[lit], g[lit], em.fine_radiance_da[kids[lit]],
                  em.area_emitter[parent[lit]], ~em.area_two_sided[parent[lit]])
        return out, shine

    def _world_unseen(self, depth: int, refracted: np.ndarray) -> np.ndarray:
        """(N,) bool: escaping rays of this depth (refracted (N,): each last refracted) that
        Cycles hides the world from (`Scene.world_hidden_from`): the primary rays by their
        kind (`primary_kind`), later ones as transmission or glossy rays."""
        hidden = self.scene.world_hidden_from
        if depth == 0:
            return np.full(len(refracted), self.primary_kind in hidden)
        return np.where(refracted, "transmission" in hidden, "glossy" in hidden)

    def _mapped(self, tri: np.ndarray) -> np.ndarray:
        """(N,) bool: which hit triangles belong to an environment-mapped object."""
        return np.isin(self.scene.object_ids[tri], list(self.environment))

    def _environment(self, tri: np.ndarray, p: np.ndarray, r_dir: np.ndarray,
                     mirror_w: np.ndarray, normals: np.ndarray | None = None,
                     diffuse_rgb: np.ndarray | None = None) -> np.ndarray:
        """(N, 3) radiance the mirror part reflects off environment-mapped objects (0 elsewhere):
        the mirror weight times the object's map read for the reflected ray (hit point p, r, the
        surface's roughness), plus, on mirrors, the area lamps the ray meets unshadowed (a rough
        surface's lamps are its highlights, `direct`); and with a look-up's `irradiance`, the
        diffuse reflectance `diffuse_rgb` (N, 3) / pi times the irradiance along `normals`.
        The maps hold the scene's surfaces only: a lamp, small and bright, smeared over a few
        texels and shifted by the look-up's parallax shows as a misplaced blob (env_room's ceiling
        panel read from the map has about five times the error of the panel added here); one
        occlusion ray per mirror point that meets a lamp shows it exactly."""
        out = np.zeros_like(mirror_w)
        objects = self.scene.object_ids[tri]
        rough = self.roughness[self.scene.material_ids[tri]]
        for k, lookup in self.environment.items():
            lit = getattr(lookup, "irradiance", None)
            if lit is not None and normals is not None and diffuse_rgb is not None:
                rows = np.nonzero((objects == k) & (max_of_three(diffuse_rgb) > 0.0))[0]
                if len(rows):
                    out[rows] += diffuse_rgb[rows] * lit(p[rows], normals[rows]) / np.pi
            rows = np.nonzero((objects == k) & (max_of_three(mirror_w) > 0.0))[0]
            if len(rows):
                out[rows] += mirror_w[rows] * lookup(p[rows], r_dir[rows], rough[rows])
                rows = rows[rough[rows] < self.settings.mirror_roughness]
                if self.mirror_lamps and len(rows):
                    lamp, t = light_units.area_lamps_seen(self.mirror_lamps, p[rows], r_dir[rows],
                                                          np.full(len(rows), np.inf))
                    meet = np.flatnonzero(np.isfinite(t))
                    if meet.size:
                        at = rows[meet]
                        vis = self._visible(p[at] + r_dir[at] * self.offset, r_dir[at],
                                            t[meet] - 2.0 * self.offset)
                        out[at] += mirror_w[at] * lamp[meet] * vis[:, None]
        return out

    def hit_ids(self, tri: np.ndarray, materials: np.ndarray | None = None) -> np.ndarray:
        """Object * (materials + 1) + material of each hit triangle (`materials` (N,): the hits'
        own, else the triangles'); -1 where nothing was hit."""
        ids = np.full(len(tri), -1, np.int64)
        hit = tri >= 0
        t = tri[hit]
        material = self.scene.material_ids[t] if materials is None else materials[hit]
        ids[hit] = (self.scene.object_ids[t].astype(np.int64) * (len(self.scene.materials) + 1)
                    + material)
        return ids

    def attribute_hits(self, ids: np.ndarray) -> np.ndarray:
        """(N,) bool: which `hit_ids` saw a material whose base colour is a colour attribute."""
        materials = np.maximum(ids, 0) % (len(self.scene.materials) + 1)
        return (ids >= 0) & self.attribute_base[materials]

    # --- the wavefront ---------------------------------------------------------------------------

    def radiance(self, origins: np.ndarray, dirs: np.ndarray,
                 primary_ids: np.ndarray | None = None, footprint: Footprint | None = None,
                 untextured: np.ndarray | None = None, strata: Strata | None = None,
                 seeds: np.ndarray | None = None,
                 primary_t: np.ndarray | None = None,
                 reach: np.ndarray | None = None) -> np.ndarray:
        """`_radiance`, its time outside the named phases counted as bookkeeping."""
        with self.clock("bookkeeping"):
            return self._radiance(origins, dirs, primary_ids, footprint, untextured, strata,
                                  primary_t, seeds, reach)

    @property
    def frames(self) -> rd.TriangleFrames:
        """The triangles' frames for ray differentials, built when first needed."""
        if self._frames is None:
            self._frames = rd.TriangleFrames(self.scene)
        return self._frames

    def _medium_transmittance(self, dirs: np.ndarray, hits) -> np.ndarray:
        """(N, 3) what each ray keeps of the medium it crossed to reach its hit (Beer-Lambert,
        exp(-absorption t), t in metres): a ray that meets a back face was inside that mesh
        (closed meshes assumed, as for `entered`); 1 for rays that hit a front face."""
        tri = hits.tri
        leaving = np.einsum("ij,ij->i", dirs, self.tri_normals[tri]) > 0.0
        sigma = self.absorption[self.scene.material_ids[tri]] * leaving[:, None]
        return np.exp(-sigma * hits.t.astype(np.float64)[:, None])

    def _lobe_rays(self, child: tuple, strong: np.ndarray, h: SurfaceHits, wo: np.ndarray,
                   rough: np.ndarray, lobe_w: np.ndarray, diffuse: np.ndarray,
                   seeds: np.ndarray | None = None, strata: Strata | None = None,
                   eta: np.ndarray | None = None) -> tuple:
        """The reflected generation `child` (origins, dirs, pixel, weight, sharp, entered, blur[,
        dp, dd]: the rays of hits `strong` (N,) bool) with each rough hit's mirror ray replaced by
        rays across its GGX lobe (`glossy_lobe.py`), sharing the ray's weight in proportion to
        their shadowing (`shadowing_weights`), each with the mirror ray's origin and differentials;
        and (pixel (M,), radiance (M, 3)) each such hit's pixel takes besides its rays
        (`_lobe_sky_mean`), None for an albedo.
        eta (N,), when given: the generation is refracted, a rough glass's; its rays cross the
        transmission lobe (`lobe_refractions`), each hit's normalised by their own sum, with
        no sky correction.

        A lobe of albedo lobe_w (N, 3) over a diffuse reflectance `diffuse` (N, 3) takes
        ceil(share x lobe_rays) rays, share its largest part of the two in any channel: a metal
        all of them, a faint layer over a white base one, the same layer over a saturated red
        most (its green and blue are the lobe's). seeds (N, 3), when given: each hit's pixel,
        whose hash shifts its points (else the hit's position); strata (stratum (N,), m): the
        hits are m sub-samples of their pixels, which draw SUBSAMPLE_LOBE_SHARE times the
        pixel's count between them from one stratified set. A whole pixel's hit none of whose
        rays leaves keeps its mirror ray; a sub-sample's gives its part of the lobe's none."""
        s = self.settings
        rows = np.flatnonzero(strong)
        share = lobe_w[rows] / np.maximum(lobe_w[rows] + diffuse[rows], 1e-12)
        whole = np.clip(np.ceil(max_of_three(share) * s.lobe_rays), 1, s.lobe_rays)
        many = np.flatnonzero((whole > 1) & (rough[rows] >= s.mirror_roughness))  # in `child`
        if not len(many):
            return child, None
        parts = 1 if strata is None else int(strata[1])
        count = np.clip(np.ceil(whole[many] * min(SUBSAMPLE_LOBE_SHARE / parts, 1.0)), 1,
                        whole[many]).astype(np.int64)
        at = rows[many]
        seeds = np.array(h.p[at] if seeds is None else seeds[at], np.float64)
        part = None if parts == 1 else strata[0][at]
        which, points = lobe_points(count, seeds, part, parts)
        if part is not None:  # the mean's directions: a whole lobe per sub-sample, own offset
            seeds[:, 2] += part
        if eta is None:
            dirs, g = lobe_rays(h.glossy_normal[at], wo[at], h.ng[at], rough[at], points, which)
        else:
            dirs, g = lobe_refractions(h.glossy_normal[at], wo[at], h.ng[at], rough[at], eta[at],
                                       points, which)
        above = g > 0.0
        leaving = np.bincount(which[above], minlength=len(many))
        new = above & (leaving[which] > 0)
        sky = s.output != "albedo" and eta is None
        own_sums = part is None or eta is not None
        mean, albedo = self._lobe_sky_mean(h, wo, rough, at, count, seeds, not own_sums, sky)
        # Each ray's share of the lobe (`glossy_lobe.py`): its shadowing over its lobe's sum; a
        # sub-sample's rays, its part of the pixel's lattice, over the sum the whole lobe's
        # albedo with F = 1 gives (count x albedo, from the mean's many directions): normalised
        # part by part, the parts whose rays leave the surface less would weigh as much as the
        # others.
        if own_sums:
            share_w = g / np.maximum(np.bincount(which, g, minlength=len(many)), 1e-300)[which]
        else:
            share_w = g / np.maximum(count * albedo, 1e-300)[which]
            # A sub-sample stands for its part of the lobe, with rays or none: its mirror ray
            # instead, where no ray of a part left the surface, left a rough metal floor under a
            # wall 17% dark at 4 x 4 sub-samples.
            new = above
        source = many[which[new]]  # the mirror ray each new ray stands in for
        kept = np.ones(len(rows), bool)
        kept[many[leaving > 0] if own_sums else many] = False
        fields = [child[0][source], dirs[new], child[2][source],
                  child[3][source] * share_w[new][:, None], child[4][source],
                  child[5][source], np.zeros(len(source))]  # across the lobe: no blur
        out = [np.concatenate([old[kept], field]) for old, field in zip(child[:7], fields, strict=True)]
        for old in child[7:]:  # ray differentials (2, n, 3)
            out.append(np.concatenate([old[:, kept], old[:, source]], axis=1))
        self.stats.lobe_rays += int(new.sum())
        correction = None
        if sky:
            # What the traced rays would bring did all of them escape, against the sky's mean
            # over the lobe (`_lobe_sky_mean`).
            traced = np.zeros((len(many), 3))
            np.add.at(traced, which[new], self._lobe_sky(dirs[new]) * share_w[new][:, None])
            lit = np.flatnonzero(leaving > 0) if part is None else np.arange(len(many))
            correction = (child[2][many[lit]], child[3][many[lit]] * (mean[lit] - traced[lit]))
        return tuple(out), correction

    @staticmethod
    def _facet_rays(rough_glass: np.ndarray, h: SurfaceHits, dirs: np.ndarray, wo: np.ndarray,
                    rough: np.ndarray, eta: np.ndarray, cos_o: np.ndarray, r_dir: np.ndarray,
                    t_dir: np.ndarray, tir: np.ndarray, depth: int) -> np.ndarray:
        """In place, at the hits `rough_glass` (N,) bool: the reflected and refracted directions
        r_dir, t_dir (N, 3) and total internal reflection tir (N,) about one microfacet normal
        drawn from the glass's lobe (`ggx_microfacets`, at a point hashed from the hit and the
        depth) instead of the surface's; returns the cosines (N,) Fresnel takes, the view's with
        that facet there (else cos_o). Where either direction would leave on the wrong side of
        the surface the hit keeps its smooth directions.

        A ray inside a rough glass ball, sent across the lobe at the camera's hit, left it
        through a smooth surface: past the critical angle all of it reflected inside, where
        Cycles' facets let part of it out (the ball 5-10% dark)."""
        cos_f = cos_o.copy()
        rows = np.flatnonzero(rough_glass)
        if not rows.size:
            return cos_f
        which, points = lobe_points(np.ones(len(rows), np.int64), h.p[rows] + depth)
        micro, _ = ggx_microfacets(h.glossy_normal[rows], wo[rows], rough[rows], points, which)
        t_m, tir_m = refract(dirs[rows], micro, eta[rows])
        r_m = reflect(dirs[rows], micro)
        fits = ((np.einsum("ij,ij->i", r_m, h.ng[rows]) > 0.0)
                & (tir_m | (np.einsum("ij,ij->i", t_m, h.ng[rows]) < 0.0)))
        at, micro = rows[fits], micro[fits]
        r_dir[at], t_dir[at], tir[at] = r_m[fits], t_m[fits], tir_m[fits]
        cos_f[at] = np.einsum("ij,ij->i", wo[at], micro)
        return cos_f

    def _lobe_sky(self, dirs: np.ndarray) -> np.ndarray:
        """(N, 3) the control variate's function of a rough lobe's ray directions dirs (N, 3)
        (`_lobe_sky_mean`): the world colour, or the map without its suns (their light is the
        lobes' highlights) above the horizon (+Z up) and 0 below, where the ground a scene
        stands on hides it; either is what such a ray brings if it escapes there."""
        return horizon_sky(self.sky_scene, dirs)

    def _lobe_sky_mean(self, h: SurfaceHits, wo: np.ndarray, rough: np.ndarray, at: np.ndarray,
                       count: np.ndarray, seeds: np.ndarray, albedo: bool, sky: bool
                       ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """For the GGX lobes of hits `at` (N,): (N, 3) `_lobe_sky` averaged over each (None when
        not `sky`), and (N,) its albedo with F = 1 (None when not `albedo`). The world colour
        itself, or a map's mean over MEAN_FACTOR x count (N,) directions each (a lattice
        shifted by a hash of seeds (N, 3)), weighted by their shadowing as the traced rays are
        and normalised by the weights' sum (a uniform sky's light exactly), whose mean is the
        albedo.

        A lobe's few traced rays read a photographed sky's detail, and their weights' spread, as
        noise. Each hit takes this mean plus what its traced rays brought less what `_lobe_sky`
        gives along the same directions (a control variate, unbiased whatever the function):
        nothing for a ray that escapes, so where nothing hides the sky the noise is the mean's,
        of many directions that cost a map read each and no traversal. A blocked ray adds what
        it met less the function there, which is why the map counts above the horizon only:
        under it a scene's ground hides the map's ground, often as bright as its sky, and
        subtracting that made the noise larger, not smaller (a rough metal dice on a floor
        under a studio map: relMSE 3.9e-2 against Cycles, 4.6e-3 with the horizon)."""
        mapped = sky and self.scene.world_texture is not None
        mean = self._lobe_sky(np.zeros((len(at), 3))).copy() if sky and not mapped else None
        if not (mapped or albedo):
            return mean, None
        sampled, weight = lobe_mean(self._lobe_sky if mapped else None, h.glossy_normal[at],
                                    wo[at], h.ng[at], rough[at], count * MEAN_FACTOR, seeds)
        return (sampled if mapped else mean), (weight if albedo else None)

    def _child_differentials(self, spawned, tri, h: SurfaceHits, dirs, t_dir, eta, rows, dp, dd):
        """Per spawned generation (strong (N,) bool: the rays spawned; side +1 reflected, -1
        refracted; bent (N,) bool: the ray turned about the normal `about` (N, 3), the geometric
        one or one bent towards it, not the shading normal), its rays' (dp, dd)
        (2, n, 3) each. rows (R,): the hits that spawn any, whose derivatives dp (the hit's) and
        dd (the arriving ray's) are (2, R, 3)."""
        if self.settings.shading == "flat":
            dn = np.zeros((2, len(rows), 3))  # the shading normal's change at those rows
        else:
            dn = rd.normal_derivatives(self.frames, tri[rows], h.ns[rows],
                                       np.maximum(h.normal_length[rows], MIN_NORMAL_LENGTH),
                                       np.where(h.front[rows], 1.0, -1.0), dp)
        out = []
        for strong, side, bent, about in spawned:
            own = strong[rows]  # strong's rows, in order, among rows
            n = (h.glossy_normal if side > 0 else h.ns)[strong]
            dn_k, dd_k = dn[:, own], dd[:, own]
            turned = bent[strong]
            if turned.any():  # turned about a normal taken as not turning across the pixel
                n[turned], dn_k[:, turned] = about[strong][turned], 0.0
            if side > 0:
                dd_k = rd.reflected(dirs[strong], n, dd_k, dn_k)
            else:
                dd_k = rd.refracted(dirs[strong], n, eta[strong], t_dir[strong], dd_k, dn_k)
            out.append((dp[:, own], dd_k))
        return out

    def _radiance(self, origins: np.ndarray, dirs: np.ndarray,
                  primary_ids: np.ndarray | None = None, footprint: Footprint | None = None,
                  untextured: np.ndarray | None = None, strata: Strata | None = None,
                  primary_t: np.ndarray | None = None,
                  seeds: np.ndarray | None = None,
                  reach: np.ndarray | None = None) -> np.ndarray:
        """Radiance (N, 3) arriving at the camera along N primary rays (reach (N,), when given:
        how far each may meet a surface, the camera's far clip, `camera_reach`).

        primary_ids: optional (N,) int64 filled with what each camera ray hit (object and
        material, -1 for the background), for edge detection without tracing twice.
        footprint: each ray's cell of the image; the base colour seen directly is then the
        texture's mean over the cell (`filtered_albedo`), not its value at the ray's point, and
        the base colour seen in mirrors and through glass its mean over the cell's image there
        (ray differentials, `footprint_albedo`).
        untextured: optional (N, 3) filled with the same radiance but a white base colour at the
        hits whose textures are filtered: what edge detection compares, so texture detail
        (filtered) is no edge.
        strata: (stratum (N,), m) when the rays are m sub-samples of pixels: area lights' samples
        are shared out among them (`_area_direct`).
        primary_t: optional (N,) filled with each primary ray's hit distance (inf: none).
        seeds: optional (N, 3) per ray, its pixel (column, row, 0): what the points of a rough
        lobe's rays are shifted by (`_lobe_rays`), the same for a pixel's sub-samples.
        Area lamps are invisible to the primary rays and to rough lobes' rays, visible to rays
        off smooth surfaces (Cycles' lamps: invisible to camera rays, visible to glossy and
        transmission rays; a rough lobe's lamps are its highlights, from `direct`).
        """
        s = self.settings
        result = np.zeros((len(origins), 3))
        flat = untextured if untextured is not None else np.zeros((0, 3))
        flat[...] = 0.0
        pixel = np.arange(len(origins))
        weight = np.ones((len(origins), 3))
        t_min = np.zeros(len(origins))
        # Whether a ray's path so far bounced off smooth surfaces only: those rays see area lamps
        # (camera rays do not: Cycles' lamps are not drawn). A rough lobe's one ray does not (its
        # lamps' highlights come from `direct`, which would count them twice), nor do rays past
        # it: a mirror's sharp image of a lamp would be a hot spot that Cycles' lobe blurs over
        # the surface.
        sharp = np.ones(len(origins), bool)
        # Whether a ray was last refracted (Cycles' transmission ray) rather than reflected: for
        # the world's ray visibility (`_world_unseen`).
        refracted = np.zeros(len(origins), bool)
        # The roughness of the lobe a ray stands for alone (0: none): a rough surface's one
        # reflected ray, and the rays after it. Escaping, it reads the world's map averaged over
        # that lobe (`world_lobes.py`), as Cycles' many rays across the lobe see it.
        blur = np.zeros(len(origins))
        # Solids a ray is inside of: +1 through a front face's refraction, -1 through a back
        # face's; -1 for "unknown" (a back face met from outside: an open or inverted mesh).
        # At 0 the ray is on the camera's side (`DiffuseLookup`), closed meshes assumed.
        entered = np.zeros(len(origins), np.int32)
        # Ray differentials (per image pixel) where textures are filtered: the textures seen in
        # mirrors and through glass are then filtered over the pixel's footprint too.
        follow = footprint is not None and bool(self.textured.any())
        dp = dd = None  # (2, N, 3): each ray's origin and direction change across the image
        self.stats.camera_rays += len(origins)
        # Lamps light the hits of up to max_depth bounces; the rays of one bounce more still see
        # what shines (emitters, area lamps, the world), as Cycles' path after its last allowed
        # bounce does (Cycles' kernel allows Max Bounces + 1 and lights no hit past the limit).
        for depth in range(s.max_depth + 2):
            if len(origins) == 0:
                break
            self.clock.label = f"{self.pass_name} depth {depth}"
            self.stats.rays_per_depth.append(len(origins))
            if depth > 0:
                self.stats.secondary_rays += len(origins)
            with self.clock("traversal"):
                hits, layers = self._hits(origins, dirs, t_min, camera=depth == 0,
                                          t_max=reach if depth == 0 and reach is not None
                                          else np.inf, refracted=refracted)
            if depth == 0 and primary_ids is not None:
                primary_ids[...] = self.hit_ids(hits.tri)
            if depth == 0 and primary_t is not None:
                primary_t[...] = np.where(hits.tri < 0, np.inf, hits.t)
            front = None  # (N,) bool, with layers: the entries that are their ray's front one
            if layers is not None:  # a ray per surface it sees, weighted by what reaches it
                src, front = layers.ray, layers.first()
                origins, dirs, pixel, sharp, entered, blur, refracted = (
                    origins[src], dirs[src], pixel[src], sharp[src], entered[src], blur[src],
                    refracted[src])
                weight, t_min = weight[src] * layers.weight[:, None], t_min[src]
                if follow and 0 < depth <= s.max_depth:
                    dp, dd = dp[:, src], dd[:, src]
                hits = layers.hits
            miss = hits.tri < 0
            if depth > 0 and sharp.any() and self.mirror_lamps:
                rows = np.flatnonzero(sharp)
                lamps, _ = light_units.area_lamps_seen(self.mirror_lamps, origins[rows], dirs[rows],
                                                       np.where(miss[rows], np.inf, hits.t[rows]))
                _scatter_add(result, pixel[rows], weight[rows] * lamps)
            # the world as this depth's rays see it (the primary rays' own map, `world_seen_by`)
            seen_by = world_seen_by(self.scene, self.primary_kind) if depth == 0 else self.scene
            if s.output == "albedo":
                background = 0.0
            elif seen_by.world_texture is None:
                background = seen_by.world_color
            else:  # the world's map along each escaping ray; a rough lobe's ray (off no smooth
                # surface) reads it without the suns that the lobes' highlights already carry,
                # averaged over the lobe where it stands for a whole one
                escaped, lobe = dirs[miss], blur[miss]
                rough_ray = ~sharp[miss] if depth > 0 else np.zeros(len(escaped), bool)
                wide = lobe > 0.0
                background = np.empty((len(escaped), 3))
                background[~rough_ray] = world_radiance(seen_by, escaped[~rough_ray])
                one = rough_ray & ~wide
                background[one] = world_radiance(self.sky_scene, escaped[one])
                background[wide] = (0.0 if self.world_lobes is None
                                    else self.world_lobes.radiance(escaped[wide], lobe[wide]))
            if self.scene.world_hidden_from:  # Cycles' world ray visibility
                background = np.where(self._world_unseen(depth, refracted[miss])[:, None], 0.0,
                                      background)
            _scatter_add(result, pixel[miss], weight[miss] * background)
            if untextured is not None:
                _scatter_add(flat, pixel[miss], weight[miss] * background)
            keep = ~miss
            origins, dirs, pixel, weight = origins[keep], dirs[keep], pixel[keep], weight[keep]
            sharp, entered, blur, refracted = sharp[keep], entered[keep], blur[keep], refracted[keep]
            if front is not None:
                front = front[keep]
            if follow and 0 < depth <= s.max_depth:
                dp, dd = dp[:, keep], dd[:, keep]
            hits = type(hits)(t=hits.t[keep], tri=hits.tri[keep], u=hits.u[keep], v=hits.v[keep])
            if len(origins) == 0:
                break
            if self.absorption is not None:  # what the medium it crossed left of the ray
                weight = weight * self._medium_transmittance(dirs, hits)
            u, v = hits.u.astype(np.float64), hits.v.astype(np.float64)
            bary = np.stack([1.0 - u - v, u, v], axis=1)
            if depth > s.max_depth:  # one bounce past the limit: emission only, nothing lit
                with self.clock("surface"):
                    shine = weight * emission_at(self.scene, hits.tri, bary)
                _scatter_add(result, pixel, shine)
                if untextured is not None:
                    _scatter_add(flat, pixel, shine)
                m = self.scene.material_ids[hits.tri]
                self.stats.depth_limited += int(np.count_nonzero(
                    ((self.roughness[m] < s.mirror_roughness) & (self.transmission[m] > 0))
                    | (self.metallic[m] > 0) | (self.specular[m] > 0)))
                break
            with self.clock("surface"):
                h = surface_at(self.scene, self.tri_normals, origins, dirs, hits, s.shading)
            m = h.material
            if depth == 0 and primary_ids is not None and self.scene.map_variants:
                # the variant a metallic / roughness map gives each hit: where it changes
                # inside a triangle (a metal trim), the edge pass samples the pixel again
                at = slice(None) if front is None else front
                primary_ids[pixel[at]] = self.hit_ids(hits.tri[at], m[at])
            if follow and depth > 0:  # the hit's derivatives, carried from the ray's origin
                with self.clock("differentials"):
                    dp = plane_transfer(dp, dd, dirs, hits.t.astype(np.float64), h.ng)
            if footprint is not None:
                textured = self.textured[m]
                if textured.any():
                    rows = np.nonzero(textured)[0]
                    with self.clock("texture filter"):
                        if depth == 0:
                            h.albedo[rows] = filtered_albedo(self.scene, hits.tri[rows], bary[rows],
                                                              footprint, pixel[rows])
                        else:
                            h.albedo[rows] = footprint_albedo(
                                self.scene, hits.tri[rows], bary[rows], dp[:, rows],
                                self.frames.grad[hits.tri[rows]], footprint.cell, footprint.grid)
            metallic, trans, rough = self.metallic[m], self.transmission[m], self.roughness[m]
            dielectric = (1.0 - metallic) * (1.0 - trans)
            # The diffuse base shows through the specular layer less the layer's albedo at this
            # view (`specular_layer.py`), in Cycles' Diffuse Color pass and diffuse lobe alike.
            gn = h.glossy_normal
            # A glossy normal turned from the viewer (custom normals against the faces' winding)
            # reflects and refracts nothing: Cycles' microfacet closures are 0 where cos(N, view)
            # <= 0 (its diffuse keeps cos(N, light): lamps on the viewer's side light none).
            mu_view = np.einsum("ij,ij->i", dirs, gn)
            glossy_on = mu_view < 0.0
            diffuse_w = dielectric * view_factors(self.layer_tables, m, mu_view)
            if s.output == "albedo":  # what the first hit reflects diffusely; no light, no ray
                # (a translucent surface's colour too: Cycles' Diffuse Color pass counts it)
                translucent = self.translucent[m]
                _scatter_add(result, pixel, weight * (h.albedo * diffuse_w[:, None] + translucent))
                if untextured is not None:
                    _scatter_add(flat, pixel, weight * (diffuse_w[:, None] + translucent))
                break
            wo = -dirs
            spec_level = self.specular[m]
            has_spec = ((dielectric > 0) & (spec_level > 0) & (rough >= s.mirror_roughness)
                        & glossy_on)
            f0_dielectric = self.layer_f0[m]
            # Rough glossy lobes lit directly: the specular layer's and a rough metal's.
            # (F0 (N, 3), weight (N, 3), roughness (N,)) each; the coat's below
            lobes = []
            if has_spec.any():
                lobes.append((np.where(has_spec[:, None], f0_dielectric[:, None], 0.0)
                              * self.layer_tint[m], np.where(has_spec, dielectric, 0.0)[:, None]
                              * np.ones((1, 3)), rough))
            rough_metal = (metallic > 0) & (rough >= s.mirror_roughness) & glossy_on
            f0_metal = np.where(self.tinted[m][:, None], self.metal_color[m], h.albedo)
            if rough_metal.any():
                lobes.append((f0_metal, np.where(rough_metal, metallic, 0.0)[:, None]
                              * np.ones((1, 3)), rough))
            # A rough glass reflects its lamps as a rough layer does (F0 from its IOR alone).
            rough_glass = (trans > 0) & (metallic < 1) & (rough >= s.mirror_roughness) & glossy_on
            if rough_glass.any():
                f0_glass = ((self.ior[m] - 1.0) / (self.ior[m] + 1.0)) ** 2
                lobes.append((np.where(rough_glass, f0_glass, 0.0)[:, None] * np.ones((1, 3)),
                              np.where(rough_glass, (1.0 - metallic) * trans, 0.0)[:, None]
                              * np.ones((1, 3)), rough))
            hit_strata = strata_rows(strata, pixel)
            # A black base reflects nothing diffusely: no shadow rays for it. A dark texel of a
            # coloured or textured material keeps them at the camera hits when the white-base
            # image (edge detection) needs their light; a black material never does.
            dark = max_of_three(h.albedo) <= 0.0
            if untextured is not None and (depth == 0 or follow):
                dark &= self.black[m]
            lit_w = np.where(dark, 0.0, diffuse_w)
            if self.diffuse is not None:
                lit_w = np.zeros_like(lit_w)  # the solution's diffuse light replaces it below
            # A coat over it all: what lies under shows through less the coat's albedo (and its
            # tint), so the base's light and lobes are weighed by `under`; the coat adds its own
            # highlights (a lobe lit with the others) and, below, its own reflected ray.
            coat_w = np.where(glossy_on, self.coat[m], 0.0)
            coated = coat_w > 0.0
            under = coat_e = None
            base_lit_w = lit_w
            if coated.any():
                mu_coat = np.einsum("ij,ij->i", dirs, gn)
                coat_e = np.where(coated, 1.0 - view_factors(self.coat_tables, m, mu_coat), 0.0)
                under = coat_attenuation(coat_w, coat_e, self.coat_tint[m], self.coat_ior[m],
                                         mu_coat)
                base_lit_w = lit_w[:, None] * under
                lobes = [(f0, weight * under, lobe_rough) for f0, weight, lobe_rough in lobes]
                coat_rough = self.coat_roughness[m]
                coat_lobe = np.where(coated & (coat_rough >= s.mirror_roughness), coat_w, 0.0)
                if coat_lobe.any() and s.shading != "gouraud":
                    lobes.append((self.coat_f0[m][:, None] * np.ones((1, 3)),
                                  coat_lobe[:, None] * np.ones((1, 3)), coat_rough))
            fabric = None  # the hits' sheen (`_fabric`); Gouraud shading draws none
            with self.clock("light sampling"):
                if s.shading == "gouraud":
                    lit, lambert = self.gouraud_direct(h, hits, origins, base_lit_w, lobes,
                                                       hit_strata)
                else:
                    fabric = self._fabric(hits.tri, bary, m)
                    sheen_light = None if fabric is None else np.zeros_like(h.p)
                    lit, lambert = self.direct(h, wo, base_lit_w, lobes, hit_strata,
                                               (hits.tri, bary), fabric, sheen_light)
                    if self.diffuse is None:  # else the solution carries it
                        lit = lit + self._translucent_direct(h, wo, m, under)
                        if depth == 0:
                            lit = lit + self._translucent_gather(
                                h, m, under, h.p if seeds is None else seeds[pixel])
            if self.diffuse is not None:
                with self.clock("diffuse lookup"):
                    reflected = self.diffuse(hits.tri, bary, dirs, h.front, entered == 0,
                                             hit_strata)
                if under is not None:
                    reflected = reflected * under
                lit = lit + reflected
                # A white base's share, for edge detection (the `untextured` image).
                lambert = reflected / np.maximum(h.albedo, ALBEDO_FLOOR)
            own = h.emission * (1.0 if under is None else under) + lit
            smooth = rough < s.mirror_roughness
            # Mirror and refraction directions about the (smooth) shading normal; where that would
            # send the ray to the wrong side of the surface, about a normal bent towards the
            # geometric one (reflection, below) or the geometric one itself (refraction).
            r_dir = reflect(dirs, gn)
            wrong_r = np.einsum("ij,ij->i", r_dir, h.ng) <= 0.0
            # A mirror direction below the surface (an interpolated normal tilted away from the
            # view near a silhouette, a bevel's custom normals): the normal bent towards the
            # geometric one until the reflection just leaves the surface, as Cycles does
            # (`bump.valid_reflection`). Reflecting about the geometric normal instead showed a
            # custom-normal mirror cube's bevel the lamp where Cycles shows the horizon.
            about_r = h.ng
            if wrong_r.any():
                about_r = h.ng.copy()
                about_r[wrong_r] = valid_reflection(h.ng[wrong_r], -dirs[wrong_r], gn[wrong_r])
                r_dir[wrong_r] = reflect(dirs[wrong_r], about_r[wrong_r])
            cos_o = np.einsum("ij,ij->i", wo, gn)
            # Metals: a tinted mirror (Schlick with F0 = base colour); a rough metal's one ray
            # stands for its lobe, as a rough layer's does (its lamps' highlights: `direct`),
            # with Schlick's grazing term averaged over the lobe (a wide lobe keeps the tint at
            # grazing views) and the energy multiple scattering keeps (`metal_reflectance`).
            metal_w = np.zeros((len(m), 3))
            metal = np.flatnonzero((metallic > 0) & glossy_on)
            metal_w[metal] = metallic[metal, None] * metal_reflectance(
                self.metal_tables, m[metal], cos_o[metal], f0_metal[metal], rough[metal],
                smooth[metal])
            # The dielectric specular layer of opaque surfaces reflects its surroundings along
            # the mirror direction with its albedo at this view, what the base lost under it:
            # exact Fresnel at the level-scaled F0 when smooth (`specular_layer.py`), tinted by
            # its Specular Tint (`tinted_albedo`). A rough layer's one ray stands for its lobe
            # (Cycles' glossy rays see the surroundings; the lamps' highlights come from
            # `direct`): the energy is right, the blur is not drawn.
            layer_on = (dielectric > 0) & (spec_level > 0) & glossy_on
            layer_e = 1.0 - view_factors(self.layer_untinted, m, mu_view)
            layer_w = np.where(layer_on[:, None], dielectric[:, None] * tinted_albedo(
                layer_e, f0_dielectric, self.layer_tint[m]), 0.0)
            mirror_w = metal_w + layer_w
            if self.environment:  # environment-mapped mirrors: a look-up, whatever the depth
                with self.clock("environment"):
                    own = own + self._environment(hits.tri, h.p, r_dir, mirror_w, gn,
                                                  lit_w[:, None] * h.albedo)
            # A Principled sheen over it all (`shading/sheen.py`): what lies under keeps 1 - the
            # layer's albedo; a Sheen BSDF adds its light beside the surface (keep 1).
            keep = None
            if fabric is not None:
                keep = fabric.under(np.einsum("ij,ij->i", wo, h.ns))
                own = own * keep[:, None] + sheen_light
                lambert = lambert * keep[:, None]
            _scatter_add(result, pixel, weight * own)
            if untextured is not None:  # white base colour where textures are filtered
                flat_own = own
                if depth == 0 or follow:
                    white = ~self.attribute_base[m]
                    flat_own = own + (1.0 - h.albedo) * lambert * white[:, None]
                _scatter_add(flat, pixel, weight * flat_own)
            # --- spawn the next generation: mirror reflection and refraction -----------------------
            eta = np.where(h.front, 1.0 / self.ior[m], self.ior[m])
            t_dir, tir = refract(dirs, h.ns, eta)
            wrong = ~tir & (np.einsum("ij,ij->i", t_dir, h.ng) >= 0.0)
            if wrong.any():
                t_dir[wrong], tir[wrong] = refract(dirs[wrong], h.ng[wrong], eta[wrong])
            children = []  # (origins, dirs, pixel, weight, sharp, entered, blur[, dp, dd])
            # glass: Fresnel split between the reflected and the refracted ray
            # (a rough glass's two rays stand for its lobes, as a rough layer's mirror ray does)
            glass = (trans > 0) & (metallic < 1) & glossy_on
            cos_f = cos_o
            if depth > 0:  # past the camera's hit: a rough glass's facets (`_facet_rays`)
                cos_f = self._facet_rays(glass & (rough >= s.mirror_roughness), h, dirs, wo,
                                         rough, eta, cos_o, r_dir, t_dir, tir, depth)
            f_g = fresnel_dielectric(cos_f, eta)
            glass_w = ((1.0 - metallic) * trans)[:, None]
            refl_w = mirror_w + np.where(glass[:, None], glass_w * f_g[:, None] * self.glass_tint[m],
                                         0.0)
            if self.environment:  # their mirror part was looked up above: no ray for it
                refl_w = np.where(self._mapped(hits.tri)[:, None],
                                  refl_w - mirror_w, refl_w)
            # Each refraction passes sqrt(base colour), the Principled's tint (entering and leaving
            # a solid then give the base colour; a Glass BSDF's colour is read squared for it).
            refr_w = np.where((glass & ~tir)[:, None],
                              glass_w * (1.0 - f_g)[:, None] * np.sqrt(np.maximum(h.albedo, 0.0)), 0.0)
            known = entered >= 0
            # A back face met from outside every solid: the mesh is open or inverted.
            after_reflection = np.where(known & (h.front | (entered > 0)), entered, -1)
            after_refraction = np.where(known & h.front, entered + 1,
                                        np.where(entered > 0, entered - 1, -1))
            base_lobe, coat_generation = mirror_w, []
            if under is not None:  # the layers under the coat, and the coat's own reflection
                refl_w, refr_w, base_lobe = refl_w * under, refr_w * under, mirror_w * under
                coat_refl = (coat_w * coat_e)[:, None] * np.ones((1, 3))
                coat_generation = [(coat_refl, r_dir, 1.0, after_reflection, wrong_r, about_r,
                                    self.coat_roughness[m], coat_refl, None)]
            # Each generation's lobe: its roughness and albedo, and for the refracted one the
            # relative IOR it passes (the rays across a rough glass's transmission lobe).
            generations = [(refl_w, r_dir, 1.0, after_reflection, wrong_r, about_r, rough,
                            base_lobe, None),
                           (refr_w, t_dir, -1.0, after_refraction, wrong, h.ng, rough, refr_w,
                            eta),
                           *coat_generation]
            if keep is not None:  # all of them under the sheen
                generations = [(w * keep[:, None], *rest[:-2],
                                None if rest[-2] is None else rest[-2] * keep[:, None], rest[-1])
                               for w, *rest in generations]
            # per generation spawned: (strong (N,) bool, side, bent (N,) bool, the normal the bent
            # rays turned about (N, 3)); and the roughness, albedo and relative IOR (None: a
            # reflection) of its lobe
            spawned, lobes_of = [], []
            for w_new, d_new, side, seen, bent, about, lobe_rough, lobe_w, eta_new in generations:
                # rays off smooth surfaces see area lamps (`sharp`); a refracted ray one lobe's
                # blur no more than its parent's
                reflected_rough = lobe_rough if eta_new is None else None
                sees = sharp & (reflected_rough < s.mirror_roughness
                                if reflected_rough is not None else smooth)
                lobe_blur = blur if reflected_rough is None else np.where(
                    reflected_rough >= s.mirror_roughness, np.maximum(blur, reflected_rough), blur)
                w_total = weight * w_new
                w_max = max_of_three(w_total)
                alive = w_max > 0.0
                strong = alive & (w_max >= s.min_weight)
                self.stats.pruned_branches += int(np.count_nonzero(alive & ~strong))
                if strong.any():
                    o_new = h.p[strong] + side * h.ng[strong] * self.offset
                    children.append((o_new, d_new[strong], pixel[strong], w_total[strong],
                                     sees[strong], seen[strong], lobe_blur[strong]))
                    spawned.append((strong, side, bent, about))
                    lobes_of.append((lobe_rough, lobe_w, eta_new))
            if not children:
                break
            carry = follow and depth < s.max_depth  # the last generation filters no texture
            if carry:
                with self.clock("differentials"):
                    rows = np.flatnonzero(np.logical_or.reduce([st for st, *_ in spawned]))
                    if depth == 0:  # the camera's: only for the hits that spawn rays
                        dp_rows, dd_rows = rd.camera_derivatives(footprint, pixel[rows], dirs[rows],
                                                                 h.p[rows], h.ng[rows])
                    else:
                        dp_rows, dd_rows = dp[:, rows], dd[:, rows]
                    for k, child in enumerate(self._child_differentials(
                            spawned, hits.tri, h, dirs, t_dir, eta, rows, dp_rows, dd_rows)):
                        children[k] += child
            if depth == 0 and s.lobe_rays > 1:  # rough lobes seen directly: rays across them
                diffuse_reflectance = diffuse_w[:, None] * h.albedo
                if under is not None:
                    diffuse_reflectance = diffuse_reflectance * under
                if keep is not None:
                    diffuse_reflectance = diffuse_reflectance * keep[:, None]
                with self.clock("glossy lobes"):
                    for k, ((strong, *_), (lobe_rough, lobe_w, eta_k)) in enumerate(
                            zip(spawned, lobes_of, strict=True)):
                        if lobe_rough is None:
                            continue
                        children[k], correction = self._lobe_rays(
                            children[k], strong, h, wo, lobe_rough, lobe_w, diffuse_reflectance,
                            None if seeds is None else seeds[pixel], strata_rows(strata, pixel),
                            eta_k)
                        if correction is not None:
                            _scatter_add(result, *correction)
                            if untextured is not None:
                                _scatter_add(flat, *correction)
            origins = np.concatenate([c[0] for c in children])
            dirs = np.concatenate([c[1] for c in children])
            pixel = np.concatenate([c[2] for c in children])
            weight = np.concatenate([c[3] for c in children])
            sharp = np.concatenate([c[4] for c in children])
            entered = np.concatenate([c[5] for c in children])
            blur = np.concatenate([c[6] for c in children])
            refracted = np.concatenate([np.full(len(c[0]), side < 0.0)
                                        for c, (_, side, *_) in zip(children, spawned, strict=True)])
            if carry:
                dp = np.concatenate([c[7] for c in children], axis=1)
                dd = np.concatenate([c[8] for c in children], axis=1)
            t_min = np.zeros(len(origins))
        return result


def trace_steps(scene: Scene, settings: TracerSettings, bvh: BVH | None = None,
                resolution: tuple[int, int] | None = None, out: np.ndarray | None = None,
                environment: Mapping[int, EnvironmentLookup] | None = None,
                diffuse: DiffuseLookup | None = None, rows: tuple[int, int] | None = None
                ) -> Steps[TraceResult]:
    """Trace the scene camera's view; yields progress in [0, 1), returns the `TraceResult`.

    resolution: (W, H) pixels, default the camera's. out: optional (H, W, 3) float32 buffer.
    rows: (a, b): only the image's rows a..b-1 (a tile of the view, jobs/tiles.py), each pixel
    traced as the whole view traces it; the image holds those rows (b - a, W, 3) (and `out` is
    that size). The edge pass compares pixels with their 4-neighbours and the hot-pixel pass
    their 3 x 3 neighbourhoods after it, so two rows either side of the band are traced too,
    and the nearer one edge-passed (counted in the stats).
    environment: object index -> radiance lookup(points, directions), each (N, 3); those
    objects' mirror reflections read it instead of tracing rays (`envmap.py`). diffuse: the
    diffuse light at every hit read from elsewhere (`DiffuseLookup`; kernels/hybrid/).
    """
    if scene.camera is None:
        raise ValueError("the scene has no camera to trace from")
    width, height = resolution or scene.camera.resolution
    top, bottom = rows if rows is not None else (0, height)
    if not 0 <= top < bottom <= height:
        raise ValueError(f"rows {top}..{bottom} are not rows of a {height}-row image")
    # Pass 3 reads each pixel's 3 x 3 neighbourhood after the edge pass, which reads each
    # pixel's 4-neighbours: two rows on either side are traced, one of them edge-passed too.
    halo = 2 if rows is not None and settings.adaptive > 1 else 0
    first_row, last_row = max(0, top - halo), min(height, bottom + halo)  # the rows traced
    band = last_row - first_row
    bvh = bvh or BVH.build(scene.triangles)
    tracer = Tracer(scene, bvh, settings, environment, diffuse=diffuse,
                    view_pixels=width * height)
    image = out if out is not None else np.empty((bottom - top, width, 3), np.float32)
    n = settings.supersample
    passes = n * n
    # --- pass 1: n x n stratified samples everywhere (1: the pixel centres) ----------------------
    acc = np.zeros((band * width, 3))
    flat, flat_k = np.zeros((band * width, 3)), np.empty((band * width, 3))
    first_ids = np.empty(band * width, np.int64)
    row, col = np.divmod(np.arange(band * width), width)
    row += first_row
    # Each sample stands for a 1/n cell of its pixel; its textures are averaged over that cell,
    # in g/n boxes rounded up: one box over a half-pixel cell seen obliquely blurs (its texture
    # space box is up to twice the cell's image).
    grid = -(-settings.texture_filter // n)
    tracer.pass_name = "pixels"
    # Each pixel's seed, its column and row in the whole view: its lobe rays' pattern.
    seeds = np.stack([col, row, np.zeros(len(col))], axis=1).astype(np.float64)
    for k, (ox, oy) in enumerate(stratified_offsets(n)):
        tracer.clock.label = "camera"
        with tracer.clock("camera rays"):
            o, d = camera_rays(scene.camera, width, height, offsets=(ox, oy))
            o, d = o[first_row:last_row], d[first_row:last_row]  # the whole view's floats
        footprint = None if settings.texture_filter == 1 else Footprint(
            scene.camera, width, height, col + ox, row + oy, 1.0 / n, grid)
        d = d.reshape(-1, 3)
        acc += tracer.radiance(o.reshape(-1, 3), d, first_ids if k == 0 else None,
                               footprint=footprint, untextured=flat_k,
                               strata=(np.full(band * width, k), passes), seeds=seeds,
                               reach=camera_reach(scene.camera, d))
        flat += flat_k
        yield 0.6 * (k + 1) / passes
    pixels = acc / passes
    # --- pass 2: supersample only where it changes the image (edges) -----------------------------
    a = settings.adaptive
    if a > 1:
        # Texture detail is already filtered: edges are where geometry, shadows or what the
        # mirrors show change, seen with a white base colour at the camera hits.
        seen = flat / passes if settings.texture_filter > 1 else pixels
        tracer.clock.label = "camera"
        with tracer.clock("edge detection"):
            chroma = None
            if tracer.attribute_base.any():  # colour-attribute bases: hue edges count too
                chroma = tracer.attribute_hits(first_ids).reshape(band, width)
            mark = edge_pixels(seen.reshape(band, width, 3),
                               first_ids.reshape(band, width), chroma).ravel()
            mark &= (row >= top - 1) & (row <= bottom)  # the band's rows and one either side
        tracer.stats.edge_pixels = int(mark.sum())
        if mark.any():
            sel = np.nonzero(mark)[0]
            tracer.pass_name = "edges"
            pixels[sel] = yield from scaled(_subsampled(
                tracer, scene, settings, width, height, col[sel], row[sel], seeds[sel], a),
                0.6, 0.3)
    # --- pass 3: pixels far brighter than those around them ----------------------------------------
    # A smooth surface's highlight (a lamp in a curved metal) can be far smaller than a pixel: a
    # point sample that meets it sets the pixel to its peak, where Cycles averages it over the
    # pixel. Such pixels get HOT_SAMPLES x HOT_SAMPLES rays, their mean replacing them.
    if a > 1:
        own = (row >= top) & (row < bottom)
        hot = np.flatnonzero(hot_pixels(pixels.reshape(band, width, 3)).ravel() & own)
        tracer.stats.hot_pixels = int(hot.size)
        if hot.size:
            tracer.pass_name = "hot pixels"
            pixels[hot] = yield from scaled(_subsampled(
                tracer, scene, settings, width, height, col[hot], row[hot], seeds[hot],
                HOT_SAMPLES), 0.9, 0.1)
    image[...] = pixels.reshape(band, width, 3)[top - first_row:bottom - first_row]
    tracer.stats.phases = tracer.clock.as_dict()
    return TraceResult(image=image, stats=tracer.stats, settings=settings)


def _subsampled(tracer: Tracer, scene: Scene, settings: TracerSettings, width: int, height: int,
                col: np.ndarray, row: np.ndarray, seeds: np.ndarray, a: int
                ) -> Steps[np.ndarray]:
    """(P, 3) the mean radiance of a x a stratified rays through each pixel (col, row) (P,)
    each, seeds (P, 3) their lobe rays' patterns; yields progress in [0, 1]."""
    grid = stratified_offsets(a)
    # All sub-samples of all the pixels go out as few large wavefronts: per-call costs (BVH pool
    # set-up, one pass per depth) are paid once, not once per sub-sample.
    rays = [pixel_rays(scene.camera, width, height, col + ox, row + oy) for ox, oy in grid]
    origins = np.concatenate([o for o, _ in rays])  # (a*a*P, 3)
    dirs = np.concatenate([d for _, d in rays])
    del rays
    radiance = np.empty((len(origins), 3))
    stratum = np.repeat(np.arange(len(grid)), len(col))  # the sub-sample of each ray
    ray_seeds = np.tile(seeds, (len(grid), 1))  # each ray's pixel
    # Each sub-sample's textures averaged over its 1/a cell, as in pass 1: a minified texture at
    # a silhouette would alias between a x a point samples.
    cell_x = np.concatenate([col + ox for ox, _ in grid])
    cell_y = np.concatenate([row + oy for _, oy in grid])
    for first in range(0, len(origins), EDGE_WAVEFRONT):
        last = first + EDGE_WAVEFRONT
        footprint = None if settings.texture_filter == 1 else Footprint(
            scene.camera, width, height, cell_x[first:last], cell_y[first:last], 1.0 / a,
            -(-settings.texture_filter // a))
        radiance[first:last] = tracer.radiance(
            origins[first:last], dirs[first:last], footprint=footprint,
            strata=(stratum[first:last], len(grid)), seeds=ray_seeds[first:last],
            reach=camera_reach(scene.camera, dirs[first:last]))
        yield min(last, len(origins)) / len(origins)
    return radiance.reshape(len(grid), len(col), 3).mean(axis=0)


def hot_pixels(image: np.ndarray) -> np.ndarray:
    """(H, W) bool: pixels of image (H, W, 3) whose luminance passes HOT_RATIO times the median
    of their 3 x 3 neighbourhood's and HOT_FLOOR (a small highlight a few pixels across: the
    median is the surface around it)."""
    lum = image @ np.array(REC709_LUMINANCE)
    padded = np.pad(lum, 1, mode="edge")
    h, w = lum.shape
    around = np.stack([padded[i:i + h, j:j + w] for i in range(3) for j in range(3)])
    return (lum > HOT_RATIO * np.median(around, axis=0)) & (lum > HOT_FLOOR)


def trace(scene: Scene, settings: TracerSettings | None = None, **kwargs) -> TraceResult:
    """Blocking form of `trace_steps` (settings default to `auto_settings(scene)`)."""
    return drain(trace_steps(scene, settings or auto_settings(scene), **kwargs))

