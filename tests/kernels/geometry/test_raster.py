"""The z-buffer rasteriser: exact coverage (top-left fill rule), exact depth, clipping."""

import numpy as np
import pytest

from classic_bake.kernels.geometry.raster import (
    Projection,
    coverage_count,
    look_at,
    project_points,
    rasterize,
    rasterize_steps,
)

RNG_SEED = 7


def _grid_mesh(vertices: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(n+1, m+1, 3) grid vertices -> (2 n m, 3, 3) triangles, each quad split along a random
    diagonal and wound either way at random (the rasteriser must not care)."""
    a, b = vertices[:-1, :-1], vertices[:-1, 1:]
    c, d = vertices[1:, 1:], vertices[1:, :-1]
    flip = rng.random(a.shape[:2])[..., None] < 0.5
    t1 = np.where(flip[..., None], np.stack([a, b, c], 2), np.stack([a, b, d], 2))
    t2 = np.where(flip[..., None], np.stack([a, c, d], 2), np.stack([b, c, d], 2))
    tris = np.concatenate([t1.reshape(-1, 3, 3), t2.reshape(-1, 3, 3)])
    reverse = rng.random(len(tris)) < 0.5
    tris[reverse] = tris[reverse][:, ::-1]
    return tris


def _pixel_ortho(width: int, height: int) -> Projection:
    """Orthographic camera in which world (x, y) = (col, height - row): pixel (i, j) centre is the
    world point (j + 0.5, height - i - 0.5), so vertices can sit exactly on pixel centres."""
    return Projection.orthographic(np.eye(4), (0.0, width, 0.0, height), 0.5, 10.0)


def test_pixel_centred_grid_covers_each_centre_exactly_once():
    """A grid whose vertices lie on pixel centres (interior ones jittered by whole 1/256 pixels):
    many centres sit exactly on shared edges and vertices. The top-left rule must give every centre
    of the rectangle one triangle, its left and top borders included, right and bottom excluded."""
    rng = np.random.default_rng(RNG_SEED)
    width, height = 96, 80
    c0, c1, r0, r1 = 5, 90, 7, 71  # the rectangle's corner pixel centres (cols / rows)
    cols = np.linspace(c0, c1, 18)[None, :] * np.ones((14, 1))
    rows = np.linspace(r0, r1, 14)[:, None] * np.ones((1, 18))
    cols, rows = np.round(cols), np.round(rows)  # whole pixels: vertices on pixel centres
    jitter = rng.integers(-200, 201, (2,) + cols.shape) / 256.0
    jitter[:, [0, -1], :] = 0.0  # the border stays straight
    jitter[:, :, [0, -1]] = 0.0
    jitter[:, ::3, ::2] = 0.0  # and a third of the interior stays on centres
    x = cols + 0.5 + jitter[0]
    y = height - (rows + 0.5 + jitter[1])
    tris = _grid_mesh(np.stack([x, y, np.full_like(x, -2.0)], -1), rng).astype(np.float32)
    count = coverage_count(tris, _pixel_ortho(width, height), width, height)
    expected = np.zeros((height, width), np.int32)
    expected[r0:r1, c0:c1] = 1  # top row r0 and left column c0 in; r1 and c1 out
    np.testing.assert_array_equal(count, expected)


def test_closed_mesh_front_and_back_layers_each_cover_once():
    """An icosphere in perspective: front faces alone and back faces alone each cover the
    silhouette exactly once, the same pixels, with no holes, over the expected area."""
    tris = _icosphere(3).astype(np.float64)
    rng = np.random.default_rng(RNG_SEED)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    tris = (tris @ q.T + np.array([0.3, -0.2, -6.0])).astype(np.float32)
    fov, size = np.radians(30.0), 200
    proj = Projection.perspective(np.eye(4), fov, 0.1, 100.0)
    front = coverage_count(tris, proj, size, size, cull="BACK")
    back = coverage_count(tris, proj, size, size, cull="FRONT")
    both = coverage_count(tris, proj, size, size)
    assert front.max() == 1 and back.max() == 1
    np.testing.assert_array_equal(front, back)
    np.testing.assert_array_equal(both, front + back)
    assert not _holes(front > 0).any()
    # Silhouette area: between the projected discs of the inscribed and circumscribed spheres,
    # radius f r / sqrt(D^2 - r^2) pixels (2% for the slight off-axis stretch).
    f_px, dist = size / (2 * np.tan(fov / 2)), np.linalg.norm([0.3, -0.2, -6.0])
    r_in = _inradius(3)
    lo = np.pi * (f_px * r_in) ** 2 / (dist**2 - r_in**2)
    hi = np.pi * f_px**2 / (dist**2 - 1.0)
    assert 0.98 * lo < front.sum() < 1.02 * hi


def _icosphere(level: int) -> np.ndarray:
    t = (1 + 5**0.5) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
                  [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], float)
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
         (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    tris = v[np.array(f)]
    tris /= np.linalg.norm(tris, axis=2, keepdims=True)
    for _ in range(level):  # split every triangle in four; shared midpoints are bit-identical
        a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
        ab, bc, ca = (a + b), (b + c), (c + a)
        ab, bc, ca = (m / np.linalg.norm(m, axis=1, keepdims=True) for m in (ab, bc, ca))
        tris = np.concatenate([np.stack(t, 1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c),
                                                        (ab, bc, ca))])
    return tris


def _inradius(level: int) -> float:
    tris = _icosphere(level)
    n = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return float(np.abs((n * tris[:, 0]).sum(axis=1)).min())


def _holes(mask: np.ndarray) -> np.ndarray:
    """Uncovered pixels not connected (4-neighbours) to the image border."""
    outside = np.zeros_like(mask)
    outside[[0, -1], :] = ~mask[[0, -1], :]
    outside[:, [0, -1]] |= ~mask[:, [0, -1]]
    while True:
        grown = outside.copy()
        grown[1:] |= outside[:-1]
        grown[:-1] |= outside[1:]
        grown[:, 1:] |= outside[:, :-1]
        grown[:, :-1] |= outside[:, 1:]
        grown &= ~mask
        if np.array_equal(grown, outside):
            return ~mask & ~outside
        outside = grown


def test_perspective_grid_crossing_near_and_side_planes():
    """A large jittered ground grid seen from a low eye: it passes behind the eye, through the near
    plane and far beyond the sides. Clipped triangles must still tile: each centre at most once,
    exactly once where the analytic ray hits the grid well inside [near, far], at its exact depth.
    """
    rng = np.random.default_rng(RNG_SEED)
    n = 40
    g = np.linspace(-30.0, 30.0, n + 1)
    x, y = np.meshgrid(g, g)
    x[1:-1, 1:-1] += rng.uniform(-0.4, 0.4, (n - 1, n - 1))
    y[1:-1, 1:-1] += rng.uniform(-0.4, 0.4, (n - 1, n - 1))
    tris = _grid_mesh(np.stack([x, y, np.zeros_like(x)], -1), rng).astype(np.float32)
    eye = np.array([0.2, -0.3, 1.0])
    view = look_at(eye, [0.0, 1.0, -0.35], [0.0, 0.0, 1.0])
    near, far, size = 1.5, 25.0, 160
    proj = Projection.perspective(view, np.radians(100.0), near, far)
    count = coverage_count(tris, proj, size, size)
    depth = rasterize(tris, proj, size, size).depth
    assert count.max() == 1
    # analytic: the pixel-centre ray hits z = 0 at view depth d
    top = np.tan(np.radians(50.0))
    c = (np.arange(size) + 0.5) / size * 2 - 1
    ray_v = np.stack(np.broadcast_arrays(c[None, :] * top, -c[:, None] * top, -1.0), -1)
    ray_w = ray_v @ view[:3, :3]  # view -> world rotation (inverse = transpose)
    with np.errstate(divide="ignore", invalid="ignore"):
        d = -eye[2] / ray_w[..., 2]  # the ray has view depth 1 per unit step
    hit_xy = eye[:2] + d[..., None] * ray_w[..., :2]
    inside = (d > near * 1.01) & (d < far * 0.99) & (np.abs(hit_xy) < 29.0).all(-1)
    outside = ~((d > near * 0.99) & (d < far * 1.01)) | (np.abs(hit_xy) > 31.0).any(-1)
    assert inside.sum() > 0.2 * size * size and (outside & (ray_w[..., 2] < 0)).any()
    assert np.all(count[inside] == 1) and np.all(count[outside] == 0)
    np.testing.assert_allclose(depth[inside], d[inside], rtol=2e-6)
    assert np.all(np.isinf(depth[outside]))


@pytest.mark.parametrize("kind", ["PERSP", "ORTHO"])
def test_plane_depth_is_exact(kind):
    size, dist = 64, 3.7
    quad = np.array([[[-5, -5, -dist], [5, -5, -dist], [5, 5, -dist]],
                     [[-5, -5, -dist], [5, 5, -dist], [-5, 5, -dist]]], np.float32)
    if kind == "PERSP":
        proj = Projection.perspective(np.eye(4), np.radians(60.0), 0.1, 10.0)
    else:
        proj = Projection.orthographic(np.eye(4), (-2.0, 2.0, -2.0, 2.0), 0.1, 10.0)
    depth = rasterize(quad, proj, size, size).depth
    assert np.all(depth == np.float32(dist))
    # a tilted plane: depth at each centre is the analytic ray-plane intersection
    tilted = quad.astype(np.float64).copy()
    tilted[..., 2] += 0.3 * tilted[..., 0] - 0.2 * tilted[..., 1]
    depth = rasterize(tilted.astype(np.float32), proj, size, size).depth
    c = (np.arange(size) + 0.5) / size * 2 - 1
    u, v = np.broadcast_arrays(c[None, :], -c[:, None])  # NDC of every pixel centre
    if kind == "PERSP":
        k = np.tan(np.radians(30.0))  # ray (u k, v k, -1) d; plane z = -dist + 0.3 x - 0.2 y
        expected = dist / (1 + 0.3 * u * k - 0.2 * v * k)
    else:
        expected = dist - 0.3 * 2 * u + 0.2 * 2 * v
    np.testing.assert_allclose(depth, expected, rtol=1e-6)


def test_perspective_and_orthographic_sizes():
    """A 1 m square: its width in pixels shrinks with distance in perspective, not in ortho."""
    size = 128
    persp = Projection.perspective(np.eye(4), np.radians(40.0), 0.1, 100.0)
    ortho = Projection.orthographic(np.eye(4), (-2.0, 2.0, -2.0, 2.0), 0.1, 100.0)
    for dist in (4.0, 8.0):
        c = np.array([[-0.5, -0.5, -dist], [0.5, -0.5, -dist], [0.5, 0.5, -dist],
                      [-0.5, 0.5, -dist]])
        square = np.array([[c[0], c[1], c[2]], [c[0], c[2], c[3]]], np.float32)
        widths = {}
        for name, proj in (("persp", persp), ("ortho", ortho)):
            row = coverage_count(square, proj, size, size)[size // 2]
            widths[name] = row.sum()
        assert abs(widths["persp"] - size / (2 * np.tan(np.radians(20.0)) * dist)) <= 1
        assert abs(widths["ortho"] - size / 4.0) <= 1


def test_project_points_agrees_with_the_raster():
    rng = np.random.default_rng(RNG_SEED)
    size, dist = 64, 5.0
    view = look_at([1.0, 2.0, 3.0], [-0.2, -0.3, -1.0], [0.0, 1.0, 0.0])
    proj = Projection.perspective(view, np.radians(50.0), 0.1, 50.0)
    # a plane facing the eye at view depth `dist`, as world triangles
    inv = np.linalg.inv(view)
    corners_v = np.array([[-9, -9, -dist, 1], [9, -9, -dist, 1], [9, 9, -dist, 1],
                          [-9, 9, -dist, 1]])
    c = (corners_v @ inv.T)[:, :3]
    quad = np.array([[c[0], c[1], c[2]], [c[0], c[2], c[3]]], np.float32)
    depth = rasterize(quad, proj, size, size).depth
    pts_v = np.column_stack([rng.uniform(-2, 2, (500, 2)), np.full(500, -dist), np.ones(500)])
    pts = (pts_v @ inv.T)[:, :3]
    col, row, z = project_points(pts, proj, size, size)
    np.testing.assert_allclose(z, dist, rtol=1e-12)
    ok = (col >= 0) & (col < size) & (row >= 0) & (row < size)
    assert ok.sum() > 400
    np.testing.assert_allclose(depth[row[ok].astype(int), col[ok].astype(int)], dist, rtol=1e-6)
    # its pixel coordinates: NDC = image-plane position / top
    top = np.tan(np.radians(25.0))
    np.testing.assert_allclose(col, (pts_v[:, 0] / dist / top + 1) * size / 2, rtol=1e-12)
    np.testing.assert_allclose(row, (1 - pts_v[:, 1] / dist / top) * size / 2, rtol=1e-12)
    behind = project_points((np.array([[0, 0, 1.0, 1]]) @ inv.T)[:, :3], proj, size, size)
    assert np.isnan(behind[0][0]) and behind[2][0] < 0


def test_empty_and_degenerate_input():
    proj = _pixel_ortho(32, 32)
    empty = rasterize(np.zeros((0, 3, 3), np.float32), proj, 32, 32, with_triangle_ids=True)
    assert np.all(np.isinf(empty.depth)) and np.all(empty.triangle == -1)
    good = np.array([[[2, 2, -3], [30, 4, -3], [10, 28, -3]]], np.float32)
    bad = np.array([
        [[1, 1, -3], [20, 20, -3], [10, 10, -3]],  # collinear
        [[5, 5, -3], [5, 5, -3], [9, 20, -3]],  # repeated vertex
        [[8, 8, -3], [8, 8, -3], [8, 8, -3]],  # a point
        [[1, 1, -3], [np.nan, 4, -3], [9, 20, -3]],  # not finite
        [[1, 1, -3], [np.inf, 4, -3], [9, 20, -3]],
        [[1, 1, -20], [30, 1, -20], [9, 20, -20]],  # beyond far
    ], np.float32)
    alone = rasterize(good, proj, 32, 32, with_triangle_ids=True)
    mixed = rasterize(np.concatenate([bad[:3], good, bad[3:]]), proj, 32, 32,
                      with_triangle_ids=True)
    np.testing.assert_array_equal(mixed.depth, alone.depth)
    np.testing.assert_array_equal(mixed.triangle, np.where(alone.triangle >= 0, 3, -1))
    assert np.isfinite(alone.depth).sum() > 100


def test_nearest_triangle_wins_and_steps_accumulate():
    proj = _pixel_ortho(32, 32)
    near_tri = np.array([[[0, 0, -2], [32, 0, -2], [0, 32, -2]]], np.float32)
    far_tri = np.array([[[0, 0, -4], [32, 0, -4], [32, 32, -4]]], np.float32)
    res = rasterize(np.concatenate([far_tri, near_tri]), proj, 32, 32, with_triangle_ids=True)
    assert set(np.unique(res.depth)) == {2.0, 4.0, np.inf}
    np.testing.assert_array_equal(res.triangle == 1, res.depth == 2.0)
    np.testing.assert_array_equal(res.triangle == 0, res.depth == 4.0)
    # two draws into one caller-owned z-buffer give the same as one draw of both
    depth = np.empty((32, 32), np.float32)
    ids = np.empty((32, 32), np.int64)
    progress = list(rasterize_steps(far_tri, proj, depth, ids))
    progress += list(rasterize_steps(near_tri, proj, depth, ids, clear=False))
    np.testing.assert_array_equal(depth, res.depth)
    assert progress[-1] == 1.0 and all(0.0 <= p <= 1.0 for p in progress)


def test_chunking_does_not_change_the_result(monkeypatch):
    """Tiny triangle batches, span groups and fragment chunks give bit-identical buffers."""
    from classic_bake.kernels.geometry import raster

    rng = np.random.default_rng(RNG_SEED)
    centres = rng.uniform(-1.5, 1.5, (300, 1, 3)) + np.array([0.0, 0.0, -4.0])
    tris = (centres + rng.normal(scale=0.4, size=(300, 3, 3))).astype(np.float32)
    proj = Projection.perspective(np.eye(4), np.radians(60.0), 0.1, 10.0)
    whole = rasterize(tris, proj, 120, 100, with_triangle_ids=True)
    monkeypatch.setattr(raster, "TRIANGLE_CHUNK", 7)
    monkeypatch.setattr(raster, "CHUNK_FRAGMENTS", 100)
    monkeypatch.setattr(raster, "MAX_SPANS", 3)
    parts = rasterize(tris, proj, 120, 100, with_triangle_ids=True)
    np.testing.assert_array_equal(parts.depth, whole.depth)
    np.testing.assert_array_equal(parts.triangle, whole.triangle)
    assert np.isfinite(whole.depth).mean() > 0.5


def test_spans_are_the_centres_every_edge_function_admits():
    """The spans solved from the edge functions hold exactly the pixel centres where all three
    integer edge functions are >= 0 (tested one by one over each box), for triangles of 1 to 100
    pixels, edge-on ones and ones with horizontal or vertical edges."""
    from classic_bake.kernels.geometry import raster

    rng = np.random.default_rng(RNG_SEED)
    centres = rng.uniform(-1.5, 1.5, (400, 1, 3)) + np.array([0.0, 0.0, -4.0])
    scale = rng.choice([0.002, 0.01, 0.05, 0.3], size=(400, 1, 1))
    tris = centres + scale * rng.normal(size=(400, 3, 3))
    tris[:40, 1, 1] = tris[:40, 0, 1]  # a horizontal edge (same y, same depth: same row)
    tris[:40, 1, 2] = tris[:40, 0, 2]
    tris[40:80, 1, 0] = tris[40:80, 0, 0]  # a vertical edge
    tris[40:80, 1, 2] = tris[40:80, 0, 2]
    tris[80:100, 2] = tris[80:100, 0] + 0.5 * (tris[80:100, 1] - tris[80:100, 0])  # degenerate
    proj = Projection.perspective(np.eye(4), np.radians(60.0), 0.1, 10.0)
    s = raster._setup(tris, 0, proj, 300, 200, "NONE")
    sp = raster._spans(s, 0, len(s.tri))
    got = set(zip(sp.row.repeat(sp.count).tolist(),
                  (np.arange(sp.count.sum()) + np.repeat(sp.lo - (np.cumsum(sp.count) - sp.count),
                                                         sp.count)).tolist(),
                  sp.i.repeat(sp.count).tolist(), strict=True))
    want = set()
    for t in range(len(s.tri)):
        j0, j1, i0, i1 = s.box[t]
        jj, ii = np.meshgrid(np.arange(j0, j1 + 1), np.arange(i0, i1 + 1))
        px, py = jj * raster._ONE + raster._HALF, ii * raster._ONE + raster._HALF
        e = s.edge_a[t][:, None, None] * px + s.edge_b[t][:, None, None] * py + s.edge_c[t][:, None, None]
        inside = (e >= 0).all(axis=0)
        want |= {(t, j, i) for j, i in zip(jj[inside].tolist(), ii[inside].tolist(), strict=True)}
    assert got == want
    assert len(want) > 10_000 and (sp.count >= 1).all()


def test_slivers_stay_within_their_vertex_depths():
    """Nearly edge-on triangles (a shadow map's walls seen along the light) project to slivers; the
    depth they write must stay between their vertices' depths."""
    rng = np.random.default_rng(RNG_SEED)
    a = rng.uniform(-1.0, 1.0, (400, 3)) * [1, 1, 0.5] + [0, 0, -5]
    b = a + rng.normal(scale=0.6, size=(400, 3))
    t = rng.uniform(0, 1, (400, 1))
    width = 10.0 ** rng.uniform(-6, -2, (400, 1))  # m, 1e-4 to 1 pixel
    c = a + t * (b - a) + width * rng.normal(size=(400, 3)) * [1, 1, 0]  # almost on ab
    c[:, 2] += rng.normal(scale=0.5, size=400)  # ... but at another depth: steep slivers
    tris = np.stack([a, b, c], axis=1).astype(np.float32)
    for proj in (Projection.orthographic(np.eye(4), (-1.5, 1.5, -1.5, 1.5), 0.1, 20.0),
                 Projection.perspective(np.eye(4), np.radians(40.0), 0.1, 20.0)):
        res = rasterize(tris, proj, 256, 256, with_triangle_ids=True)
        hit = res.triangle >= 0
        assert hit.sum() > 50
        depth = -tris[res.triangle[hit], :, 2].astype(np.float64)  # view depth of the vertices
        assert np.all(res.depth[hit] >= depth.min(axis=1) * (1 - 1e-6))
        assert np.all(res.depth[hit] <= depth.max(axis=1) * (1 + 1e-6))
