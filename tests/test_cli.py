"""The command line (the ``teleop`` subcommand)."""

from __future__ import annotations

import threading
from typing import ClassVar

import pytest

from so101sim import cli, teleop
from so101sim.units import JOINT_NAMES


class FakeLeaderBus:
    """A leader held with the shoulder panned by +90° (LeRobot's default calibration)."""

    instances: ClassVar[list[FakeLeaderBus]] = []

    def __init__(self, port, *, calibration=None):
        self.port = port
        self.closed = False
        self.reads = 0
        FakeLeaderBus.instances.append(self)

    def read_positions(self):
        self.reads += 1
        raw = dict.fromkeys(JOINT_NAMES, 2047)
        raw["shoulder_pan"] = 2047 + 1024  # about +90°
        return raw

    def close(self):
        self.closed = True


def test_teleop_mirrors_a_leader_in_real_time(monkeypatch, capsys):
    monkeypatch.setattr(teleop, "FeetechLeaderBus", FakeLeaderBus)
    FakeLeaderBus.instances.clear()
    rc = cli.main(["teleop", "--port", "/dev/ttyFAKE", "--headless", "--duration", "0.3"])
    out = capsys.readouterr().out
    assert rc == 0
    bus = FakeLeaderBus.instances[-1]
    assert bus.port == "/dev/ttyFAKE" and bus.closed
    assert bus.reads >= 2
    assert "no calibration file" in out
    assert "ticks in" in out
    assert not [t for t in threading.enumerate() if t.name.startswith("so101sim-physics")]


def test_teleop_reports_a_bad_calibration_file(tmp_path, capsys):
    bad = tmp_path / "leader.json"
    bad.write_text("{}")
    rc = cli.main(["teleop", "--port", "/dev/ttyFAKE", "--calibration", str(bad)])
    assert rc == 2
    assert "calibration motors do not match" in capsys.readouterr().err


def test_teleop_reports_a_missing_port(capsys):
    rc = cli.main(["teleop", "--port", "/dev/does-not-exist", "--headless", "--duration", "0.1"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "so101sim: error:" in err
    assert "/dev/does-not-exist" in err or "so101sim[leader]" in err


def test_teleop_needs_a_port(capsys):
    with pytest.raises(SystemExit):
        cli.main(["teleop"])
    assert "--port" in capsys.readouterr().err
