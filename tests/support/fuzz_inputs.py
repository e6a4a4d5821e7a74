"""Hypothesis strategies for fuzzing the kernels (tests/kernels/test_fuzz_*.py): small random
meshes drawn from a pool of vertices (so shared corners, duplicated and zero-area triangles are
common), rays (zero-length and axis-parallel directions included), lights, materials, cameras and
whole `Scene`s, plus the settings every fuzz test runs under.

The answers the fuzz tests accept: a finite result, or a ValueError whose message says what was
wrong (`documented_error`)."""

from __future__ import annotations

import contextlib

import numpy as np
from hypothesis import HealthCheck, Phase, settings
from hypothesis import strategies as st
from scene_builder import build, ortho_camera, persp_camera

from classic_bake.kernels.geometry.scene import Light, Material

# A fuzz test is a smoke test over many shapes, not a proof: few examples each, drawn from a fixed
# seed (derandomize) so that a run is repeatable and the files stay within seconds on two cores.
FUZZ_EXAMPLES = 12
# Whole-technique fuzzing (tracer, radiosity, xatlas) costs 0.1 - 1 s per example.
FUZZ_EXAMPLES_SLOW = 6

fuzz = settings(
    max_examples=FUZZ_EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                           HealthCheck.filter_too_much],
)
# Shrinking a failure of a slow kernel takes minutes: report the example as drawn.
fuzz_slow = settings(fuzz, max_examples=FUZZ_EXAMPLES_SLOW,
                     phases=(Phase.explicit, Phase.reuse, Phase.generate))

coordinate = st.one_of(
    st.integers(-2, 2).map(float),
    st.floats(-3.0, 3.0, allow_nan=False, width=32),
)
point = st.tuples(coordinate, coordinate, coordinate)
unit_interval = st.floats(0.0, 1.0, allow_nan=False)


@st.composite
def meshes(draw, min_triangles: int = 0, max_triangles: int = 24) -> np.ndarray:
    """(T, 3, 3) float32 triangles whose corners come from a pool of up to 10 points."""
    pool = np.array(draw(st.lists(point, min_size=3, max_size=10)), np.float32)
    corner = st.integers(0, len(pool) - 1)
    corners = draw(st.lists(st.tuples(corner, corner, corner), min_size=min_triangles,
                            max_size=max_triangles))
    if not corners:
        return np.zeros((0, 3, 3), np.float32)
    return pool[np.array(corners, np.int64)]


@st.composite
def rays(draw, count: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(origins (R, 3), directions (R, 3)) float32: random, axis-parallel and zero directions."""
    n = count or draw(st.integers(1, 24))
    origins = np.array(draw(st.lists(point, min_size=n, max_size=n)), np.float32)
    free = np.array(draw(st.lists(point, min_size=n, max_size=n)), np.float32)
    kind = np.array(draw(st.lists(st.integers(0, 3), min_size=n, max_size=n)))
    axis = np.eye(3, dtype=np.float32)[np.arange(n) % 3] * np.where(np.arange(n) % 2, -1, 1)[:, None]
    dirs = np.where((kind == 1)[:, None], axis, free)
    dirs = np.where((kind == 2)[:, None], 0.0, dirs)  # zero-length: documented to miss
    return origins, dirs.astype(np.float32)


def _frame(direction: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    d = direction / np.linalg.norm(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    axis_y = np.cross(-d, helper)
    axis_y /= np.linalg.norm(axis_y)
    return d, np.cross(axis_y, -d), axis_y


directions = st.tuples(coordinate, coordinate, coordinate).map(np.array).filter(
    lambda d: np.linalg.norm(d) > 1e-3)


@st.composite
def lights(draw) -> Light:
    kind = draw(st.sampled_from(["POINT", "SPOT", "SUN", "AREA"]))
    d, x, y = _frame(draw(directions))
    power = np.full(3, draw(st.floats(0.0, 50.0)))
    return Light(
        f"fuzz {kind.lower()}", kind, np.array(draw(point), float), d, x, y,
        intensity=power if kind in ("POINT", "SPOT") else None,
        irradiance=power if kind == "SUN" else None,
        radiance=power if kind == "AREA" else None,
        radius=draw(st.sampled_from([0.0, 0.1])),
        angle=draw(st.sampled_from([0.0, 0.05])),
        spot_size=draw(st.floats(0.05, np.pi)),
        spot_blend=draw(unit_interval),
        size_x=draw(st.sampled_from([0.0, 0.5])), size_y=draw(st.sampled_from([0.0, 0.5])),
        cast_shadow=draw(st.booleans()),
    )


@st.composite
def materials(draw) -> Material:
    return Material(
        name="fuzz",
        base_color=np.full(3, draw(unit_interval), np.float32),
        metallic=draw(st.sampled_from([0.0, 0.0, 1.0])),
        roughness=draw(unit_interval),
        ior=draw(st.floats(1.0, 2.5)),
        transmission=draw(st.sampled_from([0.0, 0.0, 1.0])),
        specular=draw(st.sampled_from([0.0, 0.5])),
        emission=np.full(3, draw(st.sampled_from([0.0, 0.0, 5.0])), np.float32),
        alpha=draw(st.sampled_from([1.0, 1.0, 0.5])),
    )


@st.composite
def cameras(draw, resolution=(6, 4)):
    position = np.array(draw(point), float) + np.array([0.0, -4.0, 1.0])
    forward = draw(directions)
    up = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.9 * np.linalg.norm(forward) else \
        np.array([0.0, 1.0, 0.0])
    if draw(st.booleans()):
        return persp_camera(position, forward, up, draw(st.floats(0.2, 2.5)), resolution)
    return ortho_camera(position, forward, up, draw(st.floats(0.5, 8.0)), resolution)


@st.composite
def scenes(draw, min_triangles: int = 1, max_triangles: int = 16, camera: bool = True):
    """A `Scene` of one to three random objects, up to two lights, a grey world and a camera."""
    parts = draw(st.lists(st.tuples(meshes(min_triangles=1, max_triangles=max_triangles),
                                    materials()), min_size=1, max_size=3))
    return build(parts, camera=draw(cameras()) if camera else None,
                 lights=draw(st.lists(lights(), max_size=2)),
                 world=(draw(st.sampled_from([0.0, 0.2])),) * 3)


def all_finite(*arrays) -> bool:
    return all(np.isfinite(np.asarray(a, np.float64)).all() for a in arrays)


@contextlib.contextmanager
def documented_error():
    """Accept a ValueError with a message (the kernels' documented refusal); anything else fails."""
    try:
        yield
    except ValueError as error:
        assert str(error).strip(), "a ValueError without a message"
