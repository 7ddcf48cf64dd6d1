"""The polygon → patch → element hierarchy (issue 2, item 4; docs/design.md §1 step 1, §3).

Scenes are built directly with the ``Scene`` constructor. Expected counts, areas, normals and
centroids are recomputed here from the input geometry, independently of ``daskrad.mesh``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from daskrad.errors import OptionError, SceneError
from daskrad.mesh import (
    build_hierarchy,
    default_sizes,
    element_vertex_adjacency,
    hierarchy_triangles,
    vertex_average,
    vertex_polygon,
)
from daskrad.mesh.contacts import cut_at_contacts
from daskrad.scene.types import Materials, Scene
from daskrad.tolerances import AREA_SUM_RTOL

# Lengths are compared with a relative slack of 1e-12: a computed edge is a difference of
# interpolated coordinates, exact to a few ulps of the coordinates' magnitude (≤ 1e-15
# relative), so 1e-12 absorbs round-off but not one subdivision too few (≥ 1/K ≫ 1e-12).
LEN_RTOL = 1e-12
# Unit normals from cross products of differences agree to a few ulps of 1 times the condition
# of the difference (elements are ≥ 1e-3 of the polygon here): 1e-9 is generous and still far
# below any real error (a flipped or tilted element is off by O(1)).
NORMAL_ATOL = 1e-9


def materials(n: int = 1) -> Materials:
    return Materials(
        names=tuple(f"m{i}" for i in range(n)),
        diffuse=np.full((n, 3), 0.5),
        emission=np.zeros((n, 3)),
        specular=np.zeros((n, 3)),
        shininess=np.zeros(n),
        mirror=np.zeros(n, bool),
    )


def make_scene(vertices, polygons, n_materials: int = 2) -> Scene:
    polygons = np.asarray(polygons, np.int32)
    return Scene(
        path="test",
        vertices=np.asarray(vertices, np.float64),
        polygons=polygons,
        polygon_material=(np.arange(len(polygons)) % n_materials).astype(np.int32),
        materials=materials(n_materials),
    )


def random_frame(rng):
    """An orthonormal (3, 3) basis (rows), random orientation."""
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q.T


def random_convex_quads(rng, n, scale, skew):
    """``n`` planar convex quads in random planes, counter-clockwise seen from ``+normal``.

    Points on an ellipse at sorted angles are in convex position; an affine map of the plane
    (``skew``) keeps convexity and planarity.
    """
    verts = []
    for _ in range(n):
        ang = np.sort(rng.uniform(0, 2 * np.pi, 4))
        # keep corners apart so no edge is degenerate
        ang = ang[0] + np.linspace(0, 2 * np.pi, 5)[:4] * 0.5 + (ang - ang[0]) * 0.5
        xy = np.stack([np.cos(ang), np.sin(ang)], axis=1) * rng.uniform(0.5, 2.0, 2)
        if skew:
            m = np.array([[1.0, rng.uniform(-1.5, 1.5)], [0.0, rng.uniform(0.3, 1.0)]])
            xy = xy @ m.T
        frame = random_frame(rng)
        origin = rng.uniform(-3, 3, 3)
        verts.append((origin + xy[:, :1] * frame[0] + xy[:, 1:] * frame[1]) * scale)
    v = np.concatenate(verts)
    return v, np.arange(4 * n).reshape(n, 4)


def random_triangles(rng, n, scale):
    verts = []
    while len(verts) < n:
        t = rng.uniform(-2, 2, (3, 3))
        e = np.linalg.norm(np.roll(t, -1, axis=0) - t, axis=1)
        area = 0.5 * np.linalg.norm(np.cross(t[1] - t[0], t[2] - t[0]))
        if area > 0.05 * e.max() ** 2:  # not a sliver, so no edge is tiny
            verts.append(t * scale)
    v = np.concatenate(verts)
    polys = np.full((n, 4), -1)
    polys[:, :3] = np.arange(3 * n).reshape(n, 3)
    return v, polys


def rectangles(scale):
    """Axis-aligned rectangles and one square, wound to face +z, -y and +x."""
    v = np.array([
        [0, 0, 0], [3, 0, 0], [3, 2, 0], [0, 2, 0],
        [0, 0, 0], [0, 0, 1], [1.7, 0, 1], [1.7, 0, 0],
        [5, 0, 0], [5, 1, 0], [5, 1, 1], [5, 0, 1],
    ], float) * scale
    return v, np.arange(12).reshape(3, 4)


def case(kind, rng, scale):
    if kind == "rectangles":
        v, p = rectangles(scale)
    elif kind == "convex_quads":
        v, p = random_convex_quads(rng, 6, scale, skew=False)
    elif kind == "skewed_quads":
        v, p = random_convex_quads(rng, 6, scale, skew=True)
    elif kind == "triangles":
        v, p = random_triangles(rng, 6, scale)
    else:  # mixed
        v1, p1 = random_convex_quads(rng, 4, scale, skew=True)
        v2, p2 = random_triangles(rng, 4, scale)
        p2 = np.where(p2 >= 0, p2 + len(v1), -1)
        v, p = np.concatenate([v1, v2]), np.concatenate([p1, p2])
    return make_scene(v, p)


# ---------------------------------------------------------------------------------------------
# Independent expectations


def expected_counts(scene, ps, es):
    """Patches and elements per polygon, from edge lengths alone."""
    patches, elems = [], []
    for poly in scene.polygons:
        c = scene.vertices[poly[poly >= 0]]
        e = [math.dist(c[i], c[(i + 1) % len(c)]) for i in range(len(c))]
        if len(c) == 4:
            lu, lv = max(e[0], e[2]), max(e[1], e[3])
            nu, nv = max(math.ceil(lu / ps), 1), max(math.ceil(lv / ps), 1)
            eu = max(math.ceil(lu / nu / es), 1)
            ev = max(math.ceil(lv / nv / es), 1)
            patches.append(nu * nv)
            elems.append(nu * eu * nv * ev)
        else:
            kp = max(math.ceil(max(e) / ps), 1)
            ke = max(math.ceil(max(e) / kp / es), 1)
            patches.append(kp * kp)
            elems.append((kp * ke) ** 2)
    return np.array(patches), np.array(elems)


def poly_geometry(corners):
    """Area, unit normal and centroid of a planar polygon by a triangle fan (no Newell)."""
    area2 = np.zeros(3)
    moment = np.zeros(3)
    for i in range(1, len(corners) - 1):
        cr = np.cross(corners[i] - corners[0], corners[i + 1] - corners[0])
        area2 += cr
        moment += np.linalg.norm(cr) * (corners[0] + corners[i] + corners[i + 1]) / 3
    a = np.linalg.norm(area2)
    return a / 2, area2 / a, moment / a


def shape_area(vertices, rows):
    """(n,) areas of quads/triangles (rows (n,4), -1 col 3) as |d1 × d2| / 2 resp. |ab × ac|/2."""
    a, b, c = (vertices[rows[:, i]] for i in range(3))
    d = vertices[np.where(rows[:, 3] >= 0, rows[:, 3], rows[:, 0])]
    quad = np.linalg.norm(np.cross(c - a, d - b), axis=1) / 2
    tri = np.linalg.norm(np.cross(b - a, c - a), axis=1) / 2
    return np.where(rows[:, 3] >= 0, quad, tri)


def edges_of(rows):
    """Directed edges (n, 2) of quads/triangles and their owner row."""
    is_quad = rows[:, 3] >= 0
    quad = rows[is_quad]
    tri = rows[~is_quad]
    qe = np.stack([quad, np.roll(quad, -1, axis=1)], axis=2).reshape(-1, 2)
    te = np.stack([tri[:, :3], np.roll(tri[:, :3], -1, axis=1)], axis=2).reshape(-1, 2)
    owner = np.concatenate([np.repeat(np.flatnonzero(is_quad), 4),
                            np.repeat(np.flatnonzero(~is_quad), 3)])
    return np.concatenate([qe, te]), owner


def check_invariants(scene, h, ps, es):
    diag = scene.diagonal
    nq = len(scene.polygons)
    exp_p, exp_e = expected_counts(scene, ps, es)

    # counts, ordering, dtypes and shapes
    assert np.array_equal(np.bincount(h.patch_polygon, minlength=nq), exp_p)
    assert np.array_equal(np.bincount(h.elem_polygon, minlength=nq), exp_e)
    assert h.elem_verts.dtype == np.int32 and h.elem_verts.shape == (h.n_elements, 4)
    assert h.patch_verts.dtype == np.int32 and h.patch_verts.shape == (h.n_patches, 4)
    assert h.elem_patch.dtype == np.int32 and h.patch_polygon.dtype == np.int32
    assert np.all(np.diff(h.elem_patch) >= 0) and np.all(np.diff(h.patch_polygon) >= 0)
    assert np.array_equal(h.polygon_material, scene.polygon_material)
    poly_is_quad = scene.polygons[:, 3] >= 0
    assert np.array_equal(h.elem_verts[:, 3] >= 0, poly_is_quad[h.elem_polygon])
    assert np.array_equal(h.patch_verts[:, 3] >= 0, poly_is_quad[h.patch_polygon])

    # areas at every level
    geo = [poly_geometry(scene.vertices[p[p >= 0]]) for p in scene.polygons]
    poly_area = np.array([g[0] for g in geo])
    poly_normal = np.array([g[1] for g in geo])
    poly_centroid = np.array([g[2] for g in geo])
    elem_sum = np.bincount(h.elem_patch, weights=h.elem_area, minlength=h.n_patches)
    np.testing.assert_allclose(h.patch_area, elem_sum, rtol=AREA_SUM_RTOL)
    np.testing.assert_allclose(shape_area(h.vertices, h.patch_verts), elem_sum,
                               rtol=AREA_SUM_RTOL)
    np.testing.assert_allclose(shape_area(h.vertices, h.elem_verts), h.elem_area,
                               rtol=AREA_SUM_RTOL)
    patch_sum = np.bincount(h.patch_polygon, weights=h.patch_area, minlength=nq)
    np.testing.assert_allclose(patch_sum, poly_area, rtol=AREA_SUM_RTOL)
    assert np.all(h.elem_area > 0)

    # normals: the polygon's, identical across its elements, and each element winds the same
    np.testing.assert_allclose(h.elem_normal, poly_normal[h.elem_polygon], atol=NORMAL_ATOL)
    np.testing.assert_allclose(h.patch_normal, poly_normal[h.patch_polygon], atol=NORMAL_ATOL)
    first = h.elem_normal[np.searchsorted(h.elem_polygon, np.arange(nq))]
    assert np.array_equal(h.elem_normal, first[h.elem_polygon])
    assert np.array_equal(h.patch_normal, first[h.patch_polygon])
    np.testing.assert_allclose(np.linalg.norm(h.elem_normal, axis=1), 1.0, rtol=1e-15 * 8)
    tris, tri_verts, tri_elem = hierarchy_triangles(h)
    np.testing.assert_array_equal(tris, h.vertices[tri_verts])
    cr = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    np.testing.assert_allclose(cr / np.linalg.norm(cr, axis=1, keepdims=True),
                               h.elem_normal[tri_elem], atol=NORMAL_ATOL)

    # centroids: patches' area-weighted centroids average to the polygon's (triangle fan)
    w = h.patch_area[:, None] * h.patch_centroid
    cen = np.stack([np.bincount(h.patch_polygon, weights=w[:, d], minlength=nq)
                    for d in range(3)], axis=1) / patch_sum[:, None]
    np.testing.assert_allclose(cen, poly_centroid, atol=1e-9 * diag)
    we = h.elem_area[:, None] * h.elem_centroid
    pcen = np.stack([np.bincount(h.elem_patch, weights=we[:, d], minlength=h.n_patches)
                     for d in range(3)], axis=1) / elem_sum[:, None]
    np.testing.assert_allclose(pcen, h.patch_centroid, atol=1e-9 * diag)

    # edge lengths
    ed, _ = edges_of(h.elem_verts)
    elen = np.linalg.norm(h.vertices[ed[:, 0]] - h.vertices[ed[:, 1]], axis=1)
    assert elen.max() <= es * (1 + LEN_RTOL)
    pd, _ = edges_of(h.patch_verts)
    plen = np.linalg.norm(h.vertices[pd[:, 0]] - h.vertices[pd[:, 1]], axis=1)
    assert plen.max() <= ps * (1 + LEN_RTOL)

    # vertices: each in one polygon, every one used, none duplicated within a polygon
    vp = vertex_polygon(h)
    assert np.all(vp >= 0)  # every vertex used
    assert np.all(vp[h.elem_verts[:, :3]] == h.elem_polygon[:, None])
    quad = h.elem_verts[:, 3] >= 0
    assert np.all(vp[h.elem_verts[quad, 3]] == h.elem_polygon[quad])
    key = np.column_stack([vp, np.round(h.vertices / diag * 1e9)])
    assert len(np.unique(key, axis=0)) == len(h.vertices)
    # patch corners are corners of the patch's own elements
    for p in range(0, h.n_patches, max(1, h.n_patches // 20)):
        corners = h.patch_verts[p][h.patch_verts[p] >= 0]
        assert np.isin(corners, h.elem_verts[h.elem_patch == p]).all()

    # T-junction free: an edge is shared by exactly two elements, in opposite directions
    # (consistent winding), or lies on its polygon's boundary.
    key = np.sort(ed, axis=1)
    uniq, inv, count = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    assert count.max() <= 2
    assert len(np.unique(ed, axis=0)) == len(ed)  # no edge used twice in the same direction
    single = uniq[count == 1]
    poly = vp[single[:, 0]]
    on_boundary = np.zeros(len(single), bool)
    pv = scene.polygons[poly]
    for i in range(4):
        j = (i + 1) % 4
        a = scene.vertices[pv[:, i]]
        b = scene.vertices[np.where(pv[:, j] >= 0, pv[:, j], pv[:, 0])]
        valid = pv[:, i] >= 0
        ab = b - a
        ok = valid.copy()
        for end in (0, 1):
            x = h.vertices[single[:, end]] - a
            dist = np.linalg.norm(np.cross(ab, x), axis=1) / np.linalg.norm(ab, axis=1)
            t = np.einsum("ij,ij->i", x, ab) / np.einsum("ij,ij->i", ab, ab)
            ok &= (dist <= 1e-9 * diag) & (t >= -1e-9) & (t <= 1 + 1e-9)
        on_boundary |= ok
    assert on_boundary.all()

    # vertex_average of a constant field is that constant
    const = np.full((h.n_elements, 3), [0.25, 1.5, -7.0])
    want = np.broadcast_to(const[0], (len(h.vertices), 3))
    np.testing.assert_allclose(vertex_average(h, const), want, rtol=1e-14)


# ---------------------------------------------------------------------------------------------
# Tests


KINDS = ["rectangles", "convex_quads", "skewed_quads", "triangles", "mixed"]


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
@pytest.mark.parametrize("kind", KINDS)
def test_invariants(kind, scale, rng):
    scene = case(kind, rng, scale)
    # sizes chosen relative to the scene so every scale gives the same counts; patch size not a
    # multiple of element size, so patches are cut into uneven numbers of elements per axis
    ps, es = 0.9 * scale, 0.23 * scale
    h = build_hierarchy(scene, ps, es)
    assert h.n_patches > len(scene.polygons)  # something was actually subdivided
    assert h.n_elements > 4 * h.n_patches
    check_invariants(scene, h, ps, es)


@pytest.mark.parametrize("kind", KINDS)
def test_sizes_larger_than_polygons(kind, rng):
    """One patch and one element per polygon: the polygon itself, corners unchanged."""
    scene = case(kind, rng, 1.0)
    h = build_hierarchy(scene, 1e3, 1e3)
    assert h.n_patches == h.n_elements == len(scene.polygons)
    check_invariants(scene, h, 1e3, 1e3)
    tri = scene.polygons[:, 3] < 0
    ev = np.where(h.elem_verts >= 0, h.elem_verts, 0)
    assert np.array_equal(h.vertices[ev][~tri], scene.vertices[scene.polygons[~tri]])
    assert np.array_equal(h.vertices[ev][tri, :3], scene.vertices[scene.polygons[tri, :3]])


@settings(max_examples=30, deadline=None, derandomize=True)
# es ≥ 0.0625 on edges ≤ ~7 keeps every case below ~10⁵ elements (fast to check)
@given(ps=st.floats(0.25, 5.0), ratio=st.floats(0.25, 2.0), seed=st.integers(0, 2**16))
def test_invariants_random_sizes(ps, ratio, seed):
    rng = np.random.default_rng(seed)
    scene = case("mixed", rng, 1.0)
    h = build_hierarchy(scene, ps, ps * ratio)
    check_invariants(scene, h, ps, ps * ratio)


def test_rectangle_grid_exact():
    """A 3 × 2 rectangle with patch 1.5, element 0.5: 2 × 2 patches of 3 × 2 elements."""
    scene = make_scene([[0, 0, 0], [3, 0, 0], [3, 2, 0], [0, 2, 0]], [[0, 1, 2, 3]])
    h = build_hierarchy(scene, 1.5, 0.5)
    assert (h.n_patches, h.n_elements, len(h.vertices)) == (4, 24, 7 * 5)
    np.testing.assert_allclose(h.elem_area, 0.5 * 0.5, rtol=1e-15)
    np.testing.assert_allclose(h.patch_area, 1.5 * 1.0, rtol=1e-15)
    np.testing.assert_array_equal(h.elem_normal, np.tile([0.0, 0.0, 1.0], (24, 1)))
    # element centroids are the cell centres, patch centroids the block centres
    cx = np.sort(np.unique(np.round(h.elem_centroid[:, 0], 12)))
    np.testing.assert_allclose(cx, [0.25, 0.75, 1.25, 1.75, 2.25, 2.75], atol=1e-15)
    np.testing.assert_allclose(np.sort(h.patch_centroid[:, 0]), [0.75, 0.75, 2.25, 2.25])
    np.testing.assert_allclose(np.sort(h.patch_centroid[:, 1]), [0.5, 0.5, 1.5, 1.5])


def test_triangle_lattice_exact():
    """A right triangle with legs 2: k = 2 patches per edge (4), 2 elements per patch edge."""
    scene = make_scene([[0, 0, 0], [2, 0, 0], [0, 2, 0]], [[0, 1, 2, -1]])
    h = build_hierarchy(scene, 1.5, 0.75)  # kp = ⌈2√2 / 1.5⌉ = 2, ke = ⌈√2 / 0.75⌉ = 2
    assert (h.n_patches, h.n_elements, len(h.vertices)) == (4, 16, 15)
    np.testing.assert_allclose(h.elem_area, 2.0 / 16, rtol=1e-15)
    assert np.all(h.elem_verts[:, 3] == -1) and np.all(h.patch_verts[:, 3] == -1)
    # the inverted middle patch has corners (1,0), (1,1), (0,1), counter-clockwise
    corners = {tuple(np.round(h.vertices[p[:3]], 12).ravel()) for p in h.patch_verts}
    assert (1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0) in corners
    np.testing.assert_allclose(np.sort(h.patch_centroid[:, 0]), [1 / 3, 1 / 3, 2 / 3, 4 / 3])


def test_vertex_average_weights():
    """A trapezoid cut into two elements of areas 1.875 and 2.625: the vertices on the cut get
    ``(1.875·a + 2.625·b) / 4.5``, the others their one element's value."""
    v = [[0, 0, 0], [3, 0, 0], [3, 2, 0], [0, 1, 0]]
    scene = make_scene(v, [[0, 1, 2, 3]])
    h = build_hierarchy(scene, 2.0, 2.0)  # u: ⌈3/2⌉ = 2 pieces, v: ⌈2/2⌉ = 1
    assert h.n_elements == 2
    left = int(np.argmin(h.elem_centroid[:, 0]))
    np.testing.assert_allclose(h.elem_area[[left, 1 - left]], [1.875, 2.625], rtol=1e-15)
    vals = np.empty((2, 2))
    vals[left], vals[1 - left] = [1.0, 10.0], [4.0, 40.0]
    got = vertex_average(h, vals)
    mixed = (1.875 * vals[left] + 2.625 * vals[1 - left]) / 4.5
    for i, xi in enumerate(h.vertices[:, 0]):
        want = vals[left] if xi == 0 else vals[1 - left] if xi == 3 else mixed
        np.testing.assert_allclose(got[i], want, rtol=1e-15)
    np.testing.assert_allclose(vertex_average(h, vals[:, 0]), got[:, 0])


