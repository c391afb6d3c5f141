"""Preflight over many arms: run one motion on perturbed models with ``mujoco.rollout`` and
measure each as the single check does.

* **Plan once.** :func:`plan_motion` plans what the motion commands at every physics step
  (:func:`~so101sim.motion.plan.plan_segments`, which knows where each step of the motion
  ends). Every variant gets the same targets, shifted by its zero offsets.
* **Measure from the rollout.** A copy of the model gets sensors at load time (``MjSpec``; the
  vendored files stay unchanged, physics bit for bit the same: sensors only read): one
  ``actuatorfrc`` per arm actuator (the force that acted during the step, as the single check
  reads ``data.actuator_force``) and one ``contact`` sensor matching every contact (how many,
  and the smallest distance). The rollout's states give ``qpos``; so every figure of the
  single check comes out of the rollout's outputs, except the names of the bodies that
  touched: :func:`name_contacts` replays one variant step by step to name them (only the
  variants a report shows).
* **All cores.** One Python thread per core, each with its own model copy and ``MjData``
  (the stepping kernel, :func:`~so101sim.sim.stepping.step_block`, keeps a
  ``Rollout(nthread=0)`` per thread: it steps on the calling thread and lets go of the GIL,
  and checks every block for divergence), takes the
  next variant, writes it into its model
  (:func:`~so101sim.preflight.variants.apply_variant`) and rolls
  it out in blocks of at most :data:`BLOCK` steps, reducing each block at once (memory stays
  flat however long the motion). A variant's result depends only on the variant, never on
  the thread that ran it.

The figures are then judged by :func:`so101sim.preflight.judge.judge`, the single check's own.

The block-by-block reduction, figure for figure the single check's
(:mod:`so101sim.preflight.measure`), is :mod:`so101sim.preflight.accumulate`.
"""

from __future__ import annotations

import contextlib
import copy
import logging
import math
import signal
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ..errors import ModelError
from ..exitgate import mujoco_call
from ..model.arm import ArmLike, fill_delay_history
from ..model.build import Addition, build, recipe
from ..model.load import arm_index, arm_units
from ..motion.plan import plan_segments
from ..motion.segments import Hold, Segment
from ..sim.limited import ShortMove
from ..sim.simulation import Simulation
from ..sim.stepping import Observer, advance, step_block
from ..units import GRIPPER, JOINT_NAMES, Pose
from .accumulate import Accumulator, run_lengths
from .judge import Finding, Thresholds, judge
from .measure import Contact, Measurements
from .variants import Variant, apply_variant

log = logging.getLogger(__name__)

BLOCK = 4096
"""Steps rolled out per call: at most this many states per variant are held at once."""

CONTACT_SENSOR = "so101sim_preflight_contact"
_SENSOR_CACHE_KEY = "preflight-sensors-1"
_ADVICE = (
    "Expected stable physics: this variant's perturbations make the arm unstable; narrow the "
    "variants' ranges"
)
_FULL = mujoco.mjtState.mjSTATE_FULLPHYSICS


@dataclass(frozen=True)
class MotionPlan:
    """What a motion commands, planned once for every variant."""

    phases: tuple[str, ...]
    kinds: tuple[str, ...]  # "move" | "hold"
    lines: tuple[int, ...]
    targets: np.ndarray  # (n, 6) radians, one row per physics step
    bounds: np.ndarray  # (steps + 1,) sample index where each step of the motion starts
    start: np.ndarray  # (6,) radians: the start pose, at rest
    stretched: tuple[ShortMove, ...]


def plan_motion(
    model: mujoco.MjModel,
    steps: Sequence[Segment],
    start: Pose,
    *,
    lines: Sequence[int] = (),
    strict: bool = False,
) -> MotionPlan:
    """Plan ``steps`` from ``start`` (checked as the single check checks them)."""
    sim = Simulation(model, initial_pose=start)
    units = sim.units
    # once, every segment checked (with ``strict``, a limited move too short refused)
    planned = plan_segments(model, steps, sim.commanded_array(), strict=strict)
    rows = [np.asarray(p.targets) for p in planned.segments]
    sizes = [len(r) for r in rows]
    return MotionPlan(
        phases=tuple(s.phase for s in steps),
        kinds=tuple("hold" if isinstance(s, Hold) else "move" for s in steps),
        lines=tuple(int(lines[k]) if k < len(lines) else 0 for k in range(len(steps))),
        targets=units.to_radians(np.vstack(rows)),
        bounds=np.concatenate([[0], np.cumsum(sizes)]).astype(int),
        start=units.to_radians(units.pose_to_array(start)),
        stretched=planned.stretched,
    )


