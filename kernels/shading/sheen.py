"""Sheen: the soft rim light of cloth, velvet and dust, as Cycles' two models draw it.

**Microfiber** (the Principled BSDF's Sheen, the Sheen BSDF's default) is Zeltner, Burley and
Chiang's "Practical Multiple-Scattering Sheen Using Linearly Transformed Cosines" (2022): a
volume of fibres over the surface, fitted per view angle and roughness by a clamped cosine
transformed by the matrix [[a, 0, b], [0, a, 0], [0, 0, 1]] and scaled by the layer's albedo R:

    f(v, l) cos(theta_l) = R(mu_v, r) D(l),   D(l) = z / pi x (a / |M^-1 l|^2)^2

in the frame (T, B, n), T the view's direction along the surface, with l = (x, y, z) there and
|M^-1 l|^2 = (a x + b z)^2 + (a y)^2 + z^2 (a = 1, b = 0: Lambert). a, b and R come from the
authors' fitted 32 x 32 tables, which Cycles ships (`sheen_ltc.npy`: planes a, b, R; rows the
roughness in [0, 1], columns mu_v = cos(theta_v) in [0, 1]; bilinear look-up, as Cycles reads
them). The Principled sheen is a layer: what lies under it (coat, specular layer, base,
emission) keeps 1 - max over channels of weight x tint x R(mu_v).

**Ashikhmin velvet** (the Sheen BSDF's "Ashikhmin"; Blender 2.x-3.x's Velvet BSDF, which old
glTF importers added to the surface): Ashikhmin, Premoze and Shirley's microfacet model with
the inverted-Gaussian fibre distribution of width sigma,

    D(h) = exp(-cot^2(theta_h) / sigma^2) / (pi sigma^2 sin^4(theta_h)),
    f(v, l) cos(theta_l) = D G / (4 cos(theta_v)),   G = min(1, 2 (n.h)/(v.h) cos(theta_v),
                                                             2 (n.h)/(v.h) cos(theta_l)).

Both are diffuse-labelled in Cycles (no ray continues off them in the Whitted model): lamps
light them directly.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

# (3, 32, 32) float32: a, b and R; rows roughness 0..1, columns mu_v 0..1 (Zeltner et al. 2022,
# as Blender's intern/cycles/scene/shader.tables holds them, Apache-2.0).
SHEEN_LTC = np.load(Path(__file__).with_name("sheen_ltc.npy"))
# Cycles clamps the microfiber roughness to [1e-3, 1] and drops the lobe where the fit has no
# transform or no albedo (the smoothest rows at grazing views).
MIN_SHEEN_ROUGHNESS = 1e-3
LTC_CUTOFF = 1e-5
# The velvet's sigma floor (Cycles: no narrower fibre distribution) and the half vector's
# limits, where D's cot^2 / sin^4 would divide by zero.
MIN_VELVET_SIGMA = 0.01
VELVET_EDGE = 1e-5


def ltc_table(plane: int, mu_v: np.ndarray, roughness: np.ndarray) -> np.ndarray:
    """(N,) the fitted table `plane` (0: a, 1: b, 2: R) at view cosines mu_v and roughness
    (N,), each clamped to [0, 1]: bilinear between the 32 x 32 entries."""
    table = SHEEN_LTC[plane]
    size = table.shape[0]
    x = np.clip(mu_v, 0.0, 1.0) * (size - 1)
    y = np.clip(roughness, 0.0, 1.0) * (size - 1)
    i, j = np.minimum(x.astype(int), size - 2), np.minimum(y.astype(int), size - 2)
    fx, fy = x - i, y - j
    row0 = table[j, i] * (1.0 - fx) + table[j, i + 1] * fx
    row1 = table[j + 1, i] * (1.0 - fx) + table[j + 1, i + 1] * fx
    return row0 * (1.0 - fy) + row1 * fy


def microfiber_albedo(mu_v: np.ndarray, roughness: np.ndarray) -> np.ndarray:
    """(N,) R: the microfiber layer's directional albedo at view cosines mu_v (N,), 0 where
    Cycles drops the lobe."""
    rough = np.clip(roughness, MIN_SHEEN_ROUGHNESS, 1.0)
    a, albedo = ltc_table(0, mu_v, rough), ltc_table(2, mu_v, rough)
    return np.where((np.abs(a) >= LTC_CUTOFF) & (albedo >= LTC_CUTOFF), albedo, 0.0)


def microfiber(n: np.ndarray, to_light: np.ndarray, to_eye: np.ndarray,
               roughness: np.ndarray) -> np.ndarray:
    """(N,) f cos(theta_l) of the microfiber sheen (albedo included) for unit normals, directions
    to the light and to the eye (N, 3) and roughness (N,) in [0, 1]."""
    mu_v = np.einsum("ij,ij->i", n, to_eye)
    rough = np.clip(roughness, MIN_SHEEN_ROUGHNESS, 1.0)
    a, b = ltc_table(0, mu_v, rough), ltc_table(1, mu_v, rough)
    albedo = microfiber_albedo(mu_v, roughness)
    # T: the view's direction along the surface (any tangent where the view is the normal: the
    # lobe is then symmetric about n, b = 0 there)
    t = to_eye - mu_v[:, None] * n
    t_len = np.linalg.norm(t, axis=1)
    other = np.where(np.abs(n[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    fallback = other - np.einsum("ij,ij->i", other, n)[:, None] * n
    t = np.where((t_len > 1e-6)[:, None], t / np.maximum(t_len, 1e-12)[:, None],
                 fallback / np.linalg.norm(fallback, axis=1, keepdims=True))
    z = np.einsum("ij,ij->i", n, to_light)
    x = np.einsum("ij,ij->i", t, to_light)
    y2 = np.clip(1.0 - x * x - z * z, 0.0, None)
    len2 = (a * x + b * z) ** 2 + a * a * y2 + z * z
    d = z / np.pi * (a / np.maximum(len2, 1e-12)) ** 2
    return np.where(z > 0.0, albedo * d, 0.0)


def velvet(n: np.ndarray, to_light: np.ndarray, to_eye: np.ndarray,
           sigma: np.ndarray) -> np.ndarray:
    """(N,) f cos(theta_l) of Ashikhmin's velvet for unit normals, directions to the light and to
    the eye (N, 3) and fibre widths sigma (N,) (the node's Roughness)."""
    inv_s2 = 1.0 / np.maximum(sigma, MIN_VELVET_SIGMA) ** 2
    cos_v = np.einsum("ij,ij->i", n, to_eye)
    cos_l = np.einsum("ij,ij->i", n, to_light)
    h = to_light + to_eye
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    cos_h = np.einsum("ij,ij->i", n, h)
    cos_hv = np.abs(np.einsum("ij,ij->i", to_eye, h))
    valid = (cos_v > 0.0) & (cos_l > 0.0) & (np.abs(cos_h) < 1.0 - VELVET_EDGE) \
        & (cos_hv > VELVET_EDGE)
    ratio = np.maximum(cos_h / np.maximum(cos_hv, VELVET_EDGE), VELVET_EDGE)
    g = np.minimum(1.0, np.minimum(2.0 * np.abs(ratio * cos_v), 2.0 * np.abs(ratio * cos_l)))
    sin2 = np.maximum(1.0 - cos_h * cos_h, VELVET_EDGE)
    d = np.exp(-cos_h * cos_h / sin2 * inv_s2) * inv_s2 / (np.pi * sin2 * sin2)
    return np.where(valid, 0.25 * d * g / np.maximum(cos_v, VELVET_EDGE), 0.0)


@dataclass(frozen=True, eq=False)
class Fabric:
    """The sheen at N hits.

    | field     | shape | meaning                                                          |
    |-----------|-------|------------------------------------------------------------------|
    | color     | (N, 3)| weight x tint (0: no sheen there)                                |
    | roughness | (N,)  | microfiber roughness in [0, 1], or the velvet's sigma            |
    | velvet    | (N,)  | bool: Ashikhmin's velvet, else the microfiber                    |
    | layer     | (N,)  | bool: a Principled layer over the rest, else added beside it     |
    """

    color: np.ndarray
    roughness: np.ndarray
    velvet: np.ndarray
    layer: np.ndarray

    @cached_property
    def present(self) -> np.ndarray:
        """(N,) bool: the hits with a sheen (found once: the area lights' blocks each ask)."""
        return self.color.max(axis=1) > 0.0

    def take(self, rows: np.ndarray) -> Fabric:
        """The sheen at hits `rows` only."""
        return Fabric(self.color[rows], self.roughness[rows], self.velvet[rows], self.layer[rows])

    def brdf_cos(self, rows: np.ndarray, n: np.ndarray, to_light: np.ndarray,
                 to_eye: np.ndarray) -> np.ndarray:
        """(k, 3) colour x f cos(theta_l) at hits `rows` (k,) with unit shading normals and
        directions to the light and to the eye (k, 3): a lamp of irradiance E (cosine included)
        adds this times E / cos(theta_l)."""
        fuzz, rough = self.velvet[rows], self.roughness[rows]
        f = np.empty(len(rows))
        f[~fuzz] = microfiber(n[~fuzz], to_light[~fuzz], to_eye[~fuzz], rough[~fuzz])
        f[fuzz] = velvet(n[fuzz], to_light[fuzz], to_eye[fuzz], rough[fuzz])
        return self.color[rows] * f[:, None]

    def under(self, mu_v: np.ndarray) -> np.ndarray:
        """(N,) what a layered sheen leaves of the light of what lies under it, seen at view
        cosines mu_v (N,): 1 - max over channels of colour x R(mu_v) (Cycles' layering); 1
        where the sheen is added beside the surface or absent."""
        albedo = self.color * microfiber_albedo(mu_v, self.roughness)[:, None]
        return np.where(self.layer, np.clip(1.0 - albedo.max(axis=1), 0.0, 1.0), 1.0)
