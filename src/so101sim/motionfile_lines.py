"""Line numbers for motion files: where each key of a TOML text is, and where a syntax error is.

:mod:`tomllib` reports none for values, so the loader scans the text itself for
table headers (``[poses]``, ``[poses.x]``, the n-th ``[[steps]]``), ``key =`` lines (dotted keys
too) and the keys inside single-line inline tables, and maps each key path to its line. Where a
path is not found that way (e.g. a multi-line ``steps = [...]`` array), the error points at the
line of the nearest enclosing key or table that was found.
"""

from __future__ import annotations

import re
import tomllib
from typing import Any

_BARE = r"[A-Za-z0-9_-]+"
_QUOTED = r"\"(?:[^\"\\]|\\.)*\"|'[^']*'"
_KEYPART = rf"(?:{_BARE}|{_QUOTED})"
_DOTTED = rf"{_KEYPART}(?:\s*\.\s*{_KEYPART})*"
_HEADER_RE = re.compile(rf"^\s*(\[\[|\[)\s*({_DOTTED})\s*\]\]?")
_KEY_RE = re.compile(rf"^\s*({_DOTTED})\s*=\s*(.*)$")
_INLINE_KEY_RE = re.compile(rf"({_KEYPART})\s*=")
_PART_RE = re.compile(_KEYPART)


def _split_key(dotted: str) -> tuple[str, ...]:
    parts = []
    for p in _PART_RE.findall(dotted):
        parts.append(p[1:-1] if p[:1] in "\"'" else p)
    return tuple(parts)


class KeyLines:
    """Maps key paths (``("steps", 2, "duration")``) to 1-based line numbers."""

    def __init__(self, text: str) -> None:
        self.lines: dict[tuple[Any, ...], int] = {}
        table: tuple[Any, ...] = ()
        counts: dict[tuple[str, ...], int] = {}
        for number, raw in enumerate(text.splitlines(), start=1):
            m = _HEADER_RE.match(raw)
            if m:
                path = _split_key(m.group(2))
                if m.group(1) == "[[":
                    k = counts.get(path, 0)
                    counts[path] = k + 1
                    table = (*path, k)
                else:
                    table = path
                self.lines.setdefault(table, number)
                continue
            m = _KEY_RE.match(raw)
            if not m:
                continue
            path = (*table, *_split_key(m.group(1)))
            self.lines.setdefault(path, number)
            value = m.group(2)
            if value.lstrip().startswith("{"):
                for inner in _INLINE_KEY_RE.findall(value):
                    self.lines.setdefault((*path, *_split_key(inner)), number)

    def line(self, path: tuple[Any, ...]) -> int:
        for n in range(len(path), 0, -1):
            if path[:n] in self.lines:
                return self.lines[path[:n]]
        return 1


_TOML_LINE_RE = re.compile(r"\(at line (\d+), column \d+\)")  # tomllib's position


def toml_error_line(exc: tomllib.TOMLDecodeError, text: str) -> tuple[int, str]:
    """The line of a TOML syntax error in ``text`` and its reason without the position.

    tomllib writes "(at line L, column C)", or "(at end of document)": then the last line.
    """
    msg = str(exc)
    m = _TOML_LINE_RE.search(msg)
    line = int(m.group(1)) if m else max(1, len(text.splitlines()))
    reason = _TOML_LINE_RE.sub("", msg).replace("(at end of document)", "").strip()
    if not m:
        reason += " at the end of the file"
    return line, reason


__all__ = ["KeyLines", "toml_error_line"]
