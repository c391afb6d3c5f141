"""A cache of compiled models on disk, so a new process loads the SO-101 in a fraction of the
time (and memory) that compiling its meshes takes.

Compiling ``scene.xml`` parses 13 STL meshes (~322k triangles) and builds their collision
trees: about a second and a few hundred MB at its peak. The compiled model saved in MuJoCo's
binary format (MJB) loads in a fifth of that time, bit for bit the same model.

* **Key:** a SHA-256 of every file in the model's folder (the MJCF, its includes and its
  meshes: the content, not the dates), the model file's name, MuJoCo's version and a ``variant``
  (e.g. a render preset). Change any of them and the model is compiled again.
* **Where:** ``$SO101SIM_CACHE_DIR``, else ``$XDG_CACHE_HOME/so101sim``, else
  ``~/.cache/so101sim``. ``SO101SIM_NO_CACHE=1`` turns the cache off.
* **Physics only:** ``load_or_compile(..., physics_only=True)`` keeps a second entry, the model
  without its visual geoms, its collision meshes as their convex hulls
  (:mod:`so101sim.model.trim`): 18 MB instead of 67, for runs that never draw.
* **Fast key:** each model folder's digest is remembered (``digests/``) with its files' sizes,
  times and inodes; while they are unchanged, the files are not read and hashed again.
* **Safe:** an entry is written under a temporary name in the same folder and renamed, so two
  processes never see half a file; an entry that does not load is deleted and the model is
  compiled. Any failure to read or write the cache (a read-only home, a full disk) falls back
  to compiling, with a DEBUG log line.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco

from . import trim as modeltrim

log = logging.getLogger(__name__)

MAX_HASHED_BYTES = 512 * 1024 * 1024
"""A model folder larger than this is not cached (hashing it would cost more than compiling)."""

ENTRY_SUFFIX = ".mjb"
REFUSED_SUFFIX = ".refused"  # a model the physics-only copy was refused for (empty file)
MEMO_FOLDER = "digests"  # each model folder's content digest, with its files' stat results
MEMO_SETTLE_S = 2.0  # files changed more recently than this are hashed again next time


def cache_dir() -> Path:
    """The folder the compiled models are kept in (it may not exist yet)."""
    env = os.environ.get("SO101SIM_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "so101sim"


def enabled() -> bool:
    """False when ``SO101SIM_NO_CACHE`` is set to anything but "" or "0"."""
    return os.environ.get("SO101SIM_NO_CACHE", "") in ("", "0")


def _folder_digest(folder: Path) -> str | None:
    """SHA-256 over the names and contents of every file under ``folder`` (sorted), or None
    when it holds more than :data:`MAX_HASHED_BYTES` or cannot be read.

    The digest is remembered in the cache folder with each file's size, modification and
    change times and inode: while none of them changed, the files are not read again (files
    changed in the last :data:`MEMO_SETTLE_S` seconds are not remembered)."""
    try:
        files = sorted(p for p in folder.rglob("*") if p.is_file())
        stats = [(p, p.stat()) for p in files]
    except OSError as exc:
        log.debug("model cache: cannot list %s: %s", folder, exc)
        return None
    if sum(st.st_size for _, st in stats) > MAX_HASHED_BYTES:
        return None
    signature = "\n".join(
        f"{p.relative_to(folder)}\t{st.st_size}\t{st.st_mtime_ns}\t{st.st_ctime_ns}\t{st.st_ino}"
        for p, st in stats
    )
    memo = _digest_memo(folder)
    with contextlib.suppress(OSError, ValueError):
        digest, _, remembered = memo.read_text("utf-8", "surrogateescape").partition("\n")
        if remembered == signature and len(digest) == 64:
            return digest
    h = hashlib.sha256()
    try:
        for p, _ in stats:
            h.update(str(p.relative_to(folder)).encode())
            h.update(b"\0")
            h.update(p.read_bytes())
            h.update(b"\0")
    except OSError as exc:
        log.debug("model cache: cannot hash %s: %s", folder, exc)
        return None
    digest = h.hexdigest()
    # A file changed in the last moments could change again within the file system's clock
    # tick and keep its times: remember only files that have settled.
    settled = time.time_ns() - MEMO_SETTLE_S * 1e9
    if all(st.st_ctime_ns < settled and st.st_mtime_ns < settled for _, st in stats):
        try:
            text = f"{digest}\n{signature}"
            _write_with(memo, lambda tmp: Path(tmp).write_text(text, "utf-8", "surrogateescape"))
        except (OSError, ValueError) as exc:
            log.debug("model cache: cannot write %s: %s", memo, exc)
    return digest


def _digest_memo(folder: Path) -> Path:
    name = hashlib.sha256(str(folder.resolve()).encode()).hexdigest()[:32]
    return cache_dir() / MEMO_FOLDER / f"{name}.txt"


def key_for(path: Path, variant: str = "") -> str | None:
    """The cache key of the model file ``path`` (None: not cacheable)."""
    digest = _folder_digest(path.parent)
    if digest is None:
        return None
    h = hashlib.sha256(f"{digest}\0{path.name}\0{mujoco.__version__}\0{variant}".encode())
    return h.hexdigest()[:32]


def _write(entry: Path, model: mujoco.MjModel) -> None:
    _write_with(entry, lambda tmp: mujoco.mj_saveModel(model, tmp, None))


def _write_bytes(entry: Path, data: bytes) -> None:
    _write_with(entry, lambda tmp: Path(tmp).write_bytes(data))


def _write_with(entry: Path, write: Callable[[str], object]) -> None:
    """``write(tmp)`` a file next to ``entry``, then rename it to ``entry`` (atomic)."""
    entry.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".", suffix=".partial", dir=entry.parent)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, entry)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _read(entry: Path) -> mujoco.MjModel | None:
    try:
        return mujoco.MjModel.from_binary_path(str(entry))
    except (ValueError, OSError, mujoco.FatalError) as exc:
        log.debug("model cache: %s does not load (%s); compiling again", entry, exc)
        with contextlib.suppress(OSError):
            entry.unlink()
        return None


def load_or_compile(
    path: Path,
    compile_fn: Callable[[], mujoco.MjModel],
    *,
    variant: str = "",
    physics_only: bool = False,
) -> mujoco.MjModel:
    """The model compiled from ``path``: from the cache when an entry for its current content
    exists, else ``compile_fn()`` (then saved to the cache when possible).

    ``physics_only``: the model without what only drawing and ray casting use
    (:func:`so101sim.model.trim.physics_only`: the same physics, about a quarter of the
    memory), kept as its own entry; the full model when the cache is off or unwritable or
    the model cannot be trimmed."""
    if not enabled():
        return compile_fn()
    key = key_for(path, variant)
    if key is None:
        return compile_fn()
    if physics_only:
        return _physics_only(path, compile_fn, variant, key)
    entry = cache_dir() / f"{key}{ENTRY_SUFFIX}"
    if entry.is_file():
        model = _read(entry)
        if model is not None:
            log.debug("model cache: loaded %s from %s", path, entry)
            return model
    model = compile_fn()
    try:
        _write(entry, model)
        log.debug("model cache: saved %s to %s", path, entry)
    except OSError as exc:
        log.debug("model cache: cannot write %s: %s", entry, exc)
    return model


def _physics_only(
    path: Path, compile_fn: Callable[[], mujoco.MjModel], variant: str, key: str
) -> mujoco.MjModel:
    name = f"{key}-physics{modeltrim.VERSION}"
    entry = cache_dir() / f"{name}{ENTRY_SUFFIX}"
    refused = cache_dir() / f"{name}{REFUSED_SUFFIX}"  # trimming refused: do not try again
    if entry.is_file():
        model = _read(entry)
        if model is not None:
            log.debug("model cache: loaded %s (physics only) from %s", path, entry)
            return model
    full = load_or_compile(path, compile_fn, variant=variant)
    if refused.is_file():
        return full
    try:
        spec = mujoco.MjSpec.from_file(str(path))
    except (ValueError, OSError, mujoco.FatalError) as exc:
        log.debug("model cache: cannot read %s as a spec (%s)", path, exc)
        return full
    trimmed = modeltrim.physics_only(spec, full)
    try:
        if trimmed is None:
            _write_bytes(refused, b"")
            return full
        _write(entry, trimmed)
    except OSError as exc:
        log.debug("model cache: cannot write %s: %s", entry, exc)
        return full if trimmed is None else trimmed
    return _read(entry) or trimmed


@dataclass(frozen=True)
class CacheInfo:
    """What the cache holds: its folder, the number of entries and their size in bytes."""

    folder: Path
    entries: int
    size: int


def info() -> CacheInfo:
    """The cache's folder, number of entries and total size."""
    folder = cache_dir()
    files = list(folder.glob(f"*{ENTRY_SUFFIX}")) if folder.is_dir() else []
    return CacheInfo(folder, len(files), sum(f.stat().st_size for f in files))


def clear() -> CacheInfo:
    """Delete every cached model; return what was deleted."""
    before = info()
    if before.folder.is_dir():
        for f in before.folder.glob(f"*{ENTRY_SUFFIX}"):
            f.unlink(missing_ok=True)
        for f in before.folder.glob(f"*{REFUSED_SUFFIX}"):
            f.unlink(missing_ok=True)
        for f in before.folder.glob(".*.partial"):
            f.unlink(missing_ok=True)
        for f in before.folder.glob(f"{MEMO_FOLDER}/*"):
            f.unlink(missing_ok=True)
    return before
