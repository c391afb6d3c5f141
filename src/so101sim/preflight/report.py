"""The robust preflight's report: :class:`VariantsReport` (N variants judged, the worst per
check), its text (:func:`format_variants`), its JSON (:meth:`VariantsReport.to_dict`) and its
histograms (:func:`plot_variants`). :mod:`so101sim.preflight.robust` runs the variants and
builds the report (``summarize``); these names are importable from there too.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import SettingError
from ..recording.paths import check_output_path, write_atomically
from ..recording.plot import PLOT_SUFFIXES
from ..validation import escape_controls
from .check import describe
from .judge import Thresholds
from .rollout import VariantOutcome
from .variants import Variant


@dataclass(frozen=True)
class Worst:
    """The worst variant for one check."""

    check: str  # "limit margin" | "effort" | "tracking error" | "contact"
    variant: Variant
    outcome: VariantOutcome
    text: str  # the figure in words


@dataclass(frozen=True)
class VariantsReport:
    """N variants judged."""

    job: Any  # the robust.VariantJob that was run (not imported: robust imports this module)
    outcomes: tuple[VariantOutcome, ...]
    worst: tuple[Worst, ...]
    contacts: tuple[str, ...] = ()  # what the worst-contact variant touched, named by a replay

    @property
    def passed(self) -> int:
        return sum(o.passed for o in self.outcomes)

    @property
    def fraction(self) -> float:
        return self.passed / len(self.outcomes) if self.outcomes else 0.0

    def failing(self) -> dict[str, int]:
        """How many variants fail each kind of check."""
        counts: dict[str, int] = {}
        for o in self.outcomes:
            for kind in sorted({type(f).__name__.removesuffix("Finding") for f in o.failures}):
                counts[kind] = counts.get(kind, 0) + 1
        return counts

    def to_dict(self) -> dict[str, Any]:
        th = self.job.thresholds
        return {
            "variants": len(self.outcomes),
            "seed": self.job.seed,
            "passed": self.passed,
            "fraction_passed": self.fraction,
            "failing_by_check": self.failing(),
            "checks": check_summaries(self),
            "ranges": asdict(self.job.ranges),
            "thresholds": asdict(th),
            "worst": [
                {
                    "check": w.check,
                    "text": w.text,
                    "variant": w.variant.to_dict(),
                    "passed": w.outcome.passed,
                    "failures": [describe(f, th) for f in w.outcome.failures],
                }
                for w in self.worst
            ],
            "contacts": list(self.contacts),
            "per_variant": [
                {k: v for k, v in asdict(o).items() if k != "failures"} for o in self.outcomes
            ],
        }


def _params(v: Variant) -> str:
    def span(values: np.ndarray, unit: str = "×") -> str:
        lo, hi = float(values.min()), float(values.max())
        return f"{unit}{lo:.2f}-{hi:.2f}" if unit == "×" else f"{lo:+.2f}..{hi:+.2f}{unit}"

    return (
        f"payload {v.payload_kg:.3f} kg, kp {span(v.kp_scale)}, kv {span(v.kv_scale)}, "
        f"force limit {span(v.force_scale)}, damping {span(v.damping_scale)}, friction "
        f"{span(v.frictionloss_scale)}, armature {span(v.armature_scale)}, zero offsets "
        f"{span(v.zero_offset_deg, '°')}"
    )


CHECKS = (  # (the check's name in the report, the kind of its findings)
    ("limit margin", "Limit"),
    ("effort", "Effort"),
    ("tracking error", "Tracking"),
    ("contact", "Contact"),
)


def _kind(finding: Any) -> str:
    return type(finding).__name__.removesuffix("Finding")


def _steps(findings: list[Any]) -> str:
    named = dict.fromkeys(
        f"step {f.step} ({escape_controls(f.phase, lines=False)})" for f in findings
    )
    return ", ".join(named) if named else "the steps named above"


def advice(check: str, worst: Worst | None, th: Thresholds) -> str:
    """What to change in the motion (or the arm) so that ``check`` passes in every variant."""
    kind = dict(CHECKS)[check]
    found = [f for f in worst.outcome.failures if _kind(f) == kind] if worst else []
    where = _steps(found)
    if check == "limit margin":
        need = max((th.limit_margin - f.margin for f in found), default=th.limit_margin)
        offset = float(np.abs(worst.variant.zero_offset_deg).max()) if worst else 0.0
        joints = ", ".join(
            dict.fromkeys(f"{f.joint} from its {f.side} limit ({f.limit:.2f}°)" for f in found)
        )
        return (
            f"keep {joints or 'the joints'} at least {need:.2f}° further away in the poses that "
            f"{where} start from or move to (the motion's start pose counts: a step begins "
            f"where the one before ended; a variant's zero offset moves the arm by up to "
            f"{offset:.2f}°), or calibrate the arm so its zero offsets are smaller"
        )
    if check == "effort":
        payload = f" (the worst variant carries {worst.variant.payload_kg:.3f} kg)" if worst else ""
        return (
            f"a slower move (a longer duration for {where}), a smooth shape (shape = "
            f'"minimum_jerk" or "limited" on those steps), or less payload{payload}'
        )
    if check == "tracking error":
        return (
            f"a slower move (a longer duration for {where}) or a smooth shape "
            '(shape = "minimum_jerk"): the servo lags most where a move starts or stops hard'
        )
    return f"move the path of {where} away from what it touches (a waypoint above it)"


def check_summaries(report: VariantsReport) -> list[dict[str, Any]]:
    """Per check: how many variants failed it, the worst variant (its index, figure, whether it
    failed this check and which others, its parameters, its findings) and what to change."""
    th, n = report.job.thresholds, len(report.outcomes)
    worst = {w.check: w for w in report.worst}
    counts = report.failing()
    rows = []
    for check, kind in CHECKS:
        w = worst.get(check)
        failed = counts.get(kind, 0)
        row: dict[str, Any] = {"check": check, "failed": failed, "variants": n}
        if w is not None:
            kinds = {_kind(f) for f in w.outcome.failures}
            row["worst"] = {
                "variant": w.variant.index,
                "figure": w.text,
                "fails_this_check": kind in kinds,
                "fails": [c for c, k in CHECKS if k in kinds],
                "parameters": w.variant.to_dict(),
                "findings": [describe(f, th) for f in w.outcome.failures if _kind(f) == kind],
            }
        if failed:
            row["advice"] = advice(check, w, th)
        rows.append(row)
    return rows


def thresholds_text(th: Thresholds) -> str:
    return (
        f"thresholds: limit margin {th.limit_margin:g}° (body joints), effort above "
        f"{th.max_effort:.0%} of the force limit for at most {th.max_saturation * 1000:g} ms, "
        f"tracking error {th.max_tracking_error:g}° (gripper: same figures in 0-100 units)"
    )


def format_variants(report: VariantsReport) -> str:
    """The report in words: PASS fraction, then per check how many variants failed it, the
    worst variant and its parameters, and what to change; the thresholds used."""
    job, th = report.job, report.job.thresholds
    n = len(report.outcomes)
    worst = {w.check: w for w in report.worst}
    rows = [
        f"robust preflight: {n} variants of {job.motion_path} (seed {job.seed})",
        f"PASS {report.passed}/{n} ({report.fraction:.1%}): "
        + (
            "the motion passes on every variant"
            if report.passed == n
            else f"{n - report.passed} variant(s) fail at least one check"
        ),
        thresholds_text(th),
    ]
    for row in check_summaries(report):
        check, failed = row["check"], row["failed"]
        verdict = f"FAIL in {failed}/{n} variants" if failed else f"PASS in all {n} variants"
        w = worst.get(check)
        if w is None:
            rows.append(f"{check}: {verdict} (nothing touched)")
            continue
        info = row["worst"]
        if info["fails_this_check"]:
            state = "fails it"
        elif info["fails"]:
            state = f"passes it; fails {', '.join(info['fails'])}"
        else:
            state = "passes"
        rows.append(f"{check}: {verdict}; worst {w.text}, variant {w.variant.index} ({state})")
        rows.append(f"    {_params(w.variant)}")
        rows.extend(f"    - {text}" for text in info["findings"][:3])
        if "advice" in row:
            rows.append(f"    what to change: {row['advice']}")
    rows.extend(f"  contact: {c}" for c in report.contacts[:5])
    return "\n".join(rows)


def check_plot_path(path: str | Path, *, force: bool = False) -> Path:
    """Check that the histogram can be written to ``path`` (before anything runs): an
    existing file only with ``force``."""
    return check_output_path(path, force=force, what="plot", suffixes=PLOT_SUFFIXES)


def plot_variants(report: VariantsReport, path: str | Path, *, force: bool = False) -> Path:
    """Histograms of every variant's peak tracking error (body joints, degrees) and longest
    saturation (ms), with the thresholds; written with matplotlib's Agg backend."""
    # matplotlib imported here, only to keep start-up fast: only a histogram needs it
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    p = check_output_path(path, force=force, what="plot", suffixes=PLOT_SUFFIXES)
    if not report.outcomes:
        raise SettingError("nothing to plot: no variants were run; expected at least one")
    th = report.job.thresholds
    fig = Figure(figsize=(10, 4), dpi=100, layout="constrained")
    FigureCanvasAgg(fig)
    ax1, ax2 = fig.subplots(1, 2)
    track = [o.tracking_error for o in report.outcomes]
    sat = [o.saturated * 1000 for o in report.outcomes]
    ax1.hist(track, bins=40, color="#4c72b0")
    ax1.axvline(th.max_tracking_error, color="#c44e52", ls="--", label="threshold")
    ax1.set_xlabel("peak tracking error, body joints (degrees)")
    ax2.hist(sat, bins=40, color="#55a868")
    ax2.axvline(th.max_saturation * 1000, color="#c44e52", ls="--", label="threshold")
    ax2.set_xlabel(f"longest effort above {th.max_effort:.0%} of the force limit (ms)")
    for ax in (ax1, ax2):
        ax.set_ylabel("variants")
        ax.legend(fontsize="small")
    fig.suptitle(
        f"{len(report.outcomes)} variants (seed {report.job.seed}): {report.fraction:.1%} PASS"
    )
    fmt = p.suffix.lstrip(".").lower()
    return write_atomically(p, lambda tmp: fig.savefig(tmp, format=fmt), what="plot", force=force)


__all__ = [
    "VariantsReport",
    "Worst",
    "advice",
    "check_plot_path",
    "check_summaries",
    "format_variants",
    "plot_variants",
    "thresholds_text",
]
