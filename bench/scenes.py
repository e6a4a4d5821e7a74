"""Scenes generated from a seed, for benches that must not be tuned to one sample.

    build_room(seed, path) -> dict   # writes path (.blend) and returns what was drawn

A room of random proportions (2-6 m), wall, floor and ceiling reflectances and colours drawn from
greys, near-whites and saturated colours; one to four boxes on the floor or against a wall and a
tessellated sphere; lit by one of: an area lamp, a point lamp, a spot, a sun through a window in
an otherwise closed room, an emissive quad that also reflects (hanging under the ceiling), or the
world's colour through an opening. The area lamp hangs just under the ceiling, a point lamp or
spot 0.4-0.9 m under it. A camera inside looks across the room. Every Principled
surface has Specular IOR Level 0 (Lambertian, the radiosity model's surfaces).
"""

from __future__ import annotations

import math

import numpy as np

LIGHTINGS = ("area", "point", "spot", "sun_window", "emissive_quad", "world_opening")


def _material(bpy, name: str, colour, emission=None, strength: float = 0.0):
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    if emission is not None:
        bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = strength
    return mat


def _mesh(bpy, name: str, verts, faces, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in verts], [], faces)
    mesh.materials.append(mat)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def _colour(rng) -> tuple[float, float, float]:
    kind = rng.choice(["grey", "near_white", "saturated", "pastel"])
    if kind == "grey":
        return (float(rng.uniform(0.15, 0.7)),) * 3
    if kind == "near_white":
        return (float(rng.uniform(0.8, 0.92)),) * 3
    hue = rng.random()
    sat = rng.uniform(0.7, 0.95) if kind == "saturated" else rng.uniform(0.2, 0.4)
    value = rng.uniform(0.45, 0.85)
    rgb = np.clip(np.abs(((hue * 6 + np.array([0, 4, 2])) % 6) - 3) - 1, 0, 1)
    return tuple(float(c) for c in value * (1 - sat + sat * rgb))


def _wall_with_hole(bpy, name, origin, u, v, hole, mat):
    """A rectangle origin + s u + t v (s, t in [0, 1]) facing u x v, with the hole (s0, s1, t0, t1)
    left open (four quads around it)."""
    s0, s1, t0, t1 = hole
    o, u, v = np.asarray(origin, float), np.asarray(u, float), np.asarray(v, float)
    pieces = [(0, 1, 0, t0), (0, 1, t1, 1), (0, s0, t0, t1), (s1, 1, t0, t1)]
    verts, faces = [], []
    for a0, a1, b0, b1 in pieces:
        k = len(verts)
        verts += [o + a0 * u + b0 * v, o + a1 * u + b0 * v, o + a1 * u + b1 * v, o + a0 * u + b1 * v]
        faces.append((k, k + 1, k + 2, k + 3))
    return _mesh(bpy, name, verts, faces, mat)


