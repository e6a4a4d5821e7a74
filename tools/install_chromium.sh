#!/usr/bin/env bash
# Install Debian's Chromium for the report's browser check (tests/pipeline/test_report_browser.py,
# tools/screenshot_report.py). Best-effort: it installs Chromium when it can (root or passwordless
# sudo, and apt-get), and otherwise prints one line saying why not and exits 0, so that `make test`
# goes on and the browser test skips. Does nothing when a Chromium is already on PATH or $CHROMIUM.
set -uo pipefail

skip() {
    echo "install_chromium: Chromium not installed ($1); the report's browser test will skip"
    exit 0
}

if [ -n "${CHROMIUM:-}" ] && command -v "$CHROMIUM" >/dev/null 2>&1; then
    echo "install_chromium: \$CHROMIUM present ($CHROMIUM)"
    exit 0
fi
for name in chromium chromium-browser google-chrome google-chrome-stable; do
    if command -v "$name" >/dev/null 2>&1; then
        version="$("$name" --version 2>/dev/null || echo 'version unknown')"
        echo "install_chromium: $name present ($version)"
        exit 0
    fi
done

if [ "$(id -u)" -eq 0 ]; then
    as_root=()
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
    as_root=(sudo -n)
else
    skip "this user cannot run apt-get as root"
fi
command -v apt-get >/dev/null 2>&1 || skip "no apt-get here; install it by hand or set CHROMIUM"

echo "install_chromium: installing Debian's chromium"
export DEBIAN_FRONTEND=noninteractive
"${as_root[@]}" apt-get update -qq >/dev/null 2>&1 || skip "apt-get update failed"
"${as_root[@]}" apt-get install -y -qq chromium >/dev/null 2>&1 || skip "apt-get install chromium failed"
chromium --version 2>/dev/null || skip "chromium was installed but does not start"
