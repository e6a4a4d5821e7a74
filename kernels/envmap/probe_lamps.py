"""Area lamps in a captured cube map: what the probe's centre sees of the lamps themselves.

The capture renders the scene's surfaces only (`envmap.capture_steps`): the camera view adds a
lamp that a mirror's reflected ray meets exactly, with an occlusion ray (`Tracer._environment`).
A map that leaves the kernels (the files, the material Blender renders) has no such second
look-up, so the lamps must be in its texels.

Each lamp is splatted: its surface is cut into M x M patches (M from its angular size, so that a
patch spans at most 1/PATCHES_PER_TEXEL of a texel); a patch of area dA at distance r, seen at
cos_e from its normal, spans dOmega = dA cos_e / r^2 from the centre and adds w L dOmega / Omega_t
to the four texels t around where it lands, w its bilinear weights (a tent one texel wide: no
aliasing between the patch grid and the texel grid) and Omega_t the texel's exact solid angle,
unless the texel's captured surface is nearer than r. So a texel holds the lamp's radiance
filtered over its footprint, and the map holds the lamp's power exactly however small the lamp
(up to the patches' flat-patch approximation, second order in their size); where it covers a
texel's whole footprint the texel holds L within 0.3% (the tent's ripple over patches 1/4 texel
apart). Border texels (`EnvironmentMap.border`) are splatted through their own face's wider
frustum, as the capture renders them.

Lamps are one-sided (they emit towards their local -Z, `Light.direction`), rectangles (SQUARE,
RECTANGLE) or ellipses (DISK, ELLIPSE) of size_x by size_y, as the tracer meets them.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..geometry.scene import Light
from .cubemap import FACE_FORWARD, FACE_U, FACE_V
from .envmap import EnvironmentMap

# A lamp patch spans at most 1/4 of a texel (its outline lands within a quarter texel).
PATCHES_PER_TEXEL = 4
# Patches per lamp side at least (a lamp far smaller than a texel) and at most (1M patches).
MIN_PATCHES = 8
MAX_PATCHES = 1024


def _extended_solid_angles(size: int, border: int) -> np.ndarray:
    """(S + 2B, S + 2B) float64 sr of the bordered texels of a face (the plane at distance 1,
    texel edges 2 k / S - 1 for k = -B .. S + B), as `prefilter.texel_solid_angles` inside."""
    edges = 2.0 * np.arange(-border, size + border + 1) / size - 1.0
    x, y = np.meshgrid(edges, edges, indexing="xy")
    a = np.arctan2(x * y, np.sqrt(x * x + y * y + 1.0))
    return a[:-1, :-1] - a[1:, :-1] - a[:-1, 1:] + a[1:, 1:]


def _patches(lamp: Light, centre: np.ndarray, texel_angle: float
             ) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) world points at the lamp's patch centres and (K,) sr each spans from `centre` (0 for
    patches seen from behind)."""
    distance = max(float(np.linalg.norm(lamp.position - centre)), 1e-9)
    extent = max(lamp.size_x, lamp.size_y) / distance  # rad, about
    m = int(np.clip(np.ceil(PATCHES_PER_TEXEL * extent / texel_angle), MIN_PATCHES, MAX_PATCHES))
    cells = (np.arange(m) + 0.5) / m - 0.5
    u, v = (g.reshape(-1) for g in np.meshgrid(cells, cells, indexing="xy"))
    if lamp.shape in ("DISK", "ELLIPSE"):
        keep = u * u + v * v <= 0.25
        u, v = u[keep], v[keep]
    points = (lamp.position + u[:, None] * lamp.size_x * lamp.axis_x
              + v[:, None] * lamp.size_y * lamp.axis_y)
    w = points - centre
    r2 = np.einsum("ij,ij->i", w, w)
    cos_e = -(w @ lamp.direction) / np.sqrt(np.maximum(r2, 1e-30))  # > 0: the emitting side
    area = lamp.size_x * lamp.size_y / (m * m)
    return points, np.where(cos_e > 0.0, area * cos_e / np.maximum(r2, 1e-30), 0.0)


def lamp_faces(env: EnvironmentMap, lamps: Sequence[Light]) -> np.ndarray:
    """(6, S + 2B, S + 2B, 3) float32: the area lamps' radiance each bordered texel of `env` sees
    from its centre (module docstring), to add to `env.faces`. Zero without area lamps."""
    size, border = env.size, env.border
    side = size + 2 * border
    out = np.zeros((6, side, side, 3), np.float64)
    area = [lamp for lamp in lamps if lamp.kind == "AREA" and lamp.radiance is not None]
    if not area:
        return out.astype(np.float32)
    centre = np.asarray(env.centre, np.float64)
    inverse = env.inverse_distance[..., 0].astype(np.float64)
    t_surface = np.where(inverse > 0.0, 1.0 / np.maximum(inverse, 1e-30), np.inf)  # (6, s, s)
    omega = _extended_solid_angles(size, border)
    for lamp in area:
        points, d_omega = _patches(lamp, centre, 2.0 / size)
        w = points - centre
        r = np.linalg.norm(w, axis=1)
        for f in range(6):
            a = w @ FACE_FORWARD[f]
            ahead = (a > 0.0) & (d_omega > 0.0)
            sc = np.divide(w @ FACE_U[f], a, out=np.zeros_like(a), where=ahead)
            tc = np.divide(w @ FACE_V[f], a, out=np.zeros_like(a), where=ahead)
            # continuous texel coordinates, bordered texel centres at integers
            x = (sc + 1.0) * size / 2.0 - 0.5 + border
            y = (1.0 - tc) * size / 2.0 - 0.5 + border
            x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
            fx, fy = x - x0, y - y0
            energy = np.zeros((side, side))
            for di, dj, weight in ((0, 0, (1 - fy) * (1 - fx)), (0, 1, (1 - fy) * fx),
                                   (1, 0, fy * (1 - fx)), (1, 1, fy * fx)):
                i, j = y0 + di, x0 + dj
                on = ahead & (i >= 0) & (i < side) & (j >= 0) & (j < side)
                i, j = i[on], j[on]
                seen = r[on] < t_surface[f, i, j]
                np.add.at(energy, (i[seen], j[seen]), (d_omega * weight)[on][seen])
            out[f] += (energy / omega)[..., None] * np.asarray(lamp.radiance, np.float64)
    return out.astype(np.float32)
