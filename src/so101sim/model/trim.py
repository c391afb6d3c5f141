"""A physics-only copy of a compiled model: the same physics bit for bit in a fraction of the
memory, for runs that never draw and never cast rays (``so101sim run --headless``).

Most of the SO-101's compiled model (66 of 67 MB) is there to draw it and to cast rays at it:
the triangles of its 13 meshes (~322k faces) and a bounding-volume tree over them (645k nodes,
41 MB). MuJoCo's physics reads neither: meshes collide through their vertices and convex hulls
(``mesh_vert``, ``mesh_graph``, ``mesh_poly*``), and the collision mid-phase walks the
*bodies'* trees, which hold geoms, not triangles. The face trees serve only ``mj_ray`` and
signed-distance-field collisions; the faces also serve drawing.

:func:`physics_only` writes the model's MJB without the mesh faces and the mesh trees (every
other byte as MuJoCo wrote it), loads it back, and returns it only if every other array of the
model is identical; otherwise (a layout it cannot read, flex or SDF objects, trees it cannot
separate) it returns None and the caller keeps the full model. The MJB layout is read from
the ``mjxmacro.h`` that ships with the installed MuJoCo, and checked against MuJoCo's own MJB
of the model before anything is changed.

Models whose physics may read the dropped arrays are not trimmed (:func:`why_not`: flexes,
signed-distance fields, plugins, ray-casting sensors such as rangefinders). Do not render a
physics-only model or cast rays at it yourself (``mj_ray``, ``mjv_select``, a ``mjcb_*``
callback that does): its meshes have no triangles to draw or hit. so101sim's renderers draw the
full model of the same file instead (:func:`is_physics_only`).
"""

from __future__ import annotations

import ast
import logging
import re
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np

log = logging.getLogger(__name__)

VERSION = 1
"""Part of a physics-only cache entry's name: raised when what is trimmed changes."""

TRIMMED = frozenset(
    {
        "bvh_aabb",
        "bvh_child",
        "bvh_depth",
        "bvh_nodeid",
        "mesh_bvhadr",
        "mesh_bvhnum",
        "mesh_face",
        "mesh_faceadr",
        "mesh_facenum",
        "mesh_facenormal",
        "mesh_facetexcoord",
    }
)
"""The model arrays a physics-only copy changes; every other array is kept as it is."""

_HEADER_INTS = 5  # ID, sizeof(mjtNum), number of sizes, MuJoCo version, number of pointers
_ALIGN = 64  # MuJoCo aligns each array of the model's buffer to 64 bytes
_TYPE_BYTES = {
    "mjtNum": 8,
    "mjtSize": 8,
    "float": 4,
    "int": 4,
    "char": 1,
    "mjtByte": 1,
    "mjtBool": 1,
}


class _Unreadable(Exception):
    """The MJB layout could not be read or did not match the model."""


def _header_path() -> Path:
    return Path(mujoco.__file__).parent / "include" / "mujoco" / "mjxmacro.h"


@lru_cache(maxsize=1)
def _macros() -> tuple[tuple[str, ...], tuple[tuple[str, str, str, str], ...]]:
    """The names of the model's sizes and its arrays (type, name, rows, columns), in MJB order,
    from the installed MuJoCo's ``mjxmacro.h``."""
    try:
        text = _header_path().read_text()
    except OSError as exc:
        raise _Unreadable(f"cannot read {_header_path()}: {exc}") from exc
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text).replace("\\\n", " ")
    defs = {}
    for line in text.splitlines():
        m = re.match(r"\s*#define\s+(\w+)(\(?)\s*(.*)", line)
        if m and not m.group(2):
            defs[m.group(1)] = m.group(3)
    token = re.compile(r"\b(XNV|X)\s*\(((?:[^()]|\([^()]*\))*)\)|(\w+)")

    def expand(name: str, depth: int = 0) -> list[list[str]]:
        if name not in defs or depth > 4:
            raise _Unreadable(f"macro {name} not found in {_header_path()}")
        out: list[list[str]] = []
        for m in token.finditer(defs[name]):
            if m.group(1):
                out.append([s.strip() for s in m.group(2).split(",")])
            else:
                out.extend(expand(m.group(3), depth + 1))
        return out

    sizes = tuple(e[0] for e in expand("MJMODEL_SIZES"))
    pointers = tuple(expand("MJMODEL_POINTERS"))
    if not sizes or sizes[-1] != "nbuffer" or any(len(p) != 4 for p in pointers):
        raise _Unreadable("unexpected MJMODEL_SIZES / MJMODEL_POINTERS")
    return sizes, tuple((p[0], p[1], p[2], p[3]) for p in pointers)


def _constant(name: str, sizes: dict[str, int]) -> int:
    if name in sizes:
        return sizes[name]
    value = getattr(mujoco, name, None)
    if isinstance(value, int):
        return value
    for enum_name in dir(mujoco):
        if enum_name.startswith("mjt") and hasattr(getattr(mujoco, enum_name), name):
            return int(getattr(getattr(mujoco, enum_name), name))
    raise _Unreadable(f"unknown name {name!r} in an array size")


