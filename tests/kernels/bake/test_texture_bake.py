"""Texture mapping baked into lightmaps (kernels/texture_bake.py), against the exact box-filtered
mean of each texel (what a converged Cycles colour bake stores) computed by brute force, and the
camera view of the albedo (the tracer's albedo output)."""

from dataclasses import replace

import numpy as np
import pytest
from scene_builder import build, ortho_camera, quad

from classic_bake.kernels.bake.bake_targets import lightmap_targets
from classic_bake.kernels.bake.texture_bake import (
    TextureBakeSettings,
    cells_per_side,
    straddling,
    texel_albedo,
    texel_jacobians,
    texture_bake_steps,
)
from classic_bake.kernels.geometry.scene import Material, Texture
from classic_bake.kernels.progress import drain
from classic_bake.kernels.shading.textures import checker, checker_box, sample_texture
from classic_bake.kernels.trace.settings import TracerSettings
from classic_bake.kernels.trace.tracer import trace

SIZE = 16
WHITE, BLACK = np.ones(3, np.float32), np.zeros(3, np.float32)


def checker_texture(scale):
    return Texture(kind="CHECKER", color1=WHITE, color2=BLACK, scale=scale)


def lambertian(**fields) -> Material:
    """A material without the Principled specular layer (Specular IOR Level 0): its albedo is
    base colour x (1 - metallic) x (1 - transmission) exactly."""
    return Material(specular=0.0, **fields)


def unit_square(material, angle=0.0):
    """The square [0, 1]^2 (texture UV = xy); its lightmap UVs the square turned by `angle` about
    its centre and shrunk to fit inside [0, 1]^2 (0: the identity)."""
    scene = build([(quad([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]), material)])
    xy = scene.triangles[:, :, :2].astype(np.float64) - 0.5
    c, s = np.cos(angle), np.sin(angle)
    shrink = 1.0 / (abs(c) + abs(s))
    lm = 0.5 + shrink * xy @ np.array([[c, s], [-s, c]])
    objects = tuple(replace(o, has_lightmap_uv=True) for o in scene.objects)
    return replace(scene, lightmap_uv=lm.astype(np.float32), objects=objects)


def brute_force_texels(scene, targets, lookup, m=48):
    """(N, 3) mean of lookup(uv) over texel ∩ owner triangle from m x m points per texel."""
    from classic_bake.kernels.bake.bake_targets import subtexel_points

    owner, tri, bary = subtexel_points(scene, targets, np.arange(len(targets)), m)
    uv = np.einsum("pc,pcj->pj", bary, scene.uv[tri].astype(np.float64))
    sums = np.zeros((len(targets), 3))
    np.add.at(sums, owner, lookup(uv))
    return sums / np.bincount(owner, minlength=len(targets))[:, None]


@pytest.mark.parametrize("scale", [SIZE / 4, SIZE * 2.37])
def test_an_axis_aligned_checker_is_exactly_its_box_mean(scale):
    """Magnified (4 texels a square) each texel is one colour; minified (2.37 squares a texel) a
    centre look-up aliases to black or white, the box mean is each texel's true grey. Texels on
    the square's diagonal average their own triangle's part only, as Cycles does (brute force)."""
    scene = unit_square(lambertian(name="c", base_color_texture=checker_texture(scale)))
    targets = lightmap_targets(scene, 0, SIZE)
    values, n = texel_albedo(scene, targets)
    edge = straddling(scene, targets)
    assert edge.sum() == SIZE  # the diagonal runs through texel corners: one texel a row
    assert (n[~edge] == 1).all() and (n[edge] == 4).all()  # the box IS an inner texel's footprint
    lo = np.stack([targets.cols / SIZE, 1.0 - (targets.rows + 1) / SIZE], axis=1)
    expected = checker_box(lo, lo + 1.0 / SIZE, WHITE, BLACK, scale)
    np.testing.assert_allclose(values[~edge], expected[~edge], atol=1e-6)
    truth = brute_force_texels(scene, targets, lambda uv: checker(uv, WHITE, BLACK, scale))
    assert np.abs(values[edge] - truth[edge]).mean() < 0.05
    centre = checker(lo + 0.5 / SIZE, WHITE, BLACK, scale)
    if scale > SIZE:  # the failure mode the filter removes
        assert np.abs(centre - truth).mean() > 0.2 > 10 * np.abs(values - truth).mean()


