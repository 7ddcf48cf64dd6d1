"""Every bad scene input is refused with a SceneError naming the file (DESIGN §6, §7)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from daskrad.errors import SceneError
from daskrad.scene import load_scene, scene_from_arrays

REPO = Path(__file__).resolve().parent.parent

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\n"


def _obj(tmp: Path, body: str, mtl: str | None = "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\n",
         name: str = "s") -> Path:
    """An OBJ ``name.obj`` (with ``mtllib name.mtl`` and ``usemtl lamp`` when ``mtl``)."""
    head = f"mtllib {name}.mtl\nusemtl lamp\n" if mtl is not None else ""
    if mtl is not None:
        (tmp / f"{name}.mtl").write_text(mtl)
    path = tmp / f"{name}.obj"
    path.write_text(head + body)
    return path


def _toml(tmp: Path, text: str) -> Path:
    _obj(tmp, TRI + "f 1 2 3\n")
    (tmp / "s.toml").write_text(text)
    return tmp / "s.obj"


# Each case: make(tmp) -> (scene path, config or None, the file the message must name,
# a fragment of the message)
CASES = {
    "missing": lambda t: (t / "nope.obj", None, t / "nope.obj", "no such file"),
    "directory": lambda t: ((t / "d.obj").mkdir() or t / "d.obj", None, t / "d.obj",
                            "directory"),
    "unknown-format": lambda t: (_write(t / "s.xyz", "1 2 3"), None, t / "s.xyz",
                                 "unknown scene format"),
    "no-faces": lambda t: (_obj(t, TRI), None, t / "s.obj", "no faces"),
    "empty": lambda t: (_write(t / "e.obj", ""), None, t / "e.obj", "no faces"),
    "binary-obj": lambda t: (_write_bytes(t / "b.obj", bytes(range(256)) * 8), None,
                             t / "b.obj", "binary"),
    "nan": lambda t: (_obj(t, "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n"), None, t / "s.obj",
                      "NaN or infinite"),
    "inf": lambda t: (_obj(t, "v 0 0 0\nv 1 0 0\nv 0 inf 0\nf 1 2 3\n"), None, t / "s.obj",
                      "NaN or infinite"),
    "bad-vertex": lambda t: (_obj(t, "v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), None,
                             t / "s.obj", "line 3"),
    "index-range": lambda t: (_obj(t, TRI + "f 1 2 7\n"), None, t / "s.obj", "out of range"),
    "two-corners": lambda t: (_obj(t, TRI + "f 1 2\n"), None, t / "s.obj", "3 corners"),
    "kd-one": lambda t: (_obj(t, TRI + "f 1 2 3\n", "newmtl lamp\nKd 1 0.5 0.5\nKe 1 1 1\n"),
                         None, t / "s.obj", "outside [0, 1)"),
    "kd-negative": lambda t: (_obj(t, TRI + "f 1 2 3\n",
                                   "newmtl lamp\nKd 0.5 -0.1 0.5\nKe 1 1 1\n"),
                              None, t / "s.obj", "outside [0, 1)"),
    "kd-nan": lambda t: (_obj(t, TRI + "f 1 2 3\n", "newmtl lamp\nKd 0.5 0.5 nan\nKe 1 1 1\n"),
                         None, t / "s.obj", "outside [0, 1)"),
    "ke-negative": lambda t: (_obj(t, TRI + "f 1 2 3\n",
                                   "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 -1 1\n"),
                              None, t / "s.obj", "not negative"),
    "no-light": lambda t: (_obj(t, TRI + "f 1 2 3\n", "newmtl lamp\nKd 0.5 0.5 0.5\n"), None,
                           t / "s.obj", "no light"),
    "no-light-no-mtl": lambda t: (_obj(t, TRI + "f 1 2 3\n", None), None, t / "s.obj",
                                  "no light"),
    "all-degenerate": lambda t: (_obj(t, "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"), None,
                                 t / "s.obj", "zero area"),
    "missing-mtl": lambda t: (_write(t / "m.obj", "mtllib gone.mtl\n" + TRI + "f 1 2 3\n"),
                              None, t / "gone.mtl", "not found"),
    "undefined-material": lambda t: (_obj(t, "usemtl chrome\n" + TRI + "f 1 2 3\n"), None,
                                     t / "s.obj", "'chrome' is not defined"),
    "bad-mtl-number": lambda t: (_obj(t, TRI + "f 1 2 3\n", "newmtl lamp\nKd 0.5 x 0.5\n"),
                                 None, t / "s.mtl", "needs numbers"),
    "toml-malformed": lambda t: (_toml(t, "[camera\neye = 1"), None, t / "s.toml",
                                 "malformed TOML"),
    "toml-unknown-key": lambda t: (_toml(t, "[camera]\neye = [0, 0, 1]\nlook_at = [0, 0, 0]\n"
                                         "fov = 40\nzoom = 2\n"), None, t / "s.toml", "'zoom'"),
    "toml-unknown-table": lambda t: (_toml(t, "[render]\nspp = 4\n"), None, t / "s.toml",
                                     "'render'"),
    "toml-shape": lambda t: (_toml(t, '[[shape]]\ntype = "sphere"\n'), None, t / "s.toml",
                             "needs 'material'"),
    "toml-wrong-type": lambda t: (_toml(t, "[camera]\neye = [0, 0, 1]\nlook_at = [0, 0, 0]\n"
                                        'fov = "wide"\n'), None, t / "s.toml", "fov"),
    "toml-short-vector": lambda t: (_toml(t, '[[light]]\ntype = "point"\nposition = [0, 1]\n'
                                          "intensity = [1, 1, 1]\n"), None, t / "s.toml",
                                    "position"),
    "toml-bad-light-type": lambda t: (_toml(t, '[[light]]\ntype = "spot"\n'), None,
                                      t / "s.toml", "spot"),
    "toml-light-missing-key": lambda t: (_toml(t, '[[light]]\ntype = "directional"\n'
                                               "direction = [0, -1, 0]\n"), None,
                                         t / "s.toml", "irradiance"),
    "toml-negative-intensity": lambda t: (_toml(t, '[[light]]\ntype = "point"\n'
                                                "position = [0, 1, 0]\n"
                                                "intensity = [1, -1, 1]\n"), None,
                                          t / "s.toml", "negative"),
    "toml-zero-direction": lambda t: (_toml(t, '[[light]]\ntype = "directional"\n'
                                            "direction = [0, 0, 0]\nirradiance = [1, 1, 1]\n"),
                                      None, t / "s.toml", "zero"),
    "toml-bool-width": lambda t: (_toml(t, "[camera]\neye = [0, 0, 1]\nlook_at = [0, 0, 0]\n"
                                        "fov = 40\nwidth = true\n"), None, t / "s.toml",
                                  "width"),
    "toml-eye-is-target": lambda t: (_toml(t, "[camera]\neye = [0, 0, 1]\nlook_at = [0, 0, 1]\n"
                                           "fov = 40\n"), None, t / "s.toml", "same point"),
    "config-missing": lambda t: (_obj(t, TRI + "f 1 2 3\n"), t / "gone.toml", t / "gone.toml",
                                 "not found"),
    "garbage-ply": lambda t: (_write_bytes(t / "g.ply", b"ply\nformat nonsense\n\x00\x01"),
                              None, t / "g.ply", "PLY"),
    # 50 bytes cannot hold a binary STL's header and count: trimesh reads no triangle
    "garbage-stl": lambda t: (_write_bytes(t / "g.stl", b"\x07" * 50), None, t / "g.stl",
                              "no faces"),
    "garbage-glb": lambda t: (_write_bytes(t / "g.glb", b"glTF\x02\x00\x00\x00garbage"), None,
                              t / "g.glb", "GLB"),
    "garbage-gltf": lambda t: (_write(t / "g.gltf", "{not json"), None, t / "g.gltf", "GLTF"),
}


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _write_bytes(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_is_a_scene_error_naming_the_file(tmp_path, case):
    path, config, named, fragment = CASES[case](tmp_path)
    with pytest.raises(SceneError) as info:
        load_scene(path, config)
    err = info.value
    assert err.path == str(named)
    assert str(named) in err.line()
    assert fragment in err.line()
    assert "\n" not in err.line()


def test_unreadable_file(tmp_path, monkeypatch):
    # the suite may run as root, for whom chmod 000 changes nothing: fake the permission check
    path = _obj(tmp_path, TRI + "f 1 2 3\n")
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == path else real(p, mode))
    with pytest.raises(SceneError, match="permission denied") as info:
        load_scene(path)
    assert info.value.path == str(path)


ARRAYS = dict(
    vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]],
    polygons=[[0, 1, 2, -1]],
    polygon_material=[0],
    diffuse=[[0.5, 0.5, 0.5]],
    emission=[[1.0, 1.0, 1.0]],
)


@pytest.mark.parametrize(
    "change, fragment",
    [
        (dict(vertices=[[0, 0, 0], [1, np.nan, 0], [0, 1, 0]]), "NaN or infinite"),
        (dict(diffuse=[[0.5, 1.0, 0.5]]), "outside [0, 1)"),
        (dict(emission=[[1.0, -1.0, 1.0]]), "not negative"),
        (dict(emission=[[0.0, 0.0, 0.0]]), "no light"),
        (dict(polygons=np.zeros((0, 4), int), polygon_material=[]), "no faces"),
        (dict(polygons=[[0, 1, 5, -1]]), "out of range"),
        (dict(polygon_material=[3]), "material index"),
        (dict(specular=[[1.5, 0, 0]]), "Ks"),
    ],
)
def test_scene_from_arrays_runs_the_same_checks(change, fragment):
    with pytest.raises(SceneError, match=None) as info:
        scene_from_arrays(**{**ARRAYS, **change}, path="built-in")
    assert info.value.path == "built-in" and fragment in info.value.line()


def test_point_light_alone_is_enough():
    # the same arrays without emission but with a point light are accepted
    s = scene_from_arrays(**{**ARRAYS, "emission": [[0.0, 0.0, 0.0]]},
                          point_lights=([[0, 0, 1]], [[1, 1, 1]]))
    assert len(s.point_lights) == 1 and not s.emitting.any()


# The CLI contract (DESIGN §7): exit code 2, exactly one line on stderr, no traceback.
CLI_CASES = ["missing", "unknown-format", "nan", "kd-one", "no-light", "toml-malformed",
             "garbage-ply"]


@pytest.mark.parametrize("case", CLI_CASES)
def test_cli_info_refuses_bad_input_in_one_line(tmp_path, case):
    path, config, named, fragment = CASES[case](tmp_path)
    args = [sys.executable, "-m", "daskrad", "info", str(path)]
    if config is not None:
        args += ["--config", str(config)]
    proc = subprocess.run(args, capture_output=True, text=True, cwd=REPO, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert str(named) in lines[0] and fragment in lines[0]


# --- coplanar overlapping faces (issue 7) ---------------------------------------------------

SQUARES = ("v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\n"      # 1-4: a 2 × 2 square, facing +z
           "v 1 1 0\nv 3 1 0\nv 3 3 0\nv 1 3 0\n"      # 5-8: overlapping it by 1 × 1
           "v 4 0 0\nv 5 0 0\nv 5 1 0\nv 4 1 0\n")     # 9-12: elsewhere in the plane


def test_coplanar_overlap_is_refused_naming_both_faces_of_the_file(tmp_path):
    # faces are numbered as in the file: the disjoint square (face 1) comes first, the
    # overlapping pair are faces 2 and 3
    path = _obj(tmp_path, SQUARES + "f 9 10 11 12\nf 1 2 3 4\nf 5 6 7 8\n")
    with pytest.raises(SceneError) as err:
        load_scene(path)
    line = err.value.line()
    assert "\n" not in line
    assert line.startswith(f"{path}: faces 2 and 3 lie in one plane, face the same way "
                           "and overlap"), line


@pytest.mark.parametrize("body", [
    "f 1 2 3 4\nf 2 9 12 3\n",                 # sharing the edge x = 2 of the square
    "f 1 2 3 4\nf 9 10 11 12\n",               # coplanar, disjoint
    "f 1 2 3 4\nf 3 6 7 8\n",                  # sharing a corner only (vertex 3 = (2, 2))
    "f 1 2 3 4\nf 8 7 6 5\n",                  # overlapping back to back: a two-sided plate
    "f 1 2 3\nf 1 3 4\n",                     # a square as two triangles (the diagonal)
])
def test_faces_that_touch_or_face_away_are_not_overlaps(tmp_path, body):
    extra = "v 3 3 0\n"  # 13 (unused)
    scene = load_scene(_obj(tmp_path, SQUARES + extra + body))
    assert len(scene.polygons) >= 2


def test_cornell_box_light_in_the_ceiling_hole_is_not_an_overlap():
    # the light lies in the ceiling's plane, facing down like the ceiling's pieces around it,
    # and touches them along edges only (the ceiling is four pieces around the hole)
    scene = load_scene(REPO / "scenes" / "cornell_box.obj")
    assert scene.emitting.sum() >= 1


def test_coplanar_overlap_far_from_the_origin_and_at_any_scale():
    # the tolerance follows the scene's size: the same pair is refused in millimetres and
    # in kilometres, and 1e6 away from the origin
    v = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1, 1, 0], [3, 1, 0],
                  [3, 3, 0], [1, 3, 0]], float)
    for scale, offset in [(1e-3, 0.0), (1e3, 0.0), (1.0, 1e6)]:
        with pytest.raises(SceneError, match="faces 1 and 2 lie in one plane"):
            scene_from_arrays(v * scale + offset, [[0, 1, 2, 3], [4, 5, 6, 7]], [0, 0],
                              [[0.5] * 3], [[1.0] * 3])
        # lifted off the plane by 1e-6 of the scene's size: two planes, accepted
        lifted = v * scale + offset
        lifted[4:, 2] += 1e-6 * 3.6 * scale
        scene_from_arrays(lifted, [[0, 1, 2, 3], [4, 5, 6, 7]], [0, 0], [[0.5] * 3],
                          [[1.0] * 3])
