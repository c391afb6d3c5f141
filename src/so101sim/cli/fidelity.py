"""``so101sim compare`` and ``so101sim fit``: the twin against a real arm's recordings.

Parsing and printing only; the work is :func:`so101sim.fidelity.compare.compare` and
:func:`so101sim.fidelity.fit.fit`.
"""

from __future__ import annotations

import argparse
import json
import sys

from ..errors import SettingError
from .output import add_arm_option, say
from .studio import add_web_options

SubParsers = argparse._SubParsersAction


DEFAULT_ITERATIONS = 30
"""`so101sim fit --iterations` when not given: solver evaluations at most."""


def add_parsers(sub: SubParsers) -> None:
    """Add ``compare`` and ``fit`` to the CLI's subcommands."""
    p = sub.add_parser(
        "compare",
        help="replay a real arm's recording in the sim and measure the sim against it",
        description=(
            "Replays the commands (action) of a LeRobot dataset (v2.1 or v3.0) or a so101sim "
            "CSV log from the first measured pose, at the recording's own rate, and prints per "
            "joint the sim's error against the real arm (observation.state): mean absolute, "
            "RMS, max and lag, beside the baseline 'the arm reaches every command'. Degrees; "
            "gripper 0-100."
        ),
    )
    p.add_argument("log", help="a LeRobot dataset folder or a so101sim CSV log")
    _common(p)
    p.add_argument(
        "--plot",
        metavar="PNG",
        help="real, sim and command per joint, the compared episodes one after another (at "
        "most 10), the worst windows shaded",
    )
    p.add_argument("--force", action="store_true", help="overwrite an existing --plot file")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    add_web_options(p, linger=False)
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser(
        "fit",
        help="fit an arm profile (the servos' parameters) to real recordings",
        description=(
            "Identifies each joint's servo (kp per firmware P unit, torque limit, back-EMF "
            "damping, Coulomb friction, armature, a small calibration offset) and the command "
            "delay by least squares over parallel rollouts of the recordings; prints the error "
            "on the fitted and held-out episodes and each parameter's standard error, and "
            "writes the profile (use it with --arm FILE)."
        ),
    )
    p.add_argument("logs", nargs="+", help="LeRobot dataset folders or so101sim CSV logs")
    p.add_argument("-o", "--output", required=True, help="the profile to write (.toml)")
    _common(p)
    p.add_argument(
        "--holdout",
        metavar="EPISODES",
        help="episodes kept out of the fit and predicted, e.g. 2-3 (default: the last one, if "
        "there are 2 or more); never frames of a fitted episode. Read even when --episodes "
        "leaves them out: --episodes 0-1 --holdout 2-3 fits on 0-1 and predicts 2-3",
    )
    p.add_argument(
        "--iterations",
        type=int,
        default=DEFAULT_ITERATIONS,
        help=f"solver evaluations at most (default {DEFAULT_ITERATIONS})",
    )
    p.add_argument(
        "--calibration-only",
        action="store_true",
        help="keep --arm's servos and delay; fit only each body joint's calibration (scale and "
        "offset) of a range-mode recording without LeRobot's calibration JSON",
    )
    p.add_argument(
        "--load-friction",
        action="store_true",
        help="also fit each joint's gear friction that grows with the servo's torque "
        "(load_friction, N·m per N·m; the replays then run slower)",
    )
    p.add_argument("--threads", type=int, help="threads for the rollouts (default: the cores)")
    p.add_argument(
        "--force",
        action="store_true",
        help="overwrite an existing output file; write a profile that predicts the held-out "
        "episodes worse than the default profile",
    )
    p.set_defaults(func=cmd_fit)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--episodes", help="episodes to use, e.g. 0-1,3 (default: all)")
    add_arm_option(p)
    p.add_argument(
        "--calibration",
        help="LeRobot calibration JSON of the follower, for a range-mode (-100..100) dataset",
    )
    p.add_argument(
        "--robot-id",
        help="the follower's LeRobot id (--robot.id): its calibration JSON is read from "
        "LeRobot's folder ($HF_LEROBOT_CALIBRATION/robots/so_follower/<id>.json)",
    )
    p.add_argument(
        "--units",
        choices=["auto", "degrees", "range"],
        default="auto",
        help="the dataset's body-joint units: degrees (use_degrees=True) or range (-100..100, "
        "LeRobot's default); auto: degrees if a value exceeds ±100, else range (default)",
    )
    p.add_argument("--model", help="MJCF file to load instead of the shipped scene.xml")


