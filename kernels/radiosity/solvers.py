"""Solvers for the radiosity system B = E + rho F B, in RGB.

    B_i = E_i + rho_i sum_j F_ij B_j          i = 1..N, per colour channel

B radiosity (W/m^2, or radiance x pi), E emitted radiosity, rho diffuse reflectance, F the form
factors of `form_factors`. Every surface is perfectly diffuse, so the solution does not
depend on the viewer: it is solved once and then displayed from anywhere.

| array | shape        | dtype   | meaning                                            |
|-------|--------------|---------|----------------------------------------------------|
| E     | (N, 3)       | float64 | emitted radiosity, linear Rec.709, >= 0            |
| rho   | (N, 3)       | float64 | diffuse reflectance, in [0, 1) per channel         |
| F     | (N, N)       | float64 | dense form factors, row i = F_i* (or `rows`)       |
| rows  | object / fn  |         | `FormFactorRows` (`.row(i) -> (N,)`, `.areas`) or  |
|       |              |         | a plain function row(i) -> (N,) F_i*               |
| areas | (N,)         | float64 | patch areas, m^2 (progressive refinement)          |
| B     | (N, 3)       | float64 | radiosity, same units as E                         |

Two solvers, both consuming `FormFactorRows` (the hierarchical solver, `hierarchical.py`, iterates
over its own links):

* `GaussSeidelSolver` ("gathering"): sweeps B_i <- E_i + rho_i sum_j F_ij B_j in place (Jacobi:
  from the previous sweep). One sweep reads every row once, so F is dense or rows are cheap.
* `ProgressiveSolver` ("shooting", Cohen, Chen, Wallace and Greenberg 1988): repeatedly shoots the
  unshot radiosity of the patch with the most unshot power dB_i A_i to every patch j, using
  reciprocity F_ji = F_ij A_i / A_j, so it needs one row per shot and never the N x N matrix; the
  ambient term (1988, section 4) gives a usable display before convergence.

Both refuse rho >= 1 in any channel (the iteration would not converge: no energy leaves a
closed scene) and negative or non-finite emission with a ValueError. Both yield progress in
[0, 1] from `run()`, expose `step()`, and write into a caller-owned `out=` (N, 3) buffer.

Error bound used by Gauss-Seidel/Jacobi: with q = max_i max_c rho_ic sum_j |F_ij| < 1 both
iterations contract by q in the max norm, so after a sweep that changed B by d (max norm)
the remaining error is at most q / (1 - q) d. The solver stops when that bound falls below
`tolerance` x max|B|: a guarantee on B itself, not just on the last update.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..progress import Steps
from .form_factors.rows import DenseRows, FormFactorRows

# An error bound, unshot fraction or radiosity at or below this counts as exactly zero: a
# scene without emission is solved by B = 0 at once (no 0/0 in relative criteria).
ZERO_ENERGY = 1e-300


# --- settings and result -------------------------------------------------------------------------


@dataclass(frozen=True)
class GaussSeidelSettings:
    """Gathering iterations on (I - rho F) B = E.

    | field          | range        | default       | meaning                                   |
    |----------------|--------------|---------------|-------------------------------------------|
    | tolerance      | (0, 1)       | 1e-6          | stop when the bound on max|B - B*| is at    |
    |                |              |               | most tolerance x max|B| (see module doc)   |
    | max_iterations | >= 1         | 10 000        | sweeps before giving up (converged False) |
    | method         | gauss_seidel | gauss_seidel  | "jacobi": every row from the last sweep   |
    |                | / jacobi     |               | (vectorised, about twice the sweeps)      |
    | cache_rows     | bool         | True          | with `FormFactorRows`: keep the rows read |
    |                |              |               | in the first sweep (N^2 x 8 bytes) instead|
    |                |              |               | of asking for every row in every sweep    |
    """

    tolerance: float = 1e-6
    max_iterations: int = 10_000
    method: Literal["gauss_seidel", "jacobi"] = "gauss_seidel"
    cache_rows: bool = True

    def __post_init__(self) -> None:
        if not 0.0 < self.tolerance < 1.0:
            raise ValueError(f"tolerance must be in (0, 1), got {self.tolerance}")
        if self.max_iterations < 1:
            raise ValueError(f"max_iterations must be >= 1, got {self.max_iterations}")
        if self.method not in ("gauss_seidel", "jacobi"):
            raise ValueError(f"method must be 'gauss_seidel' or 'jacobi', got {self.method!r}")


@dataclass(frozen=True)
class ProgressiveSettings:
    """Progressive refinement (shooting).

    | field      | range  | default   | meaning                                                 |
    |------------|--------|-----------|---------------------------------------------------------|
    | tolerance  | (0, 1) | 1e-4      | stop when unshot power / emitted power <= tolerance in  |
    |            |        |           | every channel (power: sum over patches of B A)          |
    | max_shots  | >= 1   | 1 000 000 | shots before giving up (converged False)                |
    | ambient    | bool   | True      | add the 1988 ambient term to `display()` and the result |
    | row_cache  | >= 0   | 256       | form factor rows kept (least recently used first out); |
    |            |        |           | a patch is shot many times when rho is high             |
    """

    tolerance: float = 1e-4
    max_shots: int = 1_000_000
    ambient: bool = True
    row_cache: int = 256

    def __post_init__(self) -> None:
        if not 0.0 < self.tolerance < 1.0:
            raise ValueError(f"tolerance must be in (0, 1), got {self.tolerance}")
        if self.max_shots < 1:
            raise ValueError(f"max_shots must be >= 1, got {self.max_shots}")
        if self.row_cache < 0:
            raise ValueError(f"row_cache must be >= 0, got {self.row_cache}")


SolverSettings = GaussSeidelSettings | ProgressiveSettings


@dataclass(frozen=True, eq=False)
class RadiositySolution:
    """What a solver hands back.

    radiosity  (N, 3) float64  B; for progressive refinement the shot radiosity plus, when the
                               settings ask for it, rho x ambient (the displayed value)
    ambient    (3,) float64    the ambient radiosity added (zeros for Gauss-Seidel)
    iterations int             sweeps (Gauss-Seidel, Jacobi) or shots (progressive)
    error      float           the stopping quantity at the end: the relative error bound
                               (Gauss-Seidel, Jacobi) or the unshot power fraction (progressive)
    converged  bool            error <= tolerance
    method     str             "gauss_seidel", "jacobi" or "progressive"
    """

    radiosity: np.ndarray
    ambient: np.ndarray
    iterations: int
    error: float
    converged: bool
    method: str


# --- input checks -------------------------------------------------------------------------------


def check_inputs(emission, reflectance) -> tuple[np.ndarray, np.ndarray]:
    """E and rho as (N, 3) float64, or ValueError: shapes, finiteness, E >= 0, 0 <= rho < 1."""
    e = np.asarray(emission, np.float64)
    rho = np.asarray(reflectance, np.float64)
    if e.ndim != 2 or e.shape[1] != 3 or rho.shape != e.shape:
        raise ValueError(f"emission and reflectance must be (N, 3), got {e.shape}, {rho.shape}")
    if not (np.all(np.isfinite(e)) and np.all(np.isfinite(rho))):
        raise ValueError("emission and reflectance must be finite")
    if np.any(e < 0.0):
        bad = np.flatnonzero(np.any(e < 0.0, axis=1))
        raise ValueError(f"negative emission on patches {bad[:8].tolist()}: emission must be >= 0")
    if np.any(rho >= 1.0):
        bad = np.flatnonzero(np.any(rho >= 1.0, axis=1))
        raise ValueError(
            f"reflectance >= 1 on patches {bad[:8].tolist()} (max {rho.max():.4g}): a surface "
            "reflecting all light never lets a closed scene converge; use rho < 1 per channel"
        )
    if np.any(rho < 0.0):
        bad = np.flatnonzero(np.any(rho < 0.0, axis=1))
        raise ValueError(f"negative reflectance on patches {bad[:8].tolist()}")
    return e, rho


@dataclass(frozen=True, eq=False)
class _FunctionRows:
    """A plain function row(i) -> (N,) seen through the `FormFactorRows` interface."""

    function: Callable[[int], np.ndarray]
    areas: np.ndarray

    def row(self, i: int, out: np.ndarray | None = None) -> np.ndarray:
        values = np.asarray(self.function(i), np.float64)
        if out is None:
            return values.copy()
        out[...] = values
        return out


def _is_rows(form_factors) -> bool:
    return hasattr(form_factors, "row") or callable(form_factors)


def _as_rows(form_factors, areas: np.ndarray | None, count: int) -> FormFactorRows:
    """Dense (N, N) arrays become `DenseRows`, plain functions `_FunctionRows`; anything with
    `.row` passes through."""
    if hasattr(form_factors, "row"):
        return form_factors
    a = np.ones(count) if areas is None else np.asarray(areas, np.float64)
    if callable(form_factors):
        return _FunctionRows(form_factors, a)
    f = np.asarray(form_factors, np.float64)
    if f.shape != (count, count):
        raise ValueError(f"form factors must be ({count}, {count}), got {f.shape}")
    return DenseRows(f, a)


def _progress(error: float, start: float, tolerance: float) -> float:
    """Log-scale progress from `start` down to `tolerance`, clipped to [0, 1]."""
    if error <= tolerance:
        return 1.0
    if start <= tolerance or error >= start:
        return 0.0
    return float(np.clip(np.log(start / error) / np.log(start / tolerance), 0.0, 1.0))


# --- Gauss-Seidel / Jacobi ------------------------------------------------------------------------


class GaussSeidelSolver:
    """Gathering solver: `step()` runs one sweep; `run()` yields progress until convergence.

    form_factors: dense (N, N) array, `FormFactorRows` or a function row(i) -> (N,);
    emission, reflectance (N, 3).
    A patch that sees itself (F_ii > 0, non-planar patches) is solved for exactly:
    B_i = (E_i + rho_i sum_{j != i} F_ij B_j) / (1 - rho_i F_ii).
    """

    def __init__(
        self,
        form_factors,
        emission,
        reflectance,
        settings: GaussSeidelSettings | None = None,
        *,
        out: np.ndarray | None = None,
    ) -> None:
        self.emission, self.reflectance = check_inputs(emission, reflectance)
        count = len(self.emission)
        self.settings = settings or GaussSeidelSettings()
        self._dense = None if _is_rows(form_factors) else np.asarray(form_factors, np.float64)
        self.rows = _as_rows(form_factors, None, count)
        self.radiosity = np.empty((count, 3)) if out is None else out  # (N, 3), B
        self.radiosity[...] = self.emission
        self.iterations = 0
        self.error = np.inf
        self._first_error: float | None = None
        # Contraction factor q (module doc); for rows it is known after the first sweep.
        self._q = None
        if self._dense is not None:
            self._q = _contraction(np.abs(self._dense).sum(axis=1), self.reflectance)
        self._row_sums = np.zeros(count)
        self._cache = None  # (N, N) rows kept from the first sweep (settings.cache_rows)
        if self._dense is None and self.settings.cache_rows:
            self._cache = np.empty((count, count))
        if not np.any(self.emission > 0.0):
            self.error = 0.0

    @property
    def converged(self) -> bool:
        return self.error <= self.settings.tolerance

    def step(self) -> float:
        """One sweep; returns progress in [0, 1]."""
        b, e, rho = self.radiosity, self.emission, self.reflectance
        if self.settings.method == "jacobi" and self._dense is not None:
            new = e + rho * (self._dense @ b)
            diag = np.diag(self._dense)[:, None]
            new = (new - rho * diag * b) / (1.0 - rho * diag)  # self term solved exactly
            change = float(np.max(np.abs(new - b)))
            b[...] = new
        else:
            change = self._sweep_rows(jacobi=self.settings.method == "jacobi")
        if self.iterations == 0 and self._cache is not None:
            self._dense, self._cache = self._cache, None
            self.rows = DenseRows(self._dense, np.ones(len(b)))
        self.iterations += 1
        q = self._q
        if q is None:
            q = self._q = _contraction(self._row_sums, rho)
        scale = max(float(np.max(np.abs(b))), ZERO_ENERGY)
        bound = change * q / (1.0 - q) if q < 1.0 else change
        self.error = bound / scale
        if self._first_error is None:
            self._first_error = self.error
        return _progress(self.error, self._first_error, self.settings.tolerance)

    def _sweep_rows(self, jacobi: bool) -> float:
        b, e, rho = self.radiosity, self.emission, self.reflectance
        source = b.copy() if jacobi else b
        row = np.empty(len(b))
        change = 0.0
        first = self.iterations == 0
        for i in range(len(b)):
            f = self.rows.row(i, out=row)
            if first:
                self._row_sums[i] = np.abs(f).sum()
                if self._cache is not None:
                    self._cache[i] = f
            gathered = f @ source - f[i] * source[i]
            new = (e[i] + rho[i] * gathered) / (1.0 - rho[i] * f[i])
            change = max(change, float(np.max(np.abs(new - b[i]))))
            b[i] = new
        return change

    def run(self) -> Steps[None]:
        """Sweep until converged or max_iterations; yields progress after each sweep."""
        if self.converged:
            yield 1.0
        while not self.converged and self.iterations < self.settings.max_iterations:
            yield self.step()

    def solution(self) -> RadiositySolution:
        return RadiositySolution(
            self.radiosity, np.zeros(3), self.iterations, float(self.error), self.converged,
            self.settings.method,
        )


def _contraction(row_sums: np.ndarray, rho: np.ndarray) -> float:
    """q = max_i max_c rho_ic sum_j |F_ij| (the max-norm of rho F)."""
    return float(np.max(rho.max(axis=1) * row_sums)) if len(row_sums) else 0.0


# --- progressive refinement -----------------------------------------------------------------------


class ProgressiveSolver:
    """Shooting solver (Cohen et al. 1988): `step()` shoots one patch, `run()` yields progress.

    rows: `FormFactorRows`, a function row(i) -> (N,) or a dense (N, N) array; row(i) is F_i* of
    the shooter; areas (N,) m^2 (taken from `rows.areas` when omitted).

    State: `radiosity` (N, 3) shot so far (starts at E), `unshot` (N, 3) radiosity not yet
    shot; `display()` adds rho x ambient, the 1988 estimate of what the unshot power will
    still add, spread evenly:

        ambient = c sum_j dB_j A_j / sum_j A_j / (1 - c rho_avg)

    rho_avg the area-weighted mean reflectance (per channel), c the scene's closure: the share of
    shot power that landed on patches, sum_j F_ij weighted by each shot's power (1 before the
    first shot). The 1988 paper's R = 1 / (1 - rho_avg) is c = 1: a closed room. In an open
    scene (a lamp-lit ground under an empty sky) most unshot power leaves, and c = 1 displayed
    shadows.blend after one shot 3.0x too bright on average (relMSE 5.9 against Cycles; 0.99x
    and 0.012 with the closure).
    """

    def __init__(
        self,
        rows,
        emission,
        reflectance,
        areas: np.ndarray | None = None,
        settings: ProgressiveSettings | None = None,
        *,
        out: np.ndarray | None = None,
    ) -> None:
        self.emission, self.reflectance = check_inputs(emission, reflectance)
        count = len(self.emission)
        self.settings = settings or ProgressiveSettings()
        if areas is None and not hasattr(rows, "areas"):
            raise ValueError("progressive refinement needs patch areas (N,) m^2")
        self.rows = _as_rows(rows, areas, count)
        a = np.asarray(self.rows.areas if areas is None else areas, np.float64)
        if a.shape != (count,) or np.any(~(a > 0.0)):
            raise ValueError(f"areas must be ({count},) and > 0")
        self.areas = a
        self.radiosity = np.empty((count, 3)) if out is None else out
        self.radiosity[...] = self.emission
        self.unshot = self.emission.copy()  # (N, 3)
        self.shots = 0
        self._emitted = (self.emission * a[:, None]).sum(axis=0)  # (3,) W per channel
        self._cache: OrderedDict[int, np.ndarray] = OrderedDict()
        self._rho_avg = (self.reflectance * a[:, None]).sum(axis=0) / a.sum()  # (3,)
        self._shot_power = np.zeros(3)  # W per channel, every shot so far
        self._caught_power = np.zeros(3)  # W per channel of it that landed on patches

    @property
    def unshot_fraction(self) -> float:
        """Unshot over emitted power, the largest over channels that emit (0 without emission)."""
        lit = self._emitted > ZERO_ENERGY
        if not lit.any():
            return 0.0
        unshot = (self.unshot * self.areas[:, None]).sum(axis=0)
        return float(np.max(unshot[lit] / self._emitted[lit]))

    @property
    def converged(self) -> bool:
        return self.unshot_fraction <= self.settings.tolerance

    def closure(self) -> np.ndarray:
        """(3,) share of the shot power that landed on patches (1 where nothing was shot yet)."""
        shot = self._shot_power > ZERO_ENERGY
        return np.divide(self._caught_power, self._shot_power, out=np.ones(3), where=shot)

    def ambient(self) -> np.ndarray:
        """(3,) ambient radiosity estimate of the unshot power (class docstring)."""
        unshot_power = (self.unshot * self.areas[:, None]).sum(axis=0)  # (3,)
        c = self.closure()
        return c * unshot_power / self.areas.sum() / (1.0 - c * self._rho_avg)

    def display(self, out: np.ndarray | None = None) -> np.ndarray:
        """(N, 3) radiosity for display: shot radiosity + rho x ambient."""
        result = np.empty_like(self.radiosity) if out is None else out
        np.multiply(self.reflectance, self.ambient(), out=result)
        result += self.radiosity
        return result

    def _row(self, i: int) -> np.ndarray:
        cached = self._cache.get(i)
        if cached is not None:
            self._cache.move_to_end(i)
            return cached
        row = np.array(self.rows.row(i), np.float64)  # a copy: providers may reuse buffers
        if self.settings.row_cache > 0:
            self._cache[i] = row
            if len(self._cache) > self.settings.row_cache:
                self._cache.popitem(last=False)
        return row

    def step(self) -> float:
        """Shoot the patch with the most unshot power; returns progress in [0, 1]."""
        power = (self.unshot * self.areas[:, None]).sum(axis=1)  # (N,) W (summed over RGB)
        i = int(np.argmax(power))
        if power[i] <= ZERO_ENERGY:
            return 1.0
        shooting = self.unshot[i].copy()  # (3,)
        self.unshot[i] = 0.0
        row = self._row(i)
        self._shot_power += shooting * self.areas[i]
        # Capped at 1: a closed box's estimated rows may sum a little above it, and a closure
        # above 1 would take 1 - c rho_avg towards 0 at high reflectance.
        self._caught_power += shooting * self.areas[i] * min(float(row.sum()), 1.0)
        # Reciprocity: F_ji = F_ij A_i / A_j, so patch j receives rho_j dB_i F_ij A_i / A_j.
        f_ji = row * (self.areas[i] / self.areas)  # (N,)
        received = self.reflectance * (f_ji[:, None] * shooting[None, :])  # (N, 3)
        self.radiosity += received
        self.unshot += received
        self.shots += 1
        return _progress(self.unshot_fraction, 1.0, self.settings.tolerance)

    def run(self) -> Steps[None]:
        """Shoot until converged or max_shots; yields progress after each shot."""
        if self.converged:
            yield 1.0
        while not self.converged and self.shots < self.settings.max_shots:
            yield self.step()

    def solution(self) -> RadiositySolution:
        ambient = self.ambient() if self.settings.ambient else np.zeros(3)
        b = self.radiosity + self.reflectance * ambient
        return RadiositySolution(
            b, ambient, self.shots, self.unshot_fraction, self.converged, "progressive"
        )


# --- one entry point ------------------------------------------------------------------------------


def solve(
    form_factors,
    emission,
    reflectance,
    settings: SolverSettings | None = None,
    *,
    areas: np.ndarray | None = None,
    progress: Callable[[float], None] | None = None,
) -> RadiositySolution:
    """Solve to convergence with the solver the settings name (Gauss-Seidel by default).

    form_factors: dense (N, N), `FormFactorRows` or a function row(i) -> (N,); areas (N,) m^2
    are needed by progressive refinement unless form_factors carries `.areas`. `progress` is
    called with each progress value in [0, 1].
    """
    settings = settings or GaussSeidelSettings()
    if isinstance(settings, GaussSeidelSettings):
        solver = GaussSeidelSolver(form_factors, emission, reflectance, settings)
    elif isinstance(settings, ProgressiveSettings):
        solver = ProgressiveSolver(form_factors, emission, reflectance, areas, settings)
    else:
        raise TypeError(f"unknown solver settings {type(settings).__name__}")
    for value in solver.run():
        if progress is not None:
            progress(value)
    return solver.solution()
