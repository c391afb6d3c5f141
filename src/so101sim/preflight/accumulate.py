"""The robust preflight's figures, block by block: per step of the motion and joint, what the
single check (:mod:`so101sim.preflight.measure`) measures, reduced from each block of a
variant's rollout (:mod:`so101sim.preflight.rollout`) as it comes, so memory stays flat
however long the motion.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..units import JOINT_NAMES, ArmUnits
from .measure import Contact, JointCheck, StepCheck


class Accumulator:
    """Per step of the motion and joint, the single check's figures, block by block."""

    def __init__(self, n: int, units: ArmUnits) -> None:
        lo, hi = units.limits
        self.lo, self.hi = lo, hi
        self.to_lower = np.full((n, 6), np.inf)
        self.to_upper = np.full((n, 6), np.inf)
        self.peak = np.zeros((n, 6))
        self.longest = np.zeros((n, 6), dtype=int)
        self.sat_end = np.zeros((n, 6))
        self.track = np.zeros((n, 6))
        self.track_at = np.zeros((n, 6))
        self.contact_t = np.full(n, np.nan)
        self.depth = np.zeros(n)
        self.ends = np.zeros(n)
        self.starts = np.zeros(n)
        self.run = np.zeros(6, dtype=int)
        self.seen_force = np.zeros((n, 6), dtype=bool)  # the step has seen a sample
        self.seen_motion = np.zeros((n, 6), dtype=bool)

    def begin(self, j: int, start: np.ndarray) -> None:
        """Step ``j`` starts from the commanded target ``start`` (counts for its margin)."""
        self.to_lower[j] = start - self.lo
        self.to_upper[j] = self.hi - start

    def add_forces(self, j: int, t, effort, runs, found, dist) -> None:
        """What the single check's step recorder sees in step ``j``: effort, run lengths of
        saturation, contact count and smallest distance at the times ``t``."""
        new = ~self.seen_force[j]
        self.peak[j] = np.maximum(self.peak[j], effort.max(axis=0))
        k = runs.argmax(axis=0)
        best = runs[k, range(6)]
        better = (best > self.longest[j]) | new
        self.longest[j] = np.where(better, best, self.longest[j])
        self.sat_end[j] = np.where(better, t[k], self.sat_end[j])
        self.seen_force[j] = True
        touching = found > 0
        if touching.any():
            if np.isnan(self.contact_t[j]):
                self.contact_t[j] = t[touching.argmax()]
            self.depth[j] = max(self.depth[j], float(-dist[touching].min()))

    def add_motion(self, j: int, t, cmd, meas) -> None:
        """Step ``j``'s commanded and measured poses (arm units) at the times ``t``."""
        for rows in (cmd, meas):
            self.to_lower[j] = np.minimum(self.to_lower[j], (rows - self.lo).min(axis=0))
            self.to_upper[j] = np.minimum(self.to_upper[j], (self.hi - rows).min(axis=0))
        err = np.abs(cmd - meas)
        k = err.argmax(axis=0)
        best = err[k, range(6)]
        better = (best > self.track[j]) | ~self.seen_motion[j]
        self.track[j] = np.where(better, best, self.track[j])
        self.track_at[j] = np.where(better, t[k], self.track_at[j])
        self.seen_motion[j] = True
        self.ends[j] = t[-1]

    def steps(
        self, phases: Sequence[str], kinds: Sequence[str], lines: Sequence[int], dt: float
    ) -> tuple[StepCheck, ...]:
        """The figures as the single check's :class:`StepCheck` s (steps named by ``phases``,
        ``kinds`` and ``lines``)."""
        out = []
        for j in range(len(phases)):
            longest = self.longest[j] * dt
            sat_start = np.maximum(self.sat_end[j] - longest, self.starts[j])
            joints = {
                name: JointCheck(
                    limit_margin=float(min(self.to_lower[j, i], self.to_upper[j, i])),
                    limit_side="lower" if self.to_lower[j, i] <= self.to_upper[j, i] else "upper",
                    peak_effort=float(self.peak[j, i]),
                    saturated=float(longest[i]),
                    peak_tracking_error=float(self.track[j, i]),
                    saturation_time=float(sat_start[i]),
                    peak_tracking_time=float(self.track_at[j, i]),
                )
                for i, name in enumerate(JOINT_NAMES)
            }
            contacts = ()
            if not np.isnan(self.contact_t[j]):
                depth = max(0.0, float(self.depth[j]))
                contacts = (Contact("arm", "(see the replay)", float(self.contact_t[j]), depth),)
            out.append(
                StepCheck(
                    index=j + 1,
                    phase=phases[j],
                    kind=kinds[j],
                    line=lines[j],
                    start_time=float(self.starts[j]),
                    end_time=float(self.ends[j]),
                    joints=joints,
                    contacts=contacts,
                )
            )
        return tuple(out)


def run_lengths(above: np.ndarray, carry: np.ndarray) -> np.ndarray:
    """Per sample and column: consecutive True samples up to it, counting ``carry`` True
    samples before the block."""
    idx = np.arange(1, len(above) + 1)[:, None]
    last_false = np.maximum.accumulate(np.where(above, 0, idx), axis=0)
    runs = idx - last_false
    return np.where(last_false == 0, runs + carry, runs)


__all__ = ["Accumulator", "run_lengths"]
