"""The README's figures of the lab motion (`so101sim run --headless`, with the default servos
and with `--arm official`), checked against the runs that produce them (issue 29: each quoted
figure produced by a documented command and held true by a test)."""

from __future__ import annotations

import re
from pathlib import Path

from so101sim.cli import main

README = (Path(__file__).resolve().parents[2] / "README.md").read_text(encoding="utf-8")


def _run(capsys, *extra: str) -> str:
    assert main(["run", "--headless", *extra]) == 0
    return capsys.readouterr().out


def _reached(out: str, phase: int, joint: str) -> float:
    lines = [line for line in out.splitlines() if line.strip().startswith("reached:")]
    return float(re.search(rf"{joint}=(-?[\d.]+)°", lines[phase]).group(1))


def _errors(out: str) -> list[float]:
    return [float(x) for x in re.findall(r"largest tracking error: ([\d.]+)°", out)]


def test_the_readmes_lab_run_figures_are_the_runs(capsys):
    out = _run(capsys)
    first = out.splitlines()[0]
    assert first.startswith("servo model: sts3215 (") and first in README
    block = "\n".join(out.splitlines()[:5])  # the servo model and the first phase, verbatim
    assert block in README
    elbow_end, elbow_hold = _reached(out, 0, "elbow_flex"), _reached(out, 1, "elbow_flex")
    lift_hold = _reached(out, 1, "shoulder_lift")
    quoted = (
        f"the elbow is {elbow_end:.1f}° short of zero, and after the 2 s hold\n"
        f"still {elbow_hold:.1f}° (shoulder_lift {lift_hold:.1f}°)"
    )
    assert quoted in README
    official = _errors(_run(capsys, "--arm", "official"))
    assert f"{official[0]:.2f}°, {official[1]:.2f}° and {official[2]:.2f}°" in README
