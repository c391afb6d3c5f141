"""docs/fidelity.md's sample `compare` (the ideal arm's logged lab run against the default
servos) is what the two commands it shows print (issue 29/30: every quoted figure produced by a
documented command and held true by a test)."""

from __future__ import annotations

from pathlib import Path

from so101sim.cli import main

DOC = (Path(__file__).resolve().parents[2] / "docs" / "fidelity.md").read_text(encoding="utf-8")


def test_the_sample_compare_in_the_docs_is_what_it_prints(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "--headless", "--arm", "official", "--log", "ideal.csv"]) == 0
    capsys.readouterr()
    assert main(["compare", "ideal.csv"]) == 0
    out = capsys.readouterr().out.strip()
    assert "$ so101sim compare ideal.csv\n" + out + "\n```" in DOC
