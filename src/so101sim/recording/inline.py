"""The files a recording wrote, shown inline in a Jupyter notebook.

:class:`RecordedFiles` is the ``{"video"/"plot"/"log": path}`` dict that
:meth:`~so101sim.recording.Recorder.close` returns (a dict like any other), with a
``_repr_html_``: as the last expression of a notebook cell (or with
``IPython.display.display``) it shows the video in a player and the plot as an image, embedded
in the page (files above :data:`MAX_INLINE_BYTES` are linked instead). Nothing here imports
IPython: Jupyter looks for ``_repr_html_`` itself.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path

MAX_INLINE_BYTES = 25_000_000
"""Largest file embedded in the notebook; a larger one is shown as a link to its path."""

_VIDEO_TYPES = {".mp4": "video/mp4", ".mov": "video/quicktime", ".mkv": "video/x-matroska"}
_IMAGE_TYPES = {".png": "image/png", ".jpg": "image/jpeg", ".svg": "image/svg+xml"}


def _data_url(path: Path, mime: str) -> str | None:
    try:
        if path.stat().st_size > MAX_INLINE_BYTES:
            return None
        return f"data:{mime};base64," + base64.b64encode(path.read_bytes()).decode("ascii")
    except OSError:
        return None


def _link(path: Path) -> str:
    return f'<a href="{html.escape(path.as_posix())}">{html.escape(str(path))}</a>'


def file_html(kind: str, path: Path) -> str:
    """One file as HTML: a video player, an image, or a link."""
    suffix = path.suffix.lower()
    label = f"<div><b>{html.escape(kind)}</b>: {_link(path)}</div>"
    if kind == "video" and suffix in _VIDEO_TYPES:
        url = _data_url(path, _VIDEO_TYPES[suffix])
        if url is not None:
            return f'{label}<video controls style="max-width:100%" src="{url}"></video>'
    if kind == "plot" and suffix in _IMAGE_TYPES:
        url = _data_url(path, _IMAGE_TYPES[suffix])
        if url is not None:
            return f'{label}<img style="max-width:100%" src="{url}"/>'
    return label


class RecordedFiles(dict):
    """``{"video"/"plot"/"log": Path}`` of the files written; shown inline in Jupyter."""

    def _repr_html_(self) -> str:
        if not self:
            return "<div>no files were written</div>"
        return "\n".join(file_html(kind, Path(path)) for kind, path in self.items())


__all__ = ["MAX_INLINE_BYTES", "RecordedFiles", "file_html"]
