"""`python -m classic_bake COMMAND SCENE.blend [options]` with the pip `bpy` module."""

import sys

from .pipeline.cli import main

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
