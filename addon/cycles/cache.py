"""Cycles references cached on disk (`reference`): one folder per `cache_key` with one float32
OpenEXR per image and meta.json; a miss opens the .blend and renders or bakes it."""

from __future__ import annotations

import glob
import hashlib
import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import bpy
import numpy as np

from ...kernels.measure.exr import read_exr, write_exr
from ..bridge.mesh import ensure_lightmap_uv
from .bakes import COVERED_ALPHA
from .convergence import MAX_SAMPLES, START_SAMPLES, TARGET_REL_MSE, converged_run
from .models import CyclesModel
from .runner import warm_up
from .runs import BakeSpec, CyclesRun, ReferenceKind, run_cycles

# Bump this when what a cached reference means changes; it is part of every cache key.
CACHE_FORMAT = 2

# Tokens Blender expands in an image's path to one file per UDIM tile.
TILE_TOKENS = ("<UDIM>", "<UVTILE>")


@dataclass(frozen=True, eq=False)
class Reference:
    """A converged (or fixed-sample) Cycles result and where it came from.

    run: the images, masks, samples and seconds (the seconds of the renders that made it, also
    on a cache hit); cache_hit: True when read from the cache; noise_rel_mse: estimated relative
    MSE against the converged result (None when `samples` was fixed); path: the cache folder.
    """

    run: CyclesRun
    cache_hit: bool
    noise_rel_mse: float | None
    key: str
    path: Path
    settings: dict[str, Any]

    @property
    def image(self) -> np.ndarray:
        return self.run.image

    @property
    def images(self) -> dict[str, np.ndarray]:
        return self.run.images

    @property
    def masks(self) -> dict[str, np.ndarray]:
        return self.run.masks

    @property
    def samples(self) -> int:
        return self.run.samples

    @property
    def seconds(self) -> float:
        return self.run.seconds


def file_sha256(path: str | os.PathLike) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def dependency_hashes(scene_path: str | os.PathLike, paths) -> dict[str, str | None]:
    """The SHA-256 of each file a .blend reads from outside itself (images, libraries, caches),
    keyed by the path as the .blend records it (`//` is the .blend's folder); None for a missing
    file. A tiled path (`<UDIM>`) hashes the tiles it matches, in name order."""
    folder = Path(scene_path).parent
    hashes = {}
    for recorded in sorted(set(paths)):
        path = recorded.replace("\\", "/") if os.sep == "/" else recorded
        path = str(folder / path[2:]) if path.startswith("//") else path
        if any(token in path for token in TILE_TOKENS):
            pattern = glob.escape(path)
            for token in TILE_TOKENS:
                pattern = pattern.replace(glob.escape(token), "*")
            tiles = sorted(glob.glob(pattern))
            hashes[recorded] = hashlib.sha256(
                "".join(f"{Path(t).name}:{file_sha256(t)};" for t in tiles).encode()
            ).hexdigest() if tiles else None
        else:
            hashes[recorded] = file_sha256(path) if os.path.isfile(path) else None
    return hashes


def _dependencies_unchanged(scene_path: Path, meta: dict[str, Any]) -> bool:
    recorded = meta.get("dependencies")
    return isinstance(recorded, dict) and dependency_hashes(scene_path, recorded) == recorded


def cache_key(blend_sha256: str, model: CyclesModel, kind: str, *, samples: int | None,
              resolution: tuple[int, int] | None, bake: BakeSpec | None,
              target_rel_mse: float, max_samples: int) -> tuple[str, dict[str, Any]]:
    """(SHA-256 hex, the settings it hashes): the .blend's bytes, the model, the kind, the size,
    the sample count (or the convergence target and cap), the bake and Blender's version."""
    settings = {
        "format": CACHE_FORMAT,
        "blend_sha256": blend_sha256,
        "blender": bpy.app.version_string,
        "model": model.fields(),
        "kind": kind,
        "resolution": list(resolution) if resolution is not None else None,
        "samples": samples if samples is not None else {
            "auto": True, "target_rel_mse": target_rel_mse, "max_samples": max_samples,
            "start_samples": START_SAMPLES},
        "bake": bake.fields() if bake is not None and kind != "render" else None,
    }
    text = json.dumps(settings, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest(), settings


def _open_blend(path: Path) -> None:
    """Open a .blend as the CLI does: no UI, script auto-execution off."""
    bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)


def _prepare_bake(scene, bake: BakeSpec) -> None:
    if bake.lightmap_uv is None:
        return
    for name in bake.objects:
        obj = scene.objects.get(name)
        if obj is not None and obj.type == "MESH":
            ensure_lightmap_uv(obj, bake.uv_layer, bake.lightmap_uv)


def _write_cached(folder: Path, run: CyclesRun, meta: dict[str, Any]) -> None:
    """Write the run (one OpenEXR per image, masks as alpha) and meta.json into `folder`."""
    files = {}
    for index, (name, image) in enumerate(run.images.items()):
        file = "render.exr" if run.kind == "render" else f"{index:03d}.exr"
        pixels = image if image.ndim == 3 else image[:, None, :]  # attributes: (V, 1, 3)
        if name in run.masks:
            pixels = np.concatenate([pixels, run.masks[name][:, :, None].astype(np.float32)], -1)
        write_exr(folder / file, pixels)
        files[name] = file
    meta = dict(meta, files=files, samples=run.samples, seconds=run.seconds, kind=run.kind)
    (folder / "meta.json").write_text(json.dumps(meta, indent=1, sort_keys=True, default=str))


