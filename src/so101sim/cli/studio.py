"""``--web`` on ``so101sim view``, ``run``, ``hold``, ``pose``, ``demo`` and ``record``: the
studio in a browser (:mod:`so101sim.studio`). Like :mod:`so101sim.cli` it only parses and
prints: :func:`add_web_options` adds ``--web``, ``--host``, ``--port`` and ``--linger`` to a
command's parser, and each ``*_web`` function is what that command runs with ``--web``. It
prints the page's URL, then serves until Ctrl-C, or until the run's end plus ``--linger``
seconds. Ctrl-C (or SIGTERM, SIGHUP) while serving ends the command with status 0 (the page
was the point); during a run it ends it as Ctrl-C ends any run (status 130, the output files
finished). While serving, a signal only sets a flag that the serving loop reads
(:class:`_UntilSignal`): raised as an exception it could land inside any callback running in
the main thread (a ``WeakSet``'s, the garbage collector's) and be swallowed there.
"""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

from .output import say

if TYPE_CHECKING:
    from ..studio import Studio

DEFAULT_PORT = 8080  # studio.DEFAULT_PORT, repeated: the parser imports no viser
DEFAULT_HOST = "127.0.0.1"
DEFAULT_LINGER = 300.0


def add_web_options(p: argparse.ArgumentParser, *, linger: bool = True) -> None:
    """``--web``, ``--host``, ``--port``, ``--no-shadows`` (and, for commands that end,
    ``--linger``)."""
    g = p.add_argument_group("web studio (the arm in a browser; no display or GPU needed)")
    g.add_argument("--web", action="store_true", help="show it in a web browser (the studio)")
    g.add_argument(
        "--host",
        default=DEFAULT_HOST,
        help=f"address the studio listens on (default {DEFAULT_HOST}: this machine only; "
        "0.0.0.0: every network interface, with a warning: anyone who reaches this machine "
        "can then move the arm)",
    )
    g.add_argument(
        "--port", type=int, default=DEFAULT_PORT, help=f"the studio's port (default {DEFAULT_PORT})"
    )
    g.add_argument(
        "--no-shadows",
        dest="shadows",
        action="store_false",
        help="draw the page without shadows: about 3x less work for a browser that draws on "
        "its CPU (no GPU, a slow page)",
    )
    if linger:
        g.add_argument(
            "--linger",
            type=float,
            default=DEFAULT_LINGER,
            metavar="S",
            help="seconds the studio stays up after the run, to replay it "
            f"(default {DEFAULT_LINGER:g}; Ctrl-C stops it sooner)",
        )


def in_notebook() -> bool:
    """True inside a Jupyter kernel (IPython is never imported here: only looked up)."""
    ipython = sys.modules.get("IPython")
    if ipython is None:
        return False
    with contextlib.suppress(Exception):
        shell = ipython.get_ipython()
        return shell is not None and "IPKernelApp" in getattr(shell, "config", {})
    return False


def announce(url: str, what: str = "the studio", studio: Any = None) -> None:
    """Print the page's URL (a link in a notebook), the addresses the studio really listens
    on, and a warning (stderr) when they reach beyond this machine."""
    if studio is not None and studio.warning:
        say(f"so101sim: warning: {studio.warning}", file=sys.stderr, flush=True)
    where = ""
    if studio is not None:
        scope = "beyond this machine" if studio.warning else "this machine only"
        where = f"; listening on {', '.join(studio.listening)}, {scope}"
    if in_notebook():
        with contextlib.suppress(Exception):
            # optional: IPython only inside a notebook
            from IPython.display import HTML, display

            display(HTML(f'{what}: <a href="{url}" target="_blank">{url}</a>{where}'))
            return
    say(f"{what}: open {url} in a web browser (Ctrl-C to stop{where})", flush=True)


class _UntilSignal:
    """While serving: SIGINT, SIGTERM and SIGHUP set :attr:`signum` (and interrupt the
    studio's waits) instead of raising, and the serving loop stops when it sees it. The
    handlers found are put back on the way out."""

    NAMES = ("SIGINT", "SIGTERM", "SIGHUP")

    def __init__(self) -> None:
        self.signum: int | None = None
        self.studio: Any = None
        self._previous: dict[int, Any] = {}

    def __bool__(self) -> bool:
        return self.signum is not None

    def _handle(self, signum: int, frame: object) -> None:
        if self.signum is None:
            self.signum = signum
        if self.studio is not None:
            self.studio.interrupt()

    def __enter__(self) -> _UntilSignal:
        if threading.current_thread() is threading.main_thread():
            for name in self.NAMES:
                if (signum := getattr(signal, name, None)) is not None:
                    self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        self._previous.clear()

    def sleep(self, seconds: float) -> None:
        """Wait ``seconds`` of wall-clock time, or until a signal."""
        end = time.monotonic() + seconds
        while self.signum is None and (left := end - time.monotonic()) > 0:
            time.sleep(min(left, 0.1))