def test_vertex_average_unequal_areas_and_adjacency(rng):
    scene = case("skewed_quads", rng, 1.0)
    h = build_hierarchy(scene, 0.7, 0.3)
    vals = rng.normal(size=(h.n_elements, 3))
    indptr, elems, weights = element_vertex_adjacency(h)
    assert indptr[-1] == len(elems) == len(weights)
    np.testing.assert_allclose(np.add.reduceat(weights, indptr[:-1]), 1.0, rtol=1e-14)
    # an interior vertex of a quad grid has 4 elements, a corner 1, another boundary vertex 2
    valence = np.diff(indptr)
    assert set(valence.tolist()) <= {1, 2, 4} and valence.max() == 4
    via_csr = np.add.reduceat(weights[:, None] * vals[elems], indptr[:-1])
    np.testing.assert_allclose(vertex_average(h, vals), via_csr, rtol=1e-12, atol=1e-14)
    # the vertex value lies within the range of its elements' values (a convex average)
    lo = np.minimum.reduceat(vals[elems], indptr[:-1])
    hi = np.maximum.reduceat(vals[elems], indptr[:-1])
    got = vertex_average(h, vals)
    assert np.all(got >= lo - 1e-12) and np.all(got <= hi + 1e-12)
    with pytest.raises(ValueError):
        vertex_average(h, vals[:-1])


