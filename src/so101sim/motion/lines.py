"""The text of a motion file: reading it with bounds, its TOML, and where each key of it is.

:mod:`tomllib` reports no line numbers for values, so :class:`KeyLines` scans the TOML text
itself, in one pass that is linear in the text's length, and maps every key path it finds to
the line where it starts: table headers (``[poses]``, ``[poses.x]``, the n-th ``[[steps]]``,
``[steps.move]`` inside the last of them), ``key = value`` lines (dotted keys too), the keys of
inline tables and the elements of arrays (``steps = [{ hold = 1 }, ...]`` gives
``("steps", 1, "hold")``), on one line or several. Strings, multi-line strings and comments are
skipped, so a ``[[steps]]`` written inside a string is not counted. Lines are counted as TOML
counts them: only ``\\n`` (or ``\\r\\n``) ends a line; U+2028, U+0085 and the like do not.

The same pass bounds what :mod:`tomllib` would otherwise recurse on or choke on: data nested
more than :data:`MAX_NESTING` levels deep (arrays, inline tables, tables and dotted keys
together; tomllib raised RecursionError from about 330 levels) and bare values (numbers, dates)
longer than :data:`MAX_TOKEN` characters (Python refuses to convert integers of more than 4300
digits, and error messages quote the value). :attr:`KeyLines.problem` says where.
:func:`load_toml` runs the scan, then tomllib; :func:`read_text_limited` reads a file with
bounds (also the leader's calibration, :mod:`so101sim.robot.calibration`).

The scanner follows TOML's grammar loosely and never raises: where the text is not valid TOML
it skips to the next line (tomllib reports the syntax error). Where a path is not found, the
line of the nearest enclosing key or table is used.
"""

from __future__ import annotations

import bisect
import os
import re
import stat
import tomllib
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


# ---------------------------------------------------------------------------- the scanner
_WS = re.compile(r"[ \t\r]*")
_WS_NL = re.compile(r"(?:[ \t\r\n]|#[^\n]*)*")  # inside arrays: newlines and comments too
_TO_EOL = re.compile(r"[ \t\r]*(?:#[^\n]*)?(?:\n|$)")
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")
_BASIC = re.compile(r'"(?:[^"\\\n]|\\.)*"')
_LITERAL = re.compile(r"'[^'\n]*'")
_ML_BASIC = re.compile(r'"""(?:[^"\\]|\\[\s\S]|"(?!""))*"""(?:"{1,2})?')
_ML_LITERAL = re.compile(r"'''(?:[^']|'(?!''))*'''(?:'{1,2})?")
_DOT = re.compile(r"[ \t]*\.[ \t]*")
_EQUALS = re.compile(r"[ \t]*=")
_BARE_VALUE = r"\d{4}-\d\d-\d\d[ Tt]\d[0-9:.+\-Zz]*|[A-Za-z0-9_+\-.:]+"
_SCALAR = re.compile(rf"{_BASIC.pattern}|{_LITERAL.pattern}|(?P<bare>{_BARE_VALUE})")
_SEPARATOR = re.compile(r"(?:[ \t\r\n]|#[^\n]*)*(,?)(?:[ \t\r\n]|#[^\n]*)*")
_CLOSE = {"[": "]", "{": "}"}


class _Stop(Exception):
    """The text is not TOML the scanner follows here: go on at the next line."""


