"""Form factors between perfectly diffuse patches: closed forms, the exact point-to-polygon factor,
and two estimators of the patch-to-patch factor with visibility.

The radiosity equation B_i = E_i + rho_i * sum_j F_ij B_j needs F_ij, the fraction of the power
leaving patch i (uniformly, diffusely) that arrives at patch j:

    F_ij = 1/A_i  integral_Ai integral_Aj  V(x, y) cos(theta_i) cos(theta_j) / (pi s^2)  dA_j dA_i

The inner integral is the factor from a differential area at x to patch j, F_dA->j(x): the
projected solid angle of (the visible part of) j over pi. Three ways of getting it live here:

* Closed forms from Howell's catalogue (C-11, C-14, point and disk to coaxial disk): the ground
  truth of the tests, usable directly when a scene is one of those configurations.
* `point_to_polygon`: Lambert's contour formula (the unoccluded F_dA->j to a flat polygon, exact):
      F = 1/(2 pi) sum_k gamma_k  n . (R_{k+1} x R_k) / |R_{k+1} x R_k|
  R_k = V_k - x, gamma_k the angle between R_k and R_{k+1}, n the receiver's unit normal. The
  polygon is first clipped to the receiver's upper half-space (the formula only holds there).
* Two patch-to-patch estimators, both giving one row F_i* at a time (`FormFactorRows`):
  - method A, `HemicubeFormFactors` (Cohen & Greenberg 1985): hemicubes at n x n points of patch
    i; each pixel carries its delta form factor and looks through a caller-supplied
    `closest_hit`: the patch whose triangle the pixel's ray hits first receives the pixel's factor.
  - method B, `RayCastFormFactors`: the area average over n x n points x of patch i of
    point_to_polygon(x, j), times the visible fraction of j seen from x (rays to m x m stratified
    points of j through a caller-supplied `occluded`). Pairs that cannot be occluded (caller's
    word, or a quick plane/box test) use the closed form alone.
  The points on patch i are Gauss-Legendre nodes by default ("stratified", seeded jitter, is a
  setting): the area average of F_dA->j is smooth enough that a bare 4 x 4 Gauss rule is within
  1e-5 of Howell's C-11 and C-14 on unit squares, where 4 x 4 jittered strata are 1-4% off.

Near field. Adjacent patches sharing an edge are the classic failure of the point-to-point kernel
cos cos/(pi s^2), which is unbounded as s -> 0. Neither estimator evaluates it: method B
integrates the kernel over j analytically (the contour formula is bounded by 1 for every point,
including points next to the shared edge) and only averages the bounded result over patch i, over
the smaller patch of each pair (`RayCastFormFactors`); method A integrates over solid angle,
where the adjacent patch is a region of the hemicube, so nothing diverges, but its accuracy next
to a much smaller neighbour is limited by where its points sit (tests record -80% for a 1 x 1
floor beside a 0.01 high strip). Points exactly on j's plane (so on a shared edge, where the
contour integrand is 0/0) see j edge-on and get 0 (`PLANE_EPS`).

Conventions. Patches are `corners` (N, K, 3) float64, world space, metres: planar convex polygons
wound counter-clockwise around their front normal (Blender's order); a triangle among quads
repeats its last corner (zero-length edges contribute nothing). Patches are one-sided: a patch
seen from behind neither receives nor sends. Colours do not enter here.

Ray callbacks (method A and B), R rays per call:

    closest_hit(origins, directions, t_min, t_max) -> (t, tri)   # or an object with .t and .tri
    occluded(origins, directions, t_min, t_max) -> (R,) bool
        origins (R, 3) float64, world, m; directions (R, 3) float64, unit length;
        t_min float; t_max float or (R,) float64 (method B passes per-ray segment lengths);
        t (R,) float (inf on a miss); tri (R,) int (-1 on a miss); both sides of a triangle hit.

Modules: `closed_forms` (Howell, Wallace's disc), `sampling` (patch geometry, quadrature points),
`point_polygon` (the contour formula), `rays` (ray requests and their answers), `visibility`
(kernel-weighted visible shares), `rows` (`FormFactorRows`, dense matrices), `hemicube` (method A),
`raycast` (method B).

`kernels.geometry.bvh.BVH.intersect` fits `closest_hit` through a lambda returning its Hits.
`tests/support/radiosity_scenes.py` has a brute-force tracer with both callbacks for the tests.
"""
