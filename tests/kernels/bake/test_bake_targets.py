"""The texel filter of lightmap bakes (kernels/bake_targets.py: `box_filter`), checked against the
exact box-filtered mean of functions with a known integral over each texel."""

from dataclasses import replace

import numpy as np
import pytest
from scene_builder import build, quad

from classic_bake.kernels.bake.bake_targets import (
    TexelFilterSettings,
    box_filter,
    edge_texels,
    lattice_fill,
    lattice_plan,
    lightmap_targets,
    rook_offsets,
    subtexel_points,
)
from classic_bake.kernels.geometry.scene import Material

WHITE = Material(name="white", base_color=np.full(3, 0.8, np.float32), specular=0.0)
SIZE = 32


def ground(size=4.0):
    """A ground quad whose lightmap UVs map [-size/2, size/2]^2 onto [0.1, 0.9]^2."""
    h = size / 2
    scene = build([(quad([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)]), WHITE)])
    lm = 0.1 + 0.8 * (scene.triangles[:, :, :2].astype(np.float64) + h) / size
    return replace(scene, lightmap_uv=lm.astype(np.float32))


def points_of(scene, tri, bary):
    return np.einsum("nk,nkc->nc", bary, scene.triangles[tri].astype(np.float64))


def texel_x_range(targets, size=4.0):
    """World x of each texel's left and right edges (the UV map is x -> 0.1 + 0.8 (x + 2) / 4)."""
    u0 = targets.cols / SIZE
    to_x = lambda u: (u - 0.1) / 0.8 * size - size / 2  # noqa: E731
    return to_x(u0), to_x(u0 + 1.0 / SIZE)


def test_subtexel_points_lie_in_their_texel_and_triangle():
    scene = ground()
    t = lightmap_targets(scene, 0, SIZE)
    which = np.arange(len(t))
    owner, tri, bary = subtexel_points(scene, t, which, 3)
    assert (bary >= 0).all() and np.allclose(bary.sum(1), 1)
    np.testing.assert_array_equal(tri, t.triangles[which][owner])
    uv = np.einsum("nk,nkc->nc", bary, scene.lightmap_uv[tri].astype(np.float64))
    col, row = uv[:, 0] * SIZE, (1 - uv[:, 1]) * SIZE
    assert np.all(np.floor(col + 1e-9) == t.cols[owner]) and np.all(np.floor(row + 1e-9) == t.rows[owner])
    # Inner texels keep all 9 points; texels on the quad's diagonal split theirs between the two
    # triangles, each keeping only the points on its own side.
    counts = np.bincount(owner, minlength=len(which))
    assert counts.max() == 9 and 0 < counts.min()


@pytest.mark.parametrize("k", [1, 2, 3, 4, 6, 8])
def test_rook_points_share_no_row_or_column_and_fill_every_cell(k):
    """k^2 points, each alone in its column and its row of k^2, so a step along either axis of
    the texel is placed to 1 / (2 k^2); with k^2 a power of two each k x k cell holds one."""
    du, dv = rook_offsets(k)
    n = k * k
    for offsets in (du, dv):
        np.testing.assert_allclose(np.sort(offsets), (np.arange(n) + 0.5) / n)
    if n & (n - 1) == 0:
        cells = np.floor(du * k).astype(int) * k + np.floor(dv * k).astype(int)
        np.testing.assert_array_equal(np.sort(cells), np.arange(n))


@pytest.mark.parametrize("k", [2, 4])
def test_a_step_is_box_filtered_to_the_covered_fraction(k):
    scene = ground()
    t = lightmap_targets(scene, 0, SIZE)
    edge_x = 0.375  # 40% into a texel 0.15625 m wide: on no texel or sub-texel boundary

    def lit(tri, bary):  # 1 left of the edge, 0 right of it
        return (points_of(scene, tri, bary)[:, 0] < edge_x).astype(np.float64)[:, None]

    centre = lit(t.triangles, t.bary)
    values, filtered = box_filter(scene, t, centre, lit, TexelFilterSettings(k, 0.5))
    left, right = texel_x_range(t)
    exact = np.clip((edge_x - left) / (right - left), 0.0, 1.0)  # the texel's lit fraction
    crossed = (left < edge_x) & (edge_x < right)
    assert filtered >= crossed.sum()
    # The quad's diagonal cuts some texels in two; each half's mean is its own triangle's lit
    # fraction, not the texel's. The others keep all their points.
    owner, _, _ = subtexel_points(scene, t, np.arange(len(t)), 3)
    whole = crossed & (np.bincount(owner, minlength=len(t)) == 9)
    assert whole.sum() >= crossed.sum() - 3  # the diagonal meets the column in a few texels
    # k^2 rook points in k^2 columns: the covered fraction to within half a column.
    np.testing.assert_allclose(values[whole, 0], exact[whole], atol=0.5 / k**2 + 1e-9)
    assert np.abs(centre[crossed, 0] - exact[crossed]).max() > 0.5 / k  # the centre alone is off
    np.testing.assert_array_equal(values[~crossed], centre[~crossed])  # far from it: untouched


