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
* **Verified:** beside each entry, ``<entry>.digest`` holds its size, the CRC-32 of its
  bytes and the entry's own name (its key and kind: ``<key>`` or ``<key>-physics<N>``), all
  checked before MuJoCo reads them (an entry renamed or swapped with another, digests
  included, is refused: each is bound to what it holds); a truncated or changed entry never
  reaches MuJoCo (CRC-32 finds any burst of changed bits up to 32 long, and others but for 1
  in 4 billion, at a sixth of SHA-256's cost); a loaded model is then checked against the
  source file (parsed, not compiled): its joints (names, ranges), actuators (names, gains)
  and options (timestep, gravity). A bad or foreign entry is deleted and the model compiled
  again, with one WARNING through :mod:`logging`.
* **Safe:** the digest and then the entry are written under temporary names in the same folder
  and renamed, so two processes never see half a file. Any failure to read or write the cache (a
  read-only home, a full disk) falls back to compiling, with a DEBUG log line. Temporary files
  a killed process left (``.*.partial``, older than :data:`STALE_PARTIAL_S`) are deleted by
  the next write.
* **Bounded:** a model folder over :data:`MAX_HASHED_BYTES` is not cached (one WARNING per
  folder says so).

The key hashes the folder's files on every load: about 10 ms for the SO-101's 16 MB.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import tempfile
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from ..errors import SettingError
from . import trim as modeltrim

log = logging.getLogger(__name__)

MAX_HASHED_BYTES = 512 * 1024 * 1024
"""A model folder larger than this is not cached (hashing it would cost more than compiling)."""

STALE_PARTIAL_S = 3600.0
"""A temporary ``.*.partial`` file older than this (seconds since it was last written) was
left by a process that was killed: the next write deletes it. A live writer takes seconds."""

_warned_large: set[Path] = set()  # the folders the "too large to cache" warning named

ENTRY_SUFFIX = ".mjb"
DIGEST_SUFFIX = ".digest"  # beside each entry: its size and the CRC-32 of its bytes
REFUSED_SUFFIX = ".refused"  # a model the physics-only copy was refused for (empty file)
FORMAT = 3  # part of every key: raised when what an entry holds or how it is checked changes


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
    when it holds more than :data:`MAX_HASHED_BYTES` or cannot be read."""
    try:
        files = sorted(p for p in folder.rglob("*") if p.is_file())
        total = sum(p.stat().st_size for p in files)
        if total > MAX_HASHED_BYTES:
            if folder not in _warned_large:
                _warned_large.add(folder)
                log.warning(
                    "model cache: not caching the model in %s: its folder holds %.0f MB, more "
                    "than the %.0f MB the cache hashes (each load compiles it); expected a "
                    "folder holding only the model's files",
                    folder, total / 1e6, MAX_HASHED_BYTES / 1e6,
                )  # fmt: skip
            return None
        h = hashlib.sha256()
        for p in files:
            h.update(str(p.relative_to(folder)).encode())
            h.update(b"\0")
            h.update(p.read_bytes())
            h.update(b"\0")
    except OSError as exc:
        log.debug("model cache: cannot hash %s: %s", folder, exc)
        return None
    return h.hexdigest()


def key_for(path: Path, variant: str = "") -> str | None:
    """The cache key of the model file ``path`` (None: not cacheable)."""
    digest = _folder_digest(path.parent)
    if digest is None:
        return None
    text = f"{digest}\0{path.name}\0{mujoco.__version__}\0{variant}\0{FORMAT}"
    h = hashlib.sha256(text.encode())
    return h.hexdigest()[:32]


def _digest_of(entry: Path) -> Path:
    return entry.with_name(entry.name + DIGEST_SUFFIX)


def _digest(entry: Path, size: int, crc: int) -> str:
    """The digest line of ``entry``: its size, CRC-32 and name (key and kind, bound to it)."""
    return f"{size} crc32 {crc:08x} {entry.name.removesuffix(ENTRY_SUFFIX)}"


def _file_digest(path: Path) -> str:
    """:func:`_digest` of the file ``path``, read in pieces (never held whole in memory)."""
    crc, size = 0, 0
    with path.open("rb") as f:
        while chunk := f.read(1 << 20):
            crc, size = zlib.crc32(chunk, crc), size + len(chunk)
    return _digest(path, size, crc)


def _write(entry: Path, model: mujoco.MjModel) -> None:
    """Save ``model`` as ``entry``, its digest first (both renamed into place)."""
    data = _mjb_bytes(model)
    digest = _digest(entry, len(data), zlib.crc32(data))
    _write_with(_digest_of(entry), lambda tmp: Path(tmp).write_text(digest))
    _write_with(entry, lambda tmp: Path(tmp).write_bytes(data))


def _mjb_bytes(model: mujoco.MjModel) -> bytes:
    buffer = np.empty(mujoco.mj_sizeModel(model), dtype=np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer.tobytes()


def _write_with(entry: Path, write: Callable[[str], object]) -> None:
    """``write(tmp)`` a file next to ``entry``, then rename it to ``entry`` (atomic)."""
    entry.parent.mkdir(parents=True, exist_ok=True)
    remove_stale_partials(entry.parent)
    fd, tmp = tempfile.mkstemp(prefix=".", suffix=".partial", dir=entry.parent)
    os.close(fd)
    try:
        write(tmp)
        os.replace(tmp, entry)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def remove_stale_partials(folder: Path, older_than: float = STALE_PARTIAL_S) -> int:
    """Delete the temporary files (``.*.partial``) in ``folder`` last written more than
    ``older_than`` seconds ago: left by a process killed while it wrote (a live writer
    renames its file within seconds). Returns how many were deleted."""
    now, gone = time.time(), 0
    for f in folder.glob(".*.partial"):
        with contextlib.suppress(OSError):  # another process deleted or renamed it first
            if f.is_file() and now - f.stat().st_mtime > older_than:
                f.unlink()
                gone += 1
    if gone:
        log.debug("model cache: deleted %d temporary file(s) left by killed processes", gone)
    return gone


def _read(entry: Path, source: Path, gains: bool = True) -> mujoco.MjModel | None:
    """The model in ``entry`` if it is whole (its digest) and is the model of ``source``; else
    None, the entry deleted and one warning logged. None without a word when there is none."""
    if not entry.is_file():
        return None
    try:
        actual = _file_digest(entry)
        expected = _digest_of(entry).read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError) as exc:
        problem = f"cannot be read or has no digest ({exc})"
    else:
        problem = "does not match its digest (truncated or changed)"
        if expected.split(" ")[3:] != actual.split(" ")[3:]:
            problem = "holds another entry (its digest names another key or kind)"
        elif actual == expected:
            try:
                # an entry is only ever replaced whole (renamed into place): what MuJoCo reads
                # here is what was hashed, or another whole entry of the same key
                model = mujoco.MjModel.from_binary_path(str(entry))
                problem = _foreign(model, source, gains)
            except (ValueError, OSError, mujoco.FatalError) as exc:
                problem = f"does not load ({exc})"
            if problem is None:
                return model
    log.warning("model cache: %s %s; compiling %s again", entry, problem, source)
    for path in (entry, _digest_of(entry)):
        with contextlib.suppress(OSError):
            path.unlink()
    return None


def _foreign(model: mujoco.MjModel, source: Path, gains: bool = True) -> str | None:
    """How ``model`` differs from the model file ``source`` (parsed, not compiled): its joints
    (names, ranges), actuators (names, and gains unless ``gains`` is False: an arm profile
    replaces them by design) or options (timestep, gravity); None if it does not."""
    try:
        spec = mujoco.MjSpec.from_file(str(source))
    except (ValueError, OSError, mujoco.FatalError) as exc:
        return f"cannot be checked against its source ({exc})"
    angular = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_BALL)
    scale = {
        j.name: np.pi / 180 if spec.compiler.degree and j.type in angular else 1.0
        for j in spec.joints
    }
    joints = {j.name: np.asarray(j.range) * scale[j.name] for j in spec.joints}
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, i) for i in range(model.njnt)]
    if sorted(map(str, names)) != sorted(joints):
        return "is another model (other joints)"
    for i, name in enumerate(names):
        if not np.allclose(model.jnt_range[i], joints[str(name)], rtol=1e-9, atol=1e-12):
            return f"is another model (the range of joint {name!r})"
    actuators = {a.name: np.asarray(a.gainprm) for a in spec.actuators}
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, i) for i in range(model.nu)]
    if sorted(map(str, names)) != sorted(actuators):
        return "is another model (other actuators)"
    for i, name in enumerate(names if gains else ()):
        if not np.array_equal(model.actuator_gainprm[i], actuators[str(name)]):
            return f"is another model (the gains of actuator {name!r})"
    if model.opt.timestep != spec.option.timestep or not np.array_equal(
        model.opt.gravity, spec.option.gravity
    ):
        return "is another model (its timestep or gravity)"
    return None


_ARM_KEY = "arm-"
"""In a variant, the mark of an arm profile's key (:func:`so101sim.model.arm.profile_key`): the
actuators' gains are the profile's, not the file's."""


def load_or_compile(
    path: Path,
    compile_fn: Callable[[], mujoco.MjModel],
    *,
    variant: str = "",
    physics_only: bool = False,
    spec_fn: Callable[[], mujoco.MjSpec] | None = None,
    compile_spec: Callable[[mujoco.MjSpec], mujoco.MjModel] | None = None,
) -> mujoco.MjModel:
    """The model compiled from ``path``: from the cache when an entry for its current content
    exists, else ``compile_fn()`` (then saved to the cache when possible).

    ``physics_only``: the model without what only drawing and ray casting use
    (:func:`so101sim.model.trim.physics_only`: the same physics, about a quarter of the
    memory), kept as its own entry; the full model when the cache is off or unwritable or
    the model cannot be trimmed. ``spec_fn``: the spec ``compile_fn`` compiles (the physics-only
    model is trimmed from it; default: the file's, e.g. an arm profile's spec otherwise).
    ``compile_spec``: how the physics-only model is compiled (the model builder's
    :func:`~so101sim.model.build.compile_spec`); needed with ``physics_only``.

    Raises:
        SettingError: ``physics_only`` without ``compile_spec``."""
    if not enabled():
        return compile_fn()
    key = key_for(path, variant)
    if key is None:
        return compile_fn()
    if physics_only:
        if compile_spec is None:
            raise SettingError(
                "load_or_compile(physics_only=True) needs compile_spec; expected the model "
                "builder's so101sim.model.build.compile_spec"
            )
        return _physics_only(path, compile_fn, variant, key, spec_fn, compile_spec)
    entry = cache_dir() / f"{key}{ENTRY_SUFFIX}"
    model = _read(entry, path, gains=_ARM_KEY not in variant)
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
    path: Path,
    compile_fn: Callable[[], mujoco.MjModel],
    variant: str,
    key: str,
    spec_fn: Callable[[], mujoco.MjSpec] | None,
    compile_spec: Callable[[mujoco.MjSpec], mujoco.MjModel],
) -> mujoco.MjModel:
    name = f"{key}-physics{modeltrim.VERSION}"
    entry = cache_dir() / f"{name}{ENTRY_SUFFIX}"
    refused = cache_dir() / f"{name}{REFUSED_SUFFIX}"  # trimming refused: do not try again
    model = _read(entry, path, gains=_ARM_KEY not in variant)
    if model is not None:
        log.debug("model cache: loaded %s (physics only) from %s", path, entry)
        return model
    full = load_or_compile(path, compile_fn, variant=variant)
    if refused.is_file():
        return full
    try:
        spec = spec_fn() if spec_fn is not None else mujoco.MjSpec.from_file(str(path))
    except (ValueError, OSError, mujoco.FatalError) as exc:
        log.debug("model cache: cannot read %s as a spec (%s)", path, exc)
        return full
    trimmed = modeltrim.physics_only(spec, full, compile_spec=compile_spec)
    try:
        if trimmed is None:
            _write_with(refused, lambda tmp: Path(tmp).write_bytes(b""))
            return full
        _write(entry, trimmed)
    except OSError as exc:
        log.debug("model cache: cannot write %s: %s", entry, exc)
        return full if trimmed is None else trimmed
    return trimmed


