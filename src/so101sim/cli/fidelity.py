"""``so101sim compare`` and ``so101sim fit``: the twin against a real arm's recordings.

Parsing and printing only; the work is :func:`so101sim.fidelity.compare.compare` and
:func:`so101sim.fidelity.fit.fit`.
"""

from __future__ import annotations

import argparse
import json
import sys

from .output import add_arm_option, say

SubParsers = argparse._SubParsersAction


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
    p.add_argument("--plot", metavar="PNG", help="real, sim and command per joint (1st episode)")
    p.add_argument("--force", action="store_true", help="overwrite an existing --plot file")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
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
        type=int,
        help="episodes (the last ones) kept out of the fit (default 1 if there are 2 or more)",
    )
    p.add_argument(
        "--iterations", type=int, default=30, help="solver evaluations at most (default 30)"
    )
    p.add_argument("--threads", type=int, help="threads for the rollouts (default: the cores)")
    p.add_argument("--force", action="store_true", help="overwrite an existing output file")
    p.set_defaults(func=cmd_fit)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--episodes", help="episodes to use, e.g. 0-1,3 (default: all)")
    add_arm_option(p)
    p.add_argument(
        "--calibration",
        help="LeRobot calibration JSON of the follower, for a range-mode (-100..100) dataset",
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
    from ..fidelity.compare import compare, plot_overlay
    from ..fidelity.logs import parse_episodes
    from ..recording.paths import check_output_path

    episodes = parse_episodes(args.episodes) if args.episodes is not None else None
    if args.plot is not None:
        check_output_path(args.plot, force=args.force, what="plot", suffixes=(".png",))
    result = compare(
        args.log,
        arm=args.arm,
        episodes=episodes,
        calibration=args.calibration,
        model=args.model,
        keep_traces=args.plot is not None,
        units=args.units,
    )
    for w in result.warnings:
        _warn(w)
    if args.plot is not None:
        plot_overlay(result, args.plot, force=args.force)  # checked above; claimed now
    if args.json:
        say(json.dumps(result.to_json()))
        return 0
    say(
        f"{result.frames} frames at {result.fps:g} fps, episodes {_eps(result.episodes)}, "
        f"arm profile {result.profile}"
    )
    say(f"{'joint':<15}{'sim mae':>9}{'rms':>8}{'max':>8}{'lag s':>8}{'command mae':>13}")
    for name, e in result.joints.items():
        base = result.command_baseline[name]
        say(f"{name:<15}{e.mae:>9.2f}{e.rms:>8.2f}{e.max:>8.2f}{e.lag_s:>8.3f}{base:>13.2f}")
    better = sum(e.mae < result.command_baseline[n] for n, e in result.joints.items())
    say(
        f"(degrees; gripper 0-100) the sim is closer to the real arm than the commands on "
        f"{better} of {len(result.joints)} joints"
    )
    if args.plot is not None:
        say(f"wrote {args.plot}")
    return 0


def _eps(eps: list[int]) -> str:
    return ",".join(map(str, eps)) if len(eps) <= 12 else f"{eps[0]}..{eps[-1]} ({len(eps)})"


def cmd_fit(args: argparse.Namespace) -> int:
    from ..fidelity.fit import fit
    from ..fidelity.logs import parse_episodes
    from ..model.arm import profile_toml
    from ..recording.paths import check_output_path, write_atomically

    out = check_output_path(args.output, force=args.force, what="profile", suffixes=(".toml",))
    episodes = parse_episodes(args.episodes) if args.episodes is not None else None
    result = fit(
        args.logs,
        arm=args.arm,
        episodes=episodes,
        calibration=args.calibration,
        units=args.units,
        holdout=args.holdout,
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
    if result.heldout_error is not None and result.start_heldout_error is not None:
        say(f"held-out episodes {_eps(result.heldout_episodes)}:")
        _errors("held-out episodes", result.start_heldout_error, result.heldout_error)
    else:
        _warn("no episode held out (one episode): the error on unseen motion is not measured")
    comment = (
        f"so101sim fit of {', '.join(map(str, args.logs))}\n"
        f"episodes fitted {_eps(result.fit_episodes)}, held out {_eps(result.heldout_episodes)}"
    )
    text = profile_toml(result.profile, comment=comment)
    write = lambda p: p.write_text(text, encoding="utf-8")  # noqa: E731
    write_atomically(out, write, "profile", force=args.force)
    say(f"wrote {out} (use it with --arm {out})")
    return 0


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
