"""The package's shape: imports only point down the layers, and no module imports itself back.

Every ``import`` counts, also one inside a function (a lazy import hides a cycle from Python,
not from this test). The layers are those of docs/architecture.md.
"""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import so101sim

PACKAGE = Path(so101sim.__file__).parent

# (layer, packages and top-level modules), lowest first: a module may import modules of its own
# layer or below. A package's name stands for it and all its modules (docs/architecture.md).
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("base", ("errors", "validation", "gl", "exitgate", "_compat", "_lazy")),
    ("units", ("units",)),
    ("model", ("model",)),
    ("kinematics", ("kinematics",)),
    ("sim", ("sim",)),
    ("motion", ("motion",)),
    ("outputs", ("recording", "viewer", "preflight", "scenes", "fidelity", "studio")),
    ("apps", ("lab", "robot", "envs")),
    ("cli", ("cli", "__main__")),
]

# The only modules allowed at the top of the package: everything else lives in a subpackage of
# its layer (a new flat module, or a family of them, fails test_no_flat_modules).
TOP_LEVEL_MODULES = {
    "errors",
    "validation",
    "units",
    "gl",
    "exitgate",
    "_compat",
    "_lazy",
    "__main__",
}


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
    top = module.split(".")[0]
    for i, (_, names) in enumerate(LAYERS):
        if top in names:
            return i
    raise AssertionError(f"module so101sim.{module} has no layer: add it to docs/architecture.md")


def _from_names(base: list[str], node: ast.ImportFrom, known: set[str]) -> list[str]:
    """What ``from <base> import a, b`` uses: the modules a and b where they are modules
    (``from . import trim``), else the package ``base`` itself (its names)."""
    modules = [".".join([*base, a.name]) for a in node.names]
    if all(m in known for m in modules):
        return modules
    return [".".join(base), *modules]


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
            names = _from_names(base, node, known)
        elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("so101sim"):
            names = _from_names(node.module.split(".")[1:], node, known)
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


def test_no_flat_modules():
    flat = sorted(m for m in _modules() if "." not in m and (PACKAGE / f"{m}.py").is_file())
    extra = sorted(set(flat) - TOP_LEVEL_MODULES)
    assert not extra, (
        f"flat modules {extra} at the top of so101sim: put each in the subpackage of its "
        "layer (docs/architecture.md), or, for a base module, add it to TOP_LEVEL_MODULES"
    )


def _may_import(package: str, doc: str) -> set[str]:
    """The packages and top-level modules a package's docstring says it may import: its
    ``May import:`` sentence, naming ``so101sim.<name>`` in double backticks, "the base
    modules" (the base layer) or "every package"."""
    found = re.search(r"May import:(.*?)(?:\.\s|\.$)", doc, re.DOTALL)
    assert found, (
        f"so101sim.{package}'s docstring has no 'May import: ...' sentence; expected one "
        "naming what it may import (``so101sim.<package>`` and/or the base modules)"
    )
    text = " ".join(found.group(1).split())
    if "every package" in text:
        return {name for _, names in LAYERS for name in names}
    names = set(re.findall(r"``so101sim\.(\w+)``", text))
    if "the base modules" in text:
        names |= set(LAYERS[0][1])
    return names


