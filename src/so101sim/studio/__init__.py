"""The studio: the arm in a web browser, live or replayed, and a pose finder in the arm's units.

Works on a server with no display and no GPU (the browser draws); needs the ``web`` extra
(``pip install "so101sim[web]"``: viser and mjviser). The command line's ``--web`` option
(``so101sim view/run/hold/pose/demo/record/compare --web``) uses it; from Python::

    sim = so101sim.Simulation()
    studio = so101sim.studio.attach(sim)   # in Jupyter the cell shows the link
    sim.move_to({"shoulder_lift": 0}, 2.0)  # shown live, at real time
    studio.finish()                         # the page's timeline replays the run
    studio.close()

* :mod:`.server`: :class:`Studio` (the server, the page, the run's player);
* :mod:`.timeline`: a run's frames, bounded in memory (``Frame``, ``Timeline``);
* :mod:`.net`: the host and port checked, the addresses it listens on (warned beyond this
  machine), the guard that refuses a websocket from another site;
* :mod:`.look`: the model's floor, sky and lights, the camera on the arm, the docked panel;
* :mod:`.ready`: the page's "the arm is drawn" signal (``#so101sim-ready``);
* :mod:`.live`: :class:`StudioObserver` (a run, paced to the wall clock) and
  :class:`StudioViewer` (``launch_passive`` for a script);
* :mod:`.pose`: :class:`PoseStudio` (one slider per joint, the tip, copy buttons, warnings
  when the arm is in the floor or the table);
* :mod:`.compare`: :class:`CompareStudio` (``so101sim compare --web``: a recording's episodes
  replayed, the sim's arm beside the real arm drawn as a translucent ghost, :mod:`.ghost`).

May import: ``so101sim.viewer`` (the pose finder's watcher, scene and warnings),
``so101sim.recording``, ``so101sim.motion``, ``so101sim.sim``, ``so101sim.kinematics``,
``so101sim.model``, ``so101sim.units`` and the base modules; viser and mjviser only when a
studio starts.
"""

from __future__ import annotations

from typing import Any

from .server import DEFAULT_HOST, DEFAULT_PORT, Studio, StudioError, require_viser


def attach(
    sim: Any,
    *,
    host: str = DEFAULT_HOST,
    port: int = DEFAULT_PORT,
    speed: float = 1.0,
    shadows: bool = True,
):
    """Serve a studio showing ``sim`` (a :class:`~so101sim.sim.Simulation`) and add its
    observer to ``sim.observers``: every move and hold is then shown live at ``speed`` times
    real time. Returns the :class:`Studio` (``close()`` it; ``finish()`` to replay the run).
    ``shadows=False``: no shadows on the page (a browser without a GPU draws it faster)."""
    # start-up: the simulation and the live studio only when attached
    from ..sim.simulation import Pacer
    from .live import StudioObserver

    pacer = Pacer(speed)
    studio = Studio(sim.model, host=host, port=port, shadows=shadows)
    observer = StudioObserver(studio, pacer)
    sim.observers.append(observer)
    close = studio.close

    def detach_and_close() -> None:
        if observer in sim.observers:
            sim.observers.remove(observer)
        close()

    studio.close = detach_and_close  # type: ignore[method-assign]
    return studio


__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "Studio", "StudioError", "attach", "require_viser"]
