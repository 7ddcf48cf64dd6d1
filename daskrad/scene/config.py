"""The TOML sidecar: camera and lights that a mesh file cannot hold (docs/design.md §6).

Schema (every key below, nothing else; an unknown key or a wrong type is a :class:`SceneError`
naming the TOML file)::

    [camera]                 # optional; without it the renderer frames the bounding box
    eye = [x, y, z]          # required
    look_at = [x, y, z]      # required
    up = [x, y, z]           # default [0, 1, 0]
    fov = 39.3               # required, horizontal, degrees, in (0, 180)
    width = 256              # default 256
    height = 256             # default 256

    [[light]]
    type = "point"           # intensity: W/sr per RGB channel
    position = [x, y, z]
    intensity = [r, g, b]

    [[light]]
    type = "directional"     # direction the light travels (normalized here);
    direction = [x, y, z]    # irradiance: W/m² on a surface facing the light
    irradiance = [r, g, b]

    [[material]]             # a material for [[shape]]s (beside the MTL's, if any)
    name = "white"           # required, not a name the MTL already defines
    diffuse = [r, g, b]      # Kd in [0, 1), default [0.73, 0.73, 0.73]
    emission = [r, g, b]     # Ke, emitted radiance, default [0, 0, 0]

    [[shape]]                # a quadric or Bezier patch, tessellated when loading
    type = "sphere"          # sphere, cylinder, cone, disc, ring, torus, bezier
    material = "white"       # required: a [[material]] or MTL name
    radius = 0.5             # the type's dimensions (daskrad.scene.shapes.parse_shape)
    translate = [x, y, z]    # placement: scale, rotate [deg about x, y, z], translate,
                             # or matrix = 4 rows of 4; inside = true faces inward

    [mgf]
    one_sided = true         # MGF input: every face one-sided (as RenderPark runs its scenes)
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from daskrad import tolerances
from daskrad.errors import SceneError
from daskrad.scene.obj import DEFAULT_DIFFUSE
from daskrad.scene.shapes import parse_shape
from daskrad.scene.types import Camera, DirectionalLights, PointLights

DEFAULT_IMAGE_SIZE = 256

_CAMERA_KEYS = {"eye", "look_at", "up", "fov", "width", "height"}
_LIGHT_KEYS = {
    "point": {"type", "position", "intensity"},
    "directional": {"type", "direction", "irradiance"},
}


@dataclass(frozen=True)
class Config:
    """What a TOML sidecar adds to a scene."""

    path: str
    camera: Camera | None
    point_lights: PointLights
    directional_lights: DirectionalLights
    #: ``[[material]]``: ``(name, diffuse (3,), emission (3,))`` each, in file order
    materials: tuple = ()
    #: ``[[shape]]``: dicts from :func:`daskrad.scene.shapes.parse_shape`, in file order
    shapes: tuple = ()
    #: ``[mgf] one_sided``: MGF faces one-sided whatever their material's ``sides``
    mgf_one_sided: bool = False


def _is_number(x) -> bool:
    # bool is an int in Python; `fov = true` is a mistake, not 1 degree
    return isinstance(x, int | float) and not isinstance(x, bool)


def _vec3(table: dict, key: str, where: str, path: Path) -> np.ndarray:
    value = table[key]
    if not (isinstance(value, list) and len(value) == 3 and all(_is_number(x) for x in value)):
        raise SceneError(f"{where}.{key} must be an array of 3 numbers, got {value!r}", path)
    out = np.array(value, dtype=np.float64)
    if not np.isfinite(out).all():
        raise SceneError(f"{where}.{key} must be finite, got {value!r}", path)
    return out


def _check_keys(table, allowed: set[str], required: set[str], where: str, path: Path):
    if not isinstance(table, dict):
        raise SceneError(f"{where} must be a table, got {table!r}", path)
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise SceneError(
            f"unknown key {unknown[0]!r} in {where} (allowed: {', '.join(sorted(allowed))})", path
        )
    missing = sorted(required - set(table))
    if missing:
        raise SceneError(f"{where} needs {missing[0]!r}", path)


def _camera(table, path: Path) -> Camera:
    _check_keys(table, _CAMERA_KEYS, {"eye", "look_at", "fov"}, "[camera]", path)
    eye = _vec3(table, "eye", "camera", path)
    look_at = _vec3(table, "look_at", "camera", path)
    up = _vec3(table, "up", "camera", path) if "up" in table else np.array([0.0, 1.0, 0.0])
    for name, at in (("eye", eye), ("look_at", look_at)):
        if not (np.abs(at) <= tolerances.MAX_COORDINATE).all():  # the view's products overflow
            raise SceneError(f"camera.{name} {at.tolist()} lies beyond "
                             f"±{tolerances.MAX_COORDINATE:g}", path)
    fov = table["fov"]
    if not _is_number(fov) or not 0.0 < fov < 180.0:
        raise SceneError(f"camera.fov must be a number of degrees in (0, 180), got {fov!r}", path)
    size = {}
    for key in ("width", "height"):
        v = table.get(key, DEFAULT_IMAGE_SIZE)
        if not isinstance(v, int) or isinstance(v, bool) or v <= 0:
            raise SceneError(f"camera.{key} must be a positive integer, got {v!r}", path)
        size[key] = v
    forward = look_at - eye
    if not np.linalg.norm(forward) > 0:
        raise SceneError("camera.eye and camera.look_at are the same point", path)
    cross = np.linalg.norm(np.cross(forward, up))
    if not cross > tolerances.CAMERA_UP_SINE * np.linalg.norm(forward) * np.linalg.norm(up):
        raise SceneError("camera.up is zero or parallel to the view direction", path)
    return Camera(
        eye=eye, look_at=look_at, up=up, fov=float(fov), width=size["width"], height=size["height"]
    )


def _lights(entries, path: Path) -> tuple[PointLights, DirectionalLights]:
    if not isinstance(entries, list):
        raise SceneError("light must be an array of tables: write [[light]]", path)
    pos, inten, dirs, irr = [], [], [], []
    for i, entry in enumerate(entries):
        where = f"[[light]] #{i + 1}"
        if not isinstance(entry, dict):
            raise SceneError(f"{where} must be a table", path)
        kind = entry.get("type")
        if kind not in _LIGHT_KEYS:
            raise SceneError(
                f"{where}: type must be \"point\" or \"directional\", got {kind!r}", path
            )
        keys = _LIGHT_KEYS[kind]
        _check_keys(entry, keys, keys, where, path)
        if kind == "point":
            pos.append(_vec3(entry, "position", where, path))
            power = _vec3(entry, "intensity", where, path)
            inten.append(power)
            name = "intensity"
        else:
            d = _vec3(entry, "direction", where, path)
            norm = np.linalg.norm(d)
            if not norm > 0:
                raise SceneError(f"{where}: direction must not be zero", path)
            dirs.append(d / norm)
            power = _vec3(entry, "irradiance", where, path)
            irr.append(power)
            name = "irradiance"
        if (power < 0).any():
            raise SceneError(f"{where}: {name} must not be negative, got {power.tolist()}", path)
    points = PointLights(
        position=np.array(pos, dtype=np.float64).reshape(-1, 3),
        intensity=np.array(inten, dtype=np.float64).reshape(-1, 3),
    )
    directional = DirectionalLights(
        direction=np.array(dirs, dtype=np.float64).reshape(-1, 3),
        irradiance=np.array(irr, dtype=np.float64).reshape(-1, 3),
    )
    return points, directional


def _materials(entries, path: Path) -> tuple:
    if not isinstance(entries, list):
        raise SceneError("material must be an array of tables: write [[material]]", path)
    out, seen = [], set()
    for i, entry in enumerate(entries):
        where = f"[[material]] #{i + 1}"
        _check_keys(entry, {"name", "diffuse", "emission"}, {"name"}, where, path)
        name = entry["name"]
        if not isinstance(name, str) or not name:
            raise SceneError(f"{where}.name must be a non-empty string", path)
        if name in seen:
            raise SceneError(f"{where}: material {name!r} is defined twice", path)
        seen.add(name)
        kd = (_vec3(entry, "diffuse", where, path) if "diffuse" in entry
              else np.array(DEFAULT_DIFFUSE))
        ke = _vec3(entry, "emission", where, path) if "emission" in entry else np.zeros(3)
        out.append((name, kd, ke))
    return tuple(out)


def _shapes(entries, path: Path) -> tuple:
    if not isinstance(entries, list):
        raise SceneError("shape must be an array of tables: write [[shape]]", path)
    return tuple(parse_shape(e, f"[[shape]] #{i + 1}", path) for i, e in enumerate(entries))


def _mgf(table, path: Path) -> bool:
    _check_keys(table, {"one_sided"}, set(), "[mgf]", path)
    value = table.get("one_sided", False)
    if not isinstance(value, bool):
        raise SceneError(f"mgf.one_sided must be true or false, got {value!r}", path)
    return value


def read_config(path: str | Path) -> Config:
    """Parse and check one TOML sidecar."""
    path = Path(path)
    if path.exists() and not (path.is_file() or path.is_dir()):
        # a FIFO or a device: reading it hangs or never ends (issue 13)
        raise SceneError("TOML config is not a regular file (a device, FIFO or socket)", path)
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise SceneError("TOML config not found", path) from None
    except IsADirectoryError:
        raise SceneError("TOML config is a directory, not a file", path) from None
    except OSError as err:
        raise SceneError(f"cannot read TOML config: {err.strerror or err}", path) from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        raise SceneError(f"malformed TOML: {err}", path) from None
    unknown = sorted(set(data) - {"camera", "light", "material", "shape", "mgf"})
    if unknown:
        raise SceneError(
            f"unknown key {unknown[0]!r} (allowed: [camera], [[light]], [[material]], "
            "[[shape]], [mgf])", path
        )
    camera = _camera(data["camera"], path) if "camera" in data else None
    points, directional = _lights(data.get("light", []), path)
    return Config(str(path), camera, points, directional,
                  materials=_materials(data.get("material", []), path),
                  shapes=_shapes(data.get("shape", []), path),
                  mgf_one_sided=_mgf(data.get("mgf", {}), path))

