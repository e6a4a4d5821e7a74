"""Fill the generated blocks of the documents: `make docs` (or `python tools/gen_docs.py`).

A generated block sits between two HTML comments, which Markdown viewers do not show:

    <!-- BEGIN parameters -->      the technique's settings dataclasses, one table each
    <!-- END parameters -->
    <!-- BEGIN figures -->         the technique's published bench figures (bench/results/*.json)
    <!-- END figures -->
    <!-- BEGIN results -->         bench/README.md: every bench's ratios (bench/results/*.json)
    <!-- END results -->

In `docs/techniques/NAME.md` a block's subject is NAME unless the BEGIN line names another one
(`<!-- BEGIN figures rays -->`). Parameters come from the kernels' frozen settings dataclasses
(`dataclasses.fields`: name, type, default) plus the range and meaning of each field from the
parameter table in the class's docstring. The classes are found by name in every module under
`classic_bake.kernels`, so moving a class between modules changes nothing here.

    python tools/gen_docs.py            rewrite the blocks in place
    python tools/gen_docs.py --publish  first copy out/bench/NAME.json into bench/results/
    python tools/gen_docs.py --check    exit 1 when a generated block is out of date

A bench writes out/bench/NAME.json (not kept in git). Publishing copies it into bench/results/,
which is kept: the figures the documents show, each with the versions it ran with. `make bench`
runs every bench and publishes; run it on an idle machine (a second busy process on two cores
halves NumPy's speed and turns ratios over). Tests keep every block current with the code and
with bench/results/.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib
import json
import pkgutil
import re
import sys
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TECHNIQUE_DOCS = REPO / "docs" / "techniques"
BENCH_README = REPO / "bench" / "README.md"
BENCH_OUT = REPO / "out" / "bench"  # what the benches write
PUBLISHED = REPO / "bench" / "results"  # what the documents show (`--publish` copies)

# The one table of which settings dataclasses hold a technique's parameters (by class name; the
# classes are looked up in classic_bake.kernels) and which benches measure it (out/bench/NAME.json).
TECHNIQUES: dict[str, dict[str, tuple[str, ...]]] = {
    "texture": {"settings": ("TextureBakeSettings", "LightmapUVSettings"), "benches": ("texture",)},
    "envmap": {"settings": ("EnvMapSettings", "PrefilterSettings"),
               "benches": ("envmap", "envmap_eevee")},
    "bump": {"settings": ("TracerSettings",), "benches": ("bump",)},
    "shadowmap": {"settings": ("ShadowMapSettings", "DirectLightSettings"),
                  "benches": ("shadowmap",)},
    "trace": {"settings": ("TracerSettings",), "benches": ("trace", "rays", "rays_loaded")},
    "radiosity": {"settings": ("RadiositySettings",), "benches": ("radiosity",)},
    "hybrid": {"settings": ("HybridSettings",), "benches": ("hybrid",)},
    "normalmap": {"settings": ("NormalMapSettings", "HighToLowSettings"),
                  "benches": ("normalmap",)},
}
# Every bench, in the order bench/README.md describes them (the Makefile's BENCHES).
BENCHES = ("rays", "rays_loaded", "trace", "texture", "envmap", "envmap_eevee", "bump", "shadowmap",
           "radiosity", "hybrid", "normalmap", "generated", "batch", "demo")
# The reliability runs (not speed benches; hours, so `make bench` leaves them out): published
# like the benches, shown in docs/reliability.md.
RELIABILITY_BENCHES = ("huge", "soak")
RELIABILITY_DOC = REPO / "docs" / "reliability.md"

BLOCK = re.compile(r"<!-- BEGIN (?P<kind>[a-z]+)(?: (?P<arg>[a-z0-9_-]+))? -->\n"
                   r"(?P<body>.*?)"
                   r"<!-- END (?P=kind) -->", re.S)
MARKER = re.compile(r"<!-- (BEGIN|END) ([a-z]+)(?: [a-z0-9_-]+)? -->")
NO_FIGURES = "No published figures yet: run `make bench` on an idle machine"
# Columns of a bench's ladder rows worth a table, in this order (the rest stay in the JSON).
ROW_COLUMNS = ("setting", "mode", "case", "command", "commit", "scene", "light", "rung",
               "samples", "passes", "patches", "faces", "outcome", "seconds", "peak_gb", "rel_mse",
               "rel_mse_mirror", "flip", "cycles_seconds_to_same_error", "ratio")
MAX_ROW_COLUMNS = 7


# --- settings classes ----------------------------------------------------------------------------

def settings_classes(names) -> dict[str, type]:
    """{name: the settings dataclass of that name defined in a module under classic_bake.kernels}."""
    import classic_bake.kernels as kernels

    wanted = set(names)
    found: dict[str, type] = {}
    failed: dict[str, str] = {}
    for info in pkgutil.walk_packages(kernels.__path__, prefix=f"{kernels.__name__}.",
                                      onerror=lambda name: failed.setdefault(name, "import failed")):
        try:
            module = importlib.import_module(info.name)
        except Exception as exc:  # a module that does not import cannot be documented
            failed[info.name] = f"{type(exc).__name__}: {exc}"
            continue
        for name in wanted - set(found):
            cls = getattr(module, name, None)
            if (isinstance(cls, type) and dataclasses.is_dataclass(cls)
                    and cls.__module__ == module.__name__):
                found[name] = cls
    missing = wanted - set(found)
    if missing:
        because = "".join(f"\n  {name}: {why}" for name, why in sorted(failed.items()))
        raise LookupError(f"no settings dataclass named {', '.join(sorted(missing))} under "
                          f"{kernels.__name__}" + (f"; modules that did not import:{because}"
                                                   if failed else ""))
    return found


def _join(head: str, tail: str) -> str:
    """Two pieces of one table cell wrapped over two docstring rows."""
    if not head or not tail:
        return head or tail
    if head.endswith(("_", "-")) and not head.endswith(" -"):
        return head + tail
    return f"{head} {tail}"


def docstring_table(cls: type) -> dict[str, dict[str, str]]:
    """{field: {"range", "meaning"}} from the parameter table in the class's docstring, where it
    has one. Rows whose first cell is empty (or not a field, as in `shadow_back_` / `faces`)
    continue the row above, cell by cell."""
    fields = {f.name for f in dataclasses.fields(cls)}
    header: list[str] | None = None
    rows: list[list[str]] = []
    for line in (cls.__doc__ or "").splitlines():
        line = line.strip()
        if not (line.startswith("|") and line.endswith("|")):
            continue
        cells = [c.strip() for c in line[1:-1].split("|")]
        if header is None:
            header = [c.lower() for c in cells]
            continue
        if all(set(c) <= set("-: ") for c in cells):
            continue
        if len(cells) != len(header):
            continue
        if rows and cells[0] not in fields and (not cells[0] or rows[-1][0] not in fields
                                                or _join(rows[-1][0], cells[0]) in fields):
            rows[-1] = [_join(a, b) for a, b in zip(rows[-1], cells, strict=True)]
        else:
            rows.append(cells)
    if header is None:
        return {}
    range_col = next((i for i, h in enumerate(header) if h == "range"), None)
    meaning_col = len(header) - 1
    return {row[0]: {"range": row[range_col] if range_col is not None else "",
                     "meaning": row[meaning_col]}
            for row in rows if row[0] in fields}


def _type_name(annotation) -> str:
    if isinstance(annotation, str):
        return annotation
    if isinstance(annotation, type):
        return annotation.__name__
    return str(annotation).replace("typing.", "")


def _default(spec: dataclasses.Field) -> str:
    if spec.default is not dataclasses.MISSING:
        value = spec.default
    elif spec.default_factory is not dataclasses.MISSING:
        value = spec.default_factory()
    else:
        return "required"
    if dataclasses.is_dataclass(value):
        return f"`{type(value).__name__}()`"
    if isinstance(value, float):
        return f"`{value:.6g}`"
    return f"`{value!r}`"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def parameters_table(cls: type) -> str:
    """A Markdown table of one settings dataclass."""
    described = docstring_table(cls)
    # The class's name only: modules move, names stay (the page names the subpackage in prose).
    lines = [f"`{cls.__name__}`:", "",
             "| parameter | type | default | range | meaning |",
             "|-----------|------|---------|-------|---------|"]
    for spec in dataclasses.fields(cls):
        row = described.get(spec.name, {"range": "", "meaning": ""})
        lines.append(f"| `{spec.name}` | `{_cell(_type_name(spec.type))}` | {_cell(_default(spec))} "
                     f"| {_cell(row['range'])} | {_cell(row['meaning'])} |")
    return "\n".join(lines)


def parameters_block(technique: str) -> str:
    names = TECHNIQUES[technique]["settings"]
    classes = settings_classes(names)
    return "\n\n".join(parameters_table(classes[name]) for name in names)


# --- bench figures -------------------------------------------------------------------------------

def _number(value) -> str:
    if isinstance(value, bool) or value is None:
        return "-" if value is None else str(value)
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value:.3g}"
    return _cell(str(value))


def _ladders(figures, path: str = ""):
    """(path, rows) of every list of dicts with a "seconds" column inside a bench's figures."""
    if isinstance(figures, dict):
        for key, value in figures.items():
            yield from _ladders(value, f"{path}/{key}" if path else str(key))
    elif (isinstance(figures, list) and figures and all(isinstance(r, dict) for r in figures)
          and any("seconds" in r for r in figures)):
        yield path, figures


