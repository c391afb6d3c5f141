"""In a notebook: a run's video and plot show inline (the Recorder's result has
``_repr_html_``), and the studio's URL is a link. No IPython needed for any of it."""

from __future__ import annotations

import base64
import re
import sys

import pytest

from so101sim import ZERO_POSE, Recorder, Simulation
from so101sim.recording.inline import RecordedFiles


def test_a_recordings_files_show_inline_as_a_video_and_an_image(tmp_path):
    sim = Simulation()
    video, plot, log = tmp_path / "run.mp4", tmp_path / "run.png", tmp_path / "run.csv"
    from so101sim.recording import VideoSettings

    settings = VideoSettings(width=160, height=120, fps=10, quality="draft")
    with Recorder(sim, video=video, plot=plot, log=log, settings=settings) as rec:
        sim.move_to(ZERO_POSE, 0.5)
    files = rec.outputs
    assert isinstance(files, RecordedFiles) and isinstance(files, dict)
    assert files == {"video": video, "log": log, "plot": plot}
    page = files._repr_html_()
    mp4 = re.search(r'<video controls[^>]*src="data:video/mp4;base64,([^"]+)"', page)
    png = re.search(r'<img[^>]*src="data:image/png;base64,([^"]+)"', page)
    assert mp4 and base64.b64decode(mp4.group(1)) == video.read_bytes()
    assert png and base64.b64decode(png.group(1))[:8] == b"\x89PNG\r\n\x1a\n"
    assert str(log) in page  # the log as a link
    assert rec._repr_html_() == page


def test_a_file_too_large_to_embed_is_a_link(tmp_path, monkeypatch):
    from so101sim.recording import inline

    big = tmp_path / "big.mp4"
    big.write_bytes(b"0" * 100)
    monkeypatch.setattr(inline, "MAX_INLINE_BYTES", 10)
    page = RecordedFiles(video=big)._repr_html_()
    assert "<video" not in page and str(big) in page


def test_the_studio_is_a_link_in_a_notebook_and_a_line_elsewhere(capsys):
    pytest.importorskip("viser")
    from so101sim.cli.studio import announce, in_notebook
    from so101sim.studio import Studio

    assert "IPython" not in sys.modules or not in_notebook()
    with Studio(Simulation().model, port=_free_port()) as studio:
        assert f'<a href="{studio.url}"' in studio._repr_html_()
        announce(studio.url)
    assert capsys.readouterr().out.strip() == (
        f"the studio: open {studio.url} in a web browser (Ctrl-C to stop)"
    )


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_in_a_jupyter_kernel_the_url_is_displayed_as_an_html_link(monkeypatch, capsys):
    import types

    from so101sim.cli.studio import announce

    shown = []
    ipython = types.ModuleType("IPython")
    ipython.get_ipython = lambda: types.SimpleNamespace(config={"IPKernelApp": {}})
    display = types.ModuleType("IPython.display")
    display.HTML = lambda text: ("HTML", text)
    display.display = shown.append
    monkeypatch.setitem(sys.modules, "IPython", ipython)
    monkeypatch.setitem(sys.modules, "IPython.display", display)
    announce("http://127.0.0.1:8123")
    assert shown == [
        ("HTML", 'the studio: <a href="http://127.0.0.1:8123" target="_blank">'
                 "http://127.0.0.1:8123</a>")
    ]  # fmt: skip
    assert capsys.readouterr().out == ""