def test_a_rotated_lightmap_chart_is_filtered_over_its_turned_texels():
    """xatlas turns charts: a texel's footprint in the texture is then a turned square. Auto
    picks 2 x 2 or more cells; the texels stay within 0.03 of the brute-force mean on average
    (a centre look-up: 0.1)."""
    scale = 5.3
    scene = unit_square(lambertian(name="c", base_color_texture=checker_texture(scale)),
                        angle=np.radians(30.0))
    targets = lightmap_targets(scene, 0, SIZE)
    values, n = texel_albedo(scene, targets)
    assert (n >= 2).all()
    truth = brute_force_texels(scene, targets, lambda uv: checker(uv, WHITE, BLACK, scale))
    centre = checker(np.einsum("pc,pcj->pj", targets.bary,
                               scene.uv[targets.triangles].astype(np.float64)), WHITE, BLACK, scale)
    err, err_centre = np.abs(values - truth).mean(), np.abs(centre - truth).mean()
    assert err < 0.03 and err_centre > 3 * err


def test_an_image_is_sampled_as_finely_as_its_footprint_needs():
    """A 128-texel noise image on a 16-texel lightmap: 8 image texels a lightmap texel, so auto
    takes 8 x 8 cells, one look-up per image texel, and matches the box mean; magnified (a 4-texel
    image) it takes one."""
    rng = np.random.default_rng(3)
    pixels = np.concatenate([rng.random((128, 128, 3)), np.ones((128, 128, 1))], 2).astype(np.float32)
    image = Texture(kind="IMAGE", pixels=pixels)
    scene = unit_square(lambertian(name="i", base_color_texture=image))
    targets = lightmap_targets(scene, 0, SIZE)
    values, n = texel_albedo(scene, targets)
    assert (n == 8).all()  # the diagonal's texels too: 8 > the 4 an edge texel takes
    truth = brute_force_texels(scene, targets, lambda uv: sample_texture(image, uv), m=64)
    one, _ = texel_albedo(scene, targets, TextureBakeSettings(samples_per_side=1))
    err, err_one = np.abs(values - truth).mean(), np.abs(one - truth).mean()
    assert err < 0.01 and err_one > 10 * err
    small = replace(image, pixels=pixels[:4, :4].copy())
    scene = unit_square(lambertian(name="i", base_color_texture=small))
    targets = lightmap_targets(scene, 0, SIZE)
    _, n = texel_albedo(scene, targets)
    assert (n[~straddling(scene, targets)] == 1).all()


def test_untextured_materials_take_one_cell_and_their_diffuse_albedo():
    """No texture: nothing varies, one cell; the albedo is what the diffuse lobe reflects, base
    colour x (1 - metallic) x (1 - transmission)."""
    mat = lambertian(name="m", base_color=np.array([0.2, 0.5, 0.8], np.float32), metallic=0.5,
                   transmission=0.5)
    scene = unit_square(mat)
    targets = lightmap_targets(scene, 0, SIZE)
    values, n = texel_albedo(scene, targets)
    assert (n == 1).all()
    np.testing.assert_allclose(values, np.tile([0.05, 0.125, 0.2], (len(values), 1)), atol=1e-7)