def bench_tables(report: dict, ladders: bool = True) -> str:
    """The ratios of one out/bench/NAME.json, and (ladders=True) its ladders' main columns."""
    lines = []
    ratios = report.get("ratios") or {}
    if ratios:
        lines += ["| ratio | value |", "|-------|-------|"]
        lines += [f"| `{_cell(k)}` | {_number(v)} |" for k, v in sorted(ratios.items())]
    if ladders:
        for path, rows in _ladders(report.get("figures") or {}):
            columns = [c for c in ROW_COLUMNS if any(c in r for r in rows)][:MAX_ROW_COLUMNS]
            if len(columns) < 2:
                continue
            lines += ["", f"`{_cell(path)}`:", "", "| " + " | ".join(columns) + " |",
                      "|" + "|".join("---" for _ in columns) + "|"]
            lines += ["| " + " | ".join(_number(r.get(c)) for c in columns) + " |" for r in rows]
    versions = report.get("versions") or {}
    if versions:
        lines += ["", "Versions: " + ", ".join(f"{k} {v}" for k, v in sorted(versions.items())) + "."]
    return "\n".join(lines) if lines else "(the report holds no figures)"


def _read_bench(name: str, out_dir: Path) -> dict | None:
    path = out_dir / f"{name}.json"
    if not path.is_file():
        return None
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def figures_block(technique: str, out_dir: Path = PUBLISHED) -> str:
    benches = TECHNIQUES.get(technique, {}).get("benches", (technique,))
    parts = []
    for name in benches:
        report = _read_bench(name, out_dir)
        if report is None:
            parts.append(f"{NO_FIGURES} (or `.venv/bin/python bench/{name}.py`, then "
                         f"`make docs PUBLISH=1`).")
        else:
            parts.append(f"From `bench/results/{name}.json` (`bench/{name}.py`):\n\n"
                         + bench_tables(report))
    return "\n\n".join(parts)


