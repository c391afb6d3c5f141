"""A bounded summary of a run's steps for plotting (:class:`Envelope`): per bucket of
consecutive steps, the smallest and largest value of each channel (commanded, measured,
tracking error) of each joint, so a plot of an hour-long run keeps every spike in a few MB.

A run of up to :data:`MAX_BUCKETS` steps is kept step by step (buckets of one step). When the
buckets fill up, neighbours are merged in pairs and each bucket covers twice as many steps; so
at most :data:`MAX_BUCKETS` buckets (plus one unfinished) are held, whatever the run's length.

An :class:`Envelope` is never changed in place where a reader could see it: :meth:`add`
returns the new one, so an interruption (Ctrl-C) in the middle of an update leaves the old one
whole.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

MAX_BUCKETS = 10_000
"""Buckets an :class:`Envelope` holds at most: a plot draws at most twice as many points per
joint and channel (each bucket's minimum and maximum)."""


@dataclass(frozen=True)
class _Bucket:
    """An unfinished bucket: its first and last time, how many steps it holds, and the
    per-channel, per-joint minimum and maximum."""

    t0: float
    t1: float
    count: int
    lo: np.ndarray  # (channels, joints)
    hi: np.ndarray

    def merged(self, t: np.ndarray, v: np.ndarray) -> _Bucket:
        return _Bucket(
            self.t0,
            float(t[-1]),
            self.count + len(t),
            np.minimum(self.lo, v.min(axis=0)),
            np.maximum(self.hi, v.max(axis=0)),
        )


@dataclass(frozen=True)
class Envelope:
    """Buckets of ``width`` steps each: ``t0``/``t1`` (first and last time, shape (cap,)),
    ``lo``/``hi`` (shape (cap, channels, joints)); the first ``n`` rows are in use, and
    ``carry`` is the unfinished bucket after them."""

    t0: np.ndarray
    t1: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    n: int = 0
    width: int = 1
    carry: _Bucket | None = None

    @classmethod
    def empty(cls, channels: int, joints: int, max_buckets: int = MAX_BUCKETS) -> Envelope:
        cap = max(2, max_buckets + max_buckets % 2)  # even: buckets merge in pairs
        return cls(
            np.empty(cap), np.empty(cap), np.empty((cap, channels, joints)),
            np.empty((cap, channels, joints)),
        )  # fmt: skip

    @property
    def steps(self) -> int:
        """Steps summarised."""
        return self.n * self.width + (self.carry.count if self.carry else 0)

    def add(self, times: np.ndarray, values: np.ndarray) -> Envelope:
        """The envelope with the steps at ``times`` (k,) of ``values`` (k, channels, joints)
        added after those it holds (this one is left as it was)."""
        env, i, k = self, 0, len(times)
        while i < k:
            if env.carry is not None:  # fill the unfinished bucket
                take = min(env.width - env.carry.count, k - i)
                carry = env.carry.merged(times[i : i + take], values[i : i + take])
                env, i = replace(env, carry=carry), i + take
                if carry.count == env.width:
                    env = env._room()  # may merge: then the bucket is wider, and unfinished
                    if carry.count == env.width:
                        env = env._append_carry()
                continue
            env = env._room()
            full = min((k - i) // env.width, len(env.t0) - env.n)
            if full == 0:  # fewer steps left than a bucket holds
                t, v = times[i:], values[i:]
                carry = _Bucket(float(t[0]), float(t[-1]), len(t), v.min(axis=0), v.max(axis=0))
                return replace(env, carry=carry)
            env = env._append(times[i : i + full * env.width], values[i : i + full * env.width])
            i += full * env.width
        return env

    def _room(self) -> Envelope:
        """This envelope, or, when every bucket is in use, the one with neighbours merged."""
        if self.n < len(self.t0):
            return self
        half = self.n // 2
        lo, hi = self.lo[: self.n], self.hi[: self.n]
        new = Envelope.empty(self.lo.shape[1], self.lo.shape[2], len(self.t0))
        new.t0[:half] = self.t0[0 : self.n : 2]
        new.t1[:half] = self.t1[1 : self.n : 2]
        new.lo[:half] = np.minimum(lo[0::2], lo[1::2])
        new.hi[:half] = np.maximum(hi[0::2], hi[1::2])
        return replace(new, n=half, width=2 * self.width, carry=self.carry)

    def _append(self, times: np.ndarray, values: np.ndarray) -> Envelope:
        """Append whole buckets (``len(times)`` is a multiple of the width, and they fit).
        Rows past ``n`` belong to no reader, so they are written in place."""
        w, n = self.width, self.n
        m = len(times) // w
        v = values.reshape(m, w, *values.shape[1:])
        self.t0[n : n + m] = times[0::w]
        self.t1[n : n + m] = times[w - 1 :: w]
        self.lo[n : n + m] = v.min(axis=1)
        self.hi[n : n + m] = v.max(axis=1)
        return replace(self, n=n + m)

    def _append_carry(self) -> Envelope:
        c, n = self.carry, self.n
        assert c is not None
        self.t0[n], self.t1[n], self.lo[n], self.hi[n] = c.t0, c.t1, c.lo, c.hi
        return replace(self, n=n + 1, carry=None)

    def points(self) -> tuple[np.ndarray, np.ndarray]:
        """What to draw: ``(times, values)``, values of shape (points, channels, joints).

        Buckets of one step give one point per step; wider buckets give two, the minimum at
        the bucket's first time and the maximum at its last, so the line covers every value.
        """
        t0, t1, lo, hi = self.t0[: self.n], self.t1[: self.n], self.lo[: self.n], self.hi[: self.n]
        if self.carry is not None:
            c = self.carry
            t0, t1 = np.append(t0, c.t0), np.append(t1, c.t1)
            lo, hi = np.concatenate([lo, c.lo[None]]), np.concatenate([hi, c.hi[None]])
        if self.width == 1:
            return t0.copy(), lo.copy()
        times = np.column_stack([t0, t1]).reshape(-1)
        values = np.stack([lo, hi], axis=1).reshape(-1, *lo.shape[1:])
        return times, values
