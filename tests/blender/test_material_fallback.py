"""The general fallback (addon/bridge/socket_fallback.py): a socket whose node graph the reader
cannot follow is baked by Cycles over the object's UVs and read as an image, named with its cost
in the material's `fallbacks`, cached by the node tree, and leaves nothing behind in bpy.data.

The reference is an independent Cycles EMIT bake of the same graph (`cycles.bake_lightmaps`,
the user's scene and object, another sample count) of the plane the fallback baked."""

from __future__ import annotations

import importlib
import json
import subprocess
import sys

import bpy
import numpy as np
import pytest

from classic_bake.addon import bridge
from classic_bake.addon import cycles as cr
from classic_bake.addon.bridge import socket_fallback
from classic_bake.addon.bridge.request import SnapshotRequest, SocketBakeSettings
from classic_bake.kernels.shading.material_maps import ROUGHNESS_STEP
from classic_bake.kernels.shading.textures import sample_texture

SIZE = SocketBakeSettings().size
# Samples per texel of the reference bake: more than the fallback's, so the two are independent
# estimates of each texel's mean.
REFERENCE_SAMPLES = 64
# "Equal within 1%": of the signal's largest value, texel by texel.
TOLERANCE = 0.01
# A colour step between neighbouring texels above this marks a Voronoi cell's edge (the cells'
# colours are random, their differences mostly far larger).
EDGE_STEP = 1e-3
# Cells at the Voronoi's default scale of 5 are ~50 texels wide; their edges with the texels
# beside them (a band ~4 texels wide) are a fifth of the image (0.198 measured): a bound.
EDGE_SHARE = 0.3
DATA = ("materials", "images", "objects", "meshes", "scenes", "node_groups", "cameras")
snapshot_module = importlib.import_module("classic_bake.addon.bridge.snapshot")


@pytest.fixture(autouse=True)
def fresh_cache():
    socket_fallback.clear_cache()
    yield
    socket_fallback.clear_cache()


def _plane(name="Plane", uv=True, material=None, location=(0.0, 0.0, 0.0)):
    """A 2 m plane (UVs the unit square) with `material` (default: a new Principled one)."""
    if material is None:
        material = bpy.data.materials.new("Graph")
        if bpy.app.version < (5, 0, 0):
            material.use_nodes = True
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], [], [(0, 1, 2, 3)])
    if uv:
        mesh.uv_layers.new(name="UVMap").uv.foreach_set("vector", [0, 0, 1, 0, 1, 1, 0, 1])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    obj.location = location
    bpy.context.scene.collection.objects.link(obj)
    return material


def _voronoi_into(socket_name: str, output: str):
    mat = _plane()
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    voronoi = tree.nodes.new("ShaderNodeTexVoronoi")
    tree.links.new(voronoi.outputs[output], bsdf.inputs[socket_name])
    return tree, bsdf, voronoi


def _reference(tree, bsdf, source):
    """Cycles' EMIT bake of `source` on the plane: the Principled's emission fed by it
    (a number as grey), its base black, so the bake holds the socket's value alone."""
    bsdf.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    for link in list(tree.links):
        if link.to_node == bsdf:
            tree.links.remove(link)
    bsdf.inputs["Emission Strength"].default_value = 1.0
    tree.links.new(source, bsdf.inputs["Emission Color"])
    images, _, masks = cr.bake_lightmaps(bpy.context.scene, cr.albedo(), REFERENCE_SAMPLES,
                                         ["Plane"], "UVMap", SIZE, "EMIT")
    return images["Plane"], masks["Plane"]


def _texel_centres() -> np.ndarray:
    centres = (np.arange(SIZE) + 0.5) / SIZE
    u, v = np.meshgrid(centres, centres[::-1])  # row 0 at the top: v near 1
    return np.column_stack([u.ravel(), v.ravel()])


