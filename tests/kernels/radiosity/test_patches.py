"""Corner values of a patch solution: nodal averaging against the fitted continuous
piecewise-linear function (`patches.fitted_corner_values`), on hand-built meshes with known
fields."""

from __future__ import annotations

import numpy as np
import pytest
from scene_builder import build, quad, uv_sphere

from classic_bake.kernels.geometry.scene import Material
from classic_bake.kernels.radiosity import patches as patching
from classic_bake.kernels.radiosity.form_factors.sampling import sample_patches

SMOOTH = np.radians(30.0)


def grey():
    return Material(name="grey", base_color=np.full(3, 0.5, np.float32), specular=0.0)


def square_patches(size=0.1):
    """A unit floor square cut into patches of about `size` m."""
    scene = build([(quad([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]), grey())])
    return patching.make_patches(scene, size)


def patch_means(patches, field, side=8):
    """(N, 1) the exact mean of `field` over each patch (dense midpoint quadrature)."""
    points, weights = sample_patches(patches.corners, side, "midpoint")
    return np.einsum("ns,ns->n", weights, field(points))[:, None]


def test_a_ramp_is_fitted_exactly_to_the_borders_where_averaging_flattens_it():
    patches = square_patches()
    ramp = lambda p: 1.0 + 2.0 * p[..., 0]  # noqa: E731  (range 2 over the square)
    means = patch_means(patches, ramp)
    truth = ramp(patches.corners)
    fitted = patching.fitted_corner_values(patches, means, SMOOTH)[..., 0]
    averaged = patching.corner_values(patches, means, SMOOTH)[..., 0]
    # The weak pull (FIT_PULL) costs ~0.1% of the range; averaging is half a patch off at the
    # borders (a 0.1 m patch: ~0.1 of the range of 2).
    assert np.abs(fitted - truth).max() < 2e-3 * 2.0
    assert np.abs(averaged - truth).max() > 0.05
    # Each patch keeps its mean: the mean of its corners is the mean of the field.
    np.testing.assert_allclose(fitted.mean(axis=1), means[:, 0], atol=2e-3 * 2.0)


def test_a_peak_keeps_its_height_and_the_interpolation_error_drops():
    patches = square_patches(0.125)
    bump = lambda p: np.exp(-((p[..., 0] - 0.5) ** 2 + (p[..., 1] - 0.5) ** 2) / 0.04)  # noqa: E731
    means = patch_means(patches, bump)
    points, _ = sample_patches(patches.corners, 6, "midpoint")
    truth = bump(points)

    def error(corner):  # RMS of the barycentric interpolation at points inside every patch
        tri = patches.corners
        # barycentrics of the midpoint samples, recovered from positions (planar, z = 0)
        a, b, c = tri[:, 0, :2], tri[:, 1, :2], tri[:, 2, :2]
        det = (b - a)[:, 0] * (c - a)[:, 1] - (b - a)[:, 1] * (c - a)[:, 0]
        d = points[..., :2] - a[:, None, :]
        l1 = (d[..., 0] * (c - a)[:, None, 1] - d[..., 1] * (c - a)[:, None, 0]) / det[:, None]
        l2 = ((b - a)[:, None, 0] * d[..., 1] - (b - a)[:, None, 1] * d[..., 0]) / det[:, None]
        value = ((1 - l1 - l2) * corner[:, None, 0, 0] + l1 * corner[:, None, 1, 0]
                 + l2 * corner[:, None, 2, 0])
        return float(np.sqrt(np.mean((value - truth) ** 2)))

    fitted = patching.fitted_corner_values(patches, means, SMOOTH)
    averaged = patching.corner_values(patches, means, SMOOTH)
    assert fitted.max() > averaged.max()  # averaging flattens the peak
    assert error(fitted) < 0.7 * error(averaged)


