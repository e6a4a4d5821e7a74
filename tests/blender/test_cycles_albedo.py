"""Cycles' albedo model (addon/cycles/: `albedo()`, bake_type "ALBEDO").

The texture-mapping technique bakes each surface's diffuse albedo, base colour x (1 - metallic) x
(1 - transmission), and renders the camera's view of it. Cycles' counterparts: a DIFFUSE bake
with the colour pass alone, and the Diffuse Color render pass. Surfaces here are Principled with
Specular IOR Level 0 but for the specular-layer test: with a layer, Cycles' diffuse colour is
lower by the layer's albedo (3.7% at roughness 0.5 and the default level 0.5 facing the camera;
module docstring, "Bake semantics"), which kernels/specular_layer.py models.
"""

import bpy
import numpy as np
import pytest
from blender_parts import BASE, checker, lit_scene, plane, principled

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr
from classic_bake.kernels.shading.direct_light import diffuse_weight

EXACT = 1e-3  # the bound for uniform colours (they agree to ~1e-7 in practice)


# --- scene building -------------------------------------------------------------------------------


def ortho_camera(width_m):
    data = bpy.data.cameras.new("Cam")
    data.type, data.ortho_scale = "ORTHO", width_m
    cam = bpy.data.objects.new("Cam", data)
    cam.location = (0.0, 0.0, 5.0)
    scene = bpy.context.scene
    scene.collection.objects.link(cam)
    scene.camera = cam


def rna_dump(struct) -> dict:
    """Every writable plain property of an RNA struct (no pointers or collections)."""
    out = {}
    for prop in struct.bl_rna.properties:
        if prop.is_readonly or prop.type in ("POINTER", "COLLECTION"):
            continue
        value = getattr(struct, prop.identifier)
        out[prop.identifier] = tuple(value) if getattr(prop, "is_array", False) else value
    return out


def settings_dump(scene) -> dict:
    return {"view_layers": [rna_dump(v) for v in scene.view_layers],
            "cycles": rna_dump(scene.cycles), "render": rna_dump(scene.render),
            "image_settings": rna_dump(scene.render.image_settings)}


# --- tests ----------------------------------------------------------------------------------------


def test_albedo_bake_is_base_colour_times_one_minus_metallic_under_any_light():
    lit_scene()
    plane(principled("Half metal", metallic=0.5)[0])
    expected = np.multiply(BASE, 0.5)
    images, _, masks = cr.bake_lightmaps(None, cr.albedo(), 1, ["Plane"], "Lightmap", 8, "ALBEDO")
    assert masks["Plane"].all()  # the UV square covers every texel
    np.testing.assert_allclose(images["Plane"][masks["Plane"]], np.broadcast_to(expected, (64, 3)),
                               atol=EXACT)
    corners, _ = cr.bake_color_attributes(None, cr.albedo(), 1, ["Plane"], "Albedo", "ALBEDO")
    np.testing.assert_allclose(corners["Plane"], np.broadcast_to(expected, (4, 3)), atol=EXACT)


# Cycles' diffuse colour under the layer against the kernel's integral (multiple scattering
# restored): they differ by at most 0.045% (IOR 3, roughness 1: 0.89903 against 0.89863; in
# single scattering alone 0.11% at IOR 1.5, roughness 1); exact at roughness 0.
LAYER_RTOL = 1e-3


@pytest.mark.parametrize("roughness, level, ior", [(0.0, 0.5, 1.5), (0.5, 0.5, 1.5),
                                                   (1.0, 0.5, 1.5), (0.3, 1.0, 1.5),
                                                   (0.2, 0.5, 2.0), (1.0, 0.5, 3.0),
                                                   (0.5, 0.5, 0.0)])
def test_albedo_bake_under_the_specular_layer_is_the_kernels(roughness, level, ior):
    """With a specular layer (Specular IOR Level above 0) Cycles' diffuse colour is the base
    less the layer's directional albedo along the normal (kernels/specular_layer.py): 4.0% at
    roughness 0, IOR 1.5 and the default level, 11% at IOR 2, all of it at an IOR of 0 (F0 = 1:
    Cycles shows 4e-5 of the base; single scattering alone left 8%). The material goes through
    the bridge, as every bake reads it."""
    lit_scene()
    mat, bsdf = principled("Layered")
    bsdf.inputs["Specular IOR Level"].default_value = level
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["IOR"].default_value = ior
    plane(mat)
    images, _, masks = cr.bake_lightmaps(None, cr.albedo(), 1, ["Plane"], "Lightmap", 8, "ALBEDO")
    material = next(m for m in bridge.snapshot().materials if m.name == "Layered")
    expected = np.multiply(BASE, diffuse_weight(material))
    assert diffuse_weight(material) < 0.99  # the layer is there
    np.testing.assert_allclose(images["Plane"][masks["Plane"]], np.broadcast_to(expected, (64, 3)),
                               rtol=LAYER_RTOL, atol=1e-4)