@dataclass(frozen=True)
class CacheInfo:
    """What the cache holds: its folder, the number of entries and their size in bytes."""

    folder: Path
    entries: int
    size: int


def _files(folder: Path, pattern: str) -> list[Path]:
    """The plain files matching ``pattern`` in ``folder`` (a folder or link named like an
    entry is not one: it is left alone)."""
    if not folder.is_dir():
        return []
    return [f for f in folder.glob(pattern) if f.is_file() and not f.is_symlink()]


def info() -> CacheInfo:
    """The cache's folder, number of entries and total size."""
    folder = cache_dir()
    files = _files(folder, f"*{ENTRY_SUFFIX}")
    size = 0
    for f in files:
        with contextlib.suppress(OSError):  # deleted meanwhile by another process
            size += f.stat().st_size
    return CacheInfo(folder, len(files), size)


def clear() -> CacheInfo:
    """Delete every cached model (the files the cache writes; anything else in the folder,
    such as a folder named like an entry, is left as it is, with one WARNING); return what
    was deleted."""
    before = info()
    folder = before.folder
    # digests/*.txt: the folder-digest memo of cache format 1, no longer written
    patterns = (f"*{ENTRY_SUFFIX}", f"*{DIGEST_SUFFIX}", f"*{REFUSED_SUFFIX}", ".*.partial")
    for pattern in (*patterns, "digests/*.txt"):
        for f in _files(folder, pattern):
            f.unlink(missing_ok=True)
    if folder.is_dir():
        left = [f.name for p in patterns for f in folder.glob(p) if f.exists() or f.is_symlink()]
        if left:
            log.warning(
                "model cache: left %s in %s: not files the cache wrote (delete them by hand)",
                ", ".join(sorted(left)), folder,
            )  # fmt: skip
    return before
