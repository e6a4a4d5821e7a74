"""Safe, unique file names made from object and image names: what every output is called.

`safe_name` cleans one name; `NameTable` and `unique_stems` keep names that clean alike apart by a
short stable hash of the original, and never cut an extension.
"""

from __future__ import annotations

import hashlib
import re

# Windows refuses these as file names whatever the extension.
_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(10)),
             *(f"LPT{i}" for i in range(10))}
_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")
MAX_NAME_LENGTH = 120  # leaves room for suffixes under the 255-byte limit of common filesystems


def safe_name(name: str, fallback: str = "unnamed") -> str:
    """A file name made from an object or image name: ASCII letters, digits, '.', '_' and '-' only,
    no leading dots, never empty, never a path, never a reserved device name."""
    cleaned = _UNSAFE.sub("_", name).strip("._") or fallback
    cleaned = cleaned[:MAX_NAME_LENGTH]
    if cleaned.split(".")[0].upper() in _RESERVED:
        cleaned = "_" + cleaned
    return cleaned


HASH_LENGTH = 8  # hex digits of SHA-1: a collision needs ~65k names cleaned to one stem
# An extension is kept whole: up to this many letters or digits after the last dot.
MAX_EXTENSION_LENGTH = 8


def name_hash(name: str) -> str:
    """A short stable hash of an original name (the same on every run and machine)."""
    return hashlib.sha1(name.encode("utf-8", "surrogatepass")).hexdigest()[:HASH_LENGTH]


def split_extension(name: str) -> tuple[str, str]:
    """(stem, ".ext") of a file name; the extension is empty unless it is 1..8 letters or digits."""
    stem, dot, ext = name.rpartition(".")
    if dot and stem and ext.isascii() and ext.isalnum() and len(ext) <= MAX_EXTENSION_LENGTH:
        return stem, "." + ext
    return name, ""


def _stem(original: str, tail: str, tag: str | None) -> str:
    """safe_name(original) cut so that stem + ["-" tag] + tail fits MAX_NAME_LENGTH."""
    room = MAX_NAME_LENGTH - len(tail) - (len(tag) + 1 if tag else 0)
    stem = safe_name(original)[:max(room, 1)]
    # Cleaned again, so that the name is a fixed point of safe_name ("_CON" + tag: "CON-..."),
    # and staging, cleaning it once more, keeps it.
    return safe_name(f"{stem}-{tag}") if tag else stem


class NameTable:
    """Original names -> safe file names, unique (ignoring case) by construction.

    `claim(original, tail)` returns safe_name(original) + tail when cleaning and cutting left the
    name as it was and nobody holds it yet; otherwise the cleaned stem + "-" + name_hash(original)
    + tail (and, in the unlikely event that is held too, a hash of the name with a counter). The
    same original always gets the same file name back."""

    def __init__(self):
        self._given: dict[tuple[str, str], str] = {}
        self._taken: set[str] = set()

    def claim(self, original: str, tail: str = "") -> str:
        key = (original, tail)
        if key in self._given:
            return self._given[key]
        name = _stem(original, tail, None) + tail
        if name != original + tail or name.casefold() in self._taken:
            k = 0
            while True:
                tag = name_hash(original if k == 0 else f"{original}#{k}")
                name = _stem(original, tail, tag) + tail
                if name.casefold() not in self._taken:
                    break
                k += 1
        self._taken.add(name.casefold())
        self._given[key] = name
        return name


def unique_stems(names, reserve: int = 0) -> dict[str, str]:
    """{name: file-name stem} for object or image names: safe, distinct ignoring case, at most
    MAX_NAME_LENGTH - `reserve` characters (room for a suffix such as "_albedo.exr"). Names that
    are already safe keep themselves; they and then the others are claimed in sorted order, so the
    result does not depend on the order given ("Cube" keeps itself beside "cube")."""
    table = NameTable()
    tail = "x" * reserve  # stands for the caller's suffix while cutting
    names = list(dict.fromkeys(names))
    clean = sorted(n for n in names if _stem(n, tail, None) == n)
    out = {n: table.claim(n, tail)[:-reserve or None] for n in clean}
    out.update({n: table.claim(n, tail)[:-reserve or None] for n in sorted(names)
                if n not in out})
    return {n: out[n] for n in names}
