"""Test helpers for the radiosity kernels: a brute-force ray tracer and simple patch scenes.

Not for production: `BruteForceTracer` tests every ray against every triangle (O(R T)); it exists
so that form factor tests need no BVH. The scenes are the analytic configurations of
tests/data/form_factors.json and the Cornell box of tests/data/cornell_box.json.
"""

from __future__ import annotations

import math

import numpy as np

# Barycentric slack: a ray through a shared edge or corner counts as a hit on both neighbours
# (watertight for the tests' meshes); 1e-9 of an edge is far below any sampling scale used.
EDGE_EPS = 1e-9
# |det| below this (relative to |e1||e2||d|) means the ray runs parallel to the triangle's plane.
PARALLEL_EPS = 1e-12
# Broadcast work per chunk: rays x triangles (keeps temporaries near 100 MB).
CHUNK_ELEMENTS = 1 << 21


class BruteForceTracer:
    """Möller-Trumbore against all (T, 3, 3) triangles, vectorised over chunks of rays.

    Both callbacks follow the contract in `kernels.radiosity.form_factors`: origins, directions (R, 3);
    t_min float; t_max float or (R,); both sides of a triangle hit.
    """

    def __init__(self, triangles: np.ndarray) -> None:
        tri = np.asarray(triangles, np.float64)
        self.v0 = tri[:, 0]  # (T, 3), m
        self.e1 = tri[:, 1] - tri[:, 0]
        self.e2 = tri[:, 2] - tri[:, 0]
        self.scale = np.linalg.norm(self.e1, axis=1) * np.linalg.norm(self.e2, axis=1)  # (T,)

    def closest_hit(self, origins, directions, t_min=0.0, t_max=math.inf):
        """(t (R,) float32, inf on a miss; tri (R,) int32, -1 on a miss)."""
        o = np.asarray(origins, np.float64)
        d = np.asarray(directions, np.float64)
        t_max = np.broadcast_to(np.asarray(t_max, np.float64), (len(o),))
        best_t = np.full(len(o), np.inf)
        best_tri = np.full(len(o), -1, np.int64)
        chunk = max(1, CHUNK_ELEMENTS // max(1, len(self.v0)))
        for s in range(0, len(o), chunk):
            t = self._hit_t(o[s : s + chunk], d[s : s + chunk], t_min, t_max[s : s + chunk])
            arg = np.argmin(t, axis=1)
            tt = t[np.arange(len(t)), arg]
            best_t[s : s + chunk] = tt
            best_tri[s : s + chunk] = np.where(np.isfinite(tt), arg, -1)
        return best_t.astype(np.float32), best_tri.astype(np.int32)

    def occluded(self, origins, directions, t_min=0.0, t_max=math.inf):
        """(R,) bool: any hit with t_min < t < t_max."""
        t, _ = self.closest_hit(origins, directions, t_min, t_max)
        return np.isfinite(t)

    def _hit_t(self, o, d, t_min, t_max):
        """(r, T) hit distances, inf where the ray misses the triangle."""
        pvec = np.cross(d[:, None, :], self.e2[None])  # (r, T, 3)
        det = np.einsum("tc,rtc->rt", self.e1, pvec)
        lengths = self.scale[None] * np.linalg.norm(d, axis=1)[:, None]
        ok = np.abs(det) > PARALLEL_EPS * lengths
        inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
        tvec = o[:, None, :] - self.v0[None]  # (r, T, 3)
        u = np.einsum("rtc,rtc->rt", tvec, pvec) * inv
        qvec = np.cross(tvec, self.e1[None])
        v = np.einsum("rc,rtc->rt", d, qvec) * inv
        t = np.einsum("tc,rtc->rt", self.e2, qvec) * inv
        ok &= (u >= -EDGE_EPS) & (v >= -EDGE_EPS) & (u + v <= 1.0 + EDGE_EPS)
        ok &= (t > t_min) & (t < t_max[:, None])
        return np.where(ok, t, np.inf)


# --- scenes ---------------------------------------------------------------------------------------


def quad_triangles(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split (N, 4, 3) quads into (2N, 3, 3) triangles (0,1,2), (0,2,3); returns them and the
    (2N,) int32 patch index of each triangle."""
    c = np.asarray(corners, np.float64)
    tris = np.stack([c[:, [0, 1, 2]], c[:, [0, 2, 3]]], axis=1).reshape(-1, 3, 3)
    return tris, np.repeat(np.arange(len(c), dtype=np.int32), 2)


def subdivide_quad(quad: np.ndarray, nu: int, nv: int) -> np.ndarray:
    """Split one planar quad (4, 3) (corners 0-1 along u, 0-3 along v) into nu x nv bilinear
    sub-quads (nu nv, 4, 3), keeping the winding."""
    q = np.asarray(quad, np.float64)
    u = np.linspace(0.0, 1.0, nu + 1)[:, None, None]
    v = np.linspace(0.0, 1.0, nv + 1)[None, :, None]
    grid = (1 - u) * (1 - v) * q[0] + u * (1 - v) * q[1] + u * v * q[2] + (1 - u) * v * q[3]
    a, b = grid[:-1, :-1], grid[1:, :-1]
    c, d = grid[1:, 1:], grid[:-1, 1:]
    return np.stack([a, b, c, d], axis=2).reshape(-1, 4, 3)


def unit_cube_patches(n: int) -> np.ndarray:
    """The inside of the unit cube [0, 1]^3, each face split into n x n patches facing inward.

    Returns (6 n^2, 4, 3) corners, faces in the order -z (floor), +z, -x, +x, -y, +y.
    """
    faces = [
        [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],  # z = 0, normal +z
        [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]],  # z = 1, normal -z
        [[0, 0, 0], [0, 1, 0], [0, 1, 1], [0, 0, 1]],  # x = 0, normal +x
        [[1, 0, 0], [1, 0, 1], [1, 1, 1], [1, 1, 0]],  # x = 1, normal -x
        [[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0]],  # y = 0, normal +y
        [[0, 1, 0], [1, 1, 0], [1, 1, 1], [0, 1, 1]],  # y = 1, normal -y
    ]
    return np.concatenate([subdivide_quad(np.array(f, np.float64), n, n) for f in faces])


def regular_polygon(centre, normal, radius: float, sides: int) -> np.ndarray:
    """(sides, 3) corners of a regular polygon inscribed in a circle, CCW around `normal`."""
    n = np.asarray(normal, np.float64)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(n, helper)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)
    a = 2.0 * math.pi * np.arange(sides) / sides
    return np.asarray(centre, np.float64) + radius * (
        np.cos(a)[:, None] * t1 + np.sin(a)[:, None] * t2
    )


def fan_triangles(polygon: np.ndarray) -> np.ndarray:
    """(K - 2, 3, 3) fan triangulation of a convex (K, 3) polygon, keeping its winding."""
    k = len(polygon)
    idx = np.stack([np.zeros(k - 2, int), np.arange(1, k - 1), np.arange(2, k)], axis=1)
    return np.asarray(polygon, np.float64)[idx]


# The Cornell box's closed walls, for `cornell_box_patches`.
CORNELL_WALLS = ("floor", "ceiling", "back_wall", "left_wall", "right_wall")


def cornell_box_patches(data: dict, wall_divisions: int, light_drop: float = 1e-3) -> dict:
    """The Cornell box of tests/data/cornell_box.json as radiosity patches.

    `data`: the parsed JSON. Geometry is mapped to Blender's frame by the rotation
    (x, y, z) -> (-x, z, y) and from mm to m; the five walls are split into
    wall_divisions^2 patches each, every light and block quad is one patch. The light quad is
    coplanar with the ceiling in the data; it is lowered by `light_drop` metres (as renderers
    do). Colours: the CornellBox-Original MTL (Kd reflectance, light Ke as emission).
    Returns a dict: corners (N, 4, 3), reflectance (N, 3), emission (N, 3), names (N,) str.
    """
    surfaces = data["cornell_original"]["surfaces"]
    mtl = data["rgb_approximations_in_use"]["mcguire_CornellBox-Original.mtl"]
    kd = {
        "white": mtl["floor_ceiling_backWall_shortBox_tallBox_Kd"],
        "red": mtl["leftWall_red_Kd"],
        "green": mtl["rightWall_green_Kd"],
        "light": mtl["light_Kd"],
    }
    corners, reflectance, emission, names = [], [], [], []
    for name, surface in surfaces.items():
        for quad in surface["quads"]:
            q = np.asarray(quad, np.float64) / 1000.0
            q = np.stack([-q[:, 0], q[:, 2], q[:, 1]], axis=1)
            if name == "light":
                q[:, 2] -= light_drop
            n = wall_divisions if name in CORNELL_WALLS else 1
            sub = subdivide_quad(q, n, n)
            corners.append(sub)
            reflectance += [kd[surface["material"]]] * len(sub)
            emission += [mtl["light_Ke"] if name == "light" else [0.0, 0.0, 0.0]] * len(sub)
            names += [name] * len(sub)
    return {
        "corners": np.concatenate(corners),
        "reflectance": np.asarray(reflectance, np.float64),
        "emission": np.asarray(emission, np.float64),
        "names": np.asarray(names),
    }


def reflected_means(result, objects) -> np.ndarray:
    """(len(objects), 3) the area mean of each object's reflected light B - E over its patches,
    W/m^2 (a `RadiosityResult`)."""
    out = []
    for obj in objects:
        at = result.patches.object_ids == obj
        reflected = result.radiosity[at] - result.emitted[at]
        out.append(np.average(reflected, axis=0, weights=result.patches.areas[at]))
    return np.array(out)
