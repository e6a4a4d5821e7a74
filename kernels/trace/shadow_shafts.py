"""Which hits see a light whole: their shadow rays to it need not be cast.

If no scene triangle enters the convex hull of a receiver triangle and an emitter (the shaft of
`geometry/shafts.py`: an area light's rectangle, a point lamp's position, or the receiver swept
towards a sun), every point of the receiver sees every point of the emitter, so a shadow ray
from a hit there to any of the emitter's samples is unblocked: visibility exactly 1, the answer
the ray would give. With 16 samples a hit, an area light's shadow rays are most of a lit room's
work, and most of them are unblocked (a furnished room's cube-map capture: 80%).

A shaft test costs about as much as a hundred shadow rays, so only receivers that many of the
view's hits land on are tested: those holding a share of the scene's area that, times the view's
pixels and the shadow rays a hit casts to the emitter, reaches SHAFT_WORTH (a room's walls and
floor, not a fine mesh's triangles, which cast their rays as before). A receiver whose shaft is
blocked (a floor triangle under a table) may still see the light whole over most of its area: its
four midpoint children are tested, while they are large enough, and so on down to LEVELS
subdivisions, each hit following its barycentrics into the part that holds it. Answers are kept for
the tracer's life. Every such receiver a hit asks about is tested, so a hit's answer depends on the
scene, the view's size and the hit alone, not on which rays came first: the same whether it is
traced with the whole view or with a tile of it, at any samples per pixel (a ray can differ from
its clear shaft only by rounding: a hit on the edge where a ceiling meets a wall, offset a hair
outside the room, meets the wall).

Receivers are coded per level: a triangle's index at level 0, then code * 4 + child (0..2 the
corner children of corners 0..2, 3 the middle one) at each level down.
"""

from __future__ import annotations

import numpy as np

from ..geometry import shafts
from ..geometry.scene import triangle_areas

# A receiver is tested for an emitter when its share of the scene's area, times the view's pixels,
# times the shadow rays a hit casts to the emitter, reaches this: the shadow rays it would
# take if the view saw the whole scene evenly. One triangle pair costs about as much as ~100
# shadow rays (85 us against ~1 us, measured on a furnished room), a lamp's rectangle two pairs,
# and about half the receivers come out clear. At 256: a furnished room's cube map (6 x 56^2
# texels, 16 rays a hit) tests receivers of 1/1176 of its area (a flat 1/256, 1/1024, 1/4096
# there: 1/1024 the fastest); a 192 x 144 view of two point lamps none (a flat 1/1024 cost 0.07
# of its 0.27 s, more than the rays it saved); the clear rays outweigh the tests' seconds on
# raytrace.blend, bump.blend, shadows.blend and the Cornell box (256 against 1024 and no shafts).
SHAFT_WORTH = 256.0
# The view's pixels when the tracer is not told (a 256 x 256 image).
VIEW_PIXELS = 65536
# Subdivision levels below a triangle: 4^4 = 256 parts at the finest.
LEVELS = 4
# Receiver states: not tested yet (only triangles, level 0, are ever untested: parts are tested
# when their parent splits); sees the emitter whole; blocked, and too small or too deep to split;
# blocked, its children not tested yet; split, its children tested.
_UNTESTED, _CLEAR, _BLOCKED, _OPEN, _SPLIT = 0, 1, 2, 3, 4


class _Parts:
    """The parts of one level below the triangles met so far: sorted codes and their states."""

    def __init__(self) -> None:
        self.codes = np.zeros(0, np.int64)
        self.state = np.zeros(0, np.int8)

    def rows(self, codes: np.ndarray) -> np.ndarray:
        """Rows of `codes` (every one in the table) in it."""
        return np.searchsorted(self.codes, codes)

    def add(self, codes: np.ndarray, states: np.ndarray) -> None:
        """New parts (codes not in the table) with their states."""
        merged = np.concatenate([self.codes, codes])
        order = np.argsort(merged, kind="stable")
        self.codes = merged[order]
        self.state = np.concatenate([self.state, states])[order]


def children(corners: np.ndarray) -> np.ndarray:
    """(R, 4, 3, 3): the midpoint subdivision of triangles (R, 3, 3): child k < 3 keeps corner k,
    child 3 is the middle one (corners: the midpoints of edges 12, 20, 01)."""
    v0, v1, v2 = corners[:, 0], corners[:, 1], corners[:, 2]
    m01, m12, m20 = 0.5 * (v0 + v1), 0.5 * (v1 + v2), 0.5 * (v2 + v0)
    return np.stack([np.stack(c, axis=1) for c in
                     ((v0, m01, m20), (m01, v1, m12), (m20, m12, v2), (m12, m20, m01))], axis=1)


