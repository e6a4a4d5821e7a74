"""One self-contained HTML page for all runs under a results folder.

`build_report(results_dir)` reads every `results_dir/*/metrics.json` (one sub-folder per technique
run) and writes `results_dir/index.html`: a summary table, then per run its settings, seconds per
phase, errors against Cycles, the ladders and every image found. Images are referenced by paths
relative to index.html; no script, no external URL, plain CSS, so the page opens from disk.
Every text is escaped; a missing optional piece is left out (a missing file is named, not linked),
and a metrics.json that cannot be read is listed as a problem instead of stopping the report.

metrics.json (written by the pipeline):
    {"technique": str, "scene": str, "settings": {...}, "seconds": {"phase": s, ..., "total": s},
     "sizes": {...}, "versions": {...},
     "comparison": {"metrics": {...}, "ladder": {"kernel": [{"setting", "seconds", ...}],
                    "cycles": [{"samples", "seconds", ...}]}, "charts": [relative paths]},
     "outputs": [relative paths]}
Relative paths are relative to the run's folder.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from html import escape
from pathlib import Path
from typing import Any
from urllib.parse import quote

REPORT_NAME = "index.html"
METRICS_NAME = "metrics.json"
IMAGE_SUFFIXES = (".png", ".svg", ".jpg", ".jpeg", ".webp", ".gif")
# Metrics shown in the summary table, in order, with their column titles.
SUMMARY_METRICS = (("rel_mse", "relMSE"), ("flip", "FLIP"), ("psnr_db", "PSNR (dB)"))
# Titles of the metric keys that kernels/metrics.py writes; others are shown by their key.
METRIC_TITLES = {
    "rel_mse": "relative MSE",
    "rel_mse_eps": "relative MSE epsilon",
    "mse": "MSE (image unit²)",
    "rmse": "RMSE (image unit)",
    "mae": "mean absolute error (image unit)",
    "psnr_db": "PSNR (dB)",
    "psnr_peak": "PSNR peak",
    "flip": "mean HDR-FLIP (0–1)",
    "binary_disagreement": "disagreeing texels (fraction)",
    "n_valid": "valid pixels compared",
    "channels": "channels",
}

_CSS = """
body { font: 15px/1.45 system-ui, sans-serif; margin: 2em auto; max-width: 1200px;
       padding: 0 1em; color: #1d1d1f; background: #fff; }
h1 { font-size: 1.6em; } h2 { margin-top: 2.2em; border-bottom: 2px solid #ddd; }
h3 { font-size: 1.05em; margin: 1.2em 0 0.4em; color: #444; }
table { border-collapse: collapse; margin: 0.4em 0 1em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
th { background: #f0f2f5; } td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.total td { font-weight: bold; }
.figures { display: flex; flex-wrap: wrap; gap: 1em; }
figure { margin: 0; flex: 0 1 560px; max-width: 100%; }
figure img { width: 100%; border: 1px solid #ddd; image-rendering: pixelated; }
figcaption { font-size: 0.85em; color: #555; word-break: break-all; }
.missing { color: #a33; } .note { color: #555; font-size: 0.9em; }
.problems { background: #fff4f4; border: 1px solid #e3b4b4; padding: 0.5em 1em; }
code { font-size: 0.92em; }
.gallery-wrap { overflow-x: auto; } table.gallery td { padding: 0.3em; } .cell { display: flex; gap: 2px; }
.cell img { width: 96px; height: auto; border: 1px solid #ddd; image-rendering: pixelated; }
.cell-note { font-size: 0.8em; color: #444; }
details { margin: 0.6em 0; } summary { cursor: pointer; font-weight: 600; }
"""
# The pictures a compared run leaves in its folder (pipeline/commands/compare.py), in gallery order.
GALLERY_IMAGES = (("render.png", "ours"), ("cycles_reference.png", "Cycles"),
                  ("error_rel_se.png", "error"))


def format_number(value: Any) -> str:
    """How the report writes a value: 4 significant digits for floats, JSON for containers."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "NaN"
        if math.isinf(value):
            return "∞" if value > 0 else "−∞"
        return f"{value:.4g}"
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(value, sort_keys=True, ensure_ascii=False)
    return str(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _cell(value: Any) -> str:
    css = ' class="num"' if _is_number(value) else ""
    return f"<td{css}>{escape(format_number(value))}</td>"


def _key_value_table(mapping: Mapping[str, Any], titles: Mapping[str, str] | None = None) -> str:
    rows = []
    for key, value in mapping.items():
        title = (titles or {}).get(key, key)
        rows.append(f"<tr><th>{escape(str(title))}</th>{_cell(value)}</tr>")
    return "<table>" + "".join(rows) + "</table>"


def _records_table(records: Sequence[Mapping[str, Any]], first: Sequence[str]) -> str:
    """A table of dicts: columns `first` (when present) then any other keys, in order seen."""
    columns: list[str] = [c for c in first if any(c in r for r in records)]
    for record in records:
        for key in record:
            if key not in columns:
                columns.append(key)
    head = "".join(f"<th>{escape(METRIC_TITLES.get(c, c))}</th>" for c in columns)
    body = "".join(
        "<tr>" + "".join(_cell(r.get(c)) for c in columns) + "</tr>" for r in records
    )
    return f"<table><tr>{head}</tr>{body}</table>"


@dataclass
class _Run:
    folder: Path
    data: dict[str, Any]
    anchor: str
    problems: list[str] = field(default_factory=list)

    def get_mapping(self, *keys: str) -> dict[str, Any]:
        node: Any = self.data
        for key in keys:
            node = node.get(key) if isinstance(node, Mapping) else None
        return dict(node) if isinstance(node, Mapping) else {}

    def get_list(self, *keys: str) -> list[Any]:
        node: Any = self.data
        for key in keys:
            node = node.get(key) if isinstance(node, Mapping) else None
        return list(node) if isinstance(node, list) else []


def _load_runs(results_dir: Path) -> tuple[list[_Run], list[str]]:
    runs: list[_Run] = []
    problems: list[str] = []
    for path in sorted(results_dir.glob(f"*/{METRICS_NAME}")):
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
            problems.append(f"{path.parent.name}/{METRICS_NAME}: cannot be read ({error})")
            continue
        if not isinstance(data, dict):
            problems.append(f"{path.parent.name}/{METRICS_NAME}: not a JSON object")
            continue
        runs.append(_Run(path.parent, data, f"run-{len(runs) + 1}"))
    return runs, problems


def _resolve(results_dir: Path, run: _Run, relative: Any) -> tuple[Path | None, str]:
    """(existing file inside results_dir or None, shown name) for a path listed in metrics.json."""
    shown = str(relative)
    if not isinstance(relative, str) or not relative:
        return None, shown
    target = (run.folder / relative).resolve()
    if not target.is_relative_to(results_dir.resolve()):
        return None, shown + " (outside the results folder: not linked)"
    if not target.is_file():
        return None, shown + " (missing)"
    return target, shown


def _figures(results_dir: Path, run: _Run, paths: Iterable[Any]) -> str:
    items = []
    for relative in paths:
        target, shown = _resolve(results_dir, run, relative)
        if target is None:
            items.append(f'<p class="missing">{escape(shown)}</p>')
            continue
        href = escape(quote(target.relative_to(results_dir.resolve()).as_posix()))
        if target.suffix.lower() in IMAGE_SUFFIXES:
            items.append(
                f'<figure><a href="{href}"><img src="{href}" alt="{escape(shown)}"></a>'
                f"<figcaption>{escape(shown)}</figcaption></figure>"
            )
        else:
            items.append(
                f'<p><a href="{href}">{escape(shown)}</a> '
                f'<span class="note">({target.stat().st_size:,} bytes)</span></p>'
            )
    return '<div class="figures">' + "".join(items) + "</div>" if items else ""


def _split_charts(listed: list[Any]) -> tuple[list[Any], list[Any]]:
    """(charts to show, SVGs to link): a chart listed as PNG and SVG is shown once, as PNG."""
    as_text = {str(p) for p in listed}
    twins = [
        p for p in listed
        if str(p).lower().endswith(".svg") and str(p)[:-4] + ".png" in as_text
    ]
    return [p for p in listed if p not in twins], twins


def _links(results_dir: Path, run: _Run, paths: Iterable[Any]) -> str:
    items = []
    for relative in paths:
        target, shown = _resolve(results_dir, run, relative)
        if target is not None:
            href = escape(quote(target.relative_to(results_dir.resolve()).as_posix()))
            items.append(f'<a href="{href}">{escape(shown)}</a>')
    return f'<p class="note">Vector versions: {", ".join(items)}</p>' if items else ""


def _run_section(results_dir: Path, run: _Run) -> str:
    technique = str(run.data.get("technique", run.folder.name))
    scene = str(run.data.get("scene", "?"))
    parts = [
        f'<section id="{run.anchor}"><h2>{escape(technique)} — {escape(scene)}</h2>',
        f'<p class="note">folder <code>{escape(run.folder.name)}</code></p>',
    ]
    settings = run.get_mapping("settings")
    if settings:
        parts += ["<h3>Settings</h3>", _key_value_table(settings)]
    seconds = run.get_mapping("seconds")
    if seconds:
        rows = "".join(
            ('<tr class="total">' if k == "total" else "<tr>")
            + f"<th>{escape(str(k))}</th>{_cell(v)}</tr>"
            for k, v in seconds.items()
        )
        parts += ["<h3>Seconds per phase</h3>", f"<table>{rows}</table>"]
    metrics = run.get_mapping("comparison", "metrics")
    if metrics:
        parts += ["<h3>Errors against Cycles</h3>", _key_value_table(metrics, METRIC_TITLES)]
    kernel = [r for r in run.get_list("comparison", "ladder", "kernel") if isinstance(r, Mapping)]
    if kernel:
        parts += ["<h3>Kernel quality ladder</h3>",
                  _records_table(kernel, ("setting", "seconds", "rel_mse", "flip"))]
    cycles = [r for r in run.get_list("comparison", "ladder", "cycles") if isinstance(r, Mapping)]
    if cycles:
        parts += ["<h3>Cycles sample ladder</h3>",
                  _records_table(cycles, ("samples", "seconds", "rel_mse", "flip"))]
    charts = run.get_list("comparison", "charts")
    if charts:
        shown, svgs = _split_charts(charts)
        parts += ["<h3>Charts</h3>", _figures(results_dir, run, shown),
                  _links(results_dir, run, svgs)]
    outputs = run.get_list("outputs")
    if outputs:
        parts += ["<h3>Outputs</h3>", _figures(results_dir, run, outputs)]
    listed = {(run.folder / str(p)).resolve() for p in charts + outputs}
    others = [
        p.relative_to(run.folder).as_posix()
        for p in sorted(run.folder.rglob("*"))
        if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES and p.resolve() not in listed
        and not (p.suffix.lower() == ".svg" and p.with_suffix(".png").resolve() in listed)
    ]
    if others:
        parts += ["<h3>Other images in the folder</h3>", _figures(results_dir, run, others)]
    ignored = [str(why) for why in run.get_list("ignored")]
    if ignored:  # what the snapshot did not model, and what it used instead
        items = "".join(f"<li>{escape(why)}</li>" for why in ignored)
        parts += ["<h3>Not modelled</h3>", f"<ul class=\"ignored\">{items}</ul>"]
    baked = [fb for fb in run.get_list("fallbacks") if isinstance(fb, Mapping)]
    if baked:  # sockets read through a Cycles bake of their node graph, with its cost
        items = "".join(
            f"<li>{escape(str(fb.get('material')))}: '{escape(str(fb.get('socket')))}' read from "
            f"a {escape(str(fb.get('read_as')))} over '{escape(str(fb.get('object')))}' "
            f"({float(fb.get('seconds', 0.0)):.3g} s{', cached' if fb.get('cached') else ''})"
            f"</li>" for fb in baked)
        parts += ["<h3>Read through a Cycles bake</h3>", f"<ul class=\"fallbacks\">{items}</ul>"]
    for title, key in (("Sizes", "sizes"), ("Versions", "versions")):
        mapping = run.get_mapping(key)
        if mapping:
            parts += [f"<h3>{title}</h3>", _key_value_table(mapping)]
    parts.append("</section>")
    return "\n".join(parts)


def _technique_of(run: _Run) -> str:
    """A compared run's technique (its settings name it), else the run's own."""
    if run.get_mapping("comparison"):
        return str(run.get_mapping("settings").get("technique", run.data.get("technique", "?")))
    return str(run.data.get("technique", run.folder.name))


def _gallery(results_dir: Path, runs: list[_Run]) -> str:
    """A row per scene, a column per technique: ours | Cycles | error thumbnails (what exists),
    with relMSE and seconds under them; each cell links to the run's details."""
    shown = [r for r in runs if (r.folder / "render.png").is_file()]
    if not shown:
        return ""
    scenes = sorted({str(r.data.get("scene", "?")) for r in shown})
    techniques = list(dict.fromkeys(_technique_of(r) for r in shown))
    cells = {(str(r.data.get("scene", "?")), _technique_of(r)): r for r in shown}
    head = "<tr><th>scene</th>" + "".join(f"<th>{escape(t)}</th>" for t in techniques) + "</tr>"
    rows = []
    for scene in scenes:
        row = [f"<th>{escape(scene)}</th>"]
        for technique in techniques:
            run = cells.get((scene, technique))
            if run is None:
                row.append("<td></td>")
                continue
            thumbs = "".join(
                f'<img src="{_href(results_dir, run.folder / name)}" alt="{escape(label)}" '
                f'title="{escape(label)}">'
                for name, label in GALLERY_IMAGES if (run.folder / name).is_file())
            metrics = run.get_mapping("comparison", "metrics")
            note = []
            if metrics.get("rel_mse") is not None:
                note.append(f"relMSE {format_number(metrics['rel_mse'])}")
            seconds = metrics.get("seconds", run.get_mapping("seconds").get("total"))
            if seconds is not None:
                note.append(f"{format_number(seconds)} s")
            row.append(f'<td><a href="#{run.anchor}"><div class="cell">{thumbs}</div></a>'
                       f'<div class="cell-note">{escape(", ".join(note))}</div></td>')
        rows.append("<tr>" + "".join(row) + "</tr>")
    return (f'<h2>Gallery</h2><p class="note">Each cell: ours | Cycles\' converged reference | '
            f'the relative squared error (where the run was compared).</p>'
            f'<div class="gallery-wrap"><table class="gallery">{head}{"".join(rows)}</table></div>')


def _charts(results_dir: Path, runs: list[_Run]) -> str:
    """Every compared run's speed-accuracy chart, by technique."""
    figures = []
    for run in sorted(runs, key=_technique_of):
        for chart in run.get_list("comparison", "charts"):
            path = run.folder / str(chart)
            if path.is_file() and path.suffix == ".png":
                caption = f"{_technique_of(run)} — {run.data.get('scene', '?')}"
                figures.append(f'<figure><img src="{_href(results_dir, path)}" alt="'
                               f'{escape(caption)}"><figcaption>{escape(caption)}'
                               f"</figcaption></figure>")
    if not figures:
        return ""
    return '<h2>Speed against accuracy</h2><div class="figures">' + "".join(figures) + "</div>"


def _href(results_dir: Path, path: Path) -> str:
    return quote(path.relative_to(results_dir).as_posix())


def _summary(runs: list[_Run]) -> str:
    head = "<tr><th>run</th><th>technique</th><th>scene</th><th>total (s)</th>" + "".join(
        f"<th>{escape(title)}</th>" for _, title in SUMMARY_METRICS
    ) + "</tr>"
    rows = []
    for run in runs:
        metrics = run.get_mapping("comparison", "metrics")
        technique = _technique_of(run)
        rows.append(
            f'<tr><td><a href="#{run.anchor}">{escape(run.folder.name)}</a></td>'
            f"<td>{escape(technique)}</td><td>{escape(str(run.data.get('scene', '?')))}</td>"
            + _cell(run.get_mapping("seconds").get("total"))
            + "".join(_cell(metrics.get(key)) for key, _ in SUMMARY_METRICS)
            + "</tr>"
        )
    return f"<table>{head}{''.join(rows)}</table>"


_LEGEND = (
    "relMSE: mean over valid texels and channels of (t − r)² / (r² + ε), t test, r Cycles "
    "reference. FLIP: mean HDR-FLIP (0 = indistinguishable, 1 = most different). PSNR: "
    "10·log10(peak² / MSE), peak as listed per run. Times are wall-clock seconds."
)


def build_report(results_dir: str | Path, title: str = "Classic Bake against Cycles") -> Path:
    """Write `results_dir/index.html` for every `results_dir/*/metrics.json`; return its path."""
    results_dir = Path(results_dir)
    if not results_dir.is_dir():
        raise FileNotFoundError(f"results folder {results_dir} does not exist")
    runs, problems = _load_runs(results_dir)
    body = [f"<h1>{escape(title)}</h1>"]
    if runs:
        body += [_gallery(results_dir, runs), _charts(results_dir, runs),
                 "<h2>Summary</h2>", _summary(runs), f'<p class="note">{escape(_LEGEND)}</p>']
    else:
        body.append(f'<p class="note">No {METRICS_NAME} found under this folder.</p>')
    if problems:
        body.append(
            '<div class="problems"><h3>Problems</h3><ul>'
            + "".join(f"<li>{escape(p)}</li>" for p in problems)
            + "</ul></div>"
        )
    if runs:  # the details, folded away
        body.append("<h2>Runs</h2>")
    body += [f"<details><summary>{escape(run.folder.name)}</summary>\n"
             f"{_run_section(results_dir, run)}\n</details>" for run in runs]
    page = (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
        f"<title>{escape(title)}</title>\n<style>{_CSS}</style>\n</head>\n<body>\n"
        + "\n".join(body)
        + "\n</body>\n</html>\n"
    )
    out = results_dir / REPORT_NAME
    out.write_text(page, encoding="utf-8")
    return out
