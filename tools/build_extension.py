"""Build the extension zip: fetch the wheels the manifest names, then run Blender's own builder.

    python tools/build_extension.py [--out dist] [--split-platforms]

Wheels are not committed: each file listed under `wheels` in blender_manifest.toml is downloaded
with `pip download` (exact file, no dependencies) into ./wheels when missing. The zip is built by
`blender_ext.py build` from the bpy module's bundled extension tools, which validates the manifest
and applies `[build] paths_exclude_pattern`. Prints the zip's path.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def wheel_tags(filename: str) -> tuple[str, str, str, list[str]]:
    """(distribution, version, python tag, platforms) from a wheel file name (PEP 427)."""
    stem = filename.removesuffix(".whl")
    dist, version, python_tag, _abi, platform = stem.split("-")
    return dist, version, python_tag, platform.split(".")


def fetch_wheel(path: Path) -> None:
    dist, version, python_tag, platforms = wheel_tags(path.name)
    py = python_tag.removeprefix("cp")
    cmd = [sys.executable, "-m", "pip", "download", "--quiet", "--no-deps", "--only-binary=:all:",
           "--implementation", "cp", "--python-version", f"{py[0]}.{py[1:]}", "--dest",
           str(path.parent), f"{dist}=={version}"]
    for platform in platforms:
        cmd += ["--platform", platform]
    subprocess.run(cmd, check=True)
    if not path.exists():
        raise SystemExit(f"build_extension: pip did not produce {path.name}")


def blender_ext_script() -> Path:
    import bpy  # the pip module ships Blender's scripts, including the extension builder

    script = Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core/bl_pkg/cli/blender_ext.py"
    if not script.exists():
        raise SystemExit(f"build_extension: {script} not found in the bpy module")
    return script


def build(out_dir: Path, split_platforms: bool = False) -> list[Path]:
    manifest = tomllib.loads((ROOT / "blender_manifest.toml").read_text())
    for rel in manifest.get("wheels", []):
        path = (ROOT / rel).resolve()
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists():
            fetch_wheel(path)
    out_dir = out_dir.resolve()
    out_dir.mkdir(parents=True, exist_ok=True)
    cmd = [sys.executable, str(blender_ext_script()), "build", "--source-dir", str(ROOT),
           "--output-dir", str(out_dir)]
    if split_platforms:
        cmd.append("--split-platforms")
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:  # the builder explains itself on stdout (e.g. a manifest error)
        raise SystemExit(f"build_extension: {(done.stdout + done.stderr).strip()}")
    return sorted(out_dir.glob(f"{manifest['id']}-{manifest['version']}*.zip"))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "dist")
    parser.add_argument("--split-platforms", action="store_true")
    args = parser.parse_args()
    for path in build(args.out, args.split_platforms):
        print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main())
