"""Final gather: the radiosity solution read out at every receiver with exact direct light.

A patch solution holds B constant (or smoothly interpolated) over each patch, so everything that
changes faster than a patch is lost: the sharp fall-off next to a light, a block's shadow on the
floor, the floor inside a closed block. Most of that detail is DIRECT light. The final gather
(the "one-bounce final gather" of Lischinski, Tampieri and Greenberg 1992; Cohen and Wallace,
"Radiosity and Realistic Image Synthesis", ch. 9) splits a receiver x's irradiance in two:

    B(x) = E(x) + rho(x) (H_direct(x) + H_indirect(x))

* H_direct(x), evaluated AT x: the lamps' irradiance times their shadow-ray visibility (as the
  first shot), plus every emissive triangle j's exact unoccluded point-to-polygon factor times
  its kernel-weighted visible share:
      H_j(x) = pi L_j F(x -> j) V_j(x),   V_j(x) = sum_s k_s v_s / sum_s k_s,
      k_s = cos(theta_x) cos(theta_s) / d_s^2   at stratified points s of triangle j
  (`emitters.stratified_triangle_points`: equal areas),
  v_s one shadow ray each (the ratio estimator of `visibility.visible_fraction_steps`: exact
  when nothing blocks, and its noise stays in penumbrae). Cosines at x are to its shading normal
  (`shading_normals`: a smooth mesh's interpolated corner normals, as Cycles shades it); the rays
  leave along the face's own normal, which no smoothing tilts into the surface.
* H_indirect(x), interpolated from the patches: what the solution says arrives at patch i,
  (B_i - E_i) / rho_i, less the first shot H_direct(i), which the solver took from this same
  estimator at the patch's points (`sources.first_shot`) and did not carry again. It is smooth
  wherever the patches are, so patch-sized interpolation loses little; a coarse solution's
  patches are split into elements whose vertices gather it from the patches' B afresh
  (`elements.py`).

Shaft culling. Before any ray, each (patch, emissive triangle) pair is tested for an empty
shaft (`shafts.py`): a receiver in a patch that sees the triangle whole takes its exact factor
with share 1 and casts no shadow ray (about half the pairs of the Cornell box).

Enclosure. A floor texel inside a closed block sees only the block's inside (back faces) and
receives nothing; the patch that straddles the block's edge averages its open and enclosed parts.
`enclosed` probes each receiver with rays (along the normal, and if that hits a back face, four
more at 45 degrees): a receiver all of whose probes hit back faces is inside a solid, gets no
reflected light and casts no shadow ray (the probes go first). Receivers in patches that no back
face hangs over (`shafts.open_above`) are not probed: their normal's ray cannot meet one. Patches
scale their indirect irradiance by 1 / (open fraction of their sample points), and corners
average only the open parts, so the open side of a straddling patch keeps what the solver found
for it.

Measured on the sample Cornell box (bench/radiosity.py: 21k lightmap texels, 296 patches,
hierarchical): relative MSE against a 1024-sample Cycles bake 0.087 interpolated, 0.011 with the
direct light gathered, 0.0065 with the enclosure probes as well, for ~0.5 s of gathering on top
of a 0.6 s solve.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np

from ..geometry import shafts
from ..geometry.camera import Strata, strata_rows
from ..geometry.coincident import CoincidentFaces
from ..geometry.frames import RAY_OFFSET_REL, tangent_frames
from ..geometry.scene import (
    Scene,
    geometric_normals,
    interpolated_normals,
    triangle_emission,
)
from ..shading.bump import relief_sky_factor, scene_normals
from ..shading.direct_light import diffuse_at
from ..shading.material_maps import translucent_colours
from ..shading.world_light import (
    RAYS_PER_CALL,
    cosine_directions,
    cosine_ray_count,
    world_lit,
    world_radiance,
)
from . import elements
from . import patches as patching
from .emitters import (
    AWAY,
    CLEAR,
    HIDDEN,
    UNKNOWN,
    Emitters,
    clear_shafts,
    emitter_irradiance,
    thinned_side,
)
from .form_factors.sampling import sample_patches
from .lamps import LampShadows, lamp_irradiance
from .settings import FinalGatherSettings
from .sheets import flat_sheets

# A patch this little open (fraction of its sample points outside every solid) is not rescaled
# further: its indirect irradiance rests on too few points to be stretched over the rest.
MIN_OPEN_FRACTION = 0.25
# Receivers gathered at once: (receivers x visibility rays) temporaries of ~100 B per ray.
GATHER_CHUNK = 1 << 14
# A receiver on an element whose indirect light differs between its corners by more than
# STEEP_RATIO times their mean (in any channel), or UNEVEN_RATIO times on a patch DWARF_RATIO
# times larger than the smallest patch at its corners, gathers it by rays too
# (`FinalGather.uneven`): the element holds a mean over light it cannot shape, and small
# patches' means pull the corners they share with a large one, as a box's lid under the small
# loops of its bow, which reflect a blue of 1 between them (an imported gift box's lid showed
# 4x Cycles' light beside the bow). Elements of a smooth fall-off keep their fit, whose linear
# pieces follow it better than 64 rays do (a floor's light off the wall it meets: within 8.5%,
# the rays 21%; `test_elements.py`). An imported Christmas scene against Cycles: relMSE 3.6e-3
# (7.1e-3 from the elements; 3.3e-3 with a ratio of 1 everywhere, 6.3e-3 at 1 on dwarfed
# patches alone).
STEEP_RATIO = 1.5
UNEVEN_RATIO = 1.0
DWARF_RATIO = 4.0
# A receiver whose smooth normal leans further than this from its face (cosine) gathers its
# indirect light by rays about that normal (`ray_gathered_irradiance`): the patches hold what
# their faces receive, Cycles shades with the smooth normal. A mesh smoothed across its corners (a
# low-poly room whose normals lean 40 degrees from its walls) showed the walls' light where
# Cycles showed the tilted normals'. 10 degrees: a smooth sphere of 48 segments leans 4 at most.
TILT_COS = float(np.cos(np.radians(10.0)))
# Receivers are pulled this fraction of the way to their triangle's centroid before the gather:
# the point-to-polygon factor is 0 for a point ON a polygon's plane, so a mesh corner shared with
# a perpendicular wall would see nothing of that wall; 1e-4 of a triangle is far above the
# factor's PLANE_EPS (1e-10) and far below any detail a texel or a vertex colour shows.
RECEIVER_INSET = 1e-4
# Surfaces an enclosure probe walks through at most (`enclosed`): each solid it passes through
# whole costs two; beyond this it counts as open (a receiver is lit rather than wrongly dark).
MAX_CROSSINGS = 8
# Probe rays at 45 degrees (after the normal ray): their tangent-frame directions.
_PROBE_TILTS = ((1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0))


@dataclass(frozen=True, eq=False)
class Visibility:
    """What the gather's rays found at M receivers, for neighbouring receivers to reuse.

    emitters  (M, K) int8  per emitter triangle: UNKNOWN, HIDDEN, CLEAR or AWAY
    inside    (M,) int8    -1 unknown, 0 open, 1 inside a closed solid (`enclosed`)

    Given to `exitance` as `known`, a CLEAR or HIDDEN emitter takes share 1 or 0 without rays and
    a known `inside` skips the probes; `visibility_out` receives what a call found."""

    emitters: np.ndarray
    inside: np.ndarray

    @classmethod
    def unknown(cls, count: int, emitter_count: int) -> Visibility:
        return cls(np.full((count, emitter_count), UNKNOWN, np.int8), np.full(count, -1, np.int8))

    @classmethod
    def joined(cls, parts: list[Visibility]) -> Visibility:
        return cls(np.concatenate([v.emitters for v in parts]),
                   np.concatenate([v.inside for v in parts]))

    def take(self, rows: np.ndarray) -> Visibility:
        return Visibility(self.emitters[rows], self.inside[rows])

    def put(self, rows: np.ndarray, found: Visibility) -> None:
        """In place: receivers `rows` take what `found` (one per row) says."""
        self.emitters[rows], self.inside[rows] = found.emitters, found.inside

    def agreed(self, sources: np.ndarray) -> Visibility:
        """(R,) receivers each lying among receivers `sources` (R, S) of these (-1: none, which
        makes the receiver UNKNOWN): per emitter CLEAR where every source is CLEAR or AWAY and one
        is CLEAR, HIDDEN likewise, UNKNOWN otherwise; inside where every source agrees. A shadow
        edge or an enclosure's wall passing between the sources leaves them disagreeing, so the
        receiver casts its own rays; what this misses fits between the sources without touching
        one (the lattice's caveat, `bake_targets.py`)."""
        missing = (sources < 0).any(axis=1)
        states = self.emitters[np.maximum(sources, 0)]  # (R, S, K)
        facing = states != AWAY
        clear = np.all((states == CLEAR) | ~facing, axis=1) & np.any(facing, axis=1)
        hidden = np.all((states == HIDDEN) | ~facing, axis=1) & np.any(facing, axis=1)
        emitters = np.where(clear, CLEAR, np.where(hidden, HIDDEN, UNKNOWN)).astype(np.int8)
        emitters[missing] = UNKNOWN
        inside = self.inside[np.maximum(sources, 0)]  # (R, S)
        agree = (inside == inside[:, :1]).all(axis=1) & ~missing
        return Visibility(emitters, np.where(agree, inside[:, 0], -1).astype(np.int8))


def enclosed(points: np.ndarray, normals: np.ndarray, intersect, triangle_normals: np.ndarray,
             offset: float, coincident: CoincidentFaces | None = None,
             sheets: np.ndarray | None = None) -> np.ndarray:
    """(M,) bool: receivers inside a closed solid, every probe ray leaving one.

    intersect(origins, directions) -> hits with `.tri` (-1: miss) and `.t` is the BVH's
    closest-hit query; triangle_normals (T, 3) the scene's front normals. A probe walks through
    the surfaces on its way, counting a back face +1 (it leaves a solid) and a front face -1 (it
    enters one), and finds an inside when the count reaches +1: a solid it enters and leaves
    again does not end it, so a point of a block that a second block passes through, looking out
    through the second, still finds the first one's inside (two interpenetrating boxes on a
    generated room's floor: the floor under both was lit). A miss, or MAX_CROSSINGS surfaces
    without reaching +1, is open. A face with an opposite face in its plane under the hit
    (`coincident`: a box's bottom on the floor, which the closest-hit query's tie hides; a sheet
    modelled double-sided) is crossed as the pair's back face first, an exit where a solid lies
    behind it, then its front face. The normal's probe decides for most
    receivers; those it finds inside are probed four more times at 45 degrees, so a single-sided
    sheet above a floor does not enclose it. sheets (T,) bool, when given: triangles of flat
    one-sided sheets (`sheets.flat_sheets`: a card, a decal, a rug), which bound no solid: a
    probe passes them counting nothing (a 2 m card of alpha holes 1.4 cm over a floor enclosed
    all of the floor under it, at any tilt, and the gather divided that floor's light by its
    small open part: 1.5 to 5 times too bright through the holes)."""
    def leaves(rows: np.ndarray, dirs: np.ndarray) -> np.ndarray:
        origins = points[rows] + offset * normals[rows]
        count = np.zeros(len(rows), np.int64)  # back faces crossed less front faces crossed
        found = np.zeros(len(rows), bool)
        live = np.arange(len(rows))
        for _ in range(MAX_CROSSINGS):
            hits = intersect(np.ascontiguousarray(origins[live]), np.ascontiguousarray(dirs[live]))
            tri, t = np.asarray(hits.tri), np.asarray(hits.t)
            hit = tri >= 0
            live, tri, t = live[hit], tri[hit], t[hit]
            back = np.einsum("ij,ij->i", triangle_normals[tri], dirs[live]) > 0.0
            # A pair of opposite faces in one plane is crossed as both: its back member first
            # (+1: an exit where a solid lies behind it, else nothing to leave), then the front.
            paired = np.zeros(len(live), bool)
            exits = back.copy()
            if coincident is not None:
                at = origins[live] + t[:, None] * dirs[live]
                paired = coincident.covered(tri, at)
                rows = np.flatnonzero(paired)
                exits[rows] = np.where(back[rows], coincident.solid[tri[rows]],
                                       coincident.covered(tri[rows], at[rows], solid=True))
            neither = paired if sheets is None else paired | sheets[tri]  # crossed as nothing
            exits &= ~neither | paired
            before = count[live]
            out = before + np.where(exits, 1, np.where(neither, 0, -1)) > 0
            count[live] = before + np.where(neither, 0, np.where(back, 1, -1))
            found[live[out]] = True
            live, t = live[~out], t[~out]
            if live.size == 0:
                break
            # On past the surface (dirs are unit: t is in m).
            origins[live] += (t + offset)[:, None] * dirs[live]
        return found

    inside = np.zeros(len(points), bool)
    if len(points) == 0:
        return inside
    rows = np.flatnonzero(leaves(np.arange(len(points)), normals))
    if rows.size:
        t1, t2 = tangent_frames(normals[rows])
        # The four tilted probes in one BVH call (a call costs ~2 ms besides its rays).
        dirs = np.concatenate([(normals[rows] + a * t1 + b * t2) / np.sqrt(2.0)
                               for a, b in _PROBE_TILTS])
        keep = leaves(np.tile(rows, len(_PROBE_TILTS)), dirs).reshape(len(_PROBE_TILTS), -1)
        inside[rows[keep.all(axis=0)]] = True
    return inside


@dataclass(frozen=True, eq=False)
class FinalGather:
    """Everything the gather reads at receivers, prepared once per solution (`prepare`)."""

    scene: Scene
    bvh: object  # kernels.geometry.bvh.BVH over scene.triangles
    emitters: Emitters
    clear: np.ndarray  # (N, K) bool: patch i sees emitter triangle k whole (`clear_shafts`)
    open_above: np.ndarray  # (N,) bool: no back face over patch i (`shafts.open_above`)
    patches: patching.Patches  # the solution's N patches
    element_levels: int  # k: the indirect light is held on 4^k elements per patch (`elements.py`)
    corner_indirect: np.ndarray  # (N 4^k, 3, 3) indirect irradiance at element corners, W/m^2
    triangle_normals: np.ndarray  # (T, 3) float64
    coincident: CoincidentFaces | None  # opposite faces in one plane (`enclosed`); None: no probes
    emission: np.ndarray  # (T, 3) float64 pi L_e per scene triangle, W/m^2
    offset: float  # m, ray offset off surfaces
    area_samples_per_side: int
    settings: FinalGatherSettings
    stats: dict
    # What the lamps' and emitters' shadow rays meet (`levels.SolveContext.shadows`); None: `bvh`
    shadows: LampShadows | None = None
    # (T,) bool: triangles of flat one-sided sheets, which enclose nothing (`enclosed`); None: none
    sheets: np.ndarray | None = None

    @cached_property
    def uneven(self) -> np.ndarray:
        """(N 4^k,) bool: elements whose indirect light differs between their corners by more
        than STEEP_RATIO times its mean there, in any channel, or UNEVEN_RATIO times on patches
        DWARF_RATIO times larger than the smallest patch at any of their corners (their
        receivers gather it by rays)."""
        c = self.corner_indirect
        ratio = np.max((c.max(axis=1) - c.min(axis=1)) / np.maximum(c.mean(axis=1), 1e-12),
                       axis=1)
        dwarfs = self.patches.areas > DWARF_RATIO * patching.smallest_neighbours(self.patches)
        return (ratio > STEEP_RATIO) | ((ratio > UNEVEN_RATIO)
                                        & np.repeat(dwarfs, 4 ** self.element_levels))

    def shadow_occluded(self) -> LampShadows:
        """The lights' shadow-ray query (origins, directions, t_min, t_max) -> (R,) bool, each
        lamp under shadow linking taking its own."""
        return LampShadows(self.bvh) if self.shadows is None else self.shadows

    def opened(self, open_: np.ndarray) -> Visibility:
        """What M receivers are known to be (open_ (M,) bool: inside no solid, which their
        probes would find), the rest unknown."""
        known = Visibility.unknown(len(open_), len(self.emitters.triangles))
        known.inside[open_] = 0
        return known

    def thinned(self, k: int) -> FinalGather:
        """This gather for receivers averaged k x k to one value: ceil(n / k) shadow points per
        side where it had n, emitters' (`Emitters.thinned`) and area lights' alike."""
        return replace(self, emitters=self.emitters.thinned(k),
                       area_samples_per_side=thinned_side(self.area_samples_per_side, k))


def camera_enclosed(gather: FinalGather, camera) -> bool:
    """Whether the camera's central ray starts inside a closed solid (`enclosed`). Where it does
    not, every point it sees without refraction, on a front face, lies inside none either: no
    solid's surface lies between them."""
    if camera is None:
        return False
    to_world = np.asarray(camera.matrix_world, np.float64)
    forward = -to_world[:3, 2] / np.linalg.norm(to_world[:3, 2])
    start = to_world[:3, 3] + camera.clip_start * forward
    return bool(enclosed(start[None], forward[None], gather.bvh.intersect,
                         gather.triangle_normals, gather.offset, gather.coincident,
                         gather.sheets)[0])


def _occluded(bvh):
    return lambda o, d, t0, t1: bvh.occluded(o, d, t0, t1)


@dataclass(frozen=True, eq=False)
class PatchSolution:
    """A solution over N patches, as the gather reads it, W/m^2.

    radiosity, emitted, reflectance, direct (N, 3): the solution B, pi L_e, rho and the first
    shot's irradiance of `patches` (lamps and the shot emitters, which the solver did not carry
    again: `sources.first_shot`); clear (N, K): `clear_shafts` of these patches when the first
    shot already has it (None: tested here); world (N, 3): the world's irradiance on them
    (`sources.world_shot`, None: none)."""

    patches: patching.Patches
    radiosity: np.ndarray
    emitted: np.ndarray
    reflectance: np.ndarray
    direct: np.ndarray
    clear: np.ndarray | None = None
    world: np.ndarray | None = None


def prepare(scene: Scene, solution: PatchSolution, emitters: Emitters, bvh, smooth_angle: float,
            area_samples_per_side: int, settings: FinalGatherSettings,
            shadows: LampShadows | None = None) -> FinalGather:
    """The patch-level half: the indirect irradiance (W/m^2, RGB) at the corners of the patches,
    or of their elements (`elements.py`, within `settings.element_pairs`).

    What arrived at a patch less the first shot is what the solver carried between patches, the
    same numbers it solved with, so no sampling noise of the direct light leaks into the indirect
    part. Elements gather it afresh from the patches' B, plus the world's light of their patch.
    shadows: what the receivers' shadow rays to lamps and emitters meet (`FinalGather.shadows`;
    None: `bvh`)."""
    patches, radiosity, emitted = solution.patches, solution.radiosity, solution.emitted
    reflectance, direct = solution.reflectance, solution.direct
    clear, world = solution.clear, solution.world
    flat = scene.triangles.reshape(-1, 3).astype(np.float64)
    scale = float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0))) if len(flat) else 1.0
    offset = RAY_OFFSET_REL * scale
    tri_normals = geometric_normals(scene.triangles)
    coincident = None
    sheets = None
    count = len(patches)
    points, weights = sample_patches(patches.corners, settings.patch_samples, "midpoint")
    samples = points.shape[1]
    pts = points.reshape(-1, 3)
    nrm = np.repeat(patches.normals, samples, axis=0)
    arrived = np.divide(radiosity - emitted, reflectance, out=np.zeros_like(radiosity),
                        where=reflectance > 0.0)
    # Negative only by the solver's tolerance; the receivers' sums are clamped (`exitance`).
    indirect = arrived - direct
    # Idle patches (`sources.with_idle`: nothing reflected) hold no receiver that gathers
    # (`exitance` skips black ones) and their indirect 0 is not what arrives there: they weigh 0
    # in the corner fit, as enclosed patches do, and cast no probes.
    reflects = reflectance.max(axis=1) > 0.0
    weight = reflects.astype(np.float64)  # per patch, of its area in the corner fit
    open_fraction = np.ones(count)
    unroofed = np.ones(count, bool)  # without probes nothing counts as enclosed
    if settings.enclosure_probes:
        coincident = CoincidentFaces.find(scene.triangles, tri_normals, scene.object_ids,
                                           offset)
        flat = flat_sheets(scene)
        sheets = flat[scene.object_ids] if flat.any() else None
        # Patches no back face hangs over cannot be enclosed: their receivers cast no probe.
        unroofed[reflects] = shafts.open_above(patches.corners[reflects], patches.normals[reflects],
                                               scale, bvh, offset)
        inside = np.zeros((count, samples), bool)
        probed = np.flatnonzero(~unroofed)
        if probed.size:
            rows = (probed[:, None] * samples + np.arange(samples)).ravel()
            inside[probed] = enclosed(pts[rows], nrm[rows], bvh.intersect, tri_normals,
                                      offset, coincident, sheets).reshape(-1, samples)
        open_fraction = np.where(inside.any(axis=1), np.einsum("ns,ns->n", weights, ~inside), 1.0)
        # The solver averaged each patch over its enclosed part too, which receives nothing.
        indirect /= np.maximum(open_fraction, MIN_OPEN_FRACTION)[:, None]
        # An enclosed patch weighs 0: its corners follow its open neighbours
        # (`fitted_corner_values` floors the weights, so none is left undetermined).
        weight = weight * open_fraction
    # What each patch sends on: its B less the emission of the gathered emitters.
    reflected = np.maximum(radiosity - emitted * emitters.covers(patches.parent)[:, None], 0.0)
    levels = elements.element_levels(int(reflects.sum()),
                                     int(np.count_nonzero(reflected.max(axis=1) > 0.0)),
                                     settings.element_pairs)
    if levels:
        # A patch that straddles a solid's wall sends and receives through its open part only,
        # while its rays (the visibility, the world's) averaged the enclosed part's darkness in.
        open_part = np.maximum(open_fraction, MIN_OPEN_FRACTION)[:, None]
        fine, indirect = elements.element_irradiance(
            scene, patches, reflected / open_part, reflects, levels, _occluded(bvh), offset,
            np.random.default_rng(settings.seed + 4))
        if world is not None:
            indirect += np.repeat(world, 4 ** levels, axis=0)[:, None]
        indirect /= np.repeat(open_part, 4 ** levels, axis=0)[:, None]
        # Point values at the corners already: where patches meet, their corners' values (each
        # gathered with its own patch's visibility) are averaged, open patches before enclosed.
        weights = fine.areas * np.maximum(np.repeat(weight, 4 ** levels), patching.FIT_MIN_WEIGHT)
        corner = patching.corner_average(replace(fine, areas=weights), indirect, smooth_angle,
                                         scale)
    else:
        corner = patching.fitted_corner_values(replace(patches, areas=patches.areas * weight),
                                               indirect, smooth_angle, scale)
    if clear is None:
        clear = clear_shafts(patches, emitters, bvh, offset)
    stats = {"emitter_triangles": int(len(np.unique(emitters.index))),
             # back sides that face open space emit too (`emitters.open_backs`)
             "emitter_back_sides": int(len(emitters.index) - len(np.unique(emitters.index))),
             "elements": count * 4 ** levels, "element_levels": levels,
             "clear_shafts": int(clear.sum()),
             "unroofed_patches": int(unroofed.sum()),
             "emitter_rays_per_receiver": int((emitters.per_side ** 2).sum()),
             "enclosed_patches": int((open_fraction == 0.0).sum()),
             "straddling_patches": int(((open_fraction > 0.0) & (open_fraction < 1.0)).sum())}
    return FinalGather(scene, bvh, emitters, clear, unroofed, patches, levels, corner, tri_normals,
                       coincident, np.pi * triangle_emission(scene), offset, area_samples_per_side,
                       settings, stats, shadows, sheets)