def test_vertices_not_shared_between_polygons():
    """Two quads sharing an edge in the input get separate vertices along it."""
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]]
    scene = make_scene(v, [[0, 1, 2, 3], [1, 4, 5, 2]])
    h = build_hierarchy(scene, 0.5, 0.25)
    on_seam = np.isclose(h.vertices[:, 0], 1.0)
    assert on_seam.sum() == 2 * 5
    vals = np.where(h.elem_polygon == 0, 1.0, 2.0)
    avg = vertex_average(h, vals)
    np.testing.assert_array_equal(avg, np.where(vertex_polygon(h) == 0, 1.0, 2.0))


def test_hierarchy_triangles():
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 1], [1, 0, 1], [0, 1, 1]]
    scene = make_scene(v, [[0, 1, 2, 3], [4, 5, 6, -1]])
    h = build_hierarchy(scene, 0.5, 0.5)
    tris, _, owner = hierarchy_triangles(h)
    n_quads = int((h.elem_verts[:, 3] >= 0).sum())
    assert tris.shape == (h.n_elements + n_quads, 3, 3) and tris.dtype == np.float64
    assert owner.dtype == np.int32 and np.all(np.diff(owner) >= 0)
    area = np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1) / 2
    np.testing.assert_allclose(np.bincount(owner, weights=area), h.elem_area, rtol=1e-14)
    # quad (a, b, c, d) → (a, b, c), (a, c, d)
    e = 0
    a, b, c, d = h.vertices[h.elem_verts[e]]
    np.testing.assert_array_equal(tris[owner == e], [[a, b, c], [a, c, d]])


