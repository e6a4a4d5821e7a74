"""Opposite faces sharing a plane (kernels/geometry/coincident.py)."""

from __future__ import annotations

import numpy as np
from scene_builder import quad

from classic_bake.kernels.geometry.coincident import CoincidentFaces
from classic_bake.kernels.geometry.scene import geometric_normals


def test_a_box_bottom_covers_the_floor_under_it_only():
    """A 2 m floor facing up, a 0.5 m square facing down in its plane (a box's bottom, its object
    reaching 0.5 m up behind it), and a square facing down 1 m up: floor hits under the bottom are
    covered, beside it not; the bottom's own hits are covered by the floor (a box lies under it);
    the raised square is in no plane of the floor's."""
    floor = quad([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    bottom = quad([[0, 0, 0], [0, 0.5, 0], [0.5, 0.5, 0], [0.5, 0, 0]])
    top = quad([[0, 0, 0.5], [0.5, 0, 0.5], [0.5, 0.5, 0.5], [0, 0.5, 0.5]])
    raised = quad([[0, 0, 1], [0, 0.5, 1], [0.5, 0.5, 1], [0.5, 0, 1]])
    ground = quad([[-1, -1, -0.3], [1, -1, -0.3], [1, 1, -0.3], [-1, 1, -0.3]])
    tris = np.concatenate([floor, ground, bottom, top, raised])
    objects = np.array([0, 0, 0, 0, 1, 1, 1, 1, 2, 2])  # the floor a slab 0.3 m thick
    faces = CoincidentFaces.find(tris, geometric_normals(tris), objects, 1e-6)
    points = np.array([[0.25, 0.25, 0.0], [0.4, 0.1, 0.0], [0.7, 0.25, 0.0], [-0.5, -0.5, 0.0]])
    assert faces.covered(np.array([0, 0, 1, 1]), points).tolist() == [True, True, False, False]
    assert faces.covered(np.array([4, 5]), points[:2]).tolist() == [True, True]
    assert not faces.covered(np.array([8, 9]), points[:2] + [0, 0, 1.0]).any()
    # Both have a solid behind them: the box above the floor's plane, the slab below it.
    assert faces.covered(np.array([0, 0, 1, 1]), points, solid=True).tolist() == [
        True, True, False, False]
    assert faces.solid[[0, 1, 4, 5]].all() and not faces.solid[[8, 9]].any()


def test_a_sheet_modelled_double_sided_is_no_solid():
    """Two opposite 1 m squares in one plane, one object or two, nothing behind either (a sheet
    modelled double-sided): each covers the other, and neither is a solid to leave."""
    front = quad([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    back = quad([[0, 0, 0], [0, 1, 0], [1, 1, 0], [1, 0, 0]])
    tris = np.concatenate([front, back])
    normals = geometric_normals(tris)
    points = np.array([[0.3, 0.3, 0.0], [0.7, 0.6, 0.0]])
    for objects in ([0, 0, 0, 0], [0, 0, 1, 1]):
        faces = CoincidentFaces.find(tris, normals, np.array(objects), 1e-6)
        assert faces.covered(np.array([0, 2]), points).all()
        assert not faces.covered(np.array([0, 2]), points, solid=True).any()
        assert not faces.solid.any()