class KeyLines:
    """Maps key paths (``("steps", 2, "duration")``) to 1-based line numbers, scanning the text
    once. ``problem`` is ``(line, reason)`` where the data nests more than ``max_nesting``
    levels deep or a bare value is longer than :data:`MAX_TOKEN` characters (the scan stops
    there), else None."""

    def __init__(self, text: str, *, max_nesting: int = MAX_NESTING) -> None:
        self.text = text
        self.max_nesting = max_nesting
        self.problem: tuple[int, str] | None = None
        self._newlines = [m.start() for m in re.finditer("\n", text)]
        self._starts: dict[tuple[Any, ...], int] = {}  # path -> position of its first mention
        self._arrays: dict[tuple[Any, ...], int] = {}  # array of tables -> its last index
        self._pos = 0
        self._scan()

    # ------------------------------------------------------------------------ lookups
    def line_at(self, pos: int) -> int:
        """The 1-based line of character ``pos`` (only ``\\n`` ends a line)."""
        return bisect.bisect_left(self._newlines, pos) + 1

    def line(self, path: tuple[Any, ...]) -> int:
        """The line of ``path``, or of its nearest enclosing key or table that was found."""
        for n in range(len(path), 0, -1):
            if path[:n] in self._starts:
                return self.line_at(self._starts[path[:n]])
        return 1

    # ------------------------------------------------------------------------ statements
    def _scan(self) -> None:
        table: tuple[Any, ...] = ()
        n = len(self.text)
        while self.problem is None:
            self._pos = _WS_NL.match(self.text, self._pos).end()
            if self._pos >= n:
                return
            try:
                if self.text[self._pos] == "[":
                    table = self._header()
                else:
                    self._key_value(table)
                self._end_of_line()
            except _Stop:
                end = self.text.find("\n", self._pos)
                self._pos = n if end < 0 else end + 1

    def _header(self) -> tuple[Any, ...]:
        """``[a.b]`` or ``[[a.b]]``: the table's path (with the index of every enclosing array
        of tables, and its own for ``[[...]]``)."""
        double = self.text.startswith("[[", self._pos)
        start = self._pos
        self._pos += 2 if double else 1
        self._pos = _WS.match(self.text, self._pos).end()
        parts = self._key()
        self._pos = _WS.match(self.text, self._pos).end()
        close = "]]" if double else "]"
        if not self.text.startswith(close, self._pos):
            raise _Stop
        self._pos += len(close)
        path: tuple[Any, ...] = ()
        for part in parts[:-1] if double else parts:
            path = (*path, part)
            if path in self._arrays:
                path = (*path, self._arrays[path])
        if double:
            path = (*path, parts[-1])
            index = self._arrays.get(path, -1) + 1
            self._arrays[path] = index
            path = (*path, index)
        self._found(path, start)
        return path

    def _key_value(self, table: tuple[Any, ...]) -> None:
        start = self._pos
        path = (*table, *self._key())
        self._found(path, start)
        m = _EQUALS.match(self.text, self._pos)
        if not m:
            raise _Stop
        self._pos = _WS.match(self.text, m.end()).end()
        self._value(path)

    def _end_of_line(self) -> None:
        m = _TO_EOL.match(self.text, self._pos)
        if not m:
            raise _Stop
        self._pos = m.end()

    # ------------------------------------------------------------------------ pieces
    def _found(self, path: tuple[Any, ...], pos: int) -> None:
        if len(path) > self.max_nesting and self.problem is None:
            self.problem = (
                self.line_at(pos),
                f"the data nests {len(path)} levels deep here; expected at most "
                f"{self.max_nesting} (tables, arrays and dotted keys together)",
            )
            raise _Stop
        for n in range(1, len(path) + 1):  # a table named in a header or dotted key starts here
            self._starts.setdefault(path[:n], pos)

    def _key(self) -> tuple[str, ...]:
        """A key, dotted or not: its parts, unquoted."""
        parts = [self._key_part()]
        while True:
            m = _DOT.match(self.text, self._pos)
            if not m:
                return tuple(parts)
            self._pos = m.end()
            parts.append(self._key_part())
            if len(parts) > self.max_nesting:
                self._found(tuple(parts), self._pos)

    def _key_part(self) -> str:
        for pattern in (_BARE_KEY, _BASIC, _LITERAL):
            m = pattern.match(self.text, self._pos)
            if m:
                self._pos = m.end()
                raw = m.group()
                if raw[0] == '"':
                    return _unescape(raw)
                return raw[1:-1] if raw[0] == "'" else raw
        raise _Stop

    def _value(self, path: tuple[Any, ...]) -> None:
        """A value assigned to ``path``; arrays and inline tables are followed with a stack
        (no recursion), their elements and keys recorded."""
        stack: list[tuple[str, tuple[Any, ...], int]] = []  # (bracket, path, elements so far)
        while True:
            self._pos = (_WS_NL if stack else _WS).match(self.text, self._pos).end()
            bracket = self.text[self._pos : self._pos + 1]
            if bracket in _CLOSE:
                stack.append((bracket, path, 0))
                self._pos += 1
                if not self._closes_at_once(stack):
                    path = self._next_in(stack)
                    continue
            else:
                self._scalar()
            if not stack or self._after_value(stack):
                return
            path = self._next_in(stack)

    def _closes_at_once(self, stack: list[tuple[str, tuple[Any, ...], int]]) -> bool:
        """Just after an opening bracket: True if the container is empty (it is popped)."""
        bracket, path, _ = stack[-1]
        if len(path) >= self.max_nesting:
            self._found((*path, 0), self._pos - 1)  # too deep: stops here
        self._pos = _WS_NL.match(self.text, self._pos).end()
        if self.text.startswith(_CLOSE[bracket], self._pos):
            self._pos += 1
            stack.pop()
            return True
        return False

    def _next_in(self, stack: list[tuple[str, tuple[Any, ...], int]]) -> tuple[Any, ...]:
        """At the start of the next element (array) or key (inline table) of the innermost
        container: its path, recorded."""
        bracket, path, count = stack[-1]
        start = self._pos
        if bracket == "[":  # as deep as the first element, checked by _closes_at_once
            element: tuple[Any, ...] = (*path, count)
            self._starts.setdefault(element, start)
            return element
        element = (*path, *self._key())
        self._found(element, start)
        m = _EQUALS.match(self.text, self._pos)
        if not m:
            raise _Stop
        self._pos = m.end()
        return element

    def _after_value(self, stack: list[tuple[str, tuple[Any, ...], int]]) -> bool:
        """After a value in a container: consume ``,`` and closing brackets. True once the
        outermost container has closed: the ``key = value`` is complete. Stops just before
        the next element or key otherwise."""
        while stack:
            m = _SEPARATOR.match(self.text, self._pos)
            self._pos = m.end()
            bracket, path, count = stack[-1]
            if self.text.startswith(_CLOSE[bracket], self._pos):  # maybe after a last comma
                self._pos += 1
                stack.pop()
            elif m.group(1):
                stack[-1] = (bracket, path, count + 1)
                return False
            else:
                raise _Stop
        return True

    def _scalar(self) -> None:
        """A string (any of TOML's four kinds) or a bare value (number, boolean, date)."""
        text, pos = self.text, self._pos
        pattern = _SCALAR
        if text.startswith('"""', pos) or text.startswith("'''", pos):
            pattern = _ML_BASIC if text[pos] == '"' else _ML_LITERAL
        m = pattern.match(text, pos)
        if not m:
            if pattern is not _SCALAR:  # never closed: the rest of the text is that string
                self._pos = len(text)
            raise _Stop
        if m.lastgroup == "bare" and m.end() - pos > MAX_TOKEN:
            self.problem = (
                self.line_at(pos),
                f"a value {m.end() - pos} characters long; expected a number, true/false or "
                f"a date of at most {MAX_TOKEN} characters",
            )
            raise _Stop
        self._pos = m.end()


def _unescape(quoted: str) -> str:
    """A basic string's value (``"a\\u0041"`` -> ``aA``), as tomllib reads it."""
    if "\\" not in quoted:
        return quoted[1:-1]
    try:
        return str(tomllib.loads(f"k = {quoted}")["k"])
    except tomllib.TOMLDecodeError:
        return quoted[1:-1]


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
