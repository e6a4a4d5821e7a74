"""Directions across a rough glossy lobe: GGX's distribution of visible normals, sampled.

A rough metal or specular layer reflects its surroundings blurred by its GGX lobe. The tracer
stands for the lobe with a few rays (`TracerSettings.lobe_rays`) whose directions are the view
reflected about microfacet normals drawn from the normals the view sees (Heitz, "Sampling the
GGX Distribution of Visible Normals", JCGT 2018). VNDF sampling weighs such a ray by
F G2 / G1(o), the light's shadowing given the view's masking (`shadowing_weights`). The rays of
a lobe share its albedo (from the tables, `specular_layer.py`, which hold F and the light
scattered more than once, as Cycles restores it by scaling the single-scattering lobe, whose
shape it keeps) in proportion to G2 / G1(o): at roughness 1 a ray near the surface's plane
carries a fraction of one near the normal, and equal shares left a rough metal face turned from
a studio's softbox 23% dark. The shares are normalised by their own sum, so uniform
surroundings come out exact: dividing by the lobe's mean E(mu) instead (unbiased) left a rough
metal ball in a uniform room with 5-10% noise from pixel to pixel.

The points are a stratified set per pixel (`lobe_points`), shifted by an offset hashed from the
pixel (Cranley-Patterson rotation): deterministic, the same wherever a tile of the view traces it,
and without the pattern a shared set would stamp on every pixel; a pixel's sub-samples draw
their rays from one set between them.
"""

from __future__ import annotations

import numpy as np

from ..geometry.frames import tangent_frames
from .optics import refract

# The golden ratio's fractional part: the second coordinate of a Fibonacci lattice.
GOLDEN_STEP = 0.6180339887498949
# Hash of a hit position into [0, 1)^2 (the classic sin-dot hash); any two unrelated directions
# and a large scale do, as the offsets only need to look unrelated between neighbouring hits.
HASH_AXES = np.array([[12.9898, 78.233, 37.719], [39.3468, 11.135, 83.155]])
HASH_SCALE = 43758.5453
# Alpha below which a lobe is taken as a mirror (Blender roughness 0.01).
MIN_ALPHA = 1e-4
# A rough lobe's mean of the sky (`lobe_mean`) reads this many times the directions its rays
# trace (a map read each, no traversal: the tracer's 8 rays 64), in chunks of about MEAN_CHUNK
# directions (memory: ~20 arrays of 3 floats).
MEAN_FACTOR = 8
MEAN_CHUNK = 1 << 19


