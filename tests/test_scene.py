"""Scene input (issue 2): OBJ/MTL, PLY, STL, glTF/GLB, the TOML sidecar, the bundled scenes."""

from __future__ import annotations

import json
import struct
import warnings

import numpy as np
import pytest
import trimesh

from daskrad import tolerances
from daskrad.scene import BOX_FACES, box_scene, load_scene, read_config, scene_from_arrays
from daskrad.scene.polygons import (
    convex_planar,
    faces_to_polygons,
    newell_normal,
    pair_coplanar,
    pair_triangles,
    polygon_area,
)
from tests.helpers import SCENES

# Coordinates are written in the files with at most 4 significant digits and areas are sums of
# a few products of them, so areas agree to round-off of float64 (relative ~1e-15); 1e-9 is
# the project's area tolerance (tolerances.AREA_SUM_RTOL).
RTOL = tolerances.AREA_SUM_RTOL


def normals(scene):
    """Unnormalized polygon normals ``(v1 - v0) × (v2 - v0)``, the contract of Scene.polygons."""
    v, p = scene.vertices, scene.polygons
    return np.cross(v[p[:, 1]] - v[p[:, 0]], v[p[:, 2]] - v[p[:, 0]])


def centroids(scene):
    v, p = scene.vertices, scene.polygons
    corners = v[np.where(p >= 0, p, p[:, :1])]
    n = np.where(p[:, 3] >= 0, 4, 3)
    corners[p[:, 3] < 0, 3] = 0.0
    return corners.sum(axis=1) / n[:, None]


def write(path, text):
    path.write_text(text)
    return path


# --------------------------------------------------------------------------- the Cornell box


@pytest.fixture(scope="module")
def cornell():
    return load_scene(SCENES / "cornell_box.obj")


def test_cornell_counts_and_materials(cornell):
    # floor 1 + ceiling 8 around the hole + light 1 + back 1 + green 1 + red 2 triangles
    # + two blocks of top and 4 sides
    assert len(cornell.polygons) == 24
    assert int((cornell.polygons[:, 3] < 0).sum()) == 2
    assert cornell.dropped_degenerate == 0
    m = cornell.materials
    assert set(m.names) == {"white", "red", "green", "light"}
    row = {name: i for i, name in enumerate(m.names)}
    np.testing.assert_array_equal(m.diffuse[row["white"]], [0.73, 0.73, 0.73])
    np.testing.assert_array_equal(m.diffuse[row["red"]], [0.63, 0.065, 0.05])
    np.testing.assert_array_equal(m.diffuse[row["green"]], [0.14, 0.45, 0.091])
    np.testing.assert_array_equal(m.diffuse[row["light"]], [0, 0, 0])
    np.testing.assert_array_equal(m.emission[row["light"]], [17, 12, 4])
    assert (m.emission[[row["white"], row["red"], row["green"]]] == 0).all()
    # the MTL has no Ks: no specular part (trimesh alone would report 0.4)
    assert (m.specular == 0).all()
    assert not m.mirror.any()
    counts = np.bincount(cornell.polygon_material, minlength=len(m))
    assert counts[row["white"]] == 1 + 8 + 1 + 10
    assert counts[row["red"]] == 2 and counts[row["green"]] == 1 and counts[row["light"]] == 1


def test_cornell_light_faces_down_with_exact_area(cornell):
    light = np.flatnonzero(cornell.emitting)
    assert len(light) == 1
    n = normals(cornell)[light[0]]
    np.testing.assert_allclose(n / np.linalg.norm(n), [0, -1, 0], atol=1e-15)
    area = polygon_area(cornell.vertices, cornell.polygons)
    np.testing.assert_allclose(area[light[0]], 130.0 * 105.0, rtol=RTOL)
    # the ceiling pieces tile the 556 x 559.2 ceiling except the light's rectangle
    white = cornell.materials.names.index("white")
    y = centroids(cornell)[:, 1]
    ceiling = (cornell.polygon_material == white) & np.isclose(y, 548.8)
    assert ceiling.sum() == 8
    np.testing.assert_allclose(area[ceiling].sum(), 556 * 559.2 - 130 * 105, rtol=RTOL)


