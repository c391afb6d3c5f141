"""Trajectory profiles: how a move's targets go from its start to its goal, step by step.

Pure planning arithmetic in the arm's units (NumPy arrays in :data:`~so101sim.units.JOINT_NAMES`
order), no MuJoCo state: :class:`~so101sim.sim.simulation.Simulation` plans a move with a profile,
then steps it. It sits below the simulation so that ``Simulation.move_to`` can plan without
importing the motion layer.

A move of T seconds is exactly ``round(T / timestep)`` physics steps. Step i of a move (0-based,
n steps) commands the profile at ``s = (i + 1) / n``: the last step commands the goal itself,
and the first already moves away from the start.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

import numpy as np

from ..errors import SettingError
from ..units import ArmUnits
from ..validation import MAX_DURATION_S, check_duration
from .limited import LimitedProfile

log = logging.getLogger(__name__)

MAX_MOVE_DURATION_S = 3600.0
"""The longest move accepted (an hour): a move's targets are planned whole, 48 bytes a step."""

Profile = Callable[[np.ndarray, np.ndarray, int, float], np.ndarray]
"""``profile(start, target, n_steps, dt) -> (n, 6)`` targets in arm units (n may differ from
``n_steps`` if the profile must stretch the move)."""


def steps_for(
    duration: float, timestep: float, *, maximum: float = MAX_DURATION_S, what: str = "duration"
) -> int:
    """Physics steps in ``duration`` seconds: ``round(duration / timestep)``, at least 1.
    ``duration`` is checked first (> 0, at most ``maximum`` seconds, a day by default; the
    error names it ``what``)."""
    return step_count(check_duration(duration, what, maximum=maximum), timestep)


def step_count(duration: float, timestep: float) -> int:
    """Physics steps in a ``duration`` already checked (by :func:`steps_for`, once: the
    planner passes its count on): ``round(duration / timestep)``, at least 1."""
    n = round(duration / timestep)
    if n == 0:
        log.warning(
            "duration %g s is shorter than half a physics step (%g s); it takes one step",
            duration,
            timestep,
        )
    return max(1, n)


LONG_DURATION_S = 600.0
"""A move or hold longer than this (10 min) gets a warning: likely milliseconds meant."""


def duration_warning(duration: float, what: str = "duration") -> str | None:
    """A sentence if ``duration`` (seconds) is long enough to be a unit mistake, else None."""
    if duration > LONG_DURATION_S:
        return (
            f"{what} = {duration:g} s is over {LONG_DURATION_S / 60:g} minutes of simulated "
            f"time; did you mean milliseconds ({duration:g} ms = {duration / 1000:g} s)?"
        )
    return None


def _shape(fn: Callable[[np.ndarray], np.ndarray]) -> Profile:
    def profile(start: np.ndarray, target: np.ndarray, n: int, dt: float) -> np.ndarray:
        s = fn(np.arange(1, n + 1) / n)[:, None]
        out = start + (target - start) * s
        out[-1] = target  # exact, whatever the rounding of the shape function
        return out

    profile.__doc__ = fn.__doc__
    return profile


def _linear(s: np.ndarray) -> np.ndarray:
    """Straight-line interpolation at constant speed (the lab's profile)."""
    return s


def _minimum_jerk(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk polynomial 10s³ − 15s⁴ + 6s⁵: zero velocity and acceleration at both ends."""
    return s**3 * (10.0 - 15.0 * s + 6.0 * s**2)


SHAPES: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "linear": _linear,
    "minimum_jerk": _minimum_jerk,
}
"""The profiles that are a shape ``s(t)`` from 0 to 1 (the same for every joint): those a
straight-line move of the tip can follow."""


def fractions(profile: str | Profile, n: int) -> np.ndarray:
    """How far along a move each of its ``n`` steps is (0..1, the last exactly 1), for a
    profile of :data:`SHAPES`: what a straight-line tip move follows.

    Raises:
        SettingError: the profile is not one of :data:`SHAPES` (``limited`` plans joint by
            joint, which a straight line of the tip cannot follow).
    """
    shape = SHAPES.get(profile) if isinstance(profile, str) else None
    if shape is None:
        raise SettingError(
            f"profile {profile!r} cannot drive a straight-line tip move; expected one of "
            f"{', '.join(SHAPES)} (or path='joint' to use {profile!r} in joint space)"
        )
    s = shape(np.arange(1, n + 1) / n)
    s[-1] = 1.0
    return s


PROFILES: dict[str, Profile] = {
    "linear": _shape(_linear),
    "minimum_jerk": _shape(_minimum_jerk),
    "limited": LimitedProfile(),
}
"""Profile name -> function. ``limited``: time-optimal under the STS3215's velocity,
acceleration and jerk limits (:mod:`so101sim.sim.limited`), for the shipped model's units."""


def get_profile(name: str | Profile, units: ArmUnits | None = None) -> Profile:
    """The profile called ``name`` (a profile function is returned as is); raises
    SettingError listing the valid names. With ``units`` (a model's own), ``"limited"``
    converts its limits with those units."""
    if callable(name):
        return name
    try:
        profile = PROFILES[name]
    except (KeyError, TypeError):
        raise SettingError(
            f"unknown profile {name!r}; valid profiles are {', '.join(sorted(PROFILES))}"
        ) from None
    if units is not None and isinstance(profile, LimitedProfile):
        return LimitedProfile(profile.limits, strict=profile.strict, units=units)
    return profile


def plan(start: np.ndarray, goal: np.ndarray, n: int, dt: float, profile: Profile) -> np.ndarray:
    """Run ``profile`` and check what it returns: an ``(m, 6)`` array of finite targets.

    Raises:
        SettingError: a custom profile returned something else.
    """
    try:
        out = np.asarray(profile(start, goal, n, dt), dtype=float)
    except (TypeError, ValueError, IndexError) as exc:
        raise SettingError(
            f"profile {getattr(profile, '__name__', profile)!r} failed ({exc}); expected a "
            "function profile(start, target, n_steps, dt) returning an (n, 6) array"
        ) from exc
    if out.ndim != 2 or out.shape[1] != len(start) or len(out) < 1 or not np.isfinite(out).all():
        raise SettingError(
            f"profile {getattr(profile, '__name__', profile)!r} returned an array of shape "
            f"{out.shape}; expected (n, {len(start)}) finite targets in the arm's units"
        )
    return out
