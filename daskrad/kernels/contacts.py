"""Contact edges: edges of one polygon lying in another's plane, on its lit side (issue 14)."""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf

#: Cells per edge of the uniform grid that :func:`contact_edges` bins the edges in. The grid
#: only prunes the exact box test; the answer does not depend on it. Kernel CPU seconds at
#: 0.25 / 1 / 4 cells per edge: graz.mgf (54k edges) 0.22 / 0.15 / 0.10, graz.obj (109k)
#: 0.64 / 0.44 / 0.35, classroom.mgf (21k) 0.03 / 0.02 / 0.02 (all edges against all
#: polygons: 19 s on graz.mgf); 1 keeps the grid about as large as the edge list.
CELLS_PER_EDGE = 1.0


@jit_leaf
def _cell(x, origin, size, n):
    """The cell along one axis holding coordinate ``x``, clipped to ``[0, n)``: monotone in
    ``x``, so two intervals that overlap share a cell."""
    c = np.floor((x - origin) / size)
    if c < 0.0:
        return 0
    if c >= n:
        return n - 1
    return int(c)


@jit
def _edge_grid(elo, ehi, cells_per_edge):
    """Edge ids binned by bounding box in a uniform grid over all the edges.

    Returns ``(origin (3,), size (3,), dims (3,) int64, start (C + 1,) int64, items int64)``:
    the edges whose box meets cell ``c = (z * ny + y) * nx + x`` are
    ``items[start[c]:start[c + 1]]``. An axis along which the edges have no extent gets one
    cell.
    """
    k = elo.shape[0]
    origin = np.empty(3)
    size = np.ones(3)
    dims = np.ones(3, np.int64)
    extent = np.empty(3)
    for d in range(3):
        origin[d] = np.inf
        top = -np.inf
        for e in range(k):
            origin[d] = min(origin[d], elo[e, d])
            top = max(top, ehi[e, d])
        extent[d] = top - origin[d]
    # cubic cells, about cells_per_edge · k of them over the axes with an extent
    volume = 1.0
    spread = 0
    for d in range(3):
        if extent[d] > 0.0:
            volume *= extent[d]
            spread += 1
    if spread > 0:
        side = (volume / max(1.0, cells_per_edge * k)) ** (1.0 / spread)
        for d in range(3):
            if extent[d] > 0.0:
                dims[d] = max(1, min(512, int(extent[d] / side)))
                size[d] = extent[d] / dims[d]
    cells = np.empty((k, 6), np.int64)     # x0 x1 y0 y1 z0 z1: the cells of each edge's box
    for e in range(k):
        for d in range(3):
            cells[e, 2 * d] = _cell(elo[e, d], origin[d], size[d], dims[d])
            cells[e, 2 * d + 1] = _cell(ehi[e, d], origin[d], size[d], dims[d])
    nx, ny = dims[0], dims[1]
    start = np.zeros(dims[0] * dims[1] * dims[2] + 1, np.int64)
    for e in range(k):
        for z in range(cells[e, 4], cells[e, 5] + 1):
            for y in range(cells[e, 2], cells[e, 3] + 1):
                for x in range(cells[e, 0], cells[e, 1] + 1):
                    start[(z * ny + y) * nx + x + 1] += 1
    for c in range(1, start.shape[0]):
        start[c] += start[c - 1]
    items = np.empty(start[-1], np.int64)
    fill = start[:-1].copy()
    for e in range(k):        # edges in increasing order, so each cell's list is sorted
        for z in range(cells[e, 4], cells[e, 5] + 1):
            for y in range(cells[e, 2], cells[e, 3] + 1):
                for x in range(cells[e, 0], cells[e, 1] + 1):
                    c = (z * ny + y) * nx + x
                    items[fill[c]] = e
                    fill[c] += 1
    return origin, size, dims, start, items


