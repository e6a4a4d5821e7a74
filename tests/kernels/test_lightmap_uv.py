"""Lightmap UVs (kernels/lightmap_uv.py): charts never share a texel and keep `padding` free texels
between them, at the requested resolution.

A chart's footprint is every texel whose square overlaps one of its triangles (an exact
triangle/box separating-axis test, so bilinear lookups of any point of a chart read only its texels).
"""

import numpy as np
import pytest

from classic_bake.kernels.lightmap_uv import LightmapUVSettings, unwrap


def uv_sphere(rings=12, segments=24):
    theta = np.linspace(0, np.pi, rings + 1)
    phi = np.linspace(0, 2 * np.pi, segments, endpoint=False)
    pos = np.array([[np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)]
                    for t in theta for p in phi])
    tris = []
    for r in range(rings):
        for s in range(segments):
            a, b = r * segments + s, r * segments + (s + 1) % segments
            c, d = a + segments, b + segments
            tris += [[a, c, b], [b, c, d]]
    return pos, np.array(tris)


def cube():
    pos = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    return pos, np.array([t for q in quads for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])])


def terrain(n=16, seed=3):
    rng = np.random.default_rng(seed)
    xs, ys = np.meshgrid(np.arange(n + 1), np.arange(n + 1))
    pos = np.stack([xs.ravel(), ys.ravel(), rng.random((n + 1) ** 2) * 2], 1).astype(float)
    tris = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            tris += [[a, a + 1, a + n + 2], [a, a + n + 2, a + n + 1]]
    return pos, np.array(tris)


def footprint(tri_uv: np.ndarray, res: int) -> np.ndarray:
    """(res, res) bool: texels whose square overlaps any of the (T, 3, 2) UV triangles (texel units)."""
    mask = np.zeros((res, res), bool)
    p = tri_uv * res
    for tri in p:
        lo = np.floor(tri.min(0)).astype(int).clip(0, res - 1)
        hi = np.floor(tri.max(0)).astype(int).clip(0, res - 1)
        ix, iy = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1))
        ix, iy = ix.ravel(), iy.ravel()
        corners = np.stack([np.stack([ix + dx, iy + dy], 1) for dx in (0, 1) for dy in (0, 1)], 1)
        hit = np.ones(ix.size, bool)
        for k in range(3):  # separating axes: the three edge normals (the box axes hold by bbox)
            e = tri[(k + 1) % 3] - tri[k]
            normal = np.array([-e[1], e[0]])
            side = (tri[(k + 2) % 3] - tri[k]) @ normal
            if side == 0:
                continue
            proj = (corners - tri[k]) @ normal
            # Separated if every box corner lies strictly on the far side of this edge.
            hit &= ~np.all(proj * np.sign(side) < 0, axis=1)
        mask[iy[hit], ix[hit]] = True
    return mask


def dilate(mask: np.ndarray, r: int) -> np.ndarray:
    out = mask.copy()
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            out |= np.roll(np.roll(mask, dy, 0), dx, 1) & _no_wrap(mask.shape, dy, dx)
    return out


def _no_wrap(shape, dy, dx):
    valid = np.ones(shape, bool)
    if dy > 0:
        valid[:dy] = False
    elif dy < 0:
        valid[dy:] = False
    if dx > 0:
        valid[:, :dx] = False
    elif dx < 0:
        valid[:, dx:] = False
    return valid


@pytest.mark.parametrize("mesh", [cube, uv_sphere, terrain], ids=["cube", "sphere", "terrain"])
@pytest.mark.parametrize("res, padding", [(64, 2), (256, 4)])
def test_charts_do_not_overlap_and_keep_their_padding(mesh, res, padding):
    pos, tris = mesh()
    result = unwrap(pos, tris, LightmapUVSettings(resolution=res, padding=padding))
    uv = result.corner_uv
    assert uv.shape == (len(tris), 3, 2)
    assert np.all((uv >= 0) & (uv <= 1))
    # Only zero-area triangles are left without a chart.
    e1, e2 = pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]]
    degenerate = np.linalg.norm(np.cross(e1, e2), axis=1) < 1e-12
    np.testing.assert_array_equal(result.chart_ids < 0, degenerate)
    ids = np.unique(result.chart_ids[~degenerate])
    charts = [footprint(uv[result.chart_ids == c], res) for c in ids]
    assert len(charts) == result.chart_count
    # `padding` free texels between charts: a chart grown by `padding` texels touches no other.
    for a in range(len(charts)):
        grown = dilate(charts[a], padding)
        for b in range(len(charts)):
            if a != b:
                assert not np.any(grown & charts[b]), f"charts {a} and {b} closer than {padding}"


def test_uv_area_keeps_relative_texel_density():
    # Two faces of a cube get the same UV area: density follows 3D area.
    pos, tris = cube()
    result = unwrap(pos, tris, LightmapUVSettings(resolution=128, padding=2))
    e1 = result.corner_uv[:, 1] - result.corner_uv[:, 0]
    e2 = result.corner_uv[:, 2] - result.corner_uv[:, 0]
    area = 0.5 * np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    faces = area.reshape(6, 2).sum(1)
    np.testing.assert_allclose(faces, faces.mean(), rtol=0.02)


def test_settings_are_validated():
    with pytest.raises(ValueError, match="resolution"):
        LightmapUVSettings(resolution=8)
    with pytest.raises(ValueError, match="padding"):
        LightmapUVSettings(padding=-1)


def test_empty_mesh():
    result = unwrap(np.zeros((0, 3)), np.zeros((0, 3), int))
    assert result.corner_uv.shape == (0, 3, 2) and result.chart_count == 0