def test_cornell_camera(cornell):
    cam = cornell.camera
    np.testing.assert_array_equal(cam.eye, [278, 273, -800])
    np.testing.assert_array_equal(cam.look_at, [278, 273, 0])
    np.testing.assert_array_equal(cam.up, [0, 1, 0])
    # 2 atan(12.5/35) = 39.30765 degrees; the file gives it to 4 decimals
    assert cam.fov == pytest.approx(np.degrees(2 * np.arctan(12.5 / 35)), abs=1e-4)
    assert (cam.width, cam.height) == (256, 256)
    assert len(cornell.point_lights) == 0 and len(cornell.directional_lights) == 0


def _block_vertex_ids(scene, top):
    top = np.asarray(top, float)
    ring = np.concatenate([top, top * [1, 0, 1]])
    d = np.linalg.norm(scene.vertices[:, None, :] - ring[None], axis=2)
    return np.flatnonzero(d.min(axis=1) == 0), ring.mean(axis=0)


def test_cornell_every_face_points_to_its_lit_side(cornell):
    """Walls, floor, ceiling and light face the room's centre; block faces face away from it."""
    n = normals(cornell)
    c = centroids(cornell)
    short_top = [(130, 165, 65), (82, 165, 225), (240, 165, 272), (290, 165, 114)]
    tall_top = [(423, 330, 247), (265, 330, 296), (314, 330, 456), (472, 330, 406)]
    in_block = np.zeros(len(n), bool)
    for top in (short_top, tall_top):
        ids, centre = _block_vertex_ids(cornell, top)
        mine = np.isin(cornell.polygons, np.r_[ids, -1]).all(axis=1)
        assert mine.sum() == 5  # top and four sides, no bottom
        out = np.einsum("ij,ij->i", n[mine], c[mine] - centre)
        assert (out > 0).all()
        in_block |= mine
    room_centre = np.array([278.0, 274.4, 279.6])
    walls = ~in_block
    assert walls.sum() == 14
    towards = np.einsum("ij,ij->i", n[walls], room_centre - c[walls])
    assert (towards > 0).all()
    # and each wall's normal is (nearly) the axis it faces: the box is almost a cube
    unit = n[walls] / np.linalg.norm(n[walls], axis=1, keepdims=True)
    assert (np.abs(unit).max(axis=1) > 0.99).all()


def test_cornell_quads_planar_convex_and_red_wall_split(cornell):
    quads = cornell.polygons[cornell.polygons[:, 3] >= 0]
    assert convex_planar(cornell.vertices, quads, cornell.diagonal).all()
    red = cornell.materials.names.index("red")
    tris = cornell.polygons[cornell.polygon_material == red]
    assert (tris[:, 3] == -1).all() and len(tris) == 2


def test_cornell_areas_match_trimesh(cornell):
    """The direct OBJ parser and trimesh.load_scene agree on every material's total area."""
    ts = trimesh.load_scene(SCENES / "cornell_box.obj", process=False)
    area = polygon_area(cornell.vertices, cornell.polygons)
    for node in ts.graph.nodes_geometry:
        _, name = ts.graph[node]
        geom = ts.geometry[name]
        row = cornell.materials.names.index(geom.visual.material.name)
        np.testing.assert_allclose(
            area[cornell.polygon_material == row].sum(), geom.area, rtol=RTOL
        )


def test_furnace_box():
    s = load_scene(SCENES / "furnace_box.obj")
    assert len(s.polygons) == 6 and (s.polygons[:, 3] >= 0).all()
    np.testing.assert_array_equal(s.materials.emission, [[1, 1, 1]])
    np.testing.assert_array_equal(s.materials.diffuse, [[0.5, 0.5, 0.5]])
    inward = np.einsum("ij,ij->i", normals(s), 0.5 - centroids(s))
    assert (inward > 0).all()
    np.testing.assert_allclose(polygon_area(s.vertices, s.polygons), 1.0, rtol=RTOL)
    assert s.camera is None


# --------------------------------------------------------------------------- OBJ and MTL details


