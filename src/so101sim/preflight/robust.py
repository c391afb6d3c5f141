"""Robust preflight: the single check (:mod:`so101sim.preflight`) on N perturbed arms.

:func:`check_variants` draws N variants (:mod:`so101sim.preflight.variants`; ranges from the motion
file's ``[variants]`` table, else the defaults), rolls the motion out on each on all cores
(:mod:`so101sim.preflight.rollout`), judges each with the single check's judge and returns a
:class:`VariantsReport`: the fraction that PASS, the worst case per check (limit margin,
effort, tracking error, contacts) with that variant's parameters, and per-variant figures for
:func:`plot_variants`.

A run is a :class:`VariantJob`, plain data: :func:`run_chunk` runs variants ``start:stop`` of
it anywhere (this process, or a Ray worker, :mod:`so101sim.preflight.distributed`); every variant is
drawn up front from the seed, so the result is the same whatever the threads or chunks.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..model.arm import ArmLike, load_profile, profile_from_toml, profile_toml
from ..model.load import arm_units, load_model, scene_path
from ..motion.file import MotionFile, load_motion, parse_motion
from ..motion.lines import MAX_FILE_BYTES, load_toml, read_text_limited
from ..validation import check_count
from .judge import Thresholds
from .report import (  # the report, importable from here as before
    VariantsReport,
    Worst,
    advice,
    check_plot_path,
    check_summaries,
    format_variants,
    plot_variants,
    thresholds_text,
)
from .rollout import (
    VariantOutcome,
    Worker,
    name_contacts,
    plan_motion,
    run_variants,
    sensor_model,
)
from .variants import (
    Variant,
    VariantRanges,
    check_variant_count,
    ranges_from_table,
    sample_variants,
)

MAX_THREADS = 1024
MAX_SEED = 2**63 - 1


@dataclass(frozen=True)
class VariantJob:
    """Everything a run needs, as plain data (it travels to Ray workers)."""

    motion_text: str
    motion_path: str
    model_path: str
    count: int
    arm: str = ""  # the arm profile as TOML text ("": the default profile)
    seed: int = 0
    ranges: VariantRanges = field(default_factory=VariantRanges)
    thresholds: Thresholds = field(default_factory=Thresholds)
    strict: bool = False

    def variants(self) -> list[Variant]:
        return sample_variants(self.count, self.seed, self.ranges)


def read_motion(path: str | Path) -> tuple[str, dict[str, Any], Any]:
    """A motion file's text, its TOML data and key lines (errors with file and line)."""
    load_motion(path)  # every check of the motion itself, with its messages
    text = read_text_limited(Path(path), MAX_FILE_BYTES)
    data, loc = load_toml(text, str(path))
    return text, data, loc


def make_job(
    path: str | Path,
    *,
    count: int,
    seed: int = 0,
    model: str | Path | None = None,
    thresholds: Thresholds | None = None,
    strict: bool = False,
    ranges: VariantRanges | None = None,
    arm: ArmLike = None,
) -> VariantJob:
    """Check every setting (count and seed first, before anything is read or allocated) and
    read the motion file and its ``[variants]`` table.

    Raises:
        SettingError: a count out of 1..100000, a bad seed.
        MotionFileError: the motion file or its ``[variants]`` table is invalid (file:line).
    """
    count = check_variant_count(count)
    seed = check_count(seed, "seed", maximum=MAX_SEED)
    text, data, loc = read_motion(path)
    if ranges is None:
        ranges = VariantRanges()
        if "variants" in data:
            ranges = ranges_from_table(data["variants"], path=str(path), line_of=loc.line)
    return VariantJob(
        motion_text=text,
        motion_path=str(path),
        model_path=str(Path(model).expanduser() if model is not None else scene_path()),
        count=count,
        arm=profile_toml(load_profile(arm)),  # plain text: it travels to Ray workers
        seed=seed,
        ranges=ranges,
        thresholds=thresholds if thresholds is not None else Thresholds(),
        strict=strict,
    )


