"""Step 1 of the lecture: z-buffer the casters into a planned shadow map's views."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..envmap import cubemap
from ..geometry.raster import rasterize_steps, rasterize_views_steps
from ..geometry.scene import Light
from ..geometry.vec import min_of_three
from ..progress import Steps, drain
from .cutouts import Cutout, cutout_depth_steps
from .shadowmap import ShadowMap, ShadowMapSettings, shared_depth
from .views import plan_shadow_map, potential_casters


def render_shadow_map_steps(shadow_map: ShadowMap, triangles: np.ndarray,
                            cutout: Cutout | None = None) -> Steps[ShadowMap]:
    """Step 1 of the lecture: z-buffer (T, 3, 3) world triangles into every view; yields
    progress, returns the map.

    Draws into the planned buffers as they are (a fresh plan holds +inf): rendering more
    triangles into the same map depth-tests them against what is there. `cutout`, when some of
    the triangles have alpha: their fragments are drawn by it (`cutouts.py`), and where some are
    partly covering, the map returned is the given one with its views' veils."""
    if cutout is not None and cutout.cut.any():
        reach = (np.ones((1, len(triangles)), bool) if shadow_map.kind != "CUBE"
                 else _reaches_faces(triangles, shadow_map.light_position))
        views = []
        for k, view in enumerate(shadow_map.views):
            veil = (np.ones_like(view.depth) if view.veil is None else view.veil,
                    np.full_like(view.depth, np.inf) if view.veil_depth is None else view.veil_depth)
            for progress in cutout_depth_steps(triangles[reach[k]], view.projection, view.depth,
                                               cutout.subset(reach[k]), veil):
                yield (k + progress) / len(shadow_map.views)
            views.append(replace(view, veil=veil[0], veil_depth=veil[1]))
        if all(np.all(v.veil == 1.0) for v in views):  # nothing partly covering: no veils
            return shadow_map
        return replace(shadow_map, views=tuple(views))
    # The planned buffers start at +inf: no second clearing pass over the map.
    if shadow_map.kind != "CUBE":
        yield from rasterize_steps(triangles, shadow_map.views[0].projection,
                                   shadow_map.views[0].depth, clear=False)
        return shadow_map
    reach = _reaches_faces(triangles, shadow_map.light_position)  # (6, T): a face draws these
    stacked = shared_depth(shadow_map)  # planned maps: the faces share one (6, H, W) array
    if stacked is not None:
        # All faces in one batch: one set-up and one pass of spans instead of one per face,
        # bit for bit the same maps.
        face, tri = np.nonzero(reach)
        yield from rasterize_views_steps(triangles[tri], face,
                                         tuple(v.projection for v in shadow_map.views), stacked)
        return shadow_map
    for k, view in enumerate(shadow_map.views):
        for progress in rasterize_steps(triangles[reach[k]], view.projection, view.depth,
                                        clear=False):
            yield (k + progress) / len(shadow_map.views)
    return shadow_map


def _reaches_faces(triangles: np.ndarray, position: np.ndarray) -> np.ndarray:
    """(6, T) bool: triangles not wholly outside one side plane of each cube face's frustum.

    Inside a face's 90-degree frustum the major component ma = F . d is at least |U . d| and
    |V . d| (d = p - L); a triangle whose three vertices all break the same one of these four
    half-spaces (or all lie behind the eye) covers no texel of the face, and the rasteriser would
    only clip it away.
    """
    d = np.asarray(triangles, np.float64) - position  # (T, 3, 3) from the light, m
    ma = d @ cubemap.FACE_FORWARD.T  # (T, 3, 6): per vertex, per face
    sc = d @ cubemap.FACE_U.T
    tc = d @ cubemap.FACE_V.T
    outside = min_of_three(ma <= 0.0)  # (T, 6): all three corners (the minimum of booleans)
    for side in (ma - sc, ma + sc, ma - tc, ma + tc):
        outside |= min_of_three(side < 0.0)
    return ~outside.T


# A receiver this close to a triangle's plane (relative to the scene's size) counts as on it, so
def build_shadow_map(
    triangles: np.ndarray,
    light: Light,
    settings: ShadowMapSettings | None = None,
    receivers: np.ndarray | None = None,
) -> ShadowMap:
    """Plan and render `light`'s shadow map of (T, 3, 3) world triangles (see `plan_shadow_map`).

    With `receivers` given, triangles that cannot shadow any of them are left out first
    (`potential_casters`): a floor under everything is never drawn into its own map.
    """
    if receivers is not None and len(receivers):
        triangles = triangles[potential_casters(triangles, light, receivers)]
    return drain(render_shadow_map_steps(plan_shadow_map(triangles, light, settings, receivers),
                                         triangles))