def test_constant_fields_stay_constant_and_folds_and_objects_keep_their_jumps():
    # Two objects: an inward box (folds at 90 degrees) and a floor sheet touching it.
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                  [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    faces = [[0, 1, 2, 3], [4, 7, 6, 5], [0, 4, 5, 1], [1, 5, 6, 2], [2, 6, 7, 3], [3, 7, 4, 0]]
    box = np.concatenate([quad(v[f]) for f in faces])
    sheet = quad([[0, 0, 0], [1, 0, 0], [1, -1, 0], [0, -1, 0]])[:, ::-1]
    scene = build([(box, grey()), (sheet, grey())])
    patches = patching.make_patches(scene, 0.25)
    normals = patches.normals
    # A value per face of the box (by normal) and another for the sheet object.
    face = np.argmax(np.abs(normals), axis=1) * 2 + (normals.max(axis=1) > 0.5)
    values = np.where(patches.object_ids == 1, 10.0, face.astype(float))[:, None]
    fitted = patching.fitted_corner_values(patches, values, SMOOTH)
    np.testing.assert_allclose(fitted[..., 0], np.repeat(values, 3, axis=1), rtol=1e-6)
    # The same with one constant: every corner takes it (the furnace's B = E / (1 - rho)).
    same = patching.fitted_corner_values(patches, np.full((len(patches), 3), 2.5), SMOOTH)
    np.testing.assert_allclose(same, 2.5, rtol=1e-6)


def test_a_lone_triangle_takes_its_value_and_steps_never_go_negative():
    scene = build([(np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], float), grey())])
    one = patching.make_patches(scene, 10.0)
    assert len(one) == 1
    np.testing.assert_allclose(patching.fitted_corner_values(one, np.array([[3.0]]), SMOOTH), 3.0)
    # A step 0 | 1 across the square: the least-squares fit over- and undershoots next to it;
    # the result is clamped at 0 (irradiance and radiosity are never negative).
    patches = square_patches(0.1)
    step = (patches.corners.mean(axis=1)[:, 0] > 0.5).astype(float)[:, None]
    fitted = patching.fitted_corner_values(patches, step, SMOOTH)
    assert fitted.min() >= 0.0
    assert fitted.max() < 1.5  # a bounded overshoot, not a blow-up


def test_smooth_surfaces_share_corners_across_their_facets():
    # A sphere's facets differ by a few degrees: one value per vertex, so a constant stays
    # constant and a height ramp stays continuous (corners at one position agree).
    scene = build([(uv_sphere([0, 0, 0], 1.0, rings=12, segments=24), grey())])
    patches = patching.make_patches(scene, 10.0)
    height = patches.corners.mean(axis=1)[:, 2:3] + 2.0
    fitted = patching.fitted_corner_values(patches, height, SMOOTH)
    flat = patches.corners.reshape(-1, 3)
    key = np.round(flat * 1e6).astype(np.int64)
    _, vertex = np.unique(key, axis=0, return_inverse=True)
    values = fitted.reshape(-1)
    spread = np.zeros(vertex.max() + 1)
    np.maximum.at(spread, vertex.ravel(), values)
    low = np.full(vertex.max() + 1, np.inf)
    np.minimum.at(low, vertex.ravel(), values)
    assert np.abs(spread - low).max() < 1e-9
    # ...and follows the height (to within the facets' sagitta at 12 rings).
    assert np.abs(fitted[..., 0] - (patches.corners[..., 2] + 2.0)).max() < 0.05


def test_a_slivers_free_corner_stays_near_the_values_around_it(monkeypatch):
    """A sliver (mean 10) on the long edge of a large triangle (mean 1): the means alone would
    put the sliver's free corner at 28, so that its corners average 10 with the two it shares
    with the large triangle held near 1 (27.7), and carry that into every patch at that
    corner. The fit keeps each corner within the values of the patches around it, widened by
    half their spread (FIT_OVERSHOOT): 14.5 here, the large triangle keeping its mean."""
    large = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    sliver = np.array([[[1.0, 0.0, 0.0], [0.505, 0.505, 0.0], [0.0, 1.0, 0.0]]])
    scene = build([(np.concatenate([large, sliver]), grey())])
    patches = patching.make_patches(scene, 10.0)
    assert len(patches) == 2
    values = np.array([[1.0], [10.0]])
    fitted = patching.fitted_corner_values(patches, values, SMOOTH)[..., 0]
    free = np.argmin(np.abs(patches.corners[1, :, 0] - 0.505))  # the sliver's own corner
    assert fitted[1, free] == pytest.approx(10.0 + patching.FIT_OVERSHOOT * 9.0)
    assert fitted[0].mean() == pytest.approx(1.0, abs=1e-3)  # the large triangle keeps its mean
    monkeypatch.setattr(patching, "FIT_OVERSHOOT", np.inf)
    unbounded = patching.fitted_corner_values(patches, values, SMOOTH)[..., 0]
    assert unbounded[1, free] > 27.0
