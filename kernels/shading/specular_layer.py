"""The Principled BSDF's specular layer: how much of the diffuse base it hides.

Cycles (Blender 4.0 on) lays a dielectric GGX lobe over the Principled diffuse base and weighs
the base by one minus the layer's directional albedo, seen from the direction the surface is
looked at (energy conservation: what the layer reflects the base never receives):

    diffuse colour = base x (1 - metallic) x (1 - transmission) x (1 - E(mu))

    E(mu) = k(mu) x integral over the outgoing hemisphere of f_spec(i, o) cos(theta_o) do,
    f_spec = D(h) G2(i, o) F(i.h) / (4 cos(theta_i) cos(theta_o))        (single scattering)

with D the GGX (Trowbridge-Reitz) distribution of alpha = roughness^2, G2 Smith's
height-correlated masking-shadowing 1 / (1 + Lambda(i) + Lambda(o)), F the exact dielectric
Fresnel reflectance (`optics.fresnel_dielectric`) and mu = cos(theta_i). k
(`energy_compensation`) restores the light that scatters more than once among the microfacets,
as Cycles' GGX does (Kulla and Conty 2017): a lobe of F = 1 then reflects everything, so a layer
of F0 = 1 (an IOR of 0) hides the base. A bake looks at every texel along its normal (mu = 1:
`addon/cycles/models.py`, "albedo()"). "Specular IOR Level" s scales the layer's
normal-incidence reflectance F0 = ((ior - 1) / (ior + 1))^2 by 2 s (0.5: none, 0: no layer,
exactly Lambertian), through the IOR that has that F0.

Measured against Cycles 5.2.3 (ALBEDO bakes of a plane of IOR 1.5, level 0.5), the base is
darkened by 4.0% at roughness 0, 3.7% at 0.5 and 1.4% at 1; this gives 4.0%, 3.73% and 1.38%
(1.27% in single scattering alone; tests/kernels/test_specular_layer.py).

Substituting the half vector (do = 4 (o.h) dh) and GGX's own distribution of it
(D(h) cos(theta_h) dh = du dphi / 2 pi, tan^2 theta_h = alpha^2 u / (1 - u)) turns E into an
integral over the unit square whose integrand is smooth at every roughness, 0 included:

    E(mu) = k(mu) x integral of G2(i, o) F(i.h) (i.h) / (mu cos(theta_h)) du dphi / (2 pi)
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from .highlight_spread import (
    NormalFootprint,
    sample_roughness,
    sub_normals,
    sub_sides,
    widened_roughness,
)
from .optics import f82_factor, fresnel_dielectric, fresnel_f82, fresnel_schlick

# Midpoint-rule points of the (u, phi) square: within 3e-4 (absolute) of 512 x 256 points at
# roughness 0.1 to 1 and mu 0.2 to 1 (64 x 32: 4e-4).
U_STEPS = 128
PHI_STEPS = 64
# Views tabulated per material for camera views (`view_factors`), evenly in sqrt(mu), which
# spreads them where E climbs towards grazing: linear interpolation is within 1e-3 of the
# integral at roughness 0 to 1 and F0 up to 0.5 (33 views evenly in mu: 5e-3).
MU_STEPS = 65
# Below this roughness a layer is a mirror: a point light's highlight shrinks to a point that no
# pixel sees (Cycles draws none either), and the tracer follows the mirror ray instead.
MIRROR_ROUGHNESS = 0.1
# Roughness steps of the table of lobe albedos with F = 1 (`lobe_albedo`), with MU_STEPS views:
# bilinear reads are within 5e-3 of the integral between the steps at roughness 0.1 to 1 (the
# lobes lit directly), 0.065 below it at grazing views, where E falls steeply from 1.
ROUGHNESS_STEPS = 33


def layer_f0(ior: float, level: float) -> float:
    """Normal-incidence reflectance of the layer: ((ior - 1) / (ior + 1))^2 x 2 level, at most 1."""
    base = ((ior - 1.0) / (ior + 1.0)) ** 2
    return float(min(max(base * 2.0 * level, 0.0), 1.0))


def tinted_albedo(e: np.ndarray, f0: np.ndarray, tint: np.ndarray) -> np.ndarray:
    """(N, 3) (N, 1 for a scalar tint) what a layer of F0 f0 (N,) tinted by the Principled's
    Specular Tint (N, 3) reflects where its untinted albedo is e (N,): Cycles' dielectric
    Fresnel is then
    F = t F0 + (1 - t F0) s with s = (F_real - F0) / (1 - F0) (tint times F0 head on, white at
    grazing), so E - (1 - t) F0 (1 - E) / (1 - F0), exact for a smooth layer (E = F_real) and
    equal to E for a white tint; kept within [0, E], since a tint of at most 1 takes light away.
    That form takes the lobe's albedo with F = 1 as 1: under a rough layer of a huge IOR (F0
    near 1) it fell far below 0 and the base showed more than all of itself (an imported house
    of IOR 1000 and a black tint drew 1.6x Cycles' light; Cycles shows it as with IOR 1.5). The
    base under it keeps 1 - this in its largest channel, as Cycles layers them (`view_tables`).
    tint: (N, 3), or a scalar for all channels alike."""
    e = np.asarray(e, np.float64)[:, None]
    f0 = np.asarray(f0, np.float64)[:, None]
    tinted = e - (1.0 - np.asarray(tint, np.float64)) * f0 * (1.0 - e) / np.maximum(1.0 - f0, 1e-9)
    return np.clip(tinted, 0.0, e)


def layer_tints(materials) -> np.ndarray:
    """(M, 3) each material's `specular_tint` (white where it has none)."""
    return np.array([np.ones(3) if m.specular_tint is None else m.specular_tint
                     for m in materials], np.float64).reshape(-1, 3)


def _smith_lambda(cos_theta: np.ndarray, alpha: float) -> np.ndarray:
    """GGX's Smith Lambda for directions at cos_theta (> 0) from the normal."""
    cos2 = np.maximum(cos_theta * cos_theta, 1e-300)
    return 0.5 * (np.sqrt(1.0 + alpha * alpha * (1.0 - cos2) / cos2) - 1.0)


def _lobe_terms(mu: np.ndarray, roughness: float) -> tuple[np.ndarray, np.ndarray]:
    """The half-vector integrand of E (module docstring) without its Fresnel factor, on the
    (u, phi) grid for views mu (K,): terms (K, U, PHI) = G2 (i.h) / (mu cos(theta_h)), 0 where
    the mirrored direction falls below the horizon, and i.h (K, U, PHI), at which F is read.
    The mean of terms x F over the grid is E."""
    alpha = float(np.clip(roughness, 0.0, 1.0)) ** 2
    u = (np.arange(U_STEPS) + 0.5) / U_STEPS
    phi = (np.arange(PHI_STEPS) + 0.5) / PHI_STEPS * 2.0 * np.pi
    tan2 = alpha * alpha * u / (1.0 - u)
    cos_h = (1.0 / np.sqrt(1.0 + tan2))[:, None]  # (U, 1)
    sin_h = np.sqrt(1.0 - cos_h * cos_h)
    h = np.stack(np.broadcast_arrays(sin_h * np.cos(phi), sin_h * np.sin(phi), cos_h), axis=-1)
    views = np.stack([np.sqrt(1.0 - mu * mu), np.zeros_like(mu), mu], axis=1)  # (K, 3)
    i_dot_h = np.einsum("upc,kc->kup", h, views)  # (K, U, PHI)
    m = mu[:, None, None]
    out_z = 2.0 * i_dot_h * h[..., 2] - m  # cos(theta_o) of the mirrored direction
    above = (out_z > 0.0) & (i_dot_h > 0.0)
    g2 = 1.0 / (1.0 + _smith_lambda(m, alpha) + _smith_lambda(np.where(above, out_z, 1.0), alpha))
    terms = np.where(above, g2 * i_dot_h / (m * cos_h), 0.0)
    return terms, np.where(above, i_dot_h, 1.0)


def albedo_curve(mu: np.ndarray, roughness: float, f0: float) -> np.ndarray:
    """E(mu) (module docstring) at views cos(theta_i) = mu (K,) in (0, 1], Blender roughness in
    [0, 1] and layer F0 in [0, 1); all 0 when f0 is 0 (no layer). Returns (K,) in [0, 1]."""
    mu = np.clip(np.atleast_1d(np.asarray(mu, np.float64)), 1e-4, 1.0)
    if f0 <= 0.0:
        return np.zeros(mu.shape)
    root = np.sqrt(min(f0, 1.0 - 1e-9))
    eta = (1.0 + root) / (1.0 - root)  # the IOR whose F0 this is
    terms, i_dot_h = _lobe_terms(mu, roughness)
    single = (terms * fresnel_dielectric(i_dot_h, 1.0 / eta)).mean(axis=(1, 2))
    # with the light scattered more than once among the microfacets, as Cycles' lobe keeps it
    return single * energy_compensation(mu, np.full(mu.shape, float(roughness)),
                                        np.full((mu.size, 1), f0))[:, 0]


def schlick_grazing_curve(mu: np.ndarray, roughness: float) -> np.ndarray:
    """(K,) the mean over a GGX lobe (roughness, views mu (K,)) of Schlick's grazing term
    (1 - i.h)^5, weighted as the lobe reflects: a rough metal of F0 (its base colour) reflects
    F0 + (1 - F0) x this of what its lobe would with F = 1. Roughness 0: (1 - mu)^5 exactly;
    a wide lobe's microfacets see the view less obliquely, so less. Normalised by the lobe's own
    albedo (F = 1): Cycles' multiple-scattering GGX keeps the energy single scattering loses."""
    mu = np.clip(np.atleast_1d(np.asarray(mu, np.float64)), 1e-4, 1.0)
    terms, i_dot_h = _lobe_terms(mu, roughness)
    grazing = (terms * (1.0 - np.clip(i_dot_h, 0.0, 1.0)) ** 5).mean(axis=(1, 2))
    return grazing / np.maximum(terms.mean(axis=(1, 2)), 1e-300)


def f82_curve(mu: np.ndarray, roughness: float) -> np.ndarray:
    """(K,) the mean over a GGX lobe (roughness, views mu (K,)) of the F82-tint model's term
    (i.h) (1 - i.h)^6, weighted as the lobe reflects and normalised as `schlick_grazing_curve`:
    a rough metal reflects b x this less than Schlick's curve gives. Roughness 0: mu (1 - mu)^6."""
    mu = np.clip(np.atleast_1d(np.asarray(mu, np.float64)), 1e-4, 1.0)
    terms, i_dot_h = _lobe_terms(mu, roughness)
    c = np.clip(i_dot_h, 0.0, 1.0)
    return (terms * c * (1.0 - c) ** 6).mean(axis=(1, 2)) / np.maximum(
        terms.mean(axis=(1, 2)), 1e-300)


@lru_cache(maxsize=256)
def directional_albedo(mu: float, roughness: float, f0: float) -> float:
    """E(mu) at one view (`albedo_curve`), cached: a scene has few materials."""
    return float(albedo_curve(np.array([mu]), roughness, f0)[0])


def diffuse_factor(material, mu: float = 1.0) -> float:
    """1 - E(mu): the share of the Principled diffuse base a surface of `material` (its
    roughness, ior, `specular` level and tint) shows seen at cos(theta) = mu; 1 without a
    layer. A tinted layer leaves 1 - E in its largest channel (`tinted_albedo`)."""
    f0 = layer_f0(material.ior, material.specular)
    e = directional_albedo(float(mu), float(material.roughness), f0)
    return 1.0 - float(tinted_albedo(np.array([e]), np.array([f0]), _tint_max(material))[0, 0])


def view_tables(materials, tinted: bool = True) -> np.ndarray:
    """(M, MU_STEPS) per material, 1 - E(mu) at sqrt(mu) = 0, 1 / (MU_STEPS - 1), ..., 1: the
    share of the base each shows at each view (`view_factors`), under a tinted layer 1 - E in
    the tint's largest channel, as Cycles layers them (`tinted_albedo`); `tinted` False: 1 - E
    of the layer untinted, what `tinted_albedo` takes."""
    rows = [_view_table(float(m.roughness), layer_f0(m.ior, m.specular),
                        _tint_max(m) if tinted else 1.0) for m in materials]
    return np.array(rows).reshape(len(rows), MU_STEPS)


def _tint_max(material) -> float:
    return 1.0 if material.specular_tint is None else float(np.max(material.specular_tint))


@lru_cache(maxsize=64)
def _view_table(roughness: float, f0: float, tint_max: float = 1.0) -> tuple[float, ...]:
    e = albedo_curve(np.linspace(0.0, 1.0, MU_STEPS) ** 2, roughness, f0)
    return tuple(1.0 - tinted_albedo(e, np.full(e.shape, f0), tint_max)[:, 0])


def view_factors(tables: np.ndarray, material: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """(N,) 1 - E(mu) for surfaces of materials (N,) (rows of `view_tables`) seen at |cos| = mu
    (N,), linearly interpolated between the tabulated views."""
    x = np.sqrt(np.clip(np.abs(np.asarray(mu, np.float64)), 0.0, 1.0)) * (MU_STEPS - 1)
    lo = np.minimum(x.astype(np.int64), MU_STEPS - 2)
    frac = x - lo
    return tables[material, lo] * (1.0 - frac) + tables[material, lo + 1] * frac


@lru_cache(maxsize=1)
def _lobe_albedo_table() -> tuple[np.ndarray, np.ndarray]:
    """(ROUGHNESS_STEPS, MU_STEPS) E(mu) with F = 1 at roughness 0, 1 / 32, ..., 1 and
    sqrt(mu) = 0, 1 / 64, ..., 1, and (ROUGHNESS_STEPS,) its cosine-weighted mean E_avg =
    2 integral E(mu) mu dmu (= 4 integral E x^3 dx over x = sqrt(mu), trapezoids)."""
    x = np.linspace(0.0, 1.0, MU_STEPS)
    table = np.array([_lobe_terms(np.clip(x * x, 1e-4, 1.0), r)[0].mean(axis=(1, 2))
                      for r in np.linspace(0.0, 1.0, ROUGHNESS_STEPS)])
    weighted = 4.0 * table * x ** 3
    mean = ((weighted[:, 1:] + weighted[:, :-1]) * 0.5 * np.diff(x)).sum(axis=1)
    return table, mean


def lobe_albedo(mu: np.ndarray, roughness: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A GGX lobe's single-scattering albedo with F = 1, E(mu) (N,), at views |cos| = mu (N,) and
    Blender roughness (N,), and its cosine-weighted mean over views E_avg (N,) (bilinear in the
    table of `_lobe_albedo_table`)."""
    table, mean = _lobe_albedo_table()
    r = np.clip(np.asarray(roughness, np.float64), 0.0, 1.0) * (ROUGHNESS_STEPS - 1)
    r0 = np.minimum(r.astype(np.int64), ROUGHNESS_STEPS - 2)
    fr = r - r0
    x = np.sqrt(np.clip(np.abs(np.asarray(mu, np.float64)), 0.0, 1.0)) * (MU_STEPS - 1)
    x0 = np.minimum(x.astype(np.int64), MU_STEPS - 2)
    fx = x - x0
    rows = table[r0] * (1.0 - fr)[:, None] + table[r0 + 1] * fr[:, None]
    e = np.take_along_axis(rows, x0[:, None], 1)[:, 0] * (1.0 - fx) + \
        np.take_along_axis(rows, x0[:, None] + 1, 1)[:, 0] * fx
    return e, mean[r0] * (1.0 - fr) + mean[r0 + 1] * fr


def energy_compensation(mu: np.ndarray, roughness: np.ndarray, f0: np.ndarray) -> np.ndarray:
    """(N, 3) the factor Cycles scales a GGX lobe's single-scattering BRDF by to keep the light
    that scatters more than once among the microfacets (Kulla and Conty 2017; Cycles'
    `microfacet_ggx_preserve_energy`): 1 + F_ms (1 - E) / E, with E, E_avg the lobe's albedo at
    the view |cos| = mu (N,) and over views (`lobe_albedo`), F_ms = F_ss E_avg / (1 - F_ss
    (1 - E_avg)) and F_ss = F0 + (1 - F0) / 21 Schlick's mean over the hemisphere (F0 (N, 3)).
    1 at roughness 0; at roughness 1 a white metal's highlight seen head on x 3.3 (1 / E)."""
    e, e_avg = lobe_albedo(mu, roughness)
    e = np.maximum(e, 1e-3)[:, None]
    f_ss = np.asarray(f0, np.float64) + (1.0 - np.asarray(f0, np.float64)) / 21.0
    f_ms = f_ss * e_avg[:, None] / (1.0 - f_ss * (1.0 - e_avg[:, None]))
    return 1.0 + f_ms * (1.0 - e) / e


@dataclass(frozen=True)
class MetalTables:
    """Per material (M of them), what `metal_reflectance` reads: `schlick_grazing_curve` and
    `f82_curve` at sqrt(mu) = 0, ..., 1 (M, MU_STEPS) each, and the F82 tint (M, 3) (white
    where the material has none: Schlick's curve)."""

    grazing: np.ndarray
    f82: np.ndarray
    edge: np.ndarray


def metal_reflectance(tables: MetalTables, material: np.ndarray, mu: np.ndarray, f0: np.ndarray,
                      roughness: np.ndarray, smooth: np.ndarray) -> np.ndarray:
    """(N, 3) the share of the light around it a metal's lobe reflects toward a view at
    |cos| = mu (N,), F0 (N, 3) its base colour: the F82-tint Fresnel at the view where `smooth`
    (N,) bool (`optics.fresnel_f82`: Schlick's for a white tint); else F0 + (1 - F0) x the lobe's
    mean grazing term less b x its mean F82 term (`schlick_grazing_curve`, `f82_curve`; `tables`
    of `metal_tables` and rows `material` (N,)) times what Cycles' restored multiple scattering
    keeps of the lobe (E + F_ms (1 - E), `energy_compensation`: less than all for a coloured
    metal, each bounce among the facets takes its tint) at Blender roughness (N,)."""
    mu = np.asarray(mu, np.float64)
    b = f82_factor(f0, tables.edge[material])
    out = fresnel_f82(mu, f0, b)
    rows = np.flatnonzero(~np.asarray(smooth, bool))
    if rows.size:
        m, f0_r, mu_r = material[rows], f0[rows], mu[rows]
        grazing = view_factors(tables.grazing, m, mu_r)[:, None]
        edge = view_factors(tables.f82, m, mu_r)[:, None]
        e, _ = lobe_albedo(mu_r, roughness[rows])
        out[rows] = (np.clip(f0_r + (1.0 - f0_r) * grazing - b[rows] * edge, 0.0, 1.0)
                     * e[:, None] * energy_compensation(mu_r, roughness[rows], f0_r))
    return out


def ggx_highlight(n, wi, wo, roughness, f0) -> np.ndarray:
    """A glossy lobe's GGX microfacet BRDF (Trowbridge-Reitz D, separable Smith G, Schlick F) times
    cos_i, (N, 3), for unit normals n, light directions wi and view directions wo (N, 3),
    Blender roughness (N,) and F0 (N, 3), with the light scattered more than once among the
    microfacets restored as Cycles does (`energy_compensation`): a lamp's highlight is this
    times E / cos_i."""
    alpha2 = np.maximum(roughness, 1e-3) ** 4  # Blender: alpha = roughness^2
    h = wi + wo
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    cos_i = np.clip(np.einsum("ij,ij->i", n, wi), 0.0, 1.0)
    cos_o = np.clip(np.einsum("ij,ij->i", n, wo), 1e-6, 1.0)
    cos_h = np.clip(np.einsum("ij,ij->i", n, h), 0.0, 1.0)
    d = alpha2 / (np.pi * (cos_h * cos_h * (alpha2 - 1.0) + 1.0) ** 2)

    def g1(c):
        return 2.0 * c / (c + np.sqrt(alpha2 + (1.0 - alpha2) * c * c))

    g = g1(cos_i) * g1(cos_o)
    f = fresnel_schlick(np.einsum("ij,ij->i", wi, h), f0)
    kept = energy_compensation(cos_o, np.broadcast_to(roughness, cos_o.shape), f0)
    return f * kept * (d * g / (4.0 * cos_o))[:, None]


def pixel_highlight(n, wi, wo, roughness, f0, footprint: NormalFootprint | None = None
                    ) -> np.ndarray:
    """`ggx_highlight` (N, 3) averaged over each sample's footprint (`highlight_spread`): the
    BRDF about the normal at its cell's centre, the lobe widened by the footprint's spread of
    normals, or, where the lobe is far narrower than that spread, the mean of a grid of normals
    across it (`sub_sides`), each widened by its sub-cell's share; times the cosine at n, which
    a lamp's irradiance there carries (the footprint's normals facing the lamp more than n does
    would otherwise take light n does not get: at a terminator, an area lamp's sliver of
    irradiance over n's tiny cosine made pixels 40x too bright). Without a footprint, the lobe
    at the normal n."""
    if footprint is None:
        return ggx_highlight(n, wi, wo, roughness, f0)
    roughness = np.asarray(roughness, np.float64)
    cos_n = np.clip(np.einsum("ij,ij->i", n, wi), 0.0, 1.0)

    def brdf(normals, rows, lobe_roughness):
        cos_i = np.einsum("ij,ij->i", normals, wi[rows])
        return (ggx_highlight(normals, wi[rows], wo[rows], lobe_roughness, f0[rows])
                / np.maximum(cos_i, 1e-6)[:, None])

    centred = footprint.centres(n)
    spread = footprint.spread
    out = brdf(centred, slice(None), widened_roughness(roughness, spread))
    sides = sub_sides(roughness ** 4, footprint)
    for side in np.unique(sides[sides > 1]):
        sub = np.flatnonzero(sides == side)
        part = footprint.at(sub)
        rest = widened_roughness(roughness[sub], part.spread / side ** 2)
        total = np.zeros((len(sub), 3))
        for normal in sub_normals(centred[sub], part, int(side)):
            total += brdf(normal, sub, rest)
        out[sub] = total / side ** 2
    return out * cos_n[:, None]


def lamp_highlights(materials, material: np.ndarray, normals: np.ndarray, wo: np.ndarray,
                    to_light: np.ndarray, irradiance: np.ndarray,
                    base: np.ndarray | None = None, footprint: NormalFootprint | None = None,
                    spread: np.ndarray | None = None) -> np.ndarray:
    """(N, 3) radiance W/(m^2 sr) a lamp's light leaves toward the eye by the rough glossy lobes
    of surfaces of `material` (N,) (rows of `materials`): unit shading normals, directions to the
    eye wo and to the lamp (N, 3), and the lamp's irradiance there (N, 3, cosine included).
    Lobes of roughness >= MIRROR_ROUGHNESS: the specular layer over a dielectric base (F0 from
    the IOR and level times its Specular Tint, weight (1 - metallic)(1 - transmission)), a
    metal's (F0 the base colour, `base` (N, 3) where textures set it, weight metallic) and a
    rough glass's reflection (F0 from its IOR alone, weight (1 - metallic) transmission, as the
    tracer lights it), and a coat's over them (F0 from its IOR, its own roughness, weight coat),
    which leaves those under it what it lets through (`coat_layer`). footprint, when given: how
    the normal changes across each point's pixel or sub-pixel cell, over which every lobe is
    averaged (`pixel_highlight`); spread (N,) rad, when the light is one of an area lamp's
    samples: its angular radius, which widens every lobe (`highlight_spread.sample_roughness`)."""
    rough = sample_roughness(np.array([m.roughness for m in materials], np.float64)[material],
                             spread)
    glossy = np.array([m.roughness >= MIRROR_ROUGHNESS for m in materials])[material]
    layer_w = np.array([(1.0 - m.metallic) * (1.0 - m.transmission) for m in materials])[material]
    layer_f = np.array([layer_f0(m.ior, m.specular) for m in materials])[material]
    metal_w = np.array([m.metallic for m in materials], np.float64)[material]
    glass_w = np.array([(1.0 - m.metallic) * m.transmission for m in materials])[material]
    glass_f = np.array([layer_f0(m.ior, 0.5) for m in materials])[material]  # F0 of the IOR alone
    if base is None:
        base = np.array([m.base_color for m in materials], np.float64).reshape(-1, 3)[material]
    out = np.zeros((len(material), 3))

    def add(lit, weight, f0, roughness):
        rows = np.flatnonzero(lit & (weight > 0.0))
        if rows.size:
            cos_i = np.einsum("ij,ij->i", normals[rows], to_light[rows])
            brdf = pixel_highlight(normals[rows], to_light[rows], wo[rows], roughness[rows],
                                   f0[rows], None if footprint is None else footprint.at(rows))
            out[rows] += (weight[rows] / np.maximum(cos_i, 1e-6))[:, None] * brdf * irradiance[rows]

    add(glossy, layer_w * (layer_f > 0.0), layer_f[:, None] * layer_tints(materials)[material],
        rough)
    add(glossy, metal_w, np.asarray(base, np.float64), rough)
    add(glossy, glass_w, np.repeat(glass_f[:, None], 3, axis=1), rough)
    coat = coat_layer(materials, material, np.einsum("ij,ij->i", normals, wo))
    if coat is not None:
        out *= coat.under  # the two lobes under the coat, then the coat's own
        coat_rough = np.array([m.coat_roughness for m in materials], np.float64)[material]
        coat_lit = coat_rough >= MIRROR_ROUGHNESS
        coat_rough = sample_roughness(coat_rough, spread)

        coat_f = np.array([layer_f0(m.coat_ior, 0.5) for m in materials])[material]
        add(coat_lit, coat.weight, np.repeat(coat_f[:, None], 3, axis=1), coat_rough)
    return out


@dataclass(frozen=True, eq=False)
class CoatLayer:
    """The Principled coat of N surface points seen at some view.

    weight (N,)    the coat's weight (0 where a material has none)
    under  (N, 3)  what it leaves of the light of the layers under it (`coat_attenuation`)
    albedo (N,)    weight x its albedo E at the view: the share it reflects itself
    """

    weight: np.ndarray
    under: np.ndarray
    albedo: np.ndarray


def coat_layer(materials, material: np.ndarray, mu: np.ndarray) -> CoatLayer | None:
    """The coat of surfaces of `material` (N,) (rows of `materials`) seen at cos = mu (N,), or
    None when no material has one (`CoatLayer`)."""
    if not any(m.coat > 0.0 for m in materials):
        return None
    weight = np.array([m.coat for m in materials], np.float64)[material]
    tint = np.array([m.coat_tint for m in materials], np.float64).reshape(-1, 3)[material]
    ior = np.array([m.coat_ior for m in materials], np.float64)[material]
    e = np.where(weight > 0.0, 1.0 - view_factors(coat_tables(materials), material, mu), 0.0)
    return CoatLayer(weight, coat_attenuation(weight, e, tint, ior, mu), weight * e)


@lru_cache(maxsize=64)
def _grazing_table(roughness: float) -> tuple[float, ...]:
    return tuple(schlick_grazing_curve(np.linspace(0.0, 1.0, MU_STEPS) ** 2, roughness))


@lru_cache(maxsize=256)
def _f82_table(roughness: float) -> tuple[float, ...]:
    return tuple(f82_curve(np.linspace(0.0, 1.0, MU_STEPS) ** 2, roughness))


def coat_tables(materials) -> np.ndarray:
    """(M, MU_STEPS) per material, 1 - E(mu) of its coat (`Material.coat_roughness`, F0 of
    `coat_ior`), as `view_tables` holds its specular layer's; 1 where it has no coat."""
    rows = [_view_table(float(m.coat_roughness), layer_f0(m.coat_ior, 0.5)) if m.coat > 0.0
            else (1.0,) * MU_STEPS for m in materials]
    return np.array(rows, np.float64).reshape(len(rows), MU_STEPS)


def coat_attenuation(coat: np.ndarray, coat_e: np.ndarray, tint: np.ndarray, ior: np.ndarray,
                     mu: np.ndarray) -> np.ndarray:
    """(N, 3) what a coat of weight `coat` (N,) leaves of the light of the layers under it, seen
    at |cos| = mu (N,): 1 - coat x E (its albedo `coat_e` (N,) there), times the tint (N, 3)
    raised to the path length through a coat of unit thickness, 1 / cos of the refracted view
    (Cycles' Principled BSDF: the tint is what normal incidence lets through, Beer's law
    elsewhere), mixed in by the weight."""
    mu = np.clip(np.abs(mu), 1e-6, 1.0)
    cos_t = np.sqrt(np.maximum(1.0 - (1.0 - mu * mu) / np.maximum(ior, 1.0) ** 2, 1e-12))
    tinted = np.power(np.maximum(tint, 0.0), (1.0 / cos_t)[:, None])
    return (1.0 - coat * coat_e)[:, None] * (1.0 + coat[:, None] * (tinted - 1.0))


def metal_tables(materials) -> MetalTables:
    """The materials' `MetalTables`: a metal's reflectance at a view is F0 + (1 - F0) x its
    grazing row there, less b x its F82 row (`metal_reflectance`)."""
    rows = [_grazing_table(float(m.roughness)) for m in materials]
    f82 = [_f82_table(float(m.roughness)) if m.metal_edge is not None else (0.0,) * MU_STEPS
           for m in materials]
    edge = [np.ones(3) if m.metal_edge is None else m.metal_edge for m in materials]
    return MetalTables(np.array(rows).reshape(len(rows), MU_STEPS),
                       np.array(f82, np.float64).reshape(len(rows), MU_STEPS),
                       np.array(edge, np.float64).reshape(len(rows), 3))