def test_mtl_specular_rules(tmp_path):
    write(tmp_path / "m.mtl", """
newmtl plain
Kd 0.5 0.5 0.5
Ke 2 2 2
newmtl shiny
Kd 0.3
Ks 0.2 0.3 0.4
Ns 50
illum 2
newmtl matte_ks
Kd 0.3 0.3 0.3
Ks 0.5 0.5 0.5
illum 1
newmtl off
Ks 0.5 0.5 0.5
illum 0
newmtl mirror
Kd 0 0 0
Ks 0.9 0.9 0.9
illum 3
""")
    names = ("plain", "shiny", "matte_ks", "off", "mirror")
    faces = "\n".join(f"usemtl {m}\nf 1 2 3" for m in names)
    obj = write(tmp_path / "m.obj", f"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n{faces}\n")
    s = load_scene(obj)
    m = s.materials
    row = {name: i for i, name in enumerate(m.names)}
    np.testing.assert_array_equal(m.specular[row["plain"]], 0)
    np.testing.assert_array_equal(m.specular[row["shiny"]], [0.2, 0.3, 0.4])
    assert m.shininess[row["shiny"]] == 50
    np.testing.assert_array_equal(m.diffuse[row["shiny"]], [0.3, 0.3, 0.3])  # "Kd r" is grey
    np.testing.assert_array_equal(m.specular[row["matte_ks"]], 0)
    np.testing.assert_array_equal(m.specular[row["off"]], 0)
    np.testing.assert_array_equal(m.diffuse[row["off"]], [0.73, 0.73, 0.73])  # no Kd: default
    assert m.mirror.tolist() == [name == "mirror" for name in m.names]
    np.testing.assert_array_equal(m.emission[row["plain"]], [2, 2, 2])


def test_obj_negative_indices_default_material_and_ngon(tmp_path):
    # an L-shaped hexagon (concave, area 3) given with relative indices, no material, then a
    # square given after more vertices with relative indices, counted from the last vertex read
    obj = write(tmp_path / "l.obj", """
v 0 0 0
v 2 0 0
v 2 1 0
v 1 1 0
v 1 2 0
v 0 2 0
f -6 -5 -4 -3 -2 -1
v 5 0 0
v 6 0 0
v 6 1 0
v 5 1 0
f -4 -3 -2 -1
""")
    cfg = write(tmp_path / "l.toml", '[[light]]\ntype = "point"\nposition = [0, 0, 1]\n'
                'intensity = [1, 1, 1]\n')
    s = load_scene(obj)
    assert s.materials.names == ("default",)
    np.testing.assert_array_equal(s.materials.diffuse, [[0.73, 0.73, 0.73]])
    area = polygon_area(s.vertices, s.polygons)
    tri = s.polygons[:, 3] < 0
    assert tri.sum() == 4  # hexagon → 4 triangles
    np.testing.assert_allclose(area[tri].sum(), 3.0, rtol=RTOL)
    assert (~tri).sum() == 1  # the square stays a quad
    np.testing.assert_array_equal(s.polygons[~tri][0], [6, 7, 8, 9])
    # every piece keeps the file's winding: normal +z
    assert (normals(s)[:, 2] > 0).all()
    np.testing.assert_allclose(normals(s)[:, :2], 0.0, atol=0)
    assert len(s.point_lights) == 1 and cfg.exists()


def test_nonplanar_and_concave_quads_are_split(rng):
    # a dart (concave quad): reflex corner at index 3, so the split must use diagonal 1-3
    v = np.array([[0, 0, 0], [2, 1, 0], [0, 2, 0], [0.5, 1, 0], [0, 0, 0], [1, 0, 0],
                  [1, 1, 0.3], [0, 1, 0]], float)
    flat = np.arange(8)
    polys, face = faces_to_polygons(v, flat, np.array([4, 4]), diag=3.0)
    assert (polys[:, 3] == -1).all() and face.tolist() == [0, 0, 1, 1]
    area = polygon_area(v, polys)
    # the dart's area by the shoelace formula: 1.5 (it is the triangle (0,0)(2,1)(0,2) = 2
    # minus the notch (0,0)(0.5,1)(0,2) = 0.5)
    np.testing.assert_allclose(area[:2].sum(), 1.5, rtol=RTOL)
    n = np.cross(v[polys[:, 1]] - v[polys[:, 0]], v[polys[:, 2]] - v[polys[:, 0]])
    assert (n[:, 2] > 0).all()


