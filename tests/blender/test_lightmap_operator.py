"""The lightmap-UV operator: creates missing layers only, and a cancelled run changes nothing."""

import bmesh
import bpy
import numpy as np

from classic_bake.addon import bridge


def cube(name, size=1.0):
    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    bm.loops.layers.uv.new("UVMap")  # calc_uvs fills an existing layer
    bmesh.ops.create_cube(bm, size=size, calc_uvs=True)
    bm.to_mesh(mesh)
    bm.free()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def test_operator_creates_lightmap_uvs_on_every_mesh(addon):
    a, b = cube("A"), cube("B", 2.0)
    bpy.context.scene.classic_bake.lightmap_resolution = 128
    assert bpy.ops.classic_bake.lightmap_uv(all_objects=True) == {"FINISHED"}
    for obj in (a, b):
        assert [lay.name for lay in obj.data.uv_layers] == ["UVMap", "Lightmap"]
        assert obj.data.uv_layers.active.name == "UVMap"
    snap = bridge.snapshot(request=bridge.SnapshotRequest(lightmap_uv="Lightmap"))
    assert all(o.has_lightmap_uv for o in snap.objects)
    assert np.all((snap.lightmap_uv >= 0) & (snap.lightmap_uv <= 1))


def test_existing_layers_are_never_overwritten(addon):
    obj = cube("A")
    layer = obj.data.uv_layers.new(name="Lightmap")
    layer.uv.foreach_set("vector", np.full(len(obj.data.loops) * 2, 0.25, np.float32))
    assert bpy.ops.classic_bake.lightmap_uv(all_objects=True) == {"FINISHED"}
    values = np.empty(len(obj.data.loops) * 2, np.float32)
    obj.data.uv_layers["Lightmap"].uv.foreach_get("vector", values)
    assert np.all(values == 0.25)


def test_cancelled_job_leaves_the_scene_as_it_was(addon):
    from classic_bake.jobs.lightmap_uv import unwrap_job
    from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings

    targets = [cube("A"), cube("B")]
    job = unwrap_job(targets, "Lightmap", LightmapUVSettings(resolution=64))
    assert 0.0 < next(job) < 1.0  # one mesh unwrapped, nothing written yet
    job.close()  # what Esc does
    assert all("Lightmap" not in o.data.uv_layers for o in bpy.data.objects)


def test_operator_poll_explains_itself(addon):
    assert not bpy.ops.classic_bake.lightmap_uv.poll()


def test_a_subdivided_monkey_gets_one_uv_per_polygon_corner(addon):
    """xatlas charts triangles and cuts some of a subdivided Suzanne's quads along their
    diagonal; a mesh stores one UV per polygon corner, which once made the shared corners take
    the other chart's UV: slivers thousands of times their 3D area across the lightmap, over
    other charts. Every polygon now lies in one chart, and the layer Blender stores holds the
    UVs xatlas packed."""
    bpy.ops.mesh.primitive_monkey_add()
    monkey = bpy.context.active_object
    bmesh_ = bmesh.new()
    bmesh_.from_mesh(monkey.data)
    bmesh.ops.subdivide_edges(bmesh_, edges=bmesh_.edges[:], cuts=1, use_grid_fill=True)
    bmesh_.to_mesh(monkey.data)
    bmesh_.free()
    from classic_bake.kernels.bake.lightmap_uv import LightmapUVSettings

    loop_uv, summary = bridge.lightmap_loop_uv(monkey, LightmapUVSettings(resolution=128))
    assert summary["split_polygons"] == 0
    verts, loops, _, _ = bridge.mesh_triangles(monkey.data)
    positions = bridge.mesh_positions(monkey.data).astype(np.float64)[verts]
    uv = loop_uv[loops].astype(np.float64)  # (T, 3, 2): what the stored layer gives each triangle
    area3 = 0.5 * np.linalg.norm(np.cross(positions[:, 1] - positions[:, 0],
                                          positions[:, 2] - positions[:, 0]), axis=1)
    u1, u2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    area2 = 0.5 * np.abs(u1[:, 0] * u2[:, 1] - u1[:, 1] * u2[:, 0])
    real = area3 > 1e-6 * np.median(area3)
    ratio = area2[real] / area3[real]
    # xatlas' own charts stretch a triangle a few times at most; a sliver is 100-10,000 times.
    assert ratio.max() < 10.0 * np.median(ratio)
