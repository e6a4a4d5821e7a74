"""Charts, PNG previews and the HTML report, without Blender (pipeline/charts.py, images.py,
report.py). The data plotted is read back from the chart's artists and its JSON sidecar and
compared with what was passed in; the report is built from a temporary results folder."""

import json
import math
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import numpy as np
import pytest

from classic_bake.pipeline import charts, images, report

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"

KERNEL_LADDER = [
    {"setting": "res 128", "seconds": 0.21, "rel_mse": 0.052, "flip": 0.11},
    {"setting": "res 256", "seconds": 0.63, "rel_mse": 0.021, "flip": 0.07},
    {"setting": "res 512", "seconds": 2.4, "rel_mse": 0.0087, "flip": 0.04},
]
CYCLES_LADDER = [
    {"samples": 16, "seconds": 1.5, "rel_mse": 0.1, "flip": 0.2},
    {"samples": 64, "seconds": 5.5, "rel_mse": 0.031, "flip": 0.12},
    {"samples": 256, "seconds": 21.0, "rel_mse": 0.0071, "flip": 0.05},
]


def _series(entries, metric="rel_mse"):
    return [e["seconds"] for e in entries], [e[metric] for e in entries]


# --- speed against accuracy ------------------------------------------------------------------


def test_speed_accuracy_chart_writes_png_svg_and_plots_exactly_the_input(tmp_path):
    result = charts.speed_accuracy_chart(KERNEL_LADDER, CYCLES_LADDER, tmp_path / "c" / "speed")
    assert result.paths == (result.png, result.svg, result.data)
    assert result.png.read_bytes().startswith(PNG_SIGNATURE)
    svg = result.svg.read_text(encoding="utf-8")
    assert svg.lstrip().startswith("<?xml") and "<svg" in svg
    for text in ("Classic Bake kernel", "Cycles", "wall-clock time (s)",
                 "relative MSE (dimensionless)", "64 spp", "res 512"):
        assert text in svg, text
    # Read back from the artists: the plotted points and annotations are the input, in order.
    kernel, cycles = result.series["Classic Bake kernel"], result.series["Cycles"]
    assert (kernel["x"], kernel["y"]) == tuple(map(list, _series(KERNEL_LADDER)))
    assert (cycles["x"], cycles["y"]) == tuple(map(list, _series(CYCLES_LADDER)))
    assert kernel["labels"] == ["res 128", "res 256", "res 512"]
    assert cycles["labels"] == ["16 spp", "64 spp", "256 spp"]
    sidecar = json.loads(result.data.read_text(encoding="utf-8"))
    assert sidecar["series"] == result.series and sidecar["omitted"] == []


def test_speed_accuracy_chart_frontier_joins_only_the_unbeaten_points(tmp_path):
    """A ladder of several methods: every point is drawn, unjoined; the line and the labels go
    through the points no other beats on both seconds and error, in order of seconds."""
    ladder = [{"setting": "a", "seconds": 1.0, "rel_mse": 0.1},
              {"setting": "slow", "seconds": 5.0, "rel_mse": 0.2},
              {"setting": "b", "seconds": 2.0, "rel_mse": 0.01},
              {"setting": "c", "seconds": 0.5, "rel_mse": 0.5}]
    result = charts.speed_accuracy_chart(ladder, CYCLES_LADDER, tmp_path / "front",
                                         kernel_frontier=True)
    points = result.series["Classic Bake kernel"]
    assert points["x"] == [1.0, 5.0, 2.0, 0.5] and points["labels"] == ["c", "a", "b"]
    front = result.series["Classic Bake kernel frontier"]
    assert (front["x"], front["y"]) == ([0.5, 1.0, 2.0], [0.5, 0.1, 0.01])


