"""docs/reliability.md lists every case of the bad-input catalogue: each test function of the
files below appears in its table."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CATALOGUE = ["tests/blender/test_bad_inputs.py", "tests/pipeline/test_outputs_publish.py"]


def case_ids(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return [node.name for node in tree.body
            if isinstance(node, ast.FunctionDef) and node.name.startswith("test_")]


@pytest.mark.parametrize("test_file", CATALOGUE)
def test_the_docs_table_lists_every_case(test_file):
    table = (ROOT / "docs" / "reliability.md").read_text(encoding="utf-8")
    ids = case_ids(ROOT / test_file)
    assert ids
    missing = [case for case in ids if f"| `{case}` |" not in table]
    assert not missing, f"docs/reliability.md lacks rows for {missing}"
