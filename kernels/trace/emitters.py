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


def mesh_light_samples(scene: Scene, tri_ids: np.ndarray, n: int
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """Shadow-ray targets on one object's emissive triangles `tri_ids`: points (S, 3), their
    faces' normals (S, 3), radiance x the area each stands for (S, 3, W/sr), that area (S,) m^2,
    each one's index among its emitter's samples (S,) and that emitter's sample count (a
    triangle's, or the object's when it is one light).

    Up to MESH_LIGHT_TRIANGLES triangles, n x n stratified points on each (a folded square
    grid). A finer mesh is one light of MESH_LIGHT_TRIANGLES x n x n points in all, spread
    along the triangles' cumulative area (systematic sampling: a triangle gets points in
    proportion to its area, a small one maybe none, each standing for an equal share of the
    total): an emissive ball of 80 triangles casts 64 shadow rays a hit, not 1280."""
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
        return (pts, np.repeat(ng, k, axis=0), np.repeat(radiance * (area / k)[:, None], k, axis=0),
                np.repeat(area / k, k), np.tile(np.arange(k), len(tri_ids)), k)
    total = MESH_LIGHT_TRIANGLES * n * n
    if not area.sum() > 0.0:  # every triangle degenerate: nothing emits (and no nan CDF)
        return (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0),
                np.zeros(0, np.int64), total)
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
    pts = np.einsum("sc,scj->sj", bary, tris[t])
    share = area.sum() / total
    return pts, ng[t], radiance[t] * share, np.full(total, share), np.arange(total), total


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
    points, normals, power, areas, two_sided, local, count, hulls = [], [], [], [], [], [], [], []
    n = settings.area_samples
    for light in scene.lights:
        if light.kind != "AREA":
            continue
        if light.shape in ("DISK", "ELLIPSE"):
            samples = light_units.area_light_samples(light, max(n, 2) * 2)  # cells inside the shape
        else:
            samples = light_units.area_light_samples(light, n)
        area = light_units.area_of_shape(light.shape, light.size_x, light.size_y)
        points.append(samples)
        normals.append(np.tile(light.direction, (len(samples), 1)))
        power.append(np.tile(light.radiance * area / len(samples), (len(samples), 1)))
        areas.append(np.full(len(samples), area / len(samples)))
        two_sided.append(np.zeros(len(samples), bool))
        local.append(np.arange(len(samples)))
        count.append(np.full(len(samples), len(samples)))
        hulls.append(lamp_rectangle(light))
    # Emissive triangles (an emission texture's black parts are not lights).
    tri_ids = np.flatnonzero(np.any(triangle_emission(scene) > 0.0, axis=1))
    if len(tri_ids):
        for obj in np.unique(scene.object_ids[tri_ids]):
            own = tri_ids[scene.object_ids[tri_ids] == obj]
            pts, ng, radiance_da, da, index, per_emitter = mesh_light_samples(scene, own, n)
            points.append(pts)
            normals.append(ng)
            power.append(radiance_da)
            areas.append(da)
            two_sided.append(np.ones(len(pts), bool))
            local.append(index)
            count.append(np.full(len(pts), per_emitter))
            hulls.append(scene.triangles[own].astype(np.float64)
                         if len(own) <= MESH_LIGHT_TRIANGLES else None)
    if points:
        emitter = np.repeat(np.arange(len(points)), [len(p) for p in points])
        return Emitters([li for li in scene.lights if li.kind != "AREA"], np.concatenate(points),
                        np.concatenate(normals), np.concatenate(power), np.concatenate(areas),
                        np.concatenate(two_sided), np.concatenate(local), np.concatenate(count),
                        emitter, hulls)
    z = np.zeros((0, 3))
    none = np.zeros(0, np.int64)
    return Emitters(list(scene.lights), z, z, z, np.zeros(0), np.zeros(0, bool), none, none, none,
                    [])


def point_light(name: str, position, intensity) -> Light:
    """A kernel point light of radiant intensity `intensity` (W/sr, RGB) — for tests and tools."""
    return Light(name=name, kind="POINT", position=np.asarray(position, np.float64),
                 direction=np.array([0.0, 0.0, -1.0]), axis_x=np.array([1.0, 0.0, 0.0]),
                 axis_y=np.array([0.0, 1.0, 0.0]), intensity=np.asarray(intensity, np.float64))