def test_a_chart_of_no_plottable_point_is_still_drawn(tmp_path):
    """Every error 0 (a view both renderers draw alike, e.g. the world alone): nothing can sit
    on log axes, every point is listed as left out, and the chart is written all the same."""
    kernel = [{"setting": "default", "seconds": 2.0, "rel_mse": 0.0}]
    cycles = [{"samples": 1, "seconds": 0.4, "rel_mse": 0.0}]
    result = charts.speed_accuracy_chart(kernel, cycles, tmp_path / "zero")
    assert len(result.omitted) == 2 and result.png.stat().st_size > 0
    assert "not on log axes" in result.svg.read_text(encoding="utf-8")
    sweep = charts.sweep_chart([1.0, 2.0], [{"label": "relMSE", "values": [0.0, None], "log": True}],
                               tmp_path / "zero_sweep", x_label="x", title="all zero")
    assert sweep.png.stat().st_size > 0


def test_speed_accuracy_chart_other_metric_and_unplottable_points(tmp_path):
    cycles = CYCLES_LADDER + [{"samples": 4096, "seconds": 300.0, "flip": 0.0}]
    result = charts.speed_accuracy_chart(KERNEL_LADDER, cycles, tmp_path / "flip", metric="flip")
    assert result.series["Cycles"]["y"] == [0.2, 0.12, 0.05]
    assert result.omitted == [{"series": "Cycles", "label": "4096 spp", "x": 300.0, "y": 0.0}]
    assert "mean HDR-FLIP" in result.svg.read_text(encoding="utf-8")
    with pytest.raises(ValueError, match="seconds"):
        charts.speed_accuracy_chart([{"setting": "a", "rel_mse": 0.1}], [], tmp_path / "bad")
    with pytest.raises(ValueError, match="finite"):
        charts.speed_accuracy_chart(
            [{"setting": "a", "seconds": 1.0, "rel_mse": math.nan}], [], tmp_path / "bad"
        )


# --- stability sweep -------------------------------------------------------------------------


def test_sweep_chart_two_quantities_marks_and_gaps(tmp_path):
    eps = [1e-4, 3e-4, 1e-3, 3e-3, 1e-2]
    acne = [0.41, 0.2, 0.05, 0.0, 0.0]
    gap = [0.0, 0.0, 0.001, None, 0.02]
    result = charts.sweep_chart(
        eps,
        [
            {"label": "acne fraction", "values": acne, "axis_label": "acne (fraction of texels)"},
            {"label": "peter-panning gap", "values": gap, "axis_label": "gap (m)"},
        ],
        tmp_path / "sweep",
        x_label="depth bias epsilon (m)",
        title="Shadow bias sweep",
        marks={"auto eps": 0.002},
        x_log=True,
    )
    assert result.png.read_bytes().startswith(PNG_SIGNATURE)
    svg = result.svg.read_text(encoding="utf-8")
    for text in ("acne fraction", "peter-panning gap", "depth bias epsilon (m)", "gap (m)",
                 "acne (fraction of texels)", "auto eps", "Shadow bias sweep"):
        assert text in svg, text
    assert result.series["acne fraction"] == {"x": eps, "y": acne, "labels": []}
    assert result.series["peter-panning gap"]["y"] == gap  # the gap stays a gap (None)
    sidecar = json.loads(result.data.read_text(encoding="utf-8"))
    assert sidecar["series"] == result.series and sidecar["marks"] == {"auto eps": 0.002}


def test_sweep_chart_rejects_bad_data(tmp_path):
    one = [{"label": "a", "values": [1.0, 2.0]}]
    charts.sweep_chart([0.0, 1.0], one, tmp_path / "linear", x_label="x (m)", title="t")
    with pytest.raises(ValueError, match="log axis"):
        charts.sweep_chart([0.0, 1.0], one, tmp_path / "log", x_label="x", title="t", x_log=True)
    with pytest.raises(ValueError, match="one entry per x"):
        charts.sweep_chart([1.0], one, tmp_path / "n", x_label="x", title="t")
    with pytest.raises(ValueError, match="one or two"):
        charts.sweep_chart([1.0, 2.0], one * 3, tmp_path / "three", x_label="x", title="t")


# --- PNG previews ----------------------------------------------------------------------------


