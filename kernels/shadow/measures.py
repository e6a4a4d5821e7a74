"""Pictures of shadow maps and measures of their failures: acne and peter-panning."""

from __future__ import annotations

import numpy as np

from .shadowmap import ShadowMap


def debug_image(shadow_map: ShadowMap) -> np.ndarray:
    """(H, W, 1) float32 picture of the map: depth scaled to [0, 1] over its finite texels,
    1 where nothing was drawn; a cube map is its six faces side by side in face order."""
    depth = np.concatenate([v.depth for v in shadow_map.views], axis=1).astype(np.float64)
    finite = np.isfinite(depth)
    image = np.ones_like(depth)
    if finite.any():
        lo, hi = depth[finite].min(), depth[finite].max()
        image[finite] = (depth[finite] - lo) / (hi - lo) if hi > lo else 0.0
    return image[..., None].astype(np.float32)


def acne_fraction(
    visibility: np.ndarray, truth: np.ndarray, tolerance: float = 0.5,
    mask: np.ndarray | None = None,
) -> float:
    """Fraction of truly lit receivers (truth >= 0.5) reported darker than truth - tolerance.

    tolerance 0.5 counts receivers a binary test calls shadowed; a small tolerance counts any
    darkening (then exclude the PCF penumbra with `mask`, (N,) bool of receivers to consider).
    """
    lit = np.asarray(truth) >= 0.5
    if mask is not None:
        lit &= np.asarray(mask, bool)
    if not lit.any():
        return 0.0
    wrong = np.asarray(visibility)[lit] < np.asarray(truth)[lit] - tolerance
    return float(wrong.mean())


def peter_panning_gap(
    points: np.ndarray, visibility: np.ndarray, truth: np.ndarray, threshold: float = 0.5
) -> float:
    """How far a shadow comes loose from its caster, m (0: attached; inf: shadow gone).

    Leaked receivers are truly shadowed (truth < threshold) but reported lit; the gap is the largest
    distance from a leaked receiver to the nearest receiver shadowed in both, i.e. the width of the
    lit strip between a caster's contact and where its shadow starts (plus up to a texel of edge
    quantisation). Brute force, O(leaked x shadowed): meant for test- and sweep-sized point sets.
    """
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    vis, tru = np.asarray(visibility), np.asarray(truth)
    leaked = pts[(tru < threshold) & (vis >= threshold)]
    held = pts[(tru < threshold) & (vis < threshold)]
    if len(leaked) == 0:
        return 0.0
    if len(held) == 0:
        return float("inf")
    gap = 0.0
    step = max(1, (1 << 22) // len(held))  # ~4M distances (32 MB) at a time
    for a in range(0, len(leaked), step):
        d2 = ((leaked[a : a + step, None, :] - held[None, :, :]) ** 2).sum(axis=2)
        gap = max(gap, float(np.sqrt(d2.min(axis=1).max())))
    return gap