def _add_sensors(spec: mujoco.MjSpec) -> None:
    """The preflight's sensors: the deepest contact, each joint's actuator force."""
    found, dist, mindist = 1 << 0, 1 << 3, 1  # mjtConDataField bits, mjtConReduce
    spec.add_sensor(
        name=CONTACT_SENSOR,
        type=mujoco.mjtSensor.mjSENS_CONTACT,
        intprm=[found | dist, mindist, 1],
    )
    for name in JOINT_NAMES:
        spec.add_sensor(
            name=f"so101sim_preflight_force_{name}",
            type=mujoco.mjtSensor.mjSENS_ACTUATORFRC,
            objtype=mujoco.mjtObj.mjOBJ_ACTUATOR,
            objname=_actuator_name(spec, name),
        )


PREFLIGHT_SENSORS = Addition(_SENSOR_CACHE_KEY, _add_sensors)


def sensor_model(path: str | Path, arm: ArmLike = None) -> mujoco.MjModel:
    """The model at ``path`` with the arm profile ``arm`` (None: the default) and the
    preflight's sensors added: the model builder's (compiled once per content and profile)."""
    return build(recipe(path, arm=arm, additions=(PREFLIGHT_SENSORS,)))


def _actuator_name(spec: mujoco.MjSpec, joint: str) -> str:
    """The name of the actuator driving ``joint`` (named here if it had no name)."""
    for a in spec.actuators:
        if a.target == joint:
            if not a.name:
                a.name = f"so101sim_preflight_{joint}"
            return a.name
    raise ModelError(f"model has no actuator driving the joint {joint!r}")


# ---------------------------------------------------------------------------- one variant
@dataclass(frozen=True)
class VariantOutcome:
    """One variant judged: the verdict, its failures (the judge's findings) and its worst
    figure per check (arm units: degrees, gripper 0–100)."""

    index: int
    passed: bool
    failures: tuple[Finding, ...]
    limit_margin: float  # smallest over the body joints and every step
    peak_effort: float  # largest fraction of the force limit
    saturated: float  # s: longest stretch above max_effort
    tracking_error: float  # largest over the body joints, degrees
    contact_depth: float  # m: deepest penetration (0 if nothing touched)
    touched: bool


