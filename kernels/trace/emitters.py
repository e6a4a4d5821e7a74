"""The tracer's lights as point samples: area lights and emissive meshes on fixed patterns."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..bake.camera_view import stratified_offsets
from ..geometry.scene import Light, Scene, geometric_normals, triangle_emission
from ..shading import lights as light_units

if TYPE_CHECKING:
    from .settings import TracerSettings

# An emissive object of more triangles than this is one light of this many triangles' samples
# (`mesh_light_samples`): each triangle its own n x n grid would make an emissive ball of 80
# triangles cast 1280 shadow rays a hit.
MESH_LIGHT_TRIANGLES = 4
# A finer mesh light's samples each hold this many finer ones over the same stretch of its
# surface, taken instead of it by the hits closer to it than REFINE_REACH x its patch's size
# (sqrt of the area it stands for): there the patch is no point, and its one sample lit a floor
# touching an emissive ball in bright and dark spots (`Tracer._area_direct`).
FINE_SPLIT = 16
REFINE_REACH = 2.0


@dataclass
class Emitters:
    """Every light as a set of point samples: positions, a radiometric weight, and the kind."""

    lights: list  # kernel Light objects (point, spot, sun handled analytically)
    area_points: np.ndarray  # (S, 3) sample positions on area lights / emissive triangles
    area_normals: np.ndarray  # (S, 3) emitting side's normal
    area_radiance_da: np.ndarray  # (S, 3) radiance times the sample's area, W/sr
    area_da: np.ndarray  # (S,) m^2, the emitting area the sample stands for
    area_two_sided: np.ndarray  # (S,) bool: emissive meshes emit from both sides in Cycles
    area_local: np.ndarray  # (S,) int: the sample's index among its emitter's samples
    area_count: np.ndarray  # (S,) int: how many samples its emitter has
    area_emitter: np.ndarray  # (S,) int: the sample's light, an index into `hulls`
    # Per light: triangles (K, 3, 3) world m whose convex hull holds every sample of it (an area
    # lamp's rectangle, or the bounding one of a disk; a small emissive mesh's triangles), or
    # None where that would cost more shaft tests than it saves (`shadow_shafts.py`).
    hulls: list
    # The finer samples (`FINE_SPLIT` each) of the samples that have them, in the same units:
    # sample s's are rows fine_first[s] .. fine_first[s] + fine_count[s] (count 0: none).
    fine_points: np.ndarray  # (C, 3)
    fine_normals: np.ndarray  # (C, 3)
    fine_radiance_da: np.ndarray  # (C, 3)
    fine_da: np.ndarray  # (C,)
    fine_first: np.ndarray  # (S,) int
    fine_count: np.ndarray  # (S,) int


@dataclass(frozen=True, eq=False)
class EmitterReach:
    """What each area emitter (`Emitters.hulls` order: the area lamps, then emissive meshes)
    reaches, from its lamp's light and shadow linking and ray visibility (`Light.receivers`,
    `Light.blockers`, `Light.hidden_from`); an emissive mesh reaches everything."""

    cover: np.ndarray  # (E,) int: its shadow rays' coverage in `Tracer.link_covers` (-1: the scene's)
    diffuse: np.ndarray  # (E,) bool: it lights diffuse bases and sheens
    glossy: np.ndarray  # (E,) bool: it lights the glossy lobes
    objects: np.ndarray | None  # (E, O) bool: the objects it lights; None: every one, by every one


def emitter_reach(area_lamps: list[Light], count: int, object_count: int,
                  cover_of: dict) -> EmitterReach:
    """`EmitterReach` of `count` area emitters whose first ones are `area_lamps`, over a scene of
    `object_count` objects; cover_of: Light -> its coverage's index (lamps under shadow
    linking)."""
    cover = np.full(count, -1)
    diffuse, glossy = np.ones(count, bool), np.ones(count, bool)
    objects = None
    for e, lamp in enumerate(area_lamps):
        cover[e] = cover_of.get(lamp, -1)
        diffuse[e], glossy[e] = lamp.lights_diffuse, lamp.lights_glossy
        if lamp.receivers is not None:
            if objects is None:
                objects = np.ones((count, object_count), bool)
            objects[e] = lamp.receivers
    return EmitterReach(cover, diffuse, glossy, objects)


@dataclass
class Samples:
    """Point samples of emitting surfaces."""

    points: np.ndarray  # (S, 3) world m
    normals: np.ndarray  # (S, 3) the emitting side's (a mesh's: its face's)
    radiance_da: np.ndarray  # (S, 3) radiance times the area the sample stands for, W/sr
    da: np.ndarray  # (S,) m^2, that area

    @staticmethod
    def empty() -> Samples:
        return Samples(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))


def mesh_light_samples(scene: Scene, tri_ids: np.ndarray, n: int
                       ) -> tuple[Samples, np.ndarray, int, Samples | None]:
    """Shadow-ray targets on one object's emissive triangles `tri_ids`: the samples, each one's
    index among its emitter's samples (S,), that emitter's sample count (a triangle's, or the
    object's when it is one light), and the finer samples, FINE_SPLIT per sample in order
    (None: none).

    Up to MESH_LIGHT_TRIANGLES triangles, n x n stratified points on each (a folded square
    grid). A finer mesh is one light of MESH_LIGHT_TRIANGLES x n x n points in all, spread
    along the triangles' cumulative area in an order that follows the surface (`along_area`,
    `surface_order`), each standing for an equal share of the total: an emissive ball of 80
    triangles casts 64 shadow rays a hit, not 1280."""
    tris = scene.triangles[tri_ids].astype(np.float64)
    ng = geometric_normals(tris)
    area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    radiance = triangle_emission(scene)[tri_ids]
    if len(tri_ids) <= MESH_LIGHT_TRIANGLES:
        st = stratified_offsets(n)
        fold = st[:, 0] + st[:, 1] > 1.0
        st[fold] = 1.0 - st[fold][:, ::-1]
        bary = np.stack([1.0 - st[:, 0] - st[:, 1], st[:, 0], st[:, 1]], 1)  # (K, 3)
        k = len(bary)
        pts = np.einsum("kc,tcj->tkj", bary, tris).reshape(-1, 3)
        grid = Samples(pts, np.repeat(ng, k, axis=0),
                       np.repeat(radiance * (area / k)[:, None], k, axis=0), np.repeat(area / k, k))
        return grid, np.tile(np.arange(k), len(tri_ids)), k, None
    total = MESH_LIGHT_TRIANGLES * n * n
    if not area.sum() > 0.0:  # every triangle degenerate: nothing emits (and no nan CDF)
        return Samples.empty(), np.zeros(0, np.int64), total, None
    order = surface_order(tris.mean(axis=1))
    tris, ng, area, radiance = tris[order], ng[order], area[order], radiance[order]
    tiers = []
    for count in (total, total * FINE_SPLIT):
        pts, t, share = along_area(tris, area, count)
        tiers.append(Samples(pts, ng[t], radiance[t] * share, np.full(count, share)))
    return tiers[0], np.arange(total), total, tiers[1]


def along_area(tris: np.ndarray, area: np.ndarray, total: int) -> tuple[np.ndarray, np.ndarray, float]:
    """`total` points spread over triangles (T, 3, 3) of areas (T,) m^2 (some positive) by
    systematic sampling along their cumulative area: point i at (i + 1/2) / total of it, a
    triangle getting points in proportion to its area, each standing for an equal share of the
    total. Returns the points (total, 3), their triangles (total,) and that share (m^2).

    Point i lies in the stretch [i / total, (i + 1) / total), so the k points of k x total lie
    in the stretch of one of total: the finer samples of a coarser one."""
    cdf = np.cumsum(area) / area.sum()
    position = (np.arange(total) + 0.5) / total
    t = np.minimum(np.searchsorted(cdf, position, side="right"), len(area) - 1)
    start = np.concatenate([[0.0], cdf[:-1]])[t]
    # Where in its triangle: the position within the triangle's stretch of the CDF, and a
    # golden-ratio sequence across, mapped by the area-preserving square-root map.
    u = np.clip((position - start) / np.maximum(cdf[t] - start, 1e-300), 0.0, 1.0)
    v = (np.arange(total) * 0.6180339887498949 + 0.5) % 1.0
    root = np.sqrt(u)
    bary = np.stack([1.0 - root, root * (1.0 - v), root * v], axis=1)
    return np.einsum("sc,scj->sj", bary, tris[t]), t, float(area.sum()) / total


def surface_order(points: np.ndarray) -> np.ndarray:
    """(T,) int: an order of the points (T, 3) along a Z-order (Morton) curve through their bounding
    box, which keeps neighbours in space mostly neighbours in the order: equal steps along the
    area CDF in this order spread a mesh light's samples over its whole surface, where the
    mesh's own triangle order (rings of a UV sphere) bunched them."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    cells = np.clip(((points - lo) / np.maximum(hi - lo, 1e-30) * 1024).astype(np.int64), 0, 1023)
    code = np.zeros(len(points), np.int64)
    for bit in range(10):
        for axis in range(3):
            code |= ((cells[:, axis] >> bit) & 1) << (3 * bit + axis)
    return np.argsort(code, kind="stable")