def results_block(out_dir: Path = PUBLISHED) -> str:
    """One table of every bench's ratios (bench, ratio, value), then what ran and what did not."""
    rows, ran, missing = [], [], []
    for name in BENCHES:
        report = _read_bench(name, out_dir)
        if report is None:
            missing.append(name)
            continue
        ran.append((name, report.get("versions") or {}))
        rows += [f"| `{name}` | `{_cell(key)}` | {_number(value)} |"
                 for key, value in sorted((report.get("ratios") or {}).items())]
    lines = []
    if rows:
        lines += ["| bench | ratio | value |", "|-------|-------|-------|", *rows, ""]
    for name, versions in ran:
        lines.append(f"* `{name}` ran with " + (", ".join(f"{k} {v}" for k, v in sorted(versions.items()))
                                                 or "versions not recorded"))
    if missing:
        lines += ["", f"{NO_FIGURES} for " + ", ".join(f"`{n}`" for n in missing)
                  + " (`.venv/bin/python bench/NAME.py` runs one), then `make docs PUBLISH=1`."]
    return "\n".join(lines).strip()


# --- documents -----------------------------------------------------------------------------------

def fill(text: str, subject: str | None, kinds=("parameters", "figures", "results"),
         out_dir: Path = PUBLISHED) -> str:
    """`text` with its generated blocks of the given kinds regenerated."""
    makers: dict[str, Callable[[str | None], str]] = {
        "parameters": lambda arg: parameters_block(arg),
        "figures": lambda arg: figures_block(arg, out_dir),
        "results": lambda arg: results_block(out_dir),
    }

    def replace(match: re.Match) -> str:
        kind, arg = match["kind"], match["arg"] or subject
        if kind not in kinds or kind not in makers:
            return match[0]
        if kind == "parameters" and arg not in TECHNIQUES:
            raise KeyError(f"no technique {arg!r} in tools/gen_docs.py TECHNIQUES")
        head = f"<!-- BEGIN {kind}{' ' + match['arg'] if match['arg'] else ''} -->\n"
        # Blank lines around the body: a table must not run into the END comment.
        return f"{head}\n{makers[kind](arg).strip()}\n\n<!-- END {kind} -->"

    return BLOCK.sub(replace, text)


