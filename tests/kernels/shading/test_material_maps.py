"""Emission, metallic and roughness textures resolved per triangle (kernels/shading/material_maps.py)
and the node chain folded into a texture (kernels/shading/textures.py, `node_chain`)."""

import numpy as np
import pytest
from scene_builder import build

from classic_bake.kernels.geometry.scene import Material, Texture, triangle_emission
from classic_bake.kernels.shading.direct_light import diffuse_at
from classic_bake.kernels.shading.material_maps import (
    emission_at,
    emission_detail,
    hit_materials,
    lattice_points,
    resolve_material_maps,
    triangle_means,
)
from classic_bake.kernels.shading.textures import sample_texture


def _scene(uv, material):
    """Triangles lying in z = 0 whose UVs are their (x, y) (`scene_builder.build`), of one material."""
    uv = np.asarray(uv, np.float64)
    return build([(np.concatenate([uv, np.zeros(uv.shape[:2] + (1,))], axis=2), material)])


def _ramp_texture(width=64, weights=None, gain=1.0, offset=0.0):
    """An image whose red grows linearly with u (texel centres at (j + 0.5) / W), green 1 - u,
    blue 0.5 and alpha u / 2, read linearly."""
    u = (np.arange(width) + 0.5) / width
    pixels = np.zeros((4, width, 4), np.float32)
    pixels[..., 0], pixels[..., 1], pixels[..., 2], pixels[..., 3] = u, 1.0 - u, 0.5, u / 2
    return Texture(kind="IMAGE", name="ramp", pixels=pixels, extension="EXTEND",
                   weights=None if weights is None else np.asarray(weights, np.float32),
                   gain=np.full(3, gain, np.float32), offset=np.full(3, offset, np.float32))


@pytest.mark.parametrize("n", [1, 2, 5, 12])
def test_lattice_points_are_the_centroids_of_equal_sub_triangles(n):
    points = lattice_points(n)
    assert points.shape == (n * n, 3)
    assert np.all(points > 0.0) and np.allclose(points.sum(axis=1), 1.0)
    np.testing.assert_allclose(points.mean(axis=0), 1.0 / 3.0, atol=1e-12)  # the centroid


def test_node_chain_picks_a_channel_scales_and_clamps():
    uv = np.array([[0.25, 0.5], [0.75, 0.5]])
    blue = sample_texture(_ramp_texture(weights=(0, 0, 1, 0), gain=2.0, offset=-0.25), uv)
    np.testing.assert_allclose(blue, 0.75, atol=1e-6)  # 2 x 0.5 - 0.25 in all three
    alpha = sample_texture(_ramp_texture(weights=(0, 0, 0, 1)), uv)
    np.testing.assert_allclose(alpha[:, 0], [0.125, 0.375], atol=1e-6)
    clamped = replace_clamp(_ramp_texture(gain=3.0))
    assert sample_texture(clamped, uv).max() == 1.0


def replace_clamp(texture):
    from dataclasses import replace

    return replace(texture, clamp=True)


def test_triangle_means_integrate_a_linear_texture():
    """A texture linear in u averages to its value at the triangle's UV centroid."""
    scene = _scene([[[0.1, 0.2], [0.7, 0.3], [0.4, 0.9]]], Material(name="m"))
    means = triangle_means(scene, np.array([0]), _ramp_texture())
    np.testing.assert_allclose(means[0, 0], 0.4, atol=2e-3)  # red = u at the centroid
    np.testing.assert_allclose(means[0, 1], 0.6, atol=2e-3)


