"""Step 1 of the pipeline: input polygons → patches → elements (docs/design.md §1, §3).

Input polygons are first cut along their contact lines, where another polygon stands on them
(:mod:`daskrad.mesh.contacts`); the hierarchy's polygons are those pieces.
Every polygon (a planar convex quad or a triangle) is cut into one uniform lattice of
elements; patches are blocks of that lattice. Quads become bilinear ``n × m`` grids of quads,
triangles ``k²`` similar triangles. Vertices are shared by all elements and patches of one
polygon (continuous Gouraud interpolation, no T-vertex inside a polygon) and never between two
polygons (they may differ in material and normal).

Areas are *projected* areas along the polygon's unit normal, ``½ n · (d₁ × d₂)``: for a planar
polygon that is the area, and projected areas of a tiling add up exactly (to round-off) even
when a quad is planar only within ``tolerances.PLANAR_QUAD``, so elements sum to their patch
and patches to their polygon at every level.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from daskrad import tolerances
from daskrad.errors import OptionError, SceneError
from daskrad.kernels.subdivide import subdivide_quads, subdivide_triangles
from daskrad.mesh.contacts import cut_at_contacts
from daskrad.mesh.types import Hierarchy
from daskrad.scene.corners import is_quad as quad_mask
from daskrad.scene.corners import repeat_third, split_quads
from daskrad.scene.types import Scene

#: Patch edge ≈ diagonal / PATCHES_PER_DIAGONAL by default (see :func:`default_sizes`).
PATCHES_PER_DIAGONAL = 8.0
#: Element edge ≈ patch edge / ELEMENTS_PER_PATCH_EDGE by default.
ELEMENTS_PER_PATCH_EDGE = 4.0
#: Refuse sizes that would create more elements than this (≈ 100 bytes each: ~2 GB).
MAX_ELEMENTS = 20_000_000


def default_sizes(scene: Scene) -> tuple[float, float]:
    """``(patch_size, element_size)``: maximum patch and element edge lengths for ``scene``.

    Why these numbers: a shot costs work proportional to the number of elements and the solve
    needs a few shots per patch, so the cost grows like ``patches × elements``. A patch edge of
    ``diagonal / 8`` gives a room-sized scene about 5 patches along each wall (the bundled Cornell
    box, diagonal ≈ 961 mm, gets 120 mm patches: ~200 patches over its 26 polygons), coarse
    enough that shooting converges in a few hundred steps, fine enough that a patch is
    mostly far from its receivers compared with its size, where a point shooter is accurate
    (docs/design.md §2). Elements at a quarter of that (30 mm: 16 per patch, ~3,000 in the
    Cornell box) resolve the shading gradients along wall junctions that flat radiosity gets wrong,
    and adaptive refinement (step 2) adds more only where the light changes quickly.
    """
    if len(scene.polygons) == 0:
        raise SceneError("the scene has no polygons", scene.path)
    diag = scene.diagonal
    if not (np.isfinite(diag) and diag > 0):
        raise SceneError("the scene's bounding box is empty or not finite", scene.path)
    patch = diag / PATCHES_PER_DIAGONAL
    return patch, patch / ELEMENTS_PER_PATCH_EDGE


def _check_size(name: str, value: float) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise OptionError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise OptionError(f"{name} must be a positive finite length, got {value!r}")
    return value


def _divisions(length: np.ndarray, size: float) -> np.ndarray:
    """Fewest equal pieces so that each piece of ``length`` is at most ``size`` (≥ 1)."""
    return np.maximum(np.ceil(length / size), 1.0)


def _polygon_normals(corners: np.ndarray, is_quad: np.ndarray) -> np.ndarray:
    """``(Q, 3)`` Newell vectors: for a quad ``(c2-c0) × (c3-c1)``, for a triangle
    ``(c1-c0) × (c2-c0)``; twice the (projected) area times the unit normal."""
    tri = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    quad = np.cross(corners[:, 2] - corners[:, 0], corners[:, 3] - corners[:, 1])
    return np.where(is_quad[:, None], quad, tri)


def polygon_areas(scene: Scene) -> np.ndarray:
    """``(Q,) float64``: area of every input polygon (half the length of its Newell vector)."""
    corners, is_quad = _corners(scene)
    return 0.5 * np.linalg.norm(_polygon_normals(corners, is_quad), axis=1)


def _corners(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """``(Q, 4, 3)`` corners (a triangle repeats c2 as c3) and ``(Q,) bool`` is-quad."""
    poly = np.asarray(scene.polygons)
    return np.asarray(scene.vertices, dtype=np.float64)[repeat_third(poly)], quad_mask(poly)


def one_sided(scene: Scene) -> Scene:
    """``scene`` with every two-sided polygon as two one-sided ones: the front as it is and a
    reversed copy with the back's material :data:`~daskrad.tolerances.TWO_SIDED_GAP` × the
    diagonal behind it (its own vertices, welded where backs of one surface meet). Every
    later step (shadow rays, item buffers, shooting, the renderer) sees one-sided faces only,
    and the two sides of a surface never share a depth."""
    back = scene.back_material
    if back is None or not (back >= 0).any():
        return scene
    ids = np.flatnonzero(back >= 0)
    poly = scene.polygons[ids]
    quad = poly[:, 3] >= 0
    p = scene.vertices[np.where(poly >= 0, poly, poly[:, :1])]           # (k, 4, 3)
    n = np.where(quad[:, None], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1]),
                 np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    moved = p - tolerances.TWO_SIDED_GAP * scene.diagonal * n[:, None, :]
    used = poly >= 0
    welded, inverse = np.unique(moved[used] + 0.0, axis=0, return_inverse=True)
    twin = np.full(poly.shape, -1, np.int64)
    twin[used] = len(scene.vertices) + inverse.reshape(-1)
    # reversed winding, the first corner kept: (a, b, c, d) → (a, d, c, b), (a, b, c) → (a, c, b)
    twin = np.where(quad[:, None], twin[:, [0, 3, 2, 1]], twin[:, [0, 2, 1, 3]])
    return replace(
        scene, vertices=np.concatenate([scene.vertices, welded]),
        polygons=np.concatenate([scene.polygons, twin]).astype(np.int32),
        polygon_material=np.concatenate([scene.polygon_material, back[ids]]).astype(np.int32),
        back_material=None)


def build_hierarchy(scene: Scene, patch_size: float | None = None,
                    element_size: float | None = None, *, cut_contacts: bool = True
                    ) -> Hierarchy:
    """Split every polygon into patches of edge ≤ ``patch_size`` and those into elements of
    edge ≤ ``element_size`` (scene units; ``None``: :func:`default_sizes`).

    A quad with ``u`` edges ``c0c1, c3c2`` and ``v`` edges ``c0c3, c1c2`` gets
    ``nu = ⌈max|u edge| / patch_size⌉`` patches along ``u`` and ``eu = ⌈max|u edge| / nu /
    element_size⌉`` elements per patch along ``u`` (likewise ``v``); a triangle with longest
    edge ``L`` gets ``kp = ⌈L / patch_size⌉``, ``ke = ⌈L / kp / element_size⌉``, i.e. ``kp²``
    patches of ``ke²`` elements. Elements keep the polygon's winding; their normal is the
    polygon's (bit for bit), their centroid the area-weighted one.

    Two-sided polygons are meshed as two one-sided ones (:func:`one_sided`): the hierarchy's
    polygons are the scene's followed by the backs.
    ``cut_contacts``: first cut polygons along the lines where others stand on them
    (:func:`daskrad.mesh.contacts.cut_at_contacts`); ``False`` meshes the input polygons as
    they are (a patch may then straddle the foot of a block).

    Returns
    -------
    Hierarchy
        Patches in polygon order, the elements of each patch contiguous.
    """
    if patch_size is None or element_size is None:
        dp, de = default_sizes(scene)
        patch_size = dp if patch_size is None else patch_size
        element_size = de if element_size is None else element_size
    patch_size = _check_size("patch size", patch_size)
    element_size = _check_size("element size", element_size)

    # polygons cut along the lines where others stand on them (issue 14); a piece keeps its
    # input polygon's normal bit for bit, so the pieces of a polygon stay exactly coplanar
    # first; then the backs of two-sided polygons (one_sided) are made of the cut pieces: a
    # two-sided fin cuts the floor once, not along both of its sides 1e-5 of the scene apart
    # (a sliver of floor between them: furnace error 24 %)
    poly_normal = None
    if cut_contacts:
        scene, _, poly_normal = cut_at_contacts(scene)
    if scene.back_material is not None and (scene.back_material >= 0).any():
        fronts = np.flatnonzero(scene.back_material >= 0)
        scene = one_sided(scene)
        if poly_normal is not None:     # a back's normal is its front's, reversed
            poly_normal = np.concatenate([poly_normal, -poly_normal[fronts]])
    corners, is_quad = _corners(scene)
    if poly_normal is None:
        newell = _polygon_normals(corners, is_quad)
        with np.errstate(invalid="ignore", divide="ignore"):
            poly_normal = newell / np.linalg.norm(newell, axis=1, keepdims=True)
    nq = len(corners)
    edge = np.linalg.norm(np.roll(corners, -1, axis=1) - corners, axis=2)  # (Q,4): c_i c_i+1
    # quads: u pieces from the longer of c0c1 / c3c2, v from c1c2 / c3c0; triangles: the
    # longest edge (edge 3 is c2→c2 = 0 for them). Counts stay float until checked.
    lu = np.where(is_quad, np.maximum(edge[:, 0], edge[:, 2]), edge.max(axis=1))
    lv = np.where(is_quad, np.maximum(edge[:, 1], edge[:, 3]), lu)
    nu = _divisions(lu, patch_size)
    nv = _divisions(lv, patch_size)
    eu = _divisions(lu / nu, element_size)
    ev = _divisions(lv / nv, element_size)
    n_fine = nu * eu * nv * ev  # elements: N·M for a quad, K² for a triangle
    total = float(n_fine.sum())
    if not total <= MAX_ELEMENTS:
        raise OptionError(
            f"patch size {patch_size:g} and element size {element_size:g} would create "
            f"{total:.3g} elements (more than {MAX_ELEMENTS:,}); choose larger sizes")
    nu, nv, eu, ev = (a.astype(np.int64) for a in (nu, nv, eu, ev))

    n_patch = nu * nv
    n_elem = (nu * eu) * (nv * ev)
    k = nu * eu
    n_vert = np.where(is_quad, (nu * eu + 1) * (nv * ev + 1), (k + 1) * (k + 2) // 2)
    vert_start = np.concatenate([[0], np.cumsum(n_vert)[:-1]]).astype(np.int64)
    elem_start = np.concatenate([[0], np.cumsum(n_elem)[:-1]]).astype(np.int64)
    patch_start = np.concatenate([[0], np.cumsum(n_patch)[:-1]]).astype(np.int64)
    nv_tot, ne_tot, np_tot = int(n_vert.sum()), int(n_elem.sum()), int(n_patch.sum())

    vertices = np.empty((nv_tot, 3), np.float64)
    elem_verts = np.empty((ne_tot, 4), np.int32)
    elem_patch = np.empty(ne_tot, np.int32)
    patch_verts = np.empty((np_tot, 4), np.int32)
    q = np.flatnonzero(is_quad)
    t = np.flatnonzero(~is_quad)
    if len(q):
        subdivide_quads(np.ascontiguousarray(corners[q]), nu[q], nv[q], eu[q], ev[q],
                        vert_start[q], elem_start[q], patch_start[q],
                        vertices, elem_verts, elem_patch, patch_verts)
    if len(t):
        subdivide_triangles(np.ascontiguousarray(corners[t, :3]), nu[t], eu[t],
                            vert_start[t], elem_start[t], patch_start[t],
                            vertices, elem_verts, elem_patch, patch_verts)

    patch_polygon = np.repeat(np.arange(nq, dtype=np.int32), n_patch)
    elem_polygon = patch_polygon[elem_patch]
    elem_normal = poly_normal[elem_polygon]
    elem_area, elem_centroid = _areas_centroids(vertices, elem_verts, elem_normal)

    patch_area = np.bincount(elem_patch, weights=elem_area, minlength=np_tot)
    patch_centroid = np.stack(
        [np.bincount(elem_patch, weights=elem_area * elem_centroid[:, d], minlength=np_tot)
         for d in range(3)], axis=1) / patch_area[:, None]
    return Hierarchy(
        vertices=vertices,
        elem_verts=elem_verts,
        elem_patch=elem_patch,
        patch_verts=patch_verts,
        patch_polygon=patch_polygon,
        polygon_material=np.asarray(scene.polygon_material, dtype=np.int32).copy(),
        elem_area=elem_area,
        elem_normal=elem_normal,
        elem_centroid=elem_centroid,
        patch_area=patch_area,
        patch_normal=poly_normal[patch_polygon],
        patch_centroid=patch_centroid,
    )


def _areas_centroids(vertices: np.ndarray, verts: np.ndarray,
                     normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Projected area ``(n,)`` and area-weighted centroid ``(n, 3)`` of quads/triangles
    ``verts (n, 4)`` (``-1`` in column 3) along unit ``normal (n, 3)``.

    A quad is the two triangles ``(a, b, c)`` and ``(a, c, d)``; a triangle is ``(a, b, c)``
    plus the empty ``(a, c, c)``.
    """
    d_idx = repeat_third(verts)[:, 3]
    a, b, c, d = (vertices[verts[:, 0]], vertices[verts[:, 1]], vertices[verts[:, 2]],
                  vertices[d_idx])
    ac = c - a
    a1 = 0.5 * np.einsum("ij,ij->i", normal, np.cross(b - a, ac))
    a2 = 0.5 * np.einsum("ij,ij->i", normal, np.cross(ac, d - a))
    area = a1 + a2
    centroid = (a1[:, None] * (a + b + c) + a2[:, None] * (a + c + d)) / (3.0 * area[:, None])
    return area, centroid