def _at_texel_centres(scene, texture) -> np.ndarray:
    """(SIZE, SIZE, 3) the texture's look-ups at the texel centres of the plane's UV square: each
    centre's triangle and barycentrics from the UVs, its coordinates interpolated from the
    corners (`Scene.texture_coords`: UVs, Generated or a colour attribute's colours)."""
    uv = _texel_centres()
    coords = np.zeros((len(uv), 3))
    done = np.zeros(len(uv), bool)
    for t in range(scene.triangle_count):
        a, b, c = scene.uv[t].astype(np.float64)
        st = np.linalg.solve(np.column_stack([b - a, c - a]), (uv - a).T).T
        inside = (st >= -1e-9).all(axis=1) & (st.sum(axis=1) <= 1 + 1e-9) & ~done
        bary = np.column_stack([1 - st.sum(axis=1), st])[inside]
        coords[inside] = bary @ scene.texture_coords[t]
        done |= inside
    return sample_texture(texture, coords).reshape(SIZE, SIZE, 3)


def _edge_texels(image: np.ndarray) -> np.ndarray:
    """(H, W) bool: texels of a piecewise constant image that differ from a neighbour (or are
    next to one that does: both bakes' edges may fall a texel apart)."""
    step = np.zeros(image.shape[:2], bool)
    jump_x = np.abs(np.diff(image, axis=1)).max(axis=2) > EDGE_STEP
    jump_y = np.abs(np.diff(image, axis=0)).max(axis=2) > EDGE_STEP
    step[:, 1:] |= jump_x
    step[:, :-1] |= jump_x
    step[1:] |= jump_y
    step[:-1] |= jump_y
    grown = step.copy()
    grown[1:] |= step[:-1]
    grown[:-1] |= step[1:]
    grown[:, 1:] |= step[:, :-1]
    grown[:, :-1] |= step[:, 1:]
    return grown


def _unresolved_snapshot(monkeypatch, **request):
    """A snapshot whose metallic and roughness textures are kept as read (not yet resolved per
    triangle), so their texels can be compared."""
    monkeypatch.setattr(snapshot_module, "resolve_material_maps", lambda scene: scene)
    return bridge.snapshot(request=SnapshotRequest(**request))


@pytest.mark.slow
def test_a_voronoi_roughness_is_read_as_cycles_bakes_it(monkeypatch):
    tree, bsdf, voronoi = _voronoi_into("Roughness", "Distance")
    scene = _unresolved_snapshot(monkeypatch)
    mat = scene.materials[1]
    (entry,) = mat.fallbacks
    assert entry["socket"] == "Roughness" and entry["read_as"] == f"Cycles bake {SIZE}x{SIZE}"
    assert entry["seconds"] > 0.0 and not entry["cached"] and entry["object"] == "Plane"
    assert not [why for why in scene.ignored if "Roughness" in why and "default" in why]
    ours = sample_texture(mat.roughness_texture, _texel_centres())[:, 0].reshape(SIZE, SIZE)
    monkeypatch.undo()
    resolved = bridge.snapshot()  # the kernels' roughness per triangle, from the cached bake
    theirs, mask = _reference(tree, bsdf, voronoi.outputs["Distance"])
    theirs = theirs[..., 0]
    err = np.abs(ours - theirs)[mask] / theirs.max()
    assert mask.all() and theirs.max() > 0.3
    assert np.mean(err > TOLERANCE) <= EDGE_SHARE and err.mean() < TOLERANCE / 4, (
        err.max(), err.mean(), np.mean(err > TOLERANCE))
    # Each triangle's roughness is the mean of Cycles' texels over it, to the kernels' step.
    uv = _texel_centres()
    for t in range(resolved.triangle_count):
        a, b, c = resolved.uv[t].astype(np.float64)
        st = np.linalg.solve(np.column_stack([b - a, c - a]), (uv - a).T).T
        inside = (st >= 0.0).all(axis=1) & (st.sum(axis=1) <= 1.0)
        ours_t = resolved.materials[resolved.material_ids[t]].roughness
        theirs_t = theirs.ravel()[inside].mean()
        assert abs(ours_t - theirs_t) <= ROUGHNESS_STEP / 2 + TOLERANCE * theirs.max(), (
            t, ours_t, theirs_t)


