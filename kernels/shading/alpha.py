"""Surface coverage (alpha): how much of a surface a ray meets at a point.

A material's alpha (Principled BSDF Alpha: a constant or a texture's channel, `Material.alpha`,
`Material.alpha_texture`) makes the surface partly transparent to every ray, as in Cycles: a
shadow or visibility ray meeting it passes with weight 1 - alpha (`geometry/alpha_occlusion.py`),
a shadow map's depth pass keeps a fragment where alpha is 1 and lets 1 - alpha through where it
is partial (`shadow/cutouts.py`).
Leaf cards, fences and decals are the cases: an image whose alpha is 0 in the holes, 1 elsewhere.
"""

from __future__ import annotations

import numpy as np

from ..geometry.alpha_occlusion import AlphaOccluder
from ..geometry.bvh import BVH
from ..geometry.scene import Scene
from .material_maps import material_values


def has_alpha(scene: Scene) -> bool:
    """True when some triangle of `scene` may let rays through (only those scenes pay)."""
    used = np.unique(scene.material_ids) if scene.triangle_count else ()
    return any(scene.materials[m].has_alpha for m in used)


def alpha_materials(scene: Scene) -> np.ndarray:
    """(M,) bool per material: whether it has alpha (`Material.has_alpha`)."""
    return np.array([m.has_alpha for m in scene.materials], bool)


def surface_alpha(scene: Scene, tri: np.ndarray, bary: np.ndarray) -> np.ndarray:
    """(N,) float64 coverage in [0, 1] at barycentric points (N, 3) of scene triangles `tri`
    (N,): the material's alpha texture (its first channel) looked up through its coordinates,
    else its constant alpha (1 for opaque materials)."""
    tri = np.asarray(tri, np.int64)
    out = np.ones(len(tri))
    if not len(tri):
        return out
    rows = np.flatnonzero(alpha_materials(scene)[scene.material_ids[tri]])
    if rows.size:
        values = material_values(scene, tri[rows], np.asarray(bary, np.float64)[rows],
                                 lambda m: m.alpha_texture,
                                 lambda m: np.full(3, m.alpha))
        out[rows] = np.clip(values[:, 0], 0.0, 1.0)
    return out


class SceneAlpha:
    """The coverage look-up `geometry/alpha_occlusion.py` takes: alpha(tri (N,), u (N,), v (N,))
    -> (N,) over `scene`'s triangles, with u, v the BVH's barycentrics of corners 1 and 2."""

    def __init__(self, scene: Scene):
        self.scene = scene
        self.per_material = alpha_materials(scene)

    def __call__(self, tri: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        u = np.asarray(u, np.float64)
        v = np.asarray(v, np.float64)
        bary = np.stack([1.0 - u - v, u, v], axis=1)
        return surface_alpha(self.scene, tri, bary)

    def opaque(self, tri: np.ndarray) -> np.ndarray:
        """(N,) bool: triangles whose material has no alpha (a ray meeting them stops)."""
        return ~self.per_material[self.scene.material_ids[np.asarray(tri, np.int64)]]


class HiddenCoverage:
    """A coverage look-up (`SceneAlpha`'s signature) for rays Cycles does not let see some
    objects (`Scene.ray_hidden`): their triangles have coverage 0, the others `base`'s (1
    without one)."""

    def __init__(self, base: SceneAlpha | None, hidden: np.ndarray):
        self.base, self.hidden = base, hidden

    def __call__(self, tri: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        tri = np.asarray(tri, np.int64)
        out = np.ones(len(tri)) if self.base is None else self.base(tri, u, v)
        return np.where(self.hidden[tri], 0.0, out)

    def opaque(self, tri: np.ndarray) -> np.ndarray:
        """(N,) bool: triangles a ray meeting stops at (neither hidden nor partly covered)."""
        tri = np.asarray(tri, np.int64)
        opaque = np.ones(len(tri), bool) if self.base is None else self.base.opaque(tri)
        return opaque & ~self.hidden[tri]


def ray_coverage(scene: Scene, kind: str) -> SceneAlpha | HiddenCoverage | None:
    """The coverage rays of `kind` ("camera", "shadow") meet: the scene's alpha, with the objects
    Cycles hides from such rays fully transparent; None when every surface is opaque to them."""
    hidden = scene.ray_hidden(kind)
    alpha = scene_alpha(scene)
    return alpha if hidden is None else HiddenCoverage(alpha, hidden)


def lighting_coverage(scene: Scene) -> SceneAlpha | HiddenCoverage | None:
    """The coverage the rays that carry light between surfaces meet (mirror and glass rays,
    radiosity's visibility): the scene's alpha, with unlit surfaces (`Material.camera_only`)
    fully transparent; None when every surface is opaque to them."""
    unlit = scene.camera_only()
    alpha = scene_alpha(scene)
    return alpha if unlit is None else HiddenCoverage(alpha, unlit)


def shadow_aware(bvh: BVH, scene: Scene, offset: float, seed: int = 0) -> AlphaOccluder | None:
    """`alpha_aware` for the shadow rays of kernels that take a yes / no visibility query
    (radiosity's lamps and emitters): the shadowless surfaces (`Material.shadowless`) and the
    objects Cycles hides from shadow rays passed too (`Scene.ray_hidden`); None when the scene
    has neither (the lighting query serves)."""
    if scene.shadowless() is None and not any("shadow" in o.hidden_from for o in scene.objects):
        return None
    return _occluder(bvh, HiddenCoverage(scene_alpha(scene), scene.ray_hidden("shadow")), offset,
                     seed)


def linked_shadows(bvh: BVH, scene: Scene, offset: float, seed: int = 0) -> dict:
    """Light -> `alpha_aware`'s query for that light's shadow rays, for the lights under shadow
    linking (`Light.blockers`): they pass the objects outside its blockers as they pass what
    every shadow ray passes (`Scene.shadow_passing`); {} where no light has blockers."""
    return {light: _occluder(bvh, HiddenCoverage(scene_alpha(scene), scene.shadow_passing(light)),
                             offset, seed)
            for light in scene.lights if light.blockers is not None}


def _occluder(bvh: BVH, coverage, offset: float, seed: int) -> AlphaOccluder:
    """`bvh`'s yes / no query through `coverage` (a ray blocked with probability 1 -
    transmittance)."""
    return AlphaOccluder(bvh, coverage, offset, coverage.opaque, np.random.default_rng(seed))


def scene_alpha(scene: Scene) -> SceneAlpha | None:
    """The scene's coverage look-up, or None when every surface is opaque."""
    return SceneAlpha(scene) if has_alpha(scene) else None


def alpha_aware(bvh: BVH, scene: Scene, offset: float, seed: int = 0) -> BVH | AlphaOccluder:
    """`bvh` whose `occluded` sees through the scene's alpha and unlit surfaces
    (`lighting_coverage`; a ray blocked with probability 1 - transmittance, `AlphaOccluder`) for
    kernels that take a yes / no visibility query (radiosity's form factors and shadow rays);
    `bvh` itself when every surface is opaque. offset: m, how far past a hit the next query
    starts (the scene's ray offset)."""
    alpha = lighting_coverage(scene)
    return bvh if alpha is None else _occluder(bvh, alpha, offset, seed)