def _count(expr: str, sizes: dict[str, int]) -> int:
    """The value of a size expression such as ``nbody``, ``3`` or ``MJ_M(nmocap)*3``."""
    expr = re.sub(r"MJ_M\((\w+)\)", r"\1", expr)

    def value(node: ast.AST) -> int:
        if isinstance(node, ast.Constant) and isinstance(node.value, int):
            return node.value
        if isinstance(node, ast.Name):
            return _constant(node.id, sizes)
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Mult | ast.Add):
            left, right = value(node.left), value(node.right)
            return left * right if isinstance(node.op, ast.Mult) else left + right
        raise _Unreadable(f"unexpected array size {expr!r}")

    try:
        return value(ast.parse(expr, mode="eval").body)
    except SyntaxError as exc:
        raise _Unreadable(f"unexpected array size {expr!r}") from exc


def _layout(sizes: dict[str, int]) -> list[tuple[str, int]]:
    """(name, bytes) of every model array, in MJB order."""
    _, pointers = _macros()
    out = []
    for type_name, name, rows, cols in pointers:
        if type_name not in _TYPE_BYTES:
            raise _Unreadable(f"unknown type {type_name!r} of {name}")
        out.append((name, _TYPE_BYTES[type_name] * _count(rows, sizes) * _count(cols, sizes)))
    return out


def _padded_total(layout: list[tuple[str, int]]) -> int:
    offset = 0
    for _, nbytes in layout:
        offset += (-offset) % _ALIGN + nbytes
    return offset


def _mjb(model: mujoco.MjModel) -> np.ndarray:
    buffer = np.empty(mujoco.mj_sizeModel(model), np.uint8)
    mujoco.mj_saveModel(model, None, buffer)
    return buffer


def _split(
    model: mujoco.MjModel, raw: memoryview
) -> tuple[dict[str, int], memoryview, dict[str, memoryview]]:
    """The sizes, the option/visual/statistic structs and the arrays of ``model``'s MJB
    ``raw``, each checked against the model."""
    size_names, pointers = _macros()
    header = np.frombuffer(raw, np.int32, _HEADER_INTS)
    if header[2] != len(size_names) or header[4] != len(pointers) or header[1] != 8:
        raise _Unreadable("the MJB header does not match mjxmacro.h")
    values = np.frombuffer(raw, np.int64, len(size_names), offset=4 * _HEADER_INTS)
    sizes = dict(zip(size_names, (int(v) for v in values), strict=True))
    if any(sizes[n] != int(getattr(model, n)) for n in size_names):
        raise _Unreadable("the MJB sizes do not match the model")
    layout = _layout(sizes)
    if not 0 <= sizes["nbuffer"] - _padded_total(layout) < _ALIGN:
        raise _Unreadable("the buffer size rule does not match")
    start = 4 * _HEADER_INTS + 8 * len(size_names)
    structs = len(raw) - start - sum(n for _, n in layout)
    if structs <= 0:
        raise _Unreadable("the MJB is shorter than its arrays")
    pos = start + structs
    arrays = {}
    for name, nbytes in layout:
        arrays[name] = raw[pos : pos + nbytes]
        pos += nbytes
    checked = 0
    for name, view in arrays.items():  # every array Python shows must be where it was read
        value = getattr(model, name, None)
        if isinstance(value, np.ndarray):
            if value.nbytes != len(view) or value.tobytes() != view.tobytes():
                raise _Unreadable(f"{name} is not where the layout puts it")
            checked += 1
    if checked < len(arrays) // 2:
        raise _Unreadable("too few of the model's arrays could be checked")
    return sizes, raw[start : start + structs], arrays


def _trimmed_mjb(model: mujoco.MjModel) -> bytes:
    raw = memoryview(_mjb(model))  # slices of it copy nothing
    sizes, structs, arrays = _split(model, raw)
    body_ends = [
        int(a + n) for a, n in zip(model.body_bvhadr, model.body_bvhnum, strict=True) if n > 0
    ]
    keep = max(body_ends, default=0)
    mesh_starts = [
        int(a) for a, n in zip(model.mesh_bvhadr, model.mesh_bvhnum, strict=True) if n > 0
    ]
    if mesh_starts and min(mesh_starts) < keep:
        raise _Unreadable("the mesh trees are not after the body trees")
    new = dict(sizes, nbvh=keep, nbvhstatic=keep, nmeshface=0)
    minus_one = np.full(model.nmesh, -1, np.int32).tobytes()
    zero = np.zeros(model.nmesh, np.int32).tobytes()
    empty = memoryview(b"")
    arrays.update(mesh_bvhadr=memoryview(minus_one), mesh_bvhnum=memoryview(zero))
    arrays.update(mesh_faceadr=memoryview(minus_one), mesh_facenum=memoryview(zero))
    arrays.update(mesh_face=empty, mesh_facenormal=empty, mesh_facetexcoord=empty)
    for name in ("bvh_depth", "bvh_nodeid", "bvh_child", "bvh_aabb"):
        row = len(arrays[name]) // max(sizes["nbvh"], 1)
        arrays[name] = arrays[name][: row * keep]
    layout = _layout(new)
    for name, nbytes in layout:
        if len(arrays[name]) != nbytes:
            raise _Unreadable(f"{name} changed size")
    new["nbuffer"] = _padded_total(layout) + sizes["nbuffer"] - _padded_total(_layout(sizes))
    size_names, _ = _macros()
    values = np.array([new[n] for n in size_names], np.int64).tobytes()
    parts = [raw[: 4 * _HEADER_INTS], values, structs, *(arrays[n] for n, _ in layout)]
    return b"".join(parts)


