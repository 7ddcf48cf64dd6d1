"""glTF as written: its cameras and ``KHR_lights_punctual`` lights (issue 16 item 5).

trimesh reads a glTF file's meshes and materials (:mod:`daskrad.scene.meshfile`) and places
each mesh with its node's world transform; the cameras and lights hang on nodes too, so they
are placed here with the same transforms, from the file's own JSON.

Units. glTF gives a point light's ``intensity`` in candela (lm/sr) and a directional light's in
lux (lm/m²); daskrad's point lights are W/sr and directional lights W/m² on a surface facing
them. Photometric to radiometric at :data:`LUMENS_PER_WATT` = 683 lm/W, the luminous efficacy
that defines the candela (monochromatic light at 540 THz); the light's ``color`` (linear RGB,
default white) multiplies it per channel::

    I [W/sr] = intensity [cd] / 683 · color        E [W/m²] = intensity [lx] / 683 · color

A light's ``range`` (a cut-off for real-time engines) is ignored: light falls off as 1/r²
everywhere, as physics and the path tracer have it. Spot lights are refused with one line
(daskrad has no cone-limited light).

Cameras: glTF's perspective camera looks along its node's −Z with +Y up, ``yfov`` the
vertical field of view in radians; daskrad's :class:`Camera` takes the horizontal field of view
in degrees, so ``fov = 2 atan(tan(yfov/2) · aspect)`` with ``aspect = aspectRatio`` (default
1). The image is 256 pixels wide and ``256 / aspect`` high unless the run says otherwise.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from daskrad.errors import SceneError
from daskrad.scene.types import Camera, DirectionalLights, PointLights

#: Lumens per watt: converts candela to W/sr and lux to W/m² (the candela's definition).
LUMENS_PER_WATT = 683.0

#: Image width of a glTF camera (its height follows its aspect ratio).
WIDTH = 256


def _node_matrix(node: dict) -> np.ndarray:
    """The node's local 4×4 transform: ``matrix`` (column-major), or ``T · R · S``."""
    if "matrix" in node:
        return np.asarray(node["matrix"], np.float64).reshape(4, 4).T
    t = np.eye(4)
    t[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    x, y, z, w = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    r = np.eye(4)
    r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                 [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                 [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
    s = np.diag([*node.get("scale", [1.0, 1.0, 1.0]), 1.0])
    return t @ r @ s


def world_nodes(doc: dict) -> list[tuple[int, np.ndarray]]:
    """``(node index, world 4×4 transform)`` of every node of the default scene, depth
    first in the file's order (nodes of no scene: all roots, as trimesh does)."""
    nodes = doc.get("nodes", []) or []
    scenes = doc.get("scenes", []) or []
    if scenes:
        roots = scenes[int(doc.get("scene", 0))].get("nodes", [])
    else:
        children = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in children]
    out: list[tuple[int, np.ndarray]] = []
    stack = [(int(i), np.eye(4)) for i in reversed(roots)]
    seen: set[int] = set()
    while stack:
        i, parent = stack.pop()
        if i in seen or not 0 <= i < len(nodes):
            continue                       # a cycle or a bad index: trimesh refuses it first
        seen.add(i)
        world = parent @ _node_matrix(nodes[i])
        out.append((i, world))
        stack.extend((int(c), world) for c in reversed(nodes[i].get("children", [])))
    return out


def camera(doc: dict, path: Path, name: str | None = None) -> Camera | None:
    """The file's first perspective camera placed by a node, or the one called ``name``
    (``--camera``); ``None`` if it has none. An unknown name is a :class:`SceneError`."""
    cams = doc.get("cameras", []) or []
    placed = [(i, world) for i, world in world_nodes(doc)
              if "camera" in doc["nodes"][i]]
    names = [str(cams[doc["nodes"][i]["camera"]].get("name", doc["nodes"][i].get("name", "")))
             for i, _ in placed]
    if name is not None:
        if name not in names:
            raise SceneError(f"no camera called {name!r} (cameras: "
                             f"{', '.join(repr(n) for n in names) or 'none'})", path)
        placed = [placed[names.index(name)]]
    for i, world in placed:
        cam = cams[doc["nodes"][i]["camera"]]
        if cam.get("type") != "perspective":
            if name is not None:
                raise SceneError(f"camera {name!r} is orthographic; daskrad renders "
                                 "perspective cameras only", path)
            continue
        p = cam.get("perspective", {})
        aspect = float(p.get("aspectRatio", 1.0))
        yfov = float(p["yfov"])
        fov = math.degrees(2.0 * math.atan(math.tan(yfov / 2.0) * aspect))
        eye = world[:3, 3]
        forward = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
        up = world[:3, :3] @ np.array([0.0, 1.0, 0.0])
        return Camera(eye=eye, look_at=eye + forward / np.linalg.norm(forward),
                      up=up / np.linalg.norm(up), fov=fov, width=WIDTH,
                      height=max(1, round(WIDTH / aspect)))
    return None


def lights(doc: dict, path: Path) -> tuple[PointLights, DirectionalLights]:
    """The ``KHR_lights_punctual`` lights placed by nodes, in W/sr and W/m²."""
    table = ((doc.get("extensions", {}) or {}).get("KHR_lights_punctual", {}) or {}).get(
        "lights", []) or []
    pos, power, dirs, irr = [], [], [], []
    for i, world in world_nodes(doc):
        ext = (doc["nodes"][i].get("extensions", {}) or {}).get("KHR_lights_punctual")
        if not ext:
            continue
        light = table[int(ext["light"])]
        kind = light.get("type")
        rgb = np.asarray(light.get("color", [1.0, 1.0, 1.0]), np.float64)
        value = float(light.get("intensity", 1.0)) / LUMENS_PER_WATT * rgb
        if kind == "point":
            pos.append(world[:3, 3])
            power.append(value)
        elif kind == "directional":
            d = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
            dirs.append(d / np.linalg.norm(d))
            irr.append(value)
        else:
            raise SceneError(f"light {light.get('name', i)!r} is a {kind} light; daskrad has "
                             "point and directional lights only (no spot cone)", path)
    return (PointLights(np.array(pos).reshape(-1, 3), np.array(power).reshape(-1, 3)),
            DirectionalLights(np.array(dirs).reshape(-1, 3), np.array(irr).reshape(-1, 3)))