def test_preview_applies_srgb_exposure_and_clamp(tmp_path):
    from PIL import Image

    linear = np.array([[[0.0], [0.5], [1.0], [7.0]]], np.float32)  # (1, 4, 1), row 0 top
    rgb8 = images.preview_rgb8(linear)
    # sRGB(0.5) = 1.055 * 0.5^(1/2.4) - 0.055 = 0.73536 -> 188; above 1 clamps to 255.
    assert rgb8.shape == (1, 4, 3) and rgb8.dtype == np.uint8
    assert rgb8[0, :, 0].tolist() == [0, 188, 255, 255]
    assert images.preview_rgb8(linear * np.float32(0.5), exposure_stops=1.0).tolist() == (
        rgb8.tolist()
    )
    assert images.linear_to_srgb(np.float32(0.002)) == pytest.approx(12.92 * 0.002)
    image = np.zeros((3, 2, 3), np.float32)
    image[0] = 1.0  # top row white
    path = images.write_preview_png(tmp_path / "p" / "top.png", image)
    back = np.asarray(Image.open(path))
    assert back.shape == (3, 2, 3) and back[0].min() == 255 and back[1:].max() == 0
    err = images.error_rgb8(np.array([[0.0, 0.5], [1.0, 2.0]]), vmax=1.0)
    assert err.shape == (2, 2, 3) and err[1, 0].tolist() == err[1, 1].tolist()  # clamped at vmax
    assert err[0, 0].tolist() != err[1, 0].tolist()


# --- HTML report -----------------------------------------------------------------------------


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.urls = []

    def handle_starttag(self, tag, attrs):
        self.urls += [v for k, v in attrs if k in ("src", "href") and v]


def make_results(root: Path) -> dict:
    """Two fake runs (one complete, one minimal) and one broken metrics.json."""
    full = root / "shadow_map-cornell"
    full.mkdir(parents=True)
    images.write_preview_png(full / "bake.png", np.full((8, 8, 3), 0.3, np.float32))
    images.write_error_png(full / "error_flip.png", np.linspace(0, 1, 64).reshape(8, 8))
    (full / "bake.exr").write_bytes(b"not really an exr")
    chart = charts.speed_accuracy_chart(KERNEL_LADDER, CYCLES_LADDER, full / "charts" / "speed")
    metrics = {
        "technique": "Shadow <mapping> & bias",
        "scene": "cornell_box",
        "settings": {"resolution": 512, "bias": "auto", "pcf": True, "cascade": [1, 2]},
        "seconds": {"load": 0.125, "bake": 3.75, "total": 4.5},
        "sizes": {"texels": 262144},
        "versions": {"numpy": "2.5.5"},
        "comparison": {
            "metrics": {"rel_mse": 0.0123, "flip": 0.0456, "psnr_db": 31.25, "n_valid": 1000},
            "ladder": {"kernel": KERNEL_LADDER, "cycles": CYCLES_LADDER},
            "charts": [f"charts/{chart.png.name}", f"charts/{chart.svg.name}"],
        },
        "outputs": ["bake.png", "bake.exr", "missing_output.png", "../../etc/passwd"],
        "ignored": ["material 'Leaf': 'Emission Color' driven by a 'ShaderNodeVertexColor' node: "
                    "colour attributes are not modelled; its default used"],
        "fallbacks": [{"material": "Bark", "socket": "Roughness", "read_as": "Cycles bake 256x256",
                       "seconds": 0.8125, "cached": False, "object": "Tree <1>"}],
    }
    (full / "metrics.json").write_text(json.dumps(metrics), encoding="utf-8")
    minimal = root / "radiosity-box"
    minimal.mkdir()
    (minimal / "metrics.json").write_text(
        json.dumps({"technique": "Radiosity", "scene": "box", "seconds": {"total": 12.5}}),
        encoding="utf-8",
    )
    broken = root / "broken-run"
    broken.mkdir()
    (broken / "metrics.json").write_text("{not json", encoding="utf-8")
    return metrics


