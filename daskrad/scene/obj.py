"""Wavefront OBJ and MTL, read directly (docs/design.md §6).

Why not ``trimesh.load_scene`` for OBJ (docs/stack.md measured it; checked again with trimesh 5.2):

* it splits every quad into two triangles, and where the halves end up depends on its code
  path (a chunk of only quads gives all first halves, then all second halves; a mixed chunk
  keeps them adjacent), so quads cannot be recovered reliably;
* it fans n-gons from their first corner, which is wrong for a concave face;
* negative (relative) indices are resolved from the end of the whole vertex list instead of
  the vertices read so far, which differs as soon as faces and vertices interleave;
* faces with fewer than three corners and unknown materials are skipped silently;
* ``Kd``/``Ks`` come back quantized to 8 bits, ``Ks`` is 0.4 when the file has none, ``Ke``
  and ``illum`` only survive as strings in ``material.kwargs``.

So OBJ faces keep exactly the corners the file gives, and the MTL values are the file's own.
The parser walks the text once (as trimesh's does); everything after that is vectorized.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from daskrad.errors import SceneError
from daskrad.scene.files import read_text

#: Largest MTL file read (bytes). A material library holds a few lines per material: 64 MiB is
#: hundreds of thousands of materials, and the bound stops an ``mtllib`` line naming a huge or
#: endless file (issue 13: ``mtllib /dev/zero`` grew memory without bound).
MAX_MTL_BYTES = 64 << 20

#: Diffuse reflectance of a face without a material, and of a material without ``Kd``.
DEFAULT_DIFFUSE = (0.73, 0.73, 0.73)
DEFAULT_MATERIAL = "default"


@dataclass
class MtlMaterial:
    """One ``newmtl`` entry with the MTL's own values (``None``: not in the file)."""

    name: str
    kd: tuple[float, float, float] | None = None
    ke: tuple[float, float, float] | None = None
    ks: tuple[float, float, float] | None = None
    ns: float | None = None
    illum: int | None = None
    line: int = 0
    extra: dict = field(default_factory=dict)

    def resolved(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, bool]:
        """``(diffuse, emission, specular, shininess, mirror)`` by the rules of docs/design.md §6.

        No ``Ks``, or ``illum`` 0 or 1, means no specular part; ``illum 3`` is a mirror.
        """
        kd = np.array(DEFAULT_DIFFUSE if self.kd is None else self.kd, dtype=np.float64)
        ke = np.zeros(3) if self.ke is None else np.array(self.ke, dtype=np.float64)
        diffuse_only = self.ks is None or self.illum in (0, 1)
        ks = np.zeros(3) if diffuse_only else np.array(self.ks, dtype=np.float64)
        ns = 0.0 if self.ns is None else float(self.ns)
        return kd, ke, ks, ns, self.illum == 3


def _read_text(path: Path, what: str, max_bytes: int | None = None) -> str:
    """The text of an OBJ or MTL file (:func:`daskrad.scene.files.read_text`), with a line
    ending in a backslash continued on the next (OBJ spec)."""
    text = read_text(path, what, max_bytes)
    return text.replace("\\\r\n", " ").replace("\\\n", " ")


def _floats(args: list[str], n: int, lineno: int, path: Path, key: str) -> tuple[float, ...]:
    try:
        vals = [float(a) for a in args]
    except ValueError:
        got = " ".join(args)
        raise SceneError(f"line {lineno}: {key} needs numbers, got {got!r}", path) from None
    if not vals:
        raise SceneError(f"line {lineno}: {key} has no value", path)
    if n == 3 and len(vals) == 1:
        vals = vals * 3  # MTL: "Kd r" means grey r r r
    if len(vals) < n:
        raise SceneError(f"line {lineno}: {key} needs {n} numbers, got {len(vals)}", path)
    return tuple(vals[:n])


def parse_mtl(path: Path) -> dict[str, MtlMaterial]:
    """All materials of one MTL file, by name, with the values the file writes.

    A file with no ``newmtl`` line is refused: it is not a material library (an ``mtllib``
    line naming the wrong file would otherwise show up as "material not defined")."""
    text = _read_text(path, "material library (MTL)", MAX_MTL_BYTES)
    out: dict[str, MtlMaterial] = {}
    cur: MtlMaterial | None = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        parts = raw.split("#", 1)[0].split()
        if not parts:
            continue
        key, args = parts[0], parts[1:]
        low = key.lower()
        if low == "newmtl":
            name = " ".join(args)
            if not name:
                raise SceneError(f"line {lineno}: newmtl without a name", path)
            cur = MtlMaterial(name=name, line=lineno)
            out[name] = cur
            continue
        if low not in ("kd", "ke", "ks", "ns", "illum"):
            continue  # Ka, d, Tr, Ni, maps...: not used by a radiosity renderer
        if cur is None:
            raise SceneError(f"line {lineno}: {key} before any newmtl", path)
        if low in ("kd", "ke", "ks"):
            if args and args[0].lower() in ("spectral", "xyz"):
                raise SceneError(f"line {lineno}: {key} {args[0]} is not supported (use RGB)", path)
            setattr(cur, low, _floats(args, 3, lineno, path, key))
        elif low == "ns":
            cur.ns = _floats(args, 1, lineno, path, key)[0]
        else:
            try:
                cur.illum = int(args[0])
            except (ValueError, IndexError):
                raise SceneError(f"line {lineno}: illum needs an integer", path) from None
    if not out:
        raise SceneError("not a material library: no newmtl line", path)
    return out