def lobe_points(counts: np.ndarray, seeds: np.ndarray, part: np.ndarray | None = None,
                parts: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """For hits that each take counts[i] (N,) rays: (which hit (M,), points (M, 2) in [0, 1)^2),
    M = counts.sum(). Hit i's are points part[i] x c .. part[i] x c + c - 1 (c = counts[i]) of
    a Fibonacci lattice of parts x c points ((j + 1/2) / n, j x GOLDEN_STEP), shifted by an
    offset hashed from seeds[i] (3,), modulo 1: with part None and parts 1 a lattice per hit;
    the `parts` sub-samples of one pixel (the same seed, part their index) share one lattice
    between them, stratified over all of them."""
    counts = np.asarray(counts, np.int64)
    which = np.repeat(np.arange(len(counts)), counts)
    j = np.arange(len(which)) - np.repeat(np.cumsum(counts) - counts, counts)
    if part is not None:
        j = j + np.asarray(part, np.int64)[which] * counts[which]
    offset = np.sin(np.asarray(seeds, np.float64) @ HASH_AXES.T) * HASH_SCALE
    offset -= np.floor(offset)
    points = np.stack([(j + 0.5) / (parts * counts[which]), j * GOLDEN_STEP], 1) + offset[which]
    return which, points - np.floor(points)


def ggx_reflections(n: np.ndarray, wo: np.ndarray, roughness: np.ndarray,
                    points: np.ndarray, which: np.ndarray | None = None) -> np.ndarray:
    """(M, 3) unit directions: the views wo (N, 3, unit, towards the viewer, above n) reflected
    about microfacet normals drawn from GGX's visible normals about unit normals n (N, 3), of
    Blender roughness (N,) (alpha = roughness^2), at points (M, 2) in [0, 1)^2: point j of
    hit which[j] (which (M,), else M = N and point j of hit j). A direction may fall below the
    surface (a shadowed share of the lobe): callers drop it."""
    micro, wo = ggx_microfacets(n, wo, roughness, points, which)
    return 2.0 * np.einsum("ij,ij->i", wo, micro)[:, None] * micro - wo


def ggx_microfacets(n: np.ndarray, wo: np.ndarray, roughness: np.ndarray, points: np.ndarray,
                    which: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """((M, 3) microfacet normals, (M, 3) each one's view) drawn from GGX's visible normals
    (Heitz 2018) as `ggx_reflections` takes them."""
    t1, t2 = tangent_frames(n)
    local = np.stack([np.einsum("ij,ij->i", wo, t1), np.einsum("ij,ij->i", wo, t2),
                      np.einsum("ij,ij->i", wo, n)], axis=1)
    alpha = np.maximum(np.asarray(roughness, np.float64) ** 2, MIN_ALPHA)
    # The view stretched to the hemisphere configuration (alpha = 1), and a frame about it: per hit.
    vh = np.stack([alpha * local[:, 0], alpha * local[:, 1], np.maximum(local[:, 2], 0.0)], 1)
    vh /= np.maximum(np.linalg.norm(vh, axis=1, keepdims=True), 1e-12)
    lensq = vh[:, 0] ** 2 + vh[:, 1] ** 2
    inv = 1.0 / np.sqrt(np.maximum(lensq, 1e-24))
    b1 = np.where((lensq > 0.0)[:, None],
                  np.stack([-vh[:, 1] * inv, vh[:, 0] * inv, np.zeros(len(vh))], 1), [1.0, 0.0, 0.0])
    b2 = np.cross(vh, b1)
    if which is not None:  # per point from here
        vh, b1, b2, alpha = vh[which], b1[which], b2[which], alpha[which]
        t1, t2, n, wo = t1[which], t2[which], n[which], wo[which]
    # A point of the unit disc, its second half squeezed towards the view's projection.
    r = np.sqrt(points[:, 0])
    phi = 2.0 * np.pi * points[:, 1]
    d1, d2 = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1.0 + vh[:, 2])
    d2 = (1.0 - s) * np.sqrt(np.maximum(1.0 - d1 * d1, 0.0)) + s * d2
    nh = (d1[:, None] * b1 + d2[:, None] * b2
          + np.sqrt(np.maximum(1.0 - d1 * d1 - d2 * d2, 0.0))[:, None] * vh)
    # Back to the ellipsoid configuration, then to world space.
    m = np.stack([alpha * nh[:, 0], alpha * nh[:, 1], np.maximum(nh[:, 2], 0.0)], 1)
    m /= np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-12)
    return m[:, :1] * t1 + m[:, 1:2] * t2 + m[:, 2:] * n, wo


def shadowing_weights(n: np.ndarray, wo: np.ndarray, wi: np.ndarray,
                      roughness: np.ndarray) -> np.ndarray:
    """(N,) G2 / G1(o) in [0, 1]: GGX's height-correlated Smith shadowing given the view's
    masking, (1 + L(o)) / (1 + L(o) + L(i)) with L Smith's Lambda, at unit normals n, views wo and
    reflected directions wi (N, 3), Blender roughness (N,) (alpha = roughness^2); 0 where wi or
    wo is below n. For VNDF-sampled directions, a ray's weight up to Fresnel (Heitz 2018)."""
    alpha2 = np.maximum(np.asarray(roughness, np.float64) ** 2, MIN_ALPHA) ** 2
    cos_o = np.einsum("ij,ij->i", n, wo)
    cos_i = np.einsum("ij,ij->i", n, wi)

    def smith_lambda(c):
        c2 = np.clip(c * c, 1e-12, 1.0)
        return 0.5 * (np.sqrt(1.0 + alpha2 * (1.0 - c2) / c2) - 1.0)

    lambda_o = smith_lambda(cos_o)
    return np.where((cos_o > 0.0) & (cos_i > 0.0),
                    (1.0 + lambda_o) / (1.0 + lambda_o + smith_lambda(cos_i)), 0.0)