def hierarchy_triangles(h: Hierarchy) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every element as one triangle (a triangle) or two (a quad ``(a,b,c,d)`` →
    ``(a,b,c), (a,c,d)``), for the ray-tracing voxel grid.

    Returns
    -------
    triangles : (T, 3, 3) float64
        Corners, wound like the element.
    tri_verts : (T, 3) int32
        Vertex ids of the corners (for Gouraud interpolation of vertex values).
    tri_element : (T,) int32
        The element of each triangle, non-decreasing.
    """
    idx, owner = split_quads(h.elem_verts)
    owner = owner.astype(np.int32)
    order = np.argsort(owner, kind="stable")
    tri_verts = np.ascontiguousarray(idx[order], dtype=np.int32)
    return h.vertices[tri_verts], tri_verts, owner[order]


def vertex_polygon(h: Hierarchy) -> np.ndarray:
    """``(V,) int32``: the polygon each vertex belongs to (``-1`` for an unused vertex)."""
    out = np.full(len(h.vertices), -1, np.int32)
    ev = h.elem_verts
    poly = np.broadcast_to(h.elem_polygon[:, None], ev.shape)
    used = ev >= 0
    out[ev[used]] = poly[used]
    return out


def element_vertex_adjacency(h: Hierarchy) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Elements around every vertex, as CSR, with the weights of :func:`vertex_average`.

    Returns
    -------
    indptr : (V + 1,) int64
        The elements of vertex ``v`` are ``elements[indptr[v]:indptr[v+1]]``.
    elements : (n,) int32
    weights : (n,) float64
        ``area / (sum of the areas around the vertex)``: they add up to 1 for each used vertex.
    """
    ev = h.elem_verts
    used = ev >= 0
    vert = ev[used]
    elem = np.broadcast_to(np.arange(len(ev), dtype=np.int32)[:, None], ev.shape)[used]
    order = np.argsort(vert, kind="stable")
    vert, elem = vert[order], elem[order]
    counts = np.bincount(vert, minlength=len(h.vertices))
    indptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    w = h.elem_area[elem]
    total = np.bincount(vert, weights=w, minlength=len(h.vertices))
    return indptr, elem, w / total[vert]