def _read_cached(folder: Path) -> tuple[CyclesRun, dict[str, Any]]:
    meta = json.loads((folder / "meta.json").read_text())
    images, masks = {}, {}
    for name, file in meta["files"].items():
        pixels = read_exr(folder / file)
        if meta["kind"] == "bake":
            masks[name] = pixels[:, :, 3] > COVERED_ALPHA
        pixels = pixels[:, :, :3]
        images[name] = pixels[:, 0, :].copy() if meta["kind"] == "attribute" else pixels.copy()
    run = CyclesRun(meta["kind"], int(meta["samples"]), float(meta["seconds"]), images, masks)
    return run, meta


def cached_render(scene_path: str | os.PathLike, model: CyclesModel,
                  resolution: tuple[int, int] | None,
                  cache_dir: str | os.PathLike = Path("out/cache")) -> Reference | None:
    """The most converged cached camera render of this .blend (same bytes) under `model` at
    `resolution`, whatever sample count made it; None when there is none. Never renders."""
    blend = file_sha256(Path(scene_path))
    wanted = {"blend_sha256": blend, "blender": bpy.app.version_string, "model": model.fields(),
              "kind": "render", "resolution": list(resolution) if resolution else None}
    best = None
    for meta_path in Path(cache_dir).glob("*/meta.json"):
        try:
            meta = json.loads(meta_path.read_text())
            settings = meta["settings"]
        except (OSError, ValueError, KeyError):
            continue
        if any(settings.get(k) != v for k, v in wanted.items()):
            continue
        if not _dependencies_unchanged(Path(scene_path), meta):
            continue
        if best is None or int(meta["samples"]) > int(best[1]["samples"]):
            best = (meta_path.parent, meta)
    if best is None:
        return None
    run, meta = _read_cached(best[0])
    return Reference(run, True, meta.get("noise_rel_mse"), meta.get("key"), best[0],
                     meta["settings"])


def reference(scene_path: str | os.PathLike, model: CyclesModel, kind: ReferenceKind = "render",
              samples: int | None = None, cache_dir: str | os.PathLike = Path("out/cache"), *,
              resolution: tuple[int, int] | None = None, bake: BakeSpec | None = None,
              target_rel_mse: float = TARGET_REL_MSE, max_samples: int = MAX_SAMPLES,
              ) -> Reference:
    """The Cycles reference of `scene_path` under `model`, from the cache or made and cached.

    `samples` fixed renders that many samples once; None chooses the count from the scene's noise
    (`converged_run`, `target_rel_mse`, `max_samples`). The cache folder `cache_dir/<key>` holds
    one float32 OpenEXR per image (lightmaps carry their coverage mask as alpha, colour attributes
    are (V, 1) images) and `meta.json` (settings, samples, seconds, noise). The key is the SHA-256
    of `cache_key`'s settings, so a changed .blend, model, kind, size, sample count, bake or
    Blender version is a miss; meta.json also records the hash of every file the .blend reads
    from outside itself (`dependency_hashes`), and a hit whose files changed is a miss too. On a
    miss the file is opened (replacing the open one, scripts off); on a hit nothing is opened or
    rendered.
    """
    scene_path = Path(scene_path)
    key, settings = cache_key(file_sha256(scene_path), model, kind, samples=samples,
                              resolution=resolution, bake=bake, target_rel_mse=target_rel_mse,
                              max_samples=max_samples)
    folder = Path(cache_dir) / key
    if (folder / "meta.json").is_file():
        run, meta = _read_cached(folder)
        if meta.get("key") == key and _dependencies_unchanged(scene_path, meta):
            return Reference(run, True, meta.get("noise_rel_mse"), key, folder, settings)

    _open_blend(scene_path)
    dependencies = dependency_hashes(scene_path, bpy.utils.blend_paths(absolute=False))
    scene = bpy.context.scene
    if bake is not None and kind != "render":
        _prepare_bake(scene, bake)
    warm_up(scene)

    def one(n: int, seed: int) -> CyclesRun:
        return run_cycles(scene, model, kind, n, resolution=resolution, bake=bake, seed=seed)

    if samples is not None:
        run, noise = one(int(samples), model.seed), None
    else:
        run, noise = converged_run(one, first_seed=model.seed, target_rel_mse=target_rel_mse,
                                   max_samples=max_samples)
    Path(cache_dir).mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=f".{key[:12]}-", dir=cache_dir))
    try:
        _write_cached(staging, run, {"key": key, "settings": settings, "noise_rel_mse": noise,
                                     "scene": str(scene_path), "dependencies": dependencies})
        if folder.exists():  # an unreadable leftover: replace it
            shutil.rmtree(folder)
        os.replace(staging, folder)
    finally:
        if staging.exists():
            shutil.rmtree(staging, ignore_errors=True)
    return Reference(run, False, noise, key, folder, settings)