def child_of(bary: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The child (N,) int (as `children`) holding each point of barycentrics bary (N, 3), and the
    point's barycentrics (N, 3) in it: 2b with 2b_k - 1 at the kept corner k, or 1 - 2b in the
    middle."""
    corner = np.argmax(bary, axis=1)
    inner = bary[np.arange(len(bary)), corner] < 0.5  # no barycentric reaches 1/2: the middle
    child = np.where(inner, 3, corner)
    inside = 2.0 * bary
    inside[np.arange(len(bary)), corner] -= 1.0
    return child, np.where(inner[:, None], 1.0 - 2.0 * bary, inside)


class ClearShafts:
    """The shafts between a scene's triangles and its lights, tested as hits ask for them.

    triangles (T, 3, 3) world m: the receivers (the triangles rays hit); hulls: per emitter
    (K, 3, 3) world m triangles holding all of it, or a (3,) translation m (a sun: the shaft is
    the receiver swept along it), or None (never tested: always cast rays); rays (E,): the shadow
    rays a hit casts to each emitter; bvh: the geometry that may block shadow rays; slack m: the
    rays' offset off surfaces; view_pixels: the pixels of the whole view traced, supersampled
    or not (a tile's tracer is told the whole view's, so its answers are the whole view's, and
    a view's answers do not change with its samples per pixel)."""

    def __init__(self, triangles: np.ndarray, hulls: list, rays, bvh, slack: float,
                 view_pixels: int | None = None):
        self.triangles = triangles
        self.hulls = hulls
        self.bvh = bvh
        self.slack = slack
        self.areas = triangle_areas(np.asarray(triangles))  # (T,) m^2
        # (E,) m^2: the least receiver tested for each emitter
        per_hit = np.maximum(np.asarray(rays, np.float64).reshape(len(hulls)), 1.0)
        self.min_area = SHAFT_WORTH * float(self.areas.sum()) / (per_hit * (view_pixels or VIEW_PIXELS))
        # Per emitter: the triangles' states (T,) int8, allocated at its first use, and the
        # parts of levels 1..LEVELS.
        self._triangles: list[np.ndarray | None] = [None] * len(hulls)
        self._parts = [[_Parts() for _ in range(LEVELS)] for _ in hulls]
        self.tested_pairs = 0  # receiver-emitter triangle pairs whose shaft was tested

    def clear(self, e: int, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
        """(N,) bool: the hit on triangle tri[n] (N,) int at barycentrics bary[n] (N, 3) (of its
        corners 0, 1, 2) sees emitter e whole. Ask only for the hits that would cast shadow rays
        to e: every large receiver asked about is tested."""
        tri = np.asarray(tri, np.int64)
        large = self.areas[tri] >= self.min_area[e]
        out = np.zeros(len(tri), bool)
        if self.hulls[e] is not None and large.any():
            out[large] = self._clear(e, tri[large], bary[large])
        return out

    def _clear(self, e: int, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
        if self._triangles[e] is None:
            self._triangles[e] = np.zeros(len(self.triangles), np.int8)
        states = self._triangles[e]
        fresh = np.unique(tri[states[tri] == _UNTESTED])
        if fresh.size:
            states[fresh] = self._states(e, fresh, 0, self._test(self._corners(fresh, 0), e))
        out = np.zeros(len(tri), bool)
        hits, code = np.arange(len(tri)), tri
        for level in range(LEVELS + 1):
            parts = None if level == 0 else self._parts[e][level - 1]
            rows = code if parts is None else parts.rows(code)
            table = states if parts is None else parts.state
            state = table[rows]
            if (state == _OPEN).any():  # test the children of the blocked receivers hit
                nodes, at = np.unique(code[state == _OPEN], return_index=True)
                kids = 4 * nodes[:, None] + np.arange(4)  # (R, 4)
                seen = self._test(children(self._corners(nodes, level)).reshape(-1, 3, 3), e)
                self._parts[e][level].add(kids.ravel(),
                                          self._states(e, kids.ravel(), level + 1, seen))
                table[rows[state == _OPEN][at]] = _SPLIT
                state = table[rows]
            out[hits[state == _CLEAR]] = True
            down = state == _SPLIT
            if not down.any():
                break
            child, bary = child_of(bary[down])
            hits, code = hits[down], 4 * code[down] + child
        return out

    def _states(self, e: int, codes: np.ndarray, level: int, seen: np.ndarray) -> np.ndarray:
        """(R,) int8 states of receivers `codes` (R,) of `level` after their test for emitter e
        (seen (R,))."""
        area = self.areas[codes >> (2 * level)] / 4.0**level
        can_split = (level < LEVELS) & (area / 4.0 >= self.min_area[e])
        return np.where(seen, _CLEAR, np.where(can_split, _OPEN, _BLOCKED)).astype(np.int8)

    def _corners(self, codes: np.ndarray, level: int) -> np.ndarray:
        """(R, 3, 3) world m: the receivers `codes` (R,) of `level`, their triangle subdivided
        along their codes' digits."""
        corners = self.triangles[codes >> (2 * level)].astype(np.float64)
        for k in range(level):
            digit = (codes >> (2 * (level - 1 - k))) & 3
            corners = children(corners)[np.arange(len(codes)), digit]
        return corners

    def _test(self, receivers: np.ndarray, e: int) -> np.ndarray:
        """(R,) bool: receivers (R, 3, 3) see every triangle of emitter e's hull whole (or, for
        a translation, nothing lies on their way along it)."""
        hull = self.hulls[e]
        if hull.ndim == 1:
            self.tested_pairs += len(receivers)
            return shafts.clear_pairs(receivers, receivers + hull, self.bvh, self.slack)
        k = len(hull)
        self.tested_pairs += len(receivers) * k
        pairs = shafts.clear_pairs(np.repeat(receivers, k, axis=0),
                                   np.tile(hull, (len(receivers), 1, 1)), self.bvh, self.slack)
        return pairs.reshape(-1, k).all(axis=1)
