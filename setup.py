"""Only a Python-version check: the project's metadata is in pyproject.toml (PEP 621).

pip resolves dependencies before it compares ``requires-python`` for a local folder, so on an
older Python a plain ``pip install .`` fails on a dependency with no word of the version
needed. This says it first.
"""

import sys

from setuptools import setup

if sys.version_info < (3, 11):  # noqa: UP036 - the point of this file
    sys.exit(
        f"so101sim needs Python 3.11 or newer; this is Python {sys.version.split()[0]}. "
        "Create the virtual environment with python3.11 or newer (e.g. `python3.12 -m venv .venv`)."
    )

setup()