def lamp_rectangle(light: Light) -> np.ndarray:
    """(2, 3, 3) world m: the two triangles of an area lamp's rectangle (a disk's or an
    ellipse's bounding one), which hold all of its emitting surface."""
    hx = 0.5 * light.size_x * np.asarray(light.axis_x, np.float64)
    hy = 0.5 * light.size_y * np.asarray(light.axis_y, np.float64)
    c = np.asarray(light.position, np.float64)
    quad = np.array([c - hx - hy, c + hx - hy, c + hx + hy, c - hx + hy])
    return quad[[[0, 1, 2], [0, 2, 3]]]


def lamp_hull(light: Light, reach: float) -> np.ndarray | None:
    """What a lamp's shafts are built on (`shadow_shafts.py`): a point or spot lamp's position as a
    triangle of three equal corners (1, 3, 3) world m, whose shaft with a receiver is the
    tetrahedron of the two; for a sun, the (3,) translation by `reach` m towards it (the receiver
    swept that far: a prism past everything in the scene); None for other lamps."""
    if light.kind == "SUN":
        return -np.asarray(light.direction, np.float64) * reach
    if light.kind not in ("POINT", "SPOT"):
        return None
    return np.broadcast_to(np.asarray(light.position, np.float64), (1, 3, 3)).copy()


