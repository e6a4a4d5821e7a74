"""Seconds a technique run will take, estimated before it starts from the size of its work: the
camera view's rays, the lightmaps' texels, the triangles and, for radiosity and the hybrid's
first pass, the patch pairs, each times a rate measured on the sample scenes.

The estimate is rough (a factor of two either way: scenes differ in lights, materials and depth
of the ray tree, and the machine in cores and load); it is printed in a run's first lines, kept
in metrics.json (`estimate`) and refused against only when `--time-budget-s` is given.

The rates were measured with every technique's command at its default settings on
cornell_box.blend and raytrace.blend (`sample_blends/`), on a two-core machine with other work
running beside it: seconds of the technique's phase (metrics.json `seconds`) over the size of its
work (`sizes`), the larger of the two scenes' figures taken so that the estimate errs long.
"""

from __future__ import annotations

import math

# Seconds of start-up every run pays before its work: opening the scene, the snapshot, building
# the BVH of a sample scene (0.3 - 1 s measured).
START_SECONDS = 1.0
# Seconds per camera ray (pixel x supersample^2) of each technique's camera view: the whole
# shading of a pixel (shadow rays, bounces, texture filtering) per primary ray. Measured (the
# technique's phase over its rays): trace 9.5e-5 (cornell_box) and 1.4e-4 (raytrace); envmap
# 2.6e-4 (raytrace: the cube faces' capture as well); bump 1.8e-4 (cornell_box: four shadings);
# texture's albedo view 2.3e-5 (both scenes, solved together with its texels below); hybrid
# 2.5e-4 (bench/hybrid.py's trace pass: the final gather at every diffuse hit; its radiosity
# solve is counted by its patches, as radiosity's).
# shadowmap 2e-5 (raytrace: the view reads the masks).
SECONDS_PER_RAY = {
    "trace": 1.4e-4, "envmap": 2.6e-4, "bump": 1.8e-4, "texture": 2.3e-5, "shadowmap": 2e-5,
    "radiosity": 1e-4, "hybrid": 2.5e-4, "normalmap": 2.3e-5, "lightmap-uv": 0.0,
}
DEFAULT_SECONDS_PER_RAY = 1.4e-4
# Seconds per lightmap texel baked. Measured: texture 4e-6 (filtered look-ups; cornell_box's
# 0.46 M planned texels and raytrace's 86 k, solved together with the rays above); radiosity's
# final gather 5e-5 (cornell_box: 32 s in all). Shadow maps (every light's depth tests with PCF):
# 2e-5, an estimate of 4.9 s for raytrace's 2.7 s.
SECONDS_PER_TEXEL = {"texture": 4e-6, "shadowmap": 2e-5, "radiosity": 5e-5, "lightmap-uv": 0.0}
DEFAULT_SECONDS_PER_TEXEL = 2e-5
# Seconds per triangle of xatlas charting and packing (lightmap-uv of raytrace.blend: 0.98 s for
# 6626 triangles); the other techniques' per-triangle work (snapshot, BVH) is ~10x cheaper.
SECONDS_PER_TRIANGLE = {"lightmap-uv": 1.5e-4}
DEFAULT_SECONDS_PER_TRIANGLE = 1.5e-5
# Radiosity's solve: seconds per patch at the planned patch count, times log2 of the count (the
# clustered and hierarchical solvers link each patch with O(log N) others; a dense solver's
# N^2 factors fit the memory limit only up to a few thousand patches). raytrace.blend, 6626
# patches planned: ~9 s of its 21 s beside the view and the gather.
SECONDS_PER_PATCH_LOG = 1.5e-4
# The flag that lowers each part of the estimate.
LOWER_WITH = {
    "rays": "--resolution W H",
    "texels": "a smaller --lightmap-size",
    "triangles": "fewer triangles",
    "patches": "a larger --patch-size or fewer --patches",
    "unwrap_triangles": "lightmap UVs made beforehand (the lightmap-uv command)",
}


def estimate_seconds(technique: str, sizes: dict) -> list[tuple[float, str, str]]:
    """[(seconds, what, the flag that lowers it)] of a run of `technique` over `sizes`: rays,
    texels, triangles, the triangles of meshes still without lightmap UVs (unwrap_triangles),
    patches (each optional; what `pipeline/run.estimate_memory` planned)."""
    parts = [(START_SECONDS, "starting up", "")]
    for key, rates, default, what in (
            ("rays", SECONDS_PER_RAY, DEFAULT_SECONDS_PER_RAY, "camera rays"),
            ("texels", SECONDS_PER_TEXEL, DEFAULT_SECONDS_PER_TEXEL, "lightmap texels"),
            ("triangles", SECONDS_PER_TRIANGLE, DEFAULT_SECONDS_PER_TRIANGLE, "triangles")):
        count = sizes.get(key, 0)
        if count:
            parts.append((count * rates.get(technique, default), f"{count:,} {what}",
                          LOWER_WITH[key]))
    unwrap = sizes.get("unwrap_triangles", 0)
    if unwrap:  # the lightmap UVs a bake makes first, at lightmap-uv's rate
        parts.append((unwrap * SECONDS_PER_TRIANGLE["lightmap-uv"],
                      f"{unwrap:,} triangles to chart into lightmap UVs",
                      LOWER_WITH["unwrap_triangles"]))
    patches = sizes.get("patches", 0)
    if patches:
        # Every triangle is at least one patch: with as many patches as triangles, only fewer
        # triangles lower the count.
        flag = (LOWER_WITH["triangles"] + " (each is at least one patch)"
                if patches <= sizes.get("triangles", 0) else LOWER_WITH["patches"])
        parts.append((patches * math.log2(max(patches, 2)) * SECONDS_PER_PATCH_LOG,
                      f"{patches:,} radiosity patches", flag))
    return [p for p in parts if p[0] > 0.0]


def rough_seconds(seconds: float) -> str:
    """'~40 s', '~3 min', '~2.5 h': an estimate printed without false precision."""
    for limit, unit, per in ((90.0, "s", 1.0), (5400.0, "min", 60.0), (float("inf"), "h", 3600.0)):
        if seconds < limit:
            value = seconds / per
            return f"~{value:.2g} {unit}" if value < 10.0 else f"~{value:,.0f} {unit}"
    return "~? s"  # nan
