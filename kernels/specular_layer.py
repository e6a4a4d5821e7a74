"""The Principled BSDF's specular layer: how much of the diffuse base it hides.

Cycles (Blender 4.0 on) lays a dielectric GGX lobe over the Principled diffuse base and weighs
the base by one minus the layer's directional albedo, seen from the direction the surface is
looked at (energy conservation: what the layer reflects the base never receives):

    diffuse colour = base x (1 - metallic) x (1 - transmission) x (1 - E(mu))

    E(mu) = integral over the outgoing hemisphere of f_spec(i, o) cos(theta_o) do,
    f_spec = D(h) G2(i, o) F(i.h) / (4 cos(theta_i) cos(theta_o))        (single scattering)

with D the GGX (Trowbridge-Reitz) distribution of alpha = roughness^2, G2 Smith's
height-correlated masking-shadowing 1 / (1 + Lambda(i) + Lambda(o)), F the exact dielectric
Fresnel reflectance (`optics.fresnel_dielectric`) and mu = cos(theta_i). A bake looks at every
texel along its normal (mu = 1: `addon/cycles_reference.py`, "albedo()"). "Specular IOR Level"
s scales the layer's normal-incidence reflectance F0 = ((ior - 1) / (ior + 1))^2 by 2 s (0.5:
none, 0: no layer, exactly Lambertian), through the IOR that has that F0.

Measured against Cycles 5.2.3 (ALBEDO bakes of a plane of IOR 1.5, level 0.5), the base is
darkened by 4.0% at roughness 0, 3.7% at 0.5 and 1.4% at 1; this integral gives 4.0%, 3.70% and
1.27% (tests/kernels/test_specular_layer.py).

Substituting the half vector (do = 4 (o.h) dh) and GGX's own distribution of it
(D(h) cos(theta_h) dh = du dphi / 2 pi, tan^2 theta_h = alpha^2 u / (1 - u)) turns E into an
integral over the unit square whose integrand is smooth at every roughness, 0 included:

    E(mu) = integral of G2(i, o) F(i.h) (i.h) / (mu cos(theta_h)) du dphi / (2 pi)
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .optics import fresnel_dielectric

# Midpoint-rule points of the (u, phi) square: within 3e-4 (absolute) of 512 x 256 points at
# roughness 0.1 to 1 and mu 0.2 to 1 (64 x 32: 4e-4).
U_STEPS = 128
PHI_STEPS = 64


def layer_f0(ior: float, level: float) -> float:
    """Normal-incidence reflectance of the layer: ((ior - 1) / (ior + 1))^2 x 2 level, at most 1."""
    base = ((ior - 1.0) / (ior + 1.0)) ** 2
    return float(min(max(base * 2.0 * level, 0.0), 1.0))


def _smith_lambda(cos_theta: np.ndarray, alpha: float) -> np.ndarray:
    """GGX's Smith Lambda for directions at cos_theta (> 0) from the normal."""
    cos2 = np.maximum(cos_theta * cos_theta, 1e-300)
    return 0.5 * (np.sqrt(1.0 + alpha * alpha * (1.0 - cos2) / cos2) - 1.0)


@lru_cache(maxsize=256)
def directional_albedo(mu: float, roughness: float, f0: float) -> float:
    """E(mu) in [0, 1] (module docstring) for a view at cos(theta_i) = mu in (0, 1], Blender
    roughness in [0, 1] and layer F0 in [0, 1). 0 when f0 is 0 (no layer)."""
    if f0 <= 0.0:
        return 0.0
    mu = float(np.clip(mu, 1e-4, 1.0))
    alpha = float(np.clip(roughness, 0.0, 1.0)) ** 2
    root = np.sqrt(min(f0, 1.0 - 1e-9))
    eta = (1.0 + root) / (1.0 - root)  # the IOR whose F0 this is
    u = (np.arange(U_STEPS) + 0.5) / U_STEPS
    phi = (np.arange(PHI_STEPS) + 0.5) / PHI_STEPS * 2.0 * np.pi
    tan2 = alpha * alpha * u / (1.0 - u)
    cos_h = 1.0 / np.sqrt(1.0 + tan2)[:, None]  # (U, 1)
    sin_h = np.sqrt(1.0 - cos_h * cos_h)
    view = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
    h = np.stack(np.broadcast_arrays(sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h), axis=-1)
    i_dot_h = h @ view  # (U, PHI)
    out_z = 2.0 * i_dot_h * h[..., 2] - mu  # cos(theta_o) of the mirrored direction
    above = (out_z > 0.0) & (i_dot_h > 0.0)
    g2 = 1.0 / (1.0 + _smith_lambda(np.full_like(out_z, mu), alpha)
                + _smith_lambda(np.where(above, out_z, 1.0), alpha))
    fresnel = fresnel_dielectric(np.where(above, i_dot_h, 1.0), 1.0 / eta)
    terms = np.where(above, g2 * fresnel * i_dot_h / (mu * cos_h), 0.0)
    return float(terms.mean())


def diffuse_factor(material, mu: float = 1.0) -> float:
    """1 - E(mu): the share of the Principled diffuse base a surface of `material` (its
    roughness, ior and `specular` level) shows seen at cos(theta) = mu; 1 without a layer."""
    f0 = layer_f0(material.ior, material.specular)
    return 1.0 - directional_albedo(float(mu), float(material.roughness), f0)
