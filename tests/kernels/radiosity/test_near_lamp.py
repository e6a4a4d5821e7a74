"""A point lamp close to a surface: the light its first shot gives the patches against the
closed form, I times the solid angle the plate subtends (a lamp 5 cm under 0.5 m patches is where
their n x n sample points alone miss or straddle the peak under it: `lamps.near_lamp_scale`)."""

from __future__ import annotations

import numpy as np
import pytest
from scene_builder import build, grey, quad

from classic_bake.kernels.geometry.scene import Light
from classic_bake.kernels.radiosity import patches as patching
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.radiosity.sources import first_shot

HALF_SIDE = 1.0  # a 2 m x 2 m plate at z = 0, facing down (a ceiling)


def _flux(distance: float, patch_size: float, samples_per_side: int,
          off: tuple[float, float] = (0.0, 0.0)) -> tuple[float, float]:
    """(the first shot's flux onto the plate, W; the closed form I * solid angle) for a point
    lamp of intensity 1 W/sr at `distance` under the plate, `off` (x, y) m from its centre."""
    a = HALF_SIDE
    plate = quad([[-a, -a, 0.0], [-a, a, 0.0], [a, a, 0.0], [a, -a, 0.0]])
    lamp = Light(name="Lamp", kind="POINT", position=np.array([off[0], off[1], -distance]),
                 direction=np.array([0, 0, -1.0]), axis_x=np.array([1.0, 0, 0]),
                 axis_y=np.array([0, 1.0, 0]), intensity=np.full(3, 1.0))
    scene = build([(plate, grey(0.5))], lights=(lamp,))
    patches = patching.make_patches(scene, patch_size)
    never = lambda o, d, t0, t1: np.zeros(len(o), bool)  # noqa: E731
    h, _ = first_shot(scene, patches, never,
                      RadiositySettings(light_samples_per_side=samples_per_side), 1.0)
    # The solid angle of a rectangle [x0, x1] x [y0, y1] at distance d below its corner's
    # apex: atan(x y / (d sqrt(x^2 + y^2 + d^2))), summed with signs over the four corners.
    def corner(x, y):
        return np.arctan(x * y / (distance * np.sqrt(x * x + y * y + distance * distance)))

    x0, x1, y0, y1 = -a - off[0], a - off[0], -a - off[1], a - off[1]
    solid_angle = corner(x1, y1) - corner(x0, y1) - corner(x1, y0) + corner(x0, y0)
    return float(np.sum(h[:, 0] * patches.areas)), float(solid_angle)


@pytest.mark.parametrize("distance", [0.2, 0.5])
def test_first_shot_flux_of_a_lamp_under_a_ceiling(distance):
    """A lamp 20 cm or more under the plate: the patches receive I * solid angle (0.1%)."""
    flux, exact = _flux(distance, 0.5, RadiositySettings().light_samples_per_side)
    assert flux == pytest.approx(exact, rel=1e-3)


@pytest.mark.parametrize("off", [(0.0, 0.0), (0.03, 0.07), (0.25, 0.0)])
def test_first_shot_flux_of_a_lamp_5cm_under_a_ceiling(off):
    """5 cm under 0.5 m patches, on a patch's corner, off it and at a patch's centre: the
    plate receives I * solid angle (without the exact patch integral: -10.8% on the axis,
    +10.6% 3 and 7 cm off)."""
    flux, exact = _flux(0.05, 0.5, RadiositySettings().light_samples_per_side, off)
    assert flux == pytest.approx(exact, rel=1e-3)
