"""Method B: the ray-cast point-to-polygon factor, the area average of the exact factor times a
visible fraction by shadow rays (see `form_factors`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...geometry.frames import RAY_OFFSET_REL
from .point_polygon import point_to_polygon
from .rays import (
    MAX_RAYS_PER_CALL,
    RAYS_PER_BATCH,
    Occluded,
    RayRequests,
    answer_rays,
    answer_rays_together,
)
from .sampling import SampleRule, as_corners, check_rule, patch_geometry, sample_patches
from .visibility import visible_fraction_steps

# A patch is on one side of a triangle's plane when all its corners are within this fraction of
# the scene diagonal of that side (the quick unoccluded-pair test; a looser value only sends more
# pairs to the ray tests).
SIDE_EPS_REL = 1e-7
# Two patches whose areas differ by less than this fraction count as equal (rounding of areas of
# identical subdivided quads is ~1e-16): method B integrates such a pair over the lower index.
AREA_TIE_REL = 1e-9


@dataclass(frozen=True)
class RayCastSettings:
    """Method B: area average of the exact point-to-polygon factor times a visible fraction.

    | field                       | range      | default | meaning                               |
    |-----------------------------|------------|---------|---------------------------------------|
    | samples_per_side            | >= 1       | 4       | n: n x n points x on patch i          |
    | source_rule                 | gauss /    | gauss   | their placement and weights           |
    |                             | stratified |         | (`sample_patches`)                    |
    |                             | / midpoint |         |                                       |
    | visibility_samples_per_side | >= 1       | 3       | m: m x m points on patch j, one ray   |
    |                             |            |         | from each point of i to each of j     |
    | visibility_rule             | as above   | stratified | placement of the points on j       |
    | integrate_smaller           | bool       | True    | integrate each pair over its smaller  |
    |                             |            |         | patch, F_ij = A_j F_ji / A_i          |
    | near_field_cells            | >= 1       | 4       | near pairs: the unoccluded factor from|
    |                             |            |         | cells^2 sub-squares of n x n points   |
    | near_field_distance         | >= 0       | 1.0     | near: the patches' boxes closer than  |
    |                             |            |         | this x the integrating patch's size   |
    | quick_test                  | bool       | True    | prove pairs unoccluded by plane and   |
    |                             |            |         | box tests on the scene's triangles    |
    |                             |            |         | (cost O(T N) per row)                 |
    | seed                        | int        | 0       | RNG seed of the stratified points     |
    | ray_offset                  | >= 0, None | None    | m; None: RAY_OFFSET_REL x diagonal    |
    | max_rays_per_call           | >= 1       | 2^18    | rays per `occluded` call              |

    Estimator: F_ij = U_ij V_ij with U_ij = sum_s w_s F(x_s -> j), the unoccluded factor, and
    V_ij = sum_s w_s F(x_s -> j) v_s(j) / U_ij, the visible share; v_s(j) weights each ray to a
    point y of j by the point-to-point kernel cos_x cos_y / s^2 (and y's area weight), so it
    converges to the visible share of the projected solid angle (a plain count of rays would
    weight far parts of j too much). Near pairs take U_ij from the finer near-field rule (cheap:
    closed forms only) and V_ij from the n x n points. Rays per row: n^2 m^2 per pair that is not
    proven unoccluded.
    """

    samples_per_side: int = 4
    source_rule: SampleRule = "gauss"
    visibility_samples_per_side: int = 3
    visibility_rule: SampleRule = "stratified"
    integrate_smaller: bool = True
    near_field_cells: int = 4
    near_field_distance: float = 1.0
    quick_test: bool = True
    seed: int = 0
    ray_offset: float | None = None
    max_rays_per_call: int = MAX_RAYS_PER_CALL

    def __post_init__(self) -> None:
        if self.samples_per_side < 1 or self.visibility_samples_per_side < 1:
            raise ValueError("samples_per_side and visibility_samples_per_side must be >= 1")
        check_rule(self.source_rule)
        check_rule(self.visibility_rule)
        if self.near_field_cells < 1 or not self.near_field_distance >= 0.0:
            raise ValueError("near_field_cells must be >= 1 and near_field_distance >= 0")
        if self.ray_offset is not None and not self.ray_offset >= 0.0:
            raise ValueError(f"ray_offset must be >= 0 m, got {self.ray_offset}")
        if self.max_rays_per_call < 1:
            raise ValueError(f"max_rays_per_call must be >= 1, got {self.max_rays_per_call}")


def raycast_gather(
    points: np.ndarray,
    normals: np.ndarray,
    weights: np.ndarray,
    corners: np.ndarray,
    corner_normals: np.ndarray,
    occluded: Occluded | None,
    settings: RayCastSettings,
    rng: np.random.Generator | None,
    *,
    ray_offset: float,
    maybe_occluded: np.ndarray | None = None,
    target_samples: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Method B from weighted receiver points to N polygons; F_j = unoccluded_j x visible_j.

    (`raycast_gather_steps` is the same as a generator asking for its rays.)

    points (S, 3), normals (S, 3) or (3,) unit, weights (S,) summing to 1; corners (N, K, 3) and
    their unit normals (N, 3); occluded None: no rays (visible = 1); maybe_occluded (N,) bool:
    only these targets are ray-tested (None: every target with a nonzero factor);
    target_samples: visibility points of every polygon, (N, M, 3) and weights (N, M) (None:
    drawn here with `rng`). Returns unoccluded (N,) sum_s w_s F(x_s -> j) and visible (N,) in
    [0, 1], the F-weighted visible share (module doc, `RayCastSettings`).
    """
    steps = raycast_gather_steps(points, normals, weights, corners, corner_normals,
                                 occluded is not None, settings, rng, ray_offset=ray_offset,
                                 maybe_occluded=maybe_occluded, target_samples=target_samples)
    return answer_rays(steps, occluded, settings.max_rays_per_call)


def raycast_gather_steps(points, normals, weights, corners, corner_normals, trace: bool,
                         settings: RayCastSettings, rng, *, ray_offset: float,
                         maybe_occluded=None, target_samples=None) -> RayRequests:
    """`raycast_gather` as a generator asking for its shadow rays; `trace` False: none."""
    normals = np.broadcast_to(np.asarray(normals, np.float64), points.shape)
    # (S, N) exact unoccluded factors from each receiver point to every polygon.
    factors = point_to_polygon(
        points[:, None, :], normals[:, None, :], corners[None], corner_normals[None]
    )
    unoccluded = weights @ factors
    visible = np.ones(len(corners), np.float64)
    if not trace:
        return unoccluded, visible
    candidates = unoccluded > 0.0
    if maybe_occluded is not None:
        candidates &= maybe_occluded
    targets = np.flatnonzero(candidates)
    if targets.size:
        if target_samples is None:
            y, wy = sample_patches(
                corners[targets], settings.visibility_samples_per_side,
                settings.visibility_rule, rng,
            )
        else:
            y, wy = target_samples[0][targets], target_samples[1][targets]
        share = yield from visible_fraction_steps(
            points, normals, y, wy, corner_normals[targets], ray_offset
        )
        visible[targets] = (weights @ (factors[:, targets] * share)) / unoccluded[targets]
    return unoccluded, visible


class RayCastFormFactors:
    """Method B rows F_i* (see `RayCastSettings` and the module doc).

    | argument         | meaning                                                            |
    |------------------|--------------------------------------------------------------------|
    | corners          | (N, K, 3) patches                                                  |
    | occluded         | ray callback; None: the caller states no pair is occluded (a       |
    |                  | convex room), every factor is the closed form alone                |
    | triangles        | (T, 3, 3) the occluding scene, for the quick unoccluded-pair test  |
    |                  | (None: every pair with a nonzero factor is ray-tested)             |
    | known_unoccluded | (N, N) bool, pairs the caller knows are unoccluded                 |

    Near field. The points x_s integrate F_dx->j(x) over patch i; that integrand is bounded but
    varies within about dist(x, j) of patch j, so next to j (a shared edge, a T-junction, a block
    standing on a floor) an n x n rule is coarse. Two remedies: each pair is integrated over its
    smaller patch, the other entry following by reciprocity (`integrate_smaller`: F_ij =
    A_j F_ji / A_i when A_j < A_i, equal areas over the lower index), and near pairs take their
    unoccluded factor from a composite rule of near_field_cells^2 sub-squares. Every pair is
    integrated once, over fixed points, so A_i F_ij = A_j F_ji holds exactly, occluded or not;
    row sums in a closed box are then 1 up to the quadrature error rather than to rounding.
    Two equally large slivers touching along their short sides stay the hardest case (C-14 with
    w = h = 1: l = 0.1 -0.23%, l = 0.01 -12%): keep patches near square when meshing.
    """

    def __init__(
        self,
        corners: np.ndarray,
        occluded: Occluded | None = None,
        *,
        triangles: np.ndarray | None = None,
        known_unoccluded: np.ndarray | None = None,
        settings: RayCastSettings | None = None,
    ) -> None:
        self.corners = as_corners(corners)
        self.geometry = g = patch_geometry(self.corners)
        self.occluded = occluded
        self.settings = s = settings or RayCastSettings()
        self.known_unoccluded = known_unoccluded
        self.ray_offset = RAY_OFFSET_REL * g.scale if s.ray_offset is None else s.ray_offset
        # Every patch's points (N, S, 3) and visibility points (N, M, 3), with weights, drawn
        # once: a pair integrated over patch j from row i (reverse) or from row j itself uses
        # the same points and rays.
        self.points, self.weights = sample_patches(
            self.corners, s.samples_per_side, s.source_rule, np.random.default_rng([s.seed, 1])
        )
        self.visibility_points, self.visibility_weights = sample_patches(
            self.corners, s.visibility_samples_per_side, s.visibility_rule,
            np.random.default_rng([s.seed, 2]),
        )
        self._lo = self.corners.min(axis=1)  # (N, 3) boxes, m
        self._hi = self.corners.max(axis=1)
        self._size = np.linalg.norm(self._hi - self._lo, axis=1)  # (N,) box diagonals, m
        self._sides = None
        self._fine: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # near-field points per patch
        if occluded is not None and triangles is not None and s.quick_test:
            self._sides = _SideClassifier(self.corners, np.asarray(triangles, np.float64))

    @property
    def areas(self) -> np.ndarray:
        return self.geometry.areas

    def maybe_occluded(self, i: int) -> np.ndarray:
        """(N,) bool: the pairs (i, j) that need rays (all False without `occluded`)."""
        count = len(self.corners)
        if self.occluded is None:
            return np.zeros(count, bool)
        mask = np.ones(count, bool)
        if self._sides is not None:
            mask &= self._sides.maybe_occluded(i)
        if self.known_unoccluded is not None:
            mask &= ~np.asarray(self.known_unoccluded[i], bool)
        return mask

    def integrated_over_target(self, i: int) -> np.ndarray:
        """(N,) bool: the pairs of row i integrated over the target patch j (then reciprocity)."""
        areas = self.geometry.areas
        if not self.settings.integrate_smaller:
            return np.zeros(len(areas), bool)
        tie = np.abs(areas - areas[i]) <= AREA_TIE_REL * areas[i]
        return np.where(tie, np.arange(len(areas)) < i, areas < areas[i])

    def near(self, i: int) -> np.ndarray:
        """(N,) bool: pairs whose boxes are closer than near_field_distance x the size of the
        patch they are integrated over (both rows of a pair agree)."""
        gap = np.maximum(np.maximum(self._lo - self._hi[i], self._lo[i] - self._hi), 0.0)
        size = np.where(self.integrated_over_target(i), self._size, self._size[i])
        return np.linalg.norm(gap, axis=1) < self.settings.near_field_distance * size

    def row(self, i: int, out: np.ndarray | None = None) -> np.ndarray:
        return answer_rays(self._row_steps(i, out), self.occluded, self.settings.max_rays_per_call)

    def rows(self, indices, out: np.ndarray) -> None:
        """Rows `indices` into out (len(indices), N): their shadow rays go out together, a few
        large ray-casting calls instead of one small call per row (each call costs milliseconds
        of set-up in the BVH, whatever its size)."""
        answer_rays_together([self._row_steps(int(i), out[k]) for k, i in enumerate(indices)],
                             self.occluded, self.settings.max_rays_per_call)

    def rows_per_batch(self) -> int:
        """Rows whose rays make about RAYS_PER_BATCH rays (at least one)."""
        s = self.settings
        per_row = len(self.corners) * s.samples_per_side**2 * s.visibility_samples_per_side**2
        return max(1, RAYS_PER_BATCH // max(per_row, 1))

    def _row_steps(self, i: int, out: np.ndarray | None = None) -> RayRequests:
        g = self.geometry
        rays = self.maybe_occluded(i)
        reverse = self.integrated_over_target(i)
        near = self.near(i)
        near[i] = False
        result = np.zeros(len(g.areas), np.float64) if out is None else out
        forward = np.flatnonzero(~reverse)
        unoccluded, visible = yield from raycast_gather_steps(
            self.points[i], g.normals[i], self.weights[i], self.corners[forward],
            g.normals[forward], self.occluded is not None, self.settings, None,
            ray_offset=self.ray_offset, maybe_occluded=rays[forward],
            target_samples=(self.visibility_points[forward], self.visibility_weights[forward]),
        )
        refine = near[forward]
        if refine.any() and self.settings.near_field_cells > 1:
            points, weights = self._fine_points(np.array([i]))
            unoccluded[refine] = weights[0] @ point_to_polygon(
                points[0][:, None, :], g.normals[i], self.corners[forward[refine]][None],
                g.normals[forward[refine]][None],
            )
        result[...] = 0.0
        result[forward] = unoccluded * visible
        targets = np.flatnonzero(reverse)
        if targets.size:
            result[targets] = yield from self._reverse(i, targets, rays[targets], near[targets])
        result[i] = 0.0  # a flat patch does not see itself
        return result

    def _reverse(
        self, i: int, targets: np.ndarray, rays: np.ndarray, near: np.ndarray
    ) -> RayRequests:
        """(J,) F_ij = A_j F_ji / A_i, F_ji integrated over the points of each target j."""
        g = self.geometry
        y = self.points[targets]  # (J, S, 3)
        ny = np.broadcast_to(g.normals[targets][:, None, :], y.shape)  # (J, S, 3)
        factors = point_to_polygon(y, ny, self.corners[i], g.normals[i])  # (J, S)
        wy = self.weights[targets]
        unoccluded = np.einsum("js,js->j", wy, factors)
        visible = np.ones(len(targets))
        traced = rays & (unoccluded > 0.0)  # rays is all False without `occluded`
        if traced.any():
            share = (yield from visible_fraction_steps(
                y[traced].reshape(-1, 3), ny[traced].reshape(-1, 3),
                self.visibility_points[i : i + 1], self.visibility_weights[i : i + 1],
                g.normals[i : i + 1], self.ray_offset,
            )).reshape(-1, y.shape[1])
            visible[traced] = np.einsum("js,js->j", wy[traced], factors[traced] * share)
            visible[traced] /= unoccluded[traced]
        if near.any() and self.settings.near_field_cells > 1:
            points, weights = self._fine_points(targets[near])  # (J', S', 3), (J', S')
            normals = np.broadcast_to(g.normals[targets[near]][:, None, :], points.shape)
            fine = point_to_polygon(points, normals, self.corners[i], g.normals[i])
            unoccluded[near] = np.einsum("js,js->j", weights, fine)
        return unoccluded * visible * g.areas[targets] / g.areas[i]

    def _fine_points(self, patches: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The near-field rule's points (J, S', 3) and weights (J, S') of some patches; the
        same for a patch whichever row asks (stratified: seeded by the patch index)."""
        s = self.settings
        corners = self.corners[patches]
        if s.source_rule != "stratified":
            return sample_patches(corners, s.samples_per_side, s.source_rule, None,
                                  s.near_field_cells)
        parts = []
        for k, p in enumerate(patches):
            if int(p) not in self._fine:  # drawn once per patch: rows ask for the same points
                self._fine[int(p)] = sample_patches(
                    corners[k : k + 1], s.samples_per_side, "stratified",
                    np.random.default_rng([s.seed, 3, int(p)]), s.near_field_cells)
            parts.append(self._fine[int(p)])
        return np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


class _SideClassifier:
    """Quick conservative test: which pairs (i, j) no scene triangle can come between.

    A triangle blocks no segment from patch i to patch j (grazing aside) when both patches lie in
    the same closed half-space of its plane, or when its box misses the box of the two patches
    (every segment lies in their convex hull). Memory: two (T, N) bool arrays.
    """

    def __init__(self, corners: np.ndarray, triangles: np.ndarray) -> None:
        flat = np.concatenate([corners.reshape(-1, 3), triangles.reshape(-1, 3)])
        eps = SIDE_EPS_REL * float(np.linalg.norm(flat.max(axis=0) - flat.min(axis=0)))
        normal = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
        length = np.linalg.norm(normal, axis=1, keepdims=True)
        normal = np.divide(normal, length, out=np.zeros_like(normal), where=length > 0.0)
        signed = np.einsum("tc,nkc->tnk", normal, corners) - np.einsum(
            "tc,tc->t", normal, triangles[:, 0]
        )[:, None, None]  # (T, N, K) m
        self.front = np.all(signed >= -eps, axis=2)  # (T, N)
        self.back = np.all(signed <= eps, axis=2)
        self.tri_lo = triangles.min(axis=1) - eps  # (T, 3)
        self.tri_hi = triangles.max(axis=1) + eps
        self.patch_lo = corners.min(axis=1)  # (N, 3)
        self.patch_hi = corners.max(axis=1)

    def maybe_occluded(self, i: int) -> np.ndarray:
        """(N,) bool: pairs (i, j) some triangle might block."""
        same_side = (self.front[:, i, None] & self.front) | (self.back[:, i, None] & self.back)
        lo = np.minimum(self.patch_lo[i], self.patch_lo)  # (N, 3) box of i and j
        hi = np.maximum(self.patch_hi[i], self.patch_hi)
        overlap = np.all(
            (self.tri_lo[:, None, :] <= hi[None]) & (self.tri_hi[:, None, :] >= lo[None]), axis=2
        )  # (T, N)
        return np.any(overlap & ~same_side, axis=0)
