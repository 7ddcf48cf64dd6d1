"""The baked lighting as a mesh file: ``daskrad export`` (PLY, glTF binary, OBJ via trimesh).

Every vertex carries its radiance ``L = B / π`` (ambient term added, T-vertices resolved; the
solution's, without any view's junction gather), linear, plus a colour for viewers:

- **PLY**: ``red, green, blue, alpha`` (uchar, sRGB-encoded display colour, what MeshLab and
  CloudCompare show) and ``radiance_0..2`` (float32, linear radiance, W·m⁻²·sr⁻¹ per the
  scene's unit of area).
- **glTF binary (.glb)**: ``COLOR_0`` (normalized unsigned byte, **linear** display colour: the
  glTF specification defines vertex colours as linear, and a viewer encodes to sRGB on
  output) and the application attribute ``_RADIANCE`` (float32 VEC3, linear radiance).
- **OBJ**: ``v x y z r g b`` with the sRGB display colour in [0, 1] (the common extension);
  OBJ has no place for a linear float attribute.

The display colour is the PNG's tone curve (:func:`daskrad.io.image.display`) with the
exposure chosen over the vertices, shifted by ``stops``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from daskrad.errors import OptionError
from daskrad.io.files import check_directory
from daskrad.io.image import display, srgb8

#: Suffixes :func:`write_mesh` writes and the trimesh file type of each.
FORMATS = {".ply": "ply", ".glb": "glb", ".obj": "obj"}


def write_mesh(path: str | Path, vertices: np.ndarray, triangles: np.ndarray,
               radiance: np.ndarray, stops: float = 0.0) -> None:
    """Write ``vertices (V, 3) float64`` and ``triangles (T, 3) int`` (counter-clockwise from
    the lit side) with per-vertex ``radiance (V, 3)`` to ``path`` (.ply, .glb or .obj),
    atomically (a temporary file beside it, renamed)."""
    import trimesh

    path = Path(path)
    kind = FORMATS.get(path.suffix.lower())
    if kind is None:
        raise OptionError(f"the export must end in one of {', '.join(FORMATS)}, "
                          f"got {path.name}")
    check_directory(path.parent, "export")
    if path.is_symlink() or (path.exists() and not (path.is_file()
                                                    and _carries_mark(path))):
        raise OptionError("exists and was not written by daskrad; daskrad never replaces "
                          "what it did not make (move it or choose another name)", path)
    radiance = np.asarray(radiance, np.float64)
    shown = display(radiance, None, stops)
    linear8 = np.round(shown * 255.0).astype(np.uint8)
    srgb = srgb8(shown)
    alpha = np.full((len(vertices), 1), 255, np.uint8)
    colour = np.hstack([linear8 if kind == "glb" else srgb, alpha])
    mesh = trimesh.Trimesh(vertices=np.asarray(vertices, np.float64),
                           faces=np.asarray(triangles, np.int64), vertex_colors=colour,
                           process=False)
    if kind == "ply":
        for c in range(3):
            mesh.vertex_attributes[f"radiance_{c}"] = radiance[:, c].astype(np.float32)
    elif kind == "glb":
        mesh.vertex_attributes["_RADIANCE"] = radiance.astype(np.float32)
    data = mesh.export(file_type=kind)
    data = _marked(kind, data if isinstance(data, bytes) else data.encode())
    tmp = path.with_name(f".{path.name}.partial{path.suffix}")
    tmp.write_bytes(data)
    os.replace(tmp, path)


#: The mark an exported mesh carries (an OBJ comment, a PLY header comment, the glTF asset's
#: ``generator``): an existing file is replaced only when it has it.
MARK = "written by daskrad"


def _marked(kind: str, data: bytes) -> bytes:
    """``data`` of format ``kind`` with :data:`MARK` in its header."""
    if kind == "obj":
        return f"# {MARK}\n".encode() + data
    if kind == "ply":            # after the "ply" and "format" lines, where comments go
        lines = data.split(b"\n", 2)
        return b"\n".join([lines[0], lines[1], f"comment {MARK}".encode(), lines[2]])
    # glb: a 12-byte header, then a JSON chunk (length, type, body padded with spaces to 4)
    length = int.from_bytes(data[12:16], "little")
    doc = json.loads(data[20:20 + length])
    doc.setdefault("asset", {})["generator"] = MARK
    body = json.dumps(doc, separators=(",", ":")).encode()
    body += b" " * (-len(body) % 4)
    rest = data[20 + length:]
    out = (len(body).to_bytes(4, "little") + data[16:20] + body + rest)
    return data[:8] + (12 + len(out)).to_bytes(4, "little") + out


def _carries_mark(path: str | Path) -> bool:
    """Whether the mesh file at ``path`` carries :data:`MARK` (:func:`write_mesh` wrote it)."""
    try:
        with open(path, "rb") as f:
            head = f.read(1 << 16)
    except OSError:
        return False
    return MARK.encode() in head