def lobe_rays(n: np.ndarray, wo: np.ndarray, geometric: np.ndarray, roughness: np.ndarray,
              points: np.ndarray, which: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rays across N GGX lobes: (M, 3) unit directions (`ggx_reflections` at points (M, 2) of
    lobes which (M,)) and (M,) their weights (`shadowing_weights`; 0 below the geometric normals
    (N, 3) too, where the surface itself stops them). Unit shading normals n and views wo (N, 3),
    Blender roughness (N,)."""
    roughness = np.asarray(roughness, np.float64)
    dirs = ggx_reflections(n, wo, roughness, points, which)
    g = np.where(np.einsum("ij,ij->i", dirs, geometric[which]) > 0.0,
                 shadowing_weights(n[which], wo[which], dirs, roughness[which]), 0.0)
    return dirs, g


def lobe_refractions(n: np.ndarray, wo: np.ndarray, geometric: np.ndarray,
                     roughness: np.ndarray, eta: np.ndarray, points: np.ndarray,
                     which: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rays across N rough glasses' transmission lobes: (M, 3) unit directions, the views wo
    refracted (eta (N,) = n_from / n_to) through microfacet normals drawn as `ggx_reflections`
    draws them, and (M,) their weights: the shadowing of the direction below the surface given
    the view's masking (`shadowing_weights` of its mirror image above n: Smith's terms depend
    on the angle to n alone); 0 where a facet reflects all (total internal reflection) or the
    ray would not pass the geometric normals (N, 3). Shares of the lobe's light up to Fresnel,
    as the reflected rays' are."""
    roughness = np.asarray(roughness, np.float64)
    micro, w = ggx_microfacets(n, wo, roughness, points, which)
    dirs, tir = refract(-w, micro, np.asarray(eta, np.float64)[which])
    normal = n[which]
    mirror = dirs - 2.0 * np.einsum("ij,ij->i", dirs, normal)[:, None] * normal
    passes = ~tir & (np.einsum("ij,ij->i", dirs, geometric[which]) < 0.0)
    g = np.where(passes, shadowing_weights(normal, w, mirror, roughness[which]), 0.0)
    return dirs, g


def lobe_mean(radiance, n: np.ndarray, wo: np.ndarray, geometric: np.ndarray,
              roughness: np.ndarray, count: np.ndarray, seeds: np.ndarray
              ) -> tuple[np.ndarray | None, np.ndarray]:
    """Over count (N,) directions across each of N GGX lobes (`ggx_reflections` at a lattice of
    `lobe_points` shifted by a hash of seeds (N, 3)), weighted by their shadowing
    (`shadowing_weights`, 0 below the geometric normals (N, 3)): (N, 3) the mean of radiance
    ((K, 3) unit directions -> (K, 3)) normalised by the weights' sum (a uniform radiance
    exactly; None when radiance is None), and (N,) the weights' mean, the lobe's albedo with
    F = 1 (`specular_layer.lobe_albedo`). Unit shading normals n and views wo (N, 3), Blender
    roughness (N,)."""
    mean = None if radiance is None else np.zeros((len(n), 3))
    weight = np.zeros(len(n))
    ends = np.cumsum(count)
    start = 0
    while start < len(n):  # lobes in chunks of about MEAN_CHUNK directions
        stop = max(int(np.searchsorted(ends, ends[start] - count[start] + MEAN_CHUNK)), start + 1)
        rows = slice(start, stop)
        which, points = lobe_points(count[rows], seeds[rows])
        dirs, g = lobe_rays(n[rows], wo[rows], geometric[rows], np.asarray(roughness)[rows],
                            points, which)
        sums = np.bincount(which, g, minlength=stop - start)
        weight[rows] = sums / count[rows]
        if radiance is not None:
            seen = g > 0.0
            light = np.zeros((stop - start, 3))
            np.add.at(light, which[seen], g[seen, None] * radiance(dirs[seen]))
            mean[rows] = light / np.maximum(sums, 1e-300)[:, None]
        start = stop
    return mean, weight
