"""Contact edges: edges of one polygon lying in another's plane, on its lit side (issue 14)."""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit

#: Cells per edge of the uniform grid that :func:`contact_edges` bins the edges in. The grid
#: only prunes the exact box test; the answer does not depend on it. Kernel CPU seconds at
#: 0.25 / 1 / 4 cells per edge: graz.mgf (54k edges) 0.22 / 0.15 / 0.10, graz.obj (109k)
#: 0.64 / 0.44 / 0.35, classroom.mgf (21k) 0.03 / 0.02 / 0.02 (all edges against all
#: polygons: 19 s on graz.mgf); 1 keeps the grid about as large as the edge list.
CELLS_PER_EDGE = 1.0


@jit
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
