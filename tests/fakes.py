"""Test doubles shared by several test files."""


class FakeClock:
    """A wall clock whose time passes only when slept (or when a test moves ``t`` by hand).

    Usable as a clock function (``clock()``) or as an object with ``now()``.
    """

    def __init__(self, t: float = 100.0) -> None:
        self.t = t
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.t

    def now(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.t += seconds
