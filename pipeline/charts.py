"""Charts for the comparison against Cycles: PNG + SVG + a JSON sidecar of the plotted data.

Both charts take plain data (lists and dicts, as read from metrics.json) and plot exactly that:
the sidecar `<stem>.data.json` is read back from the plotted artists, so a test (or a reader) can
check that what is drawn is what was passed in. Matplotlib runs on the Agg canvas directly (no
pyplot, no global backend switch); SVG text is kept as text so labels can be searched.

speed_accuracy_chart: error against wall-clock seconds on log-log axes, the kernel's quality
ladder and Cycles' sample ladder as two labelled curves, each point annotated with its setting.
sweep_chart: one or two quantities (two y axes) against a swept parameter, with optional marked
values such as "auto eps".
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

# Axis labels, with units, of the metrics that kernels/metrics.py reports.
METRIC_LABELS = {
    "rel_mse": "relative MSE (dimensionless)",
    "mse": "MSE (image unit²)",
    "rmse": "RMSE (image unit)",
    "mae": "mean absolute error (image unit)",
    "flip": "mean HDR-FLIP (dimensionless, 0–1)",
    "psnr_db": "PSNR (dB)",
    "binary_disagreement": "disagreeing texels (fraction)",
}
SECONDS_LABEL = "wall-clock time (s)"
# Metrics that are already logarithmic (or bounded) and read best on a linear y axis.
LINEAR_Y_METRICS = frozenset({"psnr_db"})
# Fixed SVG id salt and no date: the same data gives the same SVG bytes.
_RC = {"svg.fonttype": "none", "svg.hashsalt": "classic-bake"}
_FIGSIZE_IN = (7.0, 4.8)
_DPI = 120


@dataclass(frozen=True)
class ChartFiles:
    """What a chart function wrote, and the data it plotted (read back from the artists).

    series: {curve label: {"x": [...], "y": [...], "labels": [...]}}; omitted: points that a log
    axis cannot show (value <= 0), as {"series", "label", "x", "y"}.
    """

    png: Path
    svg: Path
    data: Path
    series: dict[str, dict[str, list]] = field(default_factory=dict)
    omitted: list[dict[str, Any]] = field(default_factory=list)

    @property
    def paths(self) -> tuple[Path, Path, Path]:
        return (self.png, self.svg, self.data)


def _number(entry: Mapping[str, Any], key: str, where: str) -> float:
    if key not in entry:
        raise ValueError(f"{where}: missing {key!r} in {dict(entry)!r}")
    value = entry[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{where}: {key!r} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{where}: {key!r} must be finite, got {value!r}")
    return value


def _new_figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure(figsize=_FIGSIZE_IN, dpi=_DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def _save(figure, out_stem: Path, payload: dict[str, Any]) -> tuple[Path, Path, Path]:
    import matplotlib

    out_stem = Path(out_stem)
    out_stem.parent.mkdir(parents=True, exist_ok=True)
    png = out_stem.with_name(out_stem.name + ".png")
    svg = out_stem.with_name(out_stem.name + ".svg")
    data = out_stem.with_name(out_stem.name + ".data.json")  # never clashes with metrics.json
    with matplotlib.rc_context(_RC):
        figure.savefig(png, format="png")
        figure.savefig(svg, format="svg", metadata={"Date": None})
    data.write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
    return png, svg, data


def _read_back(line, annotations) -> dict[str, list]:
    """The data a Line2D and its annotations actually carry."""
    return {
        "x": [float(v) for v in line.get_xdata()],
        "y": [None if math.isnan(float(v)) else float(v) for v in line.get_ydata()],
        "labels": [a.get_text() for a in annotations],
    }


# --- speed against accuracy ------------------------------------------------------------------


def _ladder_points(
    entries: Sequence[Mapping[str, Any]], metric: str, name: str, default_label
) -> list[tuple[float, float, str]]:
    points = []
    for i, entry in enumerate(entries):
        where = f"{name} ladder entry {i}"
        label = str(entry["label"]) if "label" in entry else default_label(entry, where)
        points.append((_number(entry, "seconds", where), _number(entry, metric, where), label))
    return points


def _kernel_label(entry: Mapping[str, Any], where: str) -> str:
    if "setting" not in entry:
        raise ValueError(f"{where}: missing 'setting' (or 'label') in {dict(entry)!r}")
    return str(entry["setting"])


def _cycles_label(entry: Mapping[str, Any], where: str) -> str:
    return f"{int(_number(entry, 'samples', where))} spp"


def frontier(points: Sequence, key=lambda p: p) -> list:
    """The points no other point beats on both coordinates, key(point) -> (seconds, error), in
    their given order: what a ladder reaches at each error level at its fastest."""
    coords = [key(p)[:2] for p in points]
    return [p for p, (x, y) in zip(points, coords, strict=True)
            if not any(ox < x and oy < y for ox, oy in coords)]


def speed_accuracy_chart(
    kernel: Sequence[Mapping[str, Any]],
    cycles: Sequence[Mapping[str, Any]],
    out_stem: str | Path,
    *,
    metric: str = "rel_mse",
    title: str = "Speed against accuracy (reference: Cycles)",
    kernel_label: str = "Classic Bake kernel",
    cycles_label: str = "Cycles",
    kernel_frontier: bool = False,
) -> ChartFiles:
    """Error (`metric`) against seconds, log-log, one curve per ladder: stem.png/.svg/.data.json.

    kernel_frontier: the kernel's points are not joined in ladder order (a ladder of several
    methods zigzags); a line joins its frontier instead, the points no other point beats on both
    seconds and error, and only those are labelled (series "<kernel_label> frontier").

    kernel: [{"setting": str, "seconds": s, metric: x, ...}]; cycles: [{"samples": n, "seconds": s,
    metric: x, ...}], as in metrics.json "comparison.ladder"; an entry's "label" overrides the
    point's annotation. Points are drawn in the order given. A point with seconds or error <= 0
    cannot sit on a log axis: it is left out, listed in `omitted` and noted on the chart.
    """
    ladders = [
        (kernel_label, _ladder_points(kernel, metric, "kernel", _kernel_label), "o", "-"),
        (cycles_label, _ladder_points(cycles, metric, "cycles", _cycles_label), "s", "--"),
    ]
    log_y = metric not in LINEAR_Y_METRICS
    figure = _new_figure()
    axes = figure.add_subplot()
    series: dict[str, dict[str, list]] = {}
    omitted: list[dict[str, Any]] = []
    for k, (name, points, marker, style) in enumerate(ladders):
        shown = []
        for x, y, label in points:
            if x <= 0.0 or (log_y and y <= 0.0):
                omitted.append({"series": name, "label": label, "x": x, "y": y})
            else:
                shown.append((x, y, label))
        joined = not (kernel_frontier and k == 0)
        (line,) = axes.plot(
            [p[0] for p in shown], [p[1] for p in shown], marker=marker,
            linestyle=style if joined else "none", label=name
        )
        best = shown if joined else sorted(frontier(shown))
        annotations = [
            axes.annotate(label, (x, y), textcoords="offset points", xytext=(5, 4), fontsize=8,
                          color=line.get_color())
            for x, y, label in best
        ]
        series[name] = _read_back(line, annotations)
        if not joined:
            (front,) = axes.plot([p[0] for p in best], [p[1] for p in best], linestyle=style,
                                 color=line.get_color(), label=f"{name} frontier")
            series[f"{name} frontier"] = _read_back(front, [])
    axes.margins(0.12)  # room for the annotations of the end points
    if len(omitted) < sum(len(points) for _, points, _, _ in ladders):
        # Log axes need a point to scale to: a scene both render alike (every error 0) has none.
        axes.set_xscale("log")
        if log_y:
            axes.set_yscale("log")
    axes.set_xlabel(SECONDS_LABEL)
    axes.set_ylabel(METRIC_LABELS.get(metric, metric))
    axes.set_title(title)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend()
    if omitted:
        note = ", ".join(f"{o['series']} {o['label']}" for o in omitted)
        axes.text(0.01, 0.01, f"not on log axes (value <= 0): {note}", transform=axes.transAxes,
                  fontsize=7, va="bottom")
    payload = {
        "kind": "speed_accuracy",
        "metric": metric,
        "x_label": SECONDS_LABEL,
        "y_label": METRIC_LABELS.get(metric, metric),
        "series": series,
        "omitted": omitted,
    }
    png, svg, data = _save(figure, Path(out_stem), payload)
    return ChartFiles(png, svg, data, series, omitted)


# --- stability sweep -------------------------------------------------------------------------


def _sweep_values(quantity: Mapping[str, Any], n: int, index: int) -> list[float]:
    where = f"quantity {index} ({quantity.get('label', '?')!r})"
    values = quantity.get("values")
    if values is None or len(values) != n:
        raise ValueError(f"{where}: needs 'values' with one entry per x ({n})")
    out = []
    for value in values:
        if value is None:  # not measured at this x: a gap in the curve
            out.append(math.nan)
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"{where}: values must be numbers or None, got {value!r}")
        if not math.isfinite(value):
            raise ValueError(f"{where}: values must be finite (use None for a gap), got {value!r}")
        out.append(float(value))
    return out


def sweep_chart(
    x: Sequence[float],
    quantities: Sequence[Mapping[str, Any]],
    out_stem: str | Path,
    *,
    x_label: str,
    title: str,
    marks: Mapping[str, float] | None = None,
    x_log: bool = False,
) -> ChartFiles:
    """One or two quantities against a swept parameter; writes stem.png/.svg/.data.json.

    x: the swept values (e.g. depth-bias epsilon, m). quantities: one or two of
    {"label": str, "values": [y or None per x], "axis_label": str with unit, "log": bool}; the
    first uses the left axis, the second the right one. marks: {"auto eps": 0.004} draws a
    labelled vertical line at each value. x_log: logarithmic x (all x and marks must be > 0).
    """
    xs = []
    for i, value in enumerate(x):
        value = _number({"x": value}, "x", f"x[{i}]")
        if x_log and value <= 0.0:
            raise ValueError(f"x[{i}] = {value} cannot sit on a log axis")
        xs.append(value)
    if not xs:
        raise ValueError("sweep_chart needs at least one x value")
    if not 1 <= len(quantities) <= 2:
        raise ValueError(f"sweep_chart plots one or two quantities, got {len(quantities)}")
    marks = dict(marks or {})
    for name, value in marks.items():
        value = _number({"mark": value}, "mark", f"mark {name!r}")
        if x_log and value <= 0.0:
            raise ValueError(f"mark {name!r} = {value} cannot sit on a log axis")

    figure = _new_figure()
    left = figure.add_subplot()
    axes_list = [left] if len(quantities) == 1 else [left, left.twinx()]
    colours = ["tab:blue", "tab:orange"]
    markers = ["o", "s"]
    series: dict[str, dict[str, list]] = {}
    lines = []
    for index, (quantity, axes) in enumerate(zip(quantities, axes_list, strict=True)):
        label = str(quantity.get("label", f"quantity {index + 1}"))
        ys = _sweep_values(quantity, len(xs), index)
        (line,) = axes.plot(xs, ys, marker=markers[index], color=colours[index], label=label)
        axes.set_ylabel(str(quantity.get("axis_label", label)), color=colours[index])
        if quantity.get("log", False) and any(y > 0.0 for y in ys):  # else no point to scale to
            axes.set_yscale("log")
        series[label] = _read_back(line, [])
        lines.append(line)
    if x_log:
        left.set_xscale("log")
    for name, value in marks.items():
        left.axvline(float(value), color="0.3", linestyle=":", linewidth=1.2)
        left.annotate(str(name), (float(value), 1.0), xycoords=("data", "axes fraction"),
                      xytext=(3, -12), textcoords="offset points", fontsize=8, color="0.2")
    left.set_xlabel(x_label)
    left.set_title(title)
    left.grid(True, which="both", alpha=0.3)
    # Below the axes: inside, it would hide points of one axis or be drawn over by the other.
    figure.legend(lines, [line.get_label() for line in lines], loc="outside lower center",
                  ncols=len(lines))
    payload = {
        "kind": "sweep",
        "x_label": x_label,
        "x_log": x_log,
        "series": series,
        "marks": {str(k): float(v) for k, v in marks.items()},
    }
    png, svg, data = _save(figure, Path(out_stem), payload)
    return ChartFiles(png, svg, data, series, [])
