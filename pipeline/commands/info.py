"""`info`: what the snapshot extracts from a scene, and what it ignores and why."""

from __future__ import annotations

import numpy as np

from ..command import Command, RunContext
from ..outputs import UsageError


def baked_sockets(scene) -> list[dict]:
    """The sockets the snapshot read through a Cycles bake of their node graph (the bridge's
    general fallback), one entry each: material, socket, read_as, seconds, cached, object."""
    return [{"material": mat.name, **entry} for mat in scene.read_materials for entry in mat.fallbacks]


def describe(scene) -> dict:
    """A JSON-ready summary of a kernel Scene."""
    from ...kernels.geometry.scene import triangle_areas
    from ...kernels.shading.specular_layer import diffuse_factor
    from ...kernels.shading.world_light import extract_suns

    areas = triangle_areas(scene.triangles)
    objects = []
    for k, info in enumerate(scene.objects):
        rows = scene.object_slice(k)
        objects.append({
            "name": info.name,
            "triangles": info.tri_count,
            "area_m2": float(areas[rows].sum()),
            "materials": sorted({scene.materials[m].name for m in scene.material_ids[rows]}),
            "has_uv": info.has_uv,
            "instance": info.is_instance,
        })
    materials = []
    used = set(np.unique(scene.material_ids).tolist())
    for index, mat in enumerate(scene.materials):
        if index not in used:
            continue
        tex = mat.base_color_texture
        materials.append({
            "name": mat.name,
            "base_color": mat.base_color,
            "base_color_texture": None if tex is None else f"{tex.kind}:{tex.name}",
            "metallic": mat.metallic,
            "metal_color": mat.metal_color,
            "glass_tint": mat.glass_tint,
            "translucent": mat.translucent,
            "roughness": mat.roughness,
            "ior": mat.ior,
            "transmission": mat.transmission,
            "specular": mat.specular,
            # What a bake shows of the base under the specular layer (1 without one).
            "diffuse_under_layer": diffuse_factor(mat),
            "emission_radiance": mat.emission,
            # Sockets read from textures (through their node chains), by texture name.
            "textures": {socket: f"{t.kind}:{t.name}" for socket, t in (
                ("emission", mat.emission_texture), ("metallic", mat.metallic_texture),
                ("roughness", mat.roughness_texture)) if t is not None},
            "normal_map": None if mat.normal_texture is None else mat.normal_texture.name,
            "bump_height": None if mat.height_texture is None else mat.height_texture.name,
            # Sockets read through a Cycles bake of their graph, with its cost.
            "fallbacks": [dict(entry) for entry in mat.fallbacks],
        })
    lights = []
    for light in scene.lights:
        entry = {"name": light.name, "kind": light.kind, "position": light.position,
                 "direction": light.direction}
        if light.intensity is not None:
            entry["intensity_w_per_sr"] = light.intensity
            entry["radius_m"] = light.radius
        if light.irradiance is not None:
            entry["irradiance_w_per_m2"] = light.irradiance
        if light.radiance is not None:
            entry["radiance_w_per_m2_sr"] = light.radiance
            entry["size_m"] = [light.size_x, light.size_y]
        if light.kind == "SPOT":
            entry["spot_size_deg"] = float(np.degrees(light.spot_size))
            entry["spot_blend"] = light.spot_blend
        lights.append(entry)
    cam = scene.camera
    camera = None if cam is None else {
        "kind": cam.kind, "position": cam.position, "resolution": list(cam.resolution),
        "plane_min": cam.plane_min, "plane_max": cam.plane_max,
        "clip": [cam.clip_start, cam.clip_end]}
    return {
        "counts": {"objects": len(scene.objects), "triangles": scene.triangle_count,
                   "materials": len(used), "lights": len(scene.lights)},
        "total_area_m2": float(areas.sum()),
        "objects": objects,
        "materials": materials,
        "lights": lights,
        "camera": camera,
        "world_radiance": scene.world_color,
        "world_map": None if scene.world_texture is None else {
            "image": scene.world_texture.name,
            "size": list(scene.world_texture.pixels.shape[1::-1]),
            # What radiosity lights as sun lamps (`world_light.extract_suns`).
            "suns": [{"direction": -sun.direction, "irradiance": sun.irradiance}
                     for sun in extract_suns(scene.world_texture, scene.world_transform)[0]]},
        "ignored": list(scene.ignored),
        "fallbacks": baked_sockets(scene),
    }


