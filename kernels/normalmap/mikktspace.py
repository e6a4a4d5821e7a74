"""MikkTSpace tangents per face corner, as Blender computes them (`Mesh.calc_tangents`).

Every tool that bakes or reads a tangent-space normal map (Blender, Cycles, EEVEE, Unity, Unreal,
xNormal) agrees on Morten Mikkelsen's tangent space ("Simulation of Wrinkled Surfaces Revisited",
2008), so a map made here in another frame would show seams and wrong light. This module follows
Blender's C++ port of it (`intern/mikktspace/mikktspace.hh`, Blender 3.5 onwards) step by step,
with its float32 arithmetic in the same order, so that the result equals `loop.tangent` and
`loop.bitangent_sign` to float rounding:

1. **Triangles.** Triangles are kept; a quad is split along its shorter UV diagonal (0-2 or 1-3;
   on a tie, along the shorter 3D diagonal, 0-2 unless 1-3 is strictly shorter). Larger polygons
   are refused (Blender refuses them too: triangulate first).
2. **Welding.** Corners with bit-identical position, normal and UV are one vertex.
3. **Degenerate triangles** (two corners at one position) are set aside and take the frame of a
   good triangle's corner at the same welded vertex afterwards; in a quad with one good triangle
   the missing corner copies the coinciding corner of the good one.
4. **Per triangle**: the UV area's sign (its orientation, "orient preserving" when > 0), and the
   unit tangent vOs (the direction of dp/ds) times that sign. A triangle with zero UV area or a
   zero dp/ds or dp/dt is "group with any": it adds nothing and takes the orientation of the first
   group that reaches it. The two triangles of a quad are forced to one orientation (the one of
   the larger UV area, or of the good one).
5. **Groups.** Around each welded vertex, the triangles that share an edge (wound consistently)
   and the orientation form one group; a vertex whose fan is cut by a UV seam or a mirror line
   has several.
6. **Accumulation.** Each good triangle adds to each corner's group its tangent projected into the
   plane of that corner's normal, weighted by the corner's angle (measured in that plane, with
   Cycles' `fast_acosf`); the group's sum is normalised. A corner of a quad on the diagonal, in
   two groups, takes their normalised mean.

Output per face corner: a unit tangent t (object space, in the plane of the corner normal) and
the bitangent sign s (+1 or -1, -1 for mirrored UVs): b = s (n x t), which is what the Normal Map
node and Cycles use. Corners that no group reaches keep MikkTSpace's default (1, 0, 0) with s = -1
and are counted.

Shapes: positions (V, 3), corner_verts (L,), corner normals (L, 3), corner UVs (L, 2),
face_starts / face_sizes (F,); all float data are taken as float32, as Blender stores them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..progress import Steps, drain

F32 = np.float32
# MikkTSpace's `not_zero`: |x| > FLT_MIN, the smallest normal float32. Anything above it counts as
# a usable area or length, exactly as in Blender, so that near-degenerate triangles are treated
# alike by both.
NOT_ZERO = np.finfo(np.float32).tiny
UNSET = -1


@dataclass(frozen=True)
class CornerTangents:
    """MikkTSpace frames per face corner.

    | field | shape | meaning |
    |-------|-------|---------|
    | tangents | (L, 3) float32 | unit tangent, object space, in the plane of the corner normal |
    | signs | (L,) float32 | bitangent sign, +1 or -1: b = sign (n x t) |
    | degenerate_triangles | int | triangles with two corners at one position (frames copied) |
    | groupless_triangles | int | triangles with zero UV area or zero dp/ds, dp/dt (add nothing) |
    | unassigned_corners | int | corners no group reached: default frame (1, 0, 0), sign -1 |
    """

    tangents: np.ndarray
    signs: np.ndarray
    degenerate_triangles: int
    groupless_triangles: int
    unassigned_corners: int

    @property
    def degenerate_frames(self) -> int:
        """Corners whose frame is not their own: degenerate or groupless triangles' corners that
        were never given a frame (the figure metrics.json reports)."""
        return self.unassigned_corners


def _length_squared(v: np.ndarray) -> np.ndarray:
    # float32 x*x + y*y + z*z in that order, as mikk::float3::length_squared.
    return (v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1]) + v[..., 2] * v[..., 2]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]) + a[..., 2] * b[..., 2]


def _normalize(v: np.ndarray) -> np.ndarray:
    """mikk::float3::normalize in float32: v * (1 / |v|), zero vectors left as they are."""
    length = np.sqrt(_length_squared(v))
    inv = np.where(length != 0, F32(1.0) / np.where(length != 0, length, F32(1.0)), F32(1.0))
    return v * inv[..., None].astype(F32)


def _project(n: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v made perpendicular to unit n and normalised (mikk::project)."""
    return _normalize(v - n * _dot(n, v)[..., None])


