"""Faces of any corner count → input polygons: planar convex quads and triangles
(docs/design.md §1, §3).

Every function keeps the file's winding: a polygon's normal ``(v1 - v0) × (v2 - v0)`` points the
way the face's own (Newell) normal points, which is the side the file says is lit. Nothing here
"fixes" normals.

Tolerances are relative to the scene's scale ``diag`` (the bounding-box diagonal), see
:mod:`daskrad.tolerances`.
"""

from __future__ import annotations

import numpy as np

from daskrad import tolerances
from daskrad.errors import SceneError


def newell_normal(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area vectors of polygons with the same corner count (Newell's method).

    Parameters
    ----------
    vertices : (V, 3) float64
    faces : (k, n) int
        Corner indices, no ``-1``.

    Returns
    -------
    (k, 3) float64
        ``½ Σ v_i × v_{i+1}``: its length is the area of a planar polygon, its direction the
        normal given by the corners' order (counter-clockwise seen from where it points).
    """
    p = vertices[faces]
    return 0.5 * np.cross(p, np.roll(p, -1, axis=1)).sum(axis=1)


def convex_planar(vertices: np.ndarray, faces: np.ndarray, diag: float,
                  strict: bool = True) -> np.ndarray:
    """``(k,) bool``: polygons that are planar and strictly convex.

    Planar: every corner lies within ``PLANAR_QUAD * diag`` of the plane through the centroid
    with the Newell normal. Strictly convex: at every corner the turn ``e_i × e_{i+1}`` points
    along the normal by more than ``DEGENERATE_AREA * diag²`` (a corner of 180° or a reflex
    corner fails, so a kept quad never has three collinear corners and its normal
    ``(v1 - v0) × (v2 - v0)`` is well defined). With ``strict=False`` a corner of 180° (within
    that tolerance) passes too: a face cut by :func:`_ear_strips` may have them (a circle of
    10⁶ corners turns by 2.5e-16 of its size² at each), and an ear on one has zero area and is
    dropped as such.
    """
    p = vertices[faces]
    area_vec = newell_normal(vertices, faces)
    length = np.linalg.norm(area_vec, axis=1)
    n = area_vec / np.where(length > 0, length, 1.0)[:, None]
    centre = p.mean(axis=1)
    offset = np.abs(np.einsum("kij,kj->ki", p - centre[:, None, :], n))
    planar = (offset <= tolerances.PLANAR_QUAD * diag).all(axis=1) & (length > 0)
    e = np.roll(p, -1, axis=1) - p
    turn = np.einsum("kij,kj->ki", np.cross(e, np.roll(e, -1, axis=1)), n)
    eps = tolerances.DEGENERATE_AREA * diag**2
    convex = (turn > eps).all(axis=1) if strict else (turn > -eps).all(axis=1)
    return planar & convex


def polygon_area(vertices: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """``(Q,) float64`` area of triangles and quads (``-1`` in column 3 for a triangle).

    A quad's area is ``½ |d₁ × d₂|`` with ``d`` its diagonals (exact for a planar quad).
    """
    p0, p1, p2 = (vertices[polygons[:, i]] for i in range(3))
    quad = polygons[:, 3] >= 0
    p3 = vertices[np.where(quad, polygons[:, 3], polygons[:, 0])]
    tri = np.cross(p1 - p0, p2 - p0)
    qd = np.cross(p2 - p0, p3 - p1)
    return 0.5 * np.linalg.norm(np.where(quad[:, None], qd, tri), axis=1)


def _ear_clip(vertices: np.ndarray, face: np.ndarray, diag: float) -> np.ndarray:
    """Triangulate one simple polygon (possibly concave) by ear clipping, keeping its winding.

    Returns ``(n - 2, 3)`` int indices. Only non-convex or non-planar n-gons come here, which
    are rare in scene files, so a Python loop over their corners is acceptable. A polygon with
    no ear (self-intersecting, or degenerate) falls back to a fan.
    """
    n_vec = newell_normal(vertices, face[None, :])[0]
    norm = np.linalg.norm(n_vec)
    if norm == 0:
        return np.stack([np.full(len(face) - 2, face[0]), face[1:-1], face[2:]], axis=1)
    n_vec = n_vec / norm
    eps = tolerances.DEGENERATE_AREA * diag**2
    idx = list(face)
    tris = []
    start = 0
    while len(idx) > 3:
        m = len(idx)
        # the scan resumes after the last ear, so ears are cut all around the polygon in
        # turn (every other corner per round, as :func:`_ear_strips` does), not all at one
        # place, which would leave a fan of slivers
        for step in range(m):
            k = (start + step) % m
            a, b, c = idx[k - 1], idx[k], idx[(k + 1) % m]
            pa, pb, pc = vertices[a], vertices[b], vertices[c]
            if np.dot(np.cross(pb - pa, pc - pb), n_vec) <= eps:
                continue  # reflex or flat corner: not an ear
            others = [j for j in idx if j not in (a, b, c)]
            q = vertices[others]
            # a corner strictly inside (or on) triangle abc forbids the ear
            s1 = np.cross(pb - pa, q - pa) @ n_vec
            s2 = np.cross(pc - pb, q - pb) @ n_vec
            s3 = np.cross(pa - pc, q - pc) @ n_vec
            if np.any((s1 >= 0) & (s2 >= 0) & (s3 >= 0)):
                continue
            tris.append((a, b, c))
            del idx[k]
            # the corner after the ear now has index k: resume one further (its neighbourhood
            # just changed; it comes round again next time)
            start = (k + 1) % (m - 1)
            break
        else:  # no ear: give up on this polygon's shape and fan the rest
            tris.extend((idx[0], idx[j], idx[j + 1]) for j in range(1, len(idx) - 1))
            return np.asarray(tris, dtype=np.int64)
    tris.append(tuple(idx))
    return np.asarray(tris, dtype=np.int64)


#: A convex planar face with at most this many corners becomes a fan from its first corner;
#: a larger one is cut by :func:`_ear_strips` (a fan of n corners is n slivers as long as the
#: face, each meshed into as many elements as a triangle that long: 806,644 elements for one
#: 10⁴-corner disc, issue 13).
FAN_MAX_CORNERS = 8

#: A face that is not planar and convex is ear-clipped in O(n²) Python steps: faces with more
#: corners than this are refused at once (measured: 1,000 corners clip in 0.8 s, 10⁴ would
#: take minutes).
MAX_CLIPPED_CORNERS = 1000


def _ear_strips(face: np.ndarray) -> np.ndarray:
    """Triangulate a convex polygon by cutting off every other corner, level by level.

    Level 0 cuts the ears ``(r0, r1, r2), (r2, r3, r4), ...`` of the ring ``r`` and keeps
    ``r0, r2, r4, ...``; the next level does the same to what is left, until a triangle (or
    nothing) remains. Every ear is three consecutive corners of a convex polygon, so the
    triangles tile it with its winding; there are ``n − 2`` of them, the triangles of level
    ``j`` span about ``2^(j+1)`` of the face's edges, and O(n) work in all. Unlike a fan, most
    triangles are small near the boundary and only a few span the face.

    Returns ``(n − 2, 3)`` int64 corner indices.
    """
    out = []
    ring = np.asarray(face, dtype=np.int64)
    while len(ring) > 3:
        m = len(ring)
        # ears (r[2i], r[2i+1], r[2i+2 mod m]) for i < m // 2; the even corners stay (for
        # an odd m the last, r[m-1], closes the ring)
        i = 2 * np.arange(m // 2)
        out.append(np.stack([ring[i], ring[i + 1], ring[(i + 2) % m]], axis=1))
        ring = ring[0::2]
    if len(ring) == 3:
        out.append(ring[None, :])
    return np.concatenate(out)


def faces_to_polygons(
    vertices: np.ndarray, flat: np.ndarray, counts: np.ndarray, diag: float,
    path: str | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Turn faces of any corner count into triangles and planar convex quads.

    Parameters
    ----------
    vertices : (V, 3) float64
    flat : (sum(counts),) int
        Corner indices of all faces, one face after the other.
    counts : (F,) int
        Corners per face, each ≥ 3.
    diag : float
        Scene scale for the tolerances.
    path : str, optional
        The file, for the error message.

    Returns
    -------
    polygons : (Q, 4) int32
        ``-1`` in column 3 for triangles. A planar convex quad stays a quad; a non-planar or
        concave quad is split into two triangles along the diagonal through its reflex corner
        (the 0–2 diagonal if neither is reflex); a convex planar n-gon (n ≥ 5) becomes a fan
        up to ``FAN_MAX_CORNERS`` corners and ear strips (:func:`_ear_strips`) beyond; any
        other n-gon is ear-clipped, up to ``MAX_CLIPPED_CORNERS`` corners.

    Raises
    ------
    SceneError
        A face that is not planar and convex with more than ``MAX_CLIPPED_CORNERS`` corners.
    face : (Q,) int64
        The input face each polygon came from (to carry its material), in increasing order.
    """
    counts = np.asarray(counts, dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    pieces: list[tuple[np.ndarray, np.ndarray]] = []  # (polygons, face id)
    for n in np.unique(counts):
        ids = np.flatnonzero(counts == n)
        f = flat[starts[ids][:, None] + np.arange(n)]
        if n == 3:
            pieces.append((np.column_stack([f, np.full(len(f), -1)]), ids))
            continue
        good = convex_planar(vertices, f, diag, strict=n <= FAN_MAX_CORNERS)
        if n == 4:
            pieces.append((f[good], ids[good]))
            bad, bad_ids = f[~good], ids[~good]
            # the diagonal must pass through a reflex corner, if there is one: the turn at
            # corner 1 or 3 being the smallest means split along 1–3
            p = vertices[bad]
            e = np.roll(p, -1, axis=1) - p
            nv = newell_normal(vertices, bad)
            turn = np.einsum("kij,kj->ki", np.cross(np.roll(e, 1, axis=1), e), nv)
            via13 = np.isin(np.argmin(turn, axis=1), (1, 3))
            r = np.where(via13[:, None], np.roll(bad, -1, axis=1), bad)
            t1 = np.column_stack([r[:, 0], r[:, 1], r[:, 2], np.full(len(r), -1)])
            t2 = np.column_stack([r[:, 0], r[:, 2], r[:, 3], np.full(len(r), -1)])
            pieces.append((np.stack([t1, t2], axis=1).reshape(-1, 4), np.repeat(bad_ids, 2)))
            continue
        if n > FAN_MAX_CORNERS:
            for face, fid in zip(f[good], ids[good], strict=True):
                tris = _ear_strips(face)
                pieces.append((np.column_stack([tris, np.full(len(tris), -1)]),
                               np.full(len(tris), fid)))
        fan_f, fan_ids = (f[good], ids[good]) if n <= FAN_MAX_CORNERS else (f[:0], ids[:0])
        j = np.arange(1, n - 1)
        fan = np.stack(
            [np.repeat(fan_f[:, :1], n - 2, axis=1), fan_f[:, j], fan_f[:, j + 1]], axis=2
        )
        fan = np.concatenate([fan, np.full(fan.shape[:2] + (1,), -1)], axis=2)
        pieces.append((fan.reshape(-1, 4), np.repeat(fan_ids, n - 2)))
        if n > MAX_CLIPPED_CORNERS and not good.all():
            fid = int(ids[~good][0])
            raise SceneError(
                f"face {fid + 1} has {n} corners and is not planar and convex: more than "
                f"{MAX_CLIPPED_CORNERS} corners are only triangulated for convex planar faces; "
                "split it into smaller faces", path)
        for face, fid in zip(f[~good], ids[~good], strict=True):
            tris = _ear_clip(vertices, face, diag)
            tris4 = np.column_stack([tris, np.full(len(tris), -1)])
            pieces.append((tris4, np.full(len(tris), fid)))
    if not pieces:
        return np.zeros((0, 4), np.int32), np.zeros(0, np.int64)
    polys = np.concatenate([p for p, _ in pieces]).astype(np.int32)
    face = np.concatenate([i for _, i in pieces]).astype(np.int64)
    order = np.argsort(face, kind="stable")
    return polys[order], face[order]


def pair_triangles(vertices: np.ndarray, tris: np.ndarray, diag: float) -> np.ndarray:
    """Recover quads from consecutive triangle pairs, as trimesh's loaders leave them.

    trimesh splits a quad ``(a, b, c, d)`` into ``(a, b, c), (c, d, a)`` (PLY, OBJ) and a fan
    gives ``(a, b, c), (a, c, d)``; both halves stay next to each other. A pair is merged when it
    matches one of these patterns and the quad ``(a, b, c, d)`` is planar and convex (so the
    merged quad covers exactly the two triangles, with their winding). Pairs never overlap:
    inside a run of mergeable neighbours every other one is taken.

    Parameters
    ----------
    vertices : (V, 3) float64
    tris : (T, 3) int
    diag : float

    Returns
    -------
    (Q, 4) int32, ``-1`` in column 3 for the triangles left alone; order follows ``tris``.
    """
    tris = np.asarray(tris, dtype=np.int64)
    t = len(tris)
    out_tri = np.column_stack([tris, np.full(t, -1)]).astype(np.int32)
    if t < 2:
        return out_tri
    x, y = tris[:-1], tris[1:]
    # pattern (a,b,c),(c,d,a): quad a b c d with d = y[1]
    p1 = (y[:, 0] == x[:, 2]) & (y[:, 2] == x[:, 0])
    # pattern (a,b,c),(a,c,d): quad a b c d with d = y[2]
    p2 = (y[:, 0] == x[:, 0]) & (y[:, 1] == x[:, 2])
    d = np.where(p1, y[:, 1], y[:, 2])
    quads = np.column_stack([x, d])
    ok = p1 | p2
    ok &= (quads[:, 3] != quads[:, 0]) & (quads[:, 3] != quads[:, 1]) & (quads[:, 3] != quads[:, 2])
    ok[ok] = convex_planar(vertices, quads[ok], diag)
    # runs of True in ok: take offsets 0, 2, 4, ... from the start of each run
    idx = np.arange(len(ok))
    run_start = np.maximum.accumulate(np.where(~ok, idx + 1, 0))
    take = ok & ((idx - run_start) % 2 == 0)
    first = np.flatnonzero(take)
    keep = np.ones(t, dtype=bool)
    keep[first + 1] = False
    out = out_tri.copy()
    out[first] = quads[first]
    return out[keep]


def pair_coplanar(vertices: np.ndarray, polygons: np.ndarray, material: np.ndarray,
                  diag: float) -> tuple[np.ndarray, np.ndarray]:
    """Merge triangles back into convex quads whatever the order and split of the file.

    Two triangles of one material sharing an edge in opposite directions (so consistently
    wound) are merged when the quad they make is planar and convex
    (:func:`convex_planar`). Each triangle joins at most one quad, chosen greedily: first
    pairs whose shared edge is the longest edge of both triangles (the diagonal of a split
    rectangle or parallelogram), then the others, each group in order of the first triangle.
    The result does not depend on where the triangles sit in the file (issue 16 item 6:
    :func:`pair_triangles` only finds the halves its neighbours left side by side).

    Parameters
    ----------
    vertices : (V, 3) float64
    polygons : (Q, 4) int, ``-1`` in column 3 for triangles (quads are left alone)
    material : (Q,) int
    diag : float

    Returns
    -------
    polygons : (Q', 4) int32, the merged quad in place of its first triangle
    keep : (Q,) bool, the rows of the input that remain (to carry per-polygon data)
    """
    polygons = np.asarray(polygons, dtype=np.int64)
    material = np.asarray(material)
    keep = np.ones(len(polygons), dtype=bool)
    tri_rows = np.flatnonzero(polygons[:, 3] < 0)
    if len(tri_rows) < 2:
        return polygons.astype(np.int32), keep
    t = polygons[tri_rows, :3]
    nv = len(vertices)
    # directed edges k: (t[k], t[k+1]) for k = 0, 1, 2; the edge opposite corner (k + 2) % 3
    a = t.reshape(-1)
    b = np.roll(t, -1, axis=1).reshape(-1)
    owner = np.repeat(np.arange(len(t)), 3)
    fwd = a * nv + b
    order = np.argsort(fwd, kind="stable")
    sorted_fwd = fwd[order]
    unique_edge = np.ones(len(fwd), bool)
    dup = sorted_fwd[1:] == sorted_fwd[:-1]
    unique_edge[order[1:][dup]] = False
    unique_edge[order[:-1][dup]] = False
    rev = b * nv + a
    pos = np.searchsorted(sorted_fwd, rev)
    pos = np.minimum(pos, len(sorted_fwd) - 1)
    found = (sorted_fwd[pos] == rev) & unique_edge
    other = np.where(found, order[pos], -1)
    found &= other >= 0
    found &= unique_edge[np.maximum(other, 0)]
    e = np.flatnonzero(found & (owner < owner[np.maximum(other, 0)]))
    f = other[e]
    ti, ui = owner[e], owner[f]
    same = material[tri_rows[ti]] == material[tri_rows[ui]]
    e, f, ti, ui = e[same], f[same], ti[same], ui[same]
    # quad (x, y, w, z): t = (x, y, z) with the shared edge y -> z, w the far corner of u
    k = e % 3
    y, z = a[e], b[e]
    x = t[ti, (k + 2) % 3]
    w = t[ui, (f % 3 + 2) % 3]
    quads = np.column_stack([x, y, w, z])
    ok = convex_planar(vertices, quads, diag)
    e, f, ti, ui, quads = e[ok], f[ok], ti[ok], ui[ok], quads[ok]
    if len(e) == 0:
        return polygons.astype(np.int32), keep
    # priority 0 when the shared edge is the longest edge of both triangles
    length = np.linalg.norm(vertices[b] - vertices[a], axis=1).reshape(-1, 3)
    longest_t = length[ti, e % 3] >= length[ti].max(axis=1)
    longest_u = length[ui, f % 3] >= length[ui].max(axis=1)
    priority = np.where(longest_t & longest_u, 0, 1)
    ranking = np.lexsort((ui, ti, priority))
    used = np.zeros(len(t), bool)
    out = polygons.copy()
    for r in ranking:
        i, j = ti[r], ui[r]
        if used[i] or used[j]:
            continue
        used[i] = used[j] = True
        out[tri_rows[i]] = quads[r]
        keep[tri_rows[j]] = False
    return out[keep].astype(np.int32), keep
