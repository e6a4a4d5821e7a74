"""Every CLI command: one per technique record (technique.py), and info, compare, demo, report,
batch, merge."""

from __future__ import annotations

from ...jobs.techniques import TECHNIQUES
from . import batch, compare, demo, info, merge, report
from .technique import technique_command

COMMANDS = {cmd.name: cmd for cmd in (
    info.COMMAND, *(technique_command(t) for t in TECHNIQUES), compare.COMMAND, demo.COMMAND,
    report.COMMAND, batch.COMMAND, merge.COMMAND)}