def test_convex_ngons_fan_to_their_area(rng):
    # random convex polygons: points on a circle in a random plane; fan (n <= 8) or ear-strip
    # (n > 8) area = Newell area, every triangle wound like the face (no fold)
    for n in (5, 6, 9, 12, 33, 1000):
        ang = np.sort(rng.uniform(0, 2 * np.pi, n))
        basis = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        circle = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(n)])
        pts = circle @ basis.T + rng.normal(size=3)
        polys, _ = faces_to_polygons(pts, np.arange(n), np.array([n]), diag=2.0)
        assert len(polys) == n - 2
        normal = newell_normal(pts, np.arange(n)[None])[0]
        expect = np.linalg.norm(normal)
        np.testing.assert_allclose(polygon_area(pts, polys).sum(), expect, rtol=1e-12)
        p = pts[polys[:, :3]]
        assert (np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]) @ normal > 0).all()


def test_big_convex_polygon_is_cut_into_ear_strips_not_a_fan():
    # a fan of a 1000-gon is 998 triangles as long as the disc (each meshed into as many
    # elements as a big triangle: issue 13); ear strips keep all but a few short: at most
    # 2·log2(n) triangles reach half the diameter, and each corner is in O(log n) triangles
    n = 1000
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(n)])
    polys, face = faces_to_polygons(pts, np.arange(n), np.array([n]), diag=2.0)
    assert len(polys) == n - 2 and (face == 0).all() and (polys[:, 3] == -1).all()
    p = pts[polys[:, :3]]
    longest = np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2).max(axis=1)
    assert (longest > 1.0).sum() <= 2 * np.log2(n)
    assert np.bincount(polys[:, :3].ravel()).max() <= 2 * np.log2(n) + 2


def test_pair_triangles_recovers_quads():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0.5]], float)
    # quad 0123 split as trimesh does, then a non-planar pair 1 4 5 2 (must stay triangles)
    tris = np.array([[0, 1, 2], [2, 3, 0], [1, 4, 5], [1, 5, 2]])
    out = pair_triangles(v, tris, diag=3.0)
    np.testing.assert_array_equal(out, [[0, 1, 2, 3], [1, 4, 5, -1], [1, 5, 2, -1]])
    # three consecutive mergeable triangles: only the first pair merges
    tris = np.array([[0, 1, 2], [0, 2, 3], [0, 2, 3]])
    out = pair_triangles(v, tris, diag=3.0)
    assert len(out) == 2 and (out[0] == [0, 1, 2, 3]).all()


def test_degenerate_faces_dropped_with_warning(tmp_path):
    obj = write(tmp_path / "d.obj", """mtllib d.mtl
usemtl lamp
v 0 0 0
v 1 0 0
v 0 1 0
v 2 0 0
f 1 2 3
f 1 2 4
""")
    write(tmp_path / "d.mtl", "newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\n")
    with pytest.warns(UserWarning, match="1 zero-area"):
        s = load_scene(obj)
    assert s.dropped_degenerate == 1 and len(s.polygons) == 1


# --------------------------------------------------------------------------- other formats


LIGHT_TOML = '[[light]]\ntype = "point"\nposition = [0.5, 0.5, 0.5]\nintensity = [1, 1, 1]\n'


def _box_mesh():
    """A unit box with inward normals, its quads split the way trimesh splits them."""
    b = box_scene(emission_per_face=1.0)
    q = b.polygons
    tris = np.stack([q[:, [0, 1, 2]], q[:, [2, 3, 0]]], axis=1).reshape(-1, 3)
    return trimesh.Trimesh(b.vertices, tris, process=False)


