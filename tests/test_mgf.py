"""MGF input (issue 16, item 2), on small files written from the specification (mgfdoc 1.0)."""

from __future__ import annotations

import math
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from daskrad import tolerances
from daskrad.errors import SceneError
from daskrad.mesh import one_sided
from daskrad.scene import load_scene
from daskrad.scene.mgf import WHITE_EFFICACY, XYZ_TO_RGB, read_mgf, xy_to_rgb
from daskrad.scene.polygons import polygon_area

REPO = Path(__file__).resolve().parent.parent
SHARED = REPO.parent / "shared" / "scenes"

# unit cube [0, 1]³, faces wound so that their normals point out of the box (right-hand rule)
CUBE_VERTICES = "".join(
    f"v c{x}{y}{z} =\n\tp {x} {y} {z}\n" for x in (0, 1) for y in (0, 1) for z in (0, 1))
CUBE_FACES = """f c000 c010 c110 c100
f c001 c101 c111 c011
f c000 c100 c101 c001
f c010 c011 c111 c110
f c000 c001 c011 c010
f c100 c110 c111 c101
"""
LAMP = "m lamp =\n\tsides 1\n\tc\n\ted 100\n\trd .5\n"


def write(tmp: Path, text: str, name: str = "s.mgf") -> Path:
    path = tmp / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def normals(v, p):
    n = np.cross(v[p[:, 1]] - v[p[:, 0]], v[p[:, 2]] - v[p[:, 0]])
    return n / np.linalg.norm(n, axis=1)[:, None]


def centroids(v, p):
    c = v[np.where(p >= 0, p, p[:, :1])]
    w = np.where(p[:, 3] >= 0, 4, 3)
    c[p[:, 3] < 0, 3] = 0.0
    return c.sum(axis=1) / w[:, None]


def volume(v, p):
    tri = np.concatenate([p[:, [0, 1, 2]], p[p[:, 3] >= 0][:, [0, 2, 3]]])
    t = v[tri]
    return float(np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])).sum() / 6)


# --------------------------------------------------------------------------- faces, materials


def test_unit_box_one_sided(tmp_path):
    data = read_mgf(write(tmp_path, LAMP + CUBE_VERTICES + CUBE_FACES))
    assert len(data.polygons) == 6 and (data.polygons[:, 3] >= 0).all()
    assert data.two_sided == 0
    assert len(data.vertices) == 8  # named vertices are shared by the faces using them
    assert polygon_area(data.vertices, data.polygons).sum() == pytest.approx(6.0, rel=1e-15)
    assert volume(data.vertices, data.polygons) == pytest.approx(1.0, rel=1e-15)
    out = centroids(data.vertices, data.polygons) - 0.5
    assert (np.einsum("ij,ij->i", normals(data.vertices, data.polygons), out) > 0).all()
    # neutral grey (the unnamed colour): Kd = rd, Ke = ed / (183.07 π) in every channel
    assert data.names == ["lamp"]
    np.testing.assert_allclose(data.diffuse, [[0.5, 0.5, 0.5]], rtol=1e-12)
    np.testing.assert_allclose(data.emission, [[100 / (WHITE_EFFICACY * math.pi)] * 3],
                               rtol=1e-12)


def test_colour_conversion_keeps_chromaticity_and_luminance():
    # RGB -> XYZ with the primaries must give back the chromaticity and Y = 1 (in gamut)
    rgb_to_xyz = np.linalg.inv(XYZ_TO_RGB)
    for x, y in [(0.5, 0.3), (0.26, 0.26), (0.376563, 0.395833), (0.3, 0.5)]:
        xyz = rgb_to_xyz @ xy_to_rgb(x, y)
        assert xyz[1] == pytest.approx(1.0, rel=1e-12)
        assert xyz[0] / xyz.sum() == pytest.approx(x, rel=1e-12)
        assert xyz[1] / xyz.sum() == pytest.approx(y, rel=1e-12)
    np.testing.assert_allclose(xy_to_rgb(1 / 3, 1 / 3), 1.0, rtol=1e-12)
    # out of gamut: negative channels clipped (RenderPark's rule)
    assert xy_to_rgb(0.0, 0.38)[0] == 0.0


