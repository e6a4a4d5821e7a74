"""Blender light power -> radiometric quantities, and the direct irradiance they cause.

Measured in Cycles (Blender 5.2.3, CPU, black world, max_bounces 0, a white Lambertian plane; see
`tests/blender/test_light_units.py`, which re-measures these on every run):

| light  | Blender input            | radiometric quantity                                         |
|--------|--------------------------|--------------------------------------------------------------|
| POINT  | power P (W), radius r    | intensity I = P / (4 pi) W/sr; E = I cos(theta) / (d^2 + r^2) |
| SPOT   | power P, size, blend     | the same I inside the cone (the cone does not concentrate P),  |
|        |                          | times smoothstep((cos a - cos(size/2)) / ((1 - cos(size/2)) * blend)) |
| SUN    | strength S (W/m^2)       | irradiance E = S on a surface facing it                      |
| AREA   | power P, area A          | one-sided radiance L = P / (pi A) (`normalize` on, A is the   |
|        |                          | scaled area of the shape); L = P / (pi * 1 m^2) with it off  |
| mesh   | emission strength S      | radiance L = colour * S                                      |

P includes the light's colour, `2 ** exposure` and (when enabled) the blackbody temperature colour.
A point light's object scale does not change it; an area light's scale stretches its emitter.

With `normalize` off (glTF-era and some imported files) Cycles does not divide a light's power by
its emitter's area, so P or S above are multiplied by that area (`unnormalized_scale`): 4 pi r^2
for a point or spot light of radius r (4 when r = 0), pi sin^2(angle / 2) for a sun (1 when the
angle is 0). Measured as the ratio of unnormalised to normalised renders (4.0, 0.1257, 3.1416
at r = 0, 0.1, 0.5; 0.00785 and 0.192 for suns of 0.1 and 0.5 rad); Cycles' `Light::area`.
"""

from __future__ import annotations

import numpy as np

from ..geometry.scene import Light

# Below this distance (m) a receiver is "at" a point light: the inverse-square law is capped there
# instead of returning inf. One micrometre is far below any modelled feature.
MIN_LIGHT_DISTANCE = 1e-6


# --- Blender -> radiometry ------------------------------------------------------------------------


def point_intensity(power_w: float, color: np.ndarray) -> np.ndarray:
    """Radiant intensity (3,) W/sr of a point or spot light of power `power_w` W and linear colour."""
    return np.asarray(color, np.float64) * (power_w / (4.0 * np.pi))


def unnormalized_scale(kind: str, radius: float = 0.0, angle: float = 0.0) -> float:
    """What an unnormalised point, spot or sun light's power is multiplied by: its emitter's area
    as Cycles counts it (m^2 for points and spots, a solid-angle measure for suns; module table).

    | parameter | range      | unit | meaning                                  |
    |-----------|------------|------|------------------------------------------|
    | kind      | POINT, SPOT, SUN | - | the light type (others: ValueError)   |
    | radius    | >= 0       | m    | point / spot radius (`shadow_soft_size`) |
    | angle     | [0, pi]    | rad  | a sun's angular diameter                 |
    """
    if kind in ("POINT", "SPOT"):
        return 4.0 * np.pi * radius * radius if radius > 0.0 else 4.0
    if kind == "SUN":
        return np.pi * np.sin(0.5 * angle) ** 2 if angle > 0.0 else 1.0
    raise ValueError(f"no unnormalised scale for a {kind} light (area lights: area_radiance)")


def sun_irradiance(strength: float, color: np.ndarray) -> np.ndarray:
    """Irradiance (3,) W/m^2 on a surface facing a sun of `strength` W/m^2."""
    return np.asarray(color, np.float64) * strength


def area_radiance(power_w: float, color: np.ndarray, area_m2: float, normalize: bool) -> np.ndarray:
    """Radiance (3,) W/(m^2 sr) of the front face of an area light.

    With `normalize` (Blender's default) the power is spread over the emitter's area; without it the
    emitter behaves as if it had an area of 1 m^2, whatever its size (measured, see module docstring).
    """
    area = area_m2 if normalize else 1.0
    if area <= 0.0:
        return np.zeros(3)
    return np.asarray(color, np.float64) * (power_w / (np.pi * area))


