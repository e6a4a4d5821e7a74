"""Per-scene settings (`scene.classic_bake`), edited in the sidebar and read by `settings.py`."""

import bpy
from bpy.props import (
    BoolProperty,
    EnumProperty,
    FloatProperty,
    IntProperty,
    PointerProperty,
    StringProperty,
)


class CLASSICBAKE_PG_settings(bpy.types.PropertyGroup):
    lightmap_resolution: IntProperty(
        name="Lightmap Size", description="Texels along each side of a lightmap",
        default=512, min=16, max=16384, soft_max=4096)
    lightmap_padding: IntProperty(
        name="Padding", description="Texels kept free between UV charts", default=2, min=0, max=64)
    lightmap_uv_name: StringProperty(
        name="UV Layer", description="Name of the lightmap UV layer (created where missing, "
        "never overwritten)", default="Lightmap")


    trace_depth: IntProperty(
        name="Depth", description="Ray-tree depth; -1 chooses it from the scene's mirrors and glass",
        default=-1, min=-1, max=64)
    trace_supersample: IntProperty(
        name="Samples", description="N x N samples in every pixel (1: pixel centres)",
        default=1, min=1, max=16)
    trace_adaptive: IntProperty(
        name="Edge Samples", description="N x N samples again in pixels at edges (0: off)",
        default=4, min=0, max=16)
    envmap_face_size: IntProperty(
        name="Face Size", description="Texels per cube-map face side; 0 chooses it per object "
        "from its size on screen", default=0, min=0, max=4096)
    envmap_face_samples: IntProperty(
        name="Face Samples", description="N x N rays per face texel, averaged", default=1, min=1,
        max=8)
    envmap_parallax_steps: IntProperty(
        name="Parallax Steps", description="Refinements of the search along each reflected ray "
        "for the surface it meets (0: the lecture's look-up along the reflected direction alone)",
        default=4, min=0, max=16)
    envmap_selected_only: BoolProperty(
        name="Selected Only", description="Map the selected objects; off: every mirror (smooth "
        "metal)", default=False)
    texture_samples: IntProperty(
        name="Cells per Side", description="n x n texture look-ups per lightmap texel, each "
        "filtered over its part of the texel (0: from each texel's footprint in the texture)",
        default=0, min=0, max=16)
    bump_shading: EnumProperty(
        name="Shading", description="Which normals the camera view is shaded with",
        items=[("BUMP", "Bump", "Interpolated normals perturbed by the materials' height (Bump "
                "node) and normal maps, in the tangent frame"),
               ("PHONG", "Phong", "Corner normals interpolated, light per pixel"),
               ("GOURAUD", "Gouraud", "Light computed at the corners, interpolated"),
               ("FLAT", "Flat", "One normal per triangle")], default="BUMP")
    shadow_map_size: IntProperty(
        name="Map Size", description="Shadow-map texels per side; 0 chooses it per light from the "
        "receivers' texel size", default=0, min=0, max=16384)
    shadow_eps_auto: BoolProperty(
        name="Automatic Tolerance", description="Depth tolerance from texel size and slope "
        "(shadow_bias reference); off: the fixed tolerance below", default=True)
    shadow_eps: FloatProperty(
        name="Tolerance", description="The lecture's depth tolerance against self-shadowing",
        default=0.0, min=0.0, soft_max=0.5, subtype="DISTANCE", unit="LENGTH")
    shadow_pcf: IntProperty(
        name="PCF", description="K x K percentage-closer filtering (1: hard)", default=1, min=1,
        max=15, step=2)
    radiosity_method: EnumProperty(
        name="Form Factors", description="How form factors between patches are estimated",
        items=[("raycast", "Ray-Cast", "Exact point-to-polygon factors, visibility by shadow rays"),
               ("hemicube", "Hemicube", "Hemicubes at points of each patch (Cohen & Greenberg)")],
        default="raycast")
    radiosity_solver: EnumProperty(
        name="Solver", description="How the radiosity system is solved",
        items=[("auto", "Automatic", "Clustered when grouping fine meshes cuts the unknowns "
                "fourfold; else Gauss-Seidel up to 200 patches; above, hierarchical when its "
                "memory bound fits (refinement capped to fit), else Gauss-Seidel or "
                "progressive refinement"),
               ("gauss_seidel", "Gauss-Seidel", "Gathering on the dense form factor matrix"),
               ("progressive", "Progressive", "Shooting, one row at a time, never N x N"),
               ("hierarchical", "Hierarchical", "Patches gather from a hierarchy of sources, "
                "coarse where the form factor is small (links, not N x N)"),
               ("clustered", "Clustered", "Small patches of fine meshes solved as groups by "
                "object, place and facing (ray-cast factors)")],
        default="auto")
    radiosity_patches: IntProperty(
        name="Patches", description="Patches aimed at before refinement (sets the patch size)",
        default=400, min=1, soft_max=5000)
    radiosity_refine: IntProperty(
        name="Refinement", description="Adaptive refinement levels (patches split where the "
        "solution varies strongly or a shadow boundary crosses); -1: auto, none with the final "
        "gather (its receivers carry the detail), one level without it", default=-1, min=-1,
        max=4)
    radiosity_shadow_splits: IntProperty(
        name="Shadow Splits", description="Times patches across a point, spot or sun lamp's "
        "shadow edge are split before the solve, so the light they pass on follows the shadow; "
        "-1: auto, 2 with the final gather when such a lamp casts shadows, else 0", default=-1,
        min=-1, max=4)
    radiosity_final_gather: BoolProperty(
        name="Final Gather", description="Read the solution out with exact direct light (and "
        "its shadows) at every texel, pixel and corner; the patches carry only the indirect light",
        default=True)
    radiosity_gather_rays: IntProperty(
        name="Gather Rays", description="Final gather: shadow rays per receiver to the emissive "
        "surfaces (more: smoother penumbrae)", default=16, min=1, soft_max=256)
    radiosity_world_rays: IntProperty(
        name="World Rays", description="Rays per patch that find its share of open sky, which "
        "the world's colour lights as Cycles does (0: the world lights no surface)", default=64,
        min=0, soft_max=1024)
    radiosity_wire: BoolProperty(
        name="Show in Materials", description="Wire the 'Radiosity' attribute into the materials "
        "(Emission) so viewport and renders show the bake", default=False)
    compare_technique: EnumProperty(
        name="Technique", description="Which kernel render to compare with Cycles",
        items=[("TRACE", "Ray Tracing", "The Whitted tracer against Cycles' whitted model"),
               ("TEXTURE", "Texture Mapping", "The albedo seen through the camera, textures "
                "filtered over each pixel, against Cycles' Diffuse Color pass"),
               ("BUMP", "Bump Mapping", "The shading mode of the Bump Mapping panel against "
                "Cycles' whitted model (its Bump and Normal Map nodes)"),
               ("ENVMAP", "Environment Mapping", "Cube-mapped mirrors against Cycles' whitted "
                "model (true reflections)"),
               ("SHADOWMAP", "Shadow Mapping", "Direct light with shadow maps against Cycles' "
                "direct-light model")], default="TRACE")
    compare_samples: IntProperty(
        name="Cycles Samples", description="Samples of the Cycles render compared with",
        default=64, min=1, max=65536)
    # Results of the last comparison, shown in the panel (read-only in the interface).
    compare_rel_mse: FloatProperty(name="Relative MSE", default=-1.0)
    compare_flip: FloatProperty(name="HDR-FLIP", default=-1.0)
    compare_kernel_seconds: FloatProperty(name="Kernel Seconds", default=0.0)
    compare_cycles_seconds: FloatProperty(name="Cycles Seconds", default=0.0)


CLASSES = (CLASSICBAKE_PG_settings,)


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(CLASSES)


def register() -> None:
    _register_classes()
    bpy.types.Scene.classic_bake = PointerProperty(type=CLASSICBAKE_PG_settings)


def unregister() -> None:
    del bpy.types.Scene.classic_bake
    _unregister_classes()