def exitance(gather: FinalGather, tri: np.ndarray, bary: np.ndarray,
             reflected_only: bool = False, known: Visibility | None = None,
             visibility_out: Visibility | None = None,
             strata: Strata | None = None, reflected=None, albedo: np.ndarray | None = None
             ) -> np.ndarray:
    """(M, 3) exitance B(x) W/m^2 at receivers given as scene triangles (M,) and barycentric
    coordinates (M, 3): E + rho (H_direct + H_indirect), or without E (`reflected_only`), and
    for a translucent surface (`Material.translucent`: tau) tau times the irradiance on its
    back (`side_irradiance`): the lights', and with `translucent_bounce` the surfaces' exitance
    `reflected(tri, bary)` W/m^2 too.

    known: what neighbouring receivers' rays agree on (`Visibility.agreed`), taken without rays
    of its own; visibility_out (M receivers) receives what this call found, for later neighbours.
    The lamps' shadow rays are cast every time. A receiver that reflects nothing diffusely
    (`direct_light.diffuse_at`: black, metal, glass) casts no ray and stays UNKNOWN.
    strata (stratum (M,), m): the receivers are m sub-samples of pixels, which share out the
    emitters' points (`emitters.emitter_irradiance`). albedo (M, 3): the receivers' base
    colours, when given (a pixel's texture mean, `pixel_texture.cell_albedo`)."""
    scene = gather.scene
    tri = np.asarray(tri, np.int64)
    bary = np.asarray(bary, np.float64)
    out = np.zeros((len(tri), 3))
    # A seed per call keeps repeated evaluations of the same receivers identical.
    rng = np.random.default_rng(gather.settings.seed + 1)
    tau_of = translucent_colours(scene.materials)
    passed = reflected if gather.settings.translucent_bounce else None
    for a in range(0, len(tri), GATHER_CHUNK):
        t, b = tri[a:a + GATHER_CHUNK], bary[a:a + GATHER_CHUNK]
        rho = diffuse_at(scene, t, b, albedo=None if albedo is None else albedo[a:a + GATHER_CHUNK])
        lit = np.flatnonzero(rho.max(axis=1) > 0.0)
        given = None if known is None else known.take(a + lit)
        h, found = _irradiance(gather, t[lit], b[lit], given, rng, strata_rows(strata, a + lit),
                               reflected)
        if visibility_out is not None:
            visibility_out.put(a + lit, found)
        value = np.zeros((len(t), 3))
        value[lit] = rho[lit] * h
        tau = tau_of[scene.material_ids[t]]
        through = np.flatnonzero(tau.max(axis=1) > 0.0)
        if through.size:
            value[through] += tau[through] * side_irradiance(gather, t[through], b[through],
                                                             -1.0, passed, rng)
        if not reflected_only:
            value += gather.emission[t]
        out[a:a + GATHER_CHUNK] = value
    return out