def _differences(full: mujoco.MjModel, trimmed: mujoco.MjModel) -> list[str]:
    """Names of the arrays outside :data:`TRIMMED` that differ between the two models."""
    size_names, pointers = _macros()
    out = [n for n in size_names if n not in ("nbvh", "nbvhstatic", "nmeshface", "nbuffer")]
    out = [n for n in out if getattr(full, n) != getattr(trimmed, n)]
    for _, name, _, _ in pointers:
        if name in TRIMMED:
            continue
        a, b = getattr(full, name, None), getattr(trimmed, name, None)
        if isinstance(a, np.ndarray) and (a.shape != b.shape or a.tobytes() != b.tobytes()):
            out.append(name)
    for struct in ("opt", "vis", "stat"):
        if str(getattr(full, struct)) != str(getattr(trimmed, struct)):
            out.append(struct)
    return out


def physics_only(model: mujoco.MjModel) -> bytes | None:
    """The MJB of ``model`` without its mesh faces and mesh trees (:data:`TRIMMED`), checked to
    load and to hold every other array of ``model`` unchanged; None when that cannot be made
    or the model may read what is dropped (see :func:`why_not`; the reason is logged at
    DEBUG)."""
    try:
        reason = why_not(model)
        if reason is not None:
            raise _Unreadable(reason)
        data = _trimmed_mjb(model)
        trimmed = mujoco.MjModel.from_binary_path("trimmed.mjb", {"trimmed.mjb": data})
        differ = _differences(model, trimmed)
        if differ:
            raise _Unreadable(f"{', '.join(differ)} would differ")
    # anything unexpected (another MuJoCo's layout, a renamed field): keep the full model
    except Exception as exc:
        log.debug("physics-only model: not made (%s); keeping the full model", exc)
        return None
    return data


# Sensors that never cast rays at meshes nor read their triangles or trees (an allow-list: a
# sensor type a later MuJoCo adds keeps the full model until it is known).
_SAFE_SENSORS = frozenset(
    {
        "ACCELEROMETER", "ACTUATORFRC", "ACTUATORPOS", "ACTUATORVEL", "BALLANGVEL", "BALLQUAT",
        "CAMPROJECTION", "CLOCK", "CONTACT", "E_KINETIC", "E_POTENTIAL", "FORCE",
        "FRAMEANGACC", "FRAMEANGVEL", "FRAMELINACC", "FRAMELINVEL", "FRAMEPOS", "FRAMEQUAT",
        "FRAMEXAXIS", "FRAMEYAXIS", "FRAMEZAXIS", "GEOMDIST", "GEOMFROMTO", "GEOMNORMAL",
        "GYRO", "INSIDESITE", "JOINTACTFRC", "JOINTLIMITFRC", "JOINTLIMITPOS", "JOINTLIMITVEL",
        "JOINTPOS", "JOINTVEL", "MAGNETOMETER", "SUBTREEANGMOM", "SUBTREECOM", "SUBTREELINVEL",
        "TENDONACTFRC", "TENDONLIMITFRC", "TENDONLIMITPOS", "TENDONLIMITVEL", "TENDONPOS",
        "TENDONVEL", "TORQUE", "TOUCH", "VELOCIMETER",
    }
)  # fmt: skip


def why_not(model: mujoco.MjModel) -> str | None:
    """Why ``model``'s physics may read its mesh triangles or trees (then it is not trimmed),
    or None: flexes, signed-distance fields (octrees, SDF geoms), plugins, and sensors that
    cast rays (rangefinders) or are not known to be safe."""
    if model.nflex or model.nbvhdynamic:
        return "it has flex objects"
    if model.noct or (model.geom_type == mujoco.mjtGeom.mjGEOM_SDF).any():
        return "it has signed-distance-field geoms"
    if model.nplugin:
        return "it uses plugins"
    kinds = mujoco.mjtSensor
    safe = {
        int(getattr(kinds, f"mjSENS_{n}")) for n in _SAFE_SENSORS if hasattr(kinds, f"mjSENS_{n}")
    }
    for i, kind in enumerate(model.sensor_type.tolist()):
        if kind not in safe:
            return f"its sensor {i} ({mujoco.mjtSensor(kind).name}) may cast rays"
    return None


def is_physics_only(model: mujoco.MjModel) -> bool:
    """Whether ``model`` is a physics-only copy: meshes without triangles, nothing to draw."""
    return model.nmesh > 0 and model.nmeshface == 0
