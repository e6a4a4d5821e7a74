"""Opposite faces sharing a plane (kernels/geometry/coincident.py)."""

from __future__ import annotations

import numpy as np
from scene_builder import quad

from classic_bake.kernels.geometry.coincident import CoincidentFaces
from classic_bake.kernels.geometry.scene import geometric_normals


def test_a_box_bottom_covers_the_floor_under_it_only():
    """A 2 m floor facing up and a 0.5 m square facing down in its plane (a box's bottom), and a
    square facing down 1 m up: floor hits under the bottom are covered, beside it not; the bottom's
    own hits are covered by the floor; the raised square is in no plane of the floor's."""
    floor = quad([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    bottom = quad([[0, 0, 0], [0, 0.5, 0], [0.5, 0.5, 0], [0.5, 0, 0]])
    raised = quad([[0, 0, 1], [0, 0.5, 1], [0.5, 0.5, 1], [0.5, 0, 1]])
    tris = np.concatenate([floor, bottom, raised])
    faces = CoincidentFaces.find(tris, geometric_normals(tris), 1e-6)
    points = np.array([[0.25, 0.25, 0.0], [0.4, 0.1, 0.0], [0.7, 0.25, 0.0], [-0.5, -0.5, 0.0]])
    assert faces.covered(np.array([0, 0, 1, 1]), points).tolist() == [True, True, False, False]
    assert faces.covered(np.array([2, 3]), points[:2]).tolist() == [True, True]
    assert not faces.covered(np.array([4, 5]), points[:2] + [0, 0, 1.0]).any()
