"""PLY, STL and glTF/GLB through trimesh (docs/design.md §6).

trimesh gives one geometry per material; each node of ``scene.graph.nodes_geometry`` places a
geometry with its own transform. These formats hold triangles (trimesh splits PLY quads into
adjacent halves), so quads are recovered with :func:`pair_coplanar` where they are planar
and convex, whatever the order and split of the triangles.

Materials: PLY and STL have none, so every face gets a white 0.73 diffuse, non-emitting
material. glTF gives ``baseColorFactor`` (diffuse) and ``emissiveFactor`` (emitted radiance,
limited to [0, 1] by glTF) times ``KHR_materials_emissive_strength`` when present. trimesh
quantizes ``baseColorFactor`` to 8 bits and drops the strength extension, so both are read from
the file's own JSON, matched to trimesh's materials by name.
"""

from __future__ import annotations

import json
import logging
import struct
from pathlib import Path

import numpy as np

from daskrad.errors import SceneError
from daskrad.scene.obj import DEFAULT_DIFFUSE, DEFAULT_MATERIAL
from daskrad.scene.polygons import pair_coplanar
from daskrad.scene.validate import check_vertices, scale_of

FORMATS = {".ply": "ply", ".stl": "stl", ".gltf": "gltf", ".glb": "glb"}


def gltf_json(path: Path) -> dict:
    """The JSON part of a .gltf or .glb file ({} if it cannot be read: trimesh decides)."""
    try:
        data = path.read_bytes()
        if path.suffix.lower() == ".glb":
            if data[:4] != b"glTF":
                return {}
            length, kind = struct.unpack("<II", data[12:20])
            if kind != 0x4E4F534A:  # "JSON"
                return {}
            data = data[20 : 20 + length]
        out = json.loads(data)
        return out if isinstance(out, dict) else {}
    except (OSError, ValueError, struct.error):
        return {}


def _gltf_materials(doc: dict) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """``name -> (diffuse, emission)`` from the glTF JSON, exact float values.

    glTF defaults: ``baseColorFactor`` 1, ``emissiveFactor`` 0, strength 1. Names given to more
    than one material are ambiguous and left out (trimesh's values are used for them).
    """
    table: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    seen: set[str] = set()
    for mat in doc.get("materials", []) or []:
        if not isinstance(mat, dict) or not isinstance(mat.get("name"), str):
            continue
        name = mat["name"]
        pbr = mat.get("pbrMetallicRoughness", {}) or {}
        base = np.array(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0]), dtype=np.float64)
        emissive = np.array(mat.get("emissiveFactor", [0.0, 0.0, 0.0]), dtype=np.float64)
        ext = (mat.get("extensions", {}) or {}).get("KHR_materials_emissive_strength", {}) or {}
        strength = float(ext.get("emissiveStrength", 1.0))
        if name in seen:
            table.pop(name, None)
            continue
        seen.add(name)
        table[name] = (base[:3], emissive[:3] * strength)
    return table


def _material_of(geom, gltf: dict) -> tuple[str, np.ndarray, np.ndarray]:
    """``(name, diffuse, emission)`` of one trimesh geometry."""
    material = getattr(getattr(geom, "visual", None), "material", None)
    if material is None:
        return DEFAULT_MATERIAL, np.array(DEFAULT_DIFFUSE), np.zeros(3)
    name = str(getattr(material, "name", None) or "material")
    if name in gltf:
        kd, ke = gltf[name]
        return name, kd.copy(), ke.copy()
    base = getattr(material, "baseColorFactor", None)
    if base is None:  # SimpleMaterial or an unknown kind: its diffuse colour, 8-bit
        base = getattr(material, "diffuse", None)
    kd = np.array(DEFAULT_DIFFUSE) if base is None else np.asarray(base, float)[:3] / 255.0
    emissive = getattr(material, "emissiveFactor", None)
    ke = np.zeros(3) if emissive is None else np.asarray(emissive, float)[:3]
    return name, kd, ke