def build_room(seed: int, path) -> dict:
    """Build the room of `seed` in an empty scene, save it to `path`; return what was drawn."""
    import bpy

    rng = np.random.default_rng(seed)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    w, d, h = (float(x) for x in rng.uniform([2.5, 2.5, 2.2], [6.0, 6.0, 3.5]))
    lighting = LIGHTINGS[seed % len(LIGHTINGS)]
    colours = {name: _colour(rng) for name in ("floor", "ceiling", "back", "front", "left", "right")}
    quads = {
        "floor": ([0, 0, 0], [w, 0, 0], [0, d, 0]), "ceiling": ([0, 0, h], [0, d, 0], [w, 0, 0]),
        "back": ([0, d, 0], [w, 0, 0], [0, 0, h]), "front": ([0, 0, 0], [0, 0, h], [w, 0, 0]),
        "left": ([0, 0, 0], [0, d, 0], [0, 0, h]), "right": ([w, 0, 0], [0, 0, h], [0, d, 0])}
    hole_wall = "right" if lighting in ("sun_window", "world_opening") else None
    for name, (o, u, v) in quads.items():
        mat = _material(bpy, name, colours[name])
        if name == hole_wall:
            _wall_with_hole(bpy, name, o, u, v, (0.3, 0.7, 0.35, 0.8), mat)
        else:
            o, u, v = (np.asarray(x, float) for x in (o, u, v))
            _mesh(bpy, name, [o, o + u, o + u + v, o + v], [(0, 1, 2, 3)], mat)
    boxes = int(rng.integers(1, 5))
    for k in range(boxes):
        size = rng.uniform([0.3, 0.3, 0.3], [min(w, d) * 0.3, min(w, d) * 0.3, h * 0.5])
        at = rng.uniform([size[0] / 2 + 0.1, size[1] / 2 + 0.1], [w - size[0] / 2 - 0.1,
                                                                  d - size[1] / 2 - 0.1])
        bpy.ops.mesh.primitive_cube_add(size=1.0, location=(at[0], at[1], size[2] / 2))
        box = bpy.context.active_object
        box.name, box.scale = f"Box{k}", tuple(size)
        box.data.materials.append(_material(bpy, f"Box{k}", _colour(rng)))
    radius = float(rng.uniform(0.15, 0.4))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, segments=24, ring_count=12, location=(
        float(rng.uniform(radius + 0.2, w - radius - 0.2)),
        float(rng.uniform(radius + 0.2, d - radius - 0.2)), radius))
    bpy.context.active_object.data.materials.append(_material(bpy, "Ball", _colour(rng)))
    centre = (w / 2, d / 2, h - 0.05)
    if lighting in ("area", "point", "spot"):
        light = bpy.data.lights.new("Lamp", {"area": "AREA", "point": "POINT",
                                             "spot": "SPOT"}[lighting])
        light.energy = float(rng.uniform(150, 600)) * (w * d / 10)
        if lighting == "area":
            light.size = float(rng.uniform(0.4, 1.0))
        if lighting == "spot":
            light.spot_size = math.radians(float(rng.uniform(60, 110)))
        lamp = bpy.data.objects.new("Lamp", light)
        # The area lamp faces down just under the ceiling; a point lamp or spot hangs lower (a
        # pendant): 5 cm under a ceiling, a point lamp's hot spot there makes Cycles' converged
        # reference unaffordable (fireflies: relMSE 15 at 16 samples per texel).
        drop = 0.05 if lighting == "area" else float(rng.uniform(0.4, 0.9))
        lamp.location = (centre[0], centre[1], h - drop)
        scene.collection.objects.link(lamp)
    elif lighting == "emissive_quad":
        e = float(rng.uniform(0.25, 0.5))
        z = h - float(rng.uniform(0.15, 0.5))
        cx, cy = w / 2, d / 2
        _mesh(bpy, "GlowPanel", [(cx - e, cy - e, z), (cx - e, cy + e, z), (cx + e, cy + e, z),
                                 (cx + e, cy - e, z)], [(0, 1, 2, 3)],
              _material(bpy, "GlowPanel", _colour(rng), _colour(rng), float(rng.uniform(8, 20))))
    elif lighting == "sun_window":
        sun = bpy.data.lights.new("Sun", "SUN")
        sun.energy = float(rng.uniform(3, 6))
        obj = bpy.data.objects.new("Sun", sun)
        # Pointing in through the window in the right wall (x = w), downwards.
        obj.rotation_euler = (0.0, math.radians(float(rng.uniform(-60, -40))), 0.0)
        scene.collection.objects.link(obj)
    if lighting in ("sun_window", "world_opening"):
        scene.world = bpy.data.worlds.new("Sky")
        if bpy.app.version < (5, 0, 0):
            scene.world.use_nodes = True
        background = scene.world.node_tree.nodes["Background"]
        background.inputs["Color"].default_value = (0.5, 0.65, 0.9, 1.0)
        background.inputs["Strength"].default_value = float(rng.uniform(1.0, 3.0))
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.angle = math.radians(75.0)
    cam.location = (w * 0.5, 0.15, h * 0.55)
    cam.rotation_euler = (math.radians(85.0), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = 80, 60
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    lamp = {"area": "Lamp", "point": "Lamp", "spot": "Lamp", "sun_window": "Sun"}.get(lighting)
    return {"seed": seed, "size_m": [w, d, h], "lighting": lighting, "boxes": boxes,
            "sphere_radius_m": radius, "closed": lighting not in ("sun_window", "world_opening"),
            # The lamp object a shadow map handles (None: the light is emission or the world),
            # and the emissive meshes (a DIFFUSE bake leaves their emission out).
            "lamp": lamp, "emitters": ["GlowPanel"] if lighting == "emissive_quad" else []}


def build_spheres(path) -> dict:
    """The tracer's second bench scene: a solid glass sphere and a polished metal sphere over a
    checkered floor, lit by two point lamps (one warm, one cool), a dim blue world; about 12k
    triangles at 192 x 144 pixels. Writes path (.blend) and returns its description."""
    import sys
    from pathlib import Path

    import bpy

    here = Path(__file__).resolve().parents[1] / "sample_blends"
    if str(here) not in sys.path:
        sys.path.insert(0, str(here))
    from sample_datablocks import (
        camera,
        checker_texture,
        light,
        material,
        mesh_object,
        render_settings,
        reset,
        world,
    )
    from sample_geometry import grid, uv_sphere

    scene = reset("Spheres")
    glass = material("Glass", (1.0, 1.0, 1.0), roughness=0.0, specular=0.5, transmission=1.0,
                     ior=1.45)
    metal = material("Metal", (0.95, 0.64, 0.54), metallic=1.0, roughness=0.0)
    floor = material("Floor")
    checker_texture(floor, (0.85, 0.85, 0.8), (0.1, 0.1, 0.12), 12.0)
    verts, faces, uvs = grid(6.0, 6.0, 8, 8)
    mesh_object("Floor", verts, faces, uvs, [floor])
    for name, mat, x in (("GlassSphere", glass, 0.65), ("MetalSphere", metal, -0.65)):
        verts, faces, uvs = uv_sphere(0.55, 80, 40)
        mesh_object(name, verts, faces, uvs, [mat], smooth=True, location=(x, 0.0, 0.55))
    light("Warm", "POINT", 900.0, (2.5, -2.5, 4.0), color=(1.0, 0.85, 0.7))
    light("Cool", "POINT", 400.0, (-3.0, -1.0, 2.5), color=(0.7, 0.8, 1.0))
    camera((0.0, -4.2, 1.6), target=(0.0, 0.0, 0.45), lens=35.0)
    world("DimBlue", (0.05, 0.07, 0.12))
    render_settings(scene, resolution=(192, 144), max_bounces=16, diffuse=0, glossy=8,
                    transmission=16)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.context.view_layer.update()
    bpy.ops.wm.save_as_mainfile(filepath=str(path), check_existing=False)
    triangles = sum(len(o.data.loop_triangles) if o.data.calc_loop_triangles() is None else 0
                    for o in scene.objects if o.type == "MESH")
    return {"name": "spheres", "triangles": triangles, "resolution": (192, 144)}
