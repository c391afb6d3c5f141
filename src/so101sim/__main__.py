"""``python -m so101sim`` (and ``mjpython -m so101sim`` on macOS) runs the CLI."""

from .cli import main

raise SystemExit(main())
