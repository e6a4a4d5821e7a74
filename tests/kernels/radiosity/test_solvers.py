"""Radiosity solvers: the furnace test, agreement on the Cornell box, input checks.

Furnace: in a closed box whose rows of F sum to 1, uniform emission E and reflectance rho give
B = E / (1 - rho) on every patch (B = E + rho B). The unit cube's factors come from both form
factor methods of `kernels/radiosity/form_factors/`, whose rows sum to 1 there to rounding (see
test_form_factors.py). Cornell box: tests/data/cornell_box.json (geometry mapped
(x, y, z) -> (-x, z, y), mm -> m; CornellBox-Original MTL colours).
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import radiosity_scenes as T
from reference_data import DATA

from classic_bake.kernels.radiosity import solvers as rs
from classic_bake.kernels.radiosity.form_factors.hemicube import (
    HemicubeFormFactors,
    HemicubeSettings,
)
from classic_bake.kernels.radiosity.form_factors.raycast import RayCastFormFactors, RayCastSettings
from classic_bake.kernels.radiosity.form_factors.rows import form_factor_matrix
from classic_bake.kernels.radiosity.form_factors.sampling import patch_geometry

REFERENCE = DATA

EMISSION = np.array([1.0, 0.5, 0.25])  # W/m^2 per channel, the furnace's uniform emission


@pytest.fixture(scope="module")
def cube() -> dict:
    """The unit cube from inside, 2 x 2 patches per face: F from both methods."""
    corners = T.unit_cube_patches(2)
    tris, tri_patch = T.quad_triangles(corners)
    tracer = T.BruteForceTracer(tris)
    # Convex: no pair is occluded, closed form alone. One 4 x 4 Gauss rule for every pair (no
    # finer near-field rule), so every row sums to 1 to rounding (measured 2.2e-16).
    raycast = RayCastFormFactors(corners, settings=RayCastSettings(near_field_cells=1))
    settings = HemicubeSettings(resolution=16, points_per_side=2)
    hemicube = HemicubeFormFactors(corners, tracer.closest_hit, tri_patch, settings)
    return {
        "rows": raycast,
        "areas": raycast.areas,
        "raycast": form_factor_matrix(raycast),
        "hemicube": form_factor_matrix(hemicube),
    }


@pytest.fixture(scope="module")
def cornell() -> dict:
    """Cornell box, 3 x 3 patches per wall (56 patches), method B with brute-force visibility.
    Its matrix is exactly reciprocal, so gathering and shooting solve the same system."""
    data = json.loads((REFERENCE / "cornell_box.json").read_text())
    box = T.cornell_box_patches(data, 3)
    tris, _ = T.quad_triangles(box["corners"])
    rows = RayCastFormFactors(
        box["corners"], T.BruteForceTracer(tris).occluded, triangles=tris,
        settings=RayCastSettings(samples_per_side=3, visibility_samples_per_side=2),
    )
    box["areas"] = rows.areas
    box["F"] = form_factor_matrix(rows)
    return box


ALL_SOLVERS = [
    rs.GaussSeidelSettings(tolerance=1e-7),
    rs.GaussSeidelSettings(tolerance=1e-7, method="jacobi"),
    rs.ProgressiveSettings(tolerance=1e-6),
    rs.ProgressiveSettings(tolerance=1e-6, ambient=False),
]


# --- furnace --------------------------------------------------------------------------------------


@pytest.mark.parametrize("rho", [0.3, 0.8, 0.95, (0.95, 0.5, 0.1)])
@pytest.mark.parametrize("method", ["raycast", "hemicube"])
def test_furnace_closed_box(cube, rho, method):
    """B = E / (1 - rho) on all 24 patches, every solver, rho up to 0.95 (and per channel).

    Gauss-Seidel and Jacobi stop on an error bound of 1e-7 x max B, and that bound holds for
    either matrix (measured max relative error at rho = 0.95: Gauss-Seidel 4.5e-8 after 166
    sweeps, Jacobi 9.6e-8 after 314). Progressive refinement stops at an unshot power fraction
    of 1e-6 per channel; with the exactly reciprocal ray-cast F the missing radiosity is then
    below 1e-6 relative (measured at rho = 0.95 after 3270 shots: 9.7e-7 without the ambient
    term, 2e-8 with it). Shooting uses F_ji = F_ij A_i / A_j, so with the hemicube's F (3.8%
    reciprocity mismatch at R = 16) it solves a slightly different system: measured 0.29%
    (rho 0.3) to 0.9% (rho 0.95) off, asserted within 1.5%."""
    f, areas = cube[method], cube["areas"]
    count = len(areas)
    e = np.tile(EMISSION, (count, 1))
    reflectance = np.tile(np.broadcast_to(np.asarray(rho, float), 3), (count, 1))
    expected = e / (1.0 - reflectance)
    for settings in ALL_SOLVERS:
        solution = rs.solve(f, e, reflectance, settings, areas=areas)
        assert solution.converged
        error = np.abs(solution.radiosity / expected - 1.0).max()
        if isinstance(settings, rs.GaussSeidelSettings):
            tolerance = 1e-7
        else:
            tolerance = 1e-6 if method == "raycast" else 1.5e-2
        assert error <= tolerance, settings


def test_furnace_with_row_callbacks(cube):
    """The solvers on `FormFactorRows` (rows computed on demand) match the dense results; the
    shooting solver asks for each row once thanks to its cache, the gathering one once per
    patch (rows kept from the first sweep)."""
    count = len(cube["areas"])
    e = np.tile(EMISSION, (count, 1))
    reflectance = np.full((count, 3), 0.8)

    class Counting:
        def __init__(self, rows):
            self.rows, self.calls = rows, 0
            self.areas = rows.areas

        def row(self, i, out=None):
            self.calls += 1
            return self.rows.row(i, out=out)

    for settings in (rs.GaussSeidelSettings(), rs.ProgressiveSettings()):
        rows = Counting(cube["rows"])
        from_rows = rs.solve(rows, e, reflectance, settings)
        dense = rs.solve(cube["raycast"], e, reflectance, settings, areas=cube["areas"])
        np.testing.assert_allclose(from_rows.radiosity, dense.radiosity, rtol=1e-12)
        assert rows.calls == count
        # A plain function row(i) -> (N,) works too (areas passed separately).
        function = rs.solve(cube["rows"].row, e, reflectance, settings, areas=cube["areas"])
        np.testing.assert_allclose(function.radiosity, dense.radiosity, rtol=1e-12)


# --- agreement on the Cornell box -----------------------------------------------------------------


def test_solvers_agree_on_cornell_box(cornell):
    """Gauss-Seidel, Jacobi and progressive refinement (with and without ambient) give the same
    radiosity on the Cornell box (56 patches): within 1e-5 of the largest B of a 1e-9 Gauss-Seidel
    solution (measured: Gauss-Seidel 1.2e-8 after 13 sweeps, Jacobi 3.5e-8 after 22, progressive
    1.1e-8 with ambient, 1.9e-8 without, after 577 shots at an unshot fraction of 1e-6)."""
    f, e, reflectance = cornell["F"], cornell["emission"], cornell["reflectance"]
    reference = rs.solve(f, e, reflectance, rs.GaussSeidelSettings(tolerance=1e-9)).radiosity
    assert np.all(reference >= e)
    for settings in ALL_SOLVERS:
        solution = rs.solve(f, e, reflectance, settings, areas=cornell["areas"])
        assert solution.converged
        assert np.abs(solution.radiosity - reference).max() <= 1e-5 * reference.max(), settings


def test_cornell_box_colour_bleeding(cornell):
    """Colour bleeding: the white floor is redder beside the red wall (-x side) than beside the
    green wall (+x side). Measured red/green ratio of the floor patches: 1.73-4.55 along the red
    wall, 0.81-1.33 along the green wall."""
    f, e, reflectance = cornell["F"], cornell["emission"], cornell["reflectance"]
    b = rs.solve(f, e, reflectance).radiosity
    floor = cornell["names"] == "floor"
    centres = patch_geometry(cornell["corners"][floor]).centres
    ratio = b[floor, 0] / b[floor, 1]
    near_red = centres[:, 0] < -0.4
    near_green = centres[:, 0] > -0.15
    assert near_red.sum() == 3 and near_green.sum() == 3
    assert ratio[near_red].min() > ratio[near_green].max()
    # The ceiling (white, lit only indirectly) is dimmer than the light and brighter than black.
    ceiling = b[cornell["names"] == "ceiling"]
    assert np.all(ceiling > 0.0) and np.all(ceiling < e[cornell["names"] == "light"].max())


# --- progress, buffers, edge cases ----------------------------------------------------------------


def test_progress_and_out_buffers(cube):
    count = len(cube["areas"])
    e = np.tile(EMISSION, (count, 1))
    reflectance = np.full((count, 3), 0.9)
    out = np.empty((count, 3))
    solver = rs.GaussSeidelSolver(cube["raycast"], e, reflectance, out=out)
    values = list(solver.run())
    assert solver.radiosity is out and solver.converged
    assert len(values) == solver.iterations and values[-1] == 1.0
    assert all(0.0 <= v <= 1.0 for v in values)
    shooter = rs.ProgressiveSolver(cube["raycast"], e, reflectance, cube["areas"], out=out)
    values = list(shooter.run())
    assert shooter.radiosity is out and values[-1] == 1.0
    # Shooting never increases the unshot power (rho < 1, rows sum to <= 1): monotone progress.
    assert np.all(np.diff(values) >= 0.0)
    display = shooter.display()
    assert np.all(display >= shooter.radiosity)


def test_ambient_term_in_an_open_scene():
    """Two parallel unit squares 1 m apart (4 x 4 patches each, the lower one emitting, rho 0.5):
    80% of every shot escapes. The ambient term scales the unshot power by the closure the shots
    measured (their power-weighted row sums) instead of assuming a closed room, so the display's
    reflected power after a single shot is within 15% of the converged one (measured 0.855; the
    closed-room estimate 1 / (1 - rho_avg) gives 8.5x, shot light alone 0.049), and closer as
    shots accumulate."""
    bottom = T.subdivide_quad(np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float), 4, 4)
    top = T.subdivide_quad(np.array([[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]], float), 4, 4)
    rows = RayCastFormFactors(np.concatenate([bottom, top]))
    f, areas = form_factor_matrix(rows), rows.areas
    count = len(areas)
    e = np.zeros((count, 3))
    e[: count // 2] = EMISSION
    rho = np.full((count, 3), 0.5)

    def reflected(b):  # (3,) W reflected in all
        return ((b - e) * areas[:, None]).sum(axis=0)

    converged = reflected(rs.solve(f, e, rho, rs.ProgressiveSettings(tolerance=1e-9),
                                   areas=areas).radiosity)
    errors = []
    for shots in (1, 4, 16):
        solver = rs.ProgressiveSolver(f, e, rho, areas, rs.ProgressiveSettings(max_shots=shots))
        for _ in solver.run():
            pass
        # The closure is the shooters' row sums: 0.174 for a corner patch, 0.199 mid-square.
        assert np.all((solver.closure() > 0.17) & (solver.closure() < 0.21))
        shown = reflected(solver.solution().radiosity) / converged
        closed_room = reflected(solver.radiosity + rho * (solver.unshot * areas[:, None]).sum(axis=0)
                                / areas.sum() / (1.0 - 0.5)) / converged
        errors.append(float(np.abs(shown - 1.0).max()))
        assert errors[-1] < np.abs(closed_room - 1.0).min()
    assert errors[0] < 0.15 and errors[2] < 0.01 and errors == sorted(errors, reverse=True)


def test_no_emission_and_iteration_limit(cube):
    count = len(cube["areas"])
    zero = np.zeros((count, 3))
    reflectance = np.full((count, 3), 0.5)
    for settings in ALL_SOLVERS:
        solution = rs.solve(cube["raycast"], zero, reflectance, settings, areas=cube["areas"])
        assert solution.converged and np.all(solution.radiosity == 0.0)
    e = np.tile(EMISSION, (count, 1))
    high = np.full((count, 3), 0.95)
    capped = rs.solve(cube["raycast"], e, high, rs.GaussSeidelSettings(max_iterations=3))
    assert not capped.converged and capped.iterations == 3
    capped = rs.solve(cube["raycast"], e, high, rs.ProgressiveSettings(max_shots=10),
                      areas=cube["areas"])
    assert not capped.converged and capped.iterations == 10


@pytest.mark.parametrize("settings", ALL_SOLVERS[:3])
def test_invalid_inputs_raise(cube, settings):
    """rho >= 1 in any channel, negative or non-finite emission, bad shapes: ValueError."""
    f, areas = cube["raycast"], cube["areas"]
    count = len(areas)
    e = np.tile(EMISSION, (count, 1))
    for bad_channel in range(3):
        reflectance = np.full((count, 3), 0.5)
        reflectance[5, bad_channel] = 1.0
        with pytest.raises(ValueError, match="reflectance >= 1"):
            rs.solve(f, e, reflectance, settings, areas=areas)
    reflectance = np.full((count, 3), 0.5)
    negative = e.copy()
    negative[3, 1] = -0.1
    with pytest.raises(ValueError, match="negative emission"):
        rs.solve(f, negative, reflectance, settings, areas=areas)
    with pytest.raises(ValueError, match="negative reflectance"):
        rs.solve(f, e, -reflectance, settings, areas=areas)
    nan = e.copy()
    nan[0, 0] = np.nan
    with pytest.raises(ValueError, match="finite"):
        rs.solve(f, nan, reflectance, settings, areas=areas)
    with pytest.raises(ValueError):
        rs.solve(f, e[:, :2], reflectance[:, :2], settings, areas=areas)
    with pytest.raises(ValueError):
        rs.solve(f[:-1, :-1], e, reflectance, settings, areas=areas)


def test_settings_are_validated():
    with pytest.raises(ValueError):
        rs.GaussSeidelSettings(tolerance=0.0)
    with pytest.raises(ValueError):
        rs.GaussSeidelSettings(method="sor")
    with pytest.raises(ValueError):
        rs.ProgressiveSettings(max_shots=0)
    with pytest.raises(ValueError):
        rs.ProgressiveSolver(np.eye(2), np.ones((2, 3)), np.zeros((2, 3)))  # no areas
    with pytest.raises(TypeError):
        rs.solve(np.eye(2), np.ones((2, 3)), np.zeros((2, 3)), settings=object())
