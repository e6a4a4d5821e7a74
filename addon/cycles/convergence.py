"""Converged Cycles results: two independent halves rendered until they agree
(`converged_run`).

`reference(..., samples=None)` chooses the sample count from the scene's own noise: two
independent halves (different seeds) are rendered at n samples each and the relative MSE between
them (`kernels.measure.metrics.rel_mse`, over the covered pixels or texels) is measured; while it is
above `target_rel_mse` (default 1e-4) each half gets n more samples (a render with a new seed,
averaged in) until the total reaches `max_samples`. The reference is the mean of both halves
(2n samples); its own expected relative MSE against the converged image is a quarter of the
halves' (two independent halves differ by twice the variance of one; their mean has half of it).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ...kernels.measure.metrics import rel_mse
from .runs import CyclesRun

# Default relative MSE between the two independent halves at which a reference counts as converged:
# the mean of both then sits about 2.5e-5 (0.5% RMS) from the converged image.
TARGET_REL_MSE = 1e-4
# Samples per half a convergence search starts from: fewer give a too noisy noise estimate.
START_SAMPLES = 8
# Default cap on a reference's total samples (both halves): 1024 samples of the Cornell box at
# 256 x 256 take about three minutes on a 2-core machine (tests/data/cycles_facts.md: 2-2.5 us/pixel-sample).
MAX_SAMPLES = 1024


def _stack_valid(run: CyclesRun) -> np.ndarray:
    """Every valid value of a run as one (N, 1, C) image for the error metrics."""
    parts = []
    for name, image in sorted(run.images.items()):
        mask = run.masks.get(name)
        values = image[mask] if mask is not None else image.reshape(-1, image.shape[-1])
        parts.append(values.reshape(-1, image.shape[-1]))
    return np.concatenate(parts)[:, None, :]


def _average(a: CyclesRun, b: CyclesRun) -> CyclesRun:
    """The sample-weighted mean of two runs of the same kind (their masks: a's)."""
    wa, wb = a.samples / (a.samples + b.samples), b.samples / (a.samples + b.samples)
    images = {k: (wa * a.images[k] + wb * b.images[k]).astype(np.float32) for k in a.images}
    return CyclesRun(a.kind, a.samples + b.samples, a.seconds + b.seconds, images, a.masks)


def converged_run(run: Callable[[int, int], CyclesRun], *, first_seed: int = 0,
                  target_rel_mse: float = TARGET_REL_MSE, start_samples: int = START_SAMPLES,
                  max_samples: int = MAX_SAMPLES) -> tuple[CyclesRun, float]:
    """Render two independent halves until they agree (see the module docstring).

    `run(samples, seed)` makes one render or bake. Returns (the mean of both halves, its
    estimated relative MSE against the converged result: a quarter of the halves').
    """
    if max_samples < 2:
        raise ValueError(f"max_samples must be >= 2, got {max_samples}")
    n = max(1, min(start_samples, max_samples // 2))
    seed = first_seed
    halves = []
    for _ in range(2):
        halves.append(run(n, seed))
        seed += 1
    while True:
        a, b = halves
        half_error = rel_mse(_stack_valid(a), _stack_valid(b))
        if half_error <= target_rel_mse or 2 * (a.samples + b.samples) > max_samples:
            break
        for k in range(2):  # each half doubles: n more samples with a fresh seed, averaged in
            halves[k] = _average(halves[k], run(halves[k].samples, seed))
            seed += 1
    return _average(*halves), 0.25 * half_error
