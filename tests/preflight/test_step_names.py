"""A step's name is printed in every report on one line (issue 30): a motion file may not put
a control character (a newline, an escape) in a step's or a pose's name (MotionFileError at the
name's line), and a name given through the API is escaped wherever a report shows it."""

from __future__ import annotations

import pytest

from so101sim import cli
from so101sim.errors import MotionFileError, TrajectoryLimitError
from so101sim.motion import Hold, Move
from so101sim.preflight import check_motion_file, format_report, preflight
from so101sim.units import ZERO_POSE

ODD = "two\nlines\x1b[2K\u202e"  # a newline, an escape sequence, a right-to-left override


def _write(tmp_path, text: str):
    path = tmp_path / "names.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("text", "line", "what"),
    [
        ('[[steps]]\nhold = 0.1\nname = "two\\nlines"\n', 3, 'step 1 name "two\\u000alines"'),
        ('[[steps]]\nhold = 0.1\n[[steps]]\nname = "a\\tb"\nhold = 0.1\n', 4, "step 2 name"),
        ('[[steps]]\nhold = 0.1\nname = "\\u001b[1AOK"\n', 3, "U+001B at position 1"),
        ('[[steps]]\nhold = 0.1\nname = "x\\u202ey"\n', 3, "U+202E"),
        ('[poses]\n"up\\u001b" = { gripper = 5 }\n[[steps]]\nhold = 0.1\n', 2, "pose name"),
    ],
)
def test_a_motion_file_may_not_put_control_characters_in_a_name(tmp_path, text, line, what):
    path = _write(tmp_path, text)
    with pytest.raises(MotionFileError, match="control character") as err:
        check_motion_file(path)
    assert err.value.line == line and what in str(err.value)
    assert "\n" not in str(err.value) and "\x1b" not in str(err.value)


def test_the_check_command_says_where_the_bad_name_is(tmp_path, capsys):
    path = _write(tmp_path, '[[steps]]\nhold = 0.1\nname = "a\\nb"\n')
    assert cli.main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}:3: step 1 name" in err and err.count("\n") == 1, err


def test_plain_and_unicode_names_still_load(tmp_path):
    path = _write(tmp_path, '[[steps]]\nhold = 0.1\nname = "grüße 日本 ok"\n')
    report = check_motion_file(path)
    assert report.steps[0].phase == "grüße 日本 ok"
    assert "grüße 日本 ok"[:13] in format_report(report)


def test_a_name_from_the_api_is_escaped_in_the_report():
    plain = format_report(preflight([Move(ZERO_POSE, 0.05, shape="limited", phase="x")]))
    report = preflight([Move(ZERO_POSE, 0.05, shape="limited", phase=ODD)])
    text = format_report(report)
    assert report.steps[0].phase == ODD  # the data keeps what was given
    assert "\x1b" not in text and "\u202e" not in text
    assert text.count("\n") == plain.count("\n")  # every row stays one row
    row = next(r for r in text.splitlines() if r.startswith("1 "))
    assert row.startswith("1    two\\u000alin")  # escaped, then cut to the column
    stretched = [n for n in report.notes if "stretched" in n]
    assert stretched and "step 1 (two\\u000alines\\u001b[2K\\u202e)" in stretched[0]
    with pytest.raises(TrajectoryLimitError) as err:
        preflight([Hold(0.1, phase="ok"), Move(ZERO_POSE, 0.05, shape="limited", phase=ODD)],
                  strict=True)  # fmt: skip
    assert "step 2 (two\\u000alines" in str(err.value) and "\n" not in str(err.value)
