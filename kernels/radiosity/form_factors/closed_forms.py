"""Closed-form factors: Howell's catalogue (C-11, C-14, point and disk to coaxial disk; formulas in
tests/data/form_factors.json), the ground truth of the tests, and Wallace's disc approximation."""

from __future__ import annotations

import math

import numpy as np


def parallel_rectangles(a, b, c):
    """Howell C-11: identical, directly opposed, parallel a x b rectangles at distance c.

    Arguments broadcast (metres, > 0). Returns F12 (float64 array or scalar), dimensionless.
    """
    x = np.asarray(a, np.float64) / np.asarray(c, np.float64)
    y = np.asarray(b, np.float64) / np.asarray(c, np.float64)
    x2, y2 = x * x, y * y
    sx, sy = np.sqrt(1.0 + x2), np.sqrt(1.0 + y2)
    bracket = (
        0.5 * np.log((1.0 + x2) * (1.0 + y2) / (1.0 + x2 + y2))
        + x * sy * np.arctan(x / sy)
        + y * sx * np.arctan(y / sx)
        - x * np.arctan(x)
        - y * np.arctan(y)
    )
    return 2.0 / (math.pi * x * y) * bracket


def perpendicular_rectangles(w, h, l):  # noqa: E741 - Howell's names
    """Howell C-14: from a w x l rectangle to a perpendicular h x l one sharing the edge l.

    Arguments broadcast (metres, > 0). Returns F12 (from the w x l rectangle), dimensionless. The
    logarithm's powers W^2 and H^2 are taken as products of logarithms (no overflow for long l).
    """
    l = np.asarray(l, np.float64)  # noqa: E741
    big_h = np.asarray(h, np.float64) / l
    big_w = np.asarray(w, np.float64) / l
    h2, w2 = big_h * big_h, big_w * big_w
    s = np.sqrt(h2 + w2)
    log_term = (
        np.log((1.0 + w2) * (1.0 + h2) / (1.0 + w2 + h2))
        + w2 * np.log(w2 * (1.0 + w2 + h2) / ((1.0 + w2) * (w2 + h2)))
        + h2 * np.log(h2 * (1.0 + w2 + h2) / ((1.0 + h2) * (w2 + h2)))
    )
    bracket = (
        big_w * np.arctan(1.0 / big_w)
        + big_h * np.arctan(1.0 / big_h)
        - s * np.arctan(1.0 / s)
        + 0.25 * log_term
    )
    return bracket / (math.pi * big_w)


def element_to_disk(h, r, tilt=0.0):
    """Differential element on the axis of a disk of radius r at distance h, facing it.

    `tilt` (radians) turns the element's normal away from the axis; valid while the disk stays
    entirely above the element's horizon (tan(tilt) <= h / r). Returns cos(tilt) r^2/(r^2 + h^2).
    """
    h = np.asarray(h, np.float64)
    r = np.asarray(r, np.float64)
    return np.cos(tilt) * r * r / (r * r + h * h)


def disk_to_disk(r1, r2, h):
    """Coaxial parallel disks, radii r1 (from) and r2 (to), at distance h. Returns F12."""
    big_r1 = np.asarray(r1, np.float64) / np.asarray(h, np.float64)
    big_r2 = np.asarray(r2, np.float64) / np.asarray(h, np.float64)
    x = 1.0 + (1.0 + big_r2 * big_r2) / (big_r1 * big_r1)
    return 0.5 * (x - np.sqrt(x * x - 4.0 * (big_r2 / big_r1) ** 2))


def disc_form(dist2: np.ndarray, cos_x: np.ndarray, cos_y: np.ndarray, area) -> np.ndarray:
    """(...) Wallace's disc approximation of the factor from a point x to a patch of `area` m^2
    whose centre is d away (Wallace, Elmquist and Haines 1989):
    A cos_x cos_y / (pi d^2 + A), exact for a disc seen head on, 0 where either faces away.
    dist2 = d^2; cos_x, cos_y: the cosines at x and at the patch, each times d (the dot
    products with the unnormalised direction), broadcastable together."""
    return np.divide(area * cos_x * cos_y, dist2 * (np.pi * dist2 + area),
                     out=np.zeros(np.broadcast_shapes(np.shape(dist2), np.shape(cos_x),
                                                      np.shape(cos_y), np.shape(area))),
                     where=(cos_x > 0.0) & (cos_y > 0.0))
