"""Control characters escaped in everything printed (issue 30): a step named
``"\\u001b[1A\\u001b[2KPASS"`` reached the terminal raw and rewrote the verdict line."""

from __future__ import annotations

import logging

import pytest

from so101sim import cli
from so101sim.cli.output import EscapingFormatter, escape_controls, say

NAME = "\x1b[1A\x1b[2KPASS"


def test_escape_controls_keeps_lines_and_tabs_and_escapes_the_rest() -> None:
    text = "a\tb\nc\x1b[2K\r\x07\x7f\x9b\u202e\u2066d"
    assert escape_controls(text) == "a\tb\nc\\u001b[2K\\u000d\\u0007\\u007f\\u009b\\u202e\\u2066d"
    assert escape_controls("one\nname\t", lines=False) == "one\\u000aname\\u0009"
    assert escape_controls("plain: ü, °, 日本") == "plain: ü, °, 日本"


def test_say_escapes_what_it_prints(capsys) -> None:
    say("step", NAME, end="!\n")
    out = capsys.readouterr().out
    assert out == "step \\u001b[1A\\u001b[2KPASS!\n"


def test_log_lines_are_escaped() -> None:
    record = logging.LogRecord("x", logging.WARNING, __file__, 1, "file %s", (NAME,), None)
    line = EscapingFormatter("%(levelname)s %(message)s").format(record)
    assert "\x1b" not in line and "\\u001b[1A" in line


def _motion(tmp_path, name: str):
    path = tmp_path / "m.toml"
    path.write_text(
        'start = "rest"\n[[steps]]\nname = "' + name.replace("\x1b", "\\u001b") + '"\nhold = 0.05\n'
    )
    return path


@pytest.mark.parametrize("command", [["check"], ["run", "--headless"]])
def test_a_step_name_with_escapes_reaches_the_terminal_escaped(tmp_path, capsys, command):
    """The loader refuses it (tests/preflight/test_step_names.py); its error shows it escaped."""
    code = cli.main([*command, str(_motion(tmp_path, NAME))])
    out, err = capsys.readouterr()
    assert code == 2, err
    assert "\x1b" not in out + err
    assert "\\u001b[1A\\u001b[2KPASS" in err and "control character" in err


def test_an_error_naming_a_file_is_escaped(tmp_path, capsys) -> None:
    code = cli.main(["check", str(tmp_path / f"no{NAME}.toml")])
    out, err = capsys.readouterr()
    assert code == 2
    assert "\x1b" not in out + err and "\\u001b[1A" in err


def test_every_printer_of_the_command_line_goes_through_say() -> None:
    """No ``print(`` in cli/ but the one inside ``say``: a new printer cannot skip escaping."""
    import ast
    from pathlib import Path

    import so101sim.cli

    calls = []
    for path in Path(so101sim.cli.__file__).parent.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "print":
                calls.append(f"{path.name}:{node.lineno}")
    assert len(calls) == 1 and calls[0].startswith("output.py"), calls
