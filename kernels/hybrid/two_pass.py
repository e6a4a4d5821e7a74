"""The two-pass renderer: "radiosity and ray tracing are complementary to each other".

Pass 1 (view-independent) solves the scene's radiosity: diffuse interreflection, colour bleeding,
the lamps' direct light at every patch, read out per point by the final gather
(`kernels/radiosity/`). Pass 2 (per view) is the Whitted tracer from the eye (`kernels/trace/`):
mirror and refraction rays, the glossy lobes' highlights, emission; at every diffuse hit, at the
camera's first hit and behind mirrors and glass alike, the diffuse reflection is the pass-1
solution at that point (`RadiosityResult.radiance_at`, rescaled to the view angle under the
specular layer as Cycles' diffuse lobe darkens towards grazing) instead of the tracer's shadow
rays. What the mirror ball and the glass show therefore carries the global illumination, and the
walls carry their interreflection.

What neither pass carries: light that leaves a lamp, meets a mirror or glass and then a diffuse
surface (caustics: a mirror lighting a floor, light focused through glass). Radiosity treats
mirrors and glass by their diffuse weight only (a chrome ball reflects nothing diffusely, so it
is an occluder in pass 1), and the tracer's diffuse hits read pass 1. bench/hybrid.py measures
that share against Cycles with caustics on and off.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np

from ..geometry.bvh import BVH
from ..geometry.camera import strata_rows
from ..geometry.scene import Scene, interpolated_normals, triangle_emission
from ..progress import Steps, scaled
from ..radiosity.final_gather import camera_enclosed
from ..radiosity.result import RadiosityResult
from ..radiosity.settings import RadiositySettings
from ..radiosity.solve import radiosity_steps
from ..shading.specular_layer import view_factors, view_tables
from ..trace.settings import TracerSettings, TraceStats
from ..trace.tracer import trace_steps

# Near-field passes of pass 1. The second pass the radiosity bake takes by default
# (planning.AUTO_NEAR_SPLITS) resolves contacts a lightmap holds but a camera rarely sees (a
# ball's underside, the floor right under it): camera views of the solution, relMSE against
# converged Cycles (one pass / two): Cornell box with a mirror and a glass ball, hybrid at
# 96 x 96, 0.00268 / 0.00267 with pass 1 in 1.5 / 2.8 s; generated rooms' radiosity views
# 0.00062 / 0.00056 (solve 8.4 / 14.9 s) and 0.00010 / 0.00011 (5.8 / 10.4 s). None: 0.00291.
NEAR_SPLITS = 1


def pass_one_settings(**changes) -> RadiositySettings:
    """The radiosity settings pass 1 takes by default (NEAR_SPLITS; translucent surfaces pass
    all light, as global illumination follows translucent bounces), with `changes`."""
    return replace(RadiositySettings(near_splits=NEAR_SPLITS, translucent_bounce=True), **changes)


@dataclass(frozen=True)
class HybridSettings:
    """| field     | range             | default                | meaning                          |
    |-----------|-------------------|------------------------|----------------------------------|
    | radiosity | RadiositySettings | pass_one_settings()    | pass 1: the solve (patches, the  |
    |           |                   |                        | final gather that reads it out), |
    |           |                   |                        | one near-field pass (NEAR_SPLITS)|
    | tracer    | TracerSettings    | TracerSettings()       | pass 2: depth, samples, edges    |
    """

    radiosity: RadiositySettings = field(default_factory=pass_one_settings)
    tracer: TracerSettings = field(default_factory=TracerSettings)


@dataclass(frozen=True, eq=False)
class HybridResult:
    """image (H, W, 3) float32 radiance; the pass-1 solution; pass 2's ray counts; seconds per
    pass ({"radiosity": s, "trace": s})."""

    image: np.ndarray
    radiosity: RadiosityResult
    trace_stats: TraceStats
    seconds: dict


def diffuse_lookup(scene: Scene, result: RadiosityResult):
    """The tracer's `DiffuseLookup` reading the solution: the reflected part of B / pi at each
    point, on the side the ray meets, rescaled from the view along the normal (what the texels
    hold under the specular layer) to the ray's view angle. A point seen from the camera's side
    (directly, in mirrors, or through closed glass it left again) lies inside no solid when the
    camera does not, so the gather's enclosure probes are left
    out there (`final_gather.enclosed`: about 40% of the look-up's time behind the edge pass
    on the Cornell box with two balls)."""
    tables = view_tables(scene.materials)
    layered = bool((tables < 1.0).any())
    emission = triangle_emission(scene)
    open_camera = result.gather is not None and not camera_enclosed(result.gather, scene.camera)

    def lookup(tri: np.ndarray, bary: np.ndarray, dirs: np.ndarray, front: np.ndarray,
               camera_side: np.ndarray, strata=None) -> np.ndarray:
        tri = np.asarray(tri, np.int64)
        out = np.zeros((len(tri), 3))
        if front.any():
            t, b = tri[front], bary[front]
            known = result.gather.opened(camera_side[front]) if open_camera else None
            reflected = result.radiance_at(t, b, reflected_only=True, known=known,
                                           strata=strata_rows(strata, front))
            if layered:
                mids = scene.material_ids[t]
                normals = interpolated_normals(scene, t, b)
                cos = np.abs(np.einsum("ij,ij->i", normals, dirs[front]))
                reflected = reflected * (view_factors(tables, mids, cos) / tables[mids, -1])[:, None]
            out[front] = reflected
        back = ~front
        if back.any():  # the tracer adds the emission of either side itself
            out[back] = np.maximum(result.back_radiance_at(scene, tri[back], bary[back])
                                   - emission[tri[back]], 0.0)
        return out

    return lookup


def hybrid_steps(scene: Scene, settings: HybridSettings = HybridSettings(),  # noqa: B008
                 resolution: tuple[int, int] | None = None) -> Steps[HybridResult]:
    """Pass 1 then pass 2 (module docstring); yields progress in [0, 1], returns a `HybridResult`.
    resolution: (W, H) pixels, default the camera's."""
    if scene.camera is None:
        raise ValueError("the scene has no camera to render from")
    t0 = time.perf_counter()
    bvh = BVH.build(scene.triangles)
    solution = yield from scaled(radiosity_steps(scene, settings.radiosity, bvh), 0.0, 0.5)
    t1 = time.perf_counter()
    traced = yield from scaled(trace_steps(scene, settings.tracer, bvh, resolution,
                                           diffuse=diffuse_lookup(scene, solution)), 0.5, 0.5)
    t2 = time.perf_counter()
    return HybridResult(image=traced.image, radiosity=solution, trace_stats=traced.stats,
                        seconds={"radiosity": t1 - t0, "trace": t2 - t1})
