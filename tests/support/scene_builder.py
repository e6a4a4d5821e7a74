"""Build kernel `Scene`s by hand for tests: quads, boxes, spheres and cameras, no Blender."""

from __future__ import annotations

import numpy as np

from classic_bake.kernels.geometry.scene import Camera, Material, ObjectInfo, Scene


def quad(corners) -> np.ndarray:
    """Two CCW triangles (2, 3, 3) from four corners given counter-clockwise."""
    c = np.asarray(corners, np.float64)
    return np.array([[c[0], c[1], c[2]], [c[0], c[2], c[3]]])


def uv_sphere(centre, radius, rings=48, segments=96, inward=False) -> np.ndarray:
    """(T, 3, 3) triangles of a UV sphere, outward normals (inward=True flips them)."""
    th = np.linspace(0, np.pi, rings + 1)
    ph = np.linspace(0, 2 * np.pi, segments + 1)
    p = np.stack(np.meshgrid(th, ph, indexing="ij"), -1)
    pts = np.stack([np.sin(p[..., 0]) * np.cos(p[..., 1]), np.sin(p[..., 0]) * np.sin(p[..., 1]),
                    np.cos(p[..., 0])], -1) * radius + np.asarray(centre)
    tris = []
    for i in range(rings):
        for j in range(segments):
            a, b, c, d = pts[i, j], pts[i + 1, j], pts[i + 1, j + 1], pts[i, j + 1]
            if i > 0:
                tris.append([a, b, d])
            if i < rings - 1:
                tris.append([b, c, d])
    tris = np.array(tris)
    return tris if not inward else tris[:, ::-1]  # [a, b, d]: e_theta x e_phi, outwards


def build(parts, camera=None, lights=(), world=(0.0, 0.0, 0.0)) -> Scene:
    """parts: list of (triangles (T, 3, 3), Material). Flat shading normals; UV = xy of the corner."""
    tris, mats, mids, oids, objects = [], [Material(name="(default)", specular=0.0)], [], [], []
    start = 0
    for k, (t, mat) in enumerate(parts):
        t = np.asarray(t, np.float64)
        tris.append(t)
        mats.append(mat)
        mids.append(np.full(len(t), len(mats) - 1, np.int32))
        oids.append(np.full(len(t), k, np.int32))
        objects.append(ObjectInfo(name=f"obj{k}", source_name=f"obj{k}", tri_start=start,
                                  tri_count=len(t), has_uv=True, has_lightmap_uv=False,
                                  topology_matches_original=True))
        start += len(t)
    tri = np.concatenate(tris).astype(np.float32)
    e = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]).astype(np.float64)
    n = e / np.maximum(np.linalg.norm(e, axis=1, keepdims=True), 1e-30)
    return Scene(
        triangles=tri, normals=np.repeat(n[:, None], 3, 1).astype(np.float32),
        uv=tri[:, :, :2].copy(), lightmap_uv=None, material_ids=np.concatenate(mids),
        object_ids=np.concatenate(oids), corner_loops=np.zeros((len(tri), 3), np.int32),
        corner_verts=np.zeros((len(tri), 3), np.int32), objects=tuple(objects),
        materials=tuple(mats), lights=tuple(lights), camera=camera,
        world_color=np.asarray(world, np.float32))


def ortho_camera(position, forward, up, width_m, resolution=(8, 8)) -> Camera:
    """An orthographic camera at `position` looking along `forward`, `width_m` across."""
    f = np.asarray(forward, np.float64) / np.linalg.norm(forward)
    u = np.asarray(up, np.float64)
    r = np.cross(f, u)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = r, u, -f, position
    aspect = resolution[1] / resolution[0]
    half = np.array([width_m / 2, width_m / 2 * aspect])
    return Camera(kind="ORTHO", matrix_world=m, plane_min=-half, plane_max=half,
                  resolution=resolution, clip_start=0.0)


def persp_camera(position, forward, up, fov_x_rad, resolution=(8, 8)) -> Camera:
    """A perspective camera at `position` looking along `forward` with horizontal field `fov_x_rad`."""
    cam = ortho_camera(position, forward, up, 2.0 * np.tan(fov_x_rad / 2), resolution)
    return Camera(kind="PERSP", matrix_world=cam.matrix_world, plane_min=cam.plane_min,
                  plane_max=cam.plane_max, resolution=resolution, clip_start=0.0)


def grey(rho, emission=0.0, name="grey"):
    """A grey Lambertian material (Specular IOR Level 0) of reflectance rho, emitting radiance
    `emission` (W/(m^2 sr))."""
    return Material(name=name, base_color=np.full(3, rho, np.float32), specular=0.0,
                    emission=np.full(3, emission, np.float32))


