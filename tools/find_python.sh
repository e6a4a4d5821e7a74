#!/usr/bin/env bash
# Print the path of a working CPython of the version asked for (e.g. 3.13), or fail with a line
# that says what to install. A pyenv shim on PATH is not trusted: it fails unless selected.
set -euo pipefail
want=${1:?usage: find_python.sh 3.13}
candidates=()
if command -v pyenv >/dev/null 2>&1; then
  root=$(pyenv root)
  for d in $(ls -d "$root"/versions/"$want"* 2>/dev/null | sort -V -r); do
    candidates+=("$d/bin/python$want")
  done
fi
candidates+=("python$want" "/usr/local/bin/python$want" "/usr/bin/python$want")
for c in "${candidates[@]}"; do
  if "$c" -c "import sys; assert sys.version_info[:2] == tuple(map(int, '$want'.split('.')))" >/dev/null 2>&1; then
    command -v "$c" 2>/dev/null || echo "$c"
    exit 0
  fi
done
echo "find_python.sh: no working CPython $want found (install it, e.g. 'pyenv install $want')" >&2
exit 1