class Worker:
    """One thread's model copy and data (the kernel keeps a rollout runner per thread); runs
    variants one at a time."""

    def __init__(
        self,
        base: mujoco.MjModel,
        plan: MotionPlan,
        thresholds: Thresholds,
        stop: Callable[[], bool] | None = None,
    ) -> None:
        self.base, self.plan, self.th = base, plan, thresholds
        self.stop = stop  # asked before each block: True ends the run (_Stopped)
        self.m = copy.copy(base)
        self.d = mujoco.MjData(self.m)
        self.idx = arm_index(base)
        self.units = arm_units(base)
        sid = mujoco.mj_name2id(base, mujoco.mjtObj.mjOBJ_SENSOR, CONTACT_SENSOR)
        self.contact_adr = int(base.sensor_adr[sid])
        self.force_adr = self.contact_adr + 2 + np.arange(len(JOINT_NAMES))

    def _start(self, v: Variant) -> tuple[np.ndarray, np.ndarray]:
        """Put the variant's arm at rest at the start; its offsets (rad) and its state."""
        m, d, idx = self.m, self.d, self.idx
        offset = np.radians(v.zero_offset_deg)
        apply_variant(m, self.base, v, d)
        mujoco.mj_resetData(m, d)
        q = self.plan.start - offset
        d.qpos[idx.qpos] = q
        d.qvel[idx.dof] = 0.0
        d.ctrl[idx.actuator] = q
        fill_delay_history(m, d)  # a delayed servo holds the start from the first step
        mujoco.mj_forward(m, d)
        s0 = np.empty(mujoco.mj_stateSize(m, _FULL))
        mujoco.mj_getState(m, d, s0, _FULL)
        return offset, s0

    def blocks(self, offset: np.ndarray):
        """Yield ``(first sample, times, ctrl rad, qpos rad, sensordata)`` block by block from
        ``d``'s state (:meth:`_start`), targets shifted by ``offset`` (rad), each block taken by
        the stepping kernel (:func:`~so101sim.sim.stepping.step_block`: ``mujoco.rollout`` on
        this thread, the divergence check)."""
        m, d, idx = self.m, self.d, self.idx
        targets, n = self.plan.targets, len(self.plan.targets)
        for a in range(0, n, BLOCK):
            if self.stop is not None and self.stop():
                raise _Stopped
            k = min(BLOCK, n - a)
            ctrl = np.zeros((k, m.nu))
            ctrl[:, idx.actuator] = targets[a : a + k] - offset
            sens = np.empty((k, m.nsensordata))
            state = step_block(m, d, ctrl, sensordata=sens, advice=_ADVICE)
            yield a, state[:, 0], ctrl[:, idx.actuator], state[:, 1 + idx.qpos], sens

    def run(self, v: Variant) -> VariantOutcome:
        """Roll ``v`` out, measure and judge it."""
        measured = self.measure(v)
        return _outcome(v.index, measured, judge(measured, self.th))

    def _forces_of(self, acc: Accumulator, limit: np.ndarray):
        """A function adding sensor rows of step j to ``acc`` (run lengths carried)."""

        def add(j: int, t: np.ndarray, sens: np.ndarray) -> None:
            effort = np.abs(sens[:, self.force_adr]) / limit
            runs = run_lengths(effort > self.th.max_effort, acc.run)
            acc.run = runs[-1]
            found, dist = sens[:, self.contact_adr], sens[:, self.contact_adr + 1]
            acc.add_forces(j, t, effort, runs, found, dist)

        return add

    def measure(self, v: Variant) -> Measurements:
        """Roll ``v`` out and measure it as the single check does (contacts unnamed)."""
        plan, units, dt = self.plan, self.units, self.base.opt.timestep
        start = units.from_radians(plan.start - np.radians(v.zero_offset_deg))
        acc = Accumulator(len(plan.phases), units)
        last_cmd = start  # the commanded target before the first step
        with mujoco_call():  # refused once the interpreter exits (exitgate)
            offset, s0 = self._start(v)  # writes the variant into the model: read it after
        limit = np.abs(self.m.actuator_forcerange[self.idx.actuator, 1])
        force_of = self._forces_of(acc, limit)
        # the single check's recorder also reads the forces and contacts before the first step
        force_of(0, np.array([s0[0]]), self.d.sensordata[None].copy())
        prev_t = float(s0[0])  # the time before the block's first sample
        for a, t, ctrl, qpos, sens in self.blocks(offset):
            cmd, meas = units.from_radians(ctrl), units.from_radians(qpos)
            for j in range(len(plan.phases)):
                lo = max(plan.bounds[j] - a, 0)
                hi = min(plan.bounds[j + 1] - a, len(t))
                if lo >= hi:
                    continue
                if plan.bounds[j] - a == lo:  # the step begins in this block
                    acc.starts[j] = t[lo - 1] if lo > 0 else prev_t
                    acc.begin(j, cmd[lo - 1] if lo > 0 else last_cmd)
                sl = slice(lo, hi)
                force_of(j, t[sl], sens[sl])
                acc.add_motion(j, t[sl], cmd[sl], meas[sl])
            prev_t, last_cmd = float(t[-1]), cmd[-1]
        steps = acc.steps(plan.phases, plan.kinds, plan.lines, dt)
        return Measurements(steps, units.limits_dict(), plan.stretched)


def _outcome(index: int, measured: Measurements, findings: tuple[Finding, ...]) -> VariantOutcome:
    body = [n for n in JOINT_NAMES if n != GRIPPER]
    joints = [s.joints for s in measured.steps]
    depths = [c.max_penetration for s in measured.steps for c in s.contacts]
    return VariantOutcome(
        index=index,
        passed=not any(f.failed for f in findings),
        failures=tuple(f for f in findings if f.failed),
        limit_margin=min(js[n].limit_margin for js in joints for n in body),
        peak_effort=max(j.peak_effort for js in joints for j in js.values()),
        saturated=max(j.saturated for js in joints for j in js.values()),
        tracking_error=max(js[n].peak_tracking_error for js in joints for n in body),
        contact_depth=max(depths, default=0.0),
        touched=bool(depths),
    )


def run_variants(
    base: mujoco.MjModel,
    plan: MotionPlan,
    variants: Sequence[Variant],
    thresholds: Thresholds,
    threads: int,
) -> list[VariantOutcome]:
    """Every variant rolled out and judged, on ``threads`` threads, in ``variants``' order."""
    results: list[VariantOutcome | None] = [None] * len(variants)
    todo = iter(range(len(variants)))
    lock = threading.Lock()
    errors: list[BaseException] = []

    def work() -> None:
        worker = None
        try:
            with mujoco_call():  # the worker's own model and data are made in the gate too
                worker = Worker(base, plan, thresholds, stop=lambda: bool(errors))
            while not errors:
                with lock:
                    i = next(todo, None)
                if i is None:
                    return
                results[i] = worker.run(variants[i])
        except _Stopped:
            return
        except BaseException as exc:  # re-raised on the calling thread
            errors.append(exc)
        finally:
            worker = None  # its MjData freed now, while the caller waits (_run_threads)

    count = max(1, min(threads, len(variants)))
    log.info("rolling out %d variants on %d threads", len(variants), count)
    if count == 1:
        work()
    else:
        _run_threads(work, count, errors)
    if errors:
        raise errors[0]
    return [r for r in results if r is not None]