@dataclass
class ObjData:
    """What an OBJ file holds, before polygons are built.

    vertices : (V, 3) float64
    flat : (sum(counts),) int64, corner indices (0-based, relative indices resolved)
    counts : (F,) int64, corners per face
    face_material : (F,) int64, row of ``materials``
    materials : list of MtlMaterial (rows in order of first use)
    """

    vertices: np.ndarray
    flat: np.ndarray
    counts: np.ndarray
    face_material: np.ndarray
    materials: list[MtlMaterial]


def read_obj(path: Path) -> ObjData:
    """Read an OBJ file and the MTL files its ``mtllib`` lines name.

    An ``mtllib`` path is resolved against the OBJ's folder, never the working directory (as
    Blender, tinyobjloader and trimesh do); absolute paths and ``..`` are followed like theirs.
    What it names must be a regular file of at most :data:`MAX_MTL_BYTES` that defines a
    material, else the error names that file.
    """
    text = _read_text(path, "OBJ file")
    vert_rows: list[list[str]] = []
    vert_lines: list[int] = []
    face_tokens: list[list[str]] = []
    face_lines: list[int] = []
    face_nverts: list[int] = []  # vertices read before each face (for relative indices)
    face_mtl: list[str | None] = []
    libraries: dict[str, MtlMaterial] = {}
    used: dict[str | None, int] = {}
    usemtl_line: dict[str | None, int] = {}
    current: str | None = None
    for lineno, raw in enumerate(text.splitlines(), start=1):
        parts = raw.split("#", 1)[0].split()
        if not parts:
            continue
        key = parts[0]
        if key == "v":
            vert_rows.append(parts[1:4])
            vert_lines.append(lineno)
        elif key == "f":
            if len(parts) < 4:
                raise SceneError(f"line {lineno}: a face needs at least 3 corners", path)
            face_tokens.append(parts[1:])
            face_lines.append(lineno)
            face_nverts.append(len(vert_rows))
            face_mtl.append(current)
            used.setdefault(current, len(used))
        elif key == "usemtl":
            current = " ".join(parts[1:]) or None
            usemtl_line.setdefault(current, lineno)
        elif key == "mtllib":
            names = parts[1:]
            if not names:
                raise SceneError(f"line {lineno}: mtllib without a file name", path)
            # a file name may contain spaces: try the whole rest of the line first
            whole = path.parent / " ".join(names)
            files = [whole] if whole.is_file() else [path.parent / n for n in names]
            for f in files:
                libraries.update(parse_mtl(f))

    if not face_tokens:
        raise SceneError("no faces in the file", path)
    # checked after the loop: trimesh (and other readers) accept mtllib anywhere in the file
    for name in used:
        if name is not None and name not in libraries:
            raise SceneError(
                f"line {usemtl_line[name]}: material {name!r} is not defined"
                + (" (no mtllib line)" if not libraries else " in the mtllib files"),
                path,
            )
    try:
        verts = np.array(vert_rows, dtype=np.float64)
    except ValueError:
        bad = next(i for i, r in enumerate(vert_rows) if len(r) < 3 or not _is_floats(r))
        raise SceneError(f"line {vert_lines[bad]}: a vertex needs 3 numbers", path) from None
    if verts.ndim != 2 or verts.shape[1] != 3:
        bad = next(i for i, r in enumerate(vert_rows) if len(r) < 3)
        raise SceneError(f"line {vert_lines[bad]}: a vertex needs 3 numbers", path)

    counts = np.array([len(t) for t in face_tokens], dtype=np.int64)
    try:
        flat = np.array([int(c.split("/", 1)[0]) for t in face_tokens for c in t], dtype=np.int64)
    except ValueError:
        bad = next(i for i, t in enumerate(face_tokens) if not _is_ints(t))
        raise SceneError(f"line {face_lines[bad]}: bad vertex index in face", path) from None
    except OverflowError:  # beyond int64: out of range whatever the vertex count
        bad, index = next((i, c) for i, t in enumerate(face_tokens) for c in t
                          if abs(int(c.split("/", 1)[0])) >= 2**63)
        raise SceneError(f"line {face_lines[bad]}: vertex index {index.split('/', 1)[0]} is "
                         f"out of range ({len(vert_rows)} vertices)", path) from None
    before = np.repeat(np.array(face_nverts, dtype=np.int64), counts)
    # OBJ indices are 1-based; a negative index counts back from the last vertex read so far
    resolved = np.where(flat > 0, flat - 1, before + flat)
    bad = (flat == 0) | (resolved < 0) | (resolved >= len(verts))
    if bad.any():
        face = np.searchsorted(np.cumsum(counts), np.flatnonzero(bad)[0], side="right")
        raise SceneError(
            f"line {face_lines[face]}: vertex index {flat[bad][0]} is out of range "
            f"({len(verts)} vertices)",
            path,
        )
    materials = [
        libraries[name] if name is not None else MtlMaterial(name=DEFAULT_MATERIAL)
        for name in used
    ]
    face_material = np.array([used[m] for m in face_mtl], dtype=np.int64)
    return ObjData(verts, resolved, counts, face_material, materials)


def _is_floats(row: list[str]) -> bool:
    try:
        [float(x) for x in row]
    except ValueError:
        return False
    return True


def _is_ints(tokens: list[str]) -> bool:
    try:
        [int(c.split("/", 1)[0]) for c in tokens]
    except ValueError:
        return False
    return True
