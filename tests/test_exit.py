"""A clean exit with threads (issue 23): a daemon thread calling a lockstep robot's
``send_action`` in a loop crashed the interpreter at exit (exit 139, 10 runs of 10), also after
``disconnect()``; so did a daemon thread stepping a Simulation or an environment. No MuJoCo
call of so101sim may still be running when the interpreter finalises (so101sim.exitgate)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
import threading

import pytest

from so101sim.errors import ClosedError
from so101sim.exitgate import ExitGate

# Each program is (setup, run): the setup (making the robot, simulation or environment: the
# slow part, a model load) runs once in the parent; each child runs ``run`` on what the setup
# made, then ends. ``run`` starts a daemon thread that calls MuJoCo in a loop and waits for its
# first call (an event, not a sleep): the child then exits with the thread in the loop.
PROGRAMS = {
    "robot": (
        """
        import sys, threading
        from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig
        mode, disconnect = sys.argv[1], sys.argv[2] == "1"
        robot = SO101SimFollower(SO101SimFollowerConfig(id="x", mode=mode))
        """,
        """
        robot.connect()  # in the child: a real-time robot's physics thread starts here
        called = threading.Event()
        def loop():
            while True:
                try:
                    robot.send_action({"elbow_flex.pos": 5.0})
                    robot.get_observation()
                    called.set()
                except Exception:
                    pass
        threading.Thread(target=loop, daemon=True).start()
        assert called.wait(60), "the thread never sent an action"
        if disconnect:
            robot.disconnect()
        """,
    ),
    "simulation": (
        """
        import threading
        from so101sim import Simulation, ZERO_POSE
        sim = Simulation()
        """,
        """
        called = threading.Event()
        def loop():
            while True:
                try:
                    sim.move_to(ZERO_POSE, 0.5)
                    sim.reset()
                    called.set()
                except Exception:
                    pass
        threading.Thread(target=loop, daemon=True).start()
        assert called.wait(60), "the thread never stepped"
        """,
    ),
    "environment": (
        """
        import threading
        import gymnasium as gym, so101sim.envs
        env = gym.make("so101sim/PickCube-v0")
        env.reset(seed=0)
        """,
        """
        called = threading.Event()
        def loop():
            while True:
                try:
                    env.step(env.action_space.sample())
                    called.set()
                except Exception:
                    pass
        threading.Thread(target=loop, daemon=True).start()
        assert called.wait(60), "the thread never stepped"
        """,
    ),
}


# Each exit is a child forked from a process that has imported so101sim, MuJoCo and
# Gymnasium and run the program's setup already (a few ms a child instead of a second): the
# child runs the program and then ends as any program does, through the interpreter's
# finalisation; the parent collects the exit codes (-11: killed by SIGSEGV).
DRIVER = """
import gc, json, os, sys
import gymnasium, mujoco, so101sim.envs, so101sim.robot
setup, program, runs = sys.argv[1], sys.argv[2], int(sys.argv[3])
sys.argv = [sys.argv[0], *sys.argv[4:]]
exec(compile(setup, "<setup>", "exec"))
gc.freeze()  # the children never walk the parent's heap: their exit takes 0.1 s, not 1 s
codes = []
for _ in range(runs):
    pid = os.fork()
    if pid == 0:
        sys.stdout.flush()
        exec(compile(program, "<program>", "exec"))
        break  # the child ends here, as the program would
    codes.append(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))
else:
    print(json.dumps(codes))
