import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_setup_py_says_which_python_is_needed_on_an_old_one():
    code = (
        "import sys, runpy, setuptools; sys.version_info = (3, 10, 13, 'final', 0); "
        "sys.version = '3.10.13 ' + sys.version.split(' ', 1)[1]; "
        f"runpy.run_path({str(ROOT / 'setup.py')!r}, run_name='__main__')"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.returncode != 0
    assert "so101sim needs Python 3.11 or newer; this is Python 3.10.13" in out.stderr
