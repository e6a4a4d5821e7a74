"""Every technique's record, in the order the panel, the demo and the documents list them.

Adding a technique: its kernel package, `jobs/NAME.py` with its job and RECORD, one line here,
tests and `docs/techniques/NAME.md` (docs/architecture.md).
"""

from __future__ import annotations

from . import bump, envmap, hybrid, lightmap_uv, normalmap, radiosity, shadowmap, texture, trace
from .record import Technique

TECHNIQUES: tuple[Technique, ...] = (
    lightmap_uv.RECORD, texture.RECORD, trace.RECORD, envmap.RECORD, bump.RECORD,
    shadowmap.RECORD, radiosity.RECORD, hybrid.RECORD, normalmap.RECORD,
)
BY_NAME = {t.name: t for t in TECHNIQUES}
