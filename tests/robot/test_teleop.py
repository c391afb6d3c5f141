"""Teleoperation from a LeRobot SO-101 leader, tested with fake buses (no serial port)."""

from __future__ import annotations

import json
import math
import os
import sys
import types

import pytest

from so101sim import cli
from so101sim.errors import CalibrationError, DurationError, LeaderError, RateError
from so101sim.model import default_units
from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
from so101sim.robot.teleop import (
    MAX_CALIBRATION_BYTES,
    MOTOR_IDS,
    FeetechLeaderBus,
    MotorCalibration,
    decode_sign_magnitude,
    default_calibration,
    lerobot_calibration_path,
    load_calibration,
    parse_calibration,
    teleoperate,
    ticks_to_pose,
)
from so101sim.units import JOINT_NAMES

# A calibration file as LeRobot writes it (values of a typical SO-101 leader).
LEROBOT_JSON = {
    "shoulder_pan": {
        "id": 1,
        "drive_mode": 0,
        "homing_offset": -1470,
        "range_min": 758,
        "range_max": 3292,
    },
    "shoulder_lift": {
        "id": 2,
        "drive_mode": 0,
        "homing_offset": 157,
        "range_min": 612,
        "range_max": 3401,
    },
    "elbow_flex": {
        "id": 3,
        "drive_mode": 0,
        "homing_offset": -1132,
        "range_min": 904,
        "range_max": 3067,
    },
    "wrist_flex": {
        "id": 4,
        "drive_mode": 0,
        "homing_offset": -1821,
        "range_min": 870,
        "range_max": 3189,
    },
    "wrist_roll": {"id": 5, "drive_mode": 0, "homing_offset": 0, "range_min": 0, "range_max": 4095},
    "gripper": {
        "id": 6,
        "drive_mode": 0,
        "homing_offset": 1407,
        "range_min": 2031,
        "range_max": 3241,
    },
}


def ticks_for(pose: dict[str, float], cal) -> dict[str, int]:
    """The inverse of LeRobot's normalisation (what a leader at ``pose`` reports)."""
    out = {}
    for n, v in pose.items():
        c = cal[n]
        if n == "gripper":
            out[n] = round(c.range_min + v / 100 * (c.range_max - c.range_min))
        else:
            out[n] = round(v * 4095 / 360 + (c.range_min + c.range_max) / 2)
    return out


# ---------------------------------------------------------------------------- mapping
def test_ticks_to_pose_follows_lerobots_formulas():
    cal = parse_calibration(LEROBOT_JSON)
    pan = cal["shoulder_pan"]
    mid = (pan.range_min + pan.range_max) / 2  # 2025
    raw = {"shoulder_pan": mid, "elbow_flex": 1985.5 + 4095 / 4, "gripper": 2031}
    pose = ticks_to_pose(raw, cal)
    assert pose["shoulder_pan"] == 0.0
    assert pose["elbow_flex"] == pytest.approx(90.0)
    assert pose["gripper"] == 0.0
    g = cal["gripper"]
    assert ticks_to_pose({"gripper": g.range_max}, cal)["gripper"] == 100.0
    assert ticks_to_pose({"gripper": (g.range_min + g.range_max) / 2}, cal)["gripper"] == 50.0
    # gripper clamped to its range, body joints not (as LeRobot)
    assert ticks_to_pose({"gripper": 4000}, cal)["gripper"] == 100.0
    assert ticks_to_pose({"gripper": 0}, cal)["gripper"] == 0.0
    assert ticks_to_pose({"shoulder_pan": 4095}, cal)["shoulder_pan"] == pytest.approx(
        (4095 - mid) * 360 / 4095
    )


def test_drive_mode_inverts_the_gripper():
    cal = dict(parse_calibration(LEROBOT_JSON))
    cal["gripper"] = MotorCalibration(6, 1, 0, 1000, 2000)
    assert ticks_to_pose({"gripper": 1250}, cal)["gripper"] == pytest.approx(75.0)


