#!/usr/bin/env bash
# make_venv.sh PYVER VENV REQUIREMENTS... : create VENV with CPython PYVER, install the pinned
# requirements, and link this repository into site-packages as the package `classic_bake`
# (the repository root is the extension package; its folder name does not matter).
set -euo pipefail
pyver=$1; venv=$2; shift 2
repo=$(cd "$(dirname "$0")/.." && pwd)
python=$("$repo/tools/find_python.sh" "$pyver")
if [ ! -x "$venv/bin/python" ]; then
  "$python" -m venv "$venv"
  "$venv/bin/python" -m pip install -q --upgrade pip
fi
reqs=()
for r in "$@"; do reqs+=(-r "$r"); done
"$venv/bin/python" -m pip install -q "${reqs[@]}"
site=$("$venv/bin/python" -c "import sysconfig; print(sysconfig.get_paths()['purelib'])")
ln -sfn "$repo" "$site/classic_bake"
touch "$venv/.stamp"
