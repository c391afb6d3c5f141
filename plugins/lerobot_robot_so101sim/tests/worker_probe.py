"""Run in a dataset worker by the tests: which heavy packages the worker process has imported.
Imports nothing itself, so that it changes nothing of what it reports."""

from __future__ import annotations

import os
import sys


def loaded(names: list[str]) -> dict[str, object]:
    """Which of ``names`` this process has imported, and its ``LP_NUM_THREADS``."""
    return {
        "imported": sorted(n for n in names if n in sys.modules),
        "LP_NUM_THREADS": os.environ.get("LP_NUM_THREADS"),
    }
