"""Where a replay is wrong, at a glance: which frames hold still and which move (by the
command), the worst windows of error and their times, and the frames where the real gripper
is blocked on an object (it stalls short of its command). The sim has no object: in those
frames its gripper is commanded to where the real one stalled (:func:`with_stall`, so that both
leave the object from the same opening), and the frames are left out of the gripper's error."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .logdata import Episode

__all__ = [
    "BLOCKED_GAP",
    "STILL_SPEED",
    "Window",
    "blocked_gripper",
    "stall_episodes",
    "still_frames",
    "with_stall",
    "worst_windows",
]

STILL_SPEED = 2.0
"""A command slower than this (degrees or gripper units per second, over a quarter second)
holds still: the frame is a static hold of that joint."""
BLOCKED_GAP = 5.0
"""A real gripper this far (0–100) from its command while it does not move is blocked."""
BLOCKED_S = 0.3
"""... for at least this long (s)."""
GRIPPER = 5  # the gripper's column in arm order


def _smooth_speed(values: np.ndarray, times: np.ndarray, span_s: float) -> np.ndarray:
    """|d values / dt| per frame (``(n, j)``), the largest over ``±span_s / 2``."""
    if len(times) < 2:
        return np.zeros_like(values)
    v = np.abs(np.gradient(values, times, axis=0))
    period = float(np.median(np.diff(times)))
    half = max(1, round(span_s / 2 / period))
    out = v.copy()
    for k in range(1, half + 1):
        out[k:] = np.maximum(out[k:], v[:-k])
        out[:-k] = np.maximum(out[:-k], v[k:])
    return out


def still_frames(command: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Bool ``(n, j)``: where each joint's command holds still (:data:`STILL_SPEED`)."""
    return _smooth_speed(command, times, 0.25) < STILL_SPEED


def blocked_gripper(command: np.ndarray, measured: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Bool ``(n,)``: frames where the real gripper is blocked (stalled on an object): at least
    :data:`BLOCKED_GAP` from its command and not moving, for :data:`BLOCKED_S` or longer."""
    gap = np.abs(command[:, GRIPPER] - measured[:, GRIPPER]) > BLOCKED_GAP
    still = _smooth_speed(measured[:, [GRIPPER]], times, 0.1)[:, 0] < STILL_SPEED
    stalled = gap & still
    out = np.zeros(len(times), dtype=bool)
    start = None
    for k, s in enumerate([*stalled.tolist(), False]):
        if s and start is None:
            start = k
        elif not s and start is not None:
            if times[k - 1] - times[start] >= BLOCKED_S:
                out[start:k] = True
            start = None
    return out


def with_stall(command: np.ndarray, measured: np.ndarray, times: np.ndarray):
    """``(command, blocked)``: the commands with the gripper's replaced, where the real gripper
    is blocked, by where it stalled; and the blocked frames (bool ``(n,)``)."""
    blocked = blocked_gripper(command, measured, times)
    if not blocked.any():
        return command, blocked
    out = command.copy()
    out[blocked, GRIPPER] = measured[blocked, GRIPPER]
    return out, blocked


def stall_episodes(episodes: list[Episode]) -> tuple[list[Episode], np.ndarray]:
    """The episodes as replayed (a blocked gripper commanded to where it stalled,
    :func:`with_stall`) and, over all their frames, where each joint's error counts (bool
    ``(frames, 6)``: not a blocked gripper)."""
    out, used = [], []
    for e in episodes:
        command, blocked = with_stall(e.command, e.measured, e.times)
        out.append(Episode(e.index, e.times, command, e.measured))
        u = np.ones(e.measured.shape, dtype=bool)
        u[:, GRIPPER] = ~blocked
        used.append(u)
    return out, np.concatenate(used)


@dataclass(frozen=True)
class Window:
    """A stretch of an episode where the sim is furthest from the real arm: ``t0``..``t1`` (s,
    from the episode's start), the body joints' mean absolute error over it (degrees) and the
    joint that was worst in it."""

    episode: int
    t0: float
    t1: float
    mae: float
    joint: str


def worst_windows(
    episodes: list[tuple[int, np.ndarray, np.ndarray]],
    names: tuple[str, ...],
    *,
    length_s: float = 1.0,
    count: int = 3,
) -> list[Window]:
    """The ``count`` worst non-overlapping windows of ``length_s`` over ``episodes`` (each
    ``(index, times, |error| (n, j))``), by the body joints' mean absolute error."""
    found: list[Window] = []
    for index, times, err in episodes:
        period = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
        w = max(1, min(len(times), round(length_s / period)))
        body = err[:, : len(names) - 1].mean(axis=1)
        run = np.convolve(body, np.ones(w) / w, mode="valid")  # mean over each window
        taken = np.zeros(len(run), dtype=bool)
        for _ in range(count):
            cand = np.where(taken, -np.inf, run)
            k = int(np.argmax(cand))
            if not np.isfinite(cand[k]):
                break
            j = int(np.argmax(err[k : k + w, : len(names) - 1].mean(axis=0)))
            found.append(
                Window(index, float(times[k]), float(times[k + w - 1]), float(run[k]), names[j])
            )
            taken[max(0, k - w + 1) : k + w] = True
    found.sort(key=lambda x: -x.mae)
    return found[:count]
