"""Environment (cube) mapping: a shiny object reflects six pictures taken from its centre.

The lecture (lecture 13, "2. Environment Mapping"): put the eye at the centre of the shiny
object, hide the object, render the six faces of a cube with a 90-degree camera each; to shade
the object, reflect the view vector about the normal, r = v - 2 (v . n) n, pick the face of the
largest |r_i| and read the face at (s, t) = ((sc / |ma| + 1) / 2, (tc / |ma| + 1) / 2).
`cubemap.py` holds that table (OpenGL's convention); this module renders the faces with the
Whitted tracer and shades the camera's view with them.

What the lecture's map cannot know (the technique's failure modes, tested and charted):
* parallax: the map is exact only for the object's centre; a point on the surface a distance
  rho from the centre sees a nearby object at distance d off by an angle of about rho / d, so
  reflections of close objects slide and shrink (the environment is treated as infinitely far).
  The faces therefore also keep each texel's distance, and `EnvironmentMap.reflected` searches
  along the reflected ray for where it meets those surfaces (`parallax_steps`; 0 is the
  lecture's look-up). What remains is where the distances mislead: next to contact (a ball on
  a stand) and along silhouettes, where a blend of a near and a far distance is neither;
* self-reflection: the object is hidden while its map is rendered, so a concave or multi-part
  object never sees itself (it still casts its shadows: only the rays that see pass it);
* resolution: a face of S texels covers 90 degrees, so detail finer than 90 / S degrees blurs.

Seams. Each face is rendered with a border of `BORDER` texels beyond its 90 degrees (the same
camera, a wider frustum): a bilinear lookup near an edge then blends with true samples across
the edge instead of clamping to the edge texel, so the cube has no visible seams.

Faces are (6, S + 2B, S + 2B, 3) float32 radiance, W/(m^2 sr), face order and orientation as in
`cubemap.py` (texel (i, j) of the unpadded face at s = (j + 0.5) / S, t = 1 - (i + 0.5) / S).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..bake.camera_view import edge_pixels, pixel_patterns
from ..geometry.bvh import BVH
from ..geometry.scene import Scene, triangle_areas, triangle_emission
from ..progress import Steps, drain, scaled
from ..shading.material_maps import emission_at
from ..trace.settings import TraceResult, TracerSettings
from ..trace.tracer import Tracer, trace_steps
from .cubemap import (  # noqa: F401 (sample_bordered, bordered_directions re-exported)
    BORDER,
    bordered_directions,
    bordered_texel_directions,
    sample_bordered,
    texel_directions,
)
from .prefilter import PrefilterSettings, prefilter_steps
from .probe_lookup import GlossyMips
from .sh_irradiance import irradiance, sh_coefficients

# Face sizes the automatic choice stays within: 16 texels (5.6 degrees each) still shows a room's
# walls and lights as shapes; 1024 is 6 x 1M texels, ~25 MB of float32 RGB per object.
MIN_FACE_SIZE = 16
MAX_FACE_SIZE = 1024
# Rays traced per call while rendering faces: ~100 MB of wavefront records at most.
FACE_WAVEFRONT = 1 << 17
# Mip levels a rough mapped surface reads by default: the prefilter's default chain (roughness
# 0, 0.2, ..., 1; trilinear between them).
ROUGH_MIPS = PrefilterSettings().levels
# Regula falsi steps of the parallax search by default (see `EnvironmentMap.reflected`).
PARALLAX_STEPS = 4
# Doublings of the search distance, from the map's farthest distance / 2^12 up to it: a surface
# closer than 1/4096 of the environment's size is found at the first sample (treated as contact).
SEARCH_OCTAVES = 12
# A corrected look-up reads the map for surroundings seen from the object's surface, which is
# nearer to them than the centre is: a surface k radii from the centre looks k / (k - 1) times
# larger from the near side, 2x at two radii (a floor under a ball on a stand): the face size is
# chosen for that magnification (on the sample room the mirror's error falls steadily from 32 to
# 128 texels per face).
PARALLAX_MAGNIFICATION = 2.0
# Face texels at edges are traced again along 2 x 2 directions (1 x 1 elsewhere): the texel
# centres alone alias silhouettes and shadow edges. Six 56-texel faces of env_room against six
# converged Cycles cameras (relMSE, seconds, idle), area lamp / the lamp made a point:
# 1 x 1 1.4e-2 0.44 s / 8.5e-3 0.18 s; 2 x 2 everywhere 1.8e-3 0.73 s / 8.2e-4 0.46 s;
# 1 x 1 + edges 2 x 2 1.8e-3 0.68 s / 8.2e-4 0.30 s; + edges 3 x 3 4.1e-4 1.79 s / 2.0e-4
# 0.49 s. Finer faces than that serve no view: a mirror's error in the view is the map's
# parallax and resolution (relMSE ~0.05 on env_room).
FACE_EDGE_SAMPLES = 2
# The automatic face size renders at most this many face texels per camera pixel, all six faces
# together: a map of several times the view's own rays is more than one view can show.
VIEW_TEXEL_SHARE = 4.0


@dataclass(frozen=True)
class EnvMapSettings:
    """| field           | range        | default | meaning                                          |
    |-----------------|--------------|---------|--------------------------------------------------|
    | face_size       | 0, 8..4096   | 0       | texels per face side; 0: from the object's size  |
    |                 |              |         | on screen (`auto_face_size`)                     |
    | face_supersample| 1..8         | 1       | n x n rays per face texel, averaged (box filter) |
    | face_edge_samples| 1..8        | 2       | a x a rays again in face texels at edges (where  |
    |                 |              |         | a texel's neighbours see another object or a     |
    |                 |              |         | contrast), replacing them; 1: off                |
    | objects         | names        | ()      | objects to environment-map; empty: every mirror  |
    |                 |              |         | (smooth metal or specular) object               |
    | face_depth      | -1, 0..64    | -1      | ray-tree depth of the face renders (-1: the      |
    |                 |              |         | tracer's automatic depth for the scene)          |
    | parallax_steps  | 0..16        | 4       | 0: the lecture's look-up along r alone (the      |
    |                 |              |         | environment infinitely far); k: a search for     |
    |                 |              |         | where the reflected ray meets the mapped         |
    |                 |              |         | surfaces (each texel's distance), k refinements  |
    | rough_mips      | 0, 2..16     | 6       | a mapped object's rough surfaces (roughness at   |
    |                 |              |         | or above the tracer's mirror_roughness) read a   |
    |                 |              |         | GGX mip chain of this many levels, trilinear by  |
    |                 |              |         | roughness; 0: the sharp look-up along r at every |
    |                 |              |         | roughness (mirrors read it either way)           |
    | diffuse_sh      | bool         | False   | a mapped object's diffuse part also reflects the |
    |                 |              |         | map's SH9 irradiance along its normal (albedo /  |
    |                 |              |         | pi x E): light from the surroundings, which a    |
    |                 |              |         | Whitted view (and Cycles' `whitted` model) lacks |
    """

    face_size: int = 0
    face_supersample: int = 1
    face_edge_samples: int = FACE_EDGE_SAMPLES
    objects: tuple[str, ...] = ()
    face_depth: int = -1
    parallax_steps: int = PARALLAX_STEPS
    rough_mips: int = ROUGH_MIPS
    diffuse_sh: bool = False

    def __post_init__(self):
        if self.face_size != 0 and not 8 <= self.face_size <= 4096:
            raise ValueError(f"face_size must be 0 (automatic) or in [8, 4096], got {self.face_size}")
        if not 1 <= self.face_supersample <= 8:
            raise ValueError(f"face_supersample must be in [1, 8], got {self.face_supersample}")
        if not 1 <= self.face_edge_samples <= 8:
            raise ValueError(f"face_edge_samples must be in [1, 8], got {self.face_edge_samples}")
        if not -1 <= self.face_depth <= 64:
            raise ValueError(f"face_depth must be -1 (automatic) or in [0, 64], got {self.face_depth}")
        if not 0 <= self.parallax_steps <= 16:
            raise ValueError(f"parallax_steps must be in [0, 16], got {self.parallax_steps}")
        if self.rough_mips != 0 and not 2 <= self.rough_mips <= 16:
            raise ValueError(f"rough_mips must be 0 (off) or in [2, 16], got {self.rough_mips}")


@dataclass
class EnvironmentMap:
    """One object's cube map: its centre (the eye of the six renders) and the bordered faces."""

    object_index: int
    centre: np.ndarray  # (3,) float64, world, m
    faces: np.ndarray  # (6, S + 2B, S + 2B, 3) float32 radiance, W/(m^2 sr)
    # (6, S + 2B, S + 2B, 1) float32, 1/m: one over the distance from the centre to what each
    # texel sees (0: nothing, the world). Inverse, so that bilinear blends and misses stay finite.
    inverse_distance: np.ndarray | None = None
    border: int = BORDER
    # (6, S, S, 3) float32 W/(m^2 sr): the emitted part of each texel's radiance (what emissive
    # meshes send, which the tracer lights with directly; texel centres), None when nothing in
    # the scene glows.
    emission: np.ndarray | None = None
    rays: int = 0  # rays traced from the centre to render the faces

    def reflected_light(self) -> np.ndarray:
        """(6, S, S, 3) float32: the faces without borders less what emitters send (the light the
        surroundings reflect; the diffuse look-up's SH holds this alone)."""
        faces = self.face_images()
        return faces if self.emission is None else np.maximum(faces - self.emission, 0.0)

    @property
    def size(self) -> int:
        return self.faces.shape[1] - 2 * self.border

    def lookup(self, directions: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Radiance (N, 3) float32 seen along (N, 3) directions (any length): bilinear, seamless."""
        return sample_bordered(self.faces, self.border, directions, out=out)

    def reflected(self, points: np.ndarray, directions: np.ndarray, steps: int = PARALLAX_STEPS
                  ) -> np.ndarray:
        """Radiance (N, 3) float32 arriving at world `points` (N, 3) along unit `directions`.

        steps = 0 is the lecture's look-up along r alone: right only for the centre, or for an
        environment infinitely far. With steps > 0 (and distances captured) the look-up turns to
        where the ray from the point meets the mapped surfaces, as a "distance impostor" does
        (Szirmay-Kalos, Aszodi, Lazanyi and Premecz 2005). With o = p - c and x(t) = o + t r,
        the ray meets the surfaces where 1 / |x| equals the inverse distance q the map holds
        along x: f(t) = 1 / |x(t)| - q(x(t)) changes sign there (f(0) >= 0 for a point inside
        the mapped surroundings). Distances t doubling up to t_max = reach + |o| (past it the ray
        is farther out than anything mapped) bracket the first sign change, and `steps` rounds
        of regula falsi (Illinois) close in on it. No sign change: the ray leaves the scene, and
        r itself is the direction (the world).
        """
        return self.lookup(self.corrected(points, directions, steps))

    def corrected(self, points: np.ndarray, directions: np.ndarray, steps: int = PARALLAX_STEPS
                  ) -> np.ndarray:
        """(N, 3) float64 directions from the centre to read the map along for rays from world
        `points` along unit `directions` (`reflected`'s search; steps = 0: the directions)."""
        r = np.asarray(directions, np.float64)
        if steps == 0 or self.inverse_distance is None:
            return r
        o = np.asarray(points, np.float64) - self.centre

        def f(t: np.ndarray, rows: np.ndarray) -> np.ndarray:
            x = o[rows] + t[:, None] * r[rows]
            q = sample_bordered(self.inverse_distance, self.border, x)[:, 0]
            return 1.0 / np.maximum(np.linalg.norm(x, axis=1), 1e-12) - q

        n = len(r)
        every = np.arange(n)
        lo, f_lo = np.zeros(n), f(np.zeros(n), every)
        hi, f_hi = np.zeros(n), f_lo.copy()
        found = f_lo <= 0.0  # at or beyond the surfaces already (contact): the point itself
        # Past t_max = reach + |o| the ray is farther from the centre than anything mapped.
        t_max = self.reach() + np.linalg.norm(o, axis=1)
        for scale in 2.0 ** -np.arange(SEARCH_OCTAVES, -1, -1.0):
            open_rows = np.nonzero(~found)[0]
            if len(open_rows) == 0:
                break
            t_k = scale * t_max[open_rows]
            f_k = f(t_k, open_rows)
            crossed = f_k <= 0.0
            rows, stay = open_rows[crossed], open_rows[~crossed]
            hi[rows], f_hi[rows], found[rows] = t_k[crossed], f_k[crossed], True
            lo[stay], f_lo[stay] = t_k[~crossed], f_k[~crossed]
        t = np.where(found, hi, 0.0)
        rows = np.nonzero(found & (hi > lo))[0]
        a, b, fa, fb = lo[rows], hi[rows], f_lo[rows], f_hi[rows]
        side = np.zeros(len(rows))  # Illinois: halve the end that stayed twice in a row
        for _ in range(steps):
            c = b - fb * (b - a) / np.where(fb != fa, fb - fa, 1.0)
            fc = f(c, rows)
            left = fc * fa > 0.0  # the root lies in [c, b]
            a, fa = np.where(left, c, a), np.where(left, fc, fa)
            b, fb = np.where(left, b, c), np.where(left, fb, fc)
            fb = np.where(left & (side > 0), 0.5 * fb, fb)
            fa = np.where(~left & (side < 0), 0.5 * fa, fa)
            side = np.where(left, 1.0, -1.0)
        t[rows] = b - fb * (b - a) / np.where(fb != fa, fb - fa, 1.0) if len(rows) else b
        x = o + t[:, None] * r
        return np.where(found[:, None], x, r)

    def reach(self) -> float:
        """The farthest distance the map holds, m (1 when it holds only the world)."""
        q = self.inverse_distance[self.inverse_distance > 0.0]
        return float(1.0 / q.min()) if q.size else 1.0

    def face_images(self) -> np.ndarray:
        """(6, S, S, 3) float32: the faces without their borders, `cubemap.py`'s layout."""
        b = self.border
        return self.faces[:, b:b + self.size, b:b + self.size]


class MapLookup:
    """What the camera view reads at one mapped object's hits (the tracer's `EnvironmentLookup`).

    Called with (N, 3) world points, (N, 3) unit reflected directions and (N,) roughness: the
    radiance (N, 3) arriving along the directions. Mirrors (roughness below `mirror_roughness`)
    read the map itself, with the parallax search; with `mips`, rougher surfaces read the GGX
    chain along the same corrected direction, trilinear by roughness. `irradiance` (None unless
    the SH is given): (N, 3) points, (N, 3) unit normals -> (N, 3) irradiance W/m^2 from the
    mapped surfaces, for the diffuse part.
    """

    def __init__(self, env: EnvironmentMap, steps: int, mirror_roughness: float,
                 mips: GlossyMips | None = None, sh: np.ndarray | None = None):
        self.env, self.steps, self.mirror_roughness = env, steps, mirror_roughness
        self.mips, self.sh = mips, sh
        self.irradiance = None if sh is None else self._irradiance

    def __call__(self, points: np.ndarray, directions: np.ndarray,
                 roughness: np.ndarray | None = None) -> np.ndarray:
        if self.mips is None or roughness is None:
            return self.env.reflected(points, directions, self.steps)
        d = self.env.corrected(points, directions, self.steps)
        out = np.empty((len(d), 3), np.float64)
        rough = np.asarray(roughness) >= self.mirror_roughness
        out[~rough] = self.env.lookup(d[~rough])
        out[rough] = self.mips.lookup(d[rough], np.asarray(roughness)[rough])
        return out

    def _irradiance(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        return irradiance(self.sh, normals)


def has_rough_reflections(scene: Scene, index: int, mirror_roughness: float) -> bool:
    """Whether object `index` has a reflecting surface (metal or a specular layer) at or above
    `mirror_roughness`: what the prefiltered mips are computed for."""
    used = np.unique(scene.material_ids[scene.object_slice(index)])
    return any(scene.materials[m].roughness >= mirror_roughness
               and (scene.materials[m].metallic > 0.0 or scene.materials[m].specular > 0.0)
               for m in used)


@dataclass
class EnvMapResult:
    image: np.ndarray  # (H, W, 3) float32 linear radiance, row 0 top
    maps: list[EnvironmentMap]
    trace: TraceResult  # the camera view's statistics and settings
    face_rays: int = 0  # rays traced for the faces (camera rays of the six renders)
    seconds: dict = field(default_factory=dict)


def mirror_objects(scene: Scene, mirror_roughness: float = 0.1) -> list[int]:
    """Object indices whose surface is mostly a mirror (smooth metal, or a smooth specular layer
    without transmission), by area: what the technique maps by default."""
    areas = triangle_areas(scene.triangles)
    shiny = np.array([m.roughness < mirror_roughness and m.transmission == 0.0
                      and m.metallic >= 0.5 for m in scene.materials], bool)
    if scene.triangle_count == 0 or not shiny.any():
        return []
    mirror_area = np.bincount(scene.object_ids, areas * shiny[scene.material_ids],
                              minlength=len(scene.objects))
    total = np.bincount(scene.object_ids, areas, minlength=len(scene.objects))
    return [k for k in range(len(scene.objects)) if total[k] > 0 and mirror_area[k] > 0.5 * total[k]]


def object_bounds(scene: Scene, index: int) -> tuple[np.ndarray, float]:
    """(centre (3,) float64 m, radius m): the object's bounding-box centre and the distance from
    it to the farthest corner of its triangles (a bounding sphere)."""
    pts = scene.triangles[scene.object_slice(index)].reshape(-1, 3).astype(np.float64)
    if len(pts) == 0:
        raise ValueError(f"object {scene.objects[index].name!r} has no triangles")
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    return centre, float(np.linalg.norm(pts - centre, axis=1).max())


def auto_face_size(scene: Scene, index: int, resolution: tuple[int, int] | None = None,
                   corrected: bool = True) -> int:
    """Face texels per side so that one texel is about one camera pixel where the object reflects
    the least detail per pixel (the middle of a sphere facing the camera), times
    PARALLAX_MAGNIFICATION when the look-up is parallax-corrected (`corrected`).

    One pixel of angle a (the image plane's width / W at distance 1) moves the hit point by d a on
    an object at distance d; on a sphere of radius rho the normal turns by d a / rho and the
    reflection by a + 2 d a / rho. A face texel at the face's centre spans 2 / S radians, so
    S = 2 / (a (1 + 2 d / rho)), the bounding sphere standing in for the object's curvature;
    rounded up to a multiple of 8 and kept in [MIN_FACE_SIZE, MAX_FACE_SIZE], and to at most
    VIEW_TEXEL_SHARE x W x H texels over the six faces. Without a camera: 128 (one texel per
    0.7 degrees).
    """
    factor = PARALLAX_MAGNIFICATION if corrected else 1.0
    cam = scene.camera
    if cam is None:
        return 128
    width, height = resolution or cam.resolution
    centre, rho = object_bounds(scene, index)
    if cam.kind == "ORTHO":
        # A pixel moves the hit point by a fixed pixel width w; the reflection turns by 2 w / rho.
        turn = 2.0 * (cam.plane_max[0] - cam.plane_min[0]) / width / max(rho, 1e-9)
    else:
        a = (cam.plane_max[0] - cam.plane_min[0]) / width
        d = float(np.linalg.norm(centre - cam.position))
        turn = a * (1.0 + 2.0 * d / max(rho, 1e-9))
    size = int(np.ceil(2.0 * factor / turn / 8.0) * 8)
    # A mirror filling the view asks for one texel per pixel over the whole cube, most of which it
    # never shows: no more face texels than VIEW_TEXEL_SHARE x the view's pixels.
    budget = int(np.sqrt(VIEW_TEXEL_SHARE * width * height / 6.0) // 8 * 8)
    return int(np.clip(size, MIN_FACE_SIZE, max(MIN_FACE_SIZE, min(MAX_FACE_SIZE, budget))))


def hidden_bvh(scene: Scene, hidden: Sequence[int]) -> BVH:
    """A BVH of the scene without the `hidden` objects: their triangles are replaced by NaN, which
    the BVH leaves out, so triangle indices still match the scene's arrays (materials, UVs)."""
    triangles = scene.triangles.copy()
    for k in hidden:
        triangles[scene.object_slice(k)] = np.nan
    return BVH.build(triangles)


def capture_steps(scene: Scene, index: int, size: int, tracer_settings: TracerSettings,
                  supersample: int = 1, bvh: BVH | None = None, edge_samples: int = 1
                  ) -> Steps[EnvironmentMap]:
    """Render the six bordered faces from the centre of object `index`, the object hidden.

    Yields progress in [0, 1], returns the `EnvironmentMap`. Each texel is the Whitted tracer's
    radiance along n x n directions spread over it (n = supersample), averaged; then, as the
    camera view does (`trace_steps`), each texel whose 4-neighbours on its face see another
    object or a visible contrast is traced again along a x a directions (a = edge_samples, when
    above n), their mean replacing it. The object is hidden from the rays that see, not from
    shadow rays: its shadow on the floor under it is part of what it reflects. `bvh`: the whole
    scene's (built when omitted).
    """
    faces = yield from capture_faces_steps(scene, index, size, tracer_settings, supersample, bvh,
                                           edge_samples=edge_samples)
    return faces.environment_map()


@dataclass
class CapturedFaces:
    """Some faces of one object's cube map (`capture_faces_steps`): what `EnvironmentMap` holds
    for them, `faces` naming which (OpenGL face numbers, in order)."""

    object_index: int
    centre: np.ndarray  # (3,) float64, world, m
    faces: tuple[int, ...]
    radiance: np.ndarray  # (F, S + 2B, S + 2B, 3) float32
    inverse_distance: np.ndarray  # (F, S + 2B, S + 2B, 1) float32
    emission: np.ndarray | None  # (F, S, S, 3) float32, None when nothing glows
    rays: np.ndarray  # (F,) int64: rays traced from the centre for each face

    def environment_map(self) -> EnvironmentMap:
        """The map, when these are the six faces in order."""
        if self.faces != tuple(range(6)):
            raise ValueError(f"a cube map needs the six faces in order, not {self.faces}")
        return EnvironmentMap(object_index=self.object_index, centre=self.centre,
                              faces=self.radiance, inverse_distance=self.inverse_distance,
                              emission=self.emission, rays=int(self.rays.sum()))


def capture_faces_steps(scene: Scene, index: int, size: int, tracer_settings: TracerSettings,
                        supersample: int = 1, bvh: BVH | None = None,
                        faces: Sequence[int] = tuple(range(6)), edge_samples: int = 1
                        ) -> Steps[CapturedFaces]:
    """`capture_steps` for the cube faces `faces` alone (a tile's share, jobs/tiles.py): each
    texel traced as the whole cube traces it (every ray on its own, edges found within each
    face), so faces captured apart and stacked equal the six captured together, bit for bit."""
    faces = tuple(int(f) for f in faces)
    centre, _ = object_bounds(scene, index)
    bvh = bvh or BVH.build(scene.triangles)
    hidden = hidden_bvh(scene, [index])
    tracer = Tracer(scene, hidden, tracer_settings, shadow_bvh=bvh,
                    view_pixels=6 * size * size)  # the whole cube's, for any faces
    tracer.primary_kind = "glossy"  # the faces are what the object's mirror rays see
    side = size + 2 * BORDER
    n, a = supersample, edge_samples
    texels = len(faces) * side * side
    # Progress: the edge pass is counted as a quarter of the texels again until its size is known.
    total = max(texels * (n * n + (a * a // 4 if a > n else 0)), 1)
    done = 0

    def trace(dirs: np.ndarray, stratum: int | np.ndarray, strata: int, radiance: np.ndarray,
              inverse: np.ndarray, first_ids: np.ndarray | None = None):
        """Fills radiance (N, 3), inverse (N,) and first_ids (N,) along dirs (N, 3) from the
        centre, in wavefronts; yields progress."""
        nonlocal done
        for first in range(0, len(dirs), FACE_WAVEFRONT):
            last = first + FACE_WAVEFRONT
            chunk = dirs[first:last]
            origins = np.broadcast_to(centre, chunk.shape).copy()
            t = np.empty(len(chunk))
            # The surfaces only: the mirror meets area lamps exactly (`Tracer._environment`).
            # The sub-samples of a texel share out each area lamp's samples, as the camera
            # view's sub-samples of a pixel do (`Tracer._area_direct`).
            share = None if strata == 1 else (
                np.broadcast_to(stratum, len(dirs))[first:last], strata)
            ids = None if first_ids is None else first_ids[first:last]
            radiance[first:last] = tracer.radiance(origins, chunk, ids, primary_t=t, strata=share)
            inverse[first:last] = np.where(np.isfinite(t), 1.0 / np.maximum(t, 1e-12), 0.0)
            done += len(chunk)
            yield min(done / total, 1.0)

    # --- pass 1: n x n stratified positions in every texel of the face planes --------------------
    radiance = np.zeros((texels, 3))
    inverse = np.zeros(texels)
    ids = np.empty(texels, np.int64)
    one, one_q = np.empty((texels, 3)), np.empty(texels)
    # A texel's index over all six bordered faces picks its pattern (`pixel_patterns`): the same
    # in a tile as in the whole capture.
    every = np.repeat(np.asarray(faces), side * side) * (side * side) + np.tile(
        np.arange(side * side), len(faces))
    face_of, (row_of, col_of) = every // (side * side), np.divmod(every % (side * side), side)
    for k, offset in enumerate(pixel_patterns(n, every)):  # n = 1: the centres
        dirs = bordered_texel_directions(size, BORDER, face_of, row_of, col_of,
                                         (offset[:, 0], offset[:, 1]))
        yield from trace(dirs, k, n * n, one, one_q, ids if k == 0 else None)
        radiance += one
        inverse += one_q
    radiance /= n * n
    inverse /= n * n
    rays = np.full(len(faces), side * side * n * n, np.int64)
    # --- pass 2: a x a where a texel's 4-neighbours see another object or a contrast -------------
    if a > n:
        mark = np.concatenate([edge_pixels(image, face_ids).ravel() for image, face_ids in zip(
            radiance.reshape(len(faces), side, side, 3), ids.reshape(len(faces), side, side), strict=True)])
        sel = np.nonzero(mark)[0]
        count = a * a  # sub-samples per texel, one in each cell of an a x a grid
        total = done + len(sel) * count
        if len(sel):
            face, i, j = face_of[sel], row_of[sel], col_of[sel]
            dirs = np.concatenate([
                bordered_texel_directions(size, BORDER, face, i, j, (offset[:, 0], offset[:, 1]))
                for offset in pixel_patterns(a, every[sel])])
            # sel // side^2: the face's place in `faces`
            rays += count * np.bincount(sel // (side * side), minlength=len(faces))
            sub, sub_q = np.empty((len(dirs), 3)), np.empty(len(dirs))
            yield from trace(dirs, np.repeat(np.arange(count), len(sel)), count, sub, sub_q)
            radiance[sel] = sub.reshape(count, len(sel), 3).mean(axis=0)
            inverse[sel] = sub_q.reshape(count, len(sel)).mean(axis=0)
    return CapturedFaces(index, centre, faces,
                         radiance.reshape(len(faces), side, side, 3).astype(np.float32),
                         inverse.reshape(len(faces), side, side, 1).astype(np.float32),
                         seen_emission(scene, hidden, centre, size, faces), rays)


def seen_emission(scene: Scene, bvh: BVH, centre: np.ndarray, size: int,
                  faces: Sequence[int] = tuple(range(6))) -> np.ndarray | None:
    """(F, S, S, 3) float32: the emitted radiance of what each texel centre's ray from `centre`
    meets in `bvh` (0 for the world) on the cube faces `faces` (all six by default), or None when
    no triangle glows."""
    if not np.any(triangle_emission(scene) > 0.0):
        return None
    dirs = texel_directions(size)[list(faces)].reshape(-1, 3)
    hits = bvh.intersect(np.broadcast_to(centre, dirs.shape).copy(), dirs)
    out = np.zeros((len(dirs), 3))
    hit = np.flatnonzero(hits.tri >= 0)
    u, v = hits.u[hit].astype(np.float64), hits.v[hit].astype(np.float64)
    out[hit] = emission_at(scene, hits.tri[hit], np.stack([1.0 - u - v, u, v], 1))
    return out.reshape(len(faces), size, size, 3).astype(np.float32)


def resolve_objects(scene: Scene, names: Sequence[str], mirror_roughness: float) -> list[int]:
    """Object indices to map: the named ones (by snapshot or source name), else every mirror."""
    if not names:
        return mirror_objects(scene, mirror_roughness)
    chosen = []
    for name in names:
        found = [k for k, o in enumerate(scene.objects) if name in (o.name, o.source_name)]
        if not found:
            raise ValueError(f"no mesh object named {name!r} in the scene")
        chosen += [k for k in found if k not in chosen]
    return chosen


def face_tracer_settings(settings: EnvMapSettings, tracer_settings: TracerSettings
                         ) -> TracerSettings:
    """The tracer settings the faces are rendered with (depth from `settings.face_depth`)."""
    if settings.face_depth >= 0:
        return replace(tracer_settings, max_depth=settings.face_depth)
    return tracer_settings


def capture_plan(scene: Scene, settings: EnvMapSettings, tracer_settings: TracerSettings,
                 resolution: tuple[int, int] | None = None) -> list[tuple[int, int]]:
    """(object index, face size) of every object to map, in the order `render_steps` captures
    them; ValueError without a camera or an object to map."""
    if scene.camera is None:
        raise ValueError("the scene has no camera to render from")
    objects = resolve_objects(scene, settings.objects, tracer_settings.mirror_roughness)
    if not objects:
        raise ValueError("nothing to environment-map: no object is a mirror (smooth metal); "
                         "name the objects to map")
    return [(k, settings.face_size or auto_face_size(scene, k, resolution,
                                                      settings.parallax_steps > 0))
            for k in objects]


def render_steps(scene: Scene, settings: EnvMapSettings, tracer_settings: TracerSettings,
                 bvh: BVH | None = None, resolution: tuple[int, int] | None = None,
                 out: np.ndarray | None = None) -> Steps[EnvMapResult]:
    """Capture a cube map for every mapped object, then trace the camera's view with those objects'
    mirror reflections read from their maps (rough ones from the maps' GGX mips with
    `settings.rough_mips`, diffuse light from their SH9 with `settings.diffuse_sh`: `MapLookup`).
    Yields progress in [0, 1], returns the `EnvMapResult`.

    The faces are rendered with `tracer_settings` (depth from `settings.face_depth`), so other
    mirrors and glass appear in them; the camera view uses `tracer_settings` unchanged.
    """
    import time

    plan = capture_plan(scene, settings, tracer_settings, resolution)
    face_tracer = face_tracer_settings(settings, tracer_settings)
    start = time.perf_counter()
    bvh = bvh or BVH.build(scene.triangles)
    bvh_seconds = time.perf_counter() - start
    maps, capture = [], 0.0
    share = 0.5 / len(plan)  # half the progress bar for the faces, half for the view
    for number, (k, size) in enumerate(plan):
        start = time.perf_counter()
        maps.append((yield from scaled(
            capture_steps(scene, k, size, face_tracer, settings.face_supersample, bvh,
                          settings.face_edge_samples),
            share * number, share)))
        capture += time.perf_counter() - start
    result = yield from scaled(view_steps(scene, settings, tracer_settings, maps, bvh,
                                          resolution, out), 0.5, 0.5)
    result.seconds = {"capture": capture, **result.seconds, "bvh": bvh_seconds}
    return result


def view_steps(scene: Scene, settings: EnvMapSettings, tracer_settings: TracerSettings,
               maps: list[EnvironmentMap], bvh: BVH | None = None,
               resolution: tuple[int, int] | None = None, out: np.ndarray | None = None
               ) -> Steps[EnvMapResult]:
    """The second half of `render_steps`: the camera's view with the captured `maps` (also what
    `merge` runs on the maps the tiles captured). Yields progress, returns the `EnvMapResult`
    (seconds: probe, render; face_rays: the rays the maps' faces were traced with)."""
    import time

    if scene.camera is None:
        raise ValueError("the scene has no camera to render from")
    bvh = bvh or BVH.build(scene.triangles)
    face_rays = sum(env.rays for env in maps)
    seconds = {"probe": 0.0, "render": 0.0}
    # The probes' rough and diffuse look-ups, from the surfaces the faces hold (the lamps light
    # directly: their highlights on rough surfaces and their light on diffuse ones are the
    # tracer's; so does what emissive meshes send, which the SH leaves out too).
    start = time.perf_counter()
    environment = {}
    for env in maps:
        mips = None
        if settings.rough_mips and has_rough_reflections(scene, env.object_index,
                                                         tracer_settings.mirror_roughness):
            chain = yield from scaled(prefilter_steps(
                env.face_images(), PrefilterSettings(levels=settings.rough_mips)), 0.0, 0.0)
            mips = GlossyMips.from_prefiltered(chain, level0=env.faces, border=env.border)
        sh = sh_coefficients(env.reflected_light()) if settings.diffuse_sh else None
        environment[env.object_index] = MapLookup(env, settings.parallax_steps,
                                                  tracer_settings.mirror_roughness, mips, sh)
    seconds["probe"] = time.perf_counter() - start
    start = time.perf_counter()
    result = yield from trace_steps(scene, tracer_settings, bvh=bvh, resolution=resolution,
                                    out=out, environment=environment)
    seconds["render"] = time.perf_counter() - start
    return EnvMapResult(image=result.image, maps=maps, trace=result, face_rays=face_rays,
                        seconds=seconds)


def render(scene: Scene, settings: EnvMapSettings | None = None,
           tracer_settings: TracerSettings | None = None, **kwargs) -> EnvMapResult:
    """Blocking form of `render_steps` (tracer settings default to the tracer's automatic ones)."""
    from ..trace.settings import auto_settings

    settings = settings or EnvMapSettings()
    tracer_settings = tracer_settings or auto_settings(scene)
    return drain(render_steps(scene, settings, tracer_settings, **kwargs))


def strip_image(env: EnvironmentMap) -> np.ndarray:
    """(S, 6 S, 3) float32: the six faces side by side in face order (+X -X +Y -Y +Z -Z), each
    in its own orientation: what the CLI and the operator save for inspection."""
    faces = env.face_images()
    return np.concatenate(list(faces), axis=1)
