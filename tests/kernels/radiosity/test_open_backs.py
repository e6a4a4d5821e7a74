"""Emitters light from both sides, as Cycles' emission does, where their back faces open space
(kernels/radiosity/emitters.py: `open_backs`, `emitters_of`)."""

import numpy as np
from scene_builder import build, grey, quad

from classic_bake.kernels.geometry.bvh import BVH
from classic_bake.kernels.radiosity.emitters import (
    OPEN_BACK_GAP,
    emitter_irradiance,
    emitters_of,
    open_backs,
)
from classic_bake.kernels.radiosity.settings import FinalGatherSettings

L_E = 3.0


def _lamp(z, side=1.0):
    """A side x side emissive quad at height z facing down (-z), centred on the origin."""
    h = side / 2
    return quad([[-h, -h, z], [-h, h, z], [h, h, z], [h, -h, z]])


def _ceiling(z):
    return quad([[-3, -3, z], [-3, 3, z], [3, 3, z], [3, -3, z]])  # facing down


def _square_factor(half: float, height: float) -> float:
    """Point-to-square form factor for a point under the centre of a square of half-side `half`
    at `height`, facing it (four corner rectangles of the standard closed form)."""
    x = y = half / height
    corner = (x / np.sqrt(1 + x * x) * np.arctan(y / np.sqrt(1 + x * x))
              + y / np.sqrt(1 + y * y) * np.arctan(x / np.sqrt(1 + y * y))) / (2 * np.pi)
    return 4 * corner


def test_a_hanging_lamp_lights_the_ceiling_with_its_back():
    scene = build([(_lamp(1.0), grey(0.5, L_E)), (_ceiling(2.0), grey(0.8))])
    bvh = BVH.build(scene.triangles)
    open_back = open_backs(scene, bvh, 1e-5)
    assert open_back[:2].all() and not open_back[2:].any()  # only the lamp emits
    emitters = emitters_of(scene, FinalGatherSettings(), open_back)
    assert len(emitters.triangles) == 4 and (emitters.normals[2:, 2] > 0).all()  # backs face up
    point, down = np.array([[0.0, 0.0, 2.0]]), np.array([[0.0, 0.0, -1.0]])
    rng = np.random.default_rng(0)
    e = emitter_irradiance(emitters, point, down, bvh.occluded, 1e-5, rng)
    np.testing.assert_allclose(e[0], np.pi * L_E * _square_factor(0.5, 1.0), rtol=1e-6)
    one_sided = emitters_of(scene, FinalGatherSettings())
    assert emitter_irradiance(one_sided, point, down, bvh.occluded, 1e-5, rng).max() == 0.0


def test_a_lamp_flush_under_a_ceiling_and_a_closed_emitter_keep_their_backs_dark():
    gap = 0.5 * OPEN_BACK_GAP  # of the lamp's 1 m size
    flush = build([(_lamp(2.0 - gap), grey(0.5, L_E)), (_ceiling(2.0), grey(0.8))])
    assert not open_backs(flush, BVH.build(flush.triangles), 1e-5).any()
    cube = np.concatenate([quad(f) for f in (
        [[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]], [[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]],
        [[0, 0, 0], [1, 0, 0], [1, 0, 1], [0, 0, 1]], [[1, 0, 0], [1, 1, 0], [1, 1, 1], [1, 0, 1]],
        [[1, 1, 0], [0, 1, 0], [0, 1, 1], [1, 1, 1]], [[0, 1, 0], [0, 0, 0], [0, 0, 1], [0, 1, 1]])])
    closed = build([(cube, grey(0.5, L_E))])  # outward faces: the backs face the inside
    assert not open_backs(closed, BVH.build(closed.triangles), 1e-5).any()
