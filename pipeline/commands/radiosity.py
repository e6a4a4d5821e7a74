"""`radiosity`: diffuse global illumination solved on patches, baked into lightmaps and a
'Radiosity' corner colour attribute (outgoing radiance B / pi), and the camera's view of the
solution (render.exr)."""

from __future__ import annotations

from ..cli import Command, RunContext, command
from ..outputs import UsageError

# Defaults of the options, also used when another command (demo) runs this one without them.
DEFAULTS = {"method": "raycast", "solver": "auto", "patches": 400, "patch_size": 0.0,
            "refine": -1, "shadow_splits": -1, "final_gather": True, "gather_rays": 16, "world_rays": 64,
            "lightmap_size": 128,
            "padding": 2, "uv_name": "Lightmap", "wire": False}
# kernels.radiosity.settings.SOLVERS, written out: the kernels load only when a command runs.
SOLVERS = ("auto", "gauss_seidel", "progressive", "hierarchical", "clustered")


def add_arguments(parser) -> None:
    parser.add_argument("--method", choices=("raycast", "hemicube"), default=DEFAULTS["method"],
                        help="form factors: ray-cast point-to-polygon (default) or hemicube")
    parser.add_argument("--solver", choices=SOLVERS, default=DEFAULTS["solver"],
                        help="auto (default): clustered (the patches of finely tessellated meshes "
                             "solved as groups) when that cuts the unknowns fourfold; else "
                             "Gauss-Seidel up to 200 patches, above that hierarchical (links to a "
                             "hierarchy of sources) when its memory bound fits (refinement "
                             "capped to fit), else Gauss-Seidel while the dense matrix fits, "
                             "else progressive")
    parser.add_argument("--patches", type=int, default=DEFAULTS["patches"], metavar="N",
                        help="patches aimed at before refinement (default 400)")
    parser.add_argument("--patch-size", type=float, default=DEFAULTS["patch_size"], metavar="M",
                        help="longest patch edge in metres (default 0: from --patches)")
    parser.add_argument("--refine", type=int, default=DEFAULTS["refine"], metavar="LEVELS",
                        help="adaptive refinement levels (default -1, auto: 0 with the final gather, "
                             "whose receivers carry the detail, 1 without it)")
    parser.add_argument("--shadow-splits", type=int, default=DEFAULTS["shadow_splits"],
                        metavar="LEVELS",
                        help="times patches across a point, spot or sun lamp's shadow edge are "
                             "split before the solve (default -1, auto: 2 with the final gather "
                             "when such a lamp casts shadows, else 0)")
    parser.add_argument("--no-final-gather", dest="final_gather", action="store_false",
                        help="interpolate the patch solution instead of gathering direct light "
                             "at every texel, pixel and corner")
    parser.add_argument("--gather-rays", type=int, default=DEFAULTS["gather_rays"], metavar="N",
                        help="final gather: shadow rays per receiver to emissive surfaces "
                             "(default 16)")
    parser.add_argument("--world-rays", type=int, default=DEFAULTS["world_rays"], metavar="N",
                        help="rays per patch that find its share of open sky, which the world's "
                             "colour lights (default 64; 0: the world lights no surface)")
    parser.add_argument("--lightmap-size", type=int, default=DEFAULTS["lightmap_size"],
                        metavar="TEXELS", help="lightmap of the largest object (default 128)")
    parser.add_argument("--padding", type=int, default=DEFAULTS["padding"], metavar="TEXELS",
                        help="chart padding")
    parser.add_argument("--uv-name", default=DEFAULTS["uv_name"],
                        help="lightmap UV layer (created if missing)")
    parser.add_argument("--wire", action="store_true",
                        help="wire the 'Radiosity' attribute into the materials (with --save-blend)")


def settings_from(args):
    from ...kernels.bake.lightmap_uv import LightmapUVSettings
    from ...kernels.radiosity.settings import RadiositySettings

    value = {k: getattr(args, k, v) for k, v in DEFAULTS.items()}
    try:
        settings = RadiositySettings(method=value["method"], solver=value["solver"],
                                     patch_budget=value["patches"], patch_size=value["patch_size"],
                                     refine_levels=value["refine"],
                                     shadow_splits=value["shadow_splits"],
                                     final_gather=value["final_gather"],
                                     gather_rays=value["gather_rays"],
                                     world_rays=value["world_rays"])
        uv = LightmapUVSettings(resolution=value["lightmap_size"], padding=value["padding"])
    except ValueError as exc:
        raise UsageError(f"radiosity: {exc}") from exc
    return settings, uv, value


def run(ctx: RunContext) -> None:
    from dataclasses import asdict

    import bpy

    from ...addon.jobs import radiosity_bake_job, run_to_end
    from ..bake_outputs import write_bake_outputs

    settings, uv, value = settings_from(ctx.args)
    with ctx.phase("bake"):
        try:
            summary = run_to_end(radiosity_bake_job(bpy.context, settings, value["uv_name"], uv,
                                           resolution=ctx.resolution, wire=value["wire"]))
        except ValueError as exc:
            raise UsageError(str(exc)) from exc
    if summary["render"] is None:
        raise UsageError("radiosity: the scene has no camera, so there is no render.exr")
    with ctx.phase("write"):
        write_bake_outputs(ctx, summary, "radiosity")
    stats = summary["result"].stats
    scene = summary["scene"]
    ctx.record.settings = {**asdict(settings), "lightmap_size": uv.resolution,
                           "padding": uv.padding, "uv_name": value["uv_name"]}
    ctx.record.sizes = {
        "patches": stats["patches"],
        "patches_per_level": {str(k): v for k, v in stats["per_level"].items()},
        "refinement_levels": len(stats["levels"]) - 1,
        "triangles": scene.triangle_count, "lights": len(scene.lights),
        "baked_texels": int(sum(int(m.sum()) for _, m in summary["lightmaps"].values())),
        "filtered_texels": int(summary["filtered_texels"]),  # averaged over sub-texel points
        "memory_estimate_bytes": stats["memory_estimate"]["total"],
    }
    ctx.record.extra["radiosity"] = {
        "solver": stats["solver"], "method": stats["method"], "patch_size_m": stats["patch_size_m"],
        # What "auto" (0 and -1 in settings) chose for this scene.
        "samples_per_side": stats["samples_per_side"], "refine_levels": stats["refine_levels"],
        "shadow_splits": stats["shadow_splits"],
        "memory_estimate": stats["memory_estimate"],
        "levels": [{k: v for k, v in level.items() if k != "memory_estimate"}
                   for level in stats["levels"]],
        "final_gather": stats.get("final_gather"),  # None when switched off
        "world": stats.get("world"),  # sky rays per patch, suns taken from the world's map
    }
    ctx.record.extra["skipped"] = summary["skipped"]
    ctx.say(f"radiosity: {stats['patches']} patches (levels {stats['per_level']}), "
            f"{stats['solver']} with {stats['method']} form factors in {stats['seconds']:.2f} s; "
            f"lightmaps on {len(summary['lightmaps'])} objects, colour attribute 'Radiosity' on "
            f"{len(summary['attributes'])}")
    for why in summary["skipped"]:
        ctx.say(f"  skipped: {why}")


command(Command(name="radiosity", help="solve radiosity; bake lightmaps, colour attributes and "
                "render the camera's view", run=run, add_arguments=add_arguments,
                is_technique=True))