@pytest.mark.parametrize("suffix", ["ply", "stl"])
def test_ply_stl_round_trip(tmp_path, suffix):
    mesh = _box_mesh()
    path = tmp_path / f"box.{suffix}"
    mesh.export(path)
    write(tmp_path / "box.toml", LIGHT_TOML)
    s = load_scene(path)
    # quads are recovered, normals still point inward, total area 6
    assert len(s.polygons) == 6 and (s.polygons[:, 3] >= 0).all()
    assert (np.einsum("ij,ij->i", normals(s), 0.5 - centroids(s)) > 0).all()
    np.testing.assert_allclose(polygon_area(s.vertices, s.polygons).sum(), 6.0, rtol=RTOL)
    np.testing.assert_array_equal(s.materials.diffuse, [[0.73, 0.73, 0.73]])
    np.testing.assert_array_equal(s.materials.emission, [[0, 0, 0]])
    assert len(s.point_lights) == 1


def _glow_scene():
    from trimesh.visual.material import PBRMaterial

    mesh = _box_mesh()
    mesh.visual = trimesh.visual.TextureVisuals(
        material=PBRMaterial(name="glow", baseColorFactor=[0.5, 0.25, 0.1, 1.0],
                             emissiveFactor=[1.0, 0.5, 0.25])
    )
    other = trimesh.Trimesh(mesh.vertices + [3, 0, 0], mesh.faces, process=False)
    return trimesh.Scene([mesh, other])


def _patch_glb(data: bytes, edit) -> bytes:
    """Rewrite the JSON chunk of a GLB (trimesh writes baseColorFactor rounded to 8 bits)."""
    length, _ = struct.unpack("<II", data[12:20])
    doc = json.loads(data[20 : 20 + length])
    edit(doc)
    text = json.dumps(doc).encode()
    text += b" " * (-len(text) % 4)  # chunks are 4-byte aligned, JSON padded with spaces
    rest = data[20 + length :]
    body = struct.pack("<II", len(text), 0x4E4F534A) + text + rest
    return data[:8] + struct.pack("<I", 12 + len(body)) + body