def _warn(text: str) -> None:
    say(f"so101sim: warning: {text}", file=sys.stderr)


def cmd_compare(args: argparse.Namespace) -> int:
    # this command's modules, loaded when it runs (every other command starts without them)
    from ..fidelity.compare import compare
    from ..fidelity.logs import parse_episodes
    from ..fidelity.plot import plot_overlay
    from ..recording.paths import check_output_path

    episodes = parse_episodes(args.episodes) if args.episodes is not None else None
    if args.plot is not None:
        check_output_path(args.plot, force=args.force, what="plot", suffixes=(".png",))
    if args.web:
        _web_first(args)
    result = compare(
        args.log,
        arm=args.arm,
        episodes=episodes,
        calibration=args.calibration,
        model=args.model,
        keep_traces=args.plot is not None or args.web,
        units=args.units,
        robot_id=args.robot_id,
    )
    for w in result.warnings:
        _warn(w)
    if args.plot is not None:
        plot_overlay(result, args.plot, force=args.force)  # checked above; claimed now
    if args.json:
        say(json.dumps(result.to_json()))
        return 0
    _print_compare(result, args)
    return _serve_compare(result, args) if args.web else 0


def _print_compare(result, args: argparse.Namespace) -> None:
    say(
        f"{result.frames} frames at {result.fps:g} fps, episodes {_eps(result.episodes)}, "
        f"arm profile {result.profile}"
    )
    say(
        f"{'joint':<15}{'sim mae':>9}{'rms':>8}{'max':>8}{'lag s':>8}{'command mae':>13}"
        f"{'holds':>8}{'moves':>8}"
    )
    for name, e in result.joints.items():
        base = result.command_baseline[name]
        split = f"{_cell(result.holds.get(name))}{_cell(result.moves.get(name))}"
        lag = f"{e.lag_s:>8.3f}" if e.lag_s == e.lag_s else f"{'-':>8}"  # NaN: it never moved
        say(f"{name:<15}{e.mae:>9.2f}{e.rms:>8.2f}{e.max:>8.2f}{lag}{base:>13.2f}{split}")
    better = sum(e.mae < result.command_baseline[n] for n, e in result.joints.items())
    say(
        f"(degrees; gripper 0-100) the sim is closer to the real arm than the commands on "
        f"{better} of {len(result.joints)} joints"
    )
    body = [n for n in result.joints if n != "gripper"]
    if body:  # the figure docs/fidelity.md quotes: the body joints' mean absolute error
        sim_body = sum(result.joints[n].mae for n in body) / len(body)
        cmd_body = sum(result.command_baseline[n] for n in body) / len(body)
        say(f"body joints: sim mae {sim_body:.2f} deg, command mae {cmd_body:.2f} deg")
    say("holds: sim mae while the joint's command holds still; moves: while it moves")
    for w in result.worst:
        say(
            f"worst window: episode {w.episode}, {w.t0:.2f}-{w.t1:.2f} s, body mae "
            f"{w.mae:.2f} deg, worst joint {w.joint}"
        )
    if args.plot is not None:
        say(f"wrote {args.plot} (the worst windows shaded)")


def _web_first(args: argparse.Namespace) -> None:
    """``compare --web``: its settings and the port checked before anything is replayed."""
    # the studio's modules (viser: the optional web extra) only for --web
    from ..studio.net import check_host
    from ..studio.server import check_port, ensure_free, require_viser

    if args.json:
        raise SettingError("--json and --web: choose one (--json prints only the JSON object)")
    require_viser()
    ensure_free(check_host(args.host), check_port(args.port))


