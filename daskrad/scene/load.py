"""``load_scene``: a mesh file (+ its TOML sidecar) → a validated :class:`Scene`
(docs/design.md §6)."""

from __future__ import annotations

import os
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from daskrad import tolerances
from daskrad.errors import DaskradWarning, SceneError
from daskrad.scene import shapes as shp
from daskrad.scene.config import Config, read_config
from daskrad.scene.meshfile import FORMATS, gltf_json, read_mesh
from daskrad.scene.mgf import read_mgf
from daskrad.scene.obj import read_obj
from daskrad.scene.polygons import faces_to_polygons
from daskrad.scene.types import DirectionalLights, PointLights, Scene
from daskrad.scene.validate import check_vertices, scale_of, scene_from_arrays

#: Suffixes :func:`load_scene` reads (case-insensitive). A ``.toml`` scene is a sidecar alone:
#: its ``[[shape]]``s are the geometry.
SUFFIXES = (".obj", ".mgf", *FORMATS, ".toml")


def sidecar(path: str | Path) -> Path | None:
    """The TOML with the mesh's stem beside it (``box.obj`` → ``box.toml``), if it exists."""
    toml = Path(path).with_suffix(".toml")
    return toml if toml.is_file() else None


def load_scene(path: str | Path, config: str | Path | None = None,
               camera: str | None = None) -> Scene:
    """Load and check a scene: OBJ (+MTL), MGF, PLY, STL, glTF or GLB, plus its TOML sidecar
    (whose ``[[shape]]``s are tessellated and added); or a TOML file alone.

    Parameters
    ----------
    path : str or Path
        The mesh file; the format follows the suffix.
    config : str or Path, optional
        TOML with camera and lights; default: the file with the mesh's stem and ``.toml``
        suffix beside it, if there is one. Its camera replaces a glTF file's; its lights add
        to the file's.
    camera : str, optional
        The glTF camera to look through, by name (default: the file's first).

    Raises
    ------
    SceneError
        Naming the file and the problem: missing or unreadable file, unknown format, no faces,
        NaN/infinite coordinates, reflectance outside [0, 1), negative emission, no light at
        all, malformed TOML.
    """
    path = Path(path)
    if not path.exists():
        raise SceneError("no such file", path)
    if path.is_dir():
        raise SceneError("is a directory, not a scene file", path)
    if not path.is_file():  # a FIFO or a device: reading it hangs or never ends
        raise SceneError("is not a regular file (a device, FIFO or socket)", path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise SceneError(
            f"unknown scene format {path.suffix or '(no suffix)'!r} "
            f"(expected one of {', '.join(SUFFIXES)})",
            path,
        )
    if not os.access(path, os.R_OK):
        raise SceneError("cannot read the file (permission denied)", path)

    if suffix == ".toml":
        if config is not None and Path(config).resolve() != path.resolve():
            raise SceneError("a TOML scene is its own config: give its camera and lights in "
                             "it, not with --config", path)
        cfg = read_config(path)
    elif config is not None:
        cfg = read_config(config)
    else:
        found = sidecar(path)
        cfg = read_config(found) if found is not None else None

    ks, ns, mirror, polygon_face, two_sided = None, None, None, None, None
    notes: list[str] = []
    if suffix == ".toml":
        if not cfg.shapes:
            raise SceneError("no faces: a TOML scene needs [[shape]]s", path)
        vertices = np.zeros((0, 3))
        polygons = np.zeros((0, 4), np.int64)
        polygon_material = np.zeros(0, np.int64)
        names, kd, ke = [], np.zeros((0, 3)), np.zeros((0, 3))
    elif suffix == ".mgf":
        with warnings.catch_warnings(record=True) as said:     # kept for Scene.warnings
            warnings.simplefilter("always", DaskradWarning)
            mgf = read_mgf(path, one_sided=cfg is not None and cfg.mgf_one_sided)
        notes = [str(w.message) for w in said if issubclass(w.category, DaskradWarning)]
        for w in said:      # said again where the caller listens (the CLI: one line each)
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        vertices, polygons, polygon_material = mgf.vertices, mgf.polygons, mgf.polygon_material
        names, kd, ke = mgf.names, mgf.diffuse, mgf.emission
        polygon_face, two_sided = mgf.polygon_face, mgf.two_sided
    elif suffix == ".obj":
        obj = read_obj(path)
        vertices = check_vertices(obj.vertices, str(path))
        diag = scale_of(vertices, obj.flat)
        polygons, face = faces_to_polygons(vertices, obj.flat, obj.counts, diag, str(path))
        polygon_material = obj.face_material[face]
        polygon_face = face
        resolved = [m.resolved() for m in obj.materials]
        kd, ke, ks = (np.array([r[i] for r in resolved]).reshape(-1, 3) for i in range(3))
        ns = np.array([r[3] for r in resolved], dtype=np.float64)
        mirror = np.array([r[4] for r in resolved], dtype=bool)
        names = [m.name for m in obj.materials]
    else:
        vertices, polygons, polygon_material, names, kd, ke = read_mesh(path)

    if cfg is not None and (cfg.shapes or cfg.materials):
        vertices, polygons, polygon_material, names, kd, ke, ks, ns, mirror, polygon_face = (
            _add_shapes(cfg, vertices, polygons, polygon_material, names, kd, ke, ks, ns,
                        mirror, polygon_face))
    if two_sided is not None:    # materials the sidecar added are one-sided
        two_sided = np.concatenate([two_sided, np.zeros(len(kd) - len(two_sided), bool)])
    if camera is not None and suffix not in (".gltf", ".glb"):
        raise SceneError(f"--camera {camera!r}: only glTF files name their cameras", path)
    if suffix in (".gltf", ".glb"):
        cfg = _with_gltf(cfg, gltf_json(path), path, camera)

    scene = scene_from_arrays(
        vertices,
        polygons,
        polygon_material,
        kd,
        ke,
        specular=ks,
        shininess=ns,
        mirror=mirror,
        point_lights=None if cfg is None else cfg.point_lights,
        directional_lights=None if cfg is None else cfg.directional_lights,
        camera=None if cfg is None else cfg.camera,
        path=str(path),
        material_names=names,
        polygon_face=polygon_face,
        two_sided=two_sided,
    )
    return replace(scene, warnings=(*notes, *scene.warnings)) if notes else scene


def _with_gltf(cfg: Config | None, doc: dict, path: Path, name: str | None) -> Config:
    """The sidecar's settings with a glTF file's camera and lights added (the sidecar's
    camera wins; the lights of both are kept)."""
    from daskrad.scene import gltf

    points, directional = gltf.lights(doc, path)
    cam = gltf.camera(doc, path, name)
    if cfg is None:
        return Config(str(path), cam, points, directional)
    pl, dl = cfg.point_lights, cfg.directional_lights
    return replace(cfg, camera=cfg.camera or cam, point_lights=
                   PointLights(*(np.concatenate([np.reshape(a, (-1, 3)), np.reshape(b, (-1, 3))])
                                 for a, b in ((points.position, pl.position),
                                              (points.intensity, pl.intensity)))),
                   directional_lights=DirectionalLights(*(
                       np.concatenate([np.reshape(a, (-1, 3)), np.reshape(b, (-1, 3))])
                       for a, b in ((directional.direction, dl.direction),
                                    (directional.irradiance, dl.irradiance)))))


def _add_shapes(cfg: Config, vertices, polygons, polygon_material, names, kd, ke, ks, ns, mirror,
                polygon_face):
    """The sidecar's ``[[material]]``s and tessellated ``[[shape]]``s appended to a scene's
    arrays. The chord error is ``CHORD_ERROR`` times the diagonal of the box holding the file's
    geometry and every placed shape."""
    names = list(names)
    for name, _, _ in cfg.materials:
        if name in names:
            raise SceneError(f"[[material]] {name!r} is already defined by the scene file",
                             cfg.path)
    names += [name for name, _, _ in cfg.materials]
    kd = np.concatenate([np.reshape(kd, (-1, 3)),
                         np.reshape([d for _, d, _ in cfg.materials], (-1, 3))])
    ke = np.concatenate([np.reshape(ke, (-1, 3)),
                         np.reshape([e for _, _, e in cfg.materials], (-1, 3))])
    extra = len(cfg.materials)
    ks = None if ks is None else np.concatenate([ks, np.zeros((extra, 3))])
    ns = None if ns is None else np.concatenate([ns, np.zeros(extra)])
    mirror = None if mirror is None else np.concatenate([mirror, np.zeros(extra, bool)])
    if not cfg.shapes:
        return vertices, polygons, polygon_material, names, kd, ke, ks, ns, mirror, polygon_face

    row = {n: i for i, n in enumerate(names)}
    for s in cfg.shapes:
        if s["material"] not in row:
            raise SceneError(f"{s['where']}: material {s['material']!r} is not defined (give a "
                             "[[material]] or use a name from the MTL)", cfg.path)
    boxes = [shp.shape_bounds(s) for s in cfg.shapes]
    used = polygons[polygons >= 0]
    if used.size:
        v = vertices[np.unique(used)]
        boxes.append(np.stack([v.min(axis=0), v.max(axis=0)]))
    box = np.concatenate(boxes)
    diag = float(np.linalg.norm(box.max(axis=0) - box.min(axis=0)))
    n_faces = (len(polygons) if polygon_face is None
               else int(np.max(polygon_face, initial=-1)) + 1)
    face = np.arange(len(polygons)) if polygon_face is None else np.asarray(polygon_face)
    verts, polys, mats, faces = [np.asarray(vertices, float).reshape(-1, 3)], [polygons], \
        [np.asarray(polygon_material)], [face]
    offset = len(verts[0])
    for i, s in enumerate(cfg.shapes):
        v, p = shp.tessellate(s, tolerances.CHORD_ERROR * diag)
        verts.append(v)
        polys.append(np.where(p >= 0, p + offset, -1))
        mats.append(np.full(len(p), row[s["material"]]))
        # one "face" number per shape, after the file's faces, for messages
        faces.append(np.full(len(p), n_faces + i))
        offset += len(v)
    return (np.concatenate(verts), np.concatenate(polys), np.concatenate(mats), names, kd, ke,
            ks, ns, mirror, np.concatenate(faces))
