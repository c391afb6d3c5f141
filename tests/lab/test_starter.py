"""The examples ship inside the package and `so101sim examples DIR` copies them out."""

from __future__ import annotations

import subprocess
import sys
from importlib import resources
from pathlib import Path

import pytest

from so101sim import cli
from so101sim.errors import OutputPathError
from so101sim.lab import starter

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = {"wave.toml", "lab_motion.py", "record_lab.py", "lab_hold_start.py", "pick_cube.py"}


def test_the_examples_are_package_data():
    names = {p.name for p in (resources.files("so101sim") / "data" / "examples").iterdir()}
    assert names >= SHIPPED
    assert starter.example_path("wave.toml").read_text(encoding="utf-8").startswith("#")
    with pytest.raises(OutputPathError, match=r"no example named 'nope\.toml'; the examples are"):
        starter.example_path("nope.toml")


def test_the_repositorys_examples_folder_is_the_packages():
    # examples/ in the repository is a link to the package's folder, and the installed
    # package (editable or not) holds the same files
    source = ROOT / "src" / "so101sim" / "data" / "examples"
    assert (ROOT / "examples").resolve() == source.resolve()

    def names(folder):
        return {p.name for p in folder.iterdir() if p.suffix in (".py", ".toml")}

    assert names(starter.examples_dir()) == names(source)


@pytest.mark.slow
def test_a_built_package_holds_the_examples(tmp_path):
    out = tmp_path / "build"
    steps = ["egg_info", "--egg-base", str(tmp_path), "build_py", "-d", str(out)]
    done = subprocess.run(
        [sys.executable, "setup.py", "-q", *steps],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    built = {p.name for p in (out / "so101sim" / "data" / "examples").iterdir()}
    assert built == {p.name for p in starter.examples_dir().iterdir() if p.is_file()}


def test_so101sim_examples_copies_them_from_any_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # not the repository
    assert cli.main(["examples", "mine"]) == 0
    out = capsys.readouterr().out
    copied = {p.name for p in (tmp_path / "mine").iterdir()}
    assert copied >= SHIPPED and f"copied {len(copied)} file(s) to mine" in out
    wave = (tmp_path / "mine" / "wave.toml").read_bytes()
    assert wave == starter.example_path("wave.toml").read_bytes()
    assert cli.main(["examples", "mine"]) == 2  # nothing overwritten without --force
    assert "already exists" in capsys.readouterr().err
    assert cli.main(["examples", "mine", "--force"]) == 0
    (tmp_path / "file").write_text("")
    assert cli.main(["examples", "file"]) == 2
    assert "expected a folder" in capsys.readouterr().err


def test_a_copied_motion_example_runs_from_its_new_folder(tmp_path, capsys):
    starter.copy_examples(tmp_path)
    assert cli.main(["check", str(tmp_path / "wave.toml")]) == 0
    assert capsys.readouterr().out.strip().endswith("PASS")


def test_the_copied_examples_name_only_files_that_are_there(tmp_path):
    """Each `python X.py` / `so101sim ... X.toml` line in an example's opening comment names a
    file of the folder `so101sim examples FOLDER` made (the commands run from that folder)."""
    import re

    copied = starter.copy_examples(tmp_path / "mine")
    named = 0
    for path in copied:
        head = "\n".join(path.read_text(encoding="utf-8").splitlines()[:14])
        for name in re.findall(r"(?:python|so101sim \w+) (\S+\.(?:py|toml))", head):
            assert (tmp_path / "mine" / name).is_file(), f"{path.name} names {name}"
            named += 1
        assert "examples/" not in head, f"{path.name}: {head}"
    assert named >= 10


def test_wave_waves_three_times_as_it_says():
    from so101sim.motionfile import load_motion

    text = starter.example_path("wave.toml").read_text(encoding="utf-8")
    assert "three times" in text
    motion = load_motion(starter.example_path("wave.toml"))
    waves = [s for s in motion.steps if getattr(s, "phase", "").startswith("wave")]
    assert len(waves) == 3