def read_mesh(path: Path):
    """Read a PLY/STL/glTF/GLB file.

    Returns
    -------
    vertices : (V, 3) float64, in world space (node transforms applied)
    polygons : (Q, 4) int32, ``-1`` in column 3 for triangles
    polygon_material : (Q,) int64
    names : list of str
    diffuse, emission : (M, 3) float64
    """
    import trimesh  # a 0.3 s import, only when a mesh file is read

    file_type = FORMATS[path.suffix.lower()]
    # trimesh reports problems through logging and exceptions of many kinds (ValueError,
    # KeyError, struct.error, IndexError, ...): silence the former, turn the latter into one
    # clear SceneError
    log = logging.getLogger("trimesh")
    level = log.level
    log.setLevel(logging.CRITICAL)
    try:
        scene = trimesh.load_scene(str(path), file_type=file_type, process=False)
        nodes = [(scene.graph[n][0], scene.geometry[scene.graph[n][1]])
                 for n in scene.graph.nodes_geometry]
    except SceneError:
        raise
    except Exception as err:  # noqa: BLE001 - any failure inside trimesh is a bad file
        text = str(err).strip()
        if isinstance(err, ImportError) or not text:
            # trimesh reaches for optional modules when it guesses at garbage: say what it is
            text = "unrecognized content"
        detail = text.splitlines()[0][:200]
        raise SceneError(f"cannot read {file_type.upper()} file: {detail}", path) from None
    finally:
        log.setLevel(level)

    gltf = _gltf_materials(gltf_json(path)) if file_type in ("gltf", "glb") else {}
    verts, tris, tri_mat, names, kds, kes = [], [], [], [], [], []
    keys: dict[tuple, int] = {}
    offset = 0
    for transform, geom in nodes:
        faces = getattr(geom, "faces", None)
        if faces is None or len(faces) == 0:
            continue  # point clouds, paths
        v = check_vertices(geom.vertices, str(path))
        t = np.asarray(transform, dtype=np.float64)
        with np.errstate(over="ignore", invalid="ignore"):  # checked below, in one line
            v = v @ t[:3, :3].T + t[:3, 3]
        f = np.asarray(faces, dtype=np.int64)
        if f.ndim != 2 or f.shape[1] != 3:
            raise SceneError(f"faces must be triangles, got shape {f.shape}", path)
        bad = (f < 0) | (f >= len(v))
        if bad.any():
            row = int(np.flatnonzero(bad.any(axis=1))[0])
            raise SceneError(f"face {row + 1}: vertex index {int(f[bad][0])} is out of range "
                             f"({len(v)} vertices)", path)
        if np.linalg.det(t[:3, :3]) < 0:
            # a mirroring transform turns the winding around; glTF asks to reverse it back
            f = f[:, ::-1]
        name, kd, ke = _material_of(geom, gltf)
        key = (name, *kd.tolist(), *ke.tolist())
        if key not in keys:
            keys[key] = len(names)
            names.append(name if name not in names else f"{name}#{len(names)}")
            kds.append(kd)
            kes.append(ke)
        verts.append(v)
        tris.append(f + offset)
        tri_mat.append(np.full(len(f), keys[key]))
        offset += len(v)
    if not tris:
        raise SceneError("no faces in the file", path)
    vertices = np.concatenate(verts)
    faces = np.concatenate(tris)
    face_mat = np.concatenate(tri_mat)
    if file_type == "stl":
        # STL stores each triangle's corners separately; weld identical positions so that
        # triangles share vertices (and quads can be recovered below)
        vertices, inverse = np.unique(vertices, axis=0, return_inverse=True)
        faces = inverse.reshape(-1)[faces]
    vertices = check_vertices(vertices, str(path))
    diag = scale_of(vertices, faces)
    # triangles back into quads by geometry, not by where the file put them (issue 16 item 6:
    # pairing neighbours in the file only works in trimesh's own split orders, and in a
    # shuffled soup it can join halves of two different squares into a parallelogram)
    tris = np.column_stack([faces, np.full(len(faces), -1)])
    polys, keep = pair_coplanar(vertices, tris, face_mat, diag)
    return (vertices, polys, face_mat[keep], names,
            np.array(kds).reshape(-1, 3), np.array(kes).reshape(-1, 3))