@pytest.mark.slow
def test_a_voronoi_base_colour_is_read_as_cycles_bakes_it():
    tree, bsdf, voronoi = _voronoi_into("Base Color", "Color")
    scene = bridge.snapshot()
    mat = scene.materials[1]
    assert [e["socket"] for e in mat.fallbacks] == ["Base Color"]
    ours = sample_texture(mat.base_color_texture, _texel_centres()).reshape(SIZE, SIZE, 3)
    theirs, mask = _reference(tree, bsdf, voronoi.outputs["Color"])
    err = np.abs(ours - theirs).max(axis=2) / theirs.max()
    assert mask.all() and theirs.max() > 0.3
    # Inside a cell both bakes are the cell's colour; a texel a cell edge crosses is the share
    # of the texel each side covers, which the two bakes estimate with their own samples.
    edge = _edge_texels(theirs)
    assert np.all(err[~edge] <= TOLERANCE) and edge.mean() < EDGE_SHARE, (
        err[~edge].max(), edge.mean())
    assert err.mean() < TOLERANCE, err.mean()


def test_a_second_snapshot_reads_the_cached_bake(monkeypatch):
    _voronoi_into("Roughness", "Distance")
    calls = []
    bake = socket_fallback.bake_socket
    monkeypatch.setattr(socket_fallback, "bake_socket",
                        lambda *args, **kw: calls.append(args) or bake(*args, **kw))
    request = {"socket_bake": SocketBakeSettings(size=32, samples=4)}
    first = bridge.snapshot(request=SnapshotRequest(**request)).materials[1].fallbacks
    second = bridge.snapshot(request=SnapshotRequest(**request)).materials[1].fallbacks
    assert len(calls) == 1
    assert [e["cached"] for e in first] == [False] and [e["cached"] for e in second] == [True]
    assert second[0]["seconds"] == first[0]["seconds"]  # the cost of the bake that made it
    # A changed graph is baked again.
    next(n for n in bpy.data.materials["Graph"].node_tree.nodes
         if n.type == "TEX_VORONOI").inputs["Scale"].default_value = 7.0
    bridge.snapshot(request=SnapshotRequest(**request))
    assert len(calls) == 2


def test_the_fallback_leaves_nothing_behind():
    _voronoi_into("Base Color", "Color")
    before = {name: sorted(d.name for d in getattr(bpy.data, name)) for name in DATA}
    scene = bpy.context.scene
    engine = scene.render.engine
    bridge.snapshot(request=SnapshotRequest(socket_bake=SocketBakeSettings(size=32, samples=4)))
    after = {name: sorted(d.name for d in getattr(bpy.data, name)) for name in DATA}
    assert after == before
    assert bpy.context.scene == scene and scene.render.engine == engine


def test_each_object_gets_its_own_bake_of_a_shared_material():
    """The bake covers one object's UVs: a second object with the material is read again."""
    mat = _plane()
    _plane("Other", material=mat, location=(3.0, 0.0, 0.0))
    tree = mat.node_tree
    voronoi = tree.nodes.new("ShaderNodeTexVoronoi")  # a procedural texture goes through the bake
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    tree.links.new(voronoi.outputs["Color"], bsdf.inputs["Base Color"])
    scene = bridge.snapshot(request=SnapshotRequest(
        socket_bake=SocketBakeSettings(size=16, samples=1)))
    baked = sorted(e["object"] for m in scene.materials for e in m.fallbacks)
    assert baked == ["Other", "Plane"]
    ids = {scene.objects[k].name: set(scene.material_ids[scene.object_slice(k)].tolist())
           for k in range(len(scene.objects))}
    assert ids["Plane"].isdisjoint(ids["Other"])


