"""A point lamp close to a surface: the light its first shot gives the patches against the
closed form (found by bench/generated.py: a point lamp 5 cm under a room's ceiling left the
camera view 11.6% brighter than converged Cycles; 20 cm under it, within 0.4%)."""

from __future__ import annotations

import numpy as np
import pytest
from scene_builder import build, grey, quad

from classic_bake.kernels.geometry.scene import Light
from classic_bake.kernels.radiosity import patches as patching
from classic_bake.kernels.radiosity.settings import RadiositySettings
from classic_bake.kernels.radiosity.sources import first_shot

HALF_SIDE = 1.0  # a 2 m x 2 m plate at z = 0, facing down (a ceiling)


def _flux(distance: float, patch_size: float, samples_per_side: int) -> tuple[float, float]:
    """(the first shot's flux onto the plate, W; the closed form I * solid angle) for a point
    lamp of intensity 1 W/sr at `distance` under the plate's centre."""
    a = HALF_SIDE
    plate = quad([[-a, -a, 0.0], [-a, a, 0.0], [a, a, 0.0], [a, -a, 0.0]])
    lamp = Light(name="Lamp", kind="POINT", position=np.array([0.0, 0.0, -distance]),
                 direction=np.array([0, 0, -1.0]), axis_x=np.array([1.0, 0, 0]),
                 axis_y=np.array([0, 1.0, 0]), intensity=np.full(3, 1.0))
    scene = build([(plate, grey(0.5))], lights=(lamp,))
    patches = patching.make_patches(scene, patch_size)
    never = lambda o, d, t0, t1: np.zeros(len(o), bool)  # noqa: E731
    h, _ = first_shot(scene, patches, never,
                      RadiositySettings(light_samples_per_side=samples_per_side), 1.0)
    # The solid angle of a square of half side a seen from distance d on its axis.
    solid_angle = 4.0 * np.arcsin(a * a / (a * a + distance * distance))
    return float(np.sum(h[:, 0] * patches.areas)), float(solid_angle)


@pytest.mark.parametrize("distance", [0.2, 0.5])
def test_first_shot_flux_of_a_lamp_under_a_ceiling(distance):
    """A lamp 20 cm or more under the plate: the patches receive I * solid angle (0.1%)."""
    flux, exact = _flux(distance, 0.5, RadiositySettings().light_samples_per_side)
    assert flux == pytest.approx(exact, rel=1e-3)


@pytest.mark.xfail(strict=True, reason="the first shot's 3 x 3 points per patch side over- or "
                   "under-sample I cos / d^2 where a point lamp is much closer to a patch than "
                   "the patch is wide. Measured 5 cm under 0.5 m patches: -10.8% flux with the "
                   "lamp on the plate's axis, +10.6% with it 3 and 7 cm off; 8 x 8 points: "
                   "within 0.2%, 0.25 m patches: within 0.7%")
def test_first_shot_flux_of_a_lamp_5cm_under_a_ceiling():
    flux, exact = _flux(0.05, 0.5, RadiositySettings().light_samples_per_side)
    assert flux == pytest.approx(exact, rel=0.01)
