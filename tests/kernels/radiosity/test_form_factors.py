"""Form factors against analytic ground truth (tests/data/form_factors.json).

Ground truth: Howell's closed forms C-11, C-14, element-to-disk and disk-to-disk (checked against
the reference file's numbers), numerical quadrature of the form factor kernel, and identities
(reciprocity, summation to 1 in a closed box). Ray visibility comes from the brute-force tracer of
`tests/support/radiosity_scenes.py`. Each tolerance is stated next to the error measured when it was written.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import radiosity_scenes as T
from reference_data import reference_path

from classic_bake.kernels.radiosity.form_factors.closed_forms import (
    disk_to_disk,
    element_to_disk,
    parallel_rectangles,
    perpendicular_rectangles,
)
from classic_bake.kernels.radiosity.form_factors.hemicube import (
    HemicubeFormFactors,
    HemicubeSettings,
    hemicube_gather,
    hemicube_pixels,
)
from classic_bake.kernels.radiosity.form_factors.point_polygon import point_to_polygon
from classic_bake.kernels.radiosity.form_factors.raycast import (
    RayCastFormFactors,
    RayCastSettings,
    raycast_gather,
)
from classic_bake.kernels.radiosity.form_factors.rows import enforce_reciprocity, form_factor_matrix
from classic_bake.kernels.radiosity.form_factors.sampling import patch_geometry, sample_patches

REFERENCE = reference_path("form_factors.json")

# Analytic value of the hemicube's top face: 4 x Howell B-3 (element to a 1 x 1 rectangle at
# height 1 with a corner above the element) = 4 / (pi sqrt 2) atan(1 / sqrt 2).
HEMICUBE_TOP = 4.0 / (math.pi * math.sqrt(2.0)) * math.atan(1.0 / math.sqrt(2.0))
UP = np.array([0.0, 0.0, 1.0])


@pytest.fixture(scope="module")
def reference() -> dict:
    return json.loads(REFERENCE.read_text())


def _params(key: str) -> dict[str, float]:
    return {k: float(v) for k, v in (item.split("=") for item in key.split(","))}


def unit_floor() -> np.ndarray:
    """[0,1]^2 at z = 0, facing +z."""
    return np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float64)


def perpendicular_pair(w: float, h: float, l: float) -> np.ndarray:  # noqa: E741
    """Howell C-14: floor [0,l]x[0,w] (+z) and wall y = 0, [0,l]x[0,h] in z (+y), common edge l."""
    floor = np.array([[0, 0, 0], [l, 0, 0], [l, w, 0], [0, w, 0]], np.float64)
    wall = np.array([[0, 0, 0], [0, 0, h], [l, 0, h], [l, 0, 0]], np.float64)
    return np.array([floor, wall])


def parallel_pair(a: float, b: float, c: float) -> np.ndarray:
    """Howell C-11: floor [0,a]x[0,b] (+z) and the same rectangle at z = c facing -z."""
    floor = np.array([[0, 0, 0], [a, 0, 0], [a, b, 0], [0, b, 0]], np.float64)
    ceiling = np.array([[0, 0, c], [0, b, c], [a, b, c], [a, 0, c]], np.float64)
    return np.array([floor, ceiling])


def quadrature(x, n, polygon, m):
    """Reference F from point x (normal n) to a planar quad: m x m midpoint rule of
    max(cos_i, 0) max(cos_j, 0) / (pi s^2) over the polygon (no clipping logic involved)."""
    points, weights = sample_patches(polygon[None], m, "midpoint")
    g = patch_geometry(polygon[None])
    d = points[0] - x
    s2 = np.einsum("ij,ij->i", d, d)
    s = np.sqrt(s2)
    cos_i = np.maximum(d @ n / s, 0.0)
    cos_j = np.maximum(-(d @ g.normals[0]) / s, 0.0)
    return float(weights[0] @ (cos_i * cos_j / (math.pi * s2)) * g.areas[0])


# --- closed forms ---------------------------------------------------------------------------------


def test_closed_forms_reproduce_reference_values(reference):
    """Every tabulated value of form_factors.json to 1e-9 (measured: <= 1.2e-13)."""
    values = reference["values"]
    for key, expected in values["parallel_C11"].items():
        p = _params(key)
        assert parallel_rectangles(p["a"], p["b"], p["c"]) == pytest.approx(expected, abs=1e-9)
    for key, expected in values["perpendicular_C14"].items():
        p = _params(key)
        got = perpendicular_rectangles(p["w"], p["h"], p["l"])
        assert got == pytest.approx(expected, abs=1e-9), key
    for key, expected in values["element_to_disk"].items():
        p = _params(key)
        assert element_to_disk(p["h"], p["r"]) == pytest.approx(expected, abs=1e-9)
    for key, expected in values["disk_to_disk"].items():
        p = _params(key)
        assert disk_to_disk(p["r1"], p["r2"], p["h"]) == pytest.approx(expected, abs=1e-9)


def test_closed_forms_identities(reference):
    """The reference file's checks: a cube face sees the other five with total 1; C-14
    reciprocity A1 F12 = A2 F21; the closed forms broadcast over arrays."""
    total = parallel_rectangles(1, 1, 1) + 4 * perpendicular_rectangles(1, 1, 1)
    assert total == pytest.approx(1.0, abs=1e-12)
    f12 = perpendicular_rectangles(1.0, 2.0, 1.0)  # A1 = 1 x 1
    f21 = perpendicular_rectangles(2.0, 1.0, 1.0)  # A2 = 2 x 1
    assert 1.0 * f12 == pytest.approx(2.0 * f21, rel=1e-12)
    c = np.array([0.5, 1.0, 2.0])
    np.testing.assert_allclose(
        parallel_rectangles(1.0, 1.0, c), [parallel_rectangles(1.0, 1.0, v) for v in c]
    )
    # Tilted element: cos(w) r^2 / (r^2 + h^2), the disk fully above the horizon.
    assert element_to_disk(1.0, 1.0, tilt=0.3) == pytest.approx(0.5 * math.cos(0.3))


# --- the point-to-polygon contour formula -------------------------------------------------------


def test_point_to_polygon_approaches_element_to_disk(reference):
    """A regular K-gon inscribed in the disk. Measured F(disk) - F(K-gon): K = 256: 1.3e-5 to
    2.5e-5; K = 1024: 1.0e-6 to 1.6e-6 (shrinks as K^-2, the area deficit); also tilted."""
    for key, expected in reference["values"]["element_to_disk"].items():
        p = _params(key)
        for sides, tolerance in ((256, 3e-5), (1024, 2e-6)):
            disk = T.regular_polygon([0, 0, p["h"]], [0, 0, -1], p["r"], sides)
            got = point_to_polygon(np.zeros(3), UP, disk)
            assert 0.0 < expected - got < tolerance, (key, sides)
    # Tilted receiver (h = 3, r = 1: tan(0.3) < h / r keeps the disk above the horizon).
    tilt = 0.3
    normal = np.array([math.sin(tilt), 0.0, math.cos(tilt)])
    disk = T.regular_polygon([0, 0, 3.0], [0, 0, -1], 1.0, 1024)
    got = point_to_polygon(np.zeros(3), normal, disk)
    assert got == pytest.approx(element_to_disk(3.0, 1.0, tilt), abs=2e-6)


def test_point_to_polygon_matches_numerical_integration():
    """A general planar quad, above the horizon and straddling it (the clipped case), against a
    900 x 900 midpoint quadrature of the kernel. Measured agreement: <= 3e-7 relative, and 7e-9
    absolute for a quad barely above a tilted horizon (F = 1.8e-5, where the quadrature's kink
    error dominates)."""
    rng = np.random.default_rng(7)
    quad = np.array([[-0.3, -0.2, 0.7], [0.8, -0.4, 0.9], [0.9, 0.7, 0.5], [-0.2, 0.6, 0.6]])
    normal = np.cross(quad[1] - quad[0], quad[2] - quad[0])
    normal /= np.linalg.norm(normal)
    quad[3] -= ((quad[3] - quad[0]) @ normal) * normal  # planar
    quad = quad[::-1].copy()  # wound to face the receivers below it
    x = np.array([0.1, 0.2, 0.0])
    receivers = [UP, np.array([0.6, 0.0, 0.8]), np.array([1.0, 0.0, 0.0]), np.array([0.8, 0, -0.6])]
    receivers.append(rng.normal(size=3))
    for n in receivers:
        n = n / np.linalg.norm(n)
        expected = quadrature(x, n, quad, 900)
        got = point_to_polygon(x, n, quad)
        assert got == pytest.approx(expected, rel=2e-6, abs=1e-8), n


def test_point_to_polygon_on_and_near_planes_and_edges():
    """Points on or near the polygon's plane and on a shared edge: finite, never NaN.

    Floor point x = (0.5, d, 0) in front of the wall y = 0 (their common edge is the x axis):
    F(d) rises to 0.5 as d -> 0 (in the limit only the common edge contributes: gamma = pi, its
    plane is the floor's, so F = pi / (2 pi)), with slope below 1 (measured 0.78); at d = 0 the
    wall is seen edge-on: F = 0 exactly (the PLANE_EPS band, |d| < 1e-10 x reach)."""
    wall = perpendicular_pair(1.0, 1.0, 1.0)[1]
    wall_normal = patch_geometry(wall[None]).normals[0]
    np.testing.assert_allclose(wall_normal, [0, 1, 0])
    d = np.array([1e-2, 1e-4, 1e-6, 1e-8, 1e-9])
    points = np.stack([np.full_like(d, 0.5), d, np.zeros_like(d)], axis=1)
    f = point_to_polygon(points, UP, wall)
    assert np.all(np.isfinite(f))
    assert np.all(np.diff(f) > 0.0)
    assert np.all((0.5 - f > 0.0) & (0.5 - f <= d))
    # On the plane, on the common edge, on a corner, behind: exactly 0.
    on = np.array([[0.5, 0.0, 0.0], [0.0, 0.0, 0.0], [0.5, 0.0, 0.3], [0.5, -0.2, 0.1]])
    assert np.all(point_to_polygon(on, UP, wall) == 0.0)
    # Polygon below the horizon: 0; wound the other way (seen from behind): 0.
    assert point_to_polygon(np.array([0.5, 0.5, 2.0]), UP, wall) == 0.0
    assert point_to_polygon(np.array([0.5, 0.3, 0.0]), UP, wall[::-1]) == 0.0
    # A triangle given as a quad with a repeated corner equals the triangle itself.
    tri = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 1.0], [1.0, 0.0, 1.0]])
    padded = np.concatenate([tri, tri[2:]])
    x = np.array([0.2, 0.3, 0.0])
    assert point_to_polygon(x, UP, padded) == pytest.approx(
        point_to_polygon(x, UP, tri), rel=1e-14
    )
    # Coplanar neighbour: a floor point never sees the floor beside it.
    assert point_to_polygon(np.array([1.5, 0.5, 0.0]), UP, unit_floor()) == 0.0


def test_point_to_polygon_broadcasts_and_fills_out():
    polygons = np.stack([parallel_pair(1, 1, c)[1] for c in (0.5, 1.0, 2.0)])  # (3, 4, 3)
    points = np.random.default_rng(1).uniform(0.1, 0.9, size=(5, 1, 3)) * [1, 1, 0]
    out = np.empty((5, 3))
    result = point_to_polygon(points, UP, polygons, out=out)
    assert result is out
    for i in range(5):
        for j in range(3):
            assert out[i, j] == pytest.approx(point_to_polygon(points[i, 0], UP, polygons[j]))


# --- the hemicube ---------------------------------------------------------------------------------


def test_hemicube_delta_form_factor_sums():
    """Midpoint deltas (1/(pi(x^2+y^2+1)^2) dA, z/(pi(y^2+z^2+1)^2) dA): the top face sums to
    the analytic 0.5541264 and each side to (1 - top)/4 up to the midpoint error O(R^-2)
    (measured total - 1: 8.6e-3 at R = 8, 5.3e-4 at R = 32, 1.3e-4 at R = 64, about 0.53 / R^2);
    exact deltas (contour formula per pixel) sum to 1 and 0.5541264 to rounding."""
    assert point_to_polygon(
        np.zeros(3), UP, np.array([[-1, -1, 1], [-1, 1, 1], [1, 1, 1], [1, -1, 1]], float)
    ) == pytest.approx(HEMICUBE_TOP, rel=1e-14)
    for r in (8, 32, 64):
        directions, delta = hemicube_pixels(r, "midpoint")
        assert directions.shape == (3 * r * r, 3) and delta.shape == (3 * r * r,)
        np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0)
        assert np.all(directions[:, 2] > 0.0)
        assert 0.0 < delta.sum() - 1.0 < 0.6 / r**2
        assert delta[: r * r].sum() == pytest.approx(HEMICUBE_TOP, abs=0.6 / r**2)
        sides = delta[r * r :].reshape(4, -1).sum(axis=1)
        np.testing.assert_allclose(sides, (1.0 - HEMICUBE_TOP) / 4.0, atol=0.6 / r**2)
        _, exact = hemicube_pixels(r, "exact")
        assert exact.sum() == pytest.approx(1.0, abs=1e-12)
        assert exact[: r * r].sum() == pytest.approx(HEMICUBE_TOP, abs=1e-12)
        assert np.abs(exact - delta).max() < 0.05 * delta.max()


def _pair_rows(corners, method):
    tris, tri_patch = T.quad_triangles(corners)
    tracer = T.BruteForceTracer(tris)
    if method == "hemicube":
        settings = HemicubeSettings(resolution=32, points_per_side=4)
        rows = HemicubeFormFactors(corners, tracer.closest_hit, tri_patch, settings)
    else:  # rays always cast (no quick test) so that visibility is exercised
        rows = RayCastFormFactors(corners, tracer.occluded)
    return rows.row(0)[1], rows.row(1)[0]


@pytest.mark.parametrize("method", ["hemicube", "raycast"])
def test_methods_on_unit_squares(method):
    """Parallel (C-11, c = 1) and perpendicular (C-14) unit squares, both directions, within 1%.

    Measured relative errors: hemicube (R = 32, 4 x 4 Gauss points): parallel -0.23%, -0.25%;
    perpendicular +0.26%, -0.56%. Ray-cast (4 x 4 Gauss points, near pairs 4 x 4 cells of them,
    3 x 3 visibility points): parallel -1.1e-10, perpendicular 2.7e-11."""
    tolerance = 1e-2 if method == "hemicube" else 1e-8
    par = parallel_rectangles(1, 1, 1)
    perp = perpendicular_rectangles(1, 1, 1)
    for corners, expected in ((parallel_pair(1, 1, 1), par), (perpendicular_pair(1, 1, 1), perp)):
        forward, backward = _pair_rows(corners, method)
        assert forward == pytest.approx(expected, rel=tolerance)
        assert backward == pytest.approx(expected, rel=tolerance)


def test_raycast_stratified_rule_on_unit_squares():
    """The jittered-stratified source rule (seeded), 4 x 4 strata (near pairs: 16 x 16).
    Measured: parallel -0.08%, perpendicular +0.15% (without the near-field rule: +1.1% and
    +2.4%); reproducible for a given seed."""
    settings = RayCastSettings(source_rule="stratified", seed=3)
    for corners, expected in (
        (parallel_pair(1, 1, 1), parallel_rectangles(1, 1, 1)),
        (perpendicular_pair(1, 1, 1), perpendicular_rectangles(1, 1, 1)),
    ):
        rows = RayCastFormFactors(corners, settings=settings)
        assert rows.row(0)[1] == pytest.approx(expected, rel=1e-2)
        again = RayCastFormFactors(corners, settings=settings)
        assert again.row(0)[1] == rows.row(0)[1]


def _disk_scene(h, r, sides, blocker=None):
    disk = T.regular_polygon([0, 0, h], [0, 0, -1], r, sides)
    tris = T.fan_triangles(disk)
    tri_patch = np.zeros(len(tris), np.int64)
    if blocker is not None:
        extra = T.fan_triangles(T.regular_polygon([0, 0, blocker[0]], [0, 0, -1], blocker[1], 128))
        tris = np.concatenate([tris, extra])
        tri_patch = np.concatenate([tri_patch, np.full(len(extra), -1)])
    return disk, tris, tri_patch


def test_methods_point_to_disk_and_occluded_annulus():
    """Element to a coaxial disk (h = r = 1, exact 0.5; a 128-gon, 1e-4 below the disk), and the
    same with an opaque coaxial disk of radius 0.25 at height 0.5 between them: the visible part
    is the annulus r' = 0.5 .. 1, exact 0.5 - 0.2 = 0.3.

    Measured relative errors: hemicube R = 64: disk +0.16%, annulus -0.23%; ray-cast: disk
    -2e-4 (the polygon), annulus (8 x 8 stratified points per fan triangle) -0.22% (seed 0;
    within 0.31% over seeds 0-5)."""
    x, n, w = np.zeros((1, 3)), UP[None], np.ones(1)
    disk_exact = element_to_disk(1.0, 1.0)
    annulus_exact = disk_exact - element_to_disk(1.0, 0.5)
    for blocker, expected in ((None, disk_exact), ((0.5, 0.25), annulus_exact)):
        disk, tris, tri_patch = _disk_scene(1.0, 1.0, 128, blocker)
        tracer = T.BruteForceTracer(tris)
        normals = patch_geometry(disk[None]).normals
        hemi = hemicube_gather(
            x, n, w, tracer.closest_hit, tri_patch, normals, HemicubeSettings(resolution=64),
            np.random.default_rng(0), ray_offset=0.0,
        )
        assert hemi[0] == pytest.approx(expected, rel=1e-2)
        settings = RayCastSettings(visibility_samples_per_side=8)
        unoccluded, visible = raycast_gather(
            x, UP, w, disk[None], normals, tracer.occluded, settings, np.random.default_rng(0),
            ray_offset=1e-6,
        )
        assert unoccluded[0] == pytest.approx(disk_exact, rel=3e-4)
        assert unoccluded[0] * visible[0] == pytest.approx(expected, rel=1e-2)


def test_hemicube_item_buffer_of_a_cube_floor():
    """From the floor's centre of the unit cube (one patch per face, local x = +x, y = +y), the
    middle of the top face sees the ceiling, its rim and each side face the wall in that
    direction, and no pixel escapes the closed box."""
    corners = T.unit_cube_patches(1)  # floor, ceiling, x = 0, x = 1, y = 0, y = 1
    tris, tri_patch = T.quad_triangles(corners)
    rows = HemicubeFormFactors(
        corners, T.BruteForceTracer(tris).closest_hit, tri_patch, HemicubeSettings(resolution=8)
    )
    top, sides = rows.item_buffer(0)
    assert top.shape == (8, 8) and sides.shape == (4, 4, 8)
    assert np.all(top[2:6, 2:6] == 1)
    assert np.all(top[2:6, 0] == 2) and np.all(top[2:6, -1] == 3)  # x = 0 left, x = 1 right
    assert np.all(top[0, 2:6] == 5) and np.all(top[-1, 2:6] == 4)  # row 0 is +y
    for face, wall in enumerate([3, 2, 5, 4]):  # the faces x = +1, x = -1, y = +1, y = -1
        assert np.all(sides[face] == wall)


# --- closed box: summation, reciprocity, the cube's analytic rows ---------------------------------


def test_unit_cube_faces_match_howell():
    """One patch per face of the unit cube: each row holds C-11 once and C-14 four times.
    Ray-cast (closed form, 4 x 4 Gauss, near-field cells): measured error -1.1e-10 (C-11),
    2.7e-11 (C-14)."""
    corners = T.unit_cube_patches(1)
    f = form_factor_matrix(RayCastFormFactors(corners))
    par, perp = parallel_rectangles(1, 1, 1), perpendicular_rectangles(1, 1, 1)
    opposite = np.array([1, 0, 3, 2, 5, 4])
    for i in range(6):
        assert f[i, i] == 0.0
        assert f[i, opposite[i]] == pytest.approx(par, rel=1e-8)
        others = np.setdiff1d(np.arange(6), [i, opposite[i]])
        np.testing.assert_allclose(f[i, others], perp, rtol=1e-8)


def test_closed_box_row_sums_and_reciprocity():
    """The unit cube from inside, 2 x 2 patches per face (24 patches).

    Row sums: every point of a closed box sees one full hemisphere. Hemicube rows with exact
    deltas sum to 1 to rounding (the closed box catches every pixel); ray-cast rows to 1 up to
    the quadrature error (measured 5e-8: near pairs use the finer rule). Reciprocity
    A_i F_ij = A_j F_ji: ray-cast exactly (each pair integrated once); hemicube (R = 16, 2 x 2
    points) measured max deviation 3.8% of the largest A_i F_ij (1.6% at R = 32), its factors
    within 2.3% (of the largest factor) of the ray-cast ones. Quick unoccluded test: nothing in
    a convex box is ray-tested."""
    corners = T.unit_cube_patches(2)
    areas = patch_geometry(corners).areas
    tris, tri_patch = T.quad_triangles(corners)
    tracer = T.BruteForceTracer(tris)
    ray_rows = RayCastFormFactors(corners, tracer.occluded, triangles=tris)
    assert not any(ray_rows.maybe_occluded(i).any() for i in range(len(corners)))
    ray = form_factor_matrix(ray_rows)
    settings = HemicubeSettings(resolution=16, points_per_side=2)
    hemi = form_factor_matrix(
        HemicubeFormFactors(corners, tracer.closest_hit, tri_patch, settings)
    )
    for f, row_sums, recip in ((ray, 1e-6, 1e-12), (hemi, 1e-12, 5e-2)):
        np.testing.assert_allclose(f.sum(axis=1), 1.0, atol=row_sums)
        assert np.all(np.diag(f) == 0.0) and np.all(f >= 0.0)
        power = areas[:, None] * f
        assert np.abs(power - power.T).max() <= recip * power.max()
    assert np.abs(hemi - ray).max() < 0.03 * ray.max()
    fixed = enforce_reciprocity(hemi, areas)
    np.testing.assert_allclose(areas[:, None] * fixed, (areas[:, None] * fixed).T, atol=1e-15)


def test_uneven_closed_box_ray_cast():
    """A 1 x 2 x 3 box whose faces are split unevenly (27 patches of different shapes, with
    T-junctions between faces). Ray-cast defaults: rows sum to 1 within 2e-4 (measured 5.3e-5)
    and reciprocity holds exactly; without the near-field rule the row sums are off by 5.1e-3;
    integrating every pair over its own row's patch instead keeps rows exact but breaks
    reciprocity by 4.3e-3 of the largest A_i F_ij."""
    faces = T.unit_cube_patches(1) * np.array([1.0, 2.0, 3.0])
    corners = np.concatenate(
        [T.subdivide_quad(face, 2 + k % 3, 1 + k % 2) for k, face in enumerate(faces)]
    )
    areas = patch_geometry(corners).areas
    cases = (
        (RayCastSettings(), 2e-4, 1e-12),
        (RayCastSettings(near_field_cells=1), 1e-2, 1e-12),
        (RayCastSettings(integrate_smaller=False), 1e-12, 1e-2),
    )
    for settings, row_sums, recip in cases:
        f = form_factor_matrix(RayCastFormFactors(corners, settings=settings))
        np.testing.assert_allclose(f.sum(axis=1), 1.0, atol=row_sums)
        power = areas[:, None] * f
        assert np.abs(power - power.T).max() <= recip * power.max()


# --- near field -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("w", "h", "l", "tolerance"),
    [
        (1.0, 1.0, 1.0, 1e-8),  # measured 2.7e-11
        (1e-3, 1e-3, 1e-3, 1e-8),  # the same at millimetre scale
        (0.01, 1.0, 1.0, 5e-3),  # thin floor strip along a wall: 0.22%
        (1.0, 0.01, 1.0, 5e-3),  # skirting board on a big floor: 0.22%
        (1.0, 1e-4, 1.0, 1e-3),  # 0.1 mm strip: 1.6e-4
        (0.01, 0.01, 1.0, 5e-3),  # two thin strips meeting along their length: 0.27%
        (1.0, 1.0, 0.1, 5e-3),  # two 10:1 slivers meeting at a short side: -0.23%
    ],
)
def test_near_field_adjacent_patches(w, h, l, tolerance):  # noqa: E741
    """Adjacent perpendicular patches sharing an edge (C-14), both directions, with rays cast:
    finite, and accurate because the kernel is integrated analytically over the target, each
    pair is integrated over its smaller patch, and near pairs get a finer rule (measured errors
    beside each case; 100:1 slivers meeting at a short side remain hard: -12%)."""
    corners = perpendicular_pair(w, h, l)
    tris, _ = T.quad_triangles(corners)
    rows = RayCastFormFactors(corners, T.BruteForceTracer(tris).occluded)
    f01, f10 = rows.row(0)[1], rows.row(1)[0]
    assert np.isfinite(f01) and np.isfinite(f10)
    assert f01 == pytest.approx(perpendicular_rectangles(w, h, l), rel=tolerance)
    assert f10 == pytest.approx(perpendicular_rectangles(h, w, l), rel=tolerance)


def test_near_field_hemicube_stays_finite():
    """The hemicube on a 1 x 1 floor beside a 0.01 high strip: finite and below the true value,
    with the classic near-field error (its points lie farther from the strip than the strip is
    high: measured -80% with 4 x 4 points). The ray-cast method covers this case (above)."""
    corners = perpendicular_pair(1.0, 0.01, 1.0)
    tris, tri_patch = T.quad_triangles(corners)
    rows = HemicubeFormFactors(
        corners, T.BruteForceTracer(tris).closest_hit, tri_patch, HemicubeSettings(resolution=32)
    )
    f = rows.row(0)[1]
    assert np.isfinite(f) and 0.0 < f < perpendicular_rectangles(1.0, 0.01, 1.0)


# --- occlusion in a real scene --------------------------------------------------------------------


def test_cornell_box_occlusion_reciprocity_and_quick_test():
    """Cornell box (3 x 3 wall patches, blocks, 56 patches) with brute-force visibility.

    The quick unoccluded-pair test is conservative: rows are identical with and without it (it
    spares 11% of the pairs here: most pairs have a block between or beside them). Method B
    integrates each pair once over fixed points, so A_i F_ij = A_j F_ji to rounding (measured
    2.6e-16 of the largest) with occlusion too. Occlusion only removes: no factor exceeds the
    unoccluded one, and every floor patch sees less of the ceiling (the light panel hangs below
    it, the blocks stand on the floor): measured visible share 0.30 to 0.88."""
    data = json.loads((REFERENCE.parent / "cornell_box.json").read_text())
    box = T.cornell_box_patches(data, 3)
    corners = box["corners"]
    tris, _ = T.quad_triangles(corners)
    tracer = T.BruteForceTracer(tris)
    settings = RayCastSettings(samples_per_side=2, visibility_samples_per_side=2)
    quick = RayCastFormFactors(corners, tracer.occluded, triangles=tris, settings=settings)
    full = RayCastFormFactors(corners, tracer.occluded, settings=settings)
    for i in [0, 20, 45, 47, 55]:  # floor, back wall, light, short block, tall block
        np.testing.assert_array_equal(quick.row(i), full.row(i))
    spared = np.mean([1.0 - quick.maybe_occluded(i).mean() for i in range(len(corners))])
    assert spared > 0.05
    f = form_factor_matrix(quick)
    power = quick.areas[:, None] * f
    assert np.abs(power - power.T).max() <= 1e-12 * power.max()
    free = form_factor_matrix(RayCastFormFactors(corners, settings=settings))
    assert np.all(f <= free + 1e-15)
    floor, ceiling = box["names"] == "floor", box["names"] == "ceiling"
    seen = f[np.ix_(floor, ceiling)].sum(axis=1)
    seen_free = free[np.ix_(floor, ceiling)].sum(axis=1)
    assert np.all(seen / seen_free < 0.95) and np.min(seen / seen_free) < 0.5


# --- settings -------------------------------------------------------------------------------------


def test_settings_are_validated():
    with pytest.raises(ValueError):
        HemicubeSettings(resolution=33)
    with pytest.raises(ValueError):
        HemicubeSettings(points_per_side=0)
    with pytest.raises(ValueError):
        HemicubeSettings(delta_rule="nearest")
    with pytest.raises(ValueError):
        RayCastSettings(visibility_samples_per_side=0)
    with pytest.raises(ValueError):
        RayCastSettings(ray_offset=-1.0)
    with pytest.raises(ValueError):
        patch_geometry(np.zeros((1, 4, 3)))
    with pytest.raises(ValueError):
        sample_patches(unit_floor()[None], 2, "sobol")


@pytest.mark.parametrize("m", [1, 2, 3, 5])
def test_triangle_midpoints_integrate_linear_functions_exactly(m):
    rng = np.random.default_rng(m)
    tri = rng.normal(size=(4, 3, 3))
    points, weights = sample_patches(tri, m, "midpoint")
    assert points.shape == (4, m * m, 3)
    np.testing.assert_allclose(weights, 1.0 / (m * m))
    # The mean of a linear function over a triangle is its value at the centroid.
    coef = rng.normal(size=3)
    np.testing.assert_allclose(np.einsum("ns,ns->n", weights, points @ coef),
                               tri.mean(axis=1) @ coef, rtol=1e-12, atol=1e-12)
    if m == 1:
        np.testing.assert_allclose(points[:, 0], tri.mean(axis=1), atol=1e-15)
    # Every point strictly inside its triangle, no two alike.
    e1, e2 = (tri[:, 1] - tri[:, 0])[:, None], (tri[:, 2] - tri[:, 0])[:, None]
    nrm = np.cross(e1, e2)
    d = points - tri[:, None, 0]
    b1 = np.einsum("nsc,nsc->ns", np.cross(d, e2), nrm) / np.einsum("nsc,nsc->ns", nrm, nrm)
    b2 = np.einsum("nsc,nsc->ns", np.cross(e1, d), nrm) / np.einsum("nsc,nsc->ns", nrm, nrm)
    assert (b1 > 0).all() and (b2 > 0).all() and (b1 + b2 < 1).all()
    assert len(np.unique(np.round(points[0], 12), axis=0)) == m * m