@jit
def contact_edges(corners, is_quad, normals, edge_a, edge_b, edge_owner, tol):
    """``(N, 2) int64`` pairs ``(polygon, edge)``: the edge lies in the polygon's plane.

    Parameters
    ----------
    corners : (Q, 4, 3) float64
        Polygon corners (a triangle repeats c2 as c3); ``is_quad (Q,) bool``.
    normals : (Q, 3) float64, unit
    edge_a, edge_b : (K, 3) float64, edge_owner : (K,) int64
        Every polygon edge and its polygon.
    tol : float
        A length: both ends within ``tol`` of the plane, the bounding boxes overlapping by
        ``tol``.

    An edge counts when its polygon is not parallel to the plane (``|n·n'| < 1 − 1e-6``) and
    rises more than ``tol`` on the plane's lit side (a block standing on the floor, not one
    hanging under it). Whether the edge runs through the polygon's interior is left to the
    caller. Pairs come polygon by polygon, edges increasing.

    Cost: the edges are binned in a uniform grid (:func:`_edge_grid`), and each polygon tests
    only the edges of the cells its box meets: every edge whose box overlaps the polygon's
    shares a cell with it, so the pairs are those of testing all ``Q · K`` boxes.
    """
    q = corners.shape[0]
    k = edge_a.shape[0]
    lo = np.empty((q, 3))
    hi = np.empty((q, 3))
    off = np.empty(q)
    for i in range(q):
        for d in range(3):
            lo[i, d] = min(corners[i, 0, d], corners[i, 1, d], corners[i, 2, d],
                           corners[i, 3, d]) - tol
            hi[i, d] = max(corners[i, 0, d], corners[i, 1, d], corners[i, 2, d],
                           corners[i, 3, d]) + tol
        off[i] = (normals[i, 0] * corners[i, 0, 0] + normals[i, 1] * corners[i, 0, 1]
                  + normals[i, 2] * corners[i, 0, 2])
    buf = np.empty((64, 2), np.int64)
    m = 0
    if k == 0:
        return buf[:0].copy()
    elo = np.empty((k, 3))
    ehi = np.empty((k, 3))
    for e in range(k):
        for d in range(3):
            elo[e, d] = min(edge_a[e, d], edge_b[e, d])
            ehi[e, d] = max(edge_a[e, d], edge_b[e, d])
    origin, size, dims, start, items = _edge_grid(elo, ehi, CELLS_PER_EDGE)
    nx, ny = dims[0], dims[1]
    seen = -np.ones(k, np.int64)     # the last polygon that gathered the edge
    near = np.empty(k, np.int64)
    for i in range(q):
        n = normals[i]
        if not n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0.5:
            continue  # a degenerate polygon (no normal) has no plane
        count = 0
        x0 = _cell(lo[i, 0], origin[0], size[0], dims[0])
        x1 = _cell(hi[i, 0], origin[0], size[0], dims[0])
        y0 = _cell(lo[i, 1], origin[1], size[1], dims[1])
        y1 = _cell(hi[i, 1], origin[1], size[1], dims[1])
        z0 = _cell(lo[i, 2], origin[2], size[2], dims[2])
        z1 = _cell(hi[i, 2], origin[2], size[2], dims[2])
        for z in range(z0, z1 + 1):
            for y in range(y0, y1 + 1):
                for x in range(x0, x1 + 1):
                    c = (z * ny + y) * nx + x
                    for t in range(start[c], start[c + 1]):
                        e = items[t]
                        if seen[e] != i:
                            seen[e] = i
                            near[count] = e
                            count += 1
        near[:count].sort()     # the pairs in the order of a loop over all edges
        for t in range(count):
            e = near[t]
            j = edge_owner[e]
            if j == i:
                continue
            a = edge_a[e]
            b = edge_b[e]
            inside = True
            for d in range(3):
                if ehi[e, d] < lo[i, d] or elo[e, d] > hi[i, d]:
                    inside = False
            if not inside:
                continue
            da = n[0] * a[0] + n[1] * a[1] + n[2] * a[2] - off[i]
            db = n[0] * b[0] + n[1] * b[1] + n[2] * b[2] - off[i]
            if abs(da) > tol or abs(db) > tol:
                continue
            nn = n[0] * normals[j, 0] + n[1] * normals[j, 1] + n[2] * normals[j, 2]
            if abs(nn) >= 1.0 - 1e-6:
                continue
            top = -np.inf
            for c in range(4 if is_quad[j] else 3):
                h = (n[0] * corners[j, c, 0] + n[1] * corners[j, c, 1]
                     + n[2] * corners[j, c, 2] - off[i])
                top = max(top, h)
            if top <= tol:
                continue
            if m == buf.shape[0]:
                bigger = np.empty((2 * m, 2), np.int64)
                bigger[:m] = buf
                buf = bigger
            buf[m, 0] = i
            buf[m, 1] = e
            m += 1
    return buf[:m].copy()