def test_metallic_and_roughness_textures_become_variants_per_triangle():
    """Two triangles, one over u < 0.5 (metallic 0) and one over u > 0.5 (metallic 1)."""
    step = np.zeros((2, 2, 4), np.float32)
    step[:, 1, 2] = 1.0  # blue: metallic 1 on the right half
    step[:, :, 1] = 0.3  # green: roughness 0.3 everywhere
    packed = Texture(kind="IMAGE", name="mr", pixels=step, interpolation="CLOSEST")
    metal = Texture(kind="IMAGE", name="mr", pixels=step, interpolation="CLOSEST",
                    weights=np.array([0, 0, 1, 0], np.float32))
    rough = Texture(kind="IMAGE", name="mr", pixels=step, interpolation="CLOSEST",
                    weights=np.array([0, 1, 0, 0], np.float32))
    assert packed.weights is None
    mat = Material(name="Asset", metallic_texture=metal, roughness_texture=rough)
    uv = np.array([[[0.05, 0.1], [0.45, 0.1], [0.25, 0.9]],
                   [[0.55, 0.1], [0.95, 0.1], [0.75, 0.9]]], np.float32)
    resolved = resolve_material_maps(_scene(uv, mat))
    left, right = (resolved.materials[k] for k in resolved.material_ids)
    assert (left.metallic, right.metallic) == (0.0, 1.0)
    # a map of one value keeps it exactly (its extremes are levels)
    assert left.roughness == right.roughness == pytest.approx(0.3)
    # Variants for every value a look-up can round to: metallic 0, 1/8, ..., 1 (bilinear
    # look-ups between the halves), roughness 0.3 alone.
    assert left.metallic_texture is None and "9 variants" in resolved.ignored[-1]
    (family,) = resolved.map_variants
    np.testing.assert_allclose(family.metallic, np.arange(9) / 8)
    np.testing.assert_allclose(family.roughness, [0.3], rtol=1e-6)
    # Reports list the material once, under its own name, whatever its variants.
    assert [m.name for m in resolved.read_materials] == ["(default)", "Asset"]


def test_a_map_of_one_value_and_a_mask_keep_their_values():
    """A metallic map uniformly 0.3115 (a glTF metallicFactor over a map of 1) is that metal
    everywhere, not the nearest 1/8; a mask of 0 and 0.3115 keeps both ends."""
    for left, right in ((0.3115, 0.3115), (0.0, 0.3115)):
        pixels = np.zeros((1, 2, 4), np.float32)
        pixels[0, :, 2] = (left, right)
        metal = Texture(kind="IMAGE", name="m", pixels=pixels, interpolation="CLOSEST",
                        weights=np.array([0, 0, 1, 0], np.float32))
        uv = np.array([[[0.05, 0.1], [0.45, 0.1], [0.25, 0.9]],
                       [[0.55, 0.1], [0.95, 0.1], [0.75, 0.9]]], np.float32)
        resolved = resolve_material_maps(_scene(uv, Material(name="Can", metallic_texture=metal)))
        got = [resolved.materials[k].metallic for k in resolved.material_ids]
        np.testing.assert_allclose(got, (left, right), rtol=1e-6)


def test_ray_hits_read_metallic_and_roughness_at_the_hit():
    """One triangle across a metal mask's edge: its mean is half metal, each hit the texel's."""
    mask = np.zeros((1, 2, 4), np.float32)
    mask[0, 1, 2] = 1.0  # blue: metallic 1 on the right half
    mask[0, :, 1] = (0.2, 0.8)  # green: roughness 0.2 left, 0.8 right
    metal = Texture(kind="IMAGE", name="mr", pixels=mask, interpolation="CLOSEST",
                    weights=np.array([0, 0, 1, 0], np.float32))
    rough = Texture(kind="IMAGE", name="mr", pixels=mask, interpolation="CLOSEST",
                    weights=np.array([0, 1, 0, 0], np.float32))
    mat = Material(name="Asset", metallic_texture=metal, roughness_texture=rough)
    scene = resolve_material_maps(_scene([[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]], mat))
    assert 0.0 < scene.materials[scene.material_ids[0]].metallic < 1.0  # the triangle's mean
    # Barycentric points at u = 0.2 and u = 0.8 (the corners' UVs weighted).
    bary = np.array([[0.7, 0.1, 0.2], [0.1, 0.7, 0.2]])
    hits = hit_materials(scene, np.array([0, 0]), bary, scene.material_ids[[0, 0]])
    got = [(scene.materials[k].metallic, scene.materials[k].roughness) for k in hits]
    # the map's two values exactly: its extremes are levels
    np.testing.assert_allclose(got, [(0.0, 0.2), (1.0, 0.8)], rtol=1e-6)
    assert all(scene.materials[k].metallic_texture is None for k in hits)


