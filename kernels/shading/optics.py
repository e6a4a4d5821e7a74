"""Mirror reflection, refraction by Snell's law, and Fresnel reflectance: the ray tracer's optics.

All functions are vectorised over N rays: directions (N, 3) unit, normals (N, 3) unit, cosines (N,).
Conventions follow GLSL: an incident direction `d` points TOWARDS the surface, the normal `n` faces
the side the ray comes from (n . d <= 0), and `eta` is n_from / n_to.
"""

from __future__ import annotations

import numpy as np


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror direction r = d - 2 (d . n) n. (N, 3) each."""
    return d - 2.0 * np.einsum("ij,ij->i", d, n)[:, None] * n


def refract(d: np.ndarray, n: np.ndarray, eta: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Snell's law: (transmitted directions (N, 3) unit, total internal reflection mask (N,)).

    k = 1 - eta^2 (1 - (n . d)^2); k < 0 is total internal reflection (direction zeroed there);
    otherwise t = eta d - (eta (n . d) + sqrt(k)) n.
    """
    eta = np.broadcast_to(np.asarray(eta, np.float64), (d.shape[0],))
    cos_i = np.einsum("ij,ij->i", n, d)
    k = 1.0 - eta * eta * (1.0 - cos_i * cos_i)
    tir = k < 0.0
    root = np.sqrt(np.where(tir, 0.0, k))
    t = eta[:, None] * d - (eta * cos_i + root)[:, None] * n
    t[tir] = 0.0
    return t, tir


def fresnel_dielectric(cos_i: np.ndarray, eta: np.ndarray | float) -> np.ndarray:
    """Unpolarised Fresnel reflectance of a smooth dielectric boundary.

    cos_i (N,): cosine of the incidence angle (sign ignored); eta: n_from / n_to.
    Returns R (N,) in [0, 1]; 1 under total internal reflection. Exact: the mean of the s and p
    reflectances (Born & Wolf), e.g. R = 0.04 at normal incidence for air -> glass n = 1.5.
    """
    cos_i = np.clip(np.abs(np.asarray(cos_i, np.float64)), 0.0, 1.0)
    eta = np.asarray(eta, np.float64)
    sin_t2 = eta * eta * (1.0 - cos_i * cos_i)
    tir = sin_t2 >= 1.0
    cos_t = np.sqrt(np.clip(1.0 - sin_t2, 0.0, 1.0))
    # With eta = n1/n2: rs = (eta cos_i - cos_t)/(eta cos_i + cos_t), rp = (cos_i - eta cos_t)/(...).
    rs = (eta * cos_i - cos_t) / np.maximum(eta * cos_i + cos_t, 1e-300)
    rp = (cos_i - eta * cos_t) / np.maximum(cos_i + eta * cos_t, 1e-300)
    return np.where(tir, 1.0, 0.5 * (rs * rs + rp * rp))


def fresnel_schlick(cos_i: np.ndarray, f0: np.ndarray) -> np.ndarray:
    """Schlick's approximation F0 + (1 - F0)(1 - cos)^5; f0 (N, 3) or (3,) -> (N, 3).

    With Principled's default specular tint this is exactly Cycles' F82-tint metal Fresnel.
    """
    c = (1.0 - np.clip(np.abs(cos_i), 0.0, 1.0)) ** 5
    f0 = np.asarray(f0, np.float64)
    return f0 + (1.0 - f0) * c[:, None]


# The F82-tint model's angle: cos = 1/7 (about 81.8 degrees), where the tint scales Schlick's
# reflectance (Hoffman 2019, as Cycles' metals take it).
F82_COS = 1.0 / 7.0


def f82_factor(f0: np.ndarray, tint: np.ndarray) -> np.ndarray:
    """(..., 3) b of the F82-tint Fresnel, F(cos) = Schlick(cos) - b cos (1 - cos)^6, for F0 and
    tint (..., 3): chosen so F(F82_COS) = tint x Schlick(F82_COS); 0 for a white tint."""
    f = 1.0 - F82_COS
    f0 = np.asarray(f0, np.float64)
    schlick = f0 + (1.0 - f0) * f**5
    return schlick * (1.0 - np.asarray(tint, np.float64)) / (F82_COS * f**6)


def fresnel_f82(cos_i: np.ndarray, f0: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 3) the F82-tint Fresnel of a metal: Schlick's less b cos (1 - cos)^6 (`f82_factor`),
    within [0, 1]; cos_i (N,), f0 and b (N, 3)."""
    c = np.clip(np.abs(cos_i), 0.0, 1.0)
    return np.clip(fresnel_schlick(c, f0) - np.asarray(b) * (c * (1.0 - c) ** 6)[:, None], 0.0, 1.0)


def critical_angle(n_inside: float, n_outside: float = 1.0) -> float:
    """Angle (rad) beyond which light inside a medium of `n_inside` is totally reflected."""
    return float(np.arcsin(n_outside / n_inside))