def test_material_contexts_snapshot_and_templates(tmp_path):
    text = CUBE_VERTICES + """m red =
\tsides 1
\tc rc =
\t\tcxy .5 .3
\trd .29
\tc
\trs .04 .01
m lamp =
\tsides 1
\ted 10
m alias = red
f c000 c010 c110 c100
m red
\trd .1
f c001 c101 c111 c011
m lamp
f c000 c100 c101 c001
# the unnamed material: a two-sided black absorber
m
f c010 c011 c111 c110
"""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        data = read_mgf(write(tmp_path, text))
    assert data.names == ["alias", "red", "lamp", "(unnamed)"]
    red = 0.29 * xy_to_rgb(0.5, 0.3)
    np.testing.assert_allclose(data.diffuse[0], red, rtol=1e-12)  # the alias copied red
    # red modified after its first use: the earlier face keeps the old values; the new rd
    # takes the colour in effect, the unnamed grey (the colour is its own context)
    np.testing.assert_allclose(data.diffuse[1], 0.1, rtol=1e-12)
    np.testing.assert_allclose(data.diffuse[3], 0.0)
    # the unnamed material alone is two-sided (the others say sides 1)
    assert data.two_sided.tolist() == [False, False, False, True] and len(data.polygons) == 4
    assert any("rs (specular/transmission) of 2 materials ignored" in str(w.message)
               for w in caught)


def test_vertex_changed_after_use_does_not_move_earlier_faces(tmp_path):
    text = LAMP + "v a =\n\tp 0 0 0\nv b =\n\tp 1 0 0\nv c =\n\tp 0 1 0\nf a b c\n" \
        "v c\n\tp 0 2 0\nf a b c\n"
    data = read_mgf(write(tmp_path, text))
    area = polygon_area(data.vertices, data.polygons)
    np.testing.assert_allclose(area, [0.5, 1.0])


def test_two_sided_faces_are_two_sided_and_meshed_with_a_back(tmp_path):
    text = "m lamp =\n\tc\n\ted 100\n" + CUBE_VERTICES + CUBE_FACES
    data = read_mgf(write(tmp_path, text))
    assert data.two_sided.tolist() == [True] and len(data.polygons) == 6
    scene = load_scene(tmp_path / "s.mgf")
    assert scene.two_sided.all() and len(scene.polygons) == 6
    # the mesher gives each face a reversed back TWO_SIDED_GAP · diagonal behind it
    flat = one_sided(scene)
    v, p = flat.vertices, flat.polygons
    n = normals(v, p)
    np.testing.assert_allclose(n[6:], -n[:6], atol=1e-12)
    gap = np.einsum("ij,ij->i", centroids(v, p)[:6] - centroids(v, p)[6:], n[:6])
    np.testing.assert_allclose(gap, tolerances.TWO_SIDED_GAP * math.sqrt(3), rtol=1e-6)
    # the backs of a face's coplanar neighbours share corners: 24 = 8 corners x 3 normals
    assert len(v) == 8 + 24
    # the sidecar's [mgf] one_sided = true makes every face one-sided
    (tmp_path / "s.toml").write_text("[mgf]\none_sided = true\n")
    assert not load_scene(tmp_path / "s.mgf").two_sided.any()


# --------------------------------------------------------------------------- primitives


def test_sphere_primitive_in_a_transform(tmp_path):
    text = LAMP + "v cen =\n\tp 1 2 3\nxf -s 2 -t 10 0 0\nsph cen .5\nxf\nsph cen -.25\n"
    data = read_mgf(write(tmp_path, text))
    big = data.polygon_face == 0
    v, p = data.vertices, data.polygons
    # the scale applies to the centre and radius: centre (12, 4, 6), radius 1
    used = np.unique(p[big][p[big] >= 0])
    np.testing.assert_allclose(np.linalg.norm(v[used] - [12, 4, 6], axis=1), 1.0, rtol=1e-12)
    diag = np.linalg.norm(np.array([13, 5, 7]) - [0.75, 1.75, 2.75])
    eps = tolerances.CHORD_ERROR * diag
    vol = volume(v, p[big])
    assert 4 / 3 * math.pi * (1 - eps) ** 3 <= vol <= 4 / 3 * math.pi
    # a negative radius faces inward: negative enclosed volume
    small = volume(v, p[~big])
    assert -4 / 3 * math.pi * 0.25**3 <= small < 0


