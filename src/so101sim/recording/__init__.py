"""Recording a run: an MP4 video, a plot of commanded vs measured angles, and a CSV log.

Everything here is an :class:`so101sim.sim.simulation.Observer`, so any run of moves and holds can
write to it, and all of it is clocked by *simulated* time: a 6 s motion at 30 frames/s is
181 frames (t = 0, 1/30, …, 6 s) however fast the machine renders.

>>> sim = Simulation()
>>> with Recorder(sim, video="lab.mp4", plot="lab.png", log="lab.csv"):
...     sim.move_to(ZERO_POSE, 2.0, phase="to_zero")
...     sim.hold(2.0)

Every output path is checked (folder exists and files can be created there, name within the
file system's limit, file absent unless ``force=True``, never a device or a pipe) before
anything runs. Files are written under a temporary name in the same folder and renamed when
closed (a video only after ffmpeg succeeded and the file was read back), also after Ctrl-C or
an error, so a path holds either a complete, playable file of what ran or nothing. A file
that cannot be written (a full disk) raises :class:`~so101sim.errors.OutputPathError`. The log
streams to disk and the plot keeps a bounded envelope of the steps, so memory stays flat
however long the run.

Rendering uses ``mujoco.Renderer`` on a private copy of the model (its offscreen buffer raised
to the frame size), fed the simulation's joint angles: the physics model is never touched.
The ``draft`` quality preset (the default on a CPU) swaps the visual meshes for simplified ones
shipped in ``so101sim/data/draft_meshes``, draws the infinite floor as a few quads instead of
MuJoCo's 200 × 200 (the same pixels, :mod:`.floor`) and turns off shadows, reflections and
multisampling, which makes a CPU renderer (Mesa llvmpipe) about 20× faster; ``full`` keeps the
model's look. Importing this package sets no environment variable: the OpenGL backend is chosen
when the first renderer starts (:func:`so101sim.gl.prepare_for_rendering`).

The modules, one job each:

- :mod:`.settings`: :class:`VideoSettings`, quality presets, cameras;
- :mod:`.paths`: output path checks, files written under a temporary name, write errors;
- :mod:`.draft`: the private render model and the ``draft`` meshes;
- :mod:`.floor`: the draft preset's infinite planes drawn as a few quads;
- :mod:`.frames`: :class:`FrameRenderer` (offscreen frames) and the caption;
- :mod:`.encoder`: the ffmpeg process a video is piped to, and reading a video back;
- :mod:`.video`: :class:`VideoRecorder` (MP4), :func:`video_frames`;
- :mod:`.csvlog`: :class:`CsvLog`, :func:`csv_columns`;
- :mod:`.envelope`: a bounded summary of a run's steps (smallest and largest per bucket);
- :mod:`.plot`: :class:`RunLog`, :class:`TraceCollector`, :func:`plot_run`;
- :mod:`.recorder`: :class:`Recorder`, all of the above at once.

May import: ``so101sim.scenes`` (a scene's cameras), ``so101sim.motion``, ``so101sim.sim``,
``so101sim.kinematics``, ``so101sim.model``, ``so101sim.units`` and the base modules.
"""

from typing import TYPE_CHECKING

from .._lazy import lazy_names

# Each name is imported from its module on first use (PEP 562), only to keep start-up fast:
# a headless run that writes nothing (so101sim run --headless) imports .settings and no more.
# The names are those imported under TYPE_CHECKING (read by so101sim._lazy); the submodules
# (so101sim.recording.video, ...) are attributes too, imported on first use.
if TYPE_CHECKING:
    from .csvlog import CsvLog, csv_columns
    from .draft import SHIPPED_MODEL_FILES, draft_mesh_dir, draft_source, render_model
    from .frames import FrameRenderer
    from .paths import check_output_path
    from .plot import MAX_PLOT_POINTS, PLOT_SUFFIXES, RunLog, TraceCollector, plot_run
    from .recorder import Recorder
    from .settings import (
        FREE_CAMERA,
        MAX_FPS,
        MAX_FRAME_SIZE,
        QUALITIES,
        QUALITY_CHOICES,
        VideoSettings,
        camera_names,
        check_camera,
        resolve_quality,
    )
    from .video import VIDEO_SUFFIXES, VideoRecorder, video_frames


__getattr__, __dir__ = lazy_names(__name__)