def _studio(model: Any, args: argparse.Namespace, **kwargs: Any) -> Studio:
    # the studio (viser: the optional web extra) only for --web
    from ..studio import Studio

    studio = Studio(model, host=args.host, port=args.port, shadows=args.shadows, **kwargs)
    try:
        announce(studio.url, studio=studio)
    except BaseException:  # Ctrl-C while the URL is printed: nothing left serving
        studio.close()
        raise
    return studio


@contextlib.contextmanager
def _serving(studio: Studio) -> Iterator[Studio]:
    try:
        yield studio
    finally:
        studio.close()


def _linger(studio: Studio, seconds: float) -> None:
    """Keep the finished run on the page for ``seconds`` (a signal: at once)."""
    # the studio (viser: the optional web extra) only for --web
    from ..studio.server import check_linger

    seconds = check_linger(seconds)
    studio.finish()
    if seconds <= 0:
        return
    say(f"the run is over: replay it on the page for {seconds:g} s more (Ctrl-C to stop)")
    with _UntilSignal() as until:
        until.studio = studio
        until.sleep(seconds)
    if until:
        say("stopped")


# ---------------------------------------------------------------------------- view
def view_web(args: argparse.Namespace) -> int:
    """``view --web``: the model held at its starting pose, simulated live, until a signal."""
    # this command's modules, loaded when it runs (every other command starts without them)
    from ..model import load_model
    from ..sim.simulation import Pacer, Simulation
    from ..studio.live import StudioObserver
    from ..studio.net import check_host

    check_host(args.host)
    model = load_model(args.model, arm=getattr(args, "arm", None))
    sim = Simulation(model)
    with _UntilSignal() as until:
        studio = _studio(sim.model, args)
        until.studio = studio
        with _serving(studio):
            observer = StudioObserver(studio, Pacer(1.0))
            while not until:
                sim.hold(0.2, observers=[observer], phase="hold")
    say("stopped")
    return 0


# ---------------------------------------------------------------------------- run, hold
class WebRun:
    """``run --web`` / ``hold --web``: the full model (the page draws its meshes), the
    studio's observer for the run (at ``--speed``), and ``--linger`` seconds after it."""

    def __init__(self, args: argparse.Namespace) -> None:
        # the model and the studio (viser: the optional web extra) only for --web
        from ..model import load_model
        from ..studio.server import check_linger, check_port, ensure_free, require_viser

        self.args = args
        self.linger = check_linger(args.linger)
        require_viser()
        ensure_free(args.host, check_port(args.port))  # before anything runs
        self.model = load_model(args.model, arm=getattr(args, "arm", None))
        self.studio: Studio | None = None

    def observers(self, run: Any) -> list[Any]:
        # the studio (viser: the optional web extra) only for --web
        from ..studio.live import StudioObserver

        self.studio = _studio(run.sim.model, self.args)
        return [StudioObserver(self.studio, run.pacer, warn_lag=False)]  # the run says it

    def close(self, finished: bool) -> None:
        if self.studio is None:
            return
        try:
            if finished:
                _linger(self.studio, self.linger)
        finally:
            self.studio.close()


@contextlib.contextmanager
def web_run(args: argparse.Namespace) -> Iterator[WebRun | None]:
    """A :class:`WebRun` with ``--web`` (else None); the studio stays up ``--linger`` seconds
    after a run that ended, and is closed on the way out."""
    if not getattr(args, "web", False):
        yield None
        return
    web = WebRun(args)
    finished = False
    try:
        yield web
        finished = True
    finally:
        web.close(finished)


# ---------------------------------------------------------------------------- pose
def pose_web(args: argparse.Namespace) -> int:
    """``pose --web``: a slider per joint in the browser; each pose printed here (with a
    warning line when the tip or a part of the arm is below the floor or in the table)."""
    # this command's modules, loaded when it runs (every other command starts without them)
    from ..studio.net import check_host
    from ..studio.pose import PoseStudio

    check_host(args.host)
    with _UntilSignal() as until:
        studio = PoseStudio(args.model, host=args.host, port=args.port, shadows=args.shadows)
        until.studio = studio.studio
        with studio:
            announce(studio.url, "the pose finder", studio.studio)
            say(
                "Move the joint sliders on the page (degrees; gripper 0-100). Each pose the "
                "arm is left in is printed below; Ctrl-C to finish.",
                flush=True,
            )
            for change in studio.poses():
                say(format_pose(change), flush=True)
    say("stopped")
    return 0


