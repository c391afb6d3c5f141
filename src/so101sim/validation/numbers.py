"""Checking numbers and choices from a user: a finite number in a range, a duration, a rate, a
count, one of some names. Each function returns the value converted (``float`` or ``int``) or
raises the error class it is given, a :class:`~so101sim.errors.SettingError` by default."""

from __future__ import annotations

import math
import numbers
import reprlib
from collections.abc import Iterable

from ..errors import DurationError, RateError, SettingError

MAX_DURATION_S = 24 * 3600.0
"""The longest duration accepted, in simulated seconds (one day: 43.2 million physics steps at
the shipped model's 2 ms)."""

MAX_RATE_HZ = 10_000.0
"""The highest rate (goals, frames or ticks per second) accepted."""


def is_real(value: object) -> bool:
    """True for a real number (int, float, NumPy scalar) or a 0-d array or tensor holding one
    (NumPy's, or a framework's with ``ndim == 0`` and ``__float__``, as LeRobot sends); False
    for bools, strings and anything else."""
    if isinstance(value, numbers.Real):
        return not isinstance(value, bool)
    if getattr(value, "ndim", None) != 0 or not hasattr(value, "__float__"):
        return False
    dtype = str(getattr(value, "dtype", ""))
    return not any(k in dtype for k in ("bool", "complex", "str", "object"))


def shown(value: object) -> str:
    """``repr(value)`` shortened for a message (a huge int or a long string stays readable)."""
    if isinstance(value, int) and value.bit_length() > 64:
        digits = len(str(value)) if value.bit_length() < 10_000 else "thousands of"
        return f"an integer of {digits} digits"
    return reprlib.repr(value)


def _as_float(value: object, what: str, unit: str, expected: str, error: type[Exception]) -> float:
    if not is_real(value):
        raise error(f"{what} = {shown(value)} is not a number; expected {expected}")
    try:
        v = float(value)  # type: ignore[arg-type]
    except OverflowError:  # an int too big for a float
        raise error(f"{what} = {shown(value)} is too large; expected {expected}") from None
    if not math.isfinite(v):
        raise error(f"{what} = {v}{unit} is not finite; expected {expected}")
    return v


def check_range(
    value: object,
    what: str,
    *,
    low: float = -math.inf,
    high: float = math.inf,
    low_open: bool = False,
    unit: str = "",
    expected: str | None = None,
    error: type[Exception] = SettingError,
) -> float:
    """``value`` as a float if it is a finite number with ``low <= value <= high`` (``low <
    value`` when ``low_open``); else raise ``error`` naming ``what``, the value and the range.

    ``unit`` is appended to numbers in the message (``" s"``, ``" Hz"``); ``expected`` replaces
    the generated description of the valid range.
    """
    if expected is None:
        expected = _describe(low, high, low_open, unit)
    v = _as_float(value, what, unit, expected, error)
    too_low = v <= low if low_open else v < low
    if too_low or v > high:
        raise error(f"{what} = {v}{unit} is invalid; expected {expected}")
    return v


def _describe(low: float, high: float, low_open: bool, unit: str) -> str:
    if math.isinf(low) and math.isinf(high):
        return "a finite number"
    if math.isinf(high):
        return f"a finite number {'>' if low_open else '>='} {low:g}{unit}"
    if math.isinf(low):
        return f"a finite number <= {high:g}{unit}"
    lo = f"> {low:g}{unit}" if low_open else f">= {low:g}{unit}"
    return f"a finite number {lo} and <= {high:g}{unit}"


def check_positive(
    value: object,
    what: str,
    *,
    maximum: float = math.inf,
    unit: str = "",
    allow_zero: bool = False,
    error: type[Exception] = SettingError,
) -> float:
    """A finite number > 0 (>= 0 with ``allow_zero``) and <= ``maximum``."""
    return check_range(
        value, what, low=0.0, high=maximum, low_open=not allow_zero, unit=unit, error=error
    )


def check_duration(
    value: object,
    what: str = "duration",
    *,
    allow_zero: bool = False,
    maximum: float = MAX_DURATION_S,
) -> float:
    """Seconds: a finite number > 0 (>= 0 with ``allow_zero``), at most ``maximum`` (one day
    by default); raises :class:`~so101sim.errors.DurationError`."""
    return check_range(
        value,
        what,
        low=0.0,
        high=maximum,
        low_open=not allow_zero,
        unit=" s",
        expected=(
            f"a finite number of seconds {'>= 0' if allow_zero else '> 0'}, at most {maximum:g} s"
        ),
        error=DurationError,
    )


def check_rate(value: object, what: str = "rate", *, maximum: float = MAX_RATE_HZ) -> float:
    """A rate in Hz: a finite number > 0, at most ``maximum``; raises
    :class:`~so101sim.errors.RateError`."""
    return check_range(
        value,
        what,
        low=0.0,
        high=maximum,
        low_open=True,
        unit=" Hz",
        expected=f"a finite number of times per second > 0, at most {maximum:g}",
        error=RateError,
    )


def check_count(
    value: object,
    what: str,
    *,
    minimum: int = 0,
    maximum: int | None = None,
    even: bool = False,
    unit: str = "",
    expected: str | None = None,
    error: type[Exception] = SettingError,
) -> int:
    """A whole number (int or NumPy integer, not bool) in ``minimum..maximum`` (even if asked).
    ``unit`` names what is counted (``" steps"``); ``expected`` replaces the generated
    description of the valid values."""
    fits = type(value) is int and minimum <= value and (maximum is None or value <= maximum)
    if fits and not (even and value % 2):
        return value  # type: ignore[return-value]  # the common case, no message composed
    if expected is None:
        top = f" and <= {maximum}" if maximum is not None else ""
        what_of = f" of{unit}" if unit else ""
        expected = f"{'an even' if even else 'a'} whole number{what_of} >= {minimum}{top}"
    ok = isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if not ok:
        raise error(f"{what} = {shown(value)} is not a whole number; expected {expected}")
    n = int(value)  # type: ignore[arg-type]
    text = shown(n)
    number = text + unit if text == str(n) else text  # not "an integer of 20 digits pixels"
    if n < minimum or (maximum is not None and n > maximum):
        raise error(f"{what} = {number} is out of range; expected {expected}")
    if even and n % 2:
        raise error(f"{what} = {number} is odd; expected {expected}")
    return n


def check_choice(
    value: object, what: str, choices: Iterable[str], *, error: type[Exception] = SettingError
) -> str:
    """``value`` if it is one of ``choices``, else raise listing them."""
    valid = list(choices)
    if not isinstance(value, str) or value not in valid:
        raise error(f"unknown {what} {shown(value)}; valid {what}s are {', '.join(valid)}")
    return value
