"""The picture of docs/techniques/normalmap.md: the lecture's orange peel and bricks as heights and
as the tangent-space normal maps made from them (OpenGL green), side by side.

    .venv/bin/python tools/normalmap_figure.py [--size 256] [--out docs/images/normalmap.png]

Pure NumPy (kernels/normalmap); written with the project's PNG encoder (pipeline/images.py).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
# Strength of each pattern's map (UV units per unit of height): the sample scene's reliefs, 1 cm
# of height on the orange (3.1 m around: s = 0.01 / 3.1) and on the 4 m brick floor, scaled up
# fourfold so that the tilts read in a small picture.
STRENGTHS = {"orange_peel": 4 * 0.01 / 3.1, "bricks": 4 * 0.01 / 4.0}
GAP = 8  # white texels between the panels


def panels(size: int) -> list[np.ndarray]:
    """[height, normal map] of each pattern as (size, size, 3) uint8."""
    from classic_bake.kernels.normalmap.encode import to_uint8
    from classic_bake.kernels.normalmap.from_height import NormalMapSettings, normal_map, texel_uvs
    from classic_bake.kernels.normalmap.heights import ProceduralHeight

    out = []
    for name, strength in STRENGTHS.items():
        source = ProceduralHeight(name)
        uv = texel_uvs(np.arange(size), np.arange(size), size, size).reshape(-1, 2)
        h = source.heights(uv).reshape(size, size)
        h = (h - h.min()) / max(float(np.ptp(h)), 1e-12)
        out.append(to_uint8(np.repeat(h[..., None], 3, axis=2)))
        made = normal_map(source, NormalMapSettings(size=size, strength=strength))
        out.append(to_uint8(made.rgb))
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256, help="texels per side of each panel")
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "images" / "normalmap.png")
    args = parser.parse_args(argv)
    sys.path.insert(0, str(REPO.parent))
    from classic_bake.pipeline.images import write_png

    row = []
    for k, panel in enumerate(panels(args.size)):
        if k:
            row.append(np.full((args.size, GAP, 3), 255, np.uint8))
        row.append(panel)
    print(write_png(args.out, np.concatenate(row, axis=1)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
