"""What a command is (`Command`) and what it sees while it runs (`RunContext`)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .outputs import PhaseTimer, RunRecord, Staging


@dataclass(frozen=True)
class Command:
    """One CLI command. `run(ctx)` does the work; the pipeline does files, timing and errors."""

    name: str
    help: str
    run: Callable[[RunContext], None]
    add_arguments: Callable[[argparse.ArgumentParser], None] = lambda parser: None
    needs_scene: bool = True
    is_technique: bool = False  # techniques must write render.exr


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

    def phase(self, name: str):
        """`with ctx.phase("trace"): ...` adds the block's seconds to metrics.json."""
        return self.timer.phase(name)

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
        print(message, flush=True)
