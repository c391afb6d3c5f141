"""Motion files the preflight tests share (one copy: tests/preflight/test_preflight.py and
tests/preflight/test_fast_check.py both drive the arm into the floor)."""

from __future__ import annotations

from pathlib import Path

INTO_FLOOR = """\
shape = "minimum_jerk"
[poses]
down = { shoulder_lift = 45, elbow_flex = 45, wrist_flex = 60 }
[[steps]]
move = "down"
duration = 2.0
[[steps]]
hold = 0.5
"""
"""The gripper tipped down into the floor in front of the arm (contacts: the check fails)."""

TIP_LINE = """\
[[steps]]
move = { tip = [0.22, 0.05, 0.08], pitch = -60 }
duration = 1.0
"""
"""A straight tip line, step 3 after :data:`INTO_FLOOR` (its deviation from the line is
measured)."""


def floor_motion(folder: Path, *, tip_line: bool = False) -> Path:
    """:data:`INTO_FLOOR` (then :data:`TIP_LINE` with ``tip_line``) written to
    ``folder/floor.toml``."""
    path = folder / "floor.toml"
    path.write_text(INTO_FLOOR + (TIP_LINE if tip_line else ""), encoding="utf-8")
    return path
