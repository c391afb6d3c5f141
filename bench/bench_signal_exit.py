"""A robust check interrupted by a signal, many times: how many ended by a crash (issue 30).

    PYTHONPATH=src python bench/bench_signal_exit.py [SIGTERM|SIGHUP|SIGINT] [tries] [threads]

Each try runs ``so101sim -v check --variants 2000 --threads N``, waits for its "rolling out"
log line (the workers are starting: an event, not a fixed sleep), then waits 0 to 0.9 s more
(the try's number picks it, so the signal lands in every phase of the rollout), sends the
signal and records the exit status: 128 + the signal is a clean end, -11 (139 in a shell) a
segfault. Prints one line per try and the count.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time


def main() -> int:
    name = sys.argv[1] if len(sys.argv) > 1 else "SIGTERM"
    tries = int(sys.argv[2]) if len(sys.argv) > 2 else 50
    threads = sys.argv[3] if len(sys.argv) > 3 else "2"
    signum = getattr(signal, name)
    codes = []
    for i in range(tries):
        proc = subprocess.Popen(
            [sys.executable, "-m", "so101sim", "-v", "check", "--variants", "2000",
             "--threads", threads],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "PYTHONFAULTHANDLER": "1"},
        )  # fmt: skip
        while (line := proc.stderr.readline()) and "rolling out" not in line:
            pass
        time.sleep((i * 7) % 10 / 10)  # a spread of moments into the rollout, on purpose
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=300)
        codes.append(proc.returncode)
        crashed = proc.returncode != 128 + signum
        print(i, proc.returncode, err[-2000:] if crashed else "", flush=True)
    clean = codes.count(128 + signum)
    print(f"{name}, {threads} threads: {clean} of {tries} ended cleanly; exit codes {codes}")
    return 0 if clean == tries else 1


if __name__ == "__main__":
    raise SystemExit(main())