@jit_leaf
def _side(p, m, c):
    """``m · p − c``: the signed distance of point ``p (3,)`` from the plane ``m · x = c``."""
    return p[0] * m[0] + p[1] * m[1] + p[2] * m[2] - c


@jit_leaf
def _crosses(piece, k, n, a, b, tol):
    """Whether the segment ``ab`` runs through the interior of the convex ``piece[:k]``
    (normal ``n``) for more than ``tol`` (Cyrus–Beck clipping against the piece's edges)."""
    t0 = 0.0
    t1 = 1.0
    dx = b[0] - a[0]
    dy = b[1] - a[1]
    dz = b[2] - a[2]
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        ex = piece[j, 0] - piece[i, 0]
        ey = piece[j, 1] - piece[i, 1]
        ez = piece[j, 2] - piece[i, 2]
        ix = n[1] * ez - n[2] * ey          # n × e: the edge's inward normal (unnormalised)
        iy = n[2] * ex - n[0] * ez
        iz = n[0] * ey - n[1] * ex
        length = np.sqrt(ix * ix + iy * iy + iz * iz)
        if length == 0.0:
            continue
        ix /= length
        iy /= length
        iz /= length
        num = ((a[0] - piece[i, 0]) * ix + (a[1] - piece[i, 1]) * iy
               + (a[2] - piece[i, 2]) * iz) - tol     # strictly inside, by tol
        den = dx * ix + dy * iy + dz * iz
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
    return (t1 - t0) * np.sqrt(dx * dx + dy * dy + dz * dz) > tol


@jit
def _cut(piece, k, s, tol, pos, neg):
    """``piece[:k]`` cut by a plane into ``pos`` and ``neg`` (order kept), ``s[:k]`` its
    corners' signed distances from the plane; returns the parts' corner counts."""
    n_pos = 0
    n_neg = 0
    for i in range(k):
        j = i + 1 if i + 1 < k else 0
        si = s[i]
        sj = s[j]
        if si >= -tol:
            pos[n_pos] = piece[i]
            n_pos += 1
        if si <= tol:
            neg[n_neg] = piece[i]
            n_neg += 1
        if (si > tol and sj < -tol) or (si < -tol and sj > tol):
            w = si / (si - sj)
            for x in range(3):
                v = piece[i, x] + w * (piece[j, x] - piece[i, x])
                pos[n_pos, x] = v
                neg[n_neg, x] = v
            n_pos += 1
            n_neg += 1
    return n_pos, n_neg