def cornell_scene(path) -> Scene:
    """The bundled Cornell box read with a minimal OBJ reader (the real loader is elsewhere)."""
    verts, polys, mats, names = [], [], [], []
    for line in path.read_text().splitlines():
        f = line.split()
        if not f:
            continue
        if f[0] == "v":
            verts.append([float(x) for x in f[1:4]])
        elif f[0] == "usemtl":
            names += [] if f[1] in names else [f[1]]
            cur = names.index(f[1])
        elif f[0] == "f":
            idx = [int(x.split("/")[0]) - 1 for x in f[1:]]
            polys.append(idx + [-1] * (4 - len(idx)))
            mats.append(cur)
    return Scene(path=str(path), vertices=np.array(verts), polygons=np.array(polys, np.int32),
                 polygon_material=np.array(mats, np.int32), materials=materials(len(names)))


def test_cornell_box_defaults(scenes_dir):
    """The default sizes give the Cornell box 100–400 patches and 1,500–5,000 elements (the
    floor cut along the blocks' feet into 26 quads, issue 14: 309 patches, 251 uncut)."""
    path = scenes_dir / "cornell_box.obj"
    if not path.exists():
        pytest.skip("bundled Cornell box missing")
    scene = cornell_scene(path)
    ps, es = default_sizes(scene)
    assert ps == pytest.approx(scene.diagonal / 8) and es == pytest.approx(ps / 4)
    h = build_hierarchy(scene)
    assert 100 <= h.n_patches <= 400
    assert 1500 <= h.n_elements <= 5000
    cut, parent, _ = cut_at_contacts(scene)
    assert np.bincount(parent).tolist() == [26] + [1] * (len(scene.polygons) - 1)  # the floor
    check_invariants(cut, h, ps, es)


def test_bad_sizes_raise_option_error():
    scene = make_scene([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2, -1]])
    for bad in (0.0, -1.0, float("nan"), float("inf"), "x"):
        with pytest.raises(OptionError):
            build_hierarchy(scene, bad, 0.1)
        with pytest.raises(OptionError):
            build_hierarchy(scene, 0.5, bad)
    with pytest.raises(OptionError, match="elements"):
        build_hierarchy(scene, 1.0, 1e-6)  # ~1e12 elements: refused before allocating


def test_empty_scene_has_no_default_sizes():
    scene = make_scene(np.zeros((0, 3)), np.zeros((0, 4)))
    with pytest.raises(SceneError):
        default_sizes(scene)
    h = build_hierarchy(scene, 1.0, 1.0)
    assert h.n_elements == h.n_patches == len(h.vertices) == 0