def area_of_shape(shape: str, size_x: float, size_y: float) -> float:
    """Area (m^2) of an area light's emitter: SQUARE/RECTANGLE size_x*size_y, DISK/ELLIPSE pi/4 of it."""
    if shape in ("DISK", "ELLIPSE"):
        return 0.25 * np.pi * size_x * size_y
    return size_x * size_y


def spot_falloff(cos_angle: np.ndarray, spot_size: float, spot_blend: float) -> np.ndarray:
    """Cycles' spot cone attenuation in [0, 1] for the cosine between the spot axis and the ray.

    `spot_size` is the full cone angle (rad), `spot_blend` in [0, 1] the softened fraction.
    """
    cos_half = np.cos(0.5 * spot_size)
    cos_angle = np.asarray(cos_angle, np.float64)
    smooth = (1.0 - cos_half) * spot_blend
    if smooth <= 0.0:
        return (cos_angle > cos_half).astype(np.float64)
    t = np.clip((cos_angle - cos_half) / smooth, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


# --- direct irradiance ----------------------------------------------------------------------------

# Stratified samples per side of an area light when integrating its irradiance numerically: 16 x 16
# keeps the error of a unit emitter under 0.1% beyond one emitter size away.
AREA_SAMPLES_PER_SIDE = 16


def receiving(light: Light, objects: np.ndarray | None) -> np.ndarray | None:
    """(N,) float64, 1 where the points on objects `objects` (N,) (indices into
    `Scene.objects`) take `light`'s light and 0 where its light linking leaves them out; None
    where every object takes it (or the points' objects are unknown)."""
    if light.receivers is None or objects is None:
        return None
    return light.receivers[objects].astype(np.float64)


def light_vectors(light: Light, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit directions (N, 3) from `points` towards the light and distances (N,) m (inf for a sun)."""
    points = np.asarray(points, np.float64)
    if light.kind == "SUN":
        to_light = np.broadcast_to(-np.asarray(light.direction, np.float64), points.shape).copy()
        return to_light, np.full(points.shape[0], np.inf)
    delta = np.asarray(light.position, np.float64) - points
    dist = np.linalg.norm(delta, axis=1)
    safe = np.maximum(dist, MIN_LIGHT_DISTANCE)
    return delta / safe[:, None], dist


def direct_irradiance(light: Light, points: np.ndarray, normals: np.ndarray,
                      direction_weight=None) -> np.ndarray:
    """Unoccluded irradiance (N, 3) W/m^2 that `light` causes at `points` with unit `normals`.

    points (N, 3) world m, normals (N, 3) world unit. Surfaces facing away receive 0 (one-sided).
    Point, spot and sun are exact; area lights are integrated over a stratified grid of the emitter
    (`AREA_SAMPLES_PER_SIDE`), which is what a receiver far from the emitter needs.
    direction_weight: optional f(to_light (N, 3) unit) -> (N,), a factor on the light arriving
    from each direction (a relief's shadowing), taken per grid sample of an area light.
    """
    points = np.asarray(points, np.float64)
    normals = np.asarray(normals, np.float64)
    if light.kind == "AREA":
        return _area_irradiance(light, points, normals, direction_weight)
    to_light, dist = light_vectors(light, points)
    cos_r = np.clip(np.einsum("ij,ij->i", normals, to_light), 0.0, None)
    if direction_weight is not None:
        cos_r = cos_r * direction_weight(to_light)
    if light.kind == "SUN":
        return cos_r[:, None] * np.asarray(light.irradiance, np.float64)[None, :]
    falloff = cos_r / (np.maximum(dist, MIN_LIGHT_DISTANCE) ** 2 + light.radius**2)
    if light.kind == "SPOT":
        cos_axis = -np.einsum("ij,j->i", to_light, np.asarray(light.direction, np.float64))
        falloff = falloff * spot_falloff(cos_axis, light.spot_size, light.spot_blend)
    return falloff[:, None] * np.asarray(light.intensity, np.float64)[None, :]


def area_light_samples(light: Light, per_side: int = AREA_SAMPLES_PER_SIDE) -> np.ndarray:
    """Stratified sample centres (S, 3) on an area light's emitter, world m, and nothing random.

    Disks and ellipses keep the grid cells whose centres fall inside the shape.
    """
    g = (np.arange(per_side) + 0.5) / per_side - 0.5  # cell centres in [-0.5, 0.5]
    gx, gy = np.meshgrid(g, g, indexing="xy")
    gx, gy = gx.ravel(), gy.ravel()
    if light.shape in ("DISK", "ELLIPSE"):
        inside = gx * gx + gy * gy <= 0.25
        gx, gy = gx[inside], gy[inside]
    ax = np.asarray(light.axis_x, np.float64) * light.size_x
    ay = np.asarray(light.axis_y, np.float64) * light.size_y
    return np.asarray(light.position, np.float64) + gx[:, None] * ax + gy[:, None] * ay


def sample_radius(da: np.ndarray, cos_e: np.ndarray, dist: np.ndarray) -> np.ndarray:
    """(N,) rad: the angular radius of an emitter sample seen from a point: the disc of its area
    da (N,) m^2 foreshortened by cos_e (N,) (its normal against the direction to the point), at
    distance dist (N,) m."""
    return np.sqrt(np.asarray(da) * np.abs(cos_e) / np.pi) / np.maximum(dist, MIN_LIGHT_DISTANCE)


def _area_irradiance(light: Light, points: np.ndarray, normals: np.ndarray,
                     direction_weight=None) -> np.ndarray:
    samples = area_light_samples(light)  # (S, 3)
    area = area_of_shape(light.shape, light.size_x, light.size_y)
    d_area = area / samples.shape[0]
    emitter_n = np.asarray(light.direction, np.float64)  # the emitter faces its local -Z
    total = np.zeros(points.shape[0])
    for s in samples:  # S <= 256 iterations, each vectorised over all receivers
        delta = s - points
        d2 = np.maximum(np.einsum("ij,ij->i", delta, delta), MIN_LIGHT_DISTANCE**2)
        inv_d = 1.0 / np.sqrt(d2)
        cos_r = np.clip(np.einsum("ij,ij->i", normals, delta) * inv_d, 0.0, None)
        cos_e = np.clip(-(delta @ emitter_n) * inv_d, 0.0, None)
        if direction_weight is not None:
            cos_r = cos_r * direction_weight(delta * inv_d[:, None])
        total += cos_r * cos_e / d2
    return (total * d_area)[:, None] * np.asarray(light.radiance, np.float64)[None, :]


def area_lamps_seen(lamps, origins: np.ndarray, dirs: np.ndarray, t_hit: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) radiance W/(m^2 sr) of the area lamps (kernel `Light`s of kind AREA) that rays
    (origins, unit dirs (N, 3), m) meet before their hit distance t_hit (N,) (inf: none), on
    the lamp's emitting side (its -Z), summed, and the distance (N,) to the nearest one met (inf:
    none). Lamps are in no BVH: each is a rectangle or an ellipse tested here."""
    out = np.zeros((len(origins), 3))
    nearest = np.full(len(origins), np.inf)
    for lamp in lamps:
        facing = dirs @ lamp.direction  # < 0: the ray meets the emitting side
        t = np.divide((lamp.position - origins) @ lamp.direction, facing,
                      out=np.full(len(origins), -1.0), where=facing < 0.0)
        q = origins + t[:, None] * dirs - lamp.position
        x = (q @ lamp.axis_x) / max(lamp.size_x, 1e-12)
        y = (q @ lamp.axis_y) / max(lamp.size_y, 1e-12)
        inside = (x * x + y * y <= 0.25) if lamp.shape in ("DISK", "ELLIPSE") else (
            (np.abs(x) <= 0.5) & (np.abs(y) <= 0.5))
        seen = inside & (t > 0.0) & (t < t_hit)
        out[seen] += np.asarray(lamp.radiance, np.float64)
        nearest[seen] = np.minimum(nearest[seen], t[seen])
    return out, nearest