def _serve_compare(result, args: argparse.Namespace) -> int:
    """``compare --web``: the replay in the studio (the sim's arm, the real arm's ghost) until
    Ctrl-C (or SIGTERM, SIGHUP); the server stopped on the way out."""
    # the studio's modules (viser: the optional web extra) only for --web
    from ..fidelity.stops import with_stops
    from ..model import load_model
    from ..studio.compare import CompareStudio, Window
    from .studio import _UntilSignal, announce

    model = load_model(args.model, arm=args.arm)
    if result.limits is not None:  # the arms drawn where the replay put them, past the CAD's
        model = with_stops(model, *result.limits)
    windows = [
        Window(w.episode, w.t0, w.t1, f"episode {w.episode}, {w.t0:.1f}-{w.t1:.1f} s: "
               f"{w.joint} ({w.mae:.1f} deg body mae)", w.joint)
        for w in result.worst
    ]  # fmt: skip
    with _UntilSignal() as until:
        studio = CompareStudio(model, result.traces, windows=windows, host=args.host,
                               port=args.port, shadows=args.shadows)  # fmt: skip
        until.studio = studio
        try:
            announce(studio.url, "the replay (the sim's arm; the real arm a ghost)", studio)
            while not until:
                until.sleep(3600.0)
        finally:
            studio.close()
    say("stopped")
    return 0


def _cell(v: float | None) -> str:
    return f"{v:>8.2f}" if v is not None and v == v else f"{'-':>8}"


def _eps(eps: list[int]) -> str:
    return ",".join(map(str, eps)) if len(eps) <= 12 else f"{eps[0]}..{eps[-1]} ({len(eps)})"


def cmd_fit(args: argparse.Namespace) -> int:
    # this command's modules, loaded when it runs (every other command starts without them)
    from ..fidelity.fit import FIT_NAMES, fit
    from ..fidelity.fitparams import body_mean
    from ..fidelity.logs import parse_episodes
    from ..model.arm import profile_toml
    from ..recording.paths import check_output_path, write_atomically

    out = check_output_path(args.output, force=args.force, what="profile", suffixes=(".toml",))
    episodes = parse_episodes(args.episodes) if args.episodes is not None else None
    holdout = parse_episodes(args.holdout) if args.holdout is not None else None
    if episodes is not None and holdout is not None:
        # `--episodes 0-1 --holdout 2-3`: fit on 0-1, predict 2-3 (the held-out ones are read too)
        episodes = sorted(set(episodes) | set(holdout))
    if args.load_friction and args.calibration_only:
        raise SettingError(
            "--load-friction and --calibration-only cannot be combined (--calibration-only fits "
            "no servo field); expected one of them"
        )
    names = {"names": (*FIT_NAMES, "load_friction")} if args.load_friction else {}
    result = fit(
        args.logs,
        arm=args.arm,
        episodes=episodes,
        calibration=args.calibration,
        units=args.units,
        holdout=holdout,
        robot_id=args.robot_id,
        **_only_calibration(args.calibration_only),
        **names,
        max_evaluations=args.iterations,
        threads=args.threads,
        model=args.model,
    )
    say(f"fitted on episodes {_eps(result.fit_episodes)}; {result.evaluations} rollouts")
    say(f"{'joint':<15}" + "".join(f"{k:>22}" for k in _names(result.values)))
    for joint, vals in result.values.items():
        cells = "".join(
            f"{_pm(vals[k], result.stderr[joint][k]):>22}" if k in vals else f"{'':>22}"
            for k in _names(result.values)
        )
        say(f"{'all (shared)' if joint == '*' else joint:<15}{cells}")
    _errors("fitted episodes", result.start_fit_error, result.fit_error)
    if result.gripper_blocked_frames:
        _warn(
            f"the real gripper is blocked (stalled on an object) in "
            f"{result.gripper_blocked_frames} frames: left out of the gripper's error"
        )
    if result.heldout_error is not None and result.start_heldout_error is not None:
        _heldout_table(result)
    else:
        _warn("no episode held out (one episode): the error on unseen motion is not measured")
    if result.worse_than_default and not args.force:
        say(
            f"so101sim: error: REFUSED: the fitted profile predicts the held-out episodes "
            f"{_eps(result.heldout_episodes)} WORSE than the default profile "
            f"({body_mean(result.heldout_error or {}):.2f} deg against "
            f"{body_mean(result.default_heldout_error or {}):.2f}, body joints); {out} was NOT "
            f"written ({_refusal_hint(args)}; --force writes it anyway)",
            file=sys.stderr,
        )
        return 1
    if result.worse_than_default:
        _warn("the fitted profile is worse than the default on the held-out episodes (--force)")
    comment = (
        f"so101sim fit of {', '.join(map(str, args.logs))}\n"
        f"episodes fitted {_eps(result.fit_episodes)}, held out {_eps(result.heldout_episodes)}"
    )
    text = profile_toml(result.profile, comment=comment)
    write = lambda p: p.write_text(text, encoding="utf-8")  # noqa: E731
    write_atomically(out, write, "profile", force=args.force)
    say(f"wrote {out} (use it with --arm {out})")
    return 0