"""


def _exit_codes(program: str, args: list[str], runs: int) -> list[int]:
    setup, run = (textwrap.dedent(part) for part in PROGRAMS[program])
    proc = subprocess.run(
        [sys.executable, "-c", DRIVER, setup, run, str(runs), *args],
        capture_output=True,
        text=True,
        timeout=600,
        env=os.environ.copy(),
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_50_exits_with_a_thread_sending_actions_never_crash(mode: str) -> None:
    codes = _exit_codes("robot", [mode, "0"], 50)
    assert codes == [0] * 50, f"exit codes: {sorted(set(codes))}"


@pytest.mark.slow
@pytest.mark.parametrize("mode", ["lockstep", "realtime"])
def test_exits_after_disconnect_with_a_thread_sending_actions_never_crash(mode: str) -> None:
    codes = _exit_codes("robot", [mode, "1"], 10)
    assert codes == [0] * 10, f"exit codes: {sorted(set(codes))}"


@pytest.mark.slow
@pytest.mark.parametrize("program", ["simulation", "environment"])
def test_exits_with_a_thread_stepping_never_crash(program: str) -> None:
    codes = _exit_codes(program, [], 10)
    assert codes == [0] * 10, f"exit codes: {sorted(set(codes))}"


def test_the_gate_waits_for_calls_in_flight_and_refuses_later_ones() -> None:
    gate = ExitGate()
    entered, release, order = threading.Event(), threading.Event(), []

    def work() -> None:
        with gate.call():
            entered.set()
            release.wait(5)
            order.append("call ended")

    t = threading.Thread(target=work)
    t.start()
    entered.wait(5)
    assert gate.active == 1
    threading.Timer(0.1, release.set).start()
    assert gate.close(timeout=5)
    order.append("closed")
    assert order == ["call ended", "closed"]
    with pytest.raises(ClosedError, match="shutting down"), gate.call():
        pass
    t.join()


def test_a_closed_gate_refuses_a_lockstep_robot_without_touching_it() -> None:
    from so101sim import exitgate
    from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig

    robot = SO101SimFollower(SO101SimFollowerConfig(id="gate", mode="lockstep"))
    robot.connect()
    try:
        t0 = robot.time
        exitgate.GATE.close(timeout=1)
        try:
            with pytest.raises(ClosedError):
                robot.send_action({"elbow_flex.pos": 5.0})
            with pytest.raises(ClosedError):
                robot.step(0.1)
        finally:
            exitgate.GATE.reopen()
        assert robot.time == t0
    finally:
        robot.disconnect()


def test_disconnect_waits_for_an_action_in_flight() -> None:
    from so101sim.errors import DeviceNotConnectedError
    from so101sim.robot import SO101SimFollower, SO101SimFollowerConfig

    robot = SO101SimFollower(SO101SimFollowerConfig(id="wait", mode="lockstep"))
    robot.connect()
    stop, errors, sent = threading.Event(), [], []

    def loop() -> None:
        while not stop.is_set():
            try:
                robot.send_action({"elbow_flex.pos": 5.0})
                sent.append(robot.time)
            except DeviceNotConnectedError:
                errors.append(1)
            except Exception as exc:  # pragma: no cover - reported below
                errors.append(exc)

    t = threading.Thread(target=loop)
    t.start()
    while not sent:
        pass
    robot.disconnect()
    with robot.lock:  # nothing steps after disconnect() returned
        t_after = robot.simulation.data.time
    stop.set()
    t.join()
    assert robot.simulation.data.time == t_after
    assert all(e == 1 for e in errors)


def test_a_mirrored_viewer_stops_drawing_once_the_gate_closes() -> None:
    """The viewer's own sync thread (a daemon) makes MuJoCo calls too: refused at exit."""
    import contextlib

    import mujoco

    from so101sim import exitgate
    from so101sim.model import load_model
    from so101sim.viewer import MirroredViewer

    class Handle:
        synced = 0

        def lock(self):
            return contextlib.nullcontext()

        def sync(self):
            Handle.synced += 1

        def close(self):
            pass

    m = load_model()
    source = mujoco.MjData(m)
    viewer = MirroredViewer(Handle(), m, mujoco.MjData(m), source)
    viewer.sync()
    for _ in range(200):
        if viewer.frames:
            break
        threading.Event().wait(0.01)
    assert viewer.frames == 1
    exitgate.GATE.close(timeout=1)
    try:
        viewer.sync()
        viewer._thread.join(5)
        assert not viewer._thread.is_alive()  # it ended instead of calling mj_forward
        assert viewer.frames == 1
    finally:
        exitgate.GATE.reopen()
        viewer.close()
