"""Blender scene parts for tests against Cycles: Principled planes under a sun and a world.

Imported by tests that run real Blender (the pip `bpy` module) only.
"""

import bpy

BASE = (0.2, 0.5, 0.8)
WORLD = (0.3, 0.6, 0.9)  # non-zero: a background pixel of 0 is not the world's colour
SUN_E = 3.0  # any light: the albedo must not depend on it


def principled(name, base=BASE, metallic=0.0):
    """A Principled material with Specular IOR Level 0 (no specular layer over the diffuse one)."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED")
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Metallic"].default_value = metallic
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    return mat, bsdf


def bare_material(name):
    """A new material whose node tree holds its Material Output alone: (material, tree, output)."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    tree = mat.node_tree
    for node in [n for n in tree.nodes if n.type != "OUTPUT_MATERIAL"]:
        tree.nodes.remove(node)
    return mat, tree, next(n for n in tree.nodes if n.type == "OUTPUT_MATERIAL")


def checker(mat, bsdf, scale=4.0, coordinates="UV"):
    """Drive the base colour with a white/black Checker Texture over the mesh's UVs, or with
    coordinates=None over what the node reads unlinked (Generated)."""
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexChecker")
    tex.inputs["Scale"].default_value = scale
    tex.inputs["Color1"].default_value = (1.0, 1.0, 1.0, 1.0)
    tex.inputs["Color2"].default_value = (0.0, 0.0, 0.0, 1.0)
    if coordinates is not None:
        coords = tree.nodes.new("ShaderNodeTexCoord")
        tree.links.new(coords.outputs[coordinates], tex.inputs["Vector"])
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])