def test_default_calibration_centres_on_2047_and_spans_the_models_gripper_range():
    cal = default_calibration()
    assert [cal[n].id for n in JOINT_NAMES] == [1, 2, 3, 4, 5, 6]
    assert ticks_to_pose({"shoulder_lift": 2047.5}, cal)["shoulder_lift"] == 0.0
    lo, hi = default_units().limits  # gripper in degrees: -10..100 over 0..100
    g_lower = math.degrees(default_units().lower[-1])
    g_upper = math.degrees(default_units().upper[-1])
    ticks_closed = 2047 + g_lower * 4095 / 360
    ticks_open = 2047 + g_upper * 4095 / 360
    assert ticks_to_pose({"gripper": ticks_closed}, cal)["gripper"] == pytest.approx(0, abs=0.1)
    assert ticks_to_pose({"gripper": ticks_open}, cal)["gripper"] == pytest.approx(100, abs=0.1)
    assert (lo[-1], hi[-1]) == (0.0, 100.0)


def test_sign_magnitude_decoding():
    assert decode_sign_magnitude(2047, 15) == 2047
    assert decode_sign_magnitude((1 << 15) | 5, 15) == -5
    assert decode_sign_magnitude((1 << 11) | 1470, 11) == -1470


# ---------------------------------------------------------------------------- calibration files
def test_load_lerobot_calibration_file(tmp_path):
    path = tmp_path / "leader.json"
    path.write_text(json.dumps(LEROBOT_JSON, indent=4))
    cal = load_calibration(path)
    assert cal["gripper"] == MotorCalibration(6, 0, 1407, 2031, 3241)
    assert list(cal) == list(JOINT_NAMES)


def _without(d: dict, key: str) -> dict:
    return {k: v for k, v in d.items() if k != key}


@pytest.mark.parametrize(
    "data, match",
    [
        ([], "JSON object"),
        (_without(LEROBOT_JSON, "gripper"), "missing"),
        ({**LEROBOT_JSON, "elbow": LEROBOT_JSON["elbow_flex"]}, "unknown"),
        (
            {**LEROBOT_JSON, "gripper": _without(LEROBOT_JSON["gripper"], "range_max")},
            "must hold",
        ),
        ({**LEROBOT_JSON, "gripper": {**LEROBOT_JSON["gripper"], "range_min": 1.5}}, "integer"),
        (
            {**LEROBOT_JSON, "gripper": {**LEROBOT_JSON["gripper"], "range_min": 3241}},
            "range_min < range_max",
        ),
    ],
)
def test_bad_calibrations_are_refused(data, match):
    with pytest.raises(CalibrationError, match=match):
        parse_calibration(data)


def test_unreadable_calibration_files(tmp_path):
    with pytest.raises(CalibrationError, match="cannot read"):
        load_calibration(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(CalibrationError, match="not valid JSON"):
        load_calibration(bad)


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"\x7fELF\x02\x01\x01\x00\xd0\xff\x00", "not UTF-8 text"),  # a program (/bin/ls)
        (b"[" * 30_000 + b"]" * 30_000, "nests too deep"),  # was a RecursionError
        (b"9" * 5000, "cannot be read as JSON"),  # was a ValueError (over 4300 digits)
        (b"{}" + b" " * MAX_CALIBRATION_BYTES, "larger than"),
    ],
)
def test_calibration_files_that_are_not_json_are_calibration_errors(tmp_path, content, match):
    path = tmp_path / "leader.json"
    path.write_bytes(content)
    with pytest.raises(CalibrationError, match=match):
        load_calibration(path)


def test_calibration_from_a_device_or_folder_is_refused_without_reading_it(tmp_path):
    with pytest.raises(CalibrationError, match="not a regular file"):
        load_calibration(tmp_path)
    if os.path.exists("/dev/zero"):  # was read until memory ran out
        with pytest.raises(CalibrationError, match="not a regular file"):
            load_calibration("/dev/zero")


def test_cli_teleop_reports_a_binary_calibration_file(tmp_path, capsys):
    path = tmp_path / "ls"
    path.write_bytes(b"\x7fELF\x02\x01\x01\x00\xd0\xff" * 100)
    # `so101sim teleop --calibration /bin/ls` raised UnicodeDecodeError; the port is not opened
    assert cli.main(["teleop", "--port", "/dev/nonexistent", "--calibration", str(path)]) == 2
    err = capsys.readouterr().err
    assert "not UTF-8 text" in err and "Traceback" not in err