@jit_leaf
def _keep(f, quad, n, area_tol):
    """Whether the fanned quad (or triangle) ``f (4, 3)`` is more than a sliver: its area
    along ``n`` above ``area_tol`` (a cut line grazing a corner leaves slivers)."""
    if quad:
        ux, uy, uz = f[2, 0] - f[0, 0], f[2, 1] - f[0, 1], f[2, 2] - f[0, 2]
        vx, vy, vz = f[3, 0] - f[1, 0], f[3, 1] - f[1, 1], f[3, 2] - f[1, 2]
    else:
        ux, uy, uz = f[1, 0] - f[0, 0], f[1, 1] - f[0, 1], f[1, 2] - f[0, 2]
        vx, vy, vz = f[2, 0] - f[0, 0], f[2, 1] - f[0, 1], f[2, 2] - f[0, 2]
    wx = uy * vz - uz * vy
    wy = uz * vx - ux * vz
    wz = ux * vy - uy * vx
    return not 0.5 * abs(wx * n[0] + wy * n[1] + wz * n[2]) <= area_tol


@jit
def _emit(out_c, out_q, out_p, n_out, f, quad, parent):
    """Append the piece ``f (4, 3)`` to the outputs (doubled when full); returns them."""
    if n_out == out_c.shape[0]:
        grown = np.empty((2 * n_out + 16, 4, 3))
        grown[:n_out] = out_c[:n_out]
        out_c = grown
        gq = np.empty(2 * n_out + 16, np.bool_)
        gq[:n_out] = out_q[:n_out]
        out_q = gq
        gp = np.empty(2 * n_out + 16, np.int64)
        gp[:n_out] = out_p[:n_out]
        out_p = gp
    out_c[n_out] = f
    out_q[n_out] = quad
    out_p[n_out] = parent
    return out_c, out_q, out_p


@jit
def _fan_out(piece, k, n, area_tol, parent, out_c, out_q, out_p, n_out):
    """The convex ``piece[:k]`` appended as convex quads in its winding, slivers dropped:
    fanned from corner 0 into quads; a triangle left over is cut into three quads at its
    centroid and edge midpoints (the mesher gives a triangle of longest edge ``L``
    ``⌈L / patch size⌉²`` patches, which for the long thin triangles a cut leaves behind is
    many times their area's worth; its three quads get about a third of the count)."""
    f = np.empty((4, 3))
    i = 1
    while i + 2 < k:
        f[0] = piece[0]
        f[1] = piece[i]
        f[2] = piece[i + 1]
        f[3] = piece[i + 2]
        quad = not (f[3, 0] == f[2, 0] and f[3, 1] == f[2, 1] and f[3, 2] == f[2, 2])
        if _keep(f, quad, n, area_tol):
            out_c, out_q, out_p = _emit(out_c, out_q, out_p, n_out, f, quad, parent)
            n_out += 1
        i += 2
    if i + 1 < k:
        a = piece[0]
        b = piece[i]
        c = piece[i + 1]
        for q in range(3):
            for x in range(3):
                g = (a[x] + b[x] + c[x]) / 3.0
                ab = 0.5 * (a[x] + b[x])
                bc = 0.5 * (b[x] + c[x])
                ca = 0.5 * (c[x] + a[x])
                if q == 0:
                    f[0, x], f[1, x], f[2, x], f[3, x] = a[x], ab, g, ca
                elif q == 1:
                    f[0, x], f[1, x], f[2, x], f[3, x] = b[x], bc, g, ab
                else:
                    f[0, x], f[1, x], f[2, x], f[3, x] = c[x], ca, g, bc
            quad = not (f[3, 0] == f[2, 0] and f[3, 1] == f[2, 1] and f[3, 2] == f[2, 2])
            if _keep(f, quad, n, area_tol):
                out_c, out_q, out_p = _emit(out_c, out_q, out_p, n_out, f, quad, parent)
                n_out += 1
    return out_c, out_q, out_p, n_out


