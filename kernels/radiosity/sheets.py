"""Sheets whose back side faces the scene: a panel hanging under a ceiling, a card, a plane that
is one face thick. Patches are one-sided (the front normal's side), so such a sheet's back would
reflect nothing: the ceiling over a 0.84 m emissive panel hanging 41 cm under it came out 11-12%
too dark in a generated room's camera view (room brightness 0.964 of Cycles'; the same panel made
5 mm thick, whose top is then a face of its own, 0.996). `with_sheet_backs` gives the solve a
turned-over copy of each such triangle, lifted a little off it, so the back takes part as any
surface does. Only flat sheets qualify (`flat_sheets`); faces whose back looks out of the scene
(a room's walls, a ground plane) are left as they are.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..geometry.scene import Scene, geometric_normals
from ..shading.direct_light import diffuse_at

# The copy lies this many ray offsets behind the sheet (along its back normal): far enough that
# rays leaving either side never start inside the other, and that the two are not taken for a
# pair of coincident faces (`coincident.py`, which matches planes to one ray offset).
LIFT_OFFSETS = 4.0
# A back side nearer another object than this many ray offsets stays one-sided: the copy would
# not fit in the gap (the Cornell box's lamp, 0.1 mm under its ceiling), whose light patches
# cannot resolve anyway (`emitters.OPEN_BACK_GAP`).
MIN_GAP_OFFSETS = 10.0 * LIFT_OFFSETS
# A sheet is flat when its triangles' normals agree to this cosine (0.3 degrees) and its corners
# lie within this fraction of its size off one plane.
FLAT_COS = 0.99998
FLAT_REL = 1e-4


def flat_sheets(scene: Scene) -> np.ndarray:
    """(O,) bool: objects that are one flat, one-sided sheet: every triangle faces the same way
    (FLAT_COS) in one plane (FLAT_REL). (A closed mesh is never flat; a sheet modelled
    double-sided has faces both ways.) Curved open meshes (a box without its bottom, a lamp
    shade) stay one-sided: the back of a box's walls faces its inside, which a copy would open."""
    out = np.zeros(len(scene.objects), bool)
    normals = geometric_normals(scene.triangles).astype(np.float64)
    points = scene.triangles[:, 0].astype(np.float64)
    order = np.argsort(scene.object_ids, kind="stable")
    starts = np.searchsorted(scene.object_ids[order], np.arange(len(scene.objects) + 1))
    for k in range(len(scene.objects)):
        rows = order[starts[k]:starts[k + 1]]
        if not rows.size:
            continue
        n = normals[rows]
        size = float(np.ptp(points[rows], axis=0).max())
        out[k] = bool(np.all(n @ n[0] >= FLAT_COS) and np.all(
            np.abs((points[rows] - points[rows[0]]) @ n[0]) <= FLAT_REL * max(size, 1e-300)))
    return out


def sheet_backs(scene: Scene, bvh, offset: float) -> np.ndarray:
    """(T,) bool: triangles of flat sheets (`flat_sheets`) that reflect diffusely and whose back
    side faces another object of the scene: one probe from each centroid along the back normal,
    leaving `offset` m off the surface, meets a triangle of another object farther than
    MIN_GAP_OFFSETS x `offset` (a miss faces out of the scene: a room's walls, a ground)."""
    count = scene.triangle_count
    out = np.zeros(count, bool)
    rows = np.flatnonzero(flat_sheets(scene)[scene.object_ids])
    if not rows.size:
        return out
    rho = diffuse_at(scene, rows, np.full((len(rows), 3), 1.0 / 3.0), under_layer=False)
    rows = rows[rho.max(axis=1) > 0.0]
    if not rows.size:
        return out
    tri, t = back_probes(scene, rows, bvh, offset)
    met = tri >= 0
    far = t > MIN_GAP_OFFSETS * offset
    out[rows[met]] = (scene.object_ids[tri[met]] != scene.object_ids[rows[met]]) & far[met]
    return out


def back_probes(scene: Scene, rows: np.ndarray, bvh, offset: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """What one probe ray from the centroid of each triangle `rows` (R,) along its back normal,
    leaving `offset` m off the surface, meets: the triangle (R,) int64 (-1: nothing) and its
    distance (R,) float64, m."""
    tris = scene.triangles[rows].astype(np.float64)
    back = -geometric_normals(scene.triangles[rows])
    origins = tris.mean(axis=1) + offset * back
    hits = bvh.intersect(np.ascontiguousarray(origins), np.ascontiguousarray(back))
    return np.asarray(hits.tri, np.int64), np.asarray(hits.t, np.float64)


def with_sheet_backs(scene: Scene, backs: np.ndarray, offset: float
                     ) -> tuple[Scene, np.ndarray | None]:
    """`scene` with a turned-over copy of each triangle `backs` (T,) bool appended (corners in
    reverse order, normals negated, LIFT_OFFSETS x `offset` m behind the original), of its object
    and material, and each triangle's copy (T,) int64 (-1: none; None and `scene` as it is when
    there are none). An emissive sheet's copy emits as Cycles' emission does on the back side;
    the sheet's own back then meets its copy and stays dark (`emitters.open_backs`). Triangles
    0..T-1 are unchanged."""
    rows = np.flatnonzero(backs)
    if not rows.size:
        return scene, None
    back_of = np.full(scene.triangle_count, -1, np.int64)
    back_of[rows] = scene.triangle_count + np.arange(len(rows))
    lift = -geometric_normals(scene.triangles[rows]) * (LIFT_OFFSETS * offset)
    triangles = scene.triangles[rows][:, ::-1] + lift[:, None, :].astype(np.float32)

    def corners(a):  # per-corner arrays: the copies' corners in reverse order
        return None if a is None else np.concatenate([a, a[rows][:, ::-1]])

    def rowwise(a):
        return None if a is None else np.concatenate([a, a[rows]])

    tangents = scene.corner_tangents
    if tangents is not None:  # no normal-map frame on the copies: their faces' normals stand
        tangents = np.concatenate([tangents, np.zeros((len(rows), 3, 3), tangents.dtype)])
    return replace(
        scene, triangles=np.concatenate([scene.triangles, triangles]),
        normals=np.concatenate([scene.normals, -scene.normals[rows][:, ::-1]]),
        uv=corners(scene.uv), lightmap_uv=corners(scene.lightmap_uv),
        material_ids=rowwise(scene.material_ids),
        object_ids=rowwise(scene.object_ids), corner_loops=corners(scene.corner_loops),
        corner_verts=corners(scene.corner_verts),
        generated=corners(scene.generated), corner_colors=corners(scene.corner_colors),
        triangle_radiance=rowwise(scene.triangle_radiance),
        corner_tangents=tangents, corner_signs=corners(scene.corner_signs),
        normal_map_uv=corners(scene.normal_map_uv)), back_of
