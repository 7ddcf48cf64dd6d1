"""Discontinuity meshing along contact lines (issue 14, item 3).

Where a polygon stands on another (a block on the floor, a partition on a wall), the lower
polygon's light jumps along the contact line: the part under the block gets nothing, the
part beside it is lit, and along the foot the block's own face gathers light from the floor
right next to it. An element straddling the line averages both sides: its patch shoots from a
centroid that may lie under the block (its light is lost inside the block), its vertices under
the block are dark, and Gouraud interpolation spreads that darkness along the foot, where
people look first (issue 14: contact rows 30 % too dark).

So polygons are cut along every contact line before they are meshed: the supporting line of
each *contact edge* (an edge of another polygon lying in the polygon's plane, whose polygon
rises on the lit side) cuts every piece the edge passes through, BSP-fashion, into convex
pieces; elements then never straddle a contact line and Gouraud interpolation never mixes the
two sides. Pieces are returned as convex quads in the polygon's winding
(:func:`daskrad.kernels.contacts.cut_polygons`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from daskrad import tolerances
from daskrad.kernels.contacts import contact_edges, cut_polygons
from daskrad.scene.types import Scene


def cut_at_contacts(scene: Scene) -> tuple[Scene, np.ndarray, np.ndarray]:
    """``scene`` with its polygons cut along their contact lines (:func:`split_at_contacts`).

    Returns ``(cut, parent (Q',) int64, normals (Q', 3) float64)``: the scene whose polygons
    are the pieces (uncut polygons keep their row and vertices; a cut polygon's pieces get
    new vertices appended), the input polygon of each piece, and its input polygon's unit
    normal (so the pieces of a polygon are coplanar bit for bit). Without a contact the
    scene comes back as it is.
    """
    poly = np.asarray(scene.polygons)
    is_quad = poly[:, 3] >= 0
    idx = np.where(is_quad[:, None], poly, poly[:, [0, 1, 2, 2]])
    corners = np.asarray(scene.vertices, dtype=np.float64)[idx]
    tri = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    quad = np.cross(corners[:, 2] - corners[:, 0], corners[:, 3] - corners[:, 1])
    newell = np.where(is_quad[:, None], quad, tri)
    with np.errstate(invalid="ignore", divide="ignore"):
        normals = newell / np.linalg.norm(newell, axis=1, keepdims=True)
    if len(poly) < 2:
        return scene, np.arange(len(poly), dtype=np.int64), normals
    pieces, piece_quad, parent = split_at_contacts(corners, is_quad, np.nan_to_num(normals),
                                                   scene.diagonal)
    if len(parent) == len(poly):
        return scene, parent, normals
    cut = np.bincount(parent, minlength=len(poly)) > 1
    new = cut[parent]
    base = len(scene.vertices)
    rows = np.where(piece_quad[new][:, None], np.arange(4), [0, 1, 2, -1])
    rows = np.where(rows >= 0, base + 4 * np.arange(int(new.sum()))[:, None] + rows, -1)
    polygons = np.empty((len(parent), 4), dtype=poly.dtype)
    polygons[~new] = poly[parent[~new]]
    polygons[new] = rows
    vertices = np.concatenate([np.asarray(scene.vertices, np.float64),
                               pieces[new].reshape(-1, 3)])
    back = scene.back_material
    out = dataclasses.replace(scene, vertices=vertices, polygons=polygons,
                              polygon_material=np.asarray(scene.polygon_material)[parent],
                              back_material=None if back is None else back[parent])
    return out, parent, normals[parent]


def _edges(corners: np.ndarray, is_quad: np.ndarray):
    """``(a (K, 3), b (K, 3), owner (K,))``: every polygon edge (3 per triangle, 4 per quad)."""
    # a triangle's corners are c0 c1 c2 c2: its edge 2 (c2 → c2) is empty, edge 3 is c2 → c0
    a = corners
    b = corners[:, [1, 2, 3, 0]]
    keep = np.ones((len(corners), 4), bool)
    keep[~is_quad, 2] = False
    owner = np.broadcast_to(np.arange(len(corners))[:, None], (len(corners), 4))
    return (np.ascontiguousarray(a[keep]), np.ascontiguousarray(b[keep]),
            np.ascontiguousarray(owner[keep]).astype(np.int64))


def split_at_contacts(corners: np.ndarray, is_quad: np.ndarray, normals: np.ndarray,
                      diag: float):
    """Polygons cut along their contact lines.

    Parameters
    ----------
    corners : (Q, 4, 3) float64
        Polygon corners (a triangle repeats c2 as c3), wound counter-clockwise from the lit side.
    is_quad : (Q,) bool
    normals : (Q, 3) float64, unit
    diag : float
        The scene's diagonal: an edge lies in a plane within ``CONTACT · diag``.

    Returns ``(corners (Q', 4, 3), is_quad (Q',), parent (Q',) int64)``: the pieces, each a
    planar convex quad or triangle of its parent polygon, parents in order; an uncut polygon
    is its own single piece, unchanged.
    """
    q = len(corners)
    if q < 2:
        return corners, is_quad, np.arange(q, dtype=np.int64)
    tol = tolerances.CONTACT * diag
    a, b, owner = _edges(corners, is_quad)
    pairs = contact_edges(np.ascontiguousarray(corners), is_quad.astype(np.bool_),
                          np.ascontiguousarray(normals, dtype=np.float64), a, b, owner, tol)
    if len(pairs) == 0:
        return corners, is_quad, np.arange(q, dtype=np.int64)
    # each polygon's contact edges, in the order the kernel found them (the order they cut)
    order = np.argsort(pairs[:, 0], kind="stable")
    start = np.searchsorted(pairs[order, 0], np.arange(q + 1)).astype(np.int64)
    return cut_polygons(np.ascontiguousarray(corners, dtype=np.float64),
                        is_quad.astype(np.bool_), np.ascontiguousarray(normals, np.float64),
                        a, b, start, np.ascontiguousarray(pairs[order, 1], dtype=np.int64), tol)
