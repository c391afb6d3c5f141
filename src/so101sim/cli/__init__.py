"""The ``so101sim`` command line: it parses arguments, calls the library and prints results.

``so101sim.cli:main`` is the console script. :mod:`.runplan` is the library side of
``so101sim run`` (the checks, viewer or headless, outputs): it sits here because it joins
outputs (recording, viewer) to a motion, and no layer below may import both.

May import: every package of so101sim (the top layer; nothing imports it).
"""

from .main import build_parser, main

__all__ = ["build_parser", "main"]
