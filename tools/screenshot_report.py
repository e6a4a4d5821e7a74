#!/usr/bin/env python3
"""Open an HTML report in headless Chromium, take a screenshot and check it.

    tools/screenshot_report.py out/demo/index.html [--out shot.png] [--size 1280x1600]

Exit status 0 when all of these hold, non-zero otherwise (each failure is printed):
* every local file the page references (img src, a href, link href) exists;
* Chromium starts, loads the file:// URL and writes the screenshot within the time limit;
* the page logged nothing to its console (the report has no script, so any message is a fault);
* the screenshot is a PNG whose pixels are not all the same (it is not blank).

Chromium comes from Debian (`tools/install_chromium.sh`); pass --chromium or set CHROMIUM to use
another binary. Flags: headless, no sandbox (CI runs as root), no GPU, and no background network
traffic (the machine's network is closed: without these Chromium retries connections for long).
Only the standard library is needed; the blank check uses Pillow when it can be imported.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

EXIT_OK = 0
EXIT_FAILED = 1  # the page or the screenshot is wrong
EXIT_NO_CHROMIUM = 3  # no browser to run: nothing was checked
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
    "--enable-logging=stderr",
    "--log-level=0",
)
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def find_chromium(explicit: str | None = None) -> str | None:
    """The Chromium binary to use: `explicit`, $CHROMIUM, or the first known name on PATH."""
    for candidate in (explicit, os.environ.get("CHROMIUM")):
        if candidate:
            return shutil.which(candidate) or (candidate if Path(candidate).is_file() else None)
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


class _References(HTMLParser):
    """Collects the URLs a page loads or links to."""

    def __init__(self) -> None:
        super().__init__()
        self.urls: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for name, value in attrs:
            if value and name in ("src", "href"):
                self.urls.append(value)


def missing_local_files(html_path: Path) -> list[str]:
    """Relative or file: URLs in the page whose file does not exist."""
    parser = _References()
    parser.feed(html_path.read_text(encoding="utf-8"))
    missing = []
    for url in parser.urls:
        parts = urlsplit(url)
        if parts.scheme not in ("", "file") or not parts.path:
            continue  # fragments (#run-1) and other schemes are not files
        path = Path(unquote(parts.path))
        if not path.is_absolute():
            path = html_path.parent / path
        if not path.exists():
            missing.append(url)
    return missing


def console_messages(log: str) -> list[str]:
    """Lines of Chromium's log that carry a message from the page's console."""
    return [line for line in log.splitlines() if ":CONSOLE" in line]


def png_is_blank(png_path: Path) -> tuple[bool, str]:
    """(blank?, description). Without Pillow, only the PNG signature and size are checked."""
    data = png_path.read_bytes()
    if not data.startswith(PNG_SIGNATURE):
        return True, "not a PNG file"
    try:
        from PIL import Image, ImageStat
    except ImportError:
        return False, f"{len(data)} bytes (Pillow missing: pixel variance not checked)"
    with Image.open(png_path) as image:
        stat = ImageStat.Stat(image.convert("RGB"))
        variance = sum(stat.var)
        return variance <= 0.0, f"{image.size[0]}x{image.size[1]}, pixel variance {variance:.1f}"


def screenshot(
    html_path: str | Path,
    png_path: str | Path,
    width: int = 1280,
    height: int = 1600,
    chromium: str | None = None,
    timeout_s: float = 90.0,
) -> int:
    """Take and check the screenshot; return an exit status (0: all checks passed)."""
    html_path = Path(html_path).resolve()
    png_path = Path(png_path).resolve()
    if not html_path.is_file():
        print(f"screenshot_report: {html_path} does not exist", file=sys.stderr)
        return EXIT_FAILED
    binary = find_chromium(chromium)
    if binary is None:
        print("screenshot_report: Chromium not found (run tools/install_chromium.sh)",
              file=sys.stderr)
        return EXIT_NO_CHROMIUM
    failures = [f"missing local file: {url}" for url in missing_local_files(html_path)]
    png_path.parent.mkdir(parents=True, exist_ok=True)
    png_path.unlink(missing_ok=True)
    with tempfile.TemporaryDirectory(prefix="classic-bake-chromium-") as profile:
        command = [
            binary, *CHROMIUM_FLAGS, f"--user-data-dir={profile}",
            f"--window-size={width},{height}", f"--screenshot={png_path}", html_path.as_uri(),
        ]
        try:
            run = subprocess.run(command, capture_output=True, text=True, timeout=timeout_s,
                                 stdin=subprocess.DEVNULL)
        except subprocess.TimeoutExpired:
            print(f"screenshot_report: Chromium took over {timeout_s:.0f} s", file=sys.stderr)
            return EXIT_FAILED
    if run.returncode != 0:
        failures.append(f"Chromium exited with {run.returncode}: {run.stderr.strip()[-2000:]}")
    failures += [f"console: {line}" for line in console_messages(run.stderr)]
    if not png_path.is_file():
        failures.append("no screenshot was written")
    else:
        blank, description = png_is_blank(png_path)
        print(f"screenshot_report: {png_path} ({description})")
        if blank:
            failures.append(f"the screenshot is blank ({description})")
    for failure in failures:
        print(f"screenshot_report: {failure}", file=sys.stderr)
    return EXIT_FAILED if failures else EXIT_OK


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("html", type=Path, help="the report's index.html")
    parser.add_argument("--out", type=Path, default=None,
                        help="screenshot path (default: screenshot.png beside the page)")
    parser.add_argument("--size", default="1280x1600", help="window size WIDTHxHEIGHT, pixels")
    parser.add_argument("--chromium", default=None, help="Chromium binary (default: on PATH)")
    parser.add_argument("--timeout", type=float, default=90.0, help="seconds before giving up")
    args = parser.parse_args(argv)
    try:
        width, height = (int(v) for v in args.size.lower().split("x"))
    except ValueError:
        parser.error(f"--size must be WIDTHxHEIGHT, got {args.size!r}")
    out = args.out or args.html.with_name("screenshot.png")
    return screenshot(args.html, out, width, height, args.chromium, args.timeout)


if __name__ == "__main__":
    sys.exit(main())