def test_lerobot_calibration_path_honours_lerobots_variables(monkeypatch, tmp_path):
    monkeypatch.delenv("HF_LEROBOT_CALIBRATION", raising=False)
    monkeypatch.delenv("HF_LEROBOT_HOME", raising=False)
    monkeypatch.setenv("HF_HOME", str(tmp_path))
    expected = tmp_path / "lerobot" / "calibration" / "teleoperators" / "so_leader" / "x.json"
    assert lerobot_calibration_path("x") == expected
    monkeypatch.setenv("HF_LEROBOT_CALIBRATION", str(tmp_path / "cal"))
    assert lerobot_calibration_path("x") == tmp_path / "cal" / "teleoperators/so_leader/x.json"


# ---------------------------------------------------------------------------- the loop
class FakeLeaderBus:
    """Replays leader poses (raw ticks), one per read."""

    def __init__(self, frames: list[dict[str, int]]) -> None:
        self.frames = frames
        self.reads = 0
        self.closed = False

    def read_positions(self) -> dict[str, int]:
        frame = self.frames[min(self.reads, len(self.frames) - 1)]
        self.reads += 1
        return dict(frame)

    def close(self) -> None:
        self.closed = True


def test_teleoperation_mirrors_the_leader_on_the_lockstep_sim():
    cal = parse_calibration(LEROBOT_JSON)
    target = {
        "shoulder_pan": 25.0,
        "shoulder_lift": -20.0,
        "elbow_flex": 30.0,
        "wrist_flex": 10.0,
        "wrist_roll": -40.0,
        "gripper": 60.0,
    }
    start = {n: 0.0 for n in JOINT_NAMES}
    # the leader moves from zeros to the target over 30 frames, then stays
    frames = [
        ticks_for({n: start[n] + (target[n] - start[n]) * i / 30 for n in JOINT_NAMES}, cal)
        for i in range(1, 31)
    ]
    bus = FakeLeaderBus(frames)
    robot = SO101SimFollower(
        SO101SimFollowerConfig(
            mode="lockstep", lockstep_action_seconds=0.0, initial_pose=dict(start)
        )
    )
    with robot:
        result = teleoperate(robot, bus, cal, fps=60, duration=1.0)
        obs = robot.get_observation()
        elapsed = robot.time
    assert result.ticks == 60 == bus.reads
    assert result.late_ticks == 0
    assert elapsed == pytest.approx(1.0, abs=0.002)  # 60 ticks at 60 Hz of simulated time
    for n, v in target.items():
        assert abs(result.last_action[f"{n}.pos"] - v) < 0.1, n  # tick rounding only
        assert abs(obs[f"{n}.pos"] - v) < 4.0, n  # the default servo's sag (3.2° here)


def test_teleoperation_clips_the_leader_to_the_followers_limits(caplog):
    cal = default_calibration()
    bus = FakeLeaderBus([{n: 4095 for n in JOINT_NAMES}])  # every joint at its far end
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    _, hi = default_units().limits
    with robot, caplog.at_level("WARNING"):
        result = teleoperate(robot, bus, cal, max_ticks=3)
    assert result.ticks == 3
    assert [result.last_action[f"{n}.pos"] for n in JOINT_NAMES] == pytest.approx(list(hi))
    assert "clipped" not in caplog.text  # clipped by the loop, quietly


def test_teleoperation_stops_on_request_and_counts_late_ticks():
    class SlowClock:
        def __init__(self):
            self.t = 0.0

        def now(self):
            self.t += 0.01  # every reading of the clock costs 10 ms
            return self.t

        def sleep(self, s):
            self.t += s

    bus = FakeLeaderBus([{n: 2047 for n in JOINT_NAMES}])
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    calls = []
    with robot:
        result = teleoperate(
            robot,
            bus,
            fps=200,
            clock=SlowClock(),
            should_stop=lambda: calls.append(1) or len(calls) >= 4,
        )
    assert result.ticks == 4
    assert result.late_ticks == 4  # >= 10 ms of clock reads per tick > 5 ms period


def test_teleoperation_rejects_bad_rates():
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep"))
    bus = FakeLeaderBus([{n: 2047 for n in JOINT_NAMES}])
    with robot:
        with pytest.raises(RateError):
            teleoperate(robot, bus, fps=0)
        with pytest.raises(DurationError):
            teleoperate(robot, bus, duration=-1)
    assert bus.reads == 0


