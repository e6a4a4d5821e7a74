"""Sample ladders: Cycles runs at increasing sample counts, one independent rung at a time, so
that callers can interleave them with kernel runs."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import bpy

from .models import CyclesModel
from .runner import warm_up
from .runs import ReferenceKind, run_cycles


def ladder_step(scene, model: CyclesModel, kind: ReferenceKind, samples: int, **kwargs) -> dict:
    """One rung of a sample ladder: {"samples", "seconds", "image" | "images", "masks"}.

    Each call is independent (same seed, nothing kept between calls), so callers can interleave
    rungs with kernel runs and machine-load drift falls on both alike.
    """
    run = run_cycles(scene, model, kind, samples, **kwargs)
    entry: dict[str, Any] = {"samples": run.samples, "seconds": run.seconds}
    if kind == "render":
        entry["image"] = run.image
    else:
        entry["images"] = run.images
        entry["masks"] = run.masks
    return entry


def sample_ladder(scene, model: CyclesModel, sample_counts: Sequence[int],
                  kind: ReferenceKind = "render", *, warm: bool = True, **kwargs) -> list[dict]:
    """`ladder_step` for each sample count in order (e.g. 1, 2, 4, ... N), after `warm_up`.

    Returns [{"samples", "seconds", "image"} ...] ("images"/"masks" for bakes), the shape the
    speed-accuracy chart and metrics.json's comparison.ladder.cycles take once an error is added.
    """
    scene = scene or bpy.context.scene
    if warm:
        warm_up(scene)
    return [ladder_step(scene, model, kind, int(n), **kwargs) for n in sample_counts]


def doubling_counts(max_samples: int, start: int = 1) -> list[int]:
    """1, 2, 4, ... up to `max_samples` (included even when it is not a power of two)."""
    counts, n = [], max(1, start)
    while n < max_samples:
        counts.append(n)
        n *= 2
    counts.append(max_samples)
    return counts