def inward_box(size=1.0):
    """(12, 3, 3) triangles of a cube [0, size]^3 with normals pointing inside."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float) * size
    faces = [[0, 1, 2, 3], [4, 7, 6, 5], [0, 4, 5, 1], [1, 5, 6, 2], [2, 6, 7, 3], [3, 7, 4, 0]]
    return np.concatenate([quad(v[f]) for f in faces])


def floor_quad(z=0.0, lo=0.0, hi=1.0):
    """(2, 3, 3) triangles of the square [lo, hi]^2 at height z, facing +z."""
    return quad([[lo, lo, z], [hi, lo, z], [hi, hi, z], [lo, hi, z]])


def tessellated_box(n: int, size: float = 1.0) -> np.ndarray:
    """(6 x 2 n^2, 3, 3) triangles of the cube [0, size]^3, each face an n x n grid of quads,
    normals inward."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float) * size
    faces = [[0, 1, 2, 3], [4, 7, 6, 5], [0, 4, 5, 1], [1, 5, 6, 2], [2, 6, 7, 3], [3, 7, 4, 0]]
    out = []
    t = np.linspace(0.0, 1.0, n + 1)
    for f in faces:
        a, b, _, d = v[f]
        for i in range(n):
            for j in range(n):
                corner = [a + (b - a) * t[i] + (d - a) * t[j], a + (b - a) * t[i + 1] + (d - a) * t[j],
                          a + (b - a) * t[i + 1] + (d - a) * t[j + 1],
                          a + (b - a) * t[i] + (d - a) * t[j + 1]]
                out.append(quad(corner))
    return np.concatenate(out)


def lamp_room_with_ball():
    """A grey room, an emissive square under its ceiling and a finely tessellated ball (an
    orange diffuse one) standing in its light."""
    room = tessellated_box(1)
    lamp = quad([[0.4, 0.4, 0.99], [0.4, 0.6, 0.99], [0.6, 0.6, 0.99], [0.6, 0.4, 0.99]])
    ball = uv_sphere((0.5, 0.5, 0.3), 0.2, rings=16, segments=32)
    orange = Material(name="orange", base_color=np.array([0.8, 0.4, 0.1], np.float32), specular=0.0,
                      emission=np.zeros(3, np.float32))
    return build([(room, grey(0.6)), (lamp, grey(0.0, emission=20.0, name="lamp")),
                  (ball, orange)])


def mirror_highlight(roughness: float, f0: float, strength: float, degrees: float) -> float:
    """Radiance of a sun of `strength` W/m^2 reflected by a GGX layer (Blender roughness, F0)
    seen in the mirror direction, both `degrees` off the normal (half vector = normal):
    F D G1^2 S / (4 cos) with D = 1 / (pi alpha^2), Smith's G1, Schlick's F (the tracer's lobe),
    times Cycles' factor for light scattered more than once among the microfacets
    (`specular_layer.energy_compensation`, tested against the white furnace on its own)."""
    from classic_bake.kernels.shading.specular_layer import energy_compensation

    alpha2 = roughness ** 4
    c = np.cos(np.radians(degrees))
    g1 = 2.0 * c / (c + np.sqrt(alpha2 + (1.0 - alpha2) * c * c))
    fresnel = f0 + (1.0 - f0) * (1.0 - c) ** 5
    kept = energy_compensation(np.array([c]), np.array([roughness]), np.full((1, 3), f0))[0, 0]
    return fresnel / (np.pi * alpha2) * g1 * g1 * strength / (4.0 * c) * kept


def mirror_view(degrees: float, width: float = 0.5, resolution=(4, 4)):
    """An orthographic camera and a sun direction `degrees` either side of +z in the yz plane,
    mirror images of each other about the ground's normal: (camera, sun direction)."""
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    forward = np.array([0.0, s, -c])
    return ortho_camera(-5.0 * forward, forward, (0, 0, 1), width, resolution), np.array([0.0, -s, -c])



def striped_sky(height: int = 128, width: int = 256, bright=(1.5, 1.5, 1.5), dark: float = 0.15
                ) -> np.ndarray:
    """(H, W, 3) float32 equirectangular pixels (row 0 at the top): stripes of `bright` and
    `dark` radiance, 8 texels wide (5.6 degrees at 256 columns), above the horizon; `dark` below."""
    v, u = np.mgrid[0:height, 0:width]
    pixels = np.full((height, width, 3), dark, np.float32)
    pixels[((u // 8) % 2 == 0) & (v < height // 2)] = bright
    return pixels
