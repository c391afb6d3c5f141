"""Found trying issue 29 as a new user: check names the servo model it ran."""

from __future__ import annotations

import json

from so101sim.cli.main import main


def test_check_names_the_servo_model_it_ran(tmp_path, capsys):
    motion = tmp_path / "mine.toml"
    motion.write_text('start = "rest"\n[[steps]]\nhold = 0.2\n')
    assert main(["check", str(motion)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"checked {motion}"
    assert lines[1].startswith("servo model: sts3215 (STS3215 fitted")
    assert main(["check", str(motion), "--arm", "official"]) == 0
    second = capsys.readouterr().out.splitlines()[1]
    assert second == "servo model: official (the model file's own ideal position actuators)"
    assert main(["check", str(motion), "--json", "--arm", "official"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["servo_model"].startswith("official (")
    assert report["motion"] == str(motion)