def plane(mat, size=2.0):
    """A size x size quad in z = 0 facing +z, UV layer "Lightmap" spanning [0, 1]^2."""
    h = size / 2
    mesh = bpy.data.meshes.new("Plane")
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    mesh.uv_layers.new(name="Lightmap").uv.foreach_set("vector", [0, 0, 1, 0, 1, 1, 0, 1])
    mesh.materials.append(mat)
    obj = bpy.data.objects.new("Plane", mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def node_world(name: str):
    """A new world of shader nodes (a Background node) as the scene's: (scene, its node tree)."""
    scene = bpy.context.scene
    scene.world = bpy.data.worlds.new(name)
    if bpy.app.version < (5, 0, 0):
        scene.world.use_nodes = True
    return scene, scene.world.node_tree


def colour_world(colour=WORLD):
    """The scene's world: a Background of one colour (default `WORLD`); returns the scene."""
    scene, tree = node_world("World")
    tree.nodes["Background"].inputs["Color"].default_value = (*colour, 1.0)
    return scene


def lit_scene():
    """A sun and a non-black world (which must not reach the albedo)."""
    scene = colour_world()
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = SUN_E
    obj = bpy.data.objects.new("Sun", sun)
    obj.rotation_euler = (0.5, 0.0, 0.0)
    scene.collection.objects.link(obj)
    return scene


def oblique_camera(scene):
    """A perspective camera 4 m before the origin and 1.2 m up, tilted 72 degrees from looking
    down: a plane at z = 0 fills the view at 50-85 degrees from its normal."""
    import math

    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location, cam.rotation_euler = (0.0, -4.0, 1.2), (math.radians(72.0), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam


def overhead_sun(energy):
    """A camera 5 m above the origin looking straight down and a sun of `energy` W/m^2 shining
    straight down with it: (scene, camera). A Lambertian plane at z = 0 seen there shows
    albedo x energy / pi (pi W/m^2: the albedo itself)."""
    scene = bpy.context.scene
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0.0, 0.0, 5.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = energy
    scene.collection.objects.link(sun)
    return scene, cam


def hdri_world(pixels, strength=1.0):
    """The scene's world: an Environment Texture (equirectangular) of float pixels (H, W, 3),
    row 0 at the top, times `strength`."""
    import numpy as np

    height, width = pixels.shape[:2]
    image = bpy.data.images.new("Sky", width, height, alpha=True, float_buffer=True)
    rgba = np.ones((height, width, 4), np.float32)
    rgba[..., :3] = pixels
    image.pixels.foreach_set(rgba[::-1].ravel())  # Blender stores the bottom row first
    scene, tree = node_world("HDRI")
    env = tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = image
    background = tree.nodes["Background"]
    background.inputs["Strength"].default_value = strength
    tree.links.new(env.outputs["Color"], background.inputs["Color"])
    return scene


def tilted_tiles(size: int = 128, tilts=(0.5, -0.3)):
    """A Non-Color tangent-space normal map of tiles tilted `tilts` rad (two, alternating),
    along u or v."""
    import numpy as np

    i, j = np.mgrid[0:size, 0:size]
    angle = np.where(((i // 16) + (j // 16)) % 2 == 0, *tilts)
    along_u = (j // 32) % 2 == 0
    nx, ny = np.sin(angle) * along_u, np.sin(angle) * ~along_u
    pixels = np.ones((size, size, 4), np.float32)
    pixels[..., 0], pixels[..., 1] = 0.5 + 0.5 * nx, 0.5 + 0.5 * ny
    pixels[..., 2] = 0.5 + 0.5 * np.sqrt(1 - nx**2 - ny**2)
    image = bpy.data.images.new("Tiles", size, size, float_buffer=True)
    image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(pixels[::-1].ravel())  # Blender's rows run bottom-up
    return image


def normal_mapped(mat, bsdf, image):
    """Drive `bsdf`'s Normal with a tangent-space Normal Map of `image` in `mat`'s tree; returns
    the Normal Map node."""
    tree = mat.node_tree
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = image
    normal_map = tree.nodes.new("ShaderNodeNormalMap")
    tree.links.new(tex.outputs["Color"], normal_map.inputs["Color"])
    tree.links.new(normal_map.outputs["Normal"], bsdf.inputs["Normal"])
    return normal_map


def tiles_for_bumps(names):
    """Replace the Bump nodes of materials `names` by a tangent-space Normal Map of
    `tilted_tiles` on the Principled BSDF's Normal."""
    image = tilted_tiles()
    for name in names:
        mat = bpy.data.materials[name]
        tree = mat.node_tree
        for node in [n for n in tree.nodes if n.type == "BUMP"]:
            tree.nodes.remove(node)
        normal_mapped(mat, next(n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"), image)


def lit_floor():
    """A fresh scene: `lit_scene` (a sun, a blue-grey world), a 6 m grey Principled floor at
    z = 0 and `oblique_camera`: the stage the shader tests put one object on."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = lit_scene()
    plane(principled("Floor", base=(0.6, 0.6, 0.6))[0], size=6.0)
    oblique_camera(scene)
    return scene


def smooth_sphere(mat, radius=0.8, location=None):
    """A smooth UV sphere (48 x 24) with `mat`, resting on z = 0 unless `location` is given."""
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, segments=48, ring_count=24,
                                         location=location or (0.0, 0.0, radius))
    bpy.ops.object.shade_smooth()
    obj = bpy.context.object
    obj.data.materials.append(mat)
    return obj


def view_against_cycles(technique: str, resolution=(96, 72)):
    """(snapshot, relMSE) of the scene's radiosity ("radiosity") or shadow-map view against a
    256-sample Cycles render of the technique's model (radiosity lit by the world; direct)."""
    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.progress import drain
    from classic_bake.kernels.radiosity.settings import RadiositySettings
    from classic_bake.kernels.radiosity.solve import solve_radiosity
    from classic_bake.kernels.radiosity.view import render_steps
    from classic_bake.kernels.shading import direct_light

    snap = bridge.snapshot(resolution=resolution)
    if technique == "radiosity":
        ours = drain(render_steps(snap, solve_radiosity(snap, RadiositySettings()), resolution))
        model = cr.radiosity(world_lighting=True)
    else:
        ours = drain(direct_light.render_steps(snap, direct_light.DirectLightSettings(),
                                               resolution))
        model = cr.direct()
    theirs, _ = cr.render_camera(bpy.context.scene, model, 256, resolution)
    return snap, rel_mse(ours, theirs)


def glowing_ball():
    """A fresh `lit_floor` scene with a smooth sphere of an Emission shader of strength 2 resting
    on it (a mesh light of 2256 triangles); returns (scene, the ball)."""
    scene = lit_floor()
    mat, tree, out = bare_material("Glow")
    glow = tree.nodes.new("ShaderNodeEmission")
    glow.inputs["Strength"].default_value = 2.0
    tree.links.new(glow.outputs[0], out.inputs[0])
    return scene, smooth_sphere(mat)


def traced_against_cycles(scene, depth=4, samples=256, resolution=(96, 72)):
    """(snapshot, relMSE) of the tracer's view (TracerSettings(max_depth=depth)) against
    Cycles' Whitted model of the same depth at `samples` samples."""
    from classic_bake.addon import bridge
    from classic_bake.addon import cycles as cr
    from classic_bake.kernels.measure.metrics import rel_mse
    from classic_bake.kernels.trace.settings import TracerSettings
    from classic_bake.kernels.trace.tracer import trace

    snap = bridge.snapshot(resolution=resolution)
    ours = trace(snap, TracerSettings(max_depth=depth), resolution=resolution).image
    theirs, _ = cr.render_camera(scene, cr.whitted(depth), samples, resolution=resolution)
    return snap, rel_mse(ours, theirs)


def against_cycles(technique: str, scene, depth=4):
    """(snapshot, relMSE) of the technique's view against Cycles at 96 x 72: the tracer's
    ("trace", `traced_against_cycles` at `depth`), else `view_against_cycles`."""
    if technique == "trace":
        return traced_against_cycles(scene, depth)
    return view_against_cycles(technique)


def translucent_mix(tree, diffuse=(0.2, 0.6, 0.2), translucent=(0.2, 0.6, 0.2)):
    """A Mix Shader (Fac 0.5) of a Diffuse BSDF and a Translucent BSDF of those colours in
    `tree`: a leaf's material. Returns the Mix Shader node."""
    diffuse_node = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse_node.inputs["Color"].default_value = (*diffuse, 1.0)
    translucent_node = tree.nodes.new("ShaderNodeBsdfTranslucent")
    translucent_node.inputs["Color"].default_value = (*translucent, 1.0)
    mix = tree.nodes.new("ShaderNodeMixShader")
    mix.inputs["Fac"].default_value = 0.5
    tree.links.new(diffuse_node.outputs[0], mix.inputs[1])
    tree.links.new(translucent_node.outputs[0], mix.inputs[2])
    return mix


def backlit_leaf(world=(0.0, 0.0, 0.0), floor=False):
    """A fresh scene: a leaf card (a 1.6 m plane tilted 10 degrees back, half Diffuse (0.2, 0.6,
    0.1), half Translucent (0.3, 0.7, 0.1)) in a world of colour `world`, a sun of 3 W/m^2
    shining through it towards a camera in front of it; with `floor`, an 8 m grey floor under
    it. Returns the scene."""
    import math

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = colour_world(world)
    if floor:
        plane(principled("Floor", base=(0.6, 0.6, 0.6))[0], size=8.0)
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = 3.0
    sun.rotation_euler = (math.radians(-60.0), 0.0, 0.0)  # shining towards the camera
    scene.collection.objects.link(sun)
    mat, tree, out = bare_material("Leaf")
    mix = translucent_mix(tree, (0.2, 0.6, 0.1), (0.3, 0.7, 0.1))
    tree.links.new(mix.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_plane_add(size=1.6, location=(0, 0, 1.0),
                                     rotation=(math.radians(80.0), 0.0, 0.0))
    bpy.context.object.data.materials.append(mat)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.location, cam.rotation_euler = (0.0, -4.0, 1.3), (math.radians(85.0), 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    return scene
