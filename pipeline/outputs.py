"""Where a command's files go: safe names, a staging folder, and an atomic publish.

A run writes everything into a hidden staging folder beside `--out`; only when the command finishes
are the files moved into place, each with `os.replace` (atomic on one filesystem). A failed or
cancelled run removes its staging folder, so earlier outputs stay exactly as they were.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

# Windows refuses these as file names whatever the extension.
_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(10)),
             *(f"LPT{i}" for i in range(10))}
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")
MAX_NAME_LENGTH = 120  # leaves room for suffixes under the 255-byte limit of common filesystems


def safe_name(name: str, fallback: str = "unnamed") -> str:
    """A file name made from an object or image name: ASCII letters, digits, '.', '_' and '-' only,
    no leading dots, never empty, never a path, never a reserved device name."""
    cleaned = _UNSAFE.sub("_", name).strip("._") or fallback
    cleaned = cleaned[:MAX_NAME_LENGTH]
    if cleaned.split(".")[0].upper() in _RESERVED:
        cleaned = "_" + cleaned
    return cleaned


class UsageError(Exception):
    """Bad arguments or unreadable input: the command line exits 2 with this one-line message."""


@dataclass
class RunRecord:
    """What `metrics.json` says about one run."""

    technique: str
    scene: str
    settings: dict = field(default_factory=dict)
    seconds: dict = field(default_factory=dict)
    sizes: dict = field(default_factory=dict)
    outputs: list = field(default_factory=list)
    versions: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    def as_json(self) -> dict:
        out = {
            "technique": self.technique,
            "scene": self.scene,
            "settings": self.settings,
            "seconds": self.seconds,
            "sizes": self.sizes,
            "outputs": self.outputs,
            "versions": self.versions,
        }
        out.update(self.extra)
        return out


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


class Staging:
    """A run's private output folder; `publish()` moves its files into the real one."""

    def __init__(self, out_dir: Path):
        self.out_dir = Path(out_dir)
        self._made_out_dir = not self.out_dir.exists()  # a failed run removes it again if empty
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UsageError(f"cannot create output folder '{self.out_dir}': {exc.strerror}") from exc
        if not os.access(self.out_dir, os.W_OK):
            raise UsageError(f"output folder '{self.out_dir}' is not writable")
        self.path = Path(tempfile.mkdtemp(prefix=".classic_bake-", dir=self.out_dir))
        self._files: list[str] = []

    def file(self, name: str) -> Path:
        """A path in the staging folder for output `name` (made safe; may contain one subfolder)."""
        parts = [safe_name(p) for p in Path(name).parts if p not in ("", ".", "..", "/")]
        if not parts:
            raise ValueError(f"empty output name {name!r}")
        path = self.path.joinpath(*parts)
        if self.path.resolve() not in path.resolve().parents:
            raise ValueError(f"output name {name!r} leaves the output folder")
        path.parent.mkdir(parents=True, exist_ok=True)
        rel = path.relative_to(self.path).as_posix()
        if rel not in self._files:
            self._files.append(rel)
        return path

    @property
    def files(self) -> list[str]:
        return list(self._files)

    def write_json(self, name: str, data: dict) -> Path:
        path = self.file(name)
        path.write_text(json.dumps(data, indent=2, default=_json_default, allow_nan=False) + "\n")
        return path

    def publish(self) -> list[Path]:
        """Move every staged file into the output folder (atomic per file) and remove staging."""
        moved = []
        for rel in self._files:
            src = self.path / rel
            if not src.exists():
                continue
            dst = self.out_dir / rel
            dst.parent.mkdir(parents=True, exist_ok=True)
            os.replace(src, dst)
            moved.append(dst)
        self.discard()
        return moved

    def discard(self) -> None:
        """Remove the staging folder, and the output folder too if this run made it and it is
        still empty (a failed first run leaves nothing behind)."""
        shutil.rmtree(self.path, ignore_errors=True)
        if self._made_out_dir:
            try:
                self.out_dir.rmdir()  # only succeeds when empty
            except OSError:
                pass


class PhaseTimer:
    """Seconds per named phase, and in total, of one run."""

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self._start = time.perf_counter()

    @contextmanager
    def phase(self, name: str):
        t0 = time.perf_counter()
        try:
            yield
        finally:
            self.seconds[name] = self.seconds.get(name, 0.0) + time.perf_counter() - t0

    def totals(self) -> dict[str, float]:
        out = {k: round(v, 6) for k, v in self.seconds.items()}
        out["total"] = round(time.perf_counter() - self._start, 6)
        return out