def back_exitance(gather: FinalGather, tri: np.ndarray, bary: np.ndarray, reflected=None
                  ) -> np.ndarray:
    """(M, 3) exitance W/m^2 of the BACK side of receivers (scene triangles (M,), barycentrics
    (M, 3)): what a camera that sees a surface from behind shows, as Cycles shades every surface
    on the side it is seen from:

        B_back(x) = pi L_e + rho(x) H_back(x) + tau(x) H_front(x)

    H_back the light on the back (`side_irradiance`, its bounce off surfaces `reflected`
    W/m^2), and for a translucent surface (`Material.translucent`: tau) the irradiance on its
    front passed through: the lights', and with `translucent_bounce` the bounce too. The
    emission counts on both sides (Cycles' emission shader glows on either face). The patches
    are one-sided, so this is the one place where light reflected onto a back is known: one
    bounce from the front sides' solution (an inside-out mesh, a plane lit from below)."""
    scene = gather.scene
    tri = np.asarray(tri, np.int64)
    bary = np.asarray(bary, np.float64)
    out = np.zeros((len(tri), 3))
    rng = np.random.default_rng(gather.settings.seed + 2)  # a seed per call, as `exitance`
    tau_of = translucent_colours(scene.materials)
    passed = reflected if gather.settings.translucent_bounce else None
    for a in range(0, len(tri), GATHER_CHUNK):
        t, b = tri[a:a + GATHER_CHUNK], bary[a:a + GATHER_CHUNK]
        rho = diffuse_at(scene, t, b)
        lit = np.flatnonzero(rho.max(axis=1) > 0.0)  # black ones cast no ray, as in `exitance`
        value = gather.emission[t]
        value[lit] += rho[lit] * side_irradiance(gather, t[lit], b[lit], -1.0, reflected, rng)
        tau = tau_of[scene.material_ids[t]]
        through = np.flatnonzero(tau.max(axis=1) > 0.0)
        if through.size:
            value[through] += tau[through] * side_irradiance(gather, t[through], b[through],
                                                             1.0, passed, rng)
        out[a:a + GATHER_CHUNK] = value
    return out


