"""``python -m so101sim`` (and ``mjpython -m so101sim`` on macOS) runs the CLI.

Only when run as a program: importing this module (as tools that import every submodule of a
package do, e.g. LeRobot's ``--robot.discover_packages_path=so101sim``) runs nothing.
"""

from .cli import main

if __name__ == "__main__":
    raise SystemExit(main())
