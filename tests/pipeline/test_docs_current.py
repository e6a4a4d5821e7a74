"""The documents' generated blocks are current (tools/gen_docs.py, `make docs`).

Parameters blocks come from the kernels' settings dataclasses, so they are regenerated in memory
and compared with the pages. Figures and results blocks come from the benches run on a machine
(out/bench/*.json), so only their form is checked: markers paired, a body that is either a table
or the sentence saying to run `make bench`.
"""

import importlib.util
import json
import os
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
TOOL = REPO / "tools" / "gen_docs.py"
TECHNIQUE_PAGES = ("texture", "envmap", "bump", "shadowmap", "trace", "radiosity", "hybrid",
                   "normalmap")
MACHINE_PATH = re.compile(r"(?<![\w.])/(?:work|tmp|home|root|Users)/")


@pytest.fixture(scope="module")
def gen_docs():
    spec = importlib.util.spec_from_file_location("gen_docs", TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_technique_has_a_page_with_the_generated_blocks(gen_docs):
    for name in TECHNIQUE_PAGES:
        page = REPO / "docs" / "techniques" / f"{name}.md"
        assert page.is_file(), f"missing {page.relative_to(REPO)}"
        text = page.read_text(encoding="utf-8")
        kinds = [kind for kind, _, _ in gen_docs.blocks(text)]
        assert "parameters" in kinds and "figures" in kinds, page.name
        pictures = re.findall(r"!\[[^\]]*\]\((\.\./images/[^)]+)\)", text)
        assert pictures, f"{page.name} shows no picture from docs/images"
        for picture in pictures:
            assert (page.parent / picture).is_file(), f"{page.name}: missing {picture}"
    assert set(TECHNIQUE_PAGES) <= set(gen_docs.TECHNIQUES)


def test_parameters_blocks_are_current(gen_docs):
    stale = []
    for path, subject in gen_docs.documents():
        text = path.read_text(encoding="utf-8")
        if gen_docs.fill(text, subject, kinds=("parameters",)) != text:
            stale.append(str(path.relative_to(REPO)))
    assert not stale, f"parameters out of date in {stale}: run `make docs`"


def test_parameters_name_every_field_with_its_default(gen_docs):
    import dataclasses

    classes = gen_docs.settings_classes(
        {name for t in gen_docs.TECHNIQUES.values() for name in t["settings"]})
    for cls in classes.values():
        table = gen_docs.parameters_table(cls)
        for spec in dataclasses.fields(cls):
            assert f"| `{spec.name}` |" in table, (cls.__name__, spec.name)
    # The docstring's wrapped rows are joined: a range split over two rows, a field name too.
    described = gen_docs.docstring_table(classes["TracerSettings"])
    assert described["shading"]["range"] == "flat, gouraud, phong, bump"
    assert "shadow_back_faces" in gen_docs.docstring_table(classes["ShadowMapSettings"])


def test_figures_and_results_blocks_show_the_published_reports(gen_docs):
    """The figures in the documents are the ones in bench/results/ (`make docs` regenerates)."""
    stale = []
    for path, subject in gen_docs.documents():
        text = path.read_text(encoding="utf-8")
        if gen_docs.fill(text, subject, kinds=("figures", "results")) != text:
            stale.append(str(path.relative_to(REPO)))
    assert not stale, f"figures out of date in {stale}: run `make docs`"


def test_publish_copies_bench_reports_and_refuses_others(gen_docs, tmp_path):
    source, target = tmp_path / "out", tmp_path / "results"
    source.mkdir()
    (source / "trace.json").write_text(json.dumps(
        {"bench": "trace", "ratios": {"r": 1.5}, "figures": {}, "versions": {}}), encoding="utf-8")
    assert gen_docs.publish(("trace", "rays"), source, target) == ["trace"]
    assert json.loads((target / "trace.json").read_text(encoding="utf-8"))["ratios"] == {"r": 1.5}
    (source / "rays.json").write_text(json.dumps({"ratios": {}}), encoding="utf-8")
    with pytest.raises(ValueError, match="not a bench report"):
        gen_docs.publish(("rays",), source, target)


def test_figures_and_results_blocks_are_well_formed(gen_docs):
    for path, _ in gen_docs.documents():
        for kind, _, body in gen_docs.blocks(path.read_text(encoding="utf-8")):
            if kind not in ("figures", "results"):
                continue
            assert body.strip(), f"empty {kind} block in {path.name}"
            table = "| bench | ratio | value |" if kind == "results" else "| ratio | value |"
            assert gen_docs.NO_FIGURES in body or table in body, (path.name, kind)


def test_figures_render_a_bench_report(gen_docs, tmp_path):
    report = {"bench": "trace", "ratios": {"cycles_vs_tracer": 0.67, "unreached": None},
              "figures": {"scales": {"x1": {"kernel": [
                  {"setting": "pixel centres", "seconds": 0.71, "rel_mse": 2.8e-3, "ratio": 0.4}]}}},
              "versions": {"bpy": "5.2.3"}}
    (tmp_path / "trace.json").write_text(json.dumps(report), encoding="utf-8")
    block = gen_docs.figures_block("trace", tmp_path)
    assert "| `cycles_vs_tracer` | 0.67 |" in block and "| `unreached` | - |" in block
    assert "| pixel centres | 0.71 | 0.0028 | 0.4 |" in block
    assert "bpy 5.2.3" in block
    # rays.json is missing: that part says how to make it.
    assert "bench/rays.py" in block and gen_docs.NO_FIGURES in block
    results = gen_docs.results_block(tmp_path)
    assert "| `trace` | `cycles_vs_tracer` | 0.67 |" in results and "`trace` ran with bpy 5.2.3" in results
    assert gen_docs.NO_FIGURES in results and "`radiosity`" in results


NOT_SOURCES = {".git", ".venv", ".venv45", "out", "dist", "wheels", "__pycache__"}
SOURCE_SUFFIXES = {".py", ".md", ".sh", ".toml", ".txt", ".json"}


def test_code_and_documents_name_no_machine_path():
    files = []
    for folder, subfolders, names in os.walk(REPO):
        subfolders[:] = [d for d in subfolders if d not in NOT_SOURCES]
        files += [Path(folder) / n for n in names
                  if Path(n).suffix in SOURCE_SUFFIXES or n == "Makefile"]
    assert any(p.name == "README.md" for p in files)
    for path in files:
        found = MACHINE_PATH.search(path.read_text(encoding="utf-8", errors="replace"))
        assert found is None, f"{path.relative_to(REPO)} names a machine path: {found[0]}"


WORK_LOG = re.compile(r"\bsession \d+\b|\(session\b|^#+ .*\bsession\b", re.I | re.M)


def test_readme_states_the_demo_budget_the_bench_measures_against():
    source = (REPO / "pipeline" / "commands" / "demo.py").read_text(encoding="utf-8")
    minutes = int(re.search(r"^DEMO_BUDGET_S = (\d+) \* 60$", source, re.M)[1])
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert f"at most {minutes} minutes" in readme


def test_readme_is_a_short_guide_and_documents_keep_no_work_log():
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert len(readme.splitlines()) <= 300
    for name in TECHNIQUE_PAGES:
        assert f"docs/techniques/{name}.md" in readme, f"README does not link the {name} page"
    pages = [REPO / "README.md", REPO / "bench" / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
    for page in pages:
        found = WORK_LOG.search(page.read_text(encoding="utf-8"))
        assert found is None, f"{page.relative_to(REPO)} keeps a work-log entry: {found[0]!r}"
