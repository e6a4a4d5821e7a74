"""Bump mapping: shading normals perturbed in the tangent frame.

The lecture (lecture 13, "3. Bump Mapping"): the surface is displaced in thought,
p* = p + d(p) n, and only its normal n* is used for shading; the geometry (and the silhouette)
stays as it is. At a point take the tangent t and the binormal b = n x t, so that t, b, n are the
x, y, z axes of the tangent frame; the matrix M = [t; b; n] (rows) takes a vector from the world
into that frame (M t = x, M b = y, M n = z) and M^T takes it back. In the tangent frame the
unperturbed normal is z = (0, 0, 1) and the perturbed one n* = normalize((x, y, 1)), x and y
functions of the texture coordinates.

Two sources of (x, y), as Blender's shader nodes define them (and Cycles renders them):
* a height map through a Bump node: x = -D dh/dt, y = -D dh/db (D the node's Distance, h the
  height image's value, dh/dt its slope along t in metres): n* = normalize(n - D grad h), the
  normal of p + D h n to first order (Blinn 1978; Cycles' surface-gradient form);
* a tangent-space normal map: n* = 2 rgb - 1 directly (x along t, y along the UV map's v).
The node's Strength blends the result with the unperturbed normal as Cycles does.

Tangents. A normal map is read in the frames Blender reads it in wherever the snapshot has them
(`Scene.corner_tangents`, the bridge's MikkTSpace frames per corner on the Normal Map node's UV
layer; the image is looked up on the layer its Image Texture reads, `Scene.normal_map_uv`): t
and the normal interpolated from the triangle's corners (t not normalised, n made unit in
Blender 5.2, as interpolated in 4.5), b = sign (n x t), n* = normalize(x t + y b + z n)
(`mikktspace_normal_mapped`), as Cycles' Normal Map node does, so a map made by this project,
by Blender or by another MikkTSpace baker shades as in Cycles. Heights (the Bump node), and
normal maps on objects without frames, take the lecture's per-triangle frame: dp/du and dp/dv
solve
[p1 - p0, p2 - p0] = [dp/du, dp/dv] [uv1 - uv0, uv2 - uv0]; t is dp/du made perpendicular to
the (interpolated) normal; b = n x t, turned round where the UV map is mirrored (b . dp/dv < 0),
so that y always runs along v. On coarse curved meshes the two frames differ by a few degrees
about the normal (MikkTSpace averages each vertex's triangles).

Arrays are (N, 3) float64 world vectors unless named otherwise; UVs are (N, 2).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Literal, get_args

import numpy as np

from ..geometry.frames import tangent_frames
from ..geometry.scene import Material, Scene, Texture
from ..measure.metrics import REC709_LUMINANCE
from .textures import sample_texture

# Blender turns a colour into a float (the Bump node's Height) by its luminance weights.
LUMINANCE = np.array(REC709_LUMINANCE)
# Half the central-difference step of the height slope, in texels: the bilinear interpolant's own
# slope except within this distance of a texel boundary (Cycles' Bump node differences heights
# 0.1 pixel apart on screen, a small fraction of a texel wherever the texture is magnified).
HEIGHT_STEP_TEXELS = 0.05
# A UV triangle with |det [uv1 - uv0, uv2 - uv0]| below this has no usable parametrisation (all
# corners at one UV, or on a line): its tangent comes from its first edge instead.
DEGENERATE_UV_AREA = 1e-14
# Shorter vectors than this are not normalised (they have no direction to keep).
MIN_LENGTH = 1e-12
# A perturbed normal turned away from the viewer is bent back until its reflection of the view
# leaves the surface at least at this cos to the geometric normal (0.6 degrees), or at 0.9 of the
# view's own cos when that is smaller (`valid_reflection`).
REFLECTION_FLOOR = 0.01
REFLECTION_FLOOR_SHARE = 0.9
# Cycles' bump terminator softening (`bump_shadowing`): the relief's roughness alpha^2 is this
# times tan^2 of the bumped normal's tilt from the smooth one (Conty Estevez, Lecocq and Stein,
# "A Microfacet-Based Shadowing Function to Solve the Bump Terminator Problem", Ray Tracing Gems
# 2019: tilts spread like a GGX of alpha^2 = tan^2 / 8), capped at 1.
BUMP_ALPHA2_PER_TAN2 = 0.125
# Below this cos to the smooth normal a light grazes the surface: Cycles gives it nothing.
GRAZING_COS = 1e-6

# The lecture's comparison: flat (one normal per triangle), Gouraud (light computed at the
# vertices and interpolated, `tracer.Tracer.gouraud_direct`), Phong (normals interpolated, light
# per fragment) and bump (Phong's normals perturbed here).
ShadingMode = Literal["flat", "gouraud", "phong", "bump"]
SHADING_MODES: tuple[str, ...] = get_args(ShadingMode)


def _normalize(v: np.ndarray) -> np.ndarray:
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(length, MIN_LENGTH)


def uv_derivatives(triangles: np.ndarray, uvs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dp/du, dp/dv), each (N, 3) float64 m per UV unit, of (N, 3, 3) triangles with (N, 3, 2)
    corner UVs. Degenerate UV maps get dp/du along the first edge and dp/dv = 0."""
    p = np.asarray(triangles, np.float64)
    uv = np.asarray(uvs, np.float64)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > DEGENERATE_UV_AREA
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    dpdu = (d2[:, 1:2] * e1 - d1[:, 1:2] * e2) * inv
    dpdv = (d1[:, 0:1] * e2 - d2[:, 0:1] * e1) * inv
    dpdu = np.where(ok[:, None], dpdu, e1)
    return dpdu, dpdv