def test_cylinder_cone_ring_torus_and_prism(tmp_path):
    text = LAMP + """v a =
\tp 0 0 0
\tn 0 0 1
v b =
\tp 0 0 2
v cv0 =
\tp 0 0 0
v cv1 =
\tp 0 1 0
v cv2 =
\tp 1 1 0
v cv3 =
\tp 1 0 0
cyl a .5 b
cone a .5 b .25
ring a .2 .5
torus a .1 .3
prism cv0 cv1 cv2 cv3 1
"""
    data = read_mgf(write(tmp_path, text))
    v, p, face = data.vertices, data.polygons, data.polygon_face
    area = polygon_area(v, p)
    diag = np.linalg.norm([1.5, 1.5, 2.1])  # the box of everything (the torus reaches -0.1)
    rel = 2 * tolerances.CHORD_ERROR * diag / 0.1  # the smallest radius sets the worst ratio
    assert area[face == 0].sum() == pytest.approx(2 * math.pi * 0.5 * 2, rel=rel)
    slant = math.hypot(2, 0.25)
    assert area[face == 1].sum() == pytest.approx(math.pi * 0.75 * slant, rel=rel)
    assert area[face == 2].sum() == pytest.approx(math.pi * (0.5**2 - 0.2**2), rel=rel)
    assert np.allclose(normals(v, p[face == 2]), [0, 0, 1])  # the ring faces its normal
    # torus: rmin/rmax are its inner and outer radii: tube 0.1 about a circle of 0.2
    assert volume(v, p[face == 3]) == pytest.approx(2 * math.pi**2 * 0.2 * 0.1**2, rel=rel)
    # the specification's unit cube: end face looking -z, extruded to +z, all faces outward
    prism = p[face == 4]
    assert len(prism) == 6
    assert volume(v, prism) == pytest.approx(1.0, rel=1e-14)
    c = centroids(v, prism) - 0.5
    assert (np.einsum("ij,ij->i", normals(v, prism), c) > 0).all()


# --------------------------------------------------------------------------- transforms


def test_transform_example_of_the_specification(tmp_path):
    # mgfdoc 2.2.2: "The final ring center is (5,-10,0) ... The normal orientation is
    # (0,0,-1) due to the rotation about X"
    text = LAMP + "xf -t 5 0 0\nv v1 =\n\tp 0 10 0\n\tn 0 0 1\nxf -rx 180\nring v1 0 2\nxf\nxf\n"
    data = read_mgf(write(tmp_path, text))
    v, p = data.vertices, data.polygons
    np.testing.assert_allclose(centroids(v, p).mean(axis=0), [5, -10, 0], atol=1e-9)
    np.testing.assert_allclose(normals(v, p), np.tile([0, 0, -1.0], (len(p), 1)), atol=1e-12)


def test_array_and_repeat(tmp_path):
    # 3 x 2 instances at x + 2i, y + 3j, then -i 2 -t: moved twice by (0, 0, 5)
    text = LAMP + "v a =\n\tp 0 0 0\nv b =\n\tp 1 0 0\nv c =\n\tp 0 1 0\n" \
        "xf -a 3 -t 2 0 0 -a 2 -t 0 3 0 -i 2 -t 0 0 5\nf a b c\nxf\n"
    data = read_mgf(write(tmp_path, text))
    corner = data.vertices[data.polygons[:, 0]]
    expected = {(2.0 * i, 3.0 * j, 10.0) for i in range(3) for j in range(2)}
    assert {tuple(x) for x in corner.round(12)} == expected


def test_mirror_keeps_faces_facing_the_way_the_file_meant(tmp_path):
    text = LAMP + CUBE_VERTICES + "xf -mx -t 3 0 0\n" + CUBE_FACES + "xf\n"
    data = read_mgf(write(tmp_path, text))
    v, p = data.vertices, data.polygons
    assert volume(v, p) == pytest.approx(1.0, rel=1e-14)  # still outward
    assert v[:, 0].min() == pytest.approx(2.0) and v[:, 0].max() == pytest.approx(3.0)


def test_include_relative_to_the_including_file_with_a_transform(tmp_path):
    write(tmp_path, CUBE_FACES, "parts/box.inc")
    write(tmp_path, "i box.inc -t 0 0 1\n", "parts/two.inc")
    text = LAMP + CUBE_VERTICES + "i parts/box.inc\ni parts/two.inc -s 2\n"
    data = read_mgf(write(tmp_path, text))
    assert len(data.polygons) == 12
    # second box: inner -t applied first, then the scale: [0, 2] x [0, 2] x [2, 4]
    second = np.unique(data.polygons[6:])
    np.testing.assert_allclose(data.vertices[second].min(axis=0), [0, 0, 2])
    np.testing.assert_allclose(data.vertices[second].max(axis=0), [2, 2, 4])


