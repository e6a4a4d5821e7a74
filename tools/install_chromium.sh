#!/usr/bin/env bash
# Install Debian's Chromium for the report's browser check (tests/kernels/test_report_browser.py,
# tools/screenshot_report.py). Idempotent: does nothing when a Chromium is already on PATH.
# Needs root (CI and the project machines run as root) or passwordless sudo.
set -euo pipefail

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
    echo "install_chromium: Chromium is missing and this user cannot run apt-get as root" >&2
    exit 1
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "install_chromium: no apt-get here; install Chromium by hand or set CHROMIUM" >&2
    exit 1
fi

echo "install_chromium: installing Debian's chromium"
export DEBIAN_FRONTEND=noninteractive
"${as_root[@]}" apt-get update -qq
"${as_root[@]}" apt-get install -y -qq chromium >/dev/null
chromium --version
