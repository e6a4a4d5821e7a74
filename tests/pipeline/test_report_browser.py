"""The report opens in headless Chromium without errors; the screenshot is not blank.

Chromium comes from Debian (tools/install_chromium.sh, which `make test` runs and which installs it
when it can). Without a browser these tests skip with a message saying so; set
CLASSIC_BAKE_REQUIRE_BROWSER=1 to make a missing browser a failure instead.
"""

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from classic_bake.pipeline import charts, images, report

REPO = Path(__file__).resolve().parents[2]
TOOL = REPO / "tools" / "screenshot_report.py"


def _tool():
    spec = importlib.util.spec_from_file_location("screenshot_report", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def chromium() -> str:
    found = _tool().find_chromium()
    if found is None:
        message = ("no Chromium found (on PATH or in $CHROMIUM): the report's browser check is "
                   "skipped; tools/install_chromium.sh installs it (as root)")
        if os.environ.get("CLASSIC_BAKE_REQUIRE_BROWSER"):
            pytest.fail(message + " (CLASSIC_BAKE_REQUIRE_BROWSER is set)")
        pytest.skip(message)
    return found


def _shoot(html: Path, png: Path, chromium: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, str(TOOL), str(html), "--out", str(png), "--size", "1000x900",
         "--chromium", chromium],
        capture_output=True, text=True, timeout=180,
    )


def _pixels(png: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(png) as image:
        return np.asarray(image.convert("RGB"), dtype=np.float64)


def test_report_screenshot_is_a_non_blank_png(tmp_path, chromium):
    run = tmp_path / "results" / "texture-cube"
    run.mkdir(parents=True)
    ramp = np.linspace(0.0, 1.0, 32 * 32 * 3, dtype=np.float32).reshape(32, 32, 3)
    images.write_preview_png(run / "bake.png", ramp)
    chart = charts.speed_accuracy_chart(
        [{"setting": "res 256", "seconds": 0.5, "rel_mse": 0.02}],
        [{"samples": 64, "seconds": 4.0, "rel_mse": 0.03}],
        run / "speed",
    )
    (run / "metrics.json").write_text(
        '{"technique": "Texture mapping", "scene": "cube", "seconds": {"total": 0.5},'
        ' "comparison": {"metrics": {"rel_mse": 0.02}, "charts": ["speed.png"]},'
        ' "outputs": ["bake.png"]}',
        encoding="utf-8",
    )
    assert chart.png.is_file()
    index = report.build_report(tmp_path / "results")
    shot = tmp_path / "shot.png"
    result = _shoot(index, shot, chromium)
    assert result.returncode == 0, result.stderr[-3000:]
    assert shot.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
    pixels = _pixels(shot)
    assert pixels.shape == (900, 1000, 3)
    assert pixels.var() > 0.0  # not blank
    # The page is mostly white paper with dark text and tables: both extremes are present.
    assert pixels.max() >= 250 and pixels.min() <= 60


def test_screenshot_tool_fails_on_blank_page_and_missing_file(tmp_path, chromium):
    blank = tmp_path / "blank.html"
    blank.write_text("<!DOCTYPE html><html><body></body></html>", encoding="utf-8")
    result = _shoot(blank, tmp_path / "blank.png", chromium)
    assert result.returncode != 0 and "blank" in result.stderr
    broken = tmp_path / "broken.html"
    broken.write_text('<!DOCTYPE html><html><body><h1>Report</h1><img src="gone.png">'
                      "</body></html>", encoding="utf-8")
    result = _shoot(broken, tmp_path / "broken.png", chromium)
    assert result.returncode != 0 and "missing local file: gone.png" in result.stderr