def test_every_package_says_what_it_may_import():
    """Each package's docstring names what it may import; it imports nothing else, and names
    nothing the layers forbid (docs/architecture.md)."""
    actual: dict[str, set[str]] = {}
    for a, targets in _graph().items():
        top = a.split(".")[0]
        actual.setdefault(top, set()).update(b.split(".")[0] for b in targets)
    for init in sorted(PACKAGE.glob("*/__init__.py")):
        package = init.parent.name
        if package == "data":
            continue
        doc = ast.get_docstring(ast.parse(init.read_text(encoding="utf-8"))) or ""
        assert doc, f"so101sim.{package} has no docstring"
        allowed = _may_import(package, doc) - {package}
        extra = sorted(actual.get(package, set()) - allowed - {package})
        assert not extra, (
            f"so101sim.{package} imports {extra}, which its docstring's 'May import:' does not "
            "name; expected the docstring to say what the package imports"
        )
        above = sorted(n for n in allowed if _layer(n) > _layer(package))
        assert not above, (
            f"so101sim.{package}'s docstring says it may import {above}, from a layer above "
            "its own; expected only its own layer and those below (docs/architecture.md)"
        )


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of ``graph`` (node -> nodes it points to), or None."""
    state: dict[str, int] = {}  # 1: on the current path, 2: done
    path: list[str] = []

    def visit(m: str) -> list[str] | None:
        state[m] = 1
        path.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                return [*path[path.index(n) :], n]
            if n not in state and (cycle := visit(n)):
                return cycle
        path.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state and (cycle := visit(m)):
            return cycle
    return None


def test_packages_import_each_other_without_a_cycle():
    """Within a layer, packages may use each other, one way only (viewer -> recording)."""
    packages: dict[str, set[str]] = {}
    for a, targets in _graph().items():
        packages.setdefault(a.split(".")[0], set()).update(
            b.split(".")[0] for b in targets if b.split(".")[0] != a.split(".")[0]
        )
    cycle = _cycle(packages)
    assert cycle is None, "packages importing each other: " + " -> ".join(cycle or [])


def test_imports_only_point_down_the_layers():
    upward = [
        f"so101sim.{a} ({LAYERS[_layer(a)][0]}) imports so101sim.{b} ({LAYERS[_layer(b)][0]})"
        for a, targets in _graph().items()
        for b in targets
        if _layer(b) > _layer(a)
    ]
    assert not upward, "\n".join(upward)


def test_no_import_cycle():
    cycle = _cycle(_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_the_checks_fail_on_a_flat_module_and_a_cycle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None
    with pytest.raises(AssertionError, match="has no layer"):
        _layer("robot_arm")  # a new flat family has no layer until it is given a package


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
    from so101sim.sim.simulation import Simulation

    assert so101sim.Simulation is Simulation
    assert set(so101sim.__all__) <= set(dir(so101sim))
    with pytest.raises(AttributeError, match="no attribute 'Nope'"):
        _ = so101sim.Nope


def test_old_module_paths_are_the_new_modules_with_a_warning():
    import importlib
    import warnings

    from so101sim._compat import MOVED

    for old, new in sorted(MOVED.items()):
        sys.modules.pop(old, None)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            module = importlib.import_module(old)
        assert module is importlib.import_module(new), old
        assert module.__name__ == new and module.__spec__.name == new
        assert any(
            issubclass(w.category, DeprecationWarning) and new in str(w.message) for w in caught
        ), old
    with pytest.warns(DeprecationWarning, match="so101sim.sim.simulation"):
        sys.modules.pop("so101sim.simulation", None)
        from so101sim.simulation import Simulation  # the old path, on purpose
    assert Simulation is so101sim.sim.Simulation


def test_unknown_old_paths_still_fail():
    import importlib

    for name in ("so101sim.nope", "so101sim.robot_nope", "so101sim.sim.nope"):
        with pytest.raises(ModuleNotFoundError):
            importlib.import_module(name)


PLUGINS = PACKAGE.parents[1] / "plugins"


def _public(module: str, name: str) -> bool:
    """Whether ``from <module> import <name>`` uses so101sim's public API: ``module`` is
    ``so101sim``, one of its packages or a top-level module whose name has no leading
    underscore, and ``name`` is in its ``__all__`` (a module with none: a name without a
    leading underscore), or is itself such a package or module."""
    import importlib

    parts = module.split(".")
    if len(parts) > 2 or any(p.startswith("_") for p in parts) or name.startswith("_"):
        return False
    inner = len(parts) == 2 and not (PACKAGE / parts[1] / "__init__.py").is_file()
    if inner and parts[1] not in TOP_LEVEL_MODULES:
        return False
    mod = importlib.import_module(module)
    public = getattr(mod, "__all__", None)
    if public is not None and name in public:
        return True
    if public is None and hasattr(mod, name):
        return True
    return module == "so101sim" and (
        (PACKAGE / name / "__init__.py").is_file() or name in TOP_LEVEL_MODULES
    )


def test_plugins_import_only_public_names():
    """The LeRobot plugins use so101sim's public API: names exported by a package's (or a
    public top-level module's) ``__all__``, never a private name or an inner module."""
    bad = []
    for path in sorted(PLUGINS.glob("*/lerobot_*/**/*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            where = f"{path.relative_to(PLUGINS)}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "so101sim":
                bad += [
                    f"{where}: from {node.module} import {a.name}"
                    for a in node.names
                    if not _public(node.module, a.name)
                ]
            elif isinstance(node, ast.Import):
                for a in node.names:
                    parts = a.name.split(".")
                    if (
                        parts[0] == "so101sim"
                        and len(parts) > 1
                        and not _public(".".join(parts[:-1]), parts[-1])
                    ):
                        bad.append(f"{where}: import {a.name}")
    assert not bad, (
        f"the plugins import so101sim's internals: {bad}; expected names from a package's "
        "__all__ (export what a plugin needs from the package's __init__)"
    )


@pytest.mark.parametrize(
    "line",
    [
        "from so101sim.robot.scene import find_follower",
        "from so101sim.robot import _private",
        "from so101sim.model.arm import load_profile",
        "import so101sim.motion.file",
        "from so101sim._compat import install",
    ],
)
def test_the_public_api_check_refuses_internals(line):
    node = ast.parse(line).body[0]
    if isinstance(node, ast.ImportFrom):
        assert not all(_public(node.module, a.name) for a in node.names)
    else:
        parts = node.names[0].name.split(".")
        assert not _public(".".join(parts[:-1]), parts[-1])


# The stepping kernel's modules: the only ones that may call MuJoCo's stepping functions
# (docs/architecture.md: "nothing else in so101sim calls mj_step or mujoco.rollout").
# batched: make_vec's worlds (issue 33); loaded: the steps of a model with load-dependent
# friction (issue 32); blocks: the rows of one block of step_block
KERNEL = {"sim.stepping", "sim.blocks", "sim.batch", "sim.batched", "sim.loaded"}
_STEP_NAMES = {"mj_step", "mj_step1", "mj_step2", "rollout", "Rollout"}


def _stepping_calls(tree: ast.AST) -> list[tuple[int, str]]:
    """``(line, name)`` of each call of a MuJoCo stepping function (``mujoco.mj_step``,
    ``rollout.rollout``, ``pool.rollout``, ``Rollout(...)``) and each import of
    ``mujoco.rollout`` in ``tree``."""
    hits = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            f = node.func
            name = f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")
            if name in _STEP_NAMES:
                hits.append((node.lineno, name))
        elif isinstance(node, ast.ImportFrom) and node.module and "mujoco" in node.module:
            if node.module == "mujoco.rollout" or any(a.name == "rollout" for a in node.names):
                hits.append((node.lineno, "import mujoco.rollout"))
        elif isinstance(node, ast.Import) and any(a.name == "mujoco.rollout" for a in node.names):
            hits.append((node.lineno, "import mujoco.rollout"))
    return hits


def test_only_the_stepping_kernel_steps_mujoco():
    outside = [
        f"{name}:{line} {call}"
        for name, path in _modules().items()
        if name not in KERNEL
        for line, call in _stepping_calls(ast.parse(path.read_text(encoding="utf-8")))
    ]
    assert not outside, (
        f"MuJoCo stepped outside the kernel ({', '.join(sorted(KERNEL))}): {outside}"
    )


def test_the_stepping_site_check_finds_each_kind_of_call():
    code = (
        "import mujoco\nfrom mujoco import rollout\nimport mujoco.rollout\n"
        "mujoco.mj_step(m, d, nstep=2)\nrollout.rollout(ms, ds, s, c)\npool.rollout(ms, ds, s, c)\n"
        "mujoco.mj_step1(m, d)\nx = mujoco.mj_forward(m, d)\n"
    )
    found = [c for _, c in _stepping_calls(ast.parse(code))]
    assert found.count("import mujoco.rollout") == 2
    assert found.count("rollout") == 2 and "mj_step" in found and "mj_step1" in found
    assert "mj_forward" not in found


# The model builder: the only module that compiles a model (issue 30: "one model builder";
# docs/architecture.md, model/build.py). Parsing a file into an MjSpec (MjSpec.from_file) and
# reading a compiled model back (MjModel.from_binary_path, the disk cache) are not compiling.
BUILDER = {"model.build"}
_COMPILE_NAMES = {"compile", "from_xml_path", "from_xml_string"}


def _compile_calls(tree: ast.AST) -> list[tuple[int, str]]:
    """``(line, name)`` of each call that compiles a MuJoCo model in ``tree``: ``spec.compile()``
    (any receiver but the ``re`` module), ``MjModel.from_xml_path``/``from_xml_string``."""
    hits = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            f = node.func
            if f.attr in _COMPILE_NAMES and not (
                isinstance(f.value, ast.Name) and f.value.id == "re"
            ):
                hits.append((node.lineno, f.attr))
    return hits


def test_only_the_model_builder_compiles_models():
    outside = [
        f"{name}:{line} {call}"
        for name, path in _modules().items()
        if name not in BUILDER
        for line, call in _compile_calls(ast.parse(path.read_text(encoding="utf-8")))
    ]
    assert not outside, f"a model compiled outside the builder ({', '.join(BUILDER)}): {outside}"
    inside = _compile_calls(ast.parse(_modules()["model.build"].read_text(encoding="utf-8")))
    assert {c for _, c in inside} == {"compile", "from_xml_path"}  # compile_spec, a plain file


def test_the_compile_site_check_finds_each_kind_of_call():
    code = (
        "import re, mujoco\nx = re.compile('a')\nm = spec.compile()\n"
        "m = mujoco.MjModel.from_xml_path(p)\nm = mujoco.MjModel.from_xml_string(t)\n"
        "s = mujoco.MjSpec.from_file(p)\nm = mujoco.MjModel.from_binary_path(p)\n"
        "m = mujoco.MjSpec().compile()\n"
    )
    found = sorted(c for _, c in _compile_calls(ast.parse(code)))
    assert found == ["compile", "compile", "from_xml_path", "from_xml_string"]


# Imports inside functions (issue 30: "lazy imports only where start-up needs them, commented"):
# each function's first group of them says why they are there (start-up speed, an optional
# dependency, a module of a layer above...), on its own lines or on the line just above; the
# function's later imports (after a setting that must come first, in another branch) share it.
def _uncommented_lazy_imports(source: str) -> list[tuple[int, str]]:
    """``(line, text)`` of the first import of each function (outermost, methods included)
    whose first group of consecutive imports, and the line above it, carry no comment."""
    lines = source.splitlines()
    hits: list[tuple[int, str]] = []

    def first_group(fn: ast.AST) -> list[ast.stmt]:
        blocks = [
            block
            for node in ast.walk(fn)
            for block in (getattr(node, f, None) for f in ("body", "orelse", "finalbody"))
            if isinstance(block, list) and block and isinstance(block[0], ast.stmt)
        ]
        groups = []
        for block in blocks:
            run: list[ast.stmt] = []
            for stmt in [*block, None]:
                if isinstance(stmt, ast.Import | ast.ImportFrom):
                    run.append(stmt)
                elif run:
                    groups.append(run)
                    run = []
        return min(groups, key=lambda g: g[0].lineno) if groups else []

    def functions(node: ast.AST, inside: bool) -> None:
        for child in ast.iter_child_nodes(node):
            is_fn = isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef)
            if is_fn and not inside:
                group = first_group(child)
                if group:
                    first, last = group[0].lineno, group[-1].end_lineno or group[-1].lineno
                    if not any("#" in text for text in lines[max(first - 2, 0) : last]):
                        hits.append((first, lines[first - 1].strip()))
            functions(child, inside or is_fn)

    functions(ast.parse(source), False)
    return sorted(hits)


def test_imports_inside_functions_say_why():
    files = [p for p in PACKAGE.rglob("*.py") if "data" not in p.relative_to(PACKAGE).parts]
    silent = [
        f"{p.relative_to(PACKAGE)}:{line} {text}"
        for p in files
        for line, text in _uncommented_lazy_imports(p.read_text(encoding="utf-8"))
    ]
    assert not silent, (
        f"{len(silent)} imports inside functions without a comment saying why (start-up, an "
        f"optional dependency...); expected one on their lines or just above: {silent}"
    )


def test_the_lazy_import_check_finds_a_silent_import():
    code = (
        "import os\n"
        "def a():\n    import json\n    return json\n"
        "def b():\n    # start-up: matplotlib takes 0.3 s\n    import matplotlib\n"
        "    from matplotlib import figure\n    return figure\n"
        "def c():\n    if True:\n        import csv  # optional\n"
        "def d():\n    x = 1\n    import re\n    from io import StringIO\n    return re, x\n"
        "def e():\n    import io  # start-up\n    io.x = 1\n    import gzip\n"
        "class F:\n    def g(self):\n        import bz2\n"
    )
    assert [line for line, _ in _uncommented_lazy_imports(code)] == [3, 15, 24]
