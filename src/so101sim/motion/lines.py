"""The text of a motion file: reading it with bounds, its TOML, and where each key of it is.

:mod:`tomllib` reads the data but reports no line numbers for values, so :class:`KeyLines`
finds them: one regular expression splits the text into TOML's tokens (the four kinds of
string, comments, brackets, ``=``, ``,``, bare words, newlines), and one loop over them maps
every key path to the line where it starts: table headers (``[poses.x]``, the n-th
``[[steps]]``, ``[steps.move]`` inside the last of them), ``key = value`` lines (dotted keys
too), the keys of inline tables and the elements of arrays (``steps = [{ hold = 1 }, ...]``
gives ``("steps", 1, "hold")``). A ``[[steps]]`` inside a string or a comment is part of one
token, not a table. Lines are counted as TOML counts them: only ``\\n`` ends a line; U+2028,
U+0085 and the like do not. Where a path is not found, the line of the nearest enclosing key or
table is used.

The same pass runs before :mod:`tomllib` and bounds what it would otherwise recurse on or choke
on: data nested more than :data:`MAX_NESTING` levels deep (arrays, inline tables, tables and
dotted keys together; tomllib raised RecursionError from about 330 levels) and bare values
(numbers, dates) longer than :data:`MAX_TOKEN` characters (Python refuses to convert integers
of more than 4300 digits). It never raises on text that is not TOML: tomllib reports that.
:func:`read_text_limited` reads a file with bounds (also the leader's calibration,
:mod:`so101sim.robot.calibration`).
"""

from __future__ import annotations

import bisect
import contextlib
import os
import re
import stat
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import MotionFileError

MAX_FILE_BYTES = 1 << 20
"""The largest motion (or calibration) file read, in bytes (1 MiB; the lab motion is 400 B)."""

MAX_NESTING = 32
"""The deepest nesting of data accepted (``("steps", 0, "move", "elbow_flex")`` is 4 deep)."""

MAX_TOKEN = 100
"""The longest bare value (number, boolean, date) accepted, in characters."""


class UnreadableFileError(OSError):
    """A file :func:`read_text_limited` cannot or will not read; ``str()`` is the reason, to
    put in a message, and ``missing`` is True when there is no such file. Callers turn it into
    their own :class:`~so101sim.errors.So101SimError`."""

    def __init__(self, reason: str, *, missing: bool = False) -> None:
        super().__init__(reason)
        self.missing = missing


def read_text_limited(path: str | Path, max_bytes: int = MAX_FILE_BYTES) -> str:
    """The text of the regular file ``path``, UTF-8 (a leading BOM, as editors on Windows
    write, dropped), read with bounds: only a regular file is opened (not a device such as
    ``/dev/zero``, a pipe or a folder), and at most ``max_bytes + 1`` bytes of it are read.

    Raises:
        UnreadableFileError: there is no such file, it cannot be read, is not a regular file,
            is larger than ``max_bytes``, is not UTF-8 text, or ``path`` holds a NUL.
    """
    try:
        return _read(Path(path), max_bytes).decode("utf-8-sig")
    except FileNotFoundError:
        raise UnreadableFileError("no such file", missing=True) from None
    except UnicodeDecodeError as exc:
        raise UnreadableFileError(
            f"it is not UTF-8 text: {exc.reason} at byte {exc.start}"
        ) from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise UnreadableFileError(reason) from None


