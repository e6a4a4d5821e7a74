"""Lightmap UVs (kernels/lightmap_uv.py): charts never share a texel and keep `padding` free texels
between them, at the requested resolution.

A chart's footprint is every texel whose square overlaps one of its triangles (an exact
triangle/box separating-axis test, so bilinear lookups of any point of a chart read only its texels).
"""

import os
import signal

import numpy as np
import pytest

from classic_bake.kernels.bake.lightmap_uv import (
    CHART_TRIANGLES,
    ISOLATE_TRIANGLES,
    LightmapUVSettings,
    UnwrapCrash,
    _in_child,
    _moved,
    _polygons_whole,
    unwrap,
)


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


def test_charts_too_many_for_the_resolution_grow_it_up_to_largest():
    """A sphere of 48 x 96 quads charted into pieces (max_chart_area) does not fit 16^2 with 4
    texels of padding: without `largest` the unwrap refuses; with it, the charts made once are
    packed again at 32^2, 64^2, ... until one atlas holds them, whose size the result names,
    padding kept there."""
    pos, tris = uv_sphere(48, 96)
    settings = LightmapUVSettings(resolution=16, padding=4, max_chart_area=0.2)
    with pytest.raises(ValueError, match="do not fit one 16"):
        unwrap(pos, tris, settings)
    result = unwrap(pos, tris, settings, largest=1024)
    assert 32 <= result.resolution <= 1024
    charts = [footprint(result.corner_uv[result.chart_ids == c], result.resolution)
              for c in range(result.chart_count)]
    for a in range(len(charts)):
        grown = dilate(charts[a], 4)
        assert not any(np.any(grown & charts[b]) for b in range(len(charts)) if b != a)
    assert unwrap(pos, tris, LightmapUVSettings(resolution=128)).resolution == 128


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


def corner_uv_by_polygon(polygons, tris, uv) -> dict:
    """{(polygon, vertex): set of the UVs its triangles give that corner}: a mesh stores one."""
    out: dict = {}
    for t, poly in enumerate(polygons):
        for c in range(3):
            out.setdefault((int(poly), int(tris[t, c])), set()).add(tuple(np.round(uv[t, c], 7)))
    return out


def test_a_polygon_stays_in_one_chart():
    # A bumpy grid of non-planar quads: xatlas charts triangles and cuts some quads along their
    # diagonal. A mesh keeps one UV per polygon corner, so the corner both halves share would
    # take one chart's UV while the other half's own corner kept the other chart's (a sliver
    # across the atlas in Blender).
    pos, tris = terrain(8, seed=3)
    polygons = np.arange(len(tris)) // 2
    res, padding = 64, 2
    loose = unwrap(pos, tris, LightmapUVSettings(resolution=res, padding=padding))
    split = [k for k, v in corner_uv_by_polygon(polygons, tris, loose.corner_uv).items() if len(v) > 1]
    assert len(split) >= 10  # the case is exercised: xatlas alone cuts quads apart
    result = unwrap(pos, tris, LightmapUVSettings(resolution=res, padding=padding), polygons)
    assert all(len(v) == 1 for v in corner_uv_by_polygon(polygons, tris, result.corner_uv).values())
    assert all(len(set(result.chart_ids[polygons == p])) == 1 for p in np.unique(polygons))
    # The halves moved to their polygon's chart are unfolded without distortion: their UV
    # triangle is similar to the 3D one (edge lengths in proportion). Checked before the charts
    # are packed again: xatlas' packing of UV islands bends them a little (2.5% median edge
    # ratio change over all triangles here), and bends these halves no more than the rest.
    moved, _ = _moved(pos, tris, polygons, loose.chart_ids)
    assert moved.sum() >= 10
    atlas_uv = loose.corner_uv.astype(np.float64)
    uv = _polygons_whole(pos, tris, polygons, loose.chart_ids, atlas_uv)[moved]
    edges3 = np.linalg.norm(pos[tris[moved]] - pos[tris[moved]][:, [1, 2, 0]], axis=2)
    edges2 = np.linalg.norm(uv - uv[:, [1, 2, 0]], axis=2)
    scale = edges2 / edges3
    np.testing.assert_allclose(scale, scale[:, :1].repeat(3, axis=1), rtol=1e-6)
    # Packed again: charts apart by `padding` texels, as every unwrap.
    charts = [footprint(result.corner_uv[result.chart_ids == c], res)
              for c in np.unique(result.chart_ids)]
    for a in range(len(charts)):
        grown = dilate(charts[a], padding)
        assert not any(np.any(grown & charts[b]) for b in range(len(charts)) if b != a)


