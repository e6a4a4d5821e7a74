"""The command line: `python -m classic_bake COMMAND SCENE.blend [options]`.

The same commands run inside Blender as `blender -b -c classic_bake COMMAND SCENE.blend [options]`
(registered with `bpy.utils.register_cli_command` by the extension). Every scene command:

* opens SCENE.blend with script auto-execution off;
* writes into `--out DIR` (default `out/COMMAND/SCENE`) its outputs, a `metrics.json` (technique,
  settings, seconds per phase and in total, sizes), `result.blend` with `--save-blend`, and, for
  every technique, `render.exr`: the scene camera's view of its result rendered by the kernels,
  linear, at the scene's render resolution unless `--resolution W H` is given;
* exits 2 with one line naming the problem on bad arguments or unreadable input, 130 when
  interrupted, and leaves earlier outputs and the .blend file as they were unless it succeeded.
"""

from __future__ import annotations

import sys

from .commands import COMMANDS
from .outputs import UsageError
from .run import Parser, add_scene_arguments, run_command

PROG = "python -m classic_bake"
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def build_parser():
    parser = Parser(prog=PROG, description="Bake classic mapping and global-shading techniques "
                     "with NumPy kernels, and compare them with Cycles.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    sub.required = True
    for cmd in COMMANDS.values():
        p = sub.add_parser(cmd.name, help=cmd.help, description=cmd.help)
        if cmd.needs_scene:
            add_scene_arguments(p)
        cmd.add_arguments(p)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of `python -m classic_bake`; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        parser = build_parser()
        if not argv or argv[0] in ("-h", "--help"):
            parser.print_help()
            return 0 if argv else EXIT_USAGE
        args = parser.parse_args(argv)
        return run_command(COMMANDS[args.command], args)
    except UsageError as exc:
        print(f"classic_bake: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("classic_bake: interrupted; no outputs were changed", file=sys.stderr)
        return EXIT_INTERRUPTED


def blender_command(argv: list[str]) -> int:
    """`blender -c classic_bake ...`: the same commands inside a running Blender."""
    return main(argv)