def test_a_linear_ramp_has_no_edge_texels():
    scene = ground()
    t = lightmap_targets(scene, 0, SIZE)
    ramp = 1.0 + 0.2 * t.points[:, :1] + 0.1 * t.points[:, 1:2]  # box filter = centre value
    assert not edge_texels(t, ramp, 0.5).any()
    values, filtered = box_filter(scene, t, ramp, lambda tri, bary: 1 / 0, TexelFilterSettings())
    assert filtered == 0
    np.testing.assert_array_equal(values, ramp)


def test_texel_filter_settings_refuse_nonsense():
    with pytest.raises(ValueError):
        TexelFilterSettings(samples_per_side=-1)
    with pytest.raises(ValueError):
        TexelFilterSettings(edge_threshold=0.0)


def test_texels_on_a_grid_edge_go_where_blender_samples_them():
    """Four quads meeting in lines through texel centres (column 8, row 8 of 16), as a grid
    mesh's edges do when its cells span whole texels. Blender's bake samples a texel a thousandth
    of a texel along +u and twice that along +v from its centre (`BAKE_SAMPLE_SHIFT`; ours,
    snapped, `SAMPLE_SHIFT`), so those texels belong to the quads on the +u and +v side, and
    their barycentrics are taken at that point. A square's diagonal runs through texel centres
    too: those go to the triangle on the side the shift points to."""
    from classic_bake.kernels.bake.bake_targets import SAMPLE_SHIFT

    size = 16
    cu, cv = 8.5 / size, 1.0 - 8.5 / size  # the centres of column 8 and of row 8
    parts = [quad([(u0, v0, 0), (u1, v0, 0), (u1, v1, 0), (u0, v1, 0)])
             for u0, u1 in ((0.0, cu), (cu, 1.0)) for v0, v1 in ((0.0, cv), (cv, 1.0))]
    scene = build([(np.concatenate(parts), WHITE)])
    scene = replace(scene, lightmap_uv=scene.triangles[:, :, :2].copy())
    t = lightmap_targets(scene, 0, size)
    assert t.mask.all()
    centre = scene.triangles[t.triangles].mean(axis=1)[:, :2]  # which quad each texel went to
    on_column, on_row = t.cols == 8, t.rows == 8
    assert (centre[on_column, 0] > cu).all() and (centre[on_row, 1] > cv).all()
    expected = np.stack([(t.cols + 0.5 + SAMPLE_SHIFT[0]) / size,
                         1.0 - (t.rows + 0.5 - SAMPLE_SHIFT[1]) / size], axis=1)
    np.testing.assert_allclose(t.points[:, :2], expected, atol=1e-6)
    # A unit square's diagonal u = v runs through the centres of texels (i, 15 - i).
    square = build([(quad([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), WHITE)])
    square = replace(square, lightmap_uv=square.triangles[:, :, :2].copy())
    t = lightmap_targets(square, 0, size)
    on_diagonal = t.cols == size - 1 - t.rows
    assert on_diagonal.sum() == size
    assert (t.triangles[on_diagonal] == 1).all()  # (c0, c2, c3): the side where v > u


def test_a_texel_two_uv_triangles_cover_goes_to_the_later_one():
    """Blender's bake draws an object's UV triangles in order and each overwrites the texels it
    covers, with no depth test: where lightmap UVs overlap (a packer's sliver across another
    chart) the last triangle's point is baked. Two squares at one place in UV, far apart in the
    world: every texel belongs to the second square's triangles."""
    size = 16
    first = quad([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    second = quad([(0, 0, 5), (1, 0, 5), (1, 1, 5), (0, 1, 5)])
    scene = build([(np.concatenate([first, second]), WHITE)])
    scene = replace(scene, lightmap_uv=scene.triangles[:, :, :2].copy())
    t = lightmap_targets(scene, 0, size)
    assert t.mask.all()
    assert (t.triangles >= 2).all() and np.allclose(t.points[:, 2], 5.0)


# --- lattice interpolation ------------------------------------------------------------------------


def lattice_bake(scene, targets, f, threshold):
    """`lattice_fill` the way `radiosity.bake_steps` runs it: f at the lattice, then at the rest
    it names. Returns the values and how many texels f was evaluated at."""
    plan = lattice_plan(targets)
    first = f(targets.triangles[plan.first], targets.bary[plan.first])
    values, todo = lattice_fill(plan, first, threshold)
    values[todo] = f(targets.triangles[todo], targets.bary[todo])
    return values, len(plan.first) + len(todo)


def test_lattice_interpolates_a_smooth_field_and_evaluates_a_step():
    """A linear ramp is interpolated exactly (to rounding) away from the quad's diagonal, whose
    texel centres are clamped into their triangles, and the chart's border; f runs at well under
    half the texels. A step: every texel whose lattice neighbours straddle it is evaluated, so the
    result equals the full evaluation exactly."""
    scene = ground()
    t = lightmap_targets(scene, 0, SIZE)

    def ramp(tri, bary):
        p = points_of(scene, tri, bary)
        return np.stack([1.0 + 0.2 * p[:, 0], 2.0 - 0.1 * p[:, 1], np.ones(len(p))], axis=1)

    full = ramp(t.triangles, t.bary)
    values, evaluated = lattice_bake(scene, t, ramp, 0.1)
    np.testing.assert_allclose(values, full, rtol=1e-9)
    assert evaluated < 0.45 * len(t)

    def step(tri, bary):
        return np.where(points_of(scene, tri, bary)[:, :1] < 0.375, 1.0, 0.05) * np.ones((1, 3))

    values, evaluated = lattice_bake(scene, t, step, 0.1)
    np.testing.assert_array_equal(values, step(t.triangles, t.bary))
    assert evaluated < 0.5 * len(t)


def test_lattice_does_not_interpolate_across_a_seam_or_a_fold():
    """Two quads whose lightmap charts touch in UV: side by side in the world with a 90-degree
    fold between them, then far apart. A texel whose lattice neighbours lie on both charts is
    evaluated, never averaged, however equal their values."""
    left = quad([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)])
    folded = quad([(1, 0, 0), (1, 0, 1), (1, 1, 1), (1, 1, 0)])  # standing on the first's edge
    far = quad([(5, 0, 3), (6, 0, 3), (6, 1, 3), (5, 1, 3)])
    for second in (folded, far):
        scene = build([(np.concatenate([left, second]), WHITE)])
        uv = np.concatenate([np.full((2, 3, 2), 0.0), np.full((2, 3, 2), 0.0)])
        uv[:2] = 0.1 + 0.4 * scene.triangles[:2, :, :2].astype(np.float64)  # u, v in [0.1, 0.5]
        local = np.stack([scene.triangles[2:, :, 2], scene.triangles[2:, :, 1]], axis=-1)
        if second is far:
            local = np.stack([scene.triangles[2:, :, 0] - 5.0, scene.triangles[2:, :, 1]], -1)
        uv[2:] = [0.5, 0.1] + 0.4 * local.astype(np.float64)  # u in [0.5, 0.9]: touching at 0.5
        scene = replace(scene, lightmap_uv=uv.astype(np.float32))
        t = lightmap_targets(scene, 0, SIZE)
        plan = lattice_plan(t)
        on_left = t.points[:, 0] < 1.0 - 1e-9
        src_sides = on_left[np.where(plan.sources >= 0, plan.sources, 0)]
        mixed = (plan.sources >= 0).all(axis=1) & src_sides.any(axis=1) & ~src_sides.all(axis=1)
        assert mixed.any()
        assert not plan.affine[mixed].any()
        _, todo = lattice_fill(plan, np.ones((len(plan.first), 3)), 0.1)
        assert set(plan.rest[mixed]) <= set(todo)