def test_emission_textures_emit_per_triangle_and_per_hit():
    glow = np.zeros((1, 2, 4), np.float32)
    glow[0, 1, :3] = (2.0, 1.0, 0.5)  # only the right half glows
    tex = Texture(kind="IMAGE", name="glow", pixels=glow, interpolation="CLOSEST")
    uv = np.array([[[0.05, 0.1], [0.45, 0.1], [0.25, 0.9]],
                   [[0.55, 0.1], [0.95, 0.1], [0.75, 0.9]]], np.float32)
    scene = resolve_material_maps(_scene(uv, Material(name="Lamp", emission_texture=tex)))
    np.testing.assert_allclose(triangle_emission(scene), [[0, 0, 0], [2.0, 1.0, 0.5]])
    at = emission_at(scene, np.array([0, 1]), np.full((2, 3), 1.0 / 3.0))
    np.testing.assert_allclose(at, [[0, 0, 0], [2.0, 1.0, 0.5]])


def test_a_metallic_map_alone_keeps_the_constant_roughness():
    mask = np.zeros((1, 2, 4), np.float32)
    mask[0, 1, 2] = 1.0  # metallic 1 on the right half
    metal = Texture(kind="IMAGE", name="m", pixels=mask, interpolation="CLOSEST",
                    weights=np.array([0, 0, 1, 0], np.float32))
    mat = Material(name="Trim", roughness=0.37, metallic_texture=metal)
    scene = resolve_material_maps(_scene([[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]], mat))
    (family,) = scene.map_variants
    np.testing.assert_allclose(family.roughness, [0.37])
    hits = hit_materials(scene, np.array([0, 0]), np.array([[0.7, 0.1, 0.2], [0.1, 0.7, 0.2]]),
                         scene.material_ids[[0, 0]])
    assert [(scene.materials[k].metallic, scene.materials[k].roughness) for k in hits] == [
        (0.0, 0.37), (1.0, 0.37)]


def test_diffuse_reflectance_and_glow_are_read_at_the_point():
    """One triangle across a metal mask's edge and a glow's: the diffuse reflectance is the base
    colour's where the map paints no metal and 0 where it does (not the triangle's half-metal
    mean), and `emission_detail` adds to the triangle's mean glow what the point shows."""
    mask = np.zeros((1, 2, 4), np.float32)
    mask[0, 1, 2] = 1.0  # blue: metallic 1 on the right half
    metal = Texture(kind="IMAGE", name="m", pixels=mask, interpolation="CLOSEST",
                    weights=np.array([0, 0, 1, 0], np.float32))
    glow = np.zeros((1, 2, 4), np.float32)
    glow[0, 0, :3] = (3.0, 2.0, 1.0)  # the left half glows
    mat = Material(name="Trim", base_color=np.array([0.6, 0.4, 0.2], np.float32), specular=0.0,
                   metallic_texture=metal,
                   emission_texture=Texture(kind="IMAGE", name="g", pixels=glow,
                                            interpolation="CLOSEST"))
    scene = resolve_material_maps(_scene([[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]], mat))
    bary = np.array([[0.7, 0.1, 0.2], [0.1, 0.7, 0.2]])  # u = 0.2 and u = 0.8
    tri = np.array([0, 0])
    np.testing.assert_allclose(diffuse_at(scene, tri, bary), [[0.6, 0.4, 0.2], [0.0, 0.0, 0.0]],
                               atol=1e-6)
    mean = triangle_emission(scene)[0]
    assert 0.0 < mean[0] < 3.0
    detail = emission_detail(scene, tri, bary)
    np.testing.assert_allclose(mean + detail, [[3.0, 2.0, 1.0], [0.0, 0.0, 0.0]], atol=1e-6)
    plain = resolve_material_maps(_scene([[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]],
                                         Material(name="Plain")))
    assert emission_detail(plain, tri, bary) is None