def _read(p: Path, max_bytes: int) -> bytes:
    info = p.stat()  # before opening: opening a pipe with no writer would block
    if not stat.S_ISREG(info.st_mode):
        kind = "a folder" if stat.S_ISDIR(info.st_mode) else "a device, pipe or socket"
        raise OSError(f"it is {kind}, not a regular file")
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    with os.fdopen(os.open(p, flags), "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):  # swapped since stat()
            raise OSError("it is not a regular file")
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise OSError(f"it is larger than {max_bytes} bytes, the most read")
    return data


# ---------------------------------------------------------------------------- key lines
_TOKENS = re.compile(
    r'(?P<string>"""(?:[^"\\]|\\[\s\S]|"(?!""))*"""(?:"{1,2})?'  # multi-line basic
    r"|'''(?:[^']|'(?!''))*'''(?:'{1,2})?"  # multi-line literal
    r'|"(?:[^"\\\n]|\\.)*"'  # basic
    r"|'[^'\n]*')"  # literal
    r"|(?P<skip>[ \t\r]+|#[^\n]*)"
    r"|(?P<newline>\n)"
    r"|(?P<bare>[A-Za-z0-9_+\-.:]+)"
    r"|(?P<mark>\[\[|\]\]|[\[\]{}=,.])"
    r"|(?P<other>.)"
)


class _Stop(Exception):
    """The data nests too deep or holds a bare value too long: :attr:`KeyLines.problem`."""


class KeyLines:
    """Maps key paths (``("steps", 2, "duration")``) to 1-based line numbers, from one pass over
    the text's tokens. ``problem`` is ``(line, reason)`` where the data nests more than
    ``max_nesting`` levels deep or a bare value is longer than :data:`MAX_TOKEN` characters
    (the pass stops there), else None."""

    def __init__(self, text: str, *, max_nesting: int = MAX_NESTING) -> None:
        self.max_nesting = max_nesting
        self.problem: tuple[int, str] | None = None
        self._newlines = [m.start() for m in re.finditer("\n", text)]
        self._starts: dict[tuple[Any, ...], int] = {}  # path -> position of its first mention
        with contextlib.suppress(_Stop):
            self._walk(text)

    def line_at(self, pos: int) -> int:
        """The 1-based line of character ``pos`` (only ``\\n`` ends a line)."""
        return bisect.bisect_left(self._newlines, pos) + 1

    def line(self, path: tuple[Any, ...]) -> int:
        """The line of ``path``, or of its nearest enclosing key or table that was found."""
        for n in range(len(path), 0, -1):
            if path[:n] in self._starts:
                return self.line_at(self._starts[path[:n]])
        return 1

    def _found(self, path: tuple[Any, ...], pos: int) -> None:
        if len(path) > self.max_nesting:
            reason = f"the data nests {len(path)} levels deep here; expected at most "
            self._stop(pos, f"{reason}{self.max_nesting} (tables, arrays and dotted keys together)")
        for n in range(1, len(path) + 1):  # a table named in a header or dotted key starts here
            self._starts.setdefault(path[:n], pos)

    def _stop(self, pos: int, reason: str) -> None:
        self.problem = (self.line_at(pos), reason)
        raise _Stop

    def _walk(self, text: str) -> None:
        """One pass over the tokens; ``scan.state`` says what a token may be: ``line`` (a
        statement may start), ``key`` (a key's parts, of a header when ``scan.header`` is "["
        or "[["), ``value``, ``rest`` (up to the end of the line)."""
        scan = _Scan()
        for m in _TOKENS.finditer(text):
            kind, token, pos = m.lastgroup, m.group(), m.start()
            if kind == "skip" or (kind == "newline" and scan.stack):
                continue
            if kind == "newline":
                scan.state = "line"
            elif scan.state == "line" and token in ("[", "[["):
                scan.begin_key(token, pos)
            elif scan.state in ("line", "key"):
                self._key_token(scan, kind or "", token, pos)
            elif scan.state == "value":
                for mark in token if token in ("[[", "]]") else (token,):
                    self._value_mark(scan, kind or "", mark, pos)
                    if not scan.stack and scan.state == "value":
                        scan.state = "rest"

    def _key_token(self, scan: _Scan, kind: str, token: str, pos: int) -> None:
        """A token of a key (a statement's, a header's or an inline table's)."""
        if scan.state == "line":
            scan.begin_key("", pos)
        if kind in ("bare", "string"):
            scan.key += [p for p in token.split(".") if p] if kind == "bare" else [_key(token)]
            if len(scan.key) > self.max_nesting:
                self._found(tuple(scan.key), pos)
        elif token == "=" and not scan.header:
            scan.value = (*(scan.stack[-1][1] if scan.stack else scan.table), *scan.key)
            self._found(scan.value, scan.key_at)
            scan.state = "value"
        elif token in ("]", "]]") and scan.header:
            scan.table = _table_path(scan.key, scan.header == "[[", scan.arrays)
            self._found(scan.table, scan.key_at)
            scan.state = "rest"
        elif token == "}" and scan.stack:  # an empty inline table
            scan.stack.pop()
            scan.state = "value" if scan.stack else "rest"

    def _value_mark(self, scan: _Scan, kind: str, mark: str, pos: int) -> None:
        """A token of a value (a bracket of ``[[``/``]]`` at a time)."""
        if scan.element_next and mark not in ("]", ","):
            scan.value = (*scan.stack[-1][1], scan.stack[-1][2])
            self._found(scan.value, pos)
            scan.element_next = False
        if mark in ("[", "{"):
            if len(scan.value) >= self.max_nesting and mark == "[":
                self._found((*scan.value, 0), pos)  # too deep: stops here
            scan.stack.append([mark, scan.value, 0])
            scan.element_next = mark == "["
            if mark == "{":
                scan.begin_key("", pos)
        elif mark in ("]", "}") and scan.stack:
            scan.stack.pop()
            scan.element_next = False
        elif mark == "," and scan.stack:
            scan.stack[-1][2] += 1
            scan.element_next = scan.stack[-1][0] == "["
            if scan.stack[-1][0] == "{":
                scan.begin_key("", pos)
        elif kind == "bare" and len(mark) > MAX_TOKEN:
            self._stop(
                pos,
                f"a value {len(mark)} characters long; expected a number, true/false or a "
                f"date of at most {MAX_TOKEN} characters",
            )


@dataclass
class _Scan:
    """Where the pass over a file's tokens is: the current table, the arrays of tables seen,
    the open brackets of a value (``[bracket, path, elements]``), the key being read, the path
    of the value being read, and whether the next token starts an array's element."""

    state: str = "line"
    header: str = ""
    key: list[str] = field(default_factory=list)
    key_at: int = 0
    table: tuple[Any, ...] = ()
    arrays: dict[tuple[Any, ...], int] = field(default_factory=dict)
    stack: list[list[Any]] = field(default_factory=list)
    value: tuple[Any, ...] = ()
    element_next: bool = False

    def begin_key(self, header: str, pos: int) -> None:
        self.state, self.header, self.key, self.key_at = "key", header, [], pos


def _key(quoted: str) -> str:
    """A quoted key's value (``"a\\u0041"`` -> ``aA``), as tomllib reads it."""
    if quoted[0] == "'" or "\\" not in quoted:
        return quoted[1:-1]
    try:
        return str(tomllib.loads(f"k = {quoted}")["k"])
    except tomllib.TOMLDecodeError:
        return quoted[1:-1]


def _table_path(parts: list[str], double: bool, arrays: dict[tuple[Any, ...], int]) -> tuple:
    """The path of ``[a.b]`` (``double``: ``[[a.b]]``), with the index of every enclosing array
    of tables, and its own for ``[[...]]``."""
    path: tuple[Any, ...] = ()
    for part in parts[:-1] if double else parts:
        path = (*path, part)
        if path in arrays:
            path = (*path, arrays[path])
    if double and parts:
        path = (*path, parts[-1])
        arrays[path] = arrays.get(path, -1) + 1
        path = (*path, arrays[path])
    return path


# ---------------------------------------------------------------------------- TOML
def load_toml(text: str, path: str) -> tuple[dict[str, Any], KeyLines]:
    """The data of a motion file's ``text`` (read with :mod:`tomllib`) and where its keys are.

    Raises:
        MotionFileError: the text is longer than :data:`MAX_FILE_BYTES` characters, nests too
            deep or holds a bare value too long (checked before tomllib reads it), or is not
            valid TOML; with ``path`` and the line.
    """
    if len(text) > MAX_FILE_BYTES:
        raise MotionFileError(
            path, 0, f"{len(text)} characters is too long; a motion file is at most 1 MiB"
        )
    loc = KeyLines(text)  # before tomllib: it bounds what tomllib would recurse on
    if loc.problem is not None:
        raise MotionFileError(path, *loc.problem)
    try:
        return tomllib.loads(text), loc
    except tomllib.TOMLDecodeError as exc:
        line, reason = toml_error_line(exc, text)
        raise MotionFileError(path, line, f"not valid TOML: {reason}") from None
    except (RecursionError, ValueError) as exc:  # a backstop: the scan should have caught it
        raise MotionFileError(path, 0, f"not a motion file tomllib can read: {exc}") from None


# ---------------------------------------------------------------------------- syntax errors
_TOML_LINE_RE = re.compile(r"\(at line (\d+), column \d+\)")  # tomllib's position


def count_lines(text: str) -> int:
    """The number of lines in ``text`` as TOML counts them (only ``\\n`` ends a line), at least
    1; a last line without its ``\\n`` counts."""
    return max(1, text.count("\n") + (0 if text.endswith("\n") else 1))


def toml_error_line(exc: tomllib.TOMLDecodeError, text: str) -> tuple[int, str]:
    """The line of a TOML syntax error in ``text`` and its reason without the position.

    tomllib writes "(at line L, column C)", or "(at end of document)": then the last line.
    """
    msg = str(exc)
    m = _TOML_LINE_RE.search(msg)
    line = int(m.group(1)) if m else count_lines(text)
    reason = _TOML_LINE_RE.sub("", msg).replace("(at end of document)", "").strip()
    if not m:
        reason += " at the end of the file"
    return line, reason


__all__ = [
    "MAX_FILE_BYTES",
    "MAX_NESTING",
    "MAX_TOKEN",
    "KeyLines",
    "UnreadableFileError",
    "count_lines",
    "load_toml",
    "read_text_limited",
    "toml_error_line",
]