def blocks(text: str) -> list[tuple[str, str | None, str]]:
    """(kind, argument, body) of every generated block; ValueError when markers do not pair up."""
    found = [(m["kind"], m["arg"], m["body"]) for m in BLOCK.finditer(text)]
    markers = MARKER.findall(text)
    if len(markers) != 2 * len(found):
        raise ValueError(f"{len(markers)} block markers but {len(found)} complete blocks")
    return found


def documents() -> list[tuple[Path, str | None]]:
    """(path, subject) of every document with generated blocks."""
    pages = [(p, p.stem) for p in sorted(TECHNIQUE_DOCS.glob("*.md"))]
    return pages + [(BENCH_README, None), (RELIABILITY_DOC, None)]


def publish(names=BENCHES + RELIABILITY_BENCHES, source: Path = BENCH_OUT,
            target: Path = PUBLISHED) -> list[str]:
    """Copy source/NAME.json into target/ for every bench that wrote one; returns the names.
    A report that is not a bench report (no "bench" and "ratios") is refused."""
    copied = []
    for name in names:
        report = _read_bench(name, source)
        if report is None:
            continue
        if report.get("bench") != name or not isinstance(report.get("ratios"), dict):
            raise ValueError(f"{source / (name + '.json')} is not a bench report of {name!r}")
        target.mkdir(parents=True, exist_ok=True)
        (target / f"{name}.json").write_text(json.dumps(report, indent=1, sort_keys=True) + "\n",
                                             encoding="utf-8")
        copied.append(name)
    return copied


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true",
                        help="change nothing; exit 1 when a generated block is out of date")
    parser.add_argument("--publish", action="store_true",
                        help="copy out/bench/NAME.json into bench/results/ first")
    args = parser.parse_args(argv)
    if args.publish and not args.check:
        for name in publish():
            print(f"gen_docs: published bench/results/{name}.json")
    stale = []
    for path, subject in documents():
        if not path.is_file():
            continue
        text = path.read_text(encoding="utf-8")
        blocks(text)
        if args.check:
            if fill(text, subject) != text:
                stale.append(path.relative_to(REPO))
            continue
        new = fill(text, subject)
        if new != text:
            path.write_text(new, encoding="utf-8")
            print(f"gen_docs: updated {path.relative_to(REPO)}")
    if stale:
        print("gen_docs: generated blocks out of date in " + ", ".join(map(str, stale))
              + ": run `make docs`", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