def test_an_object_without_uvs_keeps_the_socket_listed_as_ignored():
    mat = _plane(uv=False)
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    tree.links.new(tree.nodes.new("ShaderNodeTexVoronoi").outputs["Distance"],
                   bsdf.inputs["Roughness"])
    scene = bridge.snapshot()
    assert not scene.materials[1].fallbacks
    (why,) = [w for w in scene.ignored if "'Roughness'" in w]
    assert "default used" in why and "no UV map" in why


def test_info_names_the_fallback_in_metrics_json(tmp_path):
    _voronoi_into("Roughness", "Distance")
    blend = tmp_path / "voronoi.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend))
    out = tmp_path / "info"
    done = subprocess.run([sys.executable, "-m", "classic_bake", "info", str(blend), "--out",
                           str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    metrics = json.loads(next(out.rglob("metrics.json")).read_text())
    (entry,) = metrics["fallbacks"]
    assert entry["material"] == "Graph" and entry["socket"] == "Roughness"
    assert entry["read_as"] == f"Cycles bake {SIZE}x{SIZE}" and entry["seconds"] > 0.0
    assert not [why for why in metrics["ignored"] if "Roughness" in why and "default" in why]
    assert "'Roughness' read from a Cycles bake" in done.stdout


def test_an_unread_alpha_is_baked_as_coverage():
    """Alpha (a leaf card's coverage) goes through the fallback too, also where the bake reads
    no colours (a shadow map's snapshot)."""
    mat = _plane()
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    step = tree.nodes.new("ShaderNodeMath")
    step.operation = "GREATER_THAN"  # a cut-out: not modelled by the reader
    step.inputs[1].default_value = 0.3
    tree.links.new(tree.nodes.new("ShaderNodeTexVoronoi").outputs["Distance"], step.inputs[0])
    tree.links.new(step.outputs[0], bsdf.inputs["Alpha"])
    scene = bridge.snapshot(request=SnapshotRequest(
        textures=False, socket_bake=SocketBakeSettings(size=32, samples=4)))
    mat = scene.materials[1]
    assert [e["socket"] for e in mat.fallbacks] == ["Alpha"]
    texels = mat.alpha_texture.pixels[..., 0]
    assert texels.min() < 0.1 and texels.max() > 0.9  # holes and cover


@pytest.mark.slow
def test_a_noise_emission_strength_bakes_the_radiance():
    """A strength the reader cannot hold as one number: Cycles bakes colour x strength."""
    mat = _plane()
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Emission Color"].default_value = (0.9, 0.5, 0.2, 1.0)
    noise = tree.nodes.new("ShaderNodeTexNoise")
    tree.links.new(noise.outputs["Fac"], bsdf.inputs["Emission Strength"])
    scene = bridge.snapshot()
    mat = scene.materials[1]
    assert [e["socket"] for e in mat.fallbacks] == ["Emission Color x Emission Strength"]
    assert not [why for why in scene.ignored if "Emission" in why]
    ours = sample_texture(mat.emission_texture, _texel_centres()).reshape(SIZE, SIZE, 3)
    images, _, masks = cr.bake_lightmaps(bpy.context.scene, cr.albedo(), REFERENCE_SAMPLES,
                                         ["Plane"], "UVMap", SIZE, "EMIT")
    theirs = images["Plane"]  # the material itself: its emission's radiance
    err = np.abs(ours - theirs).max(axis=2) / theirs.max()
    assert masks["Plane"].all() and theirs.max() > 0.3
    assert np.mean(err > TOLERANCE) <= 0.001 and err.mean() < TOLERANCE / 4, (
        err.max(), err.mean(), np.mean(err > TOLERANCE))


def test_the_cache_key_follows_what_cycles_shades_with():
    """The node tree's digest changes with a ColorRamp stop, a curve point, a default value or a
    link, and not with where a node sits in the editor."""
    from classic_bake.addon.bridge.tree_digest import tree_digest

    mat = _plane()
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    ramp = tree.nodes.new("ShaderNodeValToRGB")
    curve = tree.nodes.new("ShaderNodeRGBCurve")
    tree.links.new(ramp.outputs["Color"], curve.inputs["Color"])
    digests = [tree_digest(tree)]
    ramp.color_ramp.elements[1].position = 0.6
    digests.append(tree_digest(tree))
    curve.mapping.curves[3].points[0].location = (0.0, 0.2)
    digests.append(tree_digest(tree))
    bsdf.inputs["Roughness"].default_value = 0.25
    digests.append(tree_digest(tree))
    tree.links.new(curve.outputs["Color"], bsdf.inputs["Base Color"])
    digests.append(tree_digest(tree))
    assert len(set(digests)) == len(digests)
    ramp.location = (-400.0, 300.0)
    assert tree_digest(tree) == digests[-1]


def test_a_colour_attribute_base_colour_is_read_per_corner_not_baked():
    """A Color Attribute node (per-corner colours, blended across the face) into Base Color is
    read per corner (no bake: tests/blender/test_color_attributes.py checks it against Cycles);
    the kernels' look-ups at the bake's texel centres equal an independent Cycles bake of the
    attribute within 1%."""
    mat = _plane()
    mesh = bpy.data.objects["Plane"].data
    colours = mesh.color_attributes.new("Paint", "FLOAT_COLOR", "CORNER")
    colours.data.foreach_set("color", [1.0, 0.1, 0.1, 1.0, 0.1, 1.0, 0.1, 1.0,
                                       0.1, 0.1, 1.0, 1.0, 0.9, 0.9, 0.2, 1.0])
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    attr = tree.nodes.new("ShaderNodeVertexColor")
    attr.layer_name = "Paint"
    tree.links.new(attr.outputs["Color"], bsdf.inputs["Base Color"])
    scene = bridge.snapshot()
    material = scene.materials[1]
    assert not material.fallbacks and material.base_color_texture.kind == "ATTRIBUTE"
    ours = _at_texel_centres(scene, material.base_color_texture)
    theirs, mask = _reference(tree, bsdf, attr.outputs["Color"])
    err = np.abs(ours - theirs).max(axis=2)[mask] / theirs.max()
    assert mask.all() and theirs.max() > 0.5
    assert err.max() <= TOLERANCE, err.max()


def test_an_object_info_colour_is_baked_as_the_object_has_it():
    """An Object Info node's Color (the object's viewport colour) or Object Index through a
    ramp: the bake's stand-in object takes the source's colour and pass index, so two planes
    sharing the material bake their own colours (the stand-in's default white was read)."""
    mat = _plane()
    _plane("Other", material=mat, location=(3.0, 0.0, 0.0))
    bpy.data.objects["Plane"].color = (0.9, 0.2, 0.1, 1.0)
    bpy.data.objects["Other"].color = (0.1, 0.3, 0.8, 1.0)
    tree = mat.node_tree
    info = tree.nodes.new("ShaderNodeObjectInfo")
    bsdf = next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED")
    tree.links.new(info.outputs["Color"], bsdf.inputs["Base Color"])
    scene = bridge.snapshot(request=SnapshotRequest(
        socket_bake=SocketBakeSettings(size=16, samples=1)))
    for name, colour in (("Plane", (0.9, 0.2, 0.1)), ("Other", (0.1, 0.3, 0.8))):
        k = next(i for i, o in enumerate(scene.objects) if o.name == name)
        (mat_id,) = set(scene.material_ids[scene.object_slice(k)].tolist())
        texture = scene.materials[mat_id].base_color_texture
        np.testing.assert_allclose(texture.pixels[..., :3].reshape(-1, 3).mean(0), colour,
                                   atol=1e-4)
