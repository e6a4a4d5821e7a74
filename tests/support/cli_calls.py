"""The command line called in the test's own process.

`refusal(capfd, *args)` runs `python -m classic_bake ARGS` through `pipeline.cli.main` and returns
what a finished subprocess would: (returncode, stdout, stderr), read at the file descriptors
(pytest's `capfd`), so Blender's own C-level output is seen too. For runs refused before any work
(bad flags, paths, budgets, cameras): a subprocess's start-up is most of their cost, and an
exception past `main` (a traceback) fails the test all the same. Runs that bake stay in a
subprocess, where leaked warnings and signals are what a user sees.
"""

import subprocess


def refusal(capfd, *args) -> subprocess.CompletedProcess:
    from classic_bake.pipeline.cli import main

    capfd.readouterr()
    try:
        code = main([str(a) for a in args])
    except SystemExit as exc:  # argparse (or a command) exiting past main
        code = exc.code
    out, err = capfd.readouterr()
    return subprocess.CompletedProcess(list(args), code, out, err)
