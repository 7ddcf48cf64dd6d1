"""``load_scene``: a mesh file (+ its TOML sidecar) → a validated :class:`Scene`
(docs/design.md §6)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from daskrad.errors import SceneError
from daskrad.scene.config import Config, read_config
from daskrad.scene.meshfile import FORMATS, gltf_json, read_mesh
from daskrad.scene.obj import read_obj
from daskrad.scene.polygons import faces_to_polygons
from daskrad.scene.types import DirectionalLights, PointLights, Scene
from daskrad.scene.validate import check_vertices, scale_of, scene_from_arrays

#: Suffixes :func:`load_scene` reads (case-insensitive).
SUFFIXES = (".obj", *FORMATS)


def sidecar(path: str | Path) -> Path | None:
    """The TOML with the mesh's stem beside it (``box.obj`` → ``box.toml``), if it exists."""
    toml = Path(path).with_suffix(".toml")
    return toml if toml.is_file() else None


def load_scene(path: str | Path, config: str | Path | None = None,
               camera: str | None = None) -> Scene:
    """Load and check a scene: OBJ (+MTL), PLY, STL, glTF or GLB, plus its TOML sidecar.

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

    if config is not None:
        cfg = read_config(config)
    else:
        found = sidecar(path)
        cfg = read_config(found) if found is not None else None

    if suffix == ".obj":
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
        polygon_face = None
        ks, ns, mirror = None, None, None
    if camera is not None and suffix not in (".gltf", ".glb"):
        raise SceneError(f"--camera {camera!r}: only glTF files name their cameras", path)
    if suffix in (".gltf", ".glb"):
        cfg = _with_gltf(cfg, gltf_json(path), path, camera)

    return scene_from_arrays(
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
    )


def _with_gltf(cfg: Config | None, doc: dict, path: Path, name: str | None) -> Config:
    """The sidecar's settings with a glTF file's camera and lights added (the sidecar's
    camera wins; the lights of both are kept)."""
    from daskrad.scene import gltf

    points, directional = gltf.lights(doc, path)
    cam = gltf.camera(doc, path, name)
    if cfg is None:
        return Config(str(path), cam, points, directional)
    pl, dl = cfg.point_lights, cfg.directional_lights
    return Config(cfg.path, cfg.camera or cam,
                  PointLights(*(np.concatenate([np.reshape(a, (-1, 3)), np.reshape(b, (-1, 3))])
                                for a, b in ((points.position, pl.position),
                                             (points.intensity, pl.intensity)))),
                  DirectionalLights(*(np.concatenate([np.reshape(a, (-1, 3)),
                                                      np.reshape(b, (-1, 3))])
                                      for a, b in ((directional.direction, dl.direction),
                                                   (directional.irradiance, dl.irradiance)))))
