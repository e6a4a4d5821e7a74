"""Fixtures for tests that run real Blender (the pip `bpy` module).

Every test starts and ends in Blender's factory settings with an empty scene, so no test sees
another's data. `addon` registers Classic Bake for the tests that use its operators or properties.
"""

from __future__ import annotations

import os
from pathlib import Path

import bpy
import pytest

ROOT = Path(__file__).resolve().parents[2]
SAMPLES = ROOT / "sample_blends"


@pytest.fixture(autouse=True)
def factory_reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    yield
    bpy.ops.wm.read_factory_settings(use_empty=True)


@pytest.fixture
def addon():
    """Classic Bake registered for the duration of one test."""
    import classic_bake

    classic_bake.register()
    try:
        yield classic_bake
    finally:
        classic_bake.unregister()


@pytest.fixture
def open_sample():
    """open_sample("cornell_box") opens sample_blends/cornell_box.blend with scripts disabled."""

    def _open(name: str):
        path = SAMPLES / f"{name}.blend"
        if not path.exists():
            pytest.fail(f"sample scene missing: {path} (run `make samples`)")
        bpy.ops.wm.open_mainfile(filepath=str(path), load_ui=False, use_scripts=False)
        return path

    return _open


def pytest_configure(config):
    # Cycles on this 2-core machine: keep each test's renders tiny.
    os.environ.setdefault("CYCLES_THREADS", "2")
