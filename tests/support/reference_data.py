"""Reference data the tests read: tests/data/ (sources in tests/data/README.md)."""

import json
from pathlib import Path

DATA = Path(__file__).resolve().parents[1] / "data"


def reference_path(name: str) -> Path:
    """Path of a reference file in tests/data (e.g. "cornell_box.json")."""
    return DATA / name


def reference(name: str):
    """A JSON reference file of tests/data, parsed."""
    return json.loads(reference_path(name).read_text())
