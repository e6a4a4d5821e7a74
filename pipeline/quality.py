"""The measured-ladder store behind auto quality (kernels/auto_quality.py).

`compare` records each ladder it measures in a JSON file (default out/quality/ladders.json, or
$CLASSIC_BAKE_QUALITY_DB); technique commands given `--target-error` pick their settings from it.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

DEFAULT_DB = Path("out/quality/ladders.json")


def db_path() -> Path:
    return Path(os.environ.get("CLASSIC_BAKE_QUALITY_DB", DEFAULT_DB))


def scene_features(scene, resolution=None) -> dict:
    """What makes two scenes cost and err alike: triangles, lights, pixels, specular objects."""
    width, height = resolution or (scene.camera.resolution if scene.camera else (0, 0))
    specular = {int(o) for o in np.unique(scene.object_ids[np.isin(
        scene.material_ids, [k for k, m in enumerate(scene.materials)
                             if m.metallic > 0 or m.transmission > 0])])} if scene.triangle_count else set()
    return {"triangles": scene.triangle_count, "lights": len(scene.lights),
            "pixels": int(width * height), "specular_objects": len(specular)}


def load() -> list[dict]:
    path = db_path()
    if not path.exists():
        return []
    try:
        return json.loads(path.read_text())
    except (OSError, json.JSONDecodeError):
        return []


def record_ladder(technique: str, scene: str, features: dict, rows: list[dict]) -> Path:
    """Store (replace) the ladder measured for `technique` on `scene`; written atomically."""
    records = [r for r in load() if not (r["technique"] == technique and r["scene"] == scene)]
    records.append({"technique": technique, "scene": scene, "features": features,
                    "rows": [{"argv": r["argv"], "seconds": r["seconds"], "rel_mse": r["rel_mse"]}
                             for r in rows]})
    path = db_path()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps(records, indent=1))
    os.replace(tmp, path)
    return path


def check_target(ctx, technique, summary) -> None:
    """After a `--target-error` run: the error the view reached against a cached Cycles reference
    of this scene under the technique's model (made by `compare`; none is rendered here), and
    whether the target was met, in metrics.json's `auto_quality` and one line."""
    from pathlib import Path

    from ..addon.cycles.cache import cached_render
    from ..kernels.measure.metrics import rel_mse

    found = ctx.record.extra.setdefault("auto_quality", {})
    reference = None
    if technique.cycles_model is not None and summary.render is not None:
        reference = cached_render(Path(ctx.args.scene).resolve(),
                                  technique.cycles_model(summary.settings), ctx.resolution)
    if reference is None or reference.image.shape != summary.render.shape:
        found.update(measured_rel_mse=None, target_met=None,
                     measured="no cached Cycles reference at this size: run `compare` first")
        ctx.say("auto quality: not measured (no cached Cycles reference; `compare` makes one)")
        return
    error = rel_mse(summary.render, reference.image)
    met = error <= ctx.args.target_error
    found.update(measured_rel_mse=error, target_met=met, reference_samples=reference.samples)
    ctx.say(f"auto quality: measured relMSE {error:.3g} against Cycles ({reference.samples} "
            f"samples): target {ctx.args.target_error:.3g} {'met' if met else 'NOT met'}")


def apply_target(ctx, technique) -> None:
    """With `--target-error`, replace the technique's options by the rung `pick` chose for the most
    similar scene measured (kernels/measure/auto_quality.py)."""
    from ..addon.bridge.request import SnapshotRequest
    from ..addon.bridge.snapshot import snapshot
    from ..kernels.measure.auto_quality import pick
    from .arguments import technique_values
    from .outputs import UsageError

    target = ctx.args.target_error
    # The features read geometry, lights and materials: no world shader is rendered for them.
    scene = snapshot(request=SnapshotRequest(textures=False, uv=False, world_render=False),
                     resolution=ctx.resolution)
    try:
        chosen = pick(load(), technique.name, scene_features(scene, ctx.resolution), target)
    except ValueError as exc:
        raise UsageError(str(exc)) from exc
    for key, value in technique_values(technique, chosen.setting).items():
        if key != "target_error":
            setattr(ctx.args, key, value)
    ctx.record.extra["auto_quality"] = {"target_rel_mse": target, "picked": chosen.setting,
                                        "expected_rel_mse": chosen.expected_rel_mse,
                                        "expected_seconds": chosen.expected_seconds,
                                        "from_scene": chosen.scene, "met_target": chosen.met_target,
                                        "reason": chosen.reason}
    ctx.say(f"auto quality: picked {' '.join(chosen.setting) or 'the defaults'} ({chosen.reason})")