# ---------------------------------------------------------------------------- the Feetech bus
def fake_sdk(*, positions=None, open_ok=True, answering=None, homing=None):
    """A stand-in for ``scservo_sdk`` recording what the bus does."""
    positions = positions or {}
    answering = set(MOTOR_IDS.values()) if answering is None else answering
    log = []

    class PortHandler:
        def __init__(self, port):
            self.port = port

        def openPort(self):
            if not open_ok:
                raise OSError(2, "No such file or directory")
            return True

        def setBaudRate(self, baud):
            log.append(("baud", baud))
            return True

        def closePort(self):
            log.append(("close",))

    class Packet:
        def write1ByteTxRx(self, port, motor_id, addr, value):
            log.append(("write", motor_id, addr, value))
            return (0 if motor_id in answering else -6), 0

        def read2ByteTxRx(self, port, motor_id, addr):
            return (homing or {}).get(motor_id, 0), 0, 0

        def getTxRxResult(self, result):
            return "[TxRxResult] There is no status packet!"

    class GroupSyncRead:
        def __init__(self, port, ph, addr, size):
            self.ids = []
            log.append(("syncread", addr, size))

        def addParam(self, motor_id):
            self.ids.append(motor_id)
            return True

        def txRxPacket(self):
            return 0

        def getData(self, motor_id, addr, size):
            return positions.get(motor_id, 2047)

    sdk = types.SimpleNamespace(
        PortHandler=PortHandler,
        PacketHandler=lambda protocol: Packet(),
        GroupSyncRead=GroupSyncRead,
        COMM_SUCCESS=0,
    )
    return sdk, log


def test_feetech_bus_disables_torque_and_sync_reads_present_position(caplog):
    cal = parse_calibration(LEROBOT_JSON)
    sdk, log = fake_sdk(positions={1: 3000, 6: (1 << 15) | 3}, homing={6: 1407, 1: 5})
    with caplog.at_level("WARNING"):
        bus = FeetechLeaderBus("/dev/ttyFAKE", calibration=cal, sdk=sdk)
    assert ("baud", 1_000_000) in log
    assert ("syncread", 56, 2) in log
    assert [e for e in log if e[0] == "write"] == [("write", i, 40, 0) for i in range(1, 7)]
    raw = bus.read_positions()
    assert raw["shoulder_pan"] == 3000 and raw["gripper"] == -3 and raw["elbow_flex"] == 2047
    assert "homing offset" in caplog.text and "'shoulder_pan'" in caplog.text
    bus.close()
    assert ("close",) in log


def test_feetech_bus_errors():
    sdk, _ = fake_sdk(open_ok=False)
    with pytest.raises(LeaderError, match="cannot open"):
        FeetechLeaderBus("/dev/ttyNONE", sdk=sdk)
    sdk, log = fake_sdk(answering={1, 2, 3, 4, 5})
    with pytest.raises(LeaderError, match="'gripper' \\(id 6\\)"):
        FeetechLeaderBus("/dev/ttyFAKE", sdk=sdk)
    assert ("close",) in log


def test_missing_sdk_says_how_to_install_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "scservo_sdk", None)
    with pytest.raises(LeaderError, match=r"so101sim\[leader\]"):
        FeetechLeaderBus("/dev/ttyACM0")


def test_teleoperation_clips_to_the_limits_of_the_followers_own_model(tmp_path, caplog):
    from so101sim.model import model_dir

    # a copy of the shipped model whose shoulder_pan turns only ±30°
    src = (model_dir() / "so101_new_calib.xml").read_text()
    narrow = src.replace(
        'name="shoulder_pan" type="hinge" range="-1.9198621771937616 1.9198621771937634"',
        'name="shoulder_pan" type="hinge" range="-0.5235987755982988 0.5235987755982988"',
    )
    assert narrow != src
    (tmp_path / "so101_new_calib.xml").write_text(narrow)
    (tmp_path / "scene.xml").write_text((model_dir() / "scene.xml").read_text())
    (tmp_path / "assets").symlink_to(model_dir() / "assets")
    robot = SO101SimFollower(SO101SimFollowerConfig(mode="lockstep", model=tmp_path / "scene.xml"))
    bus = FakeLeaderBus([{n: 4095 for n in JOINT_NAMES}])
    with robot, caplog.at_level("WARNING"):
        result = teleoperate(robot, bus, default_calibration(), max_ticks=3)
    assert result.last_action["shoulder_pan.pos"] == pytest.approx(30.0, abs=1e-3)
    assert "clipped" not in caplog.text  # the loop clipped to the right limits, quietly
