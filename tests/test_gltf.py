"""glTF as written (issue 16 item 5): the file's cameras and KHR_lights_punctual lights, in
daskrad's units (candela / 683 → W/sr, lux / 683 → W/m²)."""

from __future__ import annotations

import base64
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from daskrad.errors import SceneError
from daskrad.scene import load_scene
from daskrad.scene.gltf import LUMENS_PER_WATT

S = math.sqrt(0.5)


def write_gltf(path, lights=None, cameras=None, extra_nodes=()):
    """A 2 × 2 floor facing +y (ρ 0.5) with the given light and camera nodes."""
    pos = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
    idx = np.array([0, 3, 2, 0, 2, 1], np.uint16)
    blob = pos.tobytes() + idx.tobytes()
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                     + base64.b64encode(blob).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48},
                        {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [-1, 0, -1], "max": [1, 0, 1]},
                      {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
        "materials": [{"name": "floor", "pbrMetallicRoughness": {
            "baseColorFactor": [0.5, 0.5, 0.5, 1.0]}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1,
                                    "material": 0}]}],
        "nodes": [{"mesh": 0}, *extra_nodes],
        "scenes": [{"nodes": [i for i in range(1 + len(extra_nodes))
                              if not any(i in n.get("children", []) for n in extra_nodes)]}],
        "scene": 0,
    }
    if cameras:
        doc["cameras"] = cameras
    if lights:
        doc["extensionsUsed"] = ["KHR_lights_punctual"]
        doc["extensions"] = {"KHR_lights_punctual": {"lights": lights}}
    path.write_text(json.dumps(doc))
    return path


LIGHTS = [{"type": "point", "intensity": 683.0, "color": [1.0, 0.5, 0.25]},
          {"type": "directional", "intensity": 2 * 683.0}]
NODES = [
    {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0.2, 1.0, 0.1]},
    # rotated −90° about x: the light's −z points down (−y)
    {"extensions": {"KHR_lights_punctual": {"light": 1}}, "rotation": [-S, 0.0, 0.0, S]},
    # a parent moves its child: the camera sits at (0, 1, 3), looking along −z
    {"translation": [0.0, 1.0, 0.0], "children": [4]},   # file index 3 (node 0 is the mesh)
    {"camera": 0, "translation": [0.0, 0.0, 3.0], "name": "front"},
    {"camera": 1, "translation": [0.0, 5.0, 0.0], "rotation": [-S, 0.0, 0.0, S]},
]
CAMERAS = [{"type": "perspective", "name": "front",
            "perspective": {"yfov": 0.8, "aspectRatio": 1.5, "znear": 0.1}},
           {"type": "perspective", "name": "top", "perspective": {"yfov": 0.6}}]


def test_lights_and_camera_in_daskrad_units(tmp_path):
    scene = load_scene(write_gltf(tmp_path / "f.gltf", LIGHTS, CAMERAS, NODES))
    o = scene.origin
    np.testing.assert_allclose(scene.point_lights.position + o, [[0.2, 1.0, 0.1]], atol=1e-12)
    np.testing.assert_allclose(scene.point_lights.intensity, [[1.0, 0.5, 0.25]], rtol=1e-12)
    np.testing.assert_allclose(scene.directional_lights.direction, [[0, -1, 0]], atol=1e-12)
    np.testing.assert_allclose(scene.directional_lights.irradiance, [[2, 2, 2]], rtol=1e-12)
    cam = scene.camera
    np.testing.assert_allclose(cam.eye + o, [0, 1, 3], atol=1e-12)
    np.testing.assert_allclose(cam.look_at - cam.eye, [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(cam.up, [0, 1, 0], atol=1e-12)
    assert cam.fov == pytest.approx(math.degrees(2 * math.atan(math.tan(0.4) * 1.5)))
    assert (cam.width, cam.height) == (256, 171)
    top = load_scene(tmp_path / "f.gltf", camera="top").camera
    np.testing.assert_allclose(top.eye + o, [0, 5, 0], atol=1e-12)
    np.testing.assert_allclose(top.look_at - top.eye, [0, -1, 0], atol=1e-12)
    assert top.fov == pytest.approx(math.degrees(0.6))
    assert LUMENS_PER_WATT == 683.0


def test_the_point_light_lights_the_floor_by_the_inverse_square_law(tmp_path):
    # 683 cd white 1 m above the floor: 1 W/sr, so H = 1 W/m² below it (ρ 0.5: radiance ρ/π)
    from daskrad import direct
    from daskrad.preprocess import preprocess
    from daskrad.settings import Settings

    light = [{"type": "point", "intensity": 683.0}]
    node = {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0, 1, 0]}
    scene = load_scene(write_gltf(tmp_path / "p.gltf", light, None, [node]))
    s = Settings(patch_size=1.0, element_size=0.5, subdivide=0.0)
    d = direct.light(scene, preprocess(scene, s), s)
    v = d.mesh.hierarchy.vertices + scene.origin
    centre = np.flatnonzero(np.linalg.norm(v - [0, 0, 0], axis=1) < 1e-9)
    assert len(centre) == 1
    np.testing.assert_allclose(d.irradiance[centre[0]], [1, 1, 1], rtol=1e-6)


@pytest.mark.parametrize("case, words", [
    ("spot", "spot light"), ("camera", "no camera called 'side'")])
def test_what_daskrad_cannot_do_is_one_line(tmp_path, case, words):
    if case == "spot":
        path = write_gltf(tmp_path / "s.gltf", [{"type": "spot", "intensity": 10.0}], None,
                          [{"extensions": {"KHR_lights_punctual": {"light": 0}}}])
        args = []
    else:
        path = write_gltf(tmp_path / "s.gltf", LIGHTS, CAMERAS, NODES)
        args = ["--camera", "side"]
    with pytest.raises(SceneError, match=words):
        load_scene(path, camera=args[1] if args else None)
    proc = subprocess.run([sys.executable, "-m", "daskrad", "info", str(path), *args],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "s.gltf" in lines[0] and words in lines[0], proc.stderr