def format_pose(change: Any, *, with_time: bool = False) -> str:
    """A pose as the pose finders print it: a dict, a TOML line, the tip, the warnings."""
    # start-up: the pose finder's formatting (it imports MuJoCo) only when a pose is printed
    from ..viewer.posefinder import format_python, format_toml

    when = f" (t = {change.time:.1f} s)" if with_time else ""
    lines = [
        f"\n# pose {change.number}{when}",
        f"python: {format_python(change.pose)}",
        f"toml:   {format_toml(f'pose_{change.number}', change.pose)}",
    ]
    if change.tip is not None:
        lines.append(f"tip:    {change.tip.format()}")
    lines += [f"warning: {w}" for w in getattr(change, "warnings", ())]
    return "\n".join(lines)


# ---------------------------------------------------------------------------- demo
def demo_web(args: argparse.Namespace, format_figures: Any) -> int:
    """``demo TASK --web``: the scripted expert's episode live in the studio
    (``format_figures``: cli_demo's, passed in: this module imports no other command)."""
    # this command's modules, loaded when it runs (every other command starts without them)
    from ..envs import env_id
    from ..envs.run import make, run_episode
    from ..recording import VideoRecorder, VideoSettings
    from ..sim.simulation import Pacer
    from ..studio.live import StudioObserver
    from ..studio.server import check_linger

    env_id(args.task)  # an unknown task: SettingError listing the tasks
    check_linger(args.linger)
    fields = ("width", "height", "fps", "camera", "quality", "caption")
    settings = VideoSettings(**{name: getattr(args, name) for name in fields}).validated()
    kwargs: dict[str, Any] = {"terminate_on_success": False}
    if args.record and settings.camera != "free":
        kwargs["render_camera"] = settings.camera
    env = make(args.task, **kwargs)
    recorder = None
    try:
        inner = env.unwrapped
        if args.record:
            recorder = VideoRecorder(args.record, inner.model, settings, force=args.force)
        with _serving(_studio(inner.model, args)) as studio:
            observer = StudioObserver(studio, Pacer(1.0))
            inner.sim.observers.append(observer)
            try:
                result = run_episode(env, args.seed, video=recorder, linger=1.0)
            finally:
                inner.sim.observers.remove(observer)
                written = recorder.close() if recorder is not None else None
                recorder = None
            status = (
                f"success at t = {result.success_time:.2f} s"
                if result.success_time is not None
                else "FAILED"
            )
            say(f"{args.task}, seed {result.seed}: {status} ({result.sim_time:.2f} s simulated)")
            say(format_figures(result.figures))
            if written is not None:
                say(f"wrote the video to {written}")
            _linger(studio, args.linger)
    finally:
        if recorder is not None:
            recorder.close()
        env.close()
    return 0 if result.success else 1


# ---------------------------------------------------------------------------- record
def record_web(args: argparse.Namespace, options: dict[str, Any]) -> int:
    """``record SCRIPT --web``: the student's script live in the studio as it runs (its
    ``launch_passive`` viewer draws in the page, paced to real time); with ``-o`` recorded
    too."""
    # this command's modules, loaded when it runs (every other command starts without them)
    from ..lab.handin import run_script
    from ..studio.live import StudioViewer
    from ..studio.server import check_linger, check_port, ensure_free, require_viser

    check_linger(args.linger)
    require_viser()
    ensure_free(args.host, check_port(args.port))  # before the script runs
    holder: dict[str, Studio] = {}

    def live(m: Any, d: Any) -> StudioViewer:
        studio = _studio(m, args)
        holder["studio"] = studio
        return StudioViewer(studio, m, d)

    try:
        run = run_script(args.script, list(args.script_args), args.output, live=live, **options)
        if run.message:
            say(run.message, file=sys.stderr)
        for kind, path in run.outputs.items():
            say(f"wrote the {kind} to {path}")
        say(f"{args.script}: {run.simulated_seconds:.3f} s of simulated time")
        if "studio" in holder:
            _linger(holder["studio"], args.linger)
        return run.exit_status
    finally:
        if "studio" in holder:
            holder["studio"].close()
