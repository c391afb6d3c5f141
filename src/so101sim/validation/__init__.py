"""Checking what comes from a user: numbers (durations, rates, counts, sizes), choices and paths.

One place for "a finite number in this range", so that every check says the same kind of
thing ("what was wrong, what was expected") and every number that sizes an allocation (a
duration that becomes a step count, a frame size, a rate) is bounded before it is used.

Each function returns the value converted (``float`` or ``int``) or raises the error class it
is given, a :class:`~so101sim.errors.SettingError` by default. May import: nothing of so101sim
but the errors (``so101sim.errors``), so any layer may use it. Modules: :mod:`.numbers`
(numbers, counts, choices), :mod:`.paths` (paths to read and write) and :mod:`.text` (names
and printed text: control characters refused or escaped); every name is importable from here.

Paths, one check for each direction, used by every command and function that reads or writes
a file the user names: :func:`check_input_file` (a file to read: the model, a script) and
:func:`check_output_path` (a file to write: videos, plots, logs, the workspace picture). Both
refuse an empty path and names or paths longer than the file system allows (``NAME_MAX`` and
``PATH_MAX`` from ``os.pathconf``) before anything touches the file system, so no ``OSError``
("File name too long") escapes as a traceback.
"""

from .numbers import (
    MAX_DURATION_S,
    MAX_RATE_HZ,
    check_choice,
    check_count,
    check_duration,
    check_positive,
    check_range,
    check_rate,
    is_real,
    shown,
)
from .paths import (
    DEFAULT_NAME_MAX,
    DEFAULT_PATH_MAX,
    STALE_TEMP_S,
    check_input_file,
    check_output_path,
    check_path_length,
    check_path_text,
    checked_path,
    claim_path,
    path_limit,
    remove_stale_temps,
    temp_name,
)
from .text import MAX_NAME_CHARS, check_name, escape_controls

__all__ = [
    "DEFAULT_NAME_MAX",
    "DEFAULT_PATH_MAX",
    "MAX_DURATION_S",
    "MAX_NAME_CHARS",
    "MAX_RATE_HZ",
    "STALE_TEMP_S",
    "check_choice",
    "check_count",
    "check_duration",
    "check_input_file",
    "check_name",
    "check_output_path",
    "check_path_length",
    "check_path_text",
    "check_positive",
    "check_range",
    "check_rate",
    "checked_path",
    "claim_path",
    "escape_controls",
    "is_real",
    "path_limit",
    "remove_stale_temps",
    "shown",
    "temp_name",
]