def side_irradiance(gather: FinalGather, t: np.ndarray, b: np.ndarray, side: float, reflected,
                    rng: np.random.Generator) -> np.ndarray:
    """(M, 3) irradiance W/m^2 on one side of receivers (scene triangles t (M,), barycentrics
    b (M, 3); side 1: the front, -1: the back): the lamps' and the gathered emitters' direct
    light, shadow rays leaving on that side (a sheet lit from behind, a wall seen from outside a
    lit room: 0 on the back), and what `world_rays` rays about its normal find
    (`ray_gathered_irradiance`: the world, and surfaces' `reflected(tri, bary)` exitance W/m^2;
    None: 0).

    With `reflected` None, the lights' light alone: what a translucent surface passes from one
    side to the other in Cycles' radiosity model, whose translucent bounce is a transmission
    bounce (0 of them): its light sampling reaches through (lamps, emitters, the world), light
    reflected off other surfaces does not (`FinalGatherSettings.translucent_bounce`)."""
    scene = gather.scene
    inset, points = _inset_points(scene, t, b)
    facing = side * gather.triangle_normals[t]
    normals, smooth = shading_normals(scene, t, inset, gather.triangle_normals[t])
    occluded = gather.shadow_occluded()
    h = emitter_irradiance(gather.emitters, points, side * normals, occluded, gather.offset, rng,
                           lift=facing)
    h += lamp_irradiance(scene, points, side * normals, occluded, gather.offset,
                         gather.area_samples_per_side, lift=facing,
                         smooth=None if smooth is None else side * smooth,
                         objects=scene.object_ids[t])
    if gather.settings.world_rays:
        h += ray_gathered_irradiance(gather, points, facing, side * normals,
                                     gather.settings.world_rays, reflected, rng)
    return h


