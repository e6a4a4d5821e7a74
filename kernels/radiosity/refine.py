"""Adaptive refinement: which patches the next level splits, and which a lamp's hard shadow edge
splits before the first solve.

Patches whose interpolated corner values differ from their own B by more than
`refine_threshold` (relative), or that straddle a light's shadow boundary (some of their points
see the light, others do not), are split in four and the system is solved again, up to
`refine_levels` times and `max_patches` patches. With the final gather, patches across a point,
spot or sun lamp's shadow edge are instead split before the first solve (`shadow_splits`,
`sources.shadow_edges`): receivers gather their own direct light, but such a patch still
sends one mean to its neighbours.
"""

from __future__ import annotations

import numpy as np

from ..measure.metrics import REC709_LUMINANCE
from . import patches as patching
from .settings import RadiositySettings

# Below this luminance fraction of the scene's mean radiosity a patch counts as dark: relative
# differences are measured against it, so noise in black corners does not trigger refinement.
REFINE_FLOOR_REL = 0.05
LUMINANCE = np.array(REC709_LUMINANCE)


def refine_mask(patches: patching.Patches, radiosity: np.ndarray, corner: np.ndarray,
                boundary: np.ndarray, emitted: np.ndarray, threshold: float,
                level: np.ndarray | None = None) -> np.ndarray:
    """(N,) bool: patches to split. A patch is split when a corner's smoothed value differs from
    its own value `radiosity` (N, 3) by more than `threshold` x max(its level's luminance,
    REFINE_FLOOR_REL x the area-weighted mean level), or when it straddles a light's shadow
    boundary. `level` (N, 3): what the difference is measured against (default the value itself).
    Emitters are never split."""
    y = radiosity @ LUMINANCE  # (N,)
    yc = corner @ LUMINANCE  # (N, 3)
    lev = y if level is None else level @ LUMINANCE
    mean = float(np.sum(lev * patches.areas) / max(patches.areas.sum(), 1e-300))
    floor = np.maximum(lev, REFINE_FLOOR_REL * mean)
    deviation = np.abs(yc - y[:, None]).max(axis=1) / np.maximum(floor, 1e-300)
    return ((deviation > threshold) | boundary) & ~np.any(emitted > 0.0, axis=1)


def first_splits(wanted: np.ndarray, emitted: np.ndarray, areas: np.ndarray,
                 room: int) -> np.ndarray:
    """(N,) bool: the patches split before the solve: those `wanted` (across a hard shadow edge,
    `shadow_edges`; in a near field, `near_field.near_field`), never an emitter, the largest
    first when there is room for fewer splits than that (`room`: (max_patches - patches) // 3,
    each split adding three). emitted (N, 3); areas (N,) m^2."""
    mask = wanted & ~np.any(emitted > 0.0, axis=1)
    room = max(room, 0)
    if room >= mask.sum():
        return mask
    keep = np.argsort(-np.where(mask, areas, -np.inf), kind="stable")[:room]
    out = np.zeros_like(mask)
    out[keep] = True
    return out


def refine_splits(patches: patching.Patches, b: np.ndarray, emitted: np.ndarray, rho: np.ndarray,
                  direct: np.ndarray, boundary: np.ndarray, settings: RadiositySettings,
                  scale: float) -> np.ndarray:
    """(N,) bool: the patches the next level splits (`refine_mask` within `max_patches`).

    Without the final gather the patches are what is shown, and they are refined where B is not
    smooth and across shadow boundaries. With it every receiver gathers its own direct light, and
    the patches carry only the indirect part, rho x (what arrived - the first shot): that is the
    field refined, against the patch's whole B (a steep indirect gradient under a bright direct
    light does not show), and shadow boundaries of the direct light need no split."""
    if settings.final_gather:
        field = np.maximum(b - emitted - rho * direct, 0.0)
        boundary = np.zeros_like(boundary)
    else:
        field = b
    corner = patching.corner_values(patches, field, settings.smooth_angle, scale)
    mask = refine_mask(patches, field, corner, boundary, emitted, settings.refine_threshold,
                       level=b)
    return within_budget(mask, field, corner, settings.max_patches)


def within_budget(mask: np.ndarray, radiosity: np.ndarray, corner: np.ndarray,
                  max_patches: int) -> np.ndarray:
    """`mask` (N,) cut to the splits that keep the patches at most `max_patches` (each split adds
    three), keeping those whose corners differ most from their own B (relative)."""
    room = max(max_patches - len(mask), 0) // 3
    if room >= mask.sum():
        return mask
    y = radiosity @ LUMINANCE
    score = np.abs(corner @ LUMINANCE - y[:, None]).max(axis=1) / np.maximum(y, 1e-300)
    keep = np.argsort(-np.where(mask, score, -np.inf))[:room]
    out = np.zeros_like(mask)
    out[keep] = True
    return out
