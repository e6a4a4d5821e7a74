"""A texture's mean over a pixel (kernels/shading/pixel_texture.py) at texture seams
(`Scene.texture_seams`): a pixel that straddles the edge between two UV islands takes each
triangle's own island only."""

from dataclasses import replace

import numpy as np
from scene_builder import build, ortho_camera, quad

from classic_bake.kernels.bake.camera_view import camera_fragments
from classic_bake.kernels.geometry.scene import Material, Texture
from classic_bake.kernels.shading.pixel_texture import cell_albedo


def split_atlas_scene(split: bool):
    """A 2 x 1 m floor of two quads, x < 0 and x > 0, textured from a row of four texels: green
    (u in [0.25, 0.5)), blue ([0.5, 0.75)), yellow ([0.75, 1)). The left quad reads green (u =
    0.25 + 0.25 (x + 1)); the right one blue, continuing it, or (split) yellow, its own island
    (u = 0.75 + 0.25 x): then x = 0 is a seam. Ortho pixels of 0.25 m; column 4 spans x from
    -0.0625 to 0.1875, its centre on the right quad."""
    pixels = np.zeros((1, 4, 4), np.float32)
    pixels[0, :, 3] = 1.0
    pixels[0, 0, 0] = pixels[0, 1, 1] = pixels[0, 2, 2] = 1.0  # red, green, blue
    pixels[0, 3, :2] = 1.0  # yellow
    tex = Texture(kind="IMAGE", pixels=pixels, extension="EXTEND", interpolation="CLOSEST")
    left = quad([(-1, -0.5, 0), (0, -0.5, 0), (0, 0.5, 0), (-1, 0.5, 0)])
    right = quad([(0, -0.5, 0), (1, -0.5, 0), (1, 0.5, 0), (0, 0.5, 0)])
    mat = Material(name="atlas", base_color=np.ones(3, np.float32), specular=0.0,
                   base_color_texture=tex)
    cam = ortho_camera((-0.0625, 0, 5), (0, 0, -1), (0, 1, 0), 2.0, (8, 4))
    scene = build([(np.concatenate([left, right]), mat)], cam)
    uv = scene.uv.copy()
    uv[..., 0] = 0.25 + 0.25 * (scene.triangles[..., 0] + 1.0)
    if split:
        uv[2:, :, 0] = 0.75 + 0.25 * scene.triangles[2:, :, 0]
    return replace(scene, uv=uv)


def test_an_edge_is_a_seam_where_the_coordinates_jump_and_at_the_border():
    joined, split = split_atlas_scene(False), split_atlas_scene(True)
    shared = [(k, c) for k in range(4) for c in range(3)
              if np.all(np.isclose(np.delete(joined.triangles[k], c, axis=0)[:, 0], 0.0))]
    assert len(shared) == 2  # one edge of each quad lies on x = 0
    for k, c in shared:
        assert not joined.texture_seams[k, c] and split.texture_seams[k, c]
    # the diagonals inside each quad go on; the outer edges are the border
    assert joined.texture_seams.sum() == 6 and split.texture_seams.sum() == 8


def test_a_pixel_across_a_seam_reads_its_own_triangles_island_only():
    """Column 4's centre hits the right quad, a quarter of the pixel lies on the left one. With
    the coordinates going on, the pixel's box reads green past x = 0 and blue on the right
    (their mean over the pixel, to the filter's sub-cells). Split, the right island's
    coordinates extrapolated past the seam would read blue, which no surface in the pixel
    shows: the box keeps to the right triangle, all yellow."""
    for split in (False, True):
        scene = split_atlas_scene(split)
        f = camera_fragments(scene)
        at = np.flatnonzero((f.rows == 2) & (f.cols == 4))
        assert scene.triangles[f.tri[at[0]], :, 0].max() == 1.0  # the right quad
        value = cell_albedo(scene, f.tri[at], f.bary[at], f.rows[at], f.cols[at], (4, 8))[0]
        if split:
            np.testing.assert_allclose(value, [1.0, 1.0, 0.0], atol=1e-6)
        else:  # green over about a quarter of it (the 3 x 3 sub-cells' boxes: a third)
            assert value[0] == 0.0 and 0.2 < value[1] < 0.4 and value[1] + value[2] == 1.0