def test_glb_round_trip(tmp_path):
    def exact(doc):
        doc["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = [0.5, 0.25, 0.1, 1.0]

    path = tmp_path / "glow.glb"
    path.write_bytes(_patch_glb(_glow_scene().export(file_type="glb"), exact))
    s = load_scene(path)
    row = {name: i for i, name in enumerate(s.materials.names)}
    # the file's exact JSON values, not trimesh's 8-bit 128/255
    np.testing.assert_array_equal(s.materials.diffuse[row["glow"]], [0.5, 0.25, 0.1])
    np.testing.assert_array_equal(s.materials.emission[row["glow"]], [1.0, 0.5, 0.25])
    np.testing.assert_array_equal(s.materials.diffuse[row["default"]], [0.73] * 3)
    assert len(s.polygons) == 12 and (s.polygons[:, 3] >= 0).all()
    np.testing.assert_allclose(polygon_area(s.vertices, s.polygons).sum(), 12.0, rtol=RTOL)
    # the translated copy sits at x in [3, 4]
    lo, hi = s.bounds
    np.testing.assert_allclose([lo[0], hi[0]], [0.0, 4.0])


def test_gltf_emissive_strength(tmp_path):
    files = _glow_scene().export(file_type="gltf")
    name = next(k for k in files if k.endswith(".gltf"))
    doc = json.loads(files[name])
    doc["materials"][0]["extensions"] = {"KHR_materials_emissive_strength":
                                         {"emissiveStrength": 40.0}}
    doc.setdefault("extensionsUsed", []).append("KHR_materials_emissive_strength")
    files[name] = json.dumps(doc).encode()
    for k, data in files.items():
        (tmp_path / k).write_bytes(data)
    s = load_scene(tmp_path / name)
    row = s.materials.names.index("glow")
    np.testing.assert_array_equal(s.materials.emission[row], [40.0, 20.0, 10.0])


def test_mirrored_node_keeps_lit_side(tmp_path):
    # a reflection in a node's transform reverses the winding; the loader reverses it back
    mesh = _box_mesh()
    scene = trimesh.Scene()
    scene.add_geometry(mesh, transform=np.diag([-1.0, 1.0, 1.0, 1.0]))
    path = tmp_path / "mirror.glb"
    path.write_bytes(scene.export(file_type="glb"))
    write(tmp_path / "mirror.toml", LIGHT_TOML)
    s = load_scene(path)
    centre = s.bounds.mean(axis=0)
    assert (np.einsum("ij,ij->i", normals(s), centre - centroids(s)) > 0).all()


# --------------------------------------------------------------------------- TOML


def test_toml_lights_and_camera(tmp_path):
    cfg = write(tmp_path / "c.toml", """
[camera]
eye = [0, 1, 5]
look_at = [0, 1, 0]
fov = 60

[[light]]
type = "point"
position = [1.0, 2.0, 3.0]
intensity = [10, 20, 30]

[[light]]
type = "directional"
direction = [0.0, -3.0, 4.0]
irradiance = [1, 1, 1]
""")
    c = read_config(cfg)
    np.testing.assert_array_equal(c.point_lights.position, [[1, 2, 3]])
    np.testing.assert_array_equal(c.point_lights.intensity, [[10, 20, 30]])
    np.testing.assert_allclose(c.directional_lights.direction, [[0, -0.6, 0.8]], rtol=1e-15)
    np.testing.assert_array_equal(c.camera.up, [0, 1, 0])  # default
    assert (c.camera.width, c.camera.height, c.camera.fov) == (256, 256, 60.0)
    # config= overrides the sidecar, and lights alone light an emission-free scene
    write(tmp_path / "box.toml", "this is not toml [")
    mesh = _box_mesh()
    mesh.export(tmp_path / "box.ply")
    s = load_scene(tmp_path / "box.ply", config=cfg)
    assert len(s.point_lights) == 1 and len(s.directional_lights) == 1
    assert s.camera.fov == 60.0


# --------------------------------------------------------------------------- arrays and builders


def test_box_scene_inward_and_outward():
    for inward in (True, False):
        s = box_scene(size=(2, 3, 4), emission_per_face=1, inward=inward, subdivisions=3)
        assert len(s.polygons) == 6 * 9 and (s.polygons[:, 3] >= 0).all()
        into = np.einsum("ij,ij->i", normals(s), [1, 1.5, 2] - centroids(s))
        assert ((into > 0) == inward).all()
        area = polygon_area(s.vertices, s.polygons)
        np.testing.assert_allclose(area.sum(), 2 * (6 + 8 + 12), rtol=RTOL)
        face_area = np.bincount(s.polygon_material, weights=area)
        np.testing.assert_allclose(face_area, [12, 12, 8, 8, 6, 6], rtol=RTOL)
    s = box_scene(emission_per_face=[0, 0, 0, 1, 0, 0])
    assert s.materials.names == BOX_FACES
    ceiling = np.flatnonzero(s.emitting)
    assert ceiling.tolist() == [3]
    np.testing.assert_allclose(normals(s)[3], [0, -1, 0])


def test_scene_from_arrays_splits_bad_quads_and_accepts_triangles():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0.2], [0, 1, 0], [0, 0, 1]], float)
    s = scene_from_arrays(v, [[0, 1, 2, 3], [0, 1, 4, -1]], [0, 1], [[0.5] * 3, [0.2] * 3],
                          [[1, 1, 1], [0, 0, 0]])
    assert len(s.polygons) == 3 and (s.polygons[:, 3] == -1).all()
    assert s.polygon_material.tolist() == [0, 0, 1]
    t = scene_from_arrays(v, [[0, 1, 4]], [0], [[0.5] * 3], [[1, 1, 1]])
    np.testing.assert_array_equal(t.polygons, [[0, 1, 4, -1]])
    assert t.polygons.dtype == np.int32 and t.polygon_material.dtype == np.int32
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no degenerate face here: no warning
        scene_from_arrays(v, [[0, 1, 4]], [0], [[0.5] * 3], [[1, 1, 1]])