def scene_emitters(scene: Scene, settings: TracerSettings) -> Emitters:
    sets, two_sided, local, count, hulls, fine = [], [], [], [], [], []
    n = settings.area_samples
    for light in scene.lights:
        if light.kind != "AREA":
            continue
        if light.shape in ("DISK", "ELLIPSE"):
            points = light_units.area_light_samples(light, max(n, 2) * 2)  # cells inside the shape
        else:
            points = light_units.area_light_samples(light, n)
        k = len(points)
        area = light_units.area_of_shape(light.shape, light.size_x, light.size_y)
        sets.append(Samples(points, np.tile(light.direction, (k, 1)),
                            np.tile(light.radiance * area / k, (k, 1)), np.full(k, area / k)))
        two_sided.append(np.zeros(k, bool))
        local.append(np.arange(k))
        count.append(np.full(k, k))
        hulls.append(lamp_rectangle(light))
        fine.append(None)
    # Emissive triangles (an emission texture's black parts are not lights).
    tri_ids = np.flatnonzero(np.any(triangle_emission(scene) > 0.0, axis=1))
    for obj in np.unique(scene.object_ids[tri_ids]):
        own = tri_ids[scene.object_ids[tri_ids] == obj]
        samples, index, per_emitter, finer = mesh_light_samples(scene, own, n)
        sets.append(samples)
        two_sided.append(np.ones(len(samples.da), bool))
        local.append(index)
        count.append(np.full(len(samples.da), per_emitter))
        hulls.append(scene.triangles[own].astype(np.float64) if len(own) <= MESH_LIGHT_TRIANGLES
                     else None)
        fine.append(finer)
    lights = [li for li in scene.lights if li.kind != "AREA"]
    if not sets:
        none = np.zeros(0, np.int64)
        z = Samples.empty()
        return Emitters(lights, z.points, z.normals, z.radiance_da, z.da, np.zeros(0, bool), none,
                        none, none, [], z.points, z.normals, z.radiance_da, z.da, none, none)
    sizes = [len(x.da) for x in sets]
    fine_count = np.concatenate([np.full(k, 0 if f is None else FINE_SPLIT)
                                 for k, f in zip(sizes, fine, strict=True)])
    fine_first = np.cumsum(fine_count) - fine_count
    finer = [f for f in fine if f is not None] or [Samples.empty()]

    def joined(field: str, of: list) -> np.ndarray:
        return np.concatenate([getattr(x, field) for x in of])

    return Emitters(lights, joined("points", sets), joined("normals", sets),
                    joined("radiance_da", sets), joined("da", sets), np.concatenate(two_sided),
                    np.concatenate(local), np.concatenate(count),
                    np.repeat(np.arange(len(sets)), sizes), hulls,
                    joined("points", finer), joined("normals", finer),
                    joined("radiance_da", finer), joined("da", finer), fine_first, fine_count)


def point_light(name: str, position, intensity) -> Light:
    """A kernel point light of radiant intensity `intensity` (W/sr, RGB) — for tests and tools."""
    return Light(name=name, kind="POINT", position=np.asarray(position, np.float64),
                 direction=np.array([0.0, 0.0, -1.0]), axis_x=np.array([1.0, 0.0, 0.0]),
                 axis_y=np.array([0.0, 1.0, 0.0]), intensity=np.asarray(intensity, np.float64))
