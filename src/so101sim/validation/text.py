"""Text from users that is printed: names (a motion file's step and pose names, a move's
phase) and anything a terminal would act on. Control characters are escaped wherever text is
shown (:func:`escape_controls`: a step named ``"\\u001b[1A\\u001b[2KPASS"`` would rewrite the
verdict line, a newline would break a report's row) and refused in names a file gives
(:func:`check_name`)."""

from __future__ import annotations

import re
from typing import Any

from ..errors import SettingError

_CONTROLS = re.compile(
    "[\x00-\x08\x0b-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]"
)
_CONTROLS_AND_LINES = re.compile(_CONTROLS.pattern[:-1] + "\t\n]")

MAX_NAME_CHARS = 200
"""The longest name (a step's, a pose's) a motion file may give."""


def escape_controls(text: str, *, lines: bool = True) -> str:
    """``text`` with every control character written as an escape (``\\x1b`` → ``\\u001b``):
    the terminal shows what a file or a user wrote and never acts on it. Escaped: C0 and C1
    controls, DEL, and the bidirectional marks and overrides; kept: newline and tab, unless
    ``lines`` is False (a single name, e.g. a step's, stays on its line)."""
    pattern = _CONTROLS if lines else _CONTROLS_AND_LINES
    return pattern.sub(lambda m: f"\\u{ord(m.group()):04x}", text)


def check_name(value: Any, what: str) -> str:
    """``value`` if it is a name that prints on one line: a string of at most
    :data:`MAX_NAME_CHARS` characters with no control character (newline and tab included)
    and no bidirectional mark.

    Raises:
        SettingError: it is not a string, is too long, or holds such a character (named by
            its code and position).
    """
    if not isinstance(value, str):
        raise SettingError(f"{what} must be a string, got {type(value).__name__}")
    if len(value) > MAX_NAME_CHARS:
        raise SettingError(
            f"{what} is {len(value)} characters long; expected at most {MAX_NAME_CHARS}"
        )
    bad = _CONTROLS_AND_LINES.search(value)
    if bad is not None:
        raise SettingError(
            f'{what} "{escape_controls(value, lines=False)}" holds a control character '
            f"(U+{ord(bad.group()):04X} at position {bad.start() + 1}); expected a name on one "
            "line, without control characters"
        )
    return value


__all__ = ["MAX_NAME_CHARS", "check_name", "escape_controls"]