def test_big_concave_polygon_is_ear_clipped_all_around():
    # a star of 400 corners (radii 1 and 0.9): n - 2 triangles wound like the face, tiling its
    # exact area; ears are cut all around in turn, so few triangles span the star (cutting
    # them at one place left a fan of slivers: 100,524 elements for 1000 corners, now 3,570)
    n = 400
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    r = np.where(np.arange(n) % 2, 0.9, 1.0)
    pts = np.column_stack([r * np.cos(ang), r * np.sin(ang), np.zeros(n)])
    polys, _ = faces_to_polygons(pts, np.arange(n), np.array([n]), diag=2.0)
    assert len(polys) == n - 2
    p = pts[polys[:, :3]]
    z = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2]
    assert (z > 0).all()
    exact = 0.5 * np.sum(r * np.roll(r, -1)) * np.sin(2 * np.pi / n)
    np.testing.assert_allclose(0.5 * z.sum(), exact, rtol=1e-12)
    longest = np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2).max(axis=1)
    assert (longest > 1.0).sum() <= 4 * np.log2(n)


# --------------------------------------------------------------------------- triangle soups


def _split_grid_soup(rng, n=4):
    """The six faces of the unit cube as n × n quads, each split along a random diagonal
    (either of its two), all triangles in a random order: ``(vertices, triangles)``."""
    verts, tris = [], []
    t = np.linspace(0.0, 1.0, n + 1)
    for axis in range(3):
        for high in (0, 1):
            u_ax, v_ax = (axis + 1) % 3, (axis + 2) % 3
            base = len(verts)
            for i in range(n + 1):
                for j in range(n + 1):
                    p = np.zeros(3)
                    p[u_ax], p[v_ax], p[axis] = t[i], t[j], high
                    verts.append(p)
            for i in range(n):
                for j in range(n):
                    q = [base + i * (n + 1) + j, base + (i + 1) * (n + 1) + j,
                         base + (i + 1) * (n + 1) + j + 1, base + i * (n + 1) + j + 1]
                    if not high:
                        q = q[::-1]  # outward at the min faces too
                    r = int(rng.integers(4))
                    q = q[r:] + q[:r]
                    tris += [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]
    tris = np.array(tris)
    return np.array(verts), tris[rng.permutation(len(tris))]


@pytest.mark.parametrize("suffix", [".ply", ".stl"])
def test_triangle_soup_pairs_back_into_quads_whatever_the_order(tmp_path, suffix):
    # issue 16 item 6: pairing only neighbours in the file found few quads in a shuffled soup;
    # every split square of the cube comes back as one quad, wound as its triangles
    verts, tris = _split_grid_soup(np.random.default_rng(7))
    trimesh.Trimesh(verts, tris, process=False).export(tmp_path / f"box{suffix}")
    write(tmp_path / "box.toml",
          '[[light]]\ntype = "point"\nposition = [0.5, 0.5, 0.5]\nintensity = [1, 1, 1]\n')
    scene = load_scene(tmp_path / f"box{suffix}")
    assert len(scene.polygons) == len(tris) // 2 == 96
    assert (scene.polygons[:, 3] >= 0).all()
    assert polygon_area(scene.vertices, scene.polygons).sum() == pytest.approx(6.0, rel=RTOL)
    # outward, as the triangles were
    n = normals(scene)
    assert (np.einsum("ij,ij->i", n, centroids(scene) - 0.5) > 0).all()
    # what neighbour pairing alone recovers from the same order (the old behaviour)
    alone = pair_triangles(scene.vertices if suffix == ".ply" else verts, tris, 1.7)
    assert (alone[:, 3] >= 0).sum() < 96


def test_pair_coplanar_leaves_bent_and_concave_pairs():
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.5],   # bent along 0-2
                  [3, 0, 0], [4, 0, 0], [3.2, 0.2, 0], [3, 1, 0]], float)  # concave union
    polys = np.array([[0, 1, 2, -1], [0, 2, 3, -1], [4, 5, 6, -1], [4, 6, 7, -1]])
    out, keep = pair_coplanar(v, polys, np.zeros(4, int), 5.0)
    assert keep.all() and (out[:, 3] < 0).all()
    # different materials are not merged either
    flat = v.copy()
    flat[3, 2] = 0.0
    out, keep = pair_coplanar(flat, polys[:2], np.array([0, 1]), 2.0)
    assert keep.all()
    out, keep = pair_coplanar(flat, polys[:2], np.array([0, 0]), 2.0)
    assert keep.tolist() == [True, False]
    assert out[0].tolist() in ([0, 1, 2, 3], [1, 2, 3, 0], [2, 3, 0, 1], [3, 0, 1, 2])
