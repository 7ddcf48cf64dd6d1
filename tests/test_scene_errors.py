"""Every bad scene input is refused with a SceneError naming the file (docs/design.md §6, §7)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from daskrad import tolerances
from daskrad.errors import DaskradWarning, SceneError
from daskrad.scene import load_scene, scene_from_arrays
from tests.helpers import CORNELL, REPO

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
    # --- issue 13: mtllib only names regular files of bounded size, relative to the scene ---
    "mtl-fifo": lambda t: (_mtllib(t, _fifo(t / "pipe.mtl")), None, t / "pipe.mtl",
                           "not a regular file"),
    "mtl-dev-zero": lambda t: (_mtllib(t, "/dev/zero"), None, "/dev/zero", "not a regular file"),
    "mtl-directory": lambda t: ((t / "lib.mtl").mkdir() or _mtllib(t, "lib.mtl"), None,
                                t / "lib.mtl", "directory"),
    "mtl-too-large": lambda t: (_mtllib(t, _sparse(t / "huge.mtl", (64 << 20) + 1)), None,
                                t / "huge.mtl", "too large"),
    "mtl-not-a-library": lambda t: (_mtllib(t, _write(t / "notes.txt", "root:x:0:0\n").name),
                                    None, t / "notes.txt", "not a material library"),
    "mtl-missing": lambda t: (_mtllib(t, "gone.mtl"), None, t / "gone.mtl", "not found"),
    "scene-fifo": lambda t: (_fifo(t / "s.obj") and t / "s.obj", None, t / "s.obj",
                             "not a regular file"),
    # --- issue 13: indices and magnitudes that overflow ---
    "index-overflow": lambda t: (_obj(t, TRI + "f 1 2 99999999999999999999999\n"), None,
                                 t / "s.obj", "line 6: vertex index 99999999999999999999999 is "
                                 "out of range (3 vertices)"),
    "ply-index-past-vertices": lambda t: (_write(t / "p.ply", PLY_HEAD + "0 0 0\n1 0 0\n0 1 0\n"
                                                 "3 0 1 7\n"), None, t / "p.ply",
                                          "vertex index 7 is out of range (3 vertices)"),
    "coordinates-1e308": lambda t: (_obj(t, "v 0 0 0\nv 1e308 0 0\nv 0 1e308 0\n"
                                         "v -1e308 -1e308 0\nf 1 2 3\nf 1 3 4\n"), None,
                                    t / "s.obj", "beyond ±1e+75"),
    "ke-1e308": lambda t: (_obj(t, TRI + "f 1 2 3\n", "newmtl lamp\nKd 0.5 0.5 0.5\n"
                                "Ke 1e308 1 1\n"), None, t / "s.obj", "Ke R = 1e+308 is out "
                           "of range"),
    "point-light-1e308": lambda t: (_toml(t, '[[light]]\ntype = "point"\nposition = [0, 0, 1]\n'
                                          "intensity = [1, 1e308, 1]\n"), None, t / "s.obj",
                                    "point light 1: intensity G = 1e+308 is out of range"),
    "point-light-1e200": lambda t: (_toml(t, '[[light]]\ntype = "point"\nposition = [0, 0, 1]\n'
                                          "intensity = [1e200, 1, 1]\n"), None, t / "s.obj",
                                    "point light 1: intensity R = 1e+200 is out of range"),
    "toml-fifo": lambda t: (_obj(t, TRI + "f 1 2 3\n"), t / _fifo(t / "c.toml"), t / "c.toml",
                           "not a regular file"),
    "camera-1e308": lambda t: (_toml(t, "[camera]\neye = [0, 0, 1e308]\nlook_at = [0, 0, 0]\n"
                                     "fov = 40\n"), None, t / "s.toml", "camera.eye"),
    "directional-1e308": lambda t: (_toml(t, '[[light]]\ntype = "directional"\n'
                                          "direction = [0, 0, -1]\nirradiance = [1e308, 1, 1]\n"),
                                    None, t / "s.obj", "irradiance R = 1e+308 is out of range"),
}

PLY_HEAD = ("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
            "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
            "end_header\n")


def _mtllib(tmp: Path, name: str) -> Path:
    """``s.obj`` whose ``mtllib`` line names ``name`` (as written, relative to ``tmp``)."""
    return _write(tmp / "s.obj", f"mtllib {name}\nusemtl lamp\n" + TRI + "f 1 2 3\n")


def _fifo(path: Path) -> str:
    os.mkfifo(path)
    return path.name


def _sparse(path: Path, size: int) -> str:
    with open(path, "wb") as f:
        f.truncate(size)  # no disk used: a hole
    return path.name


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
    assert err.path == str(named), err.line()
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


# The CLI contract (docs/design.md §7): exit code 2, exactly one line on stderr, no traceback.
CLI_CASES = ["missing", "unknown-format", "nan", "kd-one", "no-light", "toml-malformed",
             "garbage-ply",
             # issue 13: each of these hung, grew without bound, printed a traceback or numpy
             # RuntimeWarnings before the line, or rendered an inf/NaN image with exit 0
             "mtl-fifo", "mtl-dev-zero", "mtl-too-large", "mtl-not-a-library", "scene-fifo",
             "index-overflow", "ply-index-past-vertices", "coordinates-1e308", "ke-1e308",
             "point-light-1e308", "point-light-1e200", "toml-fifo", "camera-1e308"]


@pytest.mark.parametrize("case", CLI_CASES)
def test_cli_info_refuses_bad_input_in_one_line(tmp_path, case):
    path, config, named, fragment = CASES[case](tmp_path)
    args = [sys.executable, "-m", "daskrad", "info", str(path)]
    if config is not None:
        args += ["--config", str(config)]
    proc = subprocess.run(args, capture_output=True, text=True, cwd=REPO, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert str(named) in lines[0] and fragment in lines[0]


# --- coplanar overlapping faces (issue 7) ---------------------------------------------------

SQUARES = ("v 0 0 0\nv 2 0 0\nv 2 2 0\nv 0 2 0\n"      # 1-4: a 2 × 2 square, facing +z
           "v 1 1 0\nv 3 1 0\nv 3 3 0\nv 1 3 0\n"      # 5-8: overlapping it by 1 × 1
           "v 4 0 0\nv 5 0 0\nv 5 1 0\nv 4 1 0\n")     # 9-12: elsewhere in the plane


LAMP_AND_WALL = "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\nnewmtl wall\nKd 0.5 0.5 0.5\n"


def _walls(tmp: Path, vertices: str, faces: str) -> Path:
    """An OBJ whose first face emits and the others (``faces``) do not."""
    return _obj(tmp, vertices + "v 9 9 0\nv 9.5 9 0\nv 9 9.5 0\nf -3 -2 -1\nusemtl wall\n"
                + faces, LAMP_AND_WALL)


def test_coplanar_overlap_is_resolved_by_lifting_the_later_of_equal_faces(tmp_path):
    # issue 16: two 2 × 2 squares overlapping by 1 × 1 (equal areas: the later one, face 3,
    # goes on top, as a painter would) and a disjoint square (face 1): face 3 moves
    # DECAL_LIFT · diag up along its normal, on vertices of its own; one warning line
    path = _walls(tmp_path, SQUARES, "f 9 10 11 12\nf 1 2 3 4\nf 5 6 7 8\n")
    with pytest.warns(DaskradWarning) as record:
        scene = load_scene(path)
    assert len(record) == 1
    line = str(record[0].message)
    assert "\n" not in line
    assert line.startswith(f"{path}: 1 faces lie on larger faces in one plane (coplanar "
                           "overlaps, first face 4 on face 3): lifted 2e-05 × the scene "
                           "diagonal"), line
    assert scene.warnings == (line,)
    diag = np.hypot(9.5, 9.5)
    first = scene.vertices[scene.polygons[:, 0]]
    np.testing.assert_allclose(first[:, 2], [0, 0, 0, tolerances.DECAL_LIFT * diag],
                               rtol=1e-12, atol=0)
    # the lifted face keeps its shape; the one below keeps its vertices (1-4, shared)
    lifted = scene.vertices[scene.polygons[3]]
    np.testing.assert_allclose(lifted[:, :2], [[1, 1], [3, 1], [3, 3], [1, 3]])
    np.testing.assert_array_equal(scene.polygons[2], [0, 1, 2, 3])


def test_decals_stack_and_the_smaller_face_goes_on_top(tmp_path):
    # a 4 × 4 floor, a 2 × 2 rug on it, a 1 × 1 picture on the rug and a 0.5 × 0.5 sticker
    # on the floor only: levels 0, 1, 2, 1 whatever the order in the file (rug last)
    v = ("v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\n"          # 1-4 floor
         "v 1 1 0\nv 3 1 0\nv 3 3 0\nv 1 3 0\n"          # 5-8 rug
         "v 1.5 1.5 0\nv 2.5 1.5 0\nv 2.5 2.5 0\nv 1.5 2.5 0\n"  # 9-12 picture
         "v 3.2 3.2 0\nv 3.7 3.2 0\nv 3.7 3.7 0\nv 3.2 3.7 0\n")  # 13-16 sticker
    path = _walls(tmp_path, v, "f 9 10 11 12\nf 13 14 15 16\nf 1 2 3 4\nf 5 6 7 8\n")
    with pytest.warns(DaskradWarning, match="3 faces lie on larger faces .* "
                      r"\(2 levels where stacked\)"):
        scene = load_scene(path)
    step = tolerances.DECAL_LIFT * np.hypot(9.5, 9.5)
    z = scene.vertices[scene.polygons[1:]][:, :, 2]
    np.testing.assert_allclose(z, np.array([2, 1, 0, 1])[:, None] * step * np.ones(4),
                               rtol=1e-12, atol=0)


def test_coplanar_overlap_that_cannot_be_resolved_is_refused_naming_both_faces(tmp_path):
    # an emitting face under another: its covered part would still emit through the back of
    # the (one-sided) face lifted over it, so the input must change: one line, both faces
    path = _obj(tmp_path, SQUARES + "usemtl wall\nf 9 10 11 12\nusemtl lamp\nf 1 2 3 4\n"
                "usemtl wall\nv 0.5 0.5 0\nv 1.5 0.5 0\nv 1.5 1.5 0\nf 13 14 15\n",
                "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\nnewmtl wall\nKd 0.5 0.5 0.5\n")
    with pytest.raises(SceneError) as err:
        load_scene(path)
    line = err.value.line()
    assert line == (f"{path}: face 3 lies on emitting face 2 in one plane, facing the same way: "
                    "the covered part would still emit through it; cut it out of the emitting "
                    "face"), line
    # a soup stacked deeper than MAX_DECAL_DEPTH is no decal: refused
    k = tolerances.MAX_DECAL_DEPTH + 2
    size = 1.0 + np.arange(k)[::-1]                     # nested squares, largest first
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    verts = (square[None] * size[:, None, None]).reshape(-1, 3)
    polys = np.arange(4 * k).reshape(k, 4)
    with pytest.raises(SceneError, match=r"faces 1 and 2 lie in one plane.* "
                       f"stack more than {tolerances.MAX_DECAL_DEPTH} deep"):
        scene_from_arrays(verts, polys, np.zeros(k), [[0.5] * 3], [[0.0] * 3],
                          point_lights=([[0, 0, 1]], [[1, 1, 1]]))
    # one level less is accepted: the smallest square on top, MAX_DECAL_DEPTH levels up
    with pytest.warns(DaskradWarning):
        s = scene_from_arrays(verts[4:], polys[:-1], np.zeros(k - 1), [[0.5] * 3],
                              [[0.0] * 3], point_lights=([[0, 0, 1]], [[1, 1, 1]]))
    assert s.vertices[s.polygons[-1, 0], 2] == pytest.approx(
        tolerances.MAX_DECAL_DEPTH * tolerances.DECAL_LIFT * np.sqrt(2) * (k - 1), rel=1e-12)


def test_cli_prints_each_scene_warning_as_one_line(tmp_path):
    # a duplicated face and a decal: two lines "daskrad: warning: ...", no Python source line
    path = _walls(tmp_path, SQUARES, "f 9 10 11 12\nf 1 2 3 4\nf 1 2 3 4\nf 5 6 7 8\n")
    proc = subprocess.run([sys.executable, "-m", "daskrad", "info", str(path)],
                          capture_output=True, text=True, cwd=REPO, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.splitlines() == [
        f"daskrad: warning: {path}: dropped 1 duplicated faces (same corners and winding as an "
        "earlier face; the first is kept)",
        f"daskrad: warning: {path}: 1 faces lie on larger faces in one plane (coplanar overlaps, "
        "first face 5 on face 3): lifted 2e-05 × the scene diagonal off the plane along their "
        "normals so that they show"], proc.stderr


SHARED = REPO.parent / "shared" / "scenes"


@pytest.mark.skipif(not (SHARED / "variants" / "office3_raw").is_dir(),
                    reason="the shared scenes are not beside the repository")
def test_office3_raw_resolves_like_its_converted_twin():
    # the LBL office's 14 coplanar overlapping pairs: lifted like the converter lifted them
    # (2e-5 × the diagonal), so the raw file loads as the converted one, to the converter's
    # 17-digit rounding
    with pytest.warns(DaskradWarning, match="14 faces lie on larger faces"):
        raw = load_scene(SHARED / "variants" / "office3_raw" / "office3_raw.obj")
    conv = load_scene(SHARED / "office3" / "office3.obj")
    assert len(raw.warnings) == 1 and conv.warnings == ()

    def corners(s):
        p = s.polygons
        return s.vertices[np.where(p >= 0, p, p[:, 2:3])]

    moved = np.abs(corners(raw) - corners(conv)).max(axis=(1, 2))
    assert (moved > 0).sum() <= 14 and moved.max() < 1e-8 * raw.diagonal


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
    scene = load_scene(CORNELL)
    assert scene.emitting.sum() >= 1


def test_coplanar_overlap_far_from_the_origin_and_at_any_scale():
    # the tolerance and the lift follow the scene's size: the same pair is found and lifted by
    # the same fraction of the scene in millimetres and in kilometres, and 1e6 from the origin
    v = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1, 1, 0], [3, 1, 0],
                  [3, 3, 0], [1, 3, 0]], float)
    for scale, offset in [(1e-3, 0.0), (1e3, 0.0), (1.0, 1e6)]:
        lamp = ([[offset, offset, offset + scale]], [[scale**2] * 3])
        with pytest.warns(DaskradWarning, match="first face 2 on face 1"):
            s = scene_from_arrays(v * scale + offset, [[0, 1, 2, 3], [4, 5, 6, 7]], [0, 0],
                                  [[0.5] * 3], [[0.0] * 3], point_lights=lamp)
        lift = s.vertices[s.polygons[1], 2] + s.origin[2] - offset   # file coordinates
        np.testing.assert_allclose(lift, tolerances.DECAL_LIFT * np.sqrt(18) * scale,
                                   rtol=1e-6)
        # lifted off the plane by 1e-6 of the scene's size: two planes, nothing to do
        lifted = v * scale + offset
        lifted[4:, 2] += 1e-6 * 3.6 * scale
        assert scene_from_arrays(lifted, [[0, 1, 2, 3], [4, 5, 6, 7]], [0, 0], [[0.5] * 3],
                                 [[1.0] * 3]).warnings == ()
