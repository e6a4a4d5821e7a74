"""Kernel-weighted visible shares by shadow rays: each ray between two points counts with the
point-to-point kernel cos_x cos_y / d^2, so the estimate converges to the visible share of the
projected solid angle. The generators ask for their rays (`rays.RayRequest`)."""

from __future__ import annotations

import numpy as np

from .rays import RayRequests

# Shadow rays of method B stop this fraction of their length short of the target point, so the
# target's own surface is never its occluder even with ray_offset = 0 (float32 t rounding is 6e-8).
SHADOW_END_REL = 1e-6


def pair_kernel(between: np.ndarray, nx: np.ndarray, ny: np.ndarray) -> np.ndarray:
    """(...) the point-to-point kernel cos_x cos_y / d^2 of point pairs `between` (..., 3) = y - x
    apart (m), unit normals nx at x and ny at y broadcastable to it; 0 where either faces away."""
    dist2 = np.einsum("...c,...c->...", between, between)
    cos_x = np.einsum("...c,...c->...", between, nx)  # times d: d^4 below divides both out
    cos_y = -np.einsum("...c,...c->...", between, ny)
    return np.where((cos_x > 0.0) & (cos_y > 0.0),
                    cos_x * cos_y / np.maximum(dist2 * dist2, np.finfo(np.float64).tiny), 0.0)


def paired_share_steps(x, nx, y, ny, weight, ray_offset: float) -> RayRequests:
    """Generator asking for its shadow rays (see `RayRequest`); returns (L,) the visible share of
    L sets of point pairs: points x (L, S, 3) with unit normals nx, targets y (L, S, 3) with ny
    (normals broadcastable to the points), one ray per pair between copies lifted by
    `ray_offset` m along the normals. Each ray counts with the point-to-point kernel
    cos_x cos_y / d^2 times its weight (L, S), so a target behind either horizon carries no
    weight instead of counting as blocked; 1 where no pair of a set has weight."""
    kernel = pair_kernel(y - x, nx, ny) * weight  # (L, S)
    start = np.broadcast_to(x + ray_offset * nx, y.shape)
    seg = (y + ray_offset * ny - start).reshape(-1, 3)
    length = np.sqrt(np.einsum("ij,ij->i", seg, seg))
    rays = np.flatnonzero((kernel.ravel() > 0.0) & (length > 0.0))
    blocked = np.zeros(seg.shape[0], bool)
    if rays.size:
        blocked[rays] = yield (start.reshape(-1, 3)[rays], seg[rays] / length[rays, None],
                               length[rays] * (1.0 - SHADOW_END_REL))
    total = kernel.sum(axis=1)
    seen = np.where(blocked.reshape(kernel.shape), 0.0, kernel).sum(axis=1)
    return np.divide(seen, total, out=np.ones_like(total), where=total > 0.0)


def visible_fraction_steps(x, nx, y, wy, nj, ray_offset: float) -> RayRequests:
    """Generator asking for its shadow rays (see `RayRequest`); returns the (S, J) kernel-weighted
    visible fraction of J polygons from S points x (normals nx); y (J, M, 3), wy (J, M): the
    polygons' visibility points and weights, nj (J, 3) normals."""
    # The kernel from the surface points themselves; the rays between lifted copies of them.
    tiny = np.finfo(np.float64).tiny
    between = y[None] - x[:, None, None, :]  # (S, J, M, 3)
    dist = np.maximum(np.sqrt(np.einsum("sjmc,sjmc->sjm", between, between)), tiny)
    cos_x = np.einsum("sjmc,sc->sjm", between, nx) / dist
    cos_y = -np.einsum("sjmc,jc->sjm", between, nj) / dist
    kernel = np.where((cos_x > 0.0) & (cos_y > 0.0), cos_x * cos_y / (dist * dist), 0.0)
    kernel *= wy[None]
    origin = x + ray_offset * nx  # (S, 3)
    seg = (y + ray_offset * nj[:, None, :])[None] - origin[:, None, None, :]  # (S, J, M, 3)
    length = np.sqrt(np.einsum("sjmc,sjmc->sjm", seg, seg))
    safe = np.maximum(length, tiny)
    rays = np.flatnonzero(kernel.ravel() > 0.0)
    blocked = np.zeros(kernel.size, bool)
    if rays.size:
        dirs = (seg / safe[..., None]).reshape(-1, 3)[rays]
        origins = np.broadcast_to(origin[:, None, None, :], seg.shape).reshape(-1, 3)[rays]
        blocked[rays] = yield origins, dirs, length.ravel()[rays] * (1.0 - SHADOW_END_REL)
    total = kernel.sum(axis=2)
    seen = np.where(blocked.reshape(kernel.shape), 0.0, kernel).sum(axis=2)
    return np.divide(seen, total, out=np.zeros_like(total), where=total > 0.0)
