"""Diffuse light from a cube map: nine spherical-harmonic coefficients and the irradiance they give.

Ramamoorthi and Hanrahan 2001, "An Efficient Representation for Irradiance Environment Maps":
project the radiance L(l) onto the real spherical harmonics of order l <= 2,

    L_lm = integral L(l) Y_lm(l) dl  ~  sum_i L_i Y_lm(l_i) Omega_i     (texels i, exact solid angles)

and the irradiance at a surface of normal n is E(n) = sum_lm A_l L_lm Y_lm(n), with the clamped
cosine's coefficients A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4 (their equation 8). A constant
radiance L gives E = pi L exactly. The clamped cosine also has an l = 4 term (-pi / 24) that nine
coefficients drop: for light from a single direction E is off by up to ~9% of its peak; for
environments that vary smoothly (skies, rooms) the error stays around 1% (their figures: < 3%).

Basis order and constants (Ramamoorthi-Hanrahan's equation 3), of a unit direction (x, y, z) in
world axes:

    0 (0, 0)   0.282095             3 (1, 1)   0.488603 x     6 (2, 0)   0.315392 (3 z^2 - 1)
    1 (1, -1)  0.488603 y           4 (2, -2)  1.092548 x y   7 (2, 1)   1.092548 x z
    2 (1, 0)   0.488603 z           5 (2, -1)  1.092548 y z   8 (2, 2)   0.546274 (x^2 - y^2)

Units: L in W / (m^2 sr) (any linear radiance), L_lm the same times sr, E in W / m^2.
"""

from __future__ import annotations

import numpy as np

from .cubemap import texel_directions
from .prefilter import texel_solid_angles

# Real SH normalisation constants, l <= 2 (sqrt((2l + 1) / (4 pi) (l - |m|)! / (l + |m|)!) ...).
SH_C0 = 0.5 * np.sqrt(1.0 / np.pi)          # 0.282095
SH_C1 = np.sqrt(3.0 / (4.0 * np.pi))        # 0.488603
SH_C2 = 0.5 * np.sqrt(15.0 / np.pi)         # 1.092548
SH_C20 = 0.25 * np.sqrt(5.0 / np.pi)        # 0.315392
SH_C22 = 0.25 * np.sqrt(15.0 / np.pi)       # 0.546274
# (9,) the clamped cosine's convolution factors A_l per coefficient: pi, 2 pi / 3 (x3), pi / 4 (x5).
COSINE_LOBE = np.array([np.pi] + [2.0 * np.pi / 3.0] * 3 + [np.pi / 4.0] * 5)


def sh_basis(directions: np.ndarray) -> np.ndarray:
    """(..., 3) unit directions -> (..., 9) float64 real SH values, in the docstring's order."""
    d = np.asarray(directions, np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([
        np.full_like(x, SH_C0),
        SH_C1 * y, SH_C1 * z, SH_C1 * x,
        SH_C2 * x * y, SH_C2 * y * z, SH_C20 * (3.0 * z * z - 1.0), SH_C2 * x * z,
        SH_C22 * (x * x - y * y),
    ], axis=-1)


def sh_coefficients(faces: np.ndarray) -> np.ndarray:
    """(6, N, N, C) radiance faces (OpenGL table of `cubemap.py`) -> (9, C) float64 coefficients
    L_lm, every texel weighted by its exact solid angle."""
    faces = np.asarray(faces)
    if faces.ndim == 3:
        faces = faces[..., None]
    if faces.ndim != 4 or faces.shape[0] != 6 or faces.shape[1] != faces.shape[2]:
        raise ValueError(f"cube faces must be (6, N, N, C), got {faces.shape}")
    n = faces.shape[1]
    basis = sh_basis(texel_directions(n).reshape(-1, 3))                       # (Q, 9)
    omega = np.tile(texel_solid_angles(n).reshape(-1), 6)                       # (Q,) sr
    return (basis * omega[:, None]).T @ faces.reshape(-1, faces.shape[3]).astype(np.float64)


def irradiance(sh: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """(9, C) coefficients and (M, 3) unit normals -> (M, C) float64 irradiance E(n), W / m^2."""
    return sh_basis(np.asarray(normals).reshape(-1, 3)) @ (COSINE_LOBE[:, None]
                                                            * np.asarray(sh).reshape(9, -1))


def radiance(sh: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(9, C) coefficients and (M, 3) unit directions -> (M, C) float64 band-limited radiance."""
    return sh_basis(np.asarray(directions).reshape(-1, 3)) @ np.asarray(sh).reshape(9, -1)