def _fmt(v) -> str:
    arr = np.atleast_1d(np.asarray(v, float))
    return "(" + ", ".join(f"{x:.4g}" for x in arr) + ")" if arr.size > 1 else f"{arr[0]:.4g}"


def _print(ctx: RunContext, d: dict) -> None:
    c = d["counts"]
    ctx.say(f"{ctx.record.scene}")
    ctx.say(f"  {c['objects']} objects, {c['triangles']} triangles, "
            f"{d['total_area_m2']:.4g} m^2, {c['materials']} materials, {c['lights']} lights")
    for o in d["objects"]:
        ctx.say(f"  object {o['name']}: {o['triangles']} tris, {o['area_m2']:.4g} m^2, "
                f"materials {', '.join(o['materials'])}{'' if o['has_uv'] else ', no UVs'}")
    for m in d["materials"]:
        parts = [f"base {_fmt(m['base_color'])}"]
        if m["base_color_texture"]:
            parts.append(f"texture {m['base_color_texture']}")
        for key in ("metallic", "transmission"):
            if m[key]:
                parts.append(f"{key} {m[key]:.3g}")
        if m["metal_color"] is not None:
            parts.append(f"metal tint {_fmt(m['metal_color'])}")
        if m["glass_tint"] is not None:
            parts.append(f"glass reflection tint {_fmt(m['glass_tint'])}")
        if np.any(np.asarray(m["translucent"]) > 0):
            parts.append(f"translucent {_fmt(m['translucent'])}")
        parts.append(f"roughness {m['roughness']:.3g}")
        if m["diffuse_under_layer"] < 1.0 and m["metallic"] < 1.0 and m["transmission"] < 1.0:
            parts.append(f"specular layer {m['specular']:.3g} (a bake shows "
                         f"{100 * m['diffuse_under_layer']:.1f}% of the base)")
        if np.any(np.asarray(m["emission_radiance"]) > 0):
            parts.append(f"emits {_fmt(m['emission_radiance'])} W/(m^2 sr)")
        if m["normal_map"] or m["bump_height"]:
            parts.append(f"bump {m['normal_map'] or m['bump_height']}")
        ctx.say(f"  material {m['name']}: " + ", ".join(parts))
        for fb in m["fallbacks"]:
            ctx.say(f"    '{fb['socket']}' read from a {fb['read_as']} over '{fb['object']}' "
                    f"({fb['seconds']:.3g} s{', cached' if fb['cached'] else ''})")
    for li in d["lights"]:
        value = next((f"{label} {_fmt(li[key])}" for key, label in (
            ("intensity_w_per_sr", "I W/sr"), ("irradiance_w_per_m2", "E W/m^2"),
            ("radiance_w_per_m2_sr", "L W/(m^2 sr)")) if key in li), "")
        ctx.say(f"  light {li['name']}: {li['kind']} at {_fmt(li['position'])}, {value}")
    cam = d["camera"]
    if cam:
        ctx.say(f"  camera: {cam['kind']} at {_fmt(cam['position'])}, "
                f"{cam['resolution'][0]}x{cam['resolution'][1]} px")
    if d["world_map"]:
        ctx.say(f"  world: equirectangular map '{d['world_map']['image']}' "
                f"({d['world_map']['size'][0]}x{d['world_map']['size'][1]}), mean radiance "
                f"{_fmt(d['world_radiance'])}")
        for sun in d["world_map"]["suns"]:
            ctx.say(f"    its sun towards {_fmt(sun['direction'])}: {_fmt(sun['irradiance'])} W/m^2 "
                    "(radiosity lights it as a sun lamp)")
    else:
        ctx.say(f"  world radiance {_fmt(d['world_radiance'])}")
    for why in d["ignored"]:
        ctx.say(f"  ignored: {why}")


def run(ctx: RunContext) -> None:
    from ...addon.bridge import snapshot

    with ctx.phase("snapshot"):
        try:
            scene = snapshot(resolution=ctx.resolution)
        except ValueError as exc:  # e.g. a panoramic camera: one line, as the techniques say it
            raise UsageError(f"info: {exc}") from exc
    summary = describe(scene)
    ctx.record.sizes = dict(summary["counts"])
    ctx.record.extra["ignored"] = summary["ignored"]  # as every technique's run lists it
    ctx.record.extra["fallbacks"] = summary["fallbacks"]
    ctx.staging.write_json("info.json", summary)
    _print(ctx, summary)


COMMAND = Command(name="info", help="print what the scene snapshot extracts, and what it ignores",
                run=run)