def fast_acos(x: np.ndarray) -> np.ndarray:
    """Cycles' `fast_acosf` (max error 4.5e-5 rad), float32: MikkTSpace's corner-angle weight."""
    x = np.asarray(x, F32)
    f = np.abs(x)
    m = np.where(f < 1, F32(1) - (F32(1) - f), F32(1)).astype(F32)
    poly = F32(1.5707963267) + m * (F32(-0.213300989) + m * (F32(0.077980478) + m * F32(-0.02164095)))
    a = np.sqrt(F32(1) - m) * poly
    return np.where(x < 0, F32(np.pi) - a, a).astype(F32)


def _weld(keys: np.ndarray) -> np.ndarray:
    """(L,) int64 class id per row of bit-identical (L, K) uint32 keys."""
    view = np.ascontiguousarray(keys).view(np.dtype((np.void, keys.dtype.itemsize * keys.shape[1])))
    _, inverse = np.unique(view.ravel(), return_inverse=True)
    return inverse.ravel().astype(np.int64)


def _triangulate(pos: np.ndarray, uv: np.ndarray, starts: np.ndarray, sizes: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(tri_face (T,), tri_fv (T, 3)): MikkTSpace's triangles of each face in face order, a quad's
    two after each other; face-vertex indices 0..3. `pos`, `uv` are per corner, float32."""
    quads = np.nonzero(sizes == 4)[0]
    s = starts[quads]
    d02 = _length_squared(np.pad(uv[s + 2] - uv[s], ((0, 0), (0, 1))))
    d13 = _length_squared(np.pad(uv[s + 3] - uv[s + 1], ((0, 0), (0, 1))))
    p02 = _length_squared(pos[s + 2] - pos[s])
    p13 = _length_squared(pos[s + 3] - pos[s + 1])
    diag02 = np.where(d02 != d13, d02 < d13, ~(p13 < p02))
    per_face = np.where(sizes == 4, 2, 1)
    tri_face = np.repeat(np.arange(len(sizes)), per_face)
    first = np.concatenate([[0], np.cumsum(per_face)[:-1]])
    tri_fv = np.tile(np.array([0, 1, 2]), (len(tri_face), 1))
    qa, qb = first[quads], first[quads] + 1
    tri_fv[qa] = np.where(diag02[:, None], [0, 1, 2], [0, 1, 3])
    tri_fv[qb] = np.where(diag02[:, None], [0, 2, 3], [1, 2, 3])
    return tri_face, tri_fv


def _neighbours(verts: np.ndarray) -> np.ndarray:
    """(T, 3) int64 neighbour across each edge i (corner i to corner i + 1) of triangles with
    welded vertex ids verts (T, 3), or UNSET. As MikkTSpace pairs them: per undirected edge, in
    (triangle, edge) order, each unpaired edge takes the first later unpaired edge of the opposite
    direction; edges of more than two triangles are paired that way one by one."""
    t_count = len(verts)
    v0 = verts.ravel()
    v1 = np.roll(verts, -1, axis=1).ravel()
    lo, hi = np.minimum(v0, v1), np.maximum(v0, v1)
    order = np.lexsort((np.arange(3 * t_count), hi, lo))
    lo_s, hi_s = lo[order], hi[order]
    new = np.ones(len(order), bool)
    new[1:] = (lo_s[1:] != lo_s[:-1]) | (hi_s[1:] != hi_s[:-1])
    starts = np.nonzero(new)[0]
    counts = np.diff(np.append(starts, len(order)))
    neighbour = np.full(3 * t_count, UNSET, np.int64)
    # Two edges: paired when opposite.
    two = starts[counts == 2]
    a, b = order[two], order[two + 1]
    opposite = (v0[a] == v1[b]) & (v1[a] == v0[b])
    a, b = a[opposite], b[opposite]
    neighbour[a], neighbour[b] = b // 3, a // 3
    # More than two (non-manifold): one by one, in MikkTSpace's order.
    for start, count in zip(starts[counts > 2], counts[counts > 2], strict=True):
        entries = order[start:start + count]
        for k, ea in enumerate(entries):
            if neighbour[ea] != UNSET:
                continue
            for eb in entries[k + 1:]:
                if neighbour[eb] == UNSET and v0[ea] == v1[eb] and v1[ea] == v0[eb]:
                    neighbour[ea], neighbour[eb] = eb // 3, ea // 3
                    break
    return neighbour.reshape(t_count, 3)


def _groups(verts: np.ndarray, neighbour: np.ndarray, orient: np.ndarray, with_any: np.ndarray
            ) -> tuple[np.ndarray, np.ndarray]:
    """MikkTSpace's `build4RuleGroups`: (group (T, 3) int64 or UNSET, group orientation (G,)).
    `orient` is updated in place for group-with-any triangles (the only order dependence)."""
    t_count = len(verts)
    group = np.full((t_count, 3), UNSET, np.int64)
    group_orient: list[bool] = []
    verts_l, neigh_l = verts.tolist(), neighbour.tolist()
    orient_l, any_l = orient.tolist(), with_any.tolist()
    group_l = group.tolist()
    for t in range(t_count):
        if any_l[t]:
            continue
        for i in range(3):
            if group_l[t][i] != UNSET:
                continue
            gid = len(group_orient)
            g_orient = orient_l[t]
            group_orient.append(g_orient)
            group_l[t][i] = gid
            rep = verts_l[t][i]
            stack = [neigh_l[t][i], neigh_l[t][(i + 2) % 3]]
            while stack:
                u = stack.pop()
                if u == UNSET:
                    continue
                vu = verts_l[u]
                j = 0 if vu[0] == rep else 1 if vu[1] == rep else 2
                gu = group_l[u]
                if gu[j] != UNSET:
                    continue
                if any_l[u] and gu[0] == UNSET and gu[1] == UNSET and gu[2] == UNSET:
                    orient_l[u] = g_orient
                if orient_l[u] != g_orient:
                    continue
                gu[j] = gid
                stack.append(neigh_l[u][j])
                stack.append(neigh_l[u][(j + 2) % 3])
    orient[:] = orient_l
    return np.array(group_l, np.int64).reshape(t_count, 3), np.array(group_orient, bool)


def _groups_connected(verts: np.ndarray, neighbour: np.ndarray, orient: np.ndarray
                      ) -> tuple[np.ndarray, np.ndarray]:
    """`_groups` for meshes without group-with-any triangles, vectorised. There the groups are
    exactly the connected components of the corners (t, i) linked to the corner at the same
    welded vertex of the neighbour across either edge at i, when both share the orientation: the
    links are symmetric, so MikkTSpace's flood fill from each unassigned corner finds one whole
    component. Labelled by hooking to the smallest linked label and pointer jumping."""
    t_count = len(verts)
    node = np.arange(3 * t_count).reshape(t_count, 3)
    a_list, b_list = [], []
    for edge_of in (lambda i: i, lambda i: (i + 2) % 3):  # the edges (i, i+1) and (i-1, i)
        for i in range(3):
            other = neighbour[:, edge_of(i)]
            ok = other != UNSET
            t = np.nonzero(ok)[0]
            u = other[ok]
            v = verts[t, i]
            j = np.where(verts[u, 0] == v, 0, np.where(verts[u, 1] == v, 1, 2))
            same = orient[t] == orient[u]
            a_list.append(node[t[same], i])
            b_list.append(node[u[same], j[same]])
    a, b = np.concatenate(a_list), np.concatenate(b_list)
    label = np.arange(3 * t_count)
    while True:
        before = label.copy()
        np.minimum.at(label, a, label[b])
        np.minimum.at(label, b, label[a])
        label = label[label]
        if np.array_equal(label, before):
            break
    roots, group = np.unique(label, return_inverse=True)
    return group.reshape(t_count, 3).astype(np.int64), orient[roots // 3].copy()


def mikktspace_steps(positions: np.ndarray, corner_verts: np.ndarray, corner_normals: np.ndarray,
                     corner_uvs: np.ndarray, face_starts: np.ndarray | None = None,
                     face_sizes: np.ndarray | None = None) -> Steps[CornerTangents]:
    """MikkTSpace frames of a mesh's face corners; yields progress, returns `CornerTangents`.

    positions (V, 3) object space; corner_verts (L,) vertex of each corner; corner_normals (L, 3)
    unit, the mesh's corner normals (Blender's `Mesh.corner_normals`); corner_uvs (L, 2) the UV
    map; face_starts, face_sizes (F,) each face's first corner and corner count (3 or 4); without
    them, consecutive triangles (L = 3 F). Raises ValueError on faces of more than four corners.
    """
    pos = np.asarray(positions, F32)[np.asarray(corner_verts, np.int64)]  # (L, 3) per corner
    nrm = np.ascontiguousarray(corner_normals, F32)  # (L, 3)
    uv = np.ascontiguousarray(corner_uvs, F32)  # (L, 2)
    corners = len(pos)
    if face_sizes is None:
        face_sizes = np.full(corners // 3, 3, np.int64)
        face_starts = np.arange(0, corners - corners % 3, 3, dtype=np.int64)
    sizes = np.asarray(face_sizes, np.int64)
    starts = np.asarray(face_starts, np.int64)
    if np.any(sizes > 4):
        raise ValueError("MikkTSpace takes triangles and quads only: triangulate larger faces")
    tangents = np.zeros((corners, 3), F32)
    tangents[:, 0] = 1.0  # MikkTSpace's default frame
    signs = np.full(corners, -1.0, F32)
    real = (sizes == 3) | (sizes == 4)  # faces of 1 or 2 corners are skipped, as in Blender
    if not real.any():
        return CornerTangents(tangents, signs, 0, 0, 0)

    # ---- 1. triangles, 2. welding ---------------------------------------------------------
    face_ids = np.nonzero(real)[0]
    tri_face_local, tri_fv = _triangulate(pos, uv, starts[face_ids], sizes[face_ids])
    tri_face = face_ids[tri_face_local]
    tri_corner = starts[tri_face][:, None] + tri_fv  # (T, 3) corner index of each triangle corner
    keys = np.concatenate([pos.view(np.uint32), nrm.view(np.uint32), uv.view(np.uint32)], axis=1)
    weld = _weld(keys)  # (L,) welded vertex id per corner
    yield 0.2

    # ---- 3. degenerate triangles: good ones first, order kept -------------------------------
    p = pos[tri_corner]  # (T, 3, 3)
    degenerate = np.zeros(len(p), bool)
    for a, b in ((0, 1), (0, 2), (1, 2)):  # two corners at one position (float ==)
        degenerate |= np.all(p[:, a] == p[:, b], axis=1)
    one_degen_quad = np.zeros(len(tri_face), bool)
    pair = tri_face[:-1] == tri_face[1:]
    differ = pair & (degenerate[:-1] != degenerate[1:])
    one_degen_quad[:-1] |= differ
    one_degen_quad[1:] |= differ
    order = np.concatenate([np.nonzero(~degenerate)[0], np.nonzero(degenerate)[0]])
    good = int((~degenerate).sum())
    tri_face, tri_fv, tri_corner = tri_face[order], tri_fv[order], tri_corner[order]
    one_degen_quad = one_degen_quad[order]
    verts = weld[tri_corner]  # (T, 3)

    # ---- 4. per-triangle tangent and orientation (float32, Blender's order) -------------------
    gc = tri_corner[:good]
    v1, v2, v3 = pos[gc[:, 0]], pos[gc[:, 1]], pos[gc[:, 2]]
    t1, t2, t3 = uv[gc[:, 0]], uv[gc[:, 1]], uv[gc[:, 2]]
    t21x, t21y = t2[:, 0] - t1[:, 0], t2[:, 1] - t1[:, 1]
    t31x, t31y = t3[:, 0] - t1[:, 0], t3[:, 1] - t1[:, 1]
    d1, d2 = v2 - v1, v3 - v1
    area2 = t21x * t31y - t21y * t31x  # signed UV area x 2
    v_os = t31y[:, None] * d1 - t21y[:, None] * d2  # dp/ds direction (Mikkelsen's eq. 18)
    v_ot = -t31x[:, None] * d1 + t21x[:, None] * d2  # dp/dt direction (eq. 19)
    orient = area2 > 0
    len_os2, len_ot2 = _length_squared(v_os), _length_squared(v_ot)
    has_area = np.abs(area2) > NOT_ZERO
    has_os = has_area & (np.abs(len_os2) > NOT_ZERO)
    f_s = np.where(orient, F32(1), F32(-1))
    scale = (f_s / np.sqrt(np.where(has_os, len_os2, F32(1)))).astype(F32)
    tri_tangent = np.where(has_os[:, None], v_os * scale[:, None], F32(0)).astype(F32)
    with_any = ~(has_os & (np.abs(len_ot2) > NOT_ZERO))
    # A quad's two good triangles take one orientation: the larger UV area's, or the good one's.
    quad_a = np.nonzero(tri_face[:good - 1] == tri_face[1:good])[0] if good > 1 else np.zeros(0, int)
    clash = quad_a[orient[quad_a] != orient[quad_a + 1]]
    area_abs = np.abs(area2)
    first_wins = with_any[clash + 1] | (area_abs[clash] >= area_abs[clash + 1])
    winner = np.where(first_wins, clash, clash + 1)
    loser = np.where(first_wins, clash + 1, clash)
    orient[loser] = orient[winner]
    yield 0.35

    # ---- 5. neighbours and groups ----------------------------------------------------------
    neighbour = _neighbours(verts[:good])
    yield 0.5
    if with_any.any():  # the order-dependent case: MikkTSpace's flood fill, one corner at a time
        group, group_orient = _groups(verts[:good], neighbour, orient, with_any)
    else:
        group, group_orient = _groups_connected(verts[:good], neighbour, orient)
    yield 0.8

    # ---- 6. accumulate each group's tangent ------------------------------------------------
    n = nrm[gc]  # (G, 3, 3)
    pc = pos[gc]
    cos = np.stack([_dot(_project(n[:, k], pc[:, (k + 1) % 3] - pc[:, k]),
                         _project(n[:, k], pc[:, (k + 2) % 3] - pc[:, k])) for k in range(3)], 1)
    weight = fast_acos(np.clip(cos, F32(-1), F32(1)))  # (G, 3) corner angle, radians
    contrib = _project(n, tri_tangent[:, None, :]) * weight[..., None]  # (G, 3, 3)
    adds = (group != UNSET) & ~with_any[:, None]
    group_tangent = np.zeros((len(group_orient), 3), F32)
    np.add.at(group_tangent, group[adds], contrib[adds])  # in (triangle, corner) order, float32
    group_tangent = _normalize(group_tangent)

    # ---- 7. corner frames: one group, or the mean of a quad diagonal's two ------------------
    assigned = group != UNSET
    slot = tri_corner[:good][assigned]  # corners in (triangle, corner) order
    gids = group[assigned]
    counter = np.zeros(corners, np.int64)
    first_at = np.full(corners, -1, np.int64)
    np.add.at(counter, slot, 1)
    rank = np.arange(len(slot))
    first_at[slot[::-1]] = rank[::-1]  # first occurrence of each corner
    last_at = np.full(corners, -1, np.int64)
    last_at[slot] = rank  # last occurrence wins (fancy assignment keeps the last)
    have = counter > 0
    g_first = gids[first_at[have]]
    g_last = gids[last_at[have]]
    t_first, t_last = group_tangent[g_first], group_tangent[g_last]
    equal = np.all(t_first == t_last, axis=1)
    mean = _normalize(t_first + t_last)
    tangents[have] = np.where(equal[:, None], t_first, mean)
    signs[have] = np.where(group_orient[g_last], F32(1), F32(-1))
    unreached = np.ones(corners, bool)
    unreached[have] = False

    # ---- 8. degenerate triangles copy a good corner's frame ---------------------------------
    if good < len(tri_face):
        good_verts = verts[:good].ravel()
        good_corner = tri_corner[:good].ravel()
        lookup = np.full(weld.max() + 1, -1, np.int64)
        lookup[good_verts[::-1]] = good_corner[::-1]  # first good corner of each welded vertex
        d_verts, d_corner = verts[good:], tri_corner[good:]
        plain = ~one_degen_quad[good:]
        src = lookup[d_verts[plain]].ravel()
        dst = d_corner[plain].ravel()
        ok = src >= 0
        tangents[dst[ok]], signs[dst[ok]] = tangents[src[ok]], signs[src[ok]]
        unreached[dst[ok]] = unreached[src[ok]]
        # A quad with one good triangle: its missing corner copies the coinciding good corner.
        for t in np.nonzero(one_degen_quad[:good])[0]:
            fv = tri_fv[t].tolist()
            missing = next(k for k in (1, 2, 3) if k not in fv) if 0 in fv else 0
            start = starts[tri_face[t]]
            for k in fv:
                if np.all(pos[start + k] == pos[start + missing]):
                    tangents[start + missing] = tangents[start + k]
                    signs[start + missing] = signs[start + k]
                    unreached[start + missing] = unreached[start + k]
                    break
    yield 1.0
    in_triangle = np.zeros(corners, bool)  # corners of faces of 3 or 4 corners
    in_triangle[tri_corner.ravel()] = True
    unreached_real = unreached & in_triangle
    return CornerTangents(tangents=tangents, signs=signs,
                          degenerate_triangles=int(degenerate.sum()),
                          groupless_triangles=int(with_any.sum()),
                          unassigned_corners=int(unreached_real.sum()))


def mikktspace_tangents(positions: np.ndarray, corner_verts: np.ndarray,
                        corner_normals: np.ndarray, corner_uvs: np.ndarray,
                        face_starts: np.ndarray | None = None,
                        face_sizes: np.ndarray | None = None) -> CornerTangents:
    """`mikktspace_steps` run to its end (for scripts and tests)."""
    return drain(mikktspace_steps(positions, corner_verts, corner_normals, corner_uvs,
                                  face_starts, face_sizes))


def bitangents(normals: np.ndarray, frames: CornerTangents) -> np.ndarray:
    """(L, 3) float32 bitangents b = sign (n x t), as Blender's `loop.bitangent` and the Normal
    Map node form them from unit corner normals (L, 3)."""
    n = np.asarray(normals, F32)
    return np.cross(n, frames.tangents) * frames.signs[:, None]


def tangent_to_object(local: np.ndarray, normals: np.ndarray, tangents: np.ndarray,
                      signs: np.ndarray) -> np.ndarray:
    """(N, 3) float64 unit object-space normals of tangent-space normals local (N, 3) (x along t,
    y along b = sign (n x t), z along n; OpenGL green), as Blender's Normal Map node and Cycles
    decode them: normalize(x t + y b + z n). normals, tangents (N, 3); signs (N,)."""
    n = np.asarray(normals, np.float64)
    t = np.asarray(tangents, np.float64)
    b = np.cross(n, t) * np.asarray(signs, np.float64)[:, None]
    local = np.asarray(local, np.float64)
    out = local[:, 0:1] * t + local[:, 1:2] * b + local[:, 2:3] * n
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), NOT_ZERO)
