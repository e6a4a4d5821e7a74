"""Shadow rays between an estimator and the caller's ray callback.

An estimator that needs shadow rays is a generator that yields `RayRequest`s and receives each
answer through `send`; `answer_rays` and `answer_rays_together` run such generators against an
`occluded` callback (signatures: `form_factors`)."""

from __future__ import annotations

from collections.abc import Callable, Generator
from typing import Any

import numpy as np

# Default number of rays handed to one callback call: bounds temporary memory (~100 MB of
# (R, 3) float64 arrays and the callback's own buffers).
MAX_RAYS_PER_CALL = 1 << 18

ClosestHit = Callable[[np.ndarray, np.ndarray, float, Any], Any]
Occluded = Callable[[np.ndarray, np.ndarray, float, Any], np.ndarray]


# One shadow-ray request of a generator estimator: (origins (R, 3), unit directions (R, 3),
# t_max (R,)) with t_min 0; the answer sent back is (R,) bool, True where something is hit.
RayRequest = tuple[np.ndarray, np.ndarray, np.ndarray]
RayRequests = Generator[RayRequest, np.ndarray, Any]
# Rays gathered from several rows into one ray-casting call: the BVH reaches its full rate from
# about 50k rays a call (a few thousand rays run at a third of it).
RAYS_PER_BATCH = 1 << 17


def _cast(occluded: Occluded, request: RayRequest, per_call: int) -> np.ndarray:
    origins, dirs, t_max = request
    blocked = np.zeros(len(origins), bool)
    for start in range(0, len(origins), per_call):
        part = slice(start, start + per_call)
        blocked[part] = np.asarray(occluded(origins[part], dirs[part], 0.0, t_max[part]), bool)
    return blocked


def answer_rays(steps: RayRequests, occluded: Occluded | None, per_call: int):
    """Run a ray-requesting generator to its end, answering with `occluded`; its return value."""
    try:
        request = next(steps)
        while True:
            request = steps.send(_cast(occluded, request, per_call))
    except StopIteration as stop:
        return stop.value


def answer_rays_together(steps: list, occluded: Occluded | None, per_call: int) -> list:
    """Run several ray-requesting generators side by side, their pending requests answered by
    one batch of `occluded` calls per round. Returns their return values."""
    results: list = [None] * len(steps)
    pending: dict[int, RayRequest] = {}
    for k, gen in enumerate(steps):
        try:
            pending[k] = next(gen)
        except StopIteration as stop:
            results[k] = stop.value
    while pending:
        keys = list(pending)
        sizes = np.cumsum([0] + [len(pending[k][0]) for k in keys])
        merged = tuple(np.concatenate([pending[k][part] for k in keys]) for part in range(3))
        blocked = _cast(occluded, merged, per_call)
        for n, k in enumerate(keys):
            try:
                pending[k] = steps[k].send(blocked[sizes[n] : sizes[n + 1]])
            except StopIteration as stop:
                results[k] = stop.value
                del pending[k]
    return results