def _refusal_hint(args: argparse.Namespace) -> str:
    """What may give a fit that the held-out episodes accept, for the refusal's message."""
    from ..model.arm import load_profile  # start-up: the CLI imports the library when it runs
    from ..units import JOINT_NAMES  # start-up, as above

    hints = ["more or more varied episodes may help"]
    if args.iterations < DEFAULT_ITERATIONS:
        hints.append(
            f"so may more --iterations ({args.iterations} now, {DEFAULT_ITERATIONS} by default)"
        )
    if args.load_friction:
        start = load_profile(args.arm)
        if all(start.joint(j, scaled=False).load_friction == 0 for j in JOINT_NAMES):
            hints.append(
                "so may starting from a profile with load friction: --arm sts3215-load (the "
                "servo bench's fit with it)"
            )
    return "; ".join(hints)


def _only_calibration(only: bool) -> dict:
    """fit()'s settings for --calibration-only: no servo field, no delay, the calibration."""
    if not only:
        return {}
    body = ("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll")
    return {"names": (), "joints": body, "fit_delay": False}  # calibration: when not given


def _heldout_table(result) -> None:
    from ..fidelity.fitparams import body_mean  # lazy: MuJoCo only when the command runs

    cols = {
        "fitted": result.heldout_error,
        "start": result.start_heldout_error,
        "default": result.default_heldout_error,
        "commands": result.command_heldout_error,
    }
    cols = {k: v for k, v in cols.items() if v is not None}
    say(
        f"held-out episodes {_eps(result.heldout_episodes)}: mean |sim - real| (deg; gripper "
        "0-100); commands: the arm reaching every command"
    )
    say(f"    {'joint':<15}" + "".join(f"{k:>10}" for k in cols))
    for name in result.heldout_error:
        say(f"    {name:<15}" + "".join(f"{v[name]:>10.2f}" for v in cols.values()))
    say(f"    {'body joints':<15}" + "".join(f"{body_mean(v):>10.2f}" for v in cols.values()))


def _names(values: dict[str, dict[str, float]]) -> list[str]:
    seen: list[str] = []
    for vals in values.values():
        seen += [k for k in vals if k not in seen]
    return seen


def _pm(v: float, e: float) -> str:
    return f"{v:.4g} ± {e:.2g}"


def _errors(what: str, before: dict[str, float], after: dict[str, float]) -> None:
    say(f"  mean |sim - real| on the {what} (deg; gripper 0-100), start -> fitted:")
    for name in after:
        say(f"    {name:<15}{before[name]:>8.2f} -> {after[name]:.2f}")
