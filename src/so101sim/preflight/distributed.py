"""Robust preflight past one machine: the variants of a :class:`~so101sim.preflight.robust.
VariantJob` in chunks over Ray tasks.

Ray is an optional extra (``pip install "so101sim[ray]"``), imported only when asked for. Each
task runs :func:`~so101sim.preflight.robust.run_chunk` on variants ``start:stop`` (one
thread: Ray gives each task a CPU); every variant is drawn from the job's seed up front, so the
merged result is the same as the local run's, variant for variant.
"""

from __future__ import annotations

import importlib
import socket
from collections.abc import Sequence
from types import ModuleType

from ..errors import SettingError
from ..validation import check_count
from .robust import VariantJob, run_chunk
from .rollout import VariantOutcome

RAY_HINT = 'pip install "so101sim[ray]"'
DEFAULT_CHUNK = 64
"""Variants per Ray task: about two seconds of the lab motion on one core."""
CONNECT_TIMEOUT_S = 10.0
"""The longest wait to reach a Ray cluster's address before giving up (wall seconds): Ray
itself retries an address that does not answer for minutes, printing time-outs."""


def import_ray() -> ModuleType:
    """The ``ray`` module, or SettingError saying how to install it."""
    try:
        return importlib.import_module("ray")
    except ImportError:
        raise SettingError(
            f"--ray needs Ray, which is not installed; install it with: {RAY_HINT}"
        ) from None


def probe_address(address: str, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """Raise SettingError unless something answers at ``address`` (``host:port`` or
    ``ray://host:port``) within ``timeout`` seconds; "auto" and "local" are left to Ray (it
    finds, or starts, a cluster on this machine at once)."""
    if address in ("auto", "local"):
        return
    expected = (
        "auto (a cluster started here with `ray start --head`), local (start one), or a "
        "cluster's address host:port or ray://host:port"
    )
    hostport = address.removeprefix("ray://")
    host, _, port = hostport.rpartition(":")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise SettingError(f"--ray {address!r} is not an address; expected {expected}")
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout):
            pass
    except OSError as exc:
        reason = "no answer" if isinstance(exc, TimeoutError) else (exc.strerror or str(exc))
        raise SettingError(
            f"--ray {address}: no Ray cluster reached at {host}:{port} within {timeout:g} s "
            f"({reason}); expected {expected}"
        ) from None


def chunks(count: int, size: int) -> list[tuple[int, int]]:
    """``[start, stop)`` ranges covering ``0..count`` in order, each at most ``size`` long."""
    size = check_count(size, "chunk size", minimum=1)
    return [(a, min(a + size, count)) for a in range(0, count, size)]


def merge(parts: Sequence[Sequence[VariantOutcome]], count: int) -> list[VariantOutcome]:
    """The chunks' outcomes back in variant order; raises if any variant is missing or twice."""
    out = [o for part in parts for o in part]
    if [o.index for o in out] != list(range(count)):
        raise SettingError(
            f"the Ray tasks returned {len(out)} results for {count} variants, out of order or "
            "incomplete; expected every variant once"
        )
    return out


def connect_ray(address: str, *, num_cpus: int | None = None) -> bool:
    """Join (or start) the Ray cluster at ``address``: "auto" (a running cluster), "local"
    (start one here, with ``num_cpus`` workers if given) or ``host:port``/``ray://host:port``.
    Returns True if this call initialised Ray (the caller then shuts it down), False if Ray was
    already initialised.

    Raises:
        SettingError: Ray is not installed, or no cluster answers at ``address`` (within
            :data:`CONNECT_TIMEOUT_S` for an address given as ``host:port``).
    """
    if num_cpus is not None:
        check_count(num_cpus, "Ray workers", minimum=1, maximum=4096)
    ray = import_ray()
    if ray.is_initialized():
        return False
    probe_address(address)  # an address that does not answer fails in seconds, not minutes
    options = {"num_cpus": num_cpus, "include_dashboard": False} if address == "local" else {}
    try:
        ray.init(address=None if address == "local" else address, **options)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise SettingError(
            f"--ray {address}: no Ray cluster to join ({first}); expected a running "
            "cluster (`ray start --head`, then --ray auto), its address, or --ray local "
            "to start one here"
        ) from None
    return True


def run_on_ray(
    job: VariantJob, address: str | None = "auto", *, chunk: int = DEFAULT_CHUNK
) -> list[VariantOutcome]:
    """Run ``job`` on Ray: ``address`` "auto" (a running cluster), "local" (start one here),
    an address such as ``ray://host:10001``, or None (Ray already initialised by the caller).

    Raises:
        SettingError: Ray is not installed, or no cluster answers at ``address`` (within
            :data:`CONNECT_TIMEOUT_S` for an address given as ``host:port``).
    """
    ray = import_ray()
    if address is not None:
        connect_ray(address)
    task = ray.remote(num_cpus=1)(run_chunk)
    refs = [task.remote(job, a, b, 1) for a, b in chunks(job.count, chunk)]
    return merge(ray.get(refs), job.count)


__all__ = [
    "CONNECT_TIMEOUT_S",
    "DEFAULT_CHUNK",
    "RAY_HINT",
    "chunks",
    "connect_ray",
    "import_ray",
    "merge",
    "probe_address",
    "run_on_ray",
]