@contextlib.contextmanager
def _signals_held() -> Iterator[None]:
    """Hold SIGINT, SIGTERM and SIGHUP back (POSIX, the main thread) while the block runs; one
    that came meanwhile is handled as the block ends. The threads started meanwhile inherit
    the mask: they never take a signal (Python handles them in the main thread anyway)."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None or threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {s for n in ("SIGINT", "SIGTERM", "SIGHUP") if (s := getattr(signal, n, None))}
    previous = mask(signal.SIG_BLOCK, held)
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, previous)


class _Stopped(Exception):
    """A worker told to stop (another failed, or the caller was interrupted)."""


def _run_threads(work: Callable[[], None], count: int, errors: list[BaseException]) -> None:
    """Run ``work`` on ``count`` threads and wait until each has finished with MuJoCo,
    whatever happens meanwhile.

    A signal (Ctrl-C, SIGTERM, SIGHUP: the CLI raises them in this thread) or any error while
    waiting stops the workers (they look at ``errors`` between blocks of steps, so each ends
    within one block) and still waits for them before it goes on up: a thread inside MuJoCo
    (a call, or freeing its ``MjData``) when the interpreter finalises crashed the process
    (exit 139, issue 30). Each worker says it is done with an event of its own, set after its
    MuJoCo objects are freed: ``Thread.join`` cannot be trusted once interrupted (Python 3.11
    may then mark a running thread as stopped). A second interrupt while they stop waits too."""
    done = [threading.Event() for _ in range(count)]

    def run(k: int) -> None:
        try:
            work()
        finally:
            done[k].set()

    pending: BaseException | None = None
    pool = [threading.Thread(target=run, args=(k,), daemon=True) for k in range(count)]
    started: list[threading.Event] = []
    try:
        with _signals_held():  # a signal in Thread.start would hide a started thread
            for k, th in enumerate(pool):
                th.start()
                started.append(done[k])
        for event in done:
            event.wait()
    except BaseException as exc:
        pending = exc
        errors.append(exc)  # the workers stop at their next block
    while not all(event.is_set() for event in started):
        try:
            for event in started:
                event.wait()
        except BaseException as exc:  # another signal: still wait for them (one block each)
            pending = pending or exc
    if pending is not None:
        raise pending


class _ContactNamer(Observer):
    """Called after every step: the pairs of bodies in contact, per step of the motion, with
    when they first touched and their deepest penetration."""

    def __init__(self, step_of_sample: np.ndarray, dt: float) -> None:
        self.step = step_of_sample
        self.dt = dt
        self.i = -1  # samples seen (-1: the call before the first step)
        self.pairs: dict[tuple[int, int, int], list[float]] = {}
        self._next = -math.inf

    def next_time(self) -> float:
        return self._next

    def on_time(self, m: mujoco.MjModel, d: mujoco.MjData) -> bool:
        if self.i >= 0:  # after mj_step, d.contact holds the contacts of that step
            for c in d.contact[: d.ncon]:
                b1, b2 = sorted((int(m.geom_bodyid[c.geom[0]]), int(m.geom_bodyid[c.geom[1]])))
                seen = self.pairs.setdefault((int(self.step[self.i]), b1, b2), [d.time, 0.0])
                seen[1] = max(seen[1], -float(c.dist))
        self.i += 1
        self._next = d.time + 0.5 * self.dt
        return True


def name_contacts(worker: Worker, v: Variant) -> list[tuple[int, Contact]]:
    """Replay ``v`` one step at a time and name what touched: ``(step of the motion, Contact)``
    per pair of bodies and step, in the order they first touched."""
    m, d, plan = worker.m, worker.d, worker.plan
    offset, _ = worker._start(v)
    step = np.searchsorted(plan.bounds, np.arange(len(plan.targets)), side="right") - 1
    namer = _ContactNamer(step, m.opt.timestep)
    advance(m, d, plan.targets - offset, [namer], keep_trace=False)  # the stepping kernel
    pairs = namer.pairs
    label = {b: ("floor" if b == 0 else m.body(b).name) for k in pairs for b in k[1:]}
    return [
        (j + 1, Contact(label[b1], label[b2], t, pen))
        for (j, b1, b2), (t, pen) in sorted(pairs.items(), key=lambda kv: kv[1][0])
    ]


__all__ = [
    "BLOCK",
    "MotionPlan",
    "VariantOutcome",
    "Worker",
    "name_contacts",
    "plan_motion",
    "run_variants",
    "sensor_model",
]
