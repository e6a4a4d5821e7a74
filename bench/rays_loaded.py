"""bench/rays.py on a loaded machine: every contender beside a process that keeps a core busy.

    .venv/bin/python bench/rays_loaded.py [--quick] [any option of bench/rays.py]

Writes out/bench/rays_loaded.json, with the same ratios as rays.json.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from rays import main  # noqa: E402

if __name__ == "__main__":
    raise SystemExit(main([*sys.argv[1:], "--loaded"]))