def tangent_frame(n: np.ndarray, dpdu: np.ndarray, dpdv: np.ndarray
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal (t, b, n), each (N, 3): t = dp/du made perpendicular to the unit normal n,
    b = n x t (the lecture's binormal), turned round where the UV map is mirrored."""
    t = dpdu - np.einsum("ij,ij->i", dpdu, n)[:, None] * n
    # A tangent parallel to n (or zero): any vector perpendicular to n will do.
    lost = np.linalg.norm(t, axis=1) <= MIN_LENGTH
    if lost.any():
        t[lost] = tangent_frames(n[lost])[0]
    t = _normalize(t)
    b = np.cross(n, t)
    mirrored = np.einsum("ij,ij->i", b, dpdv) < 0.0
    b[mirrored] *= -1.0
    return t, b, n


def frame_matrix(t: np.ndarray, b: np.ndarray, n: np.ndarray) -> np.ndarray:
    """M = [t; b; n], (N, 3, 3): rows t, b, n. M v is v in the tangent frame; M^T takes it back."""
    return np.stack([t, b, n], axis=1)


def height_slope(texture: Texture, uv: np.ndarray) -> np.ndarray:
    """(N, 2) float64 (dh/du, dh/dv) of a height texture's luminance at (N, 2) UVs, by central
    differences HEIGHT_STEP_TEXELS either side (per UV unit)."""
    if texture.kind == "IMAGE" and texture.pixels is not None:
        height, width = texture.pixels.shape[:2]
    else:  # procedural: step a small fraction of a checker square
        width = height = max(64.0, 64.0 * texture.scale)
    du, dv = HEIGHT_STEP_TEXELS / width, HEIGHT_STEP_TEXELS / height
    uv = np.asarray(uv, np.float64)
    offsets = np.array([[du, 0.0], [-du, 0.0], [0.0, dv], [0.0, -dv]])
    samples = sample_texture(texture, (uv[None, :, :] + offsets[:, None, :]).reshape(-1, 2))
    h = (samples.astype(np.float64) @ LUMINANCE).reshape(4, len(uv))
    return np.stack([(h[0] - h[1]) / (2 * du), (h[2] - h[3]) / (2 * dv)], axis=1)


def bumped_normals(n: np.ndarray, dpdu: np.ndarray, dpdv: np.ndarray, slope_uv: np.ndarray,
                   distance: float, strength: float = 1.0) -> np.ndarray:
    """(N, 3) unit normals of a height map through a Bump node.

    slope_uv: (N, 2) dh/du, dh/dv. The height's gradient on the surface is
    grad h = h_u grad u + h_v grad v, grad u and grad v the dual basis of dp/du, dp/dv in the
    tangent plane; in the tangent frame n* = normalize((-D grad h . t, -D grad h . b, 1)), back to
    the world by M^T, then blended with n by the node's strength.
    """
    t, b, n = tangent_frame(n, dpdu, dpdv)
    # Tangent-plane parts of dp/du, dp/dv, and their Gram matrix's inverse: the dual basis.
    pu = dpdu - np.einsum("ij,ij->i", dpdu, n)[:, None] * n
    pv = dpdv - np.einsum("ij,ij->i", dpdv, n)[:, None] * n
    g11, g12, g22 = (np.einsum("ij,ij->i", pu, pu), np.einsum("ij,ij->i", pu, pv),
                     np.einsum("ij,ij->i", pv, pv))
    det = g11 * g22 - g12 * g12
    ok = det > MIN_LENGTH**2
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    grad_u = (g22 * inv)[:, None] * pu - (g12 * inv)[:, None] * pv
    grad_v = (g11 * inv)[:, None] * pv - (g12 * inv)[:, None] * pu
    grad_h = slope_uv[:, 0:1] * grad_u + slope_uv[:, 1:2] * grad_v  # 1/m per unit of height
    m = frame_matrix(t, b, n)
    local = np.einsum("nij,nj->ni", m, -distance * grad_h)  # (x, y, 0) in the tangent frame
    local[:, 2] = 1.0
    world = np.einsum("nji,nj->ni", m, _normalize(local))  # M^T n*
    return _normalize(strength * world + (1.0 - strength) * n) if strength != 1.0 else world


def normal_mapped(n: np.ndarray, dpdu: np.ndarray, dpdv: np.ndarray, rgb: np.ndarray,
                  strength: float = 1.0) -> np.ndarray:
    """(N, 3) unit normals of a tangent-space normal map: n* = 2 rgb - 1 in the frame (t, b, n),
    blended towards n by Blender's Normal Map strength (n + strength (n* - n))."""
    t, b, n = tangent_frame(n, dpdu, dpdv)
    local = strengthened(2.0 * np.asarray(rgb, np.float64)[:, :3] - 1.0, strength)
    return _normalize(np.einsum("nji,nj->ni", frame_matrix(t, b, n), local))


def strengthened(local: np.ndarray, strength: float) -> np.ndarray:
    """(N, 3) tangent-space normals (x, y, z) = 2 rgb - 1 under the Normal Map node's strength,
    as Cycles applies it in tangent space: (s x, s y, 1 + min(s, 1) (z - 1)) (a strength of 2
    on a steep relief: relMSE 0.032 against Cycles blending the world normals instead, 0.0013
    this way)."""
    s = max(float(strength), 0.0)
    if s == 1.0:
        return local
    out = local.copy()
    out[:, :2] *= s
    out[:, 2] = 1.0 + min(s, 1.0) * (local[:, 2] - 1.0)
    return out


def mikktspace_normal_mapped(n: np.ndarray, smooth: np.ndarray, tangents: np.ndarray,
                             signs: np.ndarray, rgb: np.ndarray, strength: float = 1.0,
                             unit_normal: bool = True) -> np.ndarray:
    """(N, 3) unit normals of a tangent-space normal map read in the mesh's MikkTSpace frames,
    as Blender's Normal Map node and Cycles read it: with t and s the corner tangents and normals
    interpolated barycentrically (`tangents`, `smooth` (N, 3); t not normalised, s made unit
    when `unit_normal`, as Cycles in Blender 5.2 does, else as interpolated, as 4.5 does), the
    bitangent b = sign (s x t) (`signs` (N,) interpolated), n* = normalize(x t + y b + z s) for
    (x, y, z) = 2 rgb - 1; turned round where the shading normal n (unit, turned towards the
    viewer by the caller) faces away from s; blended towards n by the node's strength."""
    if unit_normal:
        smooth = _normalize(smooth)
    local = strengthened(2.0 * np.asarray(rgb, np.float64)[:, :3] - 1.0, strength)
    b = np.cross(smooth, tangents) * np.asarray(signs, np.float64)[:, None]
    world = _normalize(local[:, 0:1] * tangents + local[:, 1:2] * b + local[:, 2:3] * smooth)
    world[np.einsum("ij,ij->i", n, smooth) < 0.0] *= -1.0
    return world


def valid_reflection(ng: np.ndarray, wo: np.ndarray, n: np.ndarray) -> np.ndarray:
    """(N, 3) unit normals n bent towards the geometric normals ng until the view wo (unit,
    towards the viewer, on ng's side) reflected about them leaves the surface by at least
    t = min(REFLECTION_FLOOR_SHARE wo.ng, REFLECTION_FLOOR) in cos; others are returned as they are.

    The bent normal stays in the plane of ng and n's tangential direction X: n' = x X + z ng,
    x^2 + z^2 = 1. Its reflection meets 2 z (x w_x + z w_z) - w_z = t (w_x = wo.X, w_z = wo.ng);
    squaring, u = z^2 solves 4 a u^2 - 4 (a + t w_z) u + (t + w_z)^2 = 0 with a = w_x^2 + w_z^2,
    and the sign of 2 z x w_x = t + w_z - 2 u w_z picks the root: the larger when w_x < 0.
    """
    wz = np.einsum("ij,ij->i", wo, ng)
    r = 2.0 * np.einsum("ij,ij->i", n, wo)[:, None] * n - wo
    t = np.minimum(REFLECTION_FLOOR_SHARE * wz, REFLECTION_FLOOR)
    bad = np.einsum("ij,ij->i", r, ng) < t
    if not bad.any():
        return n
    out = n.copy()
    nb, gb, wb, tb, zb = n[bad], ng[bad], wo[bad], t[bad], wz[bad]
    x_axis = nb - np.einsum("ij,ij->i", nb, gb)[:, None] * gb
    x_len = np.linalg.norm(x_axis, axis=1, keepdims=True)
    # n along ng already (no tangential part): the view's own tangent direction will do.
    x_axis = np.where(x_len > MIN_LENGTH, x_axis / np.maximum(x_len, MIN_LENGTH),
                      _normalize(wb - zb[:, None] * gb))
    wx = np.einsum("ij,ij->i", wb, x_axis)
    a = wx * wx + zb * zb
    half_b = a + tb * zb
    root = np.sqrt(np.maximum(half_b * half_b - a * (tb + zb) ** 2, 0.0))
    u = np.clip(np.where(wx < 0.0, half_b + root, half_b - root) / (2.0 * np.maximum(a, MIN_LENGTH)),
                0.0, 1.0)
    out[bad] = np.sqrt(1.0 - u)[:, None] * x_axis + np.sqrt(u)[:, None] * gb
    return out


def relief_shadowing(smooth: np.ndarray, bumped: np.ndarray):
    """`bump_shadowing` of points with smooth and bumped unit normals (N, 3) as a function of
    the unit directions to a light (N, 3) -> (N,): the direction weight
    `lights.direct_irradiance` takes, evaluated at the tilted points only (an area lamp calls it
    once per point of its grid)."""
    tilted = np.flatnonzero(np.einsum("ij,ij->i", smooth, bumped) < 1.0)
    smooth_t, bumped_t = smooth[tilted], bumped[tilted]

    def weight(to_light: np.ndarray) -> np.ndarray:
        out = np.ones(len(smooth))
        out[tilted] = bump_shadowing(smooth_t, bumped_t, to_light[tilted])
        return out

    return weight


def bump_shadowing(smooth: np.ndarray, bumped: np.ndarray, to_light: np.ndarray) -> np.ndarray:
    """(N,) factor in [0, 1] on the diffuse light arriving from unit directions to_light (N, 3)
    at points whose smooth (interpolated, unperturbed) unit normals are smooth (N, 3) and whose
    relief tilts them to bumped (N, 3): Cycles' bump shadowing term for diffuse closures.

    A tilted normal would take light from directions below the real surface, and more of it than
    the smooth surface gets at a low sun: the relief's own facets hide part of it. Cycles
    (Blender 4.x and 5.x, `bump_shadowing_term` under the material's Bump Map Correction, on by
    default) treats the tilts as a GGX microfacet surface of alpha^2 = tan^2(d) / 8
    (`BUMP_ALPHA2_PER_TAN2`, d the tilt) and weighs the light by its masking term
    G1 = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta_i)), theta_i the light's angle to the smooth
    normal; a light on the other side of the smooth surface than the bumped normal sends
    nothing. Untilted normals (d = 0) give 1 exactly, so unbumped points are left as they are."""
    cos_si = np.einsum("ij,ij->i", smooth, to_light)
    cos_sn = np.einsum("ij,ij->i", smooth, bumped)
    cos_ni = np.einsum("ij,ij->i", bumped, to_light)
    out = np.ones(len(smooth))
    cos_i, cos_d = np.abs(cos_si), np.abs(cos_sn)
    tilted = (cos_d < 1.0) & (cos_i < 1.0)
    tan2_d = 1.0 / np.maximum(cos_d[tilted], MIN_LENGTH) ** 2 - 1.0
    alpha2 = np.clip(BUMP_ALPHA2_PER_TAN2 * tan2_d, 0.0, 1.0)
    c = np.maximum(cos_i[tilted], GRAZING_COS)
    tan2_i = 1.0 / (c * c) - 1.0
    out[tilted] = 2.0 / (1.0 + np.sqrt(1.0 + alpha2 * tan2_i))
    out[tilted & (cos_i < GRAZING_COS)] = 0.0
    out[(cos_si * cos_sn * cos_ni < 0.0) & (cos_sn < 1.0)] = 0.0
    return out


# The uniform surround's share (`relief_sky_factor`) is tabulated at this many tilts, cos d in
# [0, 1] evenly, and integrated over a polar x azimuth grid of this many cells on the smooth
# normal's hemisphere (midpoints): within 0.1% of finer grids.
SKY_FACTOR_STEPS = 65
SKY_GRID = (96, 192)


def relief_sky_factor(smooth: np.ndarray, bumped: np.ndarray) -> np.ndarray:
    """(N,) the share of a uniform surround's diffuse irradiance (a sky, the light of the room
    around) that points whose smooth unit normals (N, 3) a relief tilts to bumped (N, 3) take,
    relative to the smooth normal's: (1 / pi) times the integral over the smooth normal's
    hemisphere of max(0, bumped . w) weighed by Cycles' bump shadowing term (`bump_shadowing`).
    1 for untilted points; about (1 + cos d) / 2 without the shadowing term, d the tilt.
    Radiosity's gather applies it to the light it interpolates from the patches' corners,
    which was gathered about the smooth normals."""
    cos_d = np.clip(np.einsum("ij,ij->i", smooth, bumped), 0.0, 1.0)
    table = _sky_factor_table()
    return np.interp(cos_d, np.linspace(0.0, 1.0, SKY_FACTOR_STEPS), table)


@lru_cache(maxsize=1)
def _sky_factor_table() -> np.ndarray:
    """(SKY_FACTOR_STEPS,) `relief_sky_factor` at cos d = 0, ..., 1, by midpoint quadrature."""
    rows, cols = SKY_GRID
    theta = (np.arange(rows) + 0.5) * (0.5 * np.pi / rows)
    phi = (np.arange(cols) + 0.5) * (2.0 * np.pi / cols)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    w = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    solid = (np.sin(t) * (0.5 * np.pi / rows) * (2.0 * np.pi / cols)).ravel()  # sr per cell
    smooth = np.broadcast_to([0.0, 0.0, 1.0], w.shape)
    out = []
    for c in np.linspace(0.0, 1.0, SKY_FACTOR_STEPS):
        bumped = np.broadcast_to([np.sqrt(1.0 - c * c), 0.0, c], w.shape)
        cosine = np.maximum(w @ bumped[0], 0.0)
        out.append(float(np.sum(cosine * bump_shadowing(smooth, bumped, w) * solid)) / np.pi)
    table = np.array(out)
    return table / table[-1]  # the quadrature's own error cancels: 1 exactly when untilted


def has_bump(material: Material) -> bool:
    return material.height_texture is not None or material.normal_texture is not None


def relief_at(scene: Scene, tri: np.ndarray) -> np.ndarray:
    """(N,) bool: the triangles' (N,) materials carry a bump or normal map."""
    return np.array([has_bump(m) for m in scene.materials], bool)[scene.material_ids[tri]]


def perturb(material: Material, n: np.ndarray, triangles: np.ndarray, corner_uvs: np.ndarray,
            uv: np.ndarray) -> np.ndarray:
    """(N, 3) shading normals of `material` at N points: its normal map, then its Bump node's
    height (on the mapped normal, where a Normal Map feeds the Bump node), applied to unit
    normals n, the points' triangles (N, 3, 3) with their corner UVs (N, 3, 2) and the points'
    UVs (N, 2). Materials without either return n."""
    if not has_bump(material):
        return n
    dpdu, dpdv = uv_derivatives(triangles, corner_uvs)
    if material.normal_texture is not None:
        rgb = sample_texture(material.normal_texture, uv)
        n = normal_mapped(n, dpdu, dpdv, rgb, material.normal_strength)
    if material.height_texture is None:
        return n
    slope = height_slope(material.height_texture, uv)
    return bumped_normals(n, dpdu, dpdv, slope, material.bump_distance,
                          max(float(material.bump_strength), 0.0))


def scene_normals(scene: Scene, tri: np.ndarray, bary: np.ndarray, n: np.ndarray) -> np.ndarray:
    """(N, 3) shading normals at N points of `scene` given as triangles (N,) and barycentrics
    (N, 3) (weights of corners 0, 1, 2): unit normals n perturbed by each point's material (`perturb`);
    points of materials without relief keep n. What every view that shades with normals calls."""
    materials = scene.material_ids[tri]
    out = n
    for m in np.unique(materials):
        if not has_bump(scene.materials[m]):
            continue
        if out is n:
            out = n.copy()
        rows = np.nonzero(materials == m)[0]
        material = scene.materials[m]
        if material.normal_texture is not None and scene.corner_tangents is not None:
            framed = _mikktspace_rows(scene, tri, bary, rows, material, n, out)
            if material.height_texture is not None and framed.any():
                _bump_rows(scene, tri, bary, rows[framed], material, out)
            rows = rows[~framed]  # objects without frames: the triangles' own, below
        corner_uvs = _relief_uv(scene, material)[tri[rows]].astype(np.float64)
        uv = np.einsum("nk,nkc->nc", bary[rows], corner_uvs)
        out[rows] = perturb(material, n[rows], scene.triangles[tri[rows]], corner_uvs, uv)
    return out


def _bump_rows(scene: Scene, tri: np.ndarray, bary: np.ndarray, rows: np.ndarray,
               material: Material, out: np.ndarray) -> None:
    """`material`'s Bump node on the normals out[rows] (already normal-mapped), in place."""
    corner_uvs = _relief_uv(scene, material)[tri[rows]].astype(np.float64)
    uv = np.einsum("nk,nkc->nc", bary[rows], corner_uvs)
    dpdu, dpdv = uv_derivatives(scene.triangles[tri[rows]], corner_uvs)
    slope = height_slope(material.height_texture, uv)
    out[rows] = bumped_normals(out[rows], dpdu, dpdv, slope, material.bump_distance,
                               max(float(material.bump_strength), 0.0))


def _relief_uv(scene: Scene, material: Material) -> np.ndarray:
    """(T, 3, 2) corner UVs `material`'s relief texture is read on: a normal map's own layer
    (`Scene.normal_map_uv`), else the active render layer's (`Scene.uv`)."""
    if material.normal_texture is not None and scene.normal_map_uv is not None:
        return scene.normal_map_uv
    return scene.uv


def _mikktspace_rows(scene: Scene, tri: np.ndarray, bary: np.ndarray, rows: np.ndarray,
                     material: Material, n: np.ndarray, out: np.ndarray) -> np.ndarray:
    """Shade `rows` (M,) of a normal-mapped material in the scene's MikkTSpace corner frames
    (`mikktspace_normal_mapped`), writing `out`; returns (M,) bool, the rows that had frames."""
    weights, corners = bary[rows], tri[rows]
    tangents = np.einsum("nk,nkc->nc", weights, scene.corner_tangents[corners].astype(np.float64))
    framed = np.linalg.norm(tangents, axis=1) > MIN_LENGTH
    if not framed.any():
        return framed
    weights, corners, done = weights[framed], corners[framed], rows[framed]
    smooth = np.einsum("nk,nkc->nc", weights, scene.normals[corners].astype(np.float64))
    signs = np.einsum("nk,nk->n", weights, scene.corner_signs[corners].astype(np.float64))
    uv = np.einsum("nk,nkc->nc", weights, _relief_uv(scene, material)[corners].astype(np.float64))
    rgb = sample_texture(material.normal_texture, uv)
    out[done] = mikktspace_normal_mapped(n[done], smooth, tangents[framed], signs, rgb,
                                         material.normal_strength, scene.normal_map_unit_normal)
    return framed
