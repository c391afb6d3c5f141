"""Nothing stalls (issue 23): reaching a Ray cluster is bounded in time, and planning a
straight tip line costs what its length and turn ask for, not what its duration does (a
3600 s line is 1.8 million targets: it used to be 1.8 million IK solves, and a line over
~2000 s failed with "steps of shape (1800000,) are invalid")."""

from __future__ import annotations

import time

import pytest

from so101sim.cli import main
from so101sim.errors import SettingError


# ---------------------------------------------------------------------------- Ray
def test_an_address_that_does_not_resolve_fails_at_once() -> None:
    from so101sim.distributed import probe_address

    with pytest.raises(SettingError, match=r"no Ray cluster reached at nonsense:1 within 10 s"):
        probe_address("nonsense:1")
    with pytest.raises(SettingError, match="within 10 s"):
        probe_address("127.0.0.1:1")  # nothing listens: refused
    with pytest.raises(SettingError, match="is not an address"):
        probe_address("nonsense")
    probe_address("auto")  # left to Ray, which answers at once


def test_an_address_that_does_not_answer_gives_up_in_the_time_stated(monkeypatch) -> None:
    import socket

    from so101sim.distributed import probe_address

    asked = []

    def silent(address, timeout):
        asked.append(timeout)
        raise TimeoutError("timed out")

    monkeypatch.setattr(socket, "create_connection", silent)
    with pytest.raises(SettingError, match=r"within 0\.5 s \(no answer\)"):
        probe_address("10.255.255.1:6379", timeout=0.5)
    assert asked == [0.5]


def test_check_variants_on_a_nonsense_ray_address_is_one_error_line(capsys) -> None:
    pytest.importorskip("ray")
    t0 = time.monotonic()
    assert main(["check", "--variants", "2", "--ray", "nonsense:1"]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "within 10 s" in err
    assert time.monotonic() - t0 < 60  # it hung for minutes (a loose bound: a busy machine)
