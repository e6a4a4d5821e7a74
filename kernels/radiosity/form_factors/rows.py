"""Form factor rows: the interface the solvers consume (`FormFactorRows`), a dense matrix behind it,
and whole matrices from rows."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ...progress import Steps, drain


class FormFactorRows(Protocol):
    """Anything that yields form factor rows F_i* on demand (methods A and B, a dense matrix)."""

    @property
    def areas(self) -> np.ndarray:  # (N,) float64, m^2
        ...

    def row(self, i: int, out: np.ndarray | None = None) -> np.ndarray:  # (N,) float64
        ...


@dataclass(frozen=True, eq=False)
class DenseRows:
    """A precomputed (N, N) matrix seen through the `FormFactorRows` interface."""

    matrix: np.ndarray  # (N, N) float64
    areas: np.ndarray  # (N,) float64, m^2

    def row(self, i: int, out: np.ndarray | None = None) -> np.ndarray:
        if out is None:
            return self.matrix[i].copy()
        out[...] = self.matrix[i]
        return out


def iter_matrix(rows: FormFactorRows, out: np.ndarray) -> Steps[None]:
    """Fill caller-owned `out` (N, N) from `rows`, yielding progress in (0, 1]: row by row, or
    a batch of rows at a time where `rows` can share its ray casting between rows."""
    count = out.shape[0]
    batch = rows.rows_per_batch() if hasattr(rows, "rows") else 1
    for first in range(0, count, batch):
        last = min(first + batch, count)
        if batch > 1:
            rows.rows(range(first, last), out[first:last])
        else:
            rows.row(first, out=out[first])
        yield last / count


def form_factor_matrix(rows: FormFactorRows) -> np.ndarray:
    """The full (N, N) float64 matrix of `rows` (runs `iter_matrix` to the end)."""
    count = len(rows.areas)
    out = np.empty((count, count), np.float64)
    drain(iter_matrix(rows, out))
    return out


def enforce_reciprocity(
    matrix: np.ndarray, areas: np.ndarray, out: np.ndarray | None = None
) -> np.ndarray:
    """Average each pair's two estimates of exchanged power so that A_i F_ij = A_j F_ji exactly.

    matrix (N, N) float64, areas (N,) m^2. Estimated factors satisfy reciprocity only up to
    their sampling error, so a gathering solver (rows F_i*) and a shooting one (F_ji taken as
    F_ij A_i / A_j) solve slightly different systems; after this they solve the same one.
    Row sums move by half the mismatch. `out` may be `matrix` itself.
    """
    a = np.asarray(areas, np.float64)
    power = matrix * a[:, None]  # (N, N) A_i F_ij, m^2
    mean = 0.5 * (power + power.T)
    result = np.empty_like(matrix) if out is None else out
    np.divide(mean, a[:, None], out=result)
    return result