def ray_gathered_irradiance(gather: FinalGather, points: np.ndarray, faces: np.ndarray,
                            normals: np.ndarray, rays: int, reflected, rng: np.random.Generator
                            ) -> np.ndarray:
    """(M, 3) W/m^2: the light from the world and other surfaces (`_seen_along`, the solution's
    exitance `reflected`) that reaches points (M, 3) m about their shading normals (M, 3),
    gathered by `rays` rays cosine-distributed about them, leaving `offset` off the side their
    faces' unit normals faces (M, 3) point to, those below that side counting 0 as Cycles'
    diffuse closure counts them: pi times the mean radiance. What a receiver seen from behind
    gathers (`side_irradiance`), and one whose smooth normal leans from its face: the patches
    hold what their faces receive, which neither leans with the normal nor, on a patch metres
    wide, knows the object beside the receiver (a low-poly room whose normals lean 40 degrees
    from its walls came within relMSE 2.0e-3 of Cycles gathered so; 1.27e-2 from the patches,
    5.9e-3 with the difference between the two cosines gathered by rays instead)."""
    k = cosine_ray_count(rays)
    out = np.zeros((len(points), 3))
    glow = gather.emission.copy()  # pi L_e of the emissive triangles not gathered
    glow[gather.emitters.index] = 0.0
    per_call = max(1, RAYS_PER_CALL // k)
    for a in range(0, len(points), per_call):
        p, f, n = points[a:a + per_call], faces[a:a + per_call], normals[a:a + per_call]
        dirs = cosine_directions(n, rays, rng)  # (P, k, 3)
        above = np.einsum("pkc,pc->pk", dirs, f) > 0.0
        seen = _seen_along(gather, np.repeat(p + gather.offset * f, k, axis=0),
                           dirs.reshape(-1, 3), reflected, glow).reshape(len(p), k, 3)
        out[a:a + per_call] = np.einsum("pkc,pk->pc", seen, above) / k
    return out


def _seen_along(gather: FinalGather, origins: np.ndarray, dirs: np.ndarray, reflected,
                glow: np.ndarray) -> np.ndarray:
    """(N, 3) pi times the radiance along rays (origins, unit dirs (N, 3)) from the world and the
    solution: a ray that escapes sees the world (when it lights the scene); one that meets a
    surface's front sees its `reflected(tri, bary)` exitance W/m^2 (None: 0), plus its
    triangle's `glow` (T, 3) W/m^2: the emission of emissive triangles the gathered emitters
    leave out (those are counted exactly by `emitter_irradiance`), which glow on the back side
    too."""
    hits = gather.bvh.intersect(np.ascontiguousarray(origins), np.ascontiguousarray(dirs))
    tri = np.asarray(hits.tri, np.int64)
    seen = np.zeros((len(dirs), 3))
    met = tri >= 0
    if world_lit(gather.scene) and (~met).any():
        seen[~met] = np.pi * world_radiance(gather.scene, dirs[~met])
    seen[met] = glow[tri[met]]
    facing = np.flatnonzero(met)
    facing = facing[np.einsum("ij,ij->i", gather.triangle_normals[tri[facing]],
                              dirs[facing]) < 0.0]
    if reflected is not None and facing.size:
        u, v = hits.u[facing].astype(np.float64), hits.v[facing].astype(np.float64)
        seen[facing] += reflected(tri[facing], np.stack([1.0 - u - v, u, v], axis=1))
    return seen


def _inset_points(scene: Scene, t: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Receivers' barycentrics moved `RECEIVER_INSET` towards their triangle's centroid (M, 3),
    and the world points there (M, 3), m."""
    inset = (1.0 - RECEIVER_INSET) * b + RECEIVER_INSET / 3.0
    return inset, np.einsum("mk,mkc->mc", inset, scene.triangles[t].astype(np.float64))


def shading_normals(scene: Scene, tri: np.ndarray, bary: np.ndarray, geometric: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray | None]:
    """(M, 3) unit shading normals at receivers (triangles (M,), barycentrics (M, 3)): the
    corner normals interpolated, as Cycles shades a smooth mesh (its DIFFUSE bake weighs light by
    the cosine to this normal, not the facet's), perturbed by the material's Bump or Normal Map
    node as Cycles' bake does (`bump.scene_normals`). A normal that points behind its face (a
    mesh whose normals are flipped against its winding, a corner at a sharp fold) stays so, as
    Cycles shades it: dark to the light in front of the face (an imported block whose normals
    all pointed inwards drew black in Cycles and lit in this gather, relMSE 6.5). Flat faces'
    corner normals are their face normal, so nothing changes there. Also the normals before the
    perturbation (M, 3), which `lamps.lamp_irradiance` weighs the relief's shadowing by, or None
    where no receiver's material has relief. geometric (M, 3): the faces' unit normals."""
    smooth = interpolated_normals(scene, tri, bary, geometric)
    normals = scene_normals(scene, tri, bary, smooth)
    return normals, (None if normals is smooth else smooth)


def _irradiance(gather: FinalGather, t: np.ndarray, b: np.ndarray, known: Visibility | None,
                rng: np.random.Generator, strata: Strata | None = None, reflected=None
                ) -> tuple[np.ndarray, Visibility]:
    """(M, 3) irradiance H_direct + H_indirect W/m^2 at receivers (triangles t, barycentrics b)
    and what its rays found (`exitance`); H_indirect about the smooth normals where they lean
    from the faces (`ray_gathered_irradiance`, the solution's exitance `reflected`)."""
    scene = gather.scene
    found = Visibility.unknown(len(t), len(gather.emitters.triangles))
    inset, points = _inset_points(scene, t, b)
    geometric = gather.triangle_normals[t]
    normals, smooth = shading_normals(scene, t, inset, geometric)
    # Located at the inset point: the one the rays leave from must lie in the patch whose shaft
    # clears it.
    patch, local = patching.locate(gather.patches, t, inset)
    element, local = patching.descend(local, gather.element_levels)
    element = np.where(patch >= 0, patch * 4 ** gather.element_levels + element, -1)
    occluded = gather.shadow_occluded()
    # Enclosure first: a receiver inside a solid gets no light, so it casts no shadow ray (the
    # floor under a block: a third of the edge texels' sub-texel points on the Cornell box).
    found.inside[:] = 0  # receivers no back face hangs over are open
    if gather.settings.enclosure_probes:
        probed = np.flatnonzero(~gather.open_above[patch])
        if known is not None:
            found.inside[probed] = known.inside[probed]
            probed = probed[found.inside[probed] < 0]
        found.inside[probed] = enclosed(points[probed], geometric[probed], gather.bvh.intersect,
                                        gather.triangle_normals, gather.offset, gather.coincident,
                                        gather.sheets)
    inside = found.inside == 1
    found.emitters[inside] = HIDDEN  # nothing of any emitter reaches inside
    outside = np.flatnonzero(~inside)
    h = np.zeros((len(t), 3))
    states = np.full((outside.size, found.emitters.shape[1]), UNKNOWN, np.int8)
    shared = strata_rows(strata, outside)
    h[outside] = emitter_irradiance(gather.emitters, points[outside], normals[outside],
                                    occluded, gather.offset, rng,
                                    clear=gather.clear[patch[outside]],
                                    known=None if known is None else known.emitters[outside],
                                    states_out=states, lift=geometric[outside],
                                    strata=shared)
    found.emitters[outside] = states
    h[outside] += lamp_irradiance(scene, points[outside], normals[outside], occluded,
                                  gather.offset, gather.area_samples_per_side,
                                  lift=geometric[outside], strata=shared,
                                  smooth=None if smooth is None else smooth[outside],
                                  objects=scene.object_ids[t[outside]])
    indirect = patching.interpolate(gather.corner_indirect, element[outside], local[outside])
    smoothed = normals if smooth is None else smooth
    if gather.settings.tilt_rays and reflected is not None:
        by_rays = np.flatnonzero((np.einsum("ij,ij->i", smoothed[outside], geometric[outside])
                                  < TILT_COS) | gather.uneven[np.maximum(element[outside], 0)])
        if by_rays.size:
            rows = outside[by_rays]
            indirect[by_rays] = ray_gathered_irradiance(gather, points[rows], geometric[rows],
                                                     smoothed[rows], gather.settings.tilt_rays,
                                                     reflected, rng)
    if smooth is not None:  # gathered about the smooth normals: a relief's tilt takes less
        indirect *= relief_sky_factor(smooth[outside], normals[outside])[:, None]
    h[outside] += indirect
    np.maximum(h, 0.0, out=h)
    return h, found