# --------------------------------------------------------------------------- bad input


BAD = {
    "missing vertex": (LAMP + "f a b c\n", "s.mgf", 6, "vertex 'a' is not defined"),
    "bad number": (LAMP + "v a =\n\tp 0 x 0\n", "s.mgf", 7, "'x' is not a number"),
    "few corners": (LAMP + "v a =\nf a a\n", "s.mgf", 7, "at least 3 vertices"),
    "include missing": (LAMP + "i nothere.mgf\n", "s.mgf", 6, "'nothere.mgf' not found"),
    "include loop": (LAMP + "i s.mgf\n", "s.mgf", 6, "include loop"),
    "unbalanced xf": (LAMP + "xf -t 1 0 0\n", "s.mgf", 6, "no matching end"),
    "stray xf end": (LAMP + "xf\n", "s.mgf", 6, "without a matching xf"),
    "bad transform": (LAMP + "xf -q 1\nxf\n", "s.mgf", 6, "unknown transform argument"),
    "undefined material": ("m nope\n", "s.mgf", 1, "material 'nope' is not defined"),
    "spectral colour": ("c\n\tcspec 400 700 1 1\n", "s.mgf", 2, "only CIE xy"),
    "ring without normal": (LAMP + "v a =\nring a 0 1\n", "s.mgf", 7, "has no normal"),
    "bad sides": ("m x =\n\tsides 3\n", "s.mgf", 2, "sides must be 1 or 2"),
    "cone radii": (LAMP + "v a =\nv b =\n\tp 0 0 1\ncone a 1 b -1\n", "s.mgf", 9,
                   "opposite signs"),
    "error in include": (LAMP + "i sub.mgf\n", "sub.mgf", 2, "vertex 'zz' is not defined"),
    "no geometry": (LAMP, "s.mgf", None, "no faces"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_mgf_is_one_scene_error_with_file_and_line(tmp_path, case):
    text, where, line, fragment = BAD[case]
    write(tmp_path, "# a comment\nf zz zz zz\n", "sub.mgf")
    with pytest.raises(SceneError) as info:
        load_scene(write(tmp_path, text))
    assert info.value.path == str(tmp_path / where)
    if line is not None:
        assert info.value.message.startswith(f"line {line}: ")
    assert fragment in info.value.message


def test_unknown_entity_is_skipped_with_one_warning(tmp_path):
    text = LAMP + "fh a b c\n" + CUBE_VERTICES + CUBE_FACES + "/some/stray/line\n"
    with pytest.warns(UserWarning, match=r"line 6: unknown MGF entity 'fh' skipped and 1 more"):
        data = read_mgf(write(tmp_path, text))
    assert len(data.polygons) == 6


def test_cli_refuses_bad_mgf_in_one_line(tmp_path):
    path = write(tmp_path, LAMP + "v a =\n\tp 0 0\n")
    proc = subprocess.run([sys.executable, "-m", "daskrad", "info", str(path)], cwd=REPO,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr == f"daskrad: error: {path}: line 7: p needs 3 numbers, got 2\n"


# --------------------------------------------------------------------------- the shared scenes


@pytest.mark.skipif(not (SHARED / "mgf" / "cube.mgf").is_file(),
                    reason="the shared scenes are not beside the repository")
def test_renderpark_cube_matches_its_converted_obj():
    # the shared cube scene was converted from this file by another tool (README there):
    # the same polygons, area and materials (one-sided, as RenderPark runs it)
    with pytest.warns(UserWarning, match="rs .* of 7 materials ignored"):
        data = read_mgf(SHARED / "mgf" / "cube.mgf", one_sided=True)
    obj = load_scene(SHARED / "cube" / "cube.obj")
    assert len(data.polygons) == len(obj.polygons) == 66
    assert polygon_area(data.vertices, data.polygons).sum() == pytest.approx(
        polygon_area(obj.vertices, obj.polygons).sum(), rel=1e-12)
    mine = dict(zip(data.names, data.diffuse, strict=True))
    for name, kd in zip(obj.materials.names, obj.materials.diffuse, strict=True):
        np.testing.assert_allclose(mine[name], kd, atol=1e-6)  # the MTL has 6 decimals
    ke = dict(zip(data.names, data.emission, strict=True))["bovenlicht"]
    np.testing.assert_allclose(ke, obj.materials.emission[obj.materials.names.index(
        "bovenlicht")], rtol=1e-5)