def test_a_zero_area_triangle_does_not_pull_its_polygon_to_the_origin():
    # A quad whose first triangle has three collinear corners: xatlas charts it nowhere and puts
    # its corners at UV (0, 0), which its two shared corners would carry into the real triangle.
    pos, tris = cube()
    quad = np.array([[0, 0, 2], [1, 0, 2], [2, 0, 2], [1, 1, 2]], float)
    pos = np.concatenate([pos, quad])
    tris = np.concatenate([tris, [[8, 9, 10], [8, 10, 11]]])
    polygons = np.concatenate([np.arange(12) // 2, [6, 6]])
    result = unwrap(pos, tris, LightmapUVSettings(resolution=64, padding=2), polygons)
    assert all(len(v) == 1 for v in corner_uv_by_polygon(polygons, tris, result.corner_uv).values())

    def uv_area(t):
        c = result.corner_uv[t].astype(np.float64)
        u1, u2 = c[1] - c[0], c[2] - c[0]
        return abs(u1[0] * u2[1] - u1[1] * u2[0]) / 2.0

    assert uv_area(13) > 0.0  # the real half keeps its area in UV
    # The zero-area half stays chartless and lies on its edge in UV too: it covers no texel.
    assert result.chart_ids[12] == -1 and uv_area(12) < 1e-6 * uv_area(13)


# --- xatlas' crashes kept out of the process ---------------------------------------------------

def _crash():
    os.kill(os.getpid(), signal.SIGSEGV)


def _refuse():
    raise ValueError("refused in the child")


@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_crash_in_the_child_is_an_error_here_and_results_come_back():
    with pytest.raises(UnwrapCrash, match="SIGSEGV"):
        _in_child(_crash)
    with pytest.raises(ValueError, match="refused in the child"):
        _in_child(_refuse)
    arrays = (np.arange(6.0).reshape(2, 3), np.ones(4, np.uint32))
    back = _in_child(lambda a, b: (a * 2, b), *arrays)
    assert np.array_equal(back[0], arrays[0] * 2) and np.array_equal(back[1], arrays[1])


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(os, "fork"), reason="no fork on this platform")
def test_a_dense_sphere_is_charted_or_refused_never_the_end_of_the_process():
    # 250k triangles; xatlas 0.0.11 ends its process on this sphere in a fraction of a second
    positions, triangles = uv_sphere(rings=250, segments=500)
    assert len(triangles) >= ISOLATE_TRIANGLES
    try:
        result = unwrap(positions, triangles, LightmapUVSettings(resolution=256))
    except UnwrapCrash as exc:  # xatlas 0.0.11 on this machine
        assert "250,000 triangles" in str(exc) and "Lightmap Pack" in str(exc)
    else:  # a build of xatlas without the defect
        assert result.chart_count > 0 and np.isfinite(result.corner_uv).all()


def _terrain(side: int, amplitude: float):
    """A square grid of side x side quads (two triangles each) 12 m wide, rolling by
    `amplitude` m."""
    u, v = np.meshgrid(np.linspace(-6.0, 6.0, side + 1), np.linspace(-6.0, 6.0, side + 1))
    positions = np.stack([u, v, amplitude * np.sin(1.3 * u) * np.cos(0.9 * v)], -1).reshape(-1, 3)
    ids = np.arange((side + 1) ** 2).reshape(side + 1, side + 1)
    a, b, c, d = ids[:-1, :-1].ravel(), ids[:-1, 1:].ravel(), ids[1:, :-1].ravel(), ids[1:, 1:].ravel()
    return positions, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])


def test_large_curved_meshes_get_charts_of_bounded_size_and_flat_ones_stay_whole():
    # 20k triangles: xatlas alone grew the rolling one into one chart (42 s a pass).
    rolling = unwrap(*_terrain(100, 0.15), LightmapUVSettings(resolution=256))
    assert rolling.chart_count >= 20_000 // (2 * CHART_TRIANGLES)
    sizes = np.bincount(rolling.chart_ids[rolling.chart_ids >= 0])
    assert sizes.max() <= 3 * CHART_TRIANGLES
    flat = unwrap(*_terrain(100, 0.0), LightmapUVSettings(resolution=256))
    assert flat.chart_count == 1
    small = unwrap(*_terrain(30, 0.15), LightmapUVSettings(resolution=256))  # under the bound
    assert small.chart_count <= 2


def test_a_mesh_is_charted_once_and_packed_as_charts_after(monkeypatch):
    """The density fit packs again and again: xatlas charts and flattens the mesh in the first
    pass only (add_mesh once); every later pass packs those charts as a UV mesh (add_uv_mesh),
    and what comes out is a valid atlas of the same charts."""
    import xatlas

    calls = {"mesh": 0, "uv": 0}

    class Counted(xatlas.Atlas):
        def add_mesh(self, *args, **kwargs):
            calls["mesh"] += 1
            return super().add_mesh(*args, **kwargs)

        def add_uv_mesh(self, *args, **kwargs):
            calls["uv"] += 1
            return super().add_uv_mesh(*args, **kwargs)

    monkeypatch.setattr(xatlas, "Atlas", Counted)
    pos, tris = terrain(40)
    result = unwrap(pos, tris, LightmapUVSettings(resolution=128, padding=2))
    assert calls["mesh"] == 1 and calls["uv"] >= 2  # the estimate, then at least one fit
    assert result.chart_count > 0 and (result.chart_ids >= 0).all()
    assert 0.0 <= result.corner_uv.min() and result.corner_uv.max() <= 1.0
    # No two charts share a texel (at the packing's padding).
    owner = np.full((128, 128), -1)
    for chart in range(result.chart_count):
        mask = footprint(result.corner_uv[result.chart_ids == chart], 128)
        assert not (mask & (owner >= 0)).any()
        owner[mask] = chart


def test_atlases_outlive_the_unwrap_until_later_ones_are_made(monkeypatch):
    """xatlas' destructor can miss its worker thread's going to sleep and wait for it for ever
    (`RETIRED_ATLASES`): an unwrap's atlases are not destroyed when it drops them but only after
    that many later ones were made; the oldest go first."""
    import gc
    import weakref

    import xatlas

    from classic_bake.kernels.bake import lightmap_uv

    made = []

    class Tracked(xatlas.Atlas):
        def __init__(self):
            super().__init__()
            made.append(weakref.ref(self))

    monkeypatch.setattr(xatlas, "Atlas", Tracked)
    pos, tris = terrain(6)
    for _ in range(3):
        unwrap(pos, tris, LightmapUVSettings(resolution=64))
    gc.collect()
    alive = [ref() is not None for ref in made]
    assert len(made) > lightmap_uv.RETIRED_ATLASES
    assert alive == [False] * (len(made) - lightmap_uv.RETIRED_ATLASES) + \
        [True] * lightmap_uv.RETIRED_ATLASES