def vertex_average(h: Hierarchy, elem_values: np.ndarray) -> np.ndarray:
    """Area-weighted average of the elements around each vertex.

    This is how element radiosity becomes vertex radiosity for Gouraud interpolation
    (docs/design.md §1, step 4). Vertices belong to one polygon, so values never mix across
    polygons.

    Parameters
    ----------
    elem_values : (E,) or (E, k) float
    Returns
    -------
    (V,) or (V, k) float64
        ``0`` at a vertex no element uses.
    """
    vals = np.asarray(elem_values, dtype=np.float64)
    flat = vals.ndim == 1
    vals = vals.reshape(len(vals), -1)
    if len(vals) != h.n_elements:
        raise ValueError(f"expected {h.n_elements} element values, got {len(vals)}")
    ev = h.elem_verts
    used = ev >= 0
    vert = ev[used]
    # Each used corner contributes area·value of its element; row-major order of `used`
    # matches np.repeat over elements by their corner count.
    n_corners = used.sum(axis=1)
    w = np.repeat(h.elem_area, n_corners)
    nv = len(h.vertices)
    total = np.bincount(vert, weights=w, minlength=nv)
    with np.errstate(invalid="ignore", divide="ignore"):
        inv = np.where(total > 0, 1.0 / total, 0.0)
    out = np.empty((nv, vals.shape[1]))
    for c in range(vals.shape[1]):  # channels (k is small), not elements
        out[:, c] = np.bincount(vert, weights=w * np.repeat(vals[:, c], n_corners),
                                minlength=nv) * inv
    return out[:, 0] if flat else out