def _prepare(job: VariantJob) -> tuple[Any, Any, MotionFile]:
    arm = profile_from_toml(job.arm, "the job's arm profile") if job.arm else None
    load_model(job.model_path, arm=arm)  # the model's own errors (missing file, no joints)
    base = sensor_model(job.model_path, arm)
    motion = parse_motion(job.motion_text, path=job.motion_path, units=arm_units(base))
    plan = plan_motion(base, motion.steps, motion.start, lines=motion.lines, strict=job.strict)
    return base, plan, motion


def run_chunk(
    job: VariantJob, start: int = 0, stop: int | None = None, threads: int | None = None
) -> list[VariantOutcome]:
    """Variants ``start:stop`` of ``job``, each rolled out and judged (all cores by default)."""
    stop = job.count if stop is None else stop
    base, plan, _ = _prepare(job)
    todo = job.variants()[start:stop]
    n_threads = threads if threads is not None else (os.cpu_count() or 1)
    return run_variants(base, plan, todo, job.thresholds, n_threads)


def summarize(job: VariantJob, outcomes: list[VariantOutcome]) -> VariantsReport:
    """The report of ``outcomes`` (in variant order); the deepest contact is replayed here to
    name the bodies."""
    variants = job.variants()
    worst: list[Worst] = []
    if outcomes:
        o = min(outcomes, key=lambda o: o.limit_margin)
        worst.append(Worst("limit margin", variants[o.index], o, f"{o.limit_margin:.2f}°"))
        o = max(outcomes, key=lambda o: (o.saturated, o.peak_effort))
        text = f"saturated {o.saturated * 1000:.0f} ms (peak {o.peak_effort:.0%})"
        worst.append(Worst("effort", variants[o.index], o, text))
        o = max(outcomes, key=lambda o: o.tracking_error)
        worst.append(Worst("tracking error", variants[o.index], o, f"{o.tracking_error:.2f}°"))
    touched = [o for o in outcomes if o.touched]
    contacts: tuple[str, ...] = ()
    if touched:
        o = max(touched, key=lambda o: o.contact_depth)
        worst.append(Worst("contact", variants[o.index], o, f"{o.contact_depth * 1000:.1f} mm"))
        base, plan, _ = _prepare(job)
        named = name_contacts(Worker(base, plan, job.thresholds), variants[o.index])
        contacts = tuple(
            f"step {k}: {c.body1} touches {c.body2} at t = {c.first_time:.3f} s "
            f"(up to {c.max_penetration * 1000:.1f} mm deep)"
            for k, c in named
        )
    return VariantsReport(job, tuple(outcomes), tuple(worst), contacts)


def check_variants(
    path: str | Path,
    *,
    count: int,
    seed: int = 0,
    threads: int | None = None,
    model: str | Path | None = None,
    thresholds: Thresholds | None = None,
    strict: bool = False,
    ranges: VariantRanges | None = None,
    arm: ArmLike = None,
) -> VariantsReport:
    """Run the motion file at ``path`` on ``count`` perturbed arms (of the arm profile ``arm``;
    None: the default) and judge each.

    ``threads``: at most this many (default: every core); the result does not depend on it.

    Raises:
        SettingError: a bad count (1..100000), seed or thread count, before anything runs.
        MotionFileError: the motion file or its ``[variants]`` table is invalid.
    """
    if threads is not None:
        threads = check_count(threads, "threads", minimum=1, maximum=MAX_THREADS)
    job = make_job(
        path, count=count, seed=seed, model=model, thresholds=thresholds, strict=strict,
        ranges=ranges, arm=arm,
    )  # fmt: skip
    return summarize(job, run_chunk(job, threads=threads))


__all__ = [
    "VariantJob",
    "VariantsReport",
    "Worst",
    "advice",
    "check_plot_path",
    "check_summaries",
    "check_variants",
    "format_variants",
    "make_job",
    "plot_variants",
    "run_chunk",
    "summarize",
    "thresholds_text",
]
