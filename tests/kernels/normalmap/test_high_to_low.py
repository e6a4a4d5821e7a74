"""High -> low normal-map bakes (kernels/normalmap/high_to_low.py) on analytic cases: a unit
square low mesh under a high mesh whose normals are known, the cage's reach, back faces, misses
and the round trip through the Normal Map node's decoding."""

import numpy as np
import pytest

from classic_bake.kernels.normalmap.encode import rgb_to_normals
from classic_bake.kernels.normalmap.from_height import NormalMapSettings
from classic_bake.kernels.normalmap.high_to_low import (
    HighMesh,
    HighToLowSettings,
    LowMesh,
    automatic_cage,
    high_to_low_steps,
    world_to_tangent,
)
from classic_bake.kernels.normalmap.mikktspace import tangent_to_object
from classic_bake.kernels.progress import drain

SIZE = 16
SQUARE = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, 1, 0]]], float)
SQUARE_UV = SQUARE[..., :2]


def low_square(tangent=(1.0, 0.0, 0.0), sign=1.0) -> LowMesh:
    """The unit square in z = 0, normal +z, UVs = (x, y): t = +x, b = +y."""
    return LowMesh(uv=SQUARE_UV, positions=SQUARE, normals=np.broadcast_to([0, 0, 1.0], (2, 3, 3)),
                   tangents=np.broadcast_to(tangent, (2, 3, 3)), signs=np.full((2, 3), sign))


def high_square(z: float, normal, flip: bool = False) -> HighMesh:
    """A square larger than the low one at height z, every corner normal `normal`."""
    tris = SQUARE * [3.0, 3.0, 0.0] + [-1.0, -1.0, z]
    if flip:
        tris = tris[:, ::-1]
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    return HighMesh(triangles=tris, normals=np.broadcast_to(n, (2, 3, 3)))


def bake(low, high, **settings):
    return drain(high_to_low_steps(low, high, NormalMapSettings(size=SIZE, padding=0),
                                   HighToLowSettings(**settings)))


def test_the_high_normal_comes_back_through_the_tangent_frame():
    tilted = np.array([0.3, -0.2, 0.9])
    made = bake(low_square(), high_square(0.05, tilted), cage=0.1)
    assert made.misses == 0 and made.chart_texels == SIZE * SIZE
    decoded = rgb_to_normals(made.rgb[made.mask])
    np.testing.assert_allclose(decoded, np.broadcast_to(tilted / np.linalg.norm(tilted),
                                                        decoded.shape), atol=1e-6)


def test_a_mirrored_frame_flips_green():
    tilted = np.array([0.3, -0.2, 0.9])
    made = bake(low_square(sign=-1.0), high_square(-0.05, tilted), cage=0.1)
    decoded = rgb_to_normals(made.rgb[made.mask])
    expected = np.array([0.3, 0.2, 0.9]) / np.linalg.norm(tilted)
    np.testing.assert_allclose(decoded, np.broadcast_to(expected, decoded.shape), atol=1e-6)


def test_out_of_reach_and_back_faces_are_flat_misses():
    far = bake(low_square(), high_square(0.5, [0.3, 0, 1]), cage=0.1)
    assert far.misses == SIZE * SIZE and far.back_faces == 0
    np.testing.assert_allclose(far.normals[far.mask], np.broadcast_to([0, 0, 1], (SIZE * SIZE, 3)))
    below = bake(low_square(), high_square(-0.08, [0.3, 0, 1]), cage=0.1)  # within 2 x cage
    assert below.misses == 0
    back = bake(low_square(), high_square(0.05, [0.3, 0, 1], flip=True), cage=0.1)
    assert back.misses == back.back_faces == SIZE * SIZE


def test_closest_of_two_layers_wins():
    near, far = high_square(0.08, [0.3, 0, 1]), high_square(-0.05, [-0.3, 0, 1])
    both = HighMesh(np.concatenate([far.triangles, near.triangles]),
                    np.concatenate([far.normals, near.normals]))
    made = bake(low_square(), both, cage=0.1)
    assert (made.normals[made.mask][:, 0] > 0.2).all()


@pytest.mark.parametrize("seed", [1, 2])
def test_world_to_tangent_inverts_the_normal_map_decoding(seed):
    rng = np.random.default_rng(seed)
    n = rng.normal(size=(50, 3)) * [0.2, 0.2, 1.0] + [0, 0, 1.0]  # unnormalised, as interpolated
    t = rng.normal(size=(50, 3)) * 0.2 + [1.0, 0, 0]
    signs = np.where(rng.random(50) < 0.5, -1.0, 1.0)
    local = rng.normal(size=(50, 3)) * [0.4, 0.4, 0.1] + [0, 0, 1.0]
    local /= np.linalg.norm(local, axis=1, keepdims=True)
    world = tangent_to_object(local, n, t, signs)
    np.testing.assert_allclose(world_to_tangent(world, n, t, signs), local, atol=1e-9)


def test_automatic_cage_covers_a_bulging_high_mesh():
    low = SQUARE
    high = high_square(0.3, [0, 0, 1]).triangles
    cage = automatic_cage(low, high)
    assert cage >= 0.3 * 1.5