@jit
def cut_polygons(corners, is_quad, normals, edge_a, edge_b, start, edges, tol):
    """Polygons cut along their contact edges, BSP-fashion, into convex quads.

    Parameters
    ----------
    corners : (Q, 4, 3) float64
        Polygon corners (a triangle repeats c2 as c3), wound counter-clockwise about
        ``normals (Q, 3)`` (unit); ``is_quad (Q,) bool``.
    edge_a, edge_b : (K, 3) float64
        The edges' end points.
    start : (Q + 1,) int64, edges : (P,) int64
        Polygon ``i``'s contact edges are ``edges[start[i]:start[i + 1]]``, in the order they
        cut it.
    tol : float
        Length tolerance: a piece is cut only where the edge's line leaves more than ``tol``
        on both sides and the edge runs through its interior for more than ``tol``; pieces of
        area at most ``tol²`` are dropped.

    Returns ``(corners (Q', 4, 3), is_quad (Q',), parent (Q',) int64)``: an uncut polygon
    (no contact edge, or none that cuts it) is its own row, unchanged; a cut one is its
    pieces fanned into quads (a quad repeating its third corner is a triangle).
    """
    q = corners.shape[0]
    cap = q + 16
    out_c = np.empty((cap, 4, 3))
    out_q = np.empty(cap, np.bool_)
    out_p = np.empty(cap, np.int64)
    n_out = 0
    area_tol = tol * tol
    m = np.empty(3)
    for i in range(q):
        ne = start[i + 1] - start[i]
        k0 = 4 if is_quad[i] else 3
        if ne > 0:
            n = normals[i]
            # each cut adds at most one corner to a part: a piece is cut only where the edge
            # runs through its interior (_crosses), so the line meets its boundary twice
            kmax = k0 + ne
            side = np.empty(kmax)   # a piece's corners' signed distances from the edge's line
            pieces = np.empty((1, kmax, 3))
            counts = np.empty(1, np.int64)
            pieces[0, :k0] = corners[i, :k0]
            counts[0] = k0
            n_p = 1
            for s in range(start[i], start[i + 1]):
                e = edges[s]
                dx = edge_b[e, 0] - edge_a[e, 0]
                dy = edge_b[e, 1] - edge_a[e, 1]
                dz = edge_b[e, 2] - edge_a[e, 2]
                m[0] = n[1] * dz - n[2] * dy
                m[1] = n[2] * dx - n[0] * dz
                m[2] = n[0] * dy - n[1] * dx
                length = np.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
                if length == 0.0:
                    continue
                m /= length
                c = m[0] * edge_a[e, 0] + m[1] * edge_a[e, 1] + m[2] * edge_a[e, 2]
                # the pieces after this edge, in order: each cut piece replaced by its
                # positive part then its negative one (the order they are fanned in below)
                nxt = np.empty((2 * n_p, kmax, 3))
                nxt_counts = np.empty(2 * n_p, np.int64)
                n_next = 0
                for p in range(n_p):
                    k = counts[p]
                    lo = np.inf
                    hi = -np.inf
                    for v in range(k):
                        side[v] = _side(pieces[p, v], m, c)
                        lo = min(lo, side[v])
                        hi = max(hi, side[v])
                    if (hi > tol and lo < -tol
                            and _crosses(pieces[p], k, n, edge_a[e], edge_b[e], tol)):
                        nxt_counts[n_next], nxt_counts[n_next + 1] = _cut(
                            pieces[p], k, side, tol, nxt[n_next], nxt[n_next + 1])
                        n_next += 2
                    else:
                        nxt[n_next, :k] = pieces[p, :k]
                        nxt_counts[n_next] = k
                        n_next += 1
                pieces = nxt
                counts = nxt_counts
                n_p = n_next
            if n_p > 1:
                for p in range(n_p):
                    out_c, out_q, out_p, n_out = _fan_out(pieces[p], counts[p], n, area_tol,
                                                          i, out_c, out_q, out_p, n_out)
                continue
        out_c, out_q, out_p = _emit(out_c, out_q, out_p, n_out, corners[i], is_quad[i], i)
        n_out += 1
    return out_c[:n_out].copy(), out_q[:n_out].copy(), out_p[:n_out].copy()
