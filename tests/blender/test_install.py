"""The extension as users get it: build the zip, install it into an empty user-resources folder,
enable, disable and re-enable it; every operator, panel and property registers, nothing leaks."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def probe(tmp_path_factory):
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        from build_extension import build
    finally:
        sys.path.pop(0)
    dist = tmp_path_factory.mktemp("dist")
    (zip_path,) = build(dist)
    user = tmp_path_factory.mktemp("user_resources")
    env = dict(os.environ, BLENDER_USER_RESOURCES=str(user))
    done = subprocess.run([sys.executable, str(Path(__file__).with_name("install_probe.py")),
                           str(zip_path)], capture_output=True, text=True, env=env, timeout=600)
    line = next((ln for ln in done.stdout.splitlines() if ln.startswith("PROBE")), None)
    assert done.returncode == 0 and line, done.stdout[-3000:] + done.stderr[-3000:]
    return json.loads(line[len("PROBE"):]), user


@pytest.mark.slow
def test_install_enables_every_class(probe):
    report, _ = probe
    assert report["before"] == []
    assert report["install"] == ["FINISHED"]
    enabled = report["enabled"]
    assert enabled["enabled"] and enabled["scene_property"]
    assert enabled["registered"] == report["expected"]
    assert {"CLASSICBAKE_PT_main", "CLASSICBAKE_PT_lightmap_uv",
            "CLASSICBAKE_OT_lightmap_uv", "CLASSICBAKE_PG_settings"} <= set(report["expected"])
    assert "lightmap_uv" in enabled["operators"]


def test_disable_unregisters_everything_and_reenable_restores_it(probe):
    report, _ = probe
    disabled = report["disabled"]
    assert not disabled["enabled"] and disabled["registered"] == []
    assert disabled["leaked_types"] == [] and not disabled["scene_property"]
    assert report["reenabled"]["registered"] == report["expected"]
    assert report["reenabled"] == report["enabled"]


def test_bundled_wheels_are_installed_into_the_user_folder(probe):
    _, user = probe
    site = list(user.glob("extensions/.local/lib/python3.*/site-packages"))
    assert site, "the extension's wheels were not unpacked"
    names = {p.name.split(".")[0].split("-")[0].lower() for p in site[0].iterdir()}
    assert {"xatlas", "openexr"} <= names
