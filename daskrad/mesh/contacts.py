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
two sides. Pieces are returned as convex quads in the polygon's winding (:func:`_fan`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from daskrad import tolerances
from daskrad.kernels.contacts import contact_edges
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


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``u × v`` of two 3-vectors: the products and differences of ``np.cross``, so the same
    bits, without its axis handling (which took most of the cutting's time on the offices)."""
    u0, u1, u2 = u
    v0, v1, v2 = v
    return np.array([u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0])


def _cut(piece: np.ndarray, m: np.ndarray, c: float, tol: float):
    """``piece (k, 3)`` cut by the plane ``m · x = c``: the two convex parts (order kept)."""
    s = piece @ m - c
    pos, neg = [], []
    k = len(piece)
    for i in range(k):
        j = (i + 1) % k
        if s[i] >= -tol:
            pos.append(piece[i])
        if s[i] <= tol:
            neg.append(piece[i])
        if (s[i] > tol and s[j] < -tol) or (s[i] < -tol and s[j] > tol):
            x = piece[i] + (s[i] / (s[i] - s[j])) * (piece[j] - piece[i])
            pos.append(x)
            neg.append(x)
    return np.array(pos), np.array(neg)


def _crosses(piece: np.ndarray, n: np.ndarray, a: np.ndarray, b: np.ndarray, tol: float) -> bool:
    """Whether the segment ``ab`` runs through the interior of the convex ``piece`` (normal
    ``n``) for more than ``tol`` (Cyrus–Beck clipping against the piece's edges)."""
    t0, t1 = 0.0, 1.0
    d = b - a
    k = len(piece)
    for i in range(k):
        e = piece[(i + 1) % k] - piece[i]
        inward = _cross(n, e)
        length = np.linalg.norm(inward)
        if length == 0.0:
            continue
        inward /= length
        num = (a - piece[i]) @ inward - tol   # strictly inside, by tol
        den = d @ inward
        if den == 0.0:
            if num < 0.0:
                return False
            continue
        t = -num / den
        if den > 0.0:
            t0 = max(t0, t)
        else:
            t1 = min(t1, t)
        if t0 >= t1:
            return False
    return (t1 - t0) * np.linalg.norm(d) > tol


def _fan(piece: np.ndarray) -> list[np.ndarray]:
    """A convex polygon ``(m, 3)`` as convex ``(4, 3)`` quads, in its winding.

    Fanned from corner 0 into quads; a triangle left over is cut into three quads at its
    centroid and edge midpoints: the mesher gives a triangle of longest edge ``L``
    ``⌈L / patch size⌉²`` patches, which for the long thin triangles a cut leaves behind is
    many times their area's worth; its three quads get about a third of the count.
    """
    out = []
    i = 1
    m = len(piece)
    while i + 2 < m:
        out.append(piece[[0, i, i + 1, i + 2]])
        i += 2
    if i + 1 < m:
        a, b, c = piece[0], piece[i], piece[i + 1]
        g = (a + b + c) / 3.0
        ab, bc, ca = 0.5 * (a + b), 0.5 * (b + c), 0.5 * (c + a)
        out += [np.array([a, ab, g, ca]), np.array([b, bc, g, ab]), np.array([c, ca, g, bc])]
    return out


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
    by_poly: dict[int, list[int]] = {}
    for p, e in pairs:
        by_poly.setdefault(int(p), []).append(int(e))
    out_c, out_q, out_p = [], [], []
    area_tol = tol * tol
    for i in range(q):
        if i not in by_poly:
            out_c.append(corners[i])
            out_q.append(bool(is_quad[i]))
            out_p.append(i)
            continue
        n = normals[i]
        pieces = [corners[i] if is_quad[i] else corners[i, :3]]
        for e in by_poly[i]:
            d = b[e] - a[e]
            m = _cross(n, d)
            length = np.linalg.norm(m)
            if length == 0.0:
                continue
            m /= length
            c = float(m @ a[e])
            nxt = []
            for piece in pieces:
                s = piece @ m - c
                if s.max() > tol and s.min() < -tol and _crosses(piece, n, a[e], b[e], tol):
                    nxt.extend(_cut(piece, m, c, tol))
                else:
                    nxt.append(piece)
            pieces = nxt
        if len(pieces) == 1:
            out_c.append(corners[i])
            out_q.append(bool(is_quad[i]))
            out_p.append(i)
            continue
        for piece in pieces:
            for f in _fan(piece):
                quad = not np.array_equal(f[3], f[2])
                newell = (_cross(f[2] - f[0], f[3] - f[1]) if quad
                          else _cross(f[1] - f[0], f[2] - f[0]))
                if 0.5 * abs(newell @ n) <= area_tol:
                    continue  # a sliver where a cut line grazes a corner
                out_c.append(f)
                out_q.append(quad)
                out_p.append(i)
    return (np.ascontiguousarray(np.array(out_c, dtype=np.float64)), np.array(out_q, bool),
            np.array(out_p, np.int64))
