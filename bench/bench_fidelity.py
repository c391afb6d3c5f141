"""How well each actuator model predicts a real STS3215 on the pendulum bench.

    PYTHONPATH=src python bench/bench_fidelity.py PATH [--split validation|fit|all]
        [--bam-m1 FILE] [--arm NAME|FILE ...] [--fit OUT.toml [--iterations N] [--spread]]

PATH is the public data set's folder of JSON runs (kscalelabs/sysid at commit 6b78737,
``data/feetech/STS_3215_12V_20250317/processed/``) or an ``.npz`` of runs (the project's
shared copy of the fit split). Neither is shipped: the data has no licence.

Of each (mass, length, P, trajectory) condition's two runs the one whose file name sorts first
is for fitting, the other for validation; ``--split`` picks which are scored (validation by
default; an .npz of the fit split is scored whole). Printed, side by side: the mean per-run
absolute position error (rad) of each profile (``official``, the shipped ``sts3215`` fit, with
holding friction, and ``sts3215-load``) and
of Rhoban's BAM M1 simulated from the data's authors' parameters (``friction_params/m1.json``
beside ``processed/``, or ``--bam-m1``), overall and per trajectory, and the wall time each
model took on this machine (a ratio, not a figure to quote alone).

``--fit OUT.toml``: first fit the servo (:data:`so101sim.fidelity.benchfit.FIT_PARAMS`) on the
FIT runs in PATH, starting from the shipped ``sts3215``, write the profile to OUT.toml (at 12 V
as measured, driven at 7.4 V like the shipped one) and score it beside the others: how the
shipped ``sts3215.toml`` was made (``--iterations 40``, every 4th sample).

``--load-friction`` (with ``--fit``): fit with friction that holds (``static_friction``) and
the load-dependent gearbox friction (``load_friction``, from 0.02) too.

``--spread`` (with ``--fit``): also fit each trajectory family of the FIT runs on its own and
print how far the parameters move between families; the profile's ``[uncertainty]`` table (the
standard deviations domain randomisation draws from, ``--randomize``) is then, per parameter,
the whole fit's standard error and the families' standard deviation combined
(sqrt(se² + sd²)); without ``--spread`` it is the standard error alone.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from so101sim.fidelity.bam import load_m1, simulate_m1
from so101sim.fidelity.benchdata import load_bench_runs, split_runs
from so101sim.fidelity.benchfit import per_run_errors, simulate_runs, summarize


def family_spread(runs: list, iterations: int) -> dict[str, float]:
    """Fit each trajectory family of ``runs`` on its own; print each fit and return each
    parameter's standard deviation between the families' fits."""
    from so101sim.fidelity.benchfit import fit_bench

    families = sorted({r.trajectory for r in runs})
    fits = {}
    for fam in families:
        part = [r for r in runs if r.trajectory == fam]
        t0 = time.perf_counter()
        fits[fam] = fit_bench(part, "sts3215", every=4, max_evaluations=iterations)
        print(f"  {fam:<18}{len(part):>4} runs, error {fits[fam].fit_error:.4f} rad, "
              f"{time.perf_counter() - t0:.0f} s")  # fmt: skip
    names = fits[families[0]].names
    print(f"  {'parameter':<20}" + "".join(f"{f[:12]:>13}" for f in families) + f"{'sd':>13}")
    sd = {}
    for k in names:
        vals = np.array([getattr(fits[f].servo, k) for f in families])
        sd[k] = float(np.std(vals, ddof=1)) if len(vals) > 1 else 0.0
        print(f"  {k:<20}" + "".join(f"{v:>13.5g}" for v in vals) + f"{sd[k]:>13.3g}")
    return sd


def fit_profile(
    runs: list, out: Path, iterations: int, spread: bool = False, load: bool = False
) -> Path:
    """Fit the servo on ``runs`` from the shipped sts3215 and write the profile to ``out``
    (its ``[uncertainty]``: the standard errors, with the families' spread when ``spread``).
    ``load``: with holding friction, and the load-dependent friction fitted too (from 0.02)."""
    from dataclasses import replace

    from so101sim.fidelity.benchfit import FIT_PARAMS, fit_bench
    from so101sim.model.arm import UNCERTAIN_FIELDS, load_profile, profile_toml

    if not runs:
        raise SystemExit("no FIT runs to fit on")
    t0 = time.perf_counter()
    start = load_profile("sts3215")
    names = FIT_PARAMS
    if load:
        start = replace(start, static_friction=True,
                        servo=replace(start.servo, load_friction=0.02))  # fmt: skip
        names = (*FIT_PARAMS, "load_friction")
    res = fit_bench(runs, start, names=names, every=4, max_evaluations=iterations)
    sd = family_spread(runs, iterations) if spread else {}
    sigma = {k: float(np.hypot(res.stderr[k], sd.get(k, 0.0))) for k in res.names
             if k in UNCERTAIN_FIELDS}  # fmt: skip  # what domain randomisation draws
    name = "sts3215-refit-load" if load else "sts3215-refit"
    prof = replace(start, name=name, servo=replace(res.servo, torque_scale=1.0),
                   uncertainty=sigma)  # fmt: skip
    errs = ", ".join(f"{k} ±{v:.2g}" for k, v in res.stderr.items())
    how = "standard errors and the trajectory families' spread" if spread else "standard errors"
    comment = (
        f"bench/bench_fidelity.py --fit: {len(runs)} FIT runs, {res.evaluations} evaluations, "
        f"{time.perf_counter() - t0:.0f} s\nfit error {res.fit_error:.4f} rad; standard errors: "
        f"{errs}\n[uncertainty]: {how}"
    )
    out.write_text(profile_toml(prof, comment=comment), encoding="utf-8")
    print(f"fitted {len(runs)} runs: mean per-run error {res.fit_error:.4f} rad; wrote {out}")
    for k in res.names:
        print(f"  {k:<20}{getattr(res.servo, k):>10.5g} ± {res.stderr[k]:.2g}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("path", type=Path)
    ap.add_argument("--split", choices=["validation", "fit", "all"], default=None)
    ap.add_argument("--bam-m1", type=Path, default=None)
    ap.add_argument("--arm", action="append", default=None, help="profiles (repeatable)")
    ap.add_argument("--fit", type=Path, default=None, help="fit on the FIT runs, write here")
    ap.add_argument("--iterations", type=int, default=40, help="solver evaluations (--fit)")
    ap.add_argument("--spread", action="store_true", help="also fit each trajectory family")
    ap.add_argument("--load-friction", action="store_true",
                    help="--fit with holding friction and load-dependent friction")  # fmt: skip
    args = ap.parse_args()
    if args.load_friction and args.fit is None:
        ap.error("--load-friction refits the servo: it needs --fit OUT.toml")

    runs = load_bench_runs(args.path)
    split = args.split or ("all" if args.path.suffix == ".npz" else "validation")
    fit, val = split_runs(runs)
    chosen = {"validation": val, "fit": fit, "all": runs}[split]
    if not chosen:
        raise SystemExit(f"no {split} runs in {args.path}")
    print(f"{len(chosen)} {split} runs of {len(runs)} in {args.path}")

    arms: list = list(args.arm or ["official", "sts3215", "sts3215-load"])
    if args.arm is None:  # side by side: the shipped fit with friction that holds (noslip)
        from dataclasses import replace

        from so101sim.model.arm import load_profile

        held = replace(load_profile("sts3215"), name="sts3215-hold", static_friction=True)
        arms.insert(2, held)
    if args.fit is not None:
        arms.append(fit_profile(fit, args.fit, args.iterations, args.spread, args.load_friction))
    columns: dict[str, dict[str, float]] = {}
    times: dict[str, float] = {}
    for arm in arms:
        label = getattr(arm, "name", None) or (
            Path(arm).stem if str(arm).endswith(".toml") else str(arm)
        )
        t0 = time.perf_counter()
        pred = simulate_runs(chosen, arm)
        times[label] = time.perf_counter() - t0
        columns[label] = summarize(chosen, per_run_errors(chosen, pred))
    m1_path = args.bam_m1 or args.path.parent / "friction_params" / "m1.json"
    if m1_path.is_file():
        t0 = time.perf_counter()
        pred = simulate_m1(chosen, load_m1(m1_path))
        times["BAM M1"] = time.perf_counter() - t0
        columns["BAM M1"] = summarize(chosen, per_run_errors(chosen, pred))
    else:
        print(f"(no BAM M1 column: {m1_path} not found; give --bam-m1 FILE)")

    counts = {k: sum(r.trajectory == k for r in chosen) for k in columns[next(iter(columns))]}
    counts["all"] = len(chosen)
    names = list(columns)
    print()
    print("mean per-run |position error|, rad")
    print(f"{'trajectory':<18}{'runs':>5}" + "".join(f"{n:>14}" for n in names))
    for row in columns[names[0]]:
        cells = "".join(f"{columns[n][row]:>14.4f}" for n in names)
        print(f"{row:<18}{counts[row]:>5}{cells}")
    print(f"{'wall time, s':<23}" + "".join(f"{times[n]:>14.2f}" for n in names))
    worst = {n: max(v for k, v in columns[n].items() if k != "all") for n in names}
    print(f"{'worst trajectory':<23}" + "".join(f"{worst[n]:>14.4f}" for n in names))
    _ = np  # numpy is the runs' format


if __name__ == "__main__":
    main()
