"""Area lamps added to a captured cube map (kernels/envmap/probe_lamps.py): the radiance the faces
hold times each texel's solid angle sums to the lamp's radiance times the solid angle it spans
(closed form), behind a nearer surface it vanishes, seen from behind it adds nothing, and a disk
lamp lands where a ray from the centre meets it."""

import numpy as np
import pytest

from classic_bake.kernels.envmap.envmap import EnvironmentMap
from classic_bake.kernels.envmap.prefilter import texel_solid_angles
from classic_bake.kernels.envmap.probe_lamps import lamp_faces
from classic_bake.kernels.geometry.scene import Light

SIZE = 32  # texels per face side
RADIANCE = np.array([3.0, 2.0, 1.0])


def _square_lamp(half_x, half_y, height, direction=(0.0, 0.0, -1.0)):
    """A rectangle of 2 half_x by 2 half_y m at z = height above the origin, emitting down."""
    return Light("Panel", "AREA", position=np.array([0.0, 0.0, height]),
                 direction=np.array(direction), axis_x=np.array([1.0, 0.0, 0.0]),
                 axis_y=np.array([0.0, 1.0, 0.0]), radiance=RADIANCE, shape="RECTANGLE",
                 size_x=2.0 * half_x, size_y=2.0 * half_y)


def _empty_map(inverse_distance=0.0):
    side = SIZE + 2
    return EnvironmentMap(object_index=0, centre=np.zeros(3),
                          faces=np.zeros((6, side, side, 3), np.float32),
                          inverse_distance=np.full((6, side, side, 1), inverse_distance,
                                                   np.float32))


def _power(faces):
    """sum over the inner texels of L Omega, (3,) W / m^2 (the lamp's irradiance on a sphere)."""
    inner = faces[:, 1:-1, 1:-1]
    return np.einsum("fijc,ij->c", inner.astype(np.float64), texel_solid_angles(SIZE))


@pytest.mark.parametrize("half_x, half_y, height", [(0.5, 0.5, 1.0), (0.3, 0.8, 2.0),
                                                    (0.05, 0.05, 1.0), (0.01, 0.02, 1.0)])
def test_the_faces_hold_the_lamps_solid_angle(half_x, half_y, height):
    """A rectangle of half sides p, q at distance d on its axis spans
    Omega = 4 asin(p q / sqrt((p^2 + d^2) (q^2 + d^2))); the faces' sum is L Omega within 1e-4
    (measured: 4e-5, the flat patches), also for a lamp of 1.6 texels (the splat keeps power)."""
    p, q, d = half_x, half_y, height
    omega = 4.0 * np.arcsin(p * q / np.sqrt((p * p + d * d) * (q * q + d * d)))
    faces = lamp_faces(_empty_map(), [_square_lamp(p, q, d)])
    np.testing.assert_allclose(_power(faces), RADIANCE * omega, rtol=1e-4)
    assert faces[5].max() == 0.0  # nothing on the -Z face


def test_a_nearer_surface_hides_the_lamp_and_its_back_adds_nothing():
    hidden = lamp_faces(_empty_map(inverse_distance=2.0), [_square_lamp(0.5, 0.5, 1.0)])
    assert hidden.max() == 0.0  # every texel sees a surface 0.5 m away, nearer than the lamp
    behind = lamp_faces(_empty_map(), [_square_lamp(0.5, 0.5, 1.0, direction=(0, 0, 1))])
    assert behind.max() == 0.0


def test_a_disk_lamp_lands_on_the_texels_that_look_at_it():
    """A disk of radius 0.2 m, 1 m above the centre: texels whose centre direction meets it
    well inside hold its radiance, texels looking well outside (beyond the splat's one-texel
    tent) hold nothing."""
    from classic_bake.kernels.envmap.envmap import bordered_directions

    lamp = _square_lamp(0.2, 0.2, 1.0)
    lamp = Light(**{**lamp.__dict__, "shape": "DISK", "size_x": 0.4, "size_y": 0.4})
    faces = lamp_faces(_empty_map(), [lamp])[4]  # +Z, bordered
    dirs = bordered_directions(SIZE)[4]
    radius = np.hypot(dirs[..., 0], dirs[..., 1]) / dirs[..., 2]  # where the ray meets z = 1
    inside = faces[radius < 0.15]  # measured: within 0.3% (the bilinear splat's ripple)
    np.testing.assert_allclose(inside, np.broadcast_to(RADIANCE, inside.shape), rtol=5e-3)
    assert faces[radius > 0.33].max() == 0.0  # 0.2 m + two texels (1/16 m each at z = 1)
