"""Generate the simplified visual meshes of the ``draft`` recording preset.

The shipped SO-101 STL meshes hold ~322k triangles (~399k drawn per frame, the servo mesh being
used five times; ``bench/bench_recording.py`` prints both figures), which a CPU rasteriser
(Mesa llvmpipe) draws at 2–3 frames/s. This script simplifies each one with quadric edge
collapse (``fast-simplification``, the library PyVista uses) to about ``--faces`` triangles
and writes them, with a manifest, to ``src/so101sim/data/draft_meshes/``. They are committed,
so nothing is generated at run time; rerun this script only when the model's meshes change::

    pip install fast-simplification
    python scripts/make_draft_meshes.py            # default: 5000 faces per mesh
    python scripts/make_draft_meshes.py --faces 800 --dest src/so101sim/data/draft_meshes_small
                                                   # the set for frames up to 256 pixels

Only the rendering uses them: collision geometry (and so the physics) keeps the originals.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SOURCE = ROOT / "src" / "so101sim" / "data" / "so101_official" / "assets"
DEST = ROOT / "src" / "so101sim" / "data" / "draft_meshes"
_STL_RECORD = np.dtype([("normal", "<f4", 3), ("v", "<f4", (3, 3)), ("attr", "<u2")])


def read_stl(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """A binary STL as (vertices (n, 3) float64, faces (m, 3) int), duplicate corners merged."""
    data = path.read_bytes()
    n = int(np.frombuffer(data, np.uint32, 1, 80)[0])
    if len(data) != 84 + 50 * n:
        raise ValueError(f"{path} is not a binary STL ({len(data)} bytes for {n} triangles)")
    rec = np.frombuffer(data, _STL_RECORD, count=n, offset=84)
    verts, inverse = np.unique(rec["v"].reshape(-1, 3), axis=0, return_inverse=True)
    return verts.astype(np.float64), inverse.reshape(-1, 3)


def weld(verts: np.ndarray, faces: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """Merge vertices closer than ``tol`` (a grid snap) and drop the triangles that collapse.

    CAD exports hold sliver triangles and near-duplicate vertices that stop edge collapse
    early; a sub-millimetre weld removes them without changing the part's shape.
    """
    keys = np.floor(verts / tol).astype(np.int64)
    _, label, count = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    label = label.ravel()
    merged = np.zeros((len(count), 3))
    np.add.at(merged, label, verts)
    merged /= count[:, None]
    f = label[faces]
    keep = (f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])
    f = f[keep]
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    f = f[np.sort(first)]
    used, f = np.unique(f, return_inverse=True)
    return merged[used], f.reshape(-1, 3)


def write_stl(path: Path, verts: np.ndarray, faces: np.ndarray) -> None:
    """Write a binary STL with per-face normals."""
    tri = verts[faces].astype(np.float32)
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
    rec = np.zeros(len(faces), _STL_RECORD)
    rec["normal"] = normal
    rec["v"] = tri
    header = b"so101sim draft mesh (simplified for CPU rendering)".ljust(80, b" ")
    path.write_bytes(header + np.uint32(len(faces)).tobytes() + rec.tobytes())


def simplify(verts: np.ndarray, faces: np.ndarray, target: int) -> tuple[np.ndarray, np.ndarray]:
    import fast_simplification

    if len(faces) <= target:
        return verts, faces
    v, f = fast_simplification.simplify(
        verts.astype(np.float32), faces.astype(np.int32), target_reduction=1 - target / len(faces)
    )
    return np.asarray(v, dtype=np.float64), np.asarray(f)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--faces", type=int, default=5000, help="target triangles per mesh")
    p.add_argument("--weld", type=float, default=0.0005, help="weld tolerance in metres")
    p.add_argument("--source", type=Path, default=SOURCE)
    p.add_argument("--dest", type=Path, default=DEST)
    args = p.parse_args(argv)
    args.dest.mkdir(parents=True, exist_ok=True)
    manifest: dict[str, dict[str, object]] = {}
    for src in sorted(args.source.glob("*.stl")):
        verts, faces = read_stl(src)
        n_before = len(faces)
        verts, faces = weld(verts, faces, args.weld)
        verts, faces = simplify(verts, faces, args.faces)
        write_stl(args.dest / src.name, verts, faces)
        manifest[src.name] = {
            "original_sha256": hashlib.sha256(src.read_bytes()).hexdigest(),
            "original_faces": n_before,
            "faces": len(faces),
        }
        print(f"{src.name:40s} {n_before:6d} -> {len(faces):5d} faces")
    meta = {"generator": "scripts/make_draft_meshes.py", "faces": args.faces, "weld": args.weld}
    (args.dest / "manifest.json").write_text(
        json.dumps({"settings": meta, "meshes": manifest}, indent=1) + "\n"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