def test_report_lists_runs_numbers_and_existing_files_only(tmp_path):
    metrics = make_results(tmp_path)
    index = report.build_report(tmp_path)
    assert index == tmp_path / "index.html"
    page = index.read_text(encoding="utf-8")
    # Each technique, escaped; the raw markup never appears.
    assert "Shadow &lt;mapping&gt; &amp; bias" in page and "<mapping>" not in page
    assert "Radiosity" in page and "cornell_box" in page
    # The numbers of metrics.json, as the report formats them.
    comparison = metrics["comparison"]["metrics"]
    for value in [*comparison.values(), *metrics["seconds"].values(), 12.5, 262144]:
        assert report.format_number(value) in page, value
    for entry in KERNEL_LADDER + CYCLES_LADDER:
        assert report.format_number(entry["rel_mse"]) in page
    assert "res 256" in page
    # Self-contained: no external URL, no script.
    assert "http://" not in page and "https://" not in page and "<script" not in page
    # Every referenced local file exists relative to index.html.
    parser = _Links()
    parser.feed(page)
    files = [u for u in parser.urls if not u.startswith("#")]
    assert files, "the report references no file"
    for url in files:
        assert urlsplit(url).scheme == ""
        assert (tmp_path / unquote(url)).is_file(), url
    assert "shadow_map-cornell/bake.png" in files and "shadow_map-cornell/charts/speed.png" in files
    assert "shadow_map-cornell/error_flip.png" in files  # found in the folder, not listed
    # A listed but missing output is named, not linked; a path outside the folder is not linked.
    assert "missing_output.png (missing)" in page
    assert "outside the results folder" in page
    assert "broken-run/metrics.json: cannot be read" in page
    # What the snapshot did not model, as metrics.json lists it.
    assert "Not modelled" in page and "colour attributes are not modelled; its default used" in page
    # Sockets read through a Cycles bake, with its cost (names escaped).
    assert "Read through a Cycles bake" in page
    assert "Bark: 'Roughness' read from a Cycles bake 256x256 over 'Tree &lt;1&gt;' (0.812 s)" in page
    # The summary links to both run sections.
    assert 'href="#run-1"' in page and 'href="#run-2"' in page


def test_report_of_empty_folder_and_format_number():
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        page = report.build_report(folder).read_text(encoding="utf-8")
        assert "No metrics.json found" in page
    assert report.format_number(0.000123456) == "0.0001235"
    assert report.format_number(True) == "yes" and report.format_number(None) == "—"
    assert report.format_number({"b": 1, "a": [2]}) == '{"a": [2], "b": 1}'
    with pytest.raises(FileNotFoundError):
        report.build_report("/nonexistent/results/folder")


def test_report_leads_with_a_gallery_of_ours_cycles_and_error(tmp_path):
    """A compared run's three pictures, its relMSE and seconds under them, in its scene's row and
    its technique's column (the technique named by the compare run's settings)."""
    run = tmp_path / "cornell-trace"
    run.mkdir()
    for name in ("render.png", "cycles_reference.png", "error_rel_se.png"):
        images.write_preview_png(run / name, np.full((4, 4, 3), 0.5, np.float32))
    (run / "metrics.json").write_text(json.dumps({
        "technique": "compare", "scene": "cornell.blend", "settings": {"technique": "trace"},
        "comparison": {"metrics": {"rel_mse": 0.00123, "seconds": 1.5}, "charts": []}}),
        encoding="utf-8")
    plain = tmp_path / "cornell-bump"
    plain.mkdir()
    images.write_preview_png(plain / "render.png", np.full((4, 4, 3), 0.2, np.float32))
    (plain / "metrics.json").write_text(json.dumps({
        "technique": "bump", "scene": "cornell.blend", "seconds": {"total": 0.25}}),
        encoding="utf-8")
    page = report.build_report(tmp_path).read_text(encoding="utf-8")
    gallery = page[page.index("<h2>Gallery</h2>"):page.index("<h2>Summary</h2>")]
    assert "<th>trace</th>" in gallery and "<th>bump</th>" in gallery
    for name in ("cornell-trace/render.png", "cornell-trace/cycles_reference.png",
                 "cornell-trace/error_rel_se.png", "cornell-bump/render.png"):
        assert f'src="{name}"' in gallery
    assert "relMSE 0.00123" in gallery and "1.5 s" in gallery and "0.25 s" in gallery
    assert page.index("Gallery") < page.index("<details>")  # the details come folded, after