def test_albedo_bake_maps_a_checker_texture_through_the_uvs():
    lit_scene()
    mat, bsdf = principled("Checker")
    checker(mat, bsdf, scale=4.0)
    plane(mat)
    # Scale 4 over UVs [0, 1]: 4 x 4 squares of 8 x 8 texels on a 32^2 lightmap. Blender's
    # checker gives Color1 (white) where floor(4u) + floor(4v) is odd: with row 0 at v = 1, where
    # row // 8 + column // 8 is even. Bake samples spread over each texel, and one on a square's
    # edge may land in the next square (measured: 1 of 16 in one texel), so only the 6 x 6
    # texels inside each square are required to be pure.
    images, _, masks = cr.bake_lightmaps(None, cr.albedo(), 16, ["Plane"], "Lightmap", 32,
                                         "ALBEDO")
    grey = images["Plane"].mean(axis=2)
    rows, cols = np.indices((32, 32))
    white = (rows // 8 + cols // 8) % 2 == 0
    inside = (rows % 8 > 0) & (rows % 8 < 7) & (cols % 8 > 0) & (cols % 8 < 7)
    assert masks["Plane"].all()
    assert abs(grey.mean() - 0.5) < 0.01
    assert np.all(grey[inside & white] > 0.99) and np.all(grey[inside & ~white] < 0.01)


def test_albedo_render_is_the_diffuse_colour_and_zero_on_the_background():
    scene = lit_scene()
    mat, _ = principled("Colour")
    plane(mat)
    # 3.2 m across 32 px: 0.1 m per pixel, the 2 m plane covers columns 6-25 and rows 2-21 of
    # 32 x 24 exactly (its edges on pixel edges, so no pixel mixes plane and world).
    ortho_camera(3.2)
    pixels, seconds = cr.render_camera(scene, cr.albedo(), 4, resolution=(32, 24))
    assert pixels.shape == (24, 32, 3) and pixels.dtype == np.float32 and seconds > 0.0
    on_plane = np.zeros((24, 32), bool)
    on_plane[2:22, 6:26] = True
    np.testing.assert_allclose(pixels[on_plane], np.broadcast_to(BASE, (400, 3)), atol=EXACT)
    assert np.all(pixels[~on_plane] == 0.0)  # not the world colour: no surface, no albedo


def test_albedo_render_and_bake_put_every_setting_back():
    scene = lit_scene()
    plane(principled("Colour")[0])
    ortho_camera(3.2)
    second = scene.view_layers.new("Second")  # not rendered for the pass, then on again
    second.use_pass_diffuse_color = True
    scene.render.image_settings.file_format = "JPEG"
    scene.cycles.bake_type = "AO"
    before = settings_dump(scene)
    assert not scene.view_layers[0].use_pass_diffuse_color

    cr.render_camera(scene, cr.albedo(), 1, resolution=(8, 6))
    cr.bake_lightmaps(scene, cr.albedo(), 1, ["Plane"], "Lightmap", 4, "ALBEDO")
    assert settings_dump(scene) == before  # pass flags, output format, size and bake type


def test_albedo_model_settings():
    model = cr.albedo(seed=3)
    assert cr.MODELS["albedo"] is cr.albedo
    assert (model.max_bounces, model.diffuse_bounces, model.glossy_bounces,
            model.transmission_bounces) == (0, 0, 0, 0)
    assert (model.pixel_filter, model.filter_width, model.world_lighting) == ("BOX", 1.0, False)
    assert model.render_pass == "DiffCol" and model.seed == 3
    assert model.fields()["render_pass"] == "DiffCol"  # part of the reference cache key
    assert "render_pass" not in cr.direct().fields()  # older models keep their cache keys


def test_albedo_bake_counts_a_translucent_surfaces_colour():
    """A Translucent BSDF is a diffuse-type closure: Cycles' diffuse colour holds its colour, so
    half Diffuse (0.2, 0.6, 0.1), half Translucent (0.3, 0.7, 0.1) bakes (0.25, 0.65, 0.1); the
    kernels' bake (`texture_bake.texel_albedo`) gives the same."""
    from blender_parts import bare_material, translucent_mix

    from classic_bake.kernels.bake.bake_targets import lightmap_targets
    from classic_bake.kernels.bake.texture_bake import texel_albedo

    lit_scene()
    mat, tree, out = bare_material("Leaf")
    tree.links.new(translucent_mix(tree, (0.2, 0.6, 0.1), (0.3, 0.7, 0.1)).outputs[0],
                   out.inputs["Surface"])
    plane(mat)
    expected = np.broadcast_to((0.25, 0.65, 0.1), (64, 3))
    images, _, masks = cr.bake_lightmaps(None, cr.albedo(), 1, ["Plane"], "Lightmap", 8, "ALBEDO")
    np.testing.assert_allclose(images["Plane"][masks["Plane"]], expected, atol=EXACT)
    snap = bridge.snapshot(request=bridge.SnapshotRequest(camera=False, lightmap_uv="Lightmap"))
    ours, _ = texel_albedo(snap, lightmap_targets(snap, 0, 8))
    np.testing.assert_allclose(ours, expected[: len(ours)], atol=EXACT)
