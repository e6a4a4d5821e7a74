"""Where a command's files go: safe unique names, a staging folder, and a publish as one set.

A run writes everything into a hidden staging folder inside `--out`. Only when the command
finishes is the set published: every destination is checked first (a folder or a symbolic link
where a file or folder belongs fails before anything is replaced), then each earlier file the set
replaces is moved aside into a hidden folder and the new one moved in with `os.replace` (atomic on
one filesystem), with SIGINT and SIGTERM held off; a failure part-way moves everything back. A
failed or cancelled run removes its staging folder, so earlier outputs stay exactly as they were.

Names: an object or image name becomes a safe file name; when cleaning changed it (or it collides
with a name already given, ignoring case) it gets the first 8 hex digits of the SHA-1 of the
original name as a suffix, so two names never share a file (`unique_stems`, `Staging.file`).
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..jobs.file_names import (  # noqa: F401 - re-exported: callers name them from here
    MAX_NAME_LENGTH,
    NameTable,
    name_hash,
    safe_name,
    split_extension,
    unique_stems,
)


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
        try:
            self.path = Path(tempfile.mkdtemp(prefix=".classic_bake-", dir=self.out_dir))
        except OSError as exc:
            raise UsageError(f"cannot write in output folder '{self.out_dir}': {exc.strerror}") from exc
        self._files: list[str] = []
        self._names: dict[str, NameTable] = {}  # one per folder
        self.renamed: dict[str, str] = {}  # requested name -> file written, where they differ

    def file(self, name: str) -> Path:
        """A path in the staging folder for output `name` (made safe and unique, its extension
        kept; may contain subfolders). Two different names never get the same path."""
        raw = [p for p in Path(name).parts if p not in ("", ".", "..", "/", "\\")]
        if not raw:
            raise ValueError(f"empty output name {name!r}")
        folders = [safe_name(p) for p in raw[:-1]]
        stem, ext = split_extension(raw[-1])
        table = self._names.setdefault("/".join(folders).casefold(), NameTable())
        path = self.path.joinpath(*folders, table.claim(stem, ext))
        if self.path.resolve() not in path.resolve().parents:
            raise ValueError(f"output name {name!r} leaves the output folder")
        path.parent.mkdir(parents=True, exist_ok=True)
        rel = path.relative_to(self.path).as_posix()
        if rel not in self._files:
            self._files.append(rel)
        if rel != name:
            self.renamed[name] = rel
        return path

    @property
    def files(self) -> list[str]:
        return list(self._files)

    def write_json(self, name: str, data: dict) -> Path:
        path = self.file(name)
        path.write_text(json.dumps(data, indent=2, default=_json_default, allow_nan=False) + "\n")
        return path

    def check_destinations(self) -> list[str]:
        """The staged files' relative paths, after checking that each can replace what is in the
        output folder: no symbolic link and no file among its folders (never written through),
        no folder where the file belongs. Raises UsageError naming the first that cannot."""
        rels = [rel for rel in self._files if (self.path / rel).exists()]
        for rel in rels:
            parts = rel.split("/")
            for k in range(1, len(parts)):
                folder = self.out_dir.joinpath(*parts[:k])
                if folder.is_symlink():
                    raise UsageError(f"'{folder}' is a symbolic link; outputs are never written "
                                     "through one: remove it or choose another --out")
                if folder.exists() and not folder.is_dir():
                    raise UsageError(f"'{folder}' is a file where an output folder belongs")
            dst = self.out_dir / rel
            if dst.is_dir() and not dst.is_symlink():
                raise UsageError(f"'{dst}' is a folder where output file '{rel}' belongs")
        return rels

    def publish(self) -> list[Path]:
        """Publish the staged files as one set and remove staging: check every destination,
        then (signals held off) move each earlier file aside and the new one in; any failure moves
        everything back, so the output folder holds either the whole new set or the old one."""
        rels = self.check_destinations()
        backup = Path(tempfile.mkdtemp(prefix=".classic_bake-old-", dir=self.out_dir))
        old: list[tuple[Path, Path]] = []  # (backup copy, destination)
        new: list[tuple[Path, Path]] = []  # (destination, staged file)
        made: list[Path] = []  # folders this publish created
        with signals_held():
            try:
                for rel in rels:
                    src, dst = self.path / rel, self.out_dir / rel
                    for folder in reversed(dst.relative_to(self.out_dir).parents[:-1]):
                        folder = self.out_dir / folder
                        if not folder.exists():
                            try:
                                folder.mkdir()
                            except FileExistsError:  # another run (a tile) made it meanwhile
                                continue
                            made.append(folder)
                    if dst.exists() or dst.is_symlink():
                        aside = backup / rel
                        aside.parent.mkdir(parents=True, exist_ok=True)
                        os.replace(dst, aside)
                        old.append((aside, dst))
                    os.replace(src, dst)
                    new.append((dst, src))
            except BaseException:
                for dst, src in reversed(new):
                    os.replace(dst, src)
                for aside, dst in reversed(old):
                    os.replace(aside, dst)
                for folder in reversed(made):
                    try:
                        folder.rmdir()
                    except OSError:
                        pass
                shutil.rmtree(backup, ignore_errors=True)
                raise
            shutil.rmtree(backup, ignore_errors=True)
            self.discard()
        return [dst for dst, _ in new]

    def discard(self) -> None:
        """Remove the staging folder, and the output folder too if this run made it and it is
        still empty (a failed first run leaves nothing behind)."""
        shutil.rmtree(self.path, ignore_errors=True)
        if self._made_out_dir:
            try:
                self.out_dir.rmdir()  # only succeeds when empty
            except OSError:
                pass


@contextmanager
def signals_held():
    """SIGINT and SIGTERM held back for the block (delivered after it) where the platform can."""
    held = {signal.SIGINT, signal.SIGTERM}
    try:
        previous = signal.pthread_sigmask(signal.SIG_BLOCK, held)
    except (AttributeError, OSError, ValueError):  # Windows
        yield
        return
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


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