def test_a_texel_on_a_triangle_edge_takes_its_own_triangles_part_only():
    """Two triangles of different colours meeting on the square's diagonal: Cycles gives each
    texel to one triangle and keeps that triangle's samples, so no texel mixes the two colours."""
    red = lambertian(name="r", base_color=np.array([1.0, 0.0, 0.0], np.float32))
    blue = lambertian(name="b", base_color=np.array([0.0, 0.0, 1.0], np.float32))
    scene = unit_square(red)
    scene = replace(scene, materials=scene.materials + (blue,),
                    material_ids=np.array([1, 2], np.int32))
    targets = lightmap_targets(scene, 0, SIZE)
    values, _ = texel_albedo(scene, targets, TextureBakeSettings(samples_per_side=4))
    own = np.where(targets.triangles[:, None] == 0, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(values, own)


def test_jacobian_of_a_scaled_and_turned_map():
    """Lightmap UV = the texture UV turned by +90 degrees and halved: J = 2 R(-90 degrees) (its
    third row, d z / d(lightmap uv) of UV textures' (u, v, 0), is 0)."""
    scene = unit_square(lambertian(name="c"))
    tex = scene.uv.astype(np.float64)
    lm = 0.25 + 0.5 * (tex - 0.5) @ np.array([[0.0, 1.0], [-1.0, 0.0]]) + 0.25
    scene = replace(scene, lightmap_uv=lm.astype(np.float32))
    jac, degenerate = texel_jacobians(scene, np.array([0, 1]))
    assert not degenerate.any()
    np.testing.assert_allclose(jac, np.tile([[0.0, 2.0], [-2.0, 0.0], [0.0, 0.0]], (2, 1, 1)),
                               atol=1e-6)
    n = cells_per_side(replace(scene, materials=(scene.materials[0], Material(
        name="c", base_color_texture=checker_texture(64.0)))), np.array([0, 1]), jac, (16, 16),
        TextureBakeSettings())
    assert (n == 1).all()  # a quarter turn is axis-aligned: the box is exact


def test_bake_steps_give_lightmaps_corners_and_progress():
    mat = lambertian(name="c", base_color_texture=checker_texture(2.0))
    scene = unit_square(mat)
    progress = []
    out = drain(texture_bake_steps(scene, [0], {0: SIZE}, padding=2), progress.append)
    assert progress == sorted(progress) and progress[-1] == 1.0
    bake = out[0]
    assert bake.lightmap.shape == (SIZE, SIZE, 3) and bake.lightmap_mask.all()
    # Corner (0, 0) of the square: u = v = 0 lies on four squares' meeting point; Cycles' nudge
    # puts it in colour 2's square (same parity).
    corner_uv = scene.uv.reshape(-1, 2).astype(np.float64)
    np.testing.assert_allclose(bake.corners, checker(corner_uv, WHITE, BLACK, 2.0), atol=1e-7)


def test_settings_refuse_nonsense():
    with pytest.raises(ValueError):
        TextureBakeSettings(samples_per_side=-1)
    with pytest.raises(ValueError):
        TextureBakeSettings(max_samples_per_side=0)


def test_the_camera_view_is_the_albedo_box_filtered_over_each_pixel():
    """An orthographic camera square over a minified checker plane (3.3 squares a pixel): every
    pixel the checker's exact mean over the pixel's square; the background 0 (not the world)."""
    scale = 8 * 3.3
    scene = build([(quad([(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]),
                    lambertian(name="c", base_color_texture=checker_texture(scale)))],
                  camera=ortho_camera((0.5, 0.5, 1.0), (0, 0, -1), (0, 1, 0), 1.25, (10, 10)),
                  world=(0.3, 0.3, 0.3))
    image = trace(scene, TracerSettings(max_depth=0, output="albedo", texture_filter=4)).image
    # Pixel (row r, col c) covers x in [-0.125 + c / 8, ...), y from the top down.
    inner = image[1:-1, 1:-1].reshape(-1, 3)
    r, c = np.divmod(np.arange(64), 8)
    lo = np.stack([c / 8.0, 1.0 - (r + 1) / 8.0], axis=1)
    np.testing.assert_allclose(inner, checker_box(lo, lo + 0.125, WHITE, BLACK, scale), atol=2e-3)
    assert np.abs(image[0, 0]).max() == 0.0  # a corner pixel that sees no surface
