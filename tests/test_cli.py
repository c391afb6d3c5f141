import pytest

from so101sim.cli import build_parser, main
from so101sim.model import model_dir


def test_run_headless_prints_each_phase(capsys):
    assert main(["run", "--headless"]) == 0
    out = capsys.readouterr().out
    for phase in ("to_zero", "hold", "return"):
        assert f"{phase} [" in out
    assert out.count("largest tracking error") == 3
    assert "target : shoulder_pan=0.00°" in out
    assert "shoulder_lift=-98.00°" in out  # back at the rest pose


def test_run_without_a_display_says_it_is_headless(capsys):
    assert main(["run"]) == 0  # tests run with DISPLAY unset
    assert "running headless" in capsys.readouterr().out


def test_hold(capsys):
    assert main(["hold", "--headless", "--duration", "0.5"]) == 0
    out = capsys.readouterr().out
    assert "holding the starting pose" in out and "250 steps" in out


def test_model_path(capsys):
    assert main(["model-path"]) == 0
    path = capsys.readouterr().out.strip()
    assert path == str(model_dir())
    assert (model_dir() / "scene.xml").is_file()


def test_errors_exit_2_with_a_message(capsys, tmp_path):
    assert main(["run", "--headless", "--model", str(tmp_path / "x.xml")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["hold", "--headless", "--duration", "0"]) == 2
    assert "duration" in capsys.readouterr().err


def test_view_without_display_is_an_error(capsys):
    assert main(["view"]) == 2
    assert "no display" in capsys.readouterr().err


def test_parser_requires_a_command():
    with pytest.raises(SystemExit):
        build_parser().parse_args([])
