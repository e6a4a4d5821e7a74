"""What a command is (`Command`) and what it sees while it runs (`RunContext`).

Every command takes `--quiet` (no messages, no progress; errors still go to stderr) and
`--verbose` (progress lines on stderr even when it is not a terminal): `Command` adds them to
whatever arguments the command declares, so each command's parser has them.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from .outputs import PhaseTimer, RunRecord, Staging
from .progress import NORMAL, QUIET, VERBOSE, ProgressBar


def add_verbosity_arguments(parser: argparse.ArgumentParser) -> None:
    """--quiet / --verbose (one or the other)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--quiet", action="store_true",
                       help="print nothing but errors: no messages, no progress bar")
    group.add_argument("--verbose", action="store_true",
                       help="also print progress lines when stderr is not a terminal (logs)")


def verbosity(args: argparse.Namespace) -> int:
    if getattr(args, "quiet", False):
        return QUIET
    return VERBOSE if getattr(args, "verbose", False) else NORMAL


@dataclass(frozen=True)
class Command:
    """One CLI command. `run(ctx)` does the work; the pipeline does files, timing and errors.

    `add_arguments` is the command's own arguments; the verbosity switches are added to them."""

    name: str
    help: str
    run: Callable[[RunContext], None]
    add_arguments: Callable[[argparse.ArgumentParser], None] = lambda parser: None
    needs_scene: bool = True
    is_technique: bool = False  # techniques must write render.exr

    def __post_init__(self):
        own = self.add_arguments

        def add_arguments(parser: argparse.ArgumentParser) -> None:
            own(parser)
            add_verbosity_arguments(parser)

        object.__setattr__(self, "add_arguments", add_arguments)


class RunContext:
    """What a command sees: its arguments, a staging folder, a phase timer and the run record."""

    def __init__(self, cmd: Command, args: argparse.Namespace, staging: Staging, timer: PhaseTimer):
        self.command = cmd
        self.args = args
        self.staging = staging
        self.timer = timer
        scene = getattr(args, "scene", None)
        self.record = RunRecord(technique=cmd.name, scene=str(scene) if scene else "")
        self.resolution: tuple[int, int] | None = getattr(args, "resolution", None)
        self.verbosity = verbosity(args)
        self._bars: list[ProgressBar] = []

    @contextmanager
    def phase(self, name: str):
        """`with ctx.phase("trace"): ...` adds the block's seconds to metrics.json; a progress bar
        opened inside the block (`ctx.progress`) is finished when it ends, or wiped when it fails,
        so that what is printed next starts on its own line."""
        opened = len(self._bars)
        done = False
        try:
            with self.timer.phase(name):
                yield
            done = True
        finally:
            for bar in self._bars[opened:]:
                bar.close(done)
            del self._bars[opened:]

    def progress(self, label: str | None = None) -> ProgressBar:
        """A progress bar on stderr (kernels/progress.py: `drain(step, ctx.progress())`), shown
        as the verbosity and the terminal say (pipeline/progress.py)."""
        bar = ProgressBar(label or self.command.name, self.verbosity)
        self._bars.append(bar)
        return bar

    def output(self, name: str) -> Path:
        """A staging path for output `name`; it is published into --out on success."""
        return self.staging.file(name)

    def write_render(self, pixels) -> Path:
        """Write the technique's camera view as linear `render.exr` (the Cycles comparison input)."""
        from ..kernels.measure.exr import write_exr

        path = self.output("render.exr")
        write_exr(path, pixels)
        return path

    def say(self, message: str) -> None:
        if self.verbosity > QUIET:
            print(message, flush=True)
