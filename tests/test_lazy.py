"""so101sim._lazy: a package's names imported on first use, each written once."""

import sys
import textwrap

import pytest

import so101sim
import so101sim.recording


@pytest.fixture
def package(tmp_path, monkeypatch):
    root = tmp_path / "lazypkg"
    root.mkdir()
    (root / "__init__.py").write_text(
        textwrap.dedent(
            """
            from typing import TYPE_CHECKING

            from so101sim._lazy import lazy_names

            from .eager import Eager

            if TYPE_CHECKING:
                from .heavy import Heavy, helper as renamed

            __version__ = "1"
            __getattr__, __dir__ = lazy_names(__name__)
            """
        )
    )
    (root / "eager.py").write_text("class Eager:\n    pass\n")
    (root / "heavy.py").write_text("class Heavy:\n    pass\n\ndef helper():\n    return 42\n")
    (root / "other.py").write_text("VALUE = 7\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield
    for name in [n for n in sys.modules if n.split(".")[0] == "lazypkg"]:
        del sys.modules[name]


def test_a_name_is_imported_on_first_use_from_its_type_checking_import(package):
    import lazypkg

    assert "lazypkg.heavy" not in sys.modules
    assert lazypkg.renamed() == 42 and lazypkg.Heavy.__module__ == "lazypkg.heavy"
    assert "Heavy" in vars(lazypkg)  # later look-ups skip __getattr__
    assert lazypkg.other.VALUE == 7  # a submodule is an attribute, imported on first use
    assert lazypkg.__all__ == ["Eager", "Heavy", "__version__", "renamed"]
    assert {"Heavy", "renamed", "Eager"} <= set(dir(lazypkg))
    with pytest.raises(AttributeError, match="module 'lazypkg' has no attribute 'Nope'"):
        _ = lazypkg.Nope


def test_the_packages_offer_what_they_offered():
    assert {"Simulation", "ViewerError", "__version__", "record", "check_motion_file"} <= set(
        so101sim.__all__
    )
    assert "preflight" not in so101sim.__all__  # the subpackage (a function before issue 30)
    assert "lazy_names" not in so101sim.__all__  # a private module's name is not offered
    assert {"Recorder", "VideoSettings", "video_frames"} <= set(so101sim.recording.__all__)
    assert so101sim.recording.video.__name__ == "so101sim.recording.video"


def test_the_labs_light_modules_import_no_mujoco():
    import subprocess

    code = (
        "import sys; import so101sim.lab.starter, so101sim.lab.simclock; "
        "print('mujoco' in sys.modules); from so101sim.lab import move_to_pose; "
        "print('mujoco' in sys.modules, move_to_pose.__module__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "True", "so101sim.lab.helpers"]


@pytest.mark.parametrize(
    "first", ["", "import so101sim.preflight", "from so101sim import check_motion_file"]
)
def test_so101sim_preflight_is_the_subpackage_whatever_was_imported_first(first):
    import subprocess

    code = (
        f"{first}\nimport types, warnings\nfrom so101sim import preflight\n"
        "import so101sim\n"
        "assert isinstance(preflight, types.ModuleType) and so101sim.preflight is preflight\n"
        "assert callable(preflight.preflight) and preflight.preflight is not preflight\n"
        "from so101sim.motion import Hold\n"
        "with warnings.catch_warnings(record=True) as w:\n"
        "    warnings.simplefilter('always')\n"
        "    report = so101sim.preflight([Hold(0.02)])\n"
        "assert report.passed and any(x.category is DeprecationWarning for x in w)\n"
        "print('ok')\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False
    )
    assert out.returncode == 0 and out.stdout.strip() == "ok", out.stderr
