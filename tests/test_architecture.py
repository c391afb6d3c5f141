"""The package's shape: imports only point down the layers, and no module imports itself back.

Every ``import`` counts, also one inside a function (a lazy import hides a cycle from Python,
not from this test). The layers are those of docs/architecture.md.
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from fnmatch import fnmatch
from pathlib import Path

import pytest

import so101sim

PACKAGE = Path(so101sim.__file__).parent

# (layer, module patterns), lowest first: a module may import modules of its own layer or below.
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("errors/validation", ("errors", "validation", "gl", "simclock")),
    ("units", ("units",)),
    ("model", ("model", "modelcache", "modeltrim", "variants")),
    ("planning", ("profiles", "trajectory", "kinematics", "kinematics.*")),
    ("simulation", ("simulation", "stepping")),
    ("motion", ("motion", "motionfile", "motionfile_*")),
    (
        "outputs",
        (
            "recording",
            "recording.*",
            "viewer",
            "preflight",
            "preflight.*",
            "preflight_*",
            "distributed",
            "posefinder",
            "studio",
            "studio.*",
            "framing",
            "scenes",
            "cameras",
            "scenes.*",
            "cameras",
        ),
    ),
    (
        "apps",
        (
            "lab",
            "robot",
            "robot_*",
            "robot.*",
            "teleop",
            "teleop.*",
            "teleop_*",
            "envs",
            "envs.*",
            "runplan",
            "record_script",
            "handin",
            "starter",
        ),
    ),
    ("cli", ("cli", "cli_*", "__main__")),
]


def _modules() -> dict[str, Path]:
    mods = {}
    for p in PACKAGE.rglob("*.py"):
        parts = p.relative_to(PACKAGE).with_suffix("").parts
        if parts[0] == "data":  # shipped files (the examples), not modules of the package
            continue
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        if name:  # the package's own __init__ only re-exports, lazily, by name
            mods[name] = p
    return mods


def _layer(module: str) -> int:
    for i, (_, patterns) in enumerate(LAYERS):
        if any(fnmatch(module, pat) for pat in patterns):
            return i
    raise AssertionError(f"module so101sim.{module} has no layer: add it to docs/architecture.md")


def _imports(module: str, path: Path, known: set[str]) -> set[str]:
    """so101sim modules that ``module`` imports anywhere in its file."""
    pkg = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names: list[str] = []
        if isinstance(node, ast.ImportFrom) and node.level:
            base = pkg[: len(pkg) - node.level + 1] + (
                node.module.split(".") if node.module else []
            )
            names = [".".join(base)] + [".".join([*base, a.name]) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("so101sim"):
            base = node.module.split(".")[1:]
            names = [".".join(base)] + [".".join([*base, a.name]) for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name.split(".", 1)[1] for a in node.names if a.name.startswith("so101sim.")]
        found |= {n for n in names if n in known and n != module}
    return found


def _graph() -> dict[str, set[str]]:
    mods = _modules()
    return {m: _imports(m, p, set(mods)) for m, p in mods.items()}


def test_every_module_has_a_layer():
    for m in _modules():
        _layer(m)


def test_imports_only_point_down_the_layers():
    upward = [
        f"so101sim.{a} ({LAYERS[_layer(a)][0]}) imports so101sim.{b} ({LAYERS[_layer(b)][0]})"
        for a, targets in _graph().items()
        for b in targets
        if _layer(b) > _layer(a)
    ]
    assert not upward, "\n".join(upward)


def test_no_import_cycle():
    graph = _graph()
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        path.append(m)
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                return [*path[path.index(n) :], n]
            if n not in state and (cycle := visit(n)):
                return cycle
        path.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (cycle := visit(m)):
            pytest.fail("import cycle: " + " -> ".join(cycle))


def test_the_cycle_finder_finds_a_lazy_cycle(tmp_path):
    a = tmp_path / "a.py"
    a.write_text("def f():\n    from .b import g\n")
    assert _imports("a", a, {"a", "b"}) == {"b"}


def test_importing_the_package_is_light_and_sets_nothing():
    code = (
        "import os, sys; import so101sim; "
        "print('mujoco' in sys.modules, 'matplotlib' in sys.modules, os.environ.get('MUJOCO_GL'))"
    )
    env = {k: v for k, v in os.environ.items() if k != "MUJOCO_GL"}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    assert out.stdout.split() == ["False", "False", "None"]


def test_lazy_names_resolve_to_their_modules():
    from so101sim.simulation import Simulation

    assert so101sim.Simulation is Simulation
    assert set(so101sim.__all__) <= set(dir(so101sim))
    with pytest.raises(AttributeError, match="no attribute 'Nope'"):
        _ = so101sim.Nope
