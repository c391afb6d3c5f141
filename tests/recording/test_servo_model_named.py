"""Every output names the servo model that ran (issue 29 point 2): the CSV log's
``servo_model`` column (old logs without it still read), the plot's heading, the video's
caption."""

from __future__ import annotations

import csv

import numpy as np
from recording_helpers import SMALL

from so101sim import Simulation
from so101sim import recording as rec
from so101sim.fidelity.logs import read_log
from so101sim.model import arm_units, load_model, servo_model
from so101sim.recording import recorder as recorder_module


def test_the_csv_log_names_the_servo_model_and_old_logs_still_read(tmp_path):
    sim = Simulation(arm="official")
    log = tmp_path / "run.csv"
    with rec.Recorder(sim, log=log):
        sim.move_to({**sim.pose(), "elbow_flex": 20.0}, 0.1)
    with open(log, newline="") as fh:
        rows = list(csv.reader(fh))
    assert rows[0] == rec.csv_columns() and rows[0][-1] == "servo_model"
    assert {r[-1] for r in rows[1:]} == {"official"}
    old = tmp_path / "old.csv"  # a log written before the column was added
    old.write_text("\n".join(",".join(r[:-1]) for r in rows) + "\n")
    units = arm_units(sim.model)
    new_log, old_log = read_log(log, units), read_log(old, units)
    np.testing.assert_array_equal(new_log.episodes[0].command, old_log.episodes[0].command)
    np.testing.assert_array_equal(new_log.episodes[0].measured, old_log.episodes[0].measured)


def test_the_plot_heading_and_the_video_caption_name_it(tmp_path, monkeypatch):
    seen = {}
    real = recorder_module.plot_run

    def spy(*args, **kwargs):
        seen.update(kwargs)
        return real(*args, **kwargs)

    monkeypatch.setattr(recorder_module, "plot_run", spy)
    sim = Simulation()
    with rec.Recorder(sim, video=tmp_path / "a.mp4", plot=tmp_path / "a.png", settings=SMALL) as r:
        sim.hold(0.1)
        caption = r.video.caption(sim.data)
    assert seen["servo"] == servo_model(load_model()) and seen["servo"].startswith("sts3215 (")
    assert caption.endswith("servos: sts3215"), caption


def test_the_plot_heading_names_no_command_it_did_not_come_from(tmp_path, monkeypatch):
    # `so101sim record my_lab.py --plot` draws the same plot as `run`: its heading said
    # "so101sim run:" for a run of the student's own script
    from matplotlib.figure import Figure

    headings = []
    real = Figure.suptitle
    monkeypatch.setattr(
        Figure, "suptitle", lambda fig, t, **kw: headings.append(t) or real(fig, t, **kw)
    )
    sim = Simulation(arm="official")
    with rec.Recorder(sim, plot=tmp_path / "a.png", settings=SMALL):
        sim.hold(0.1)
    assert headings == [
        "so101sim: commanded vs measured joint angles\n"
        "servo model: official (the model file's own ideal position actuators)"
    ]
