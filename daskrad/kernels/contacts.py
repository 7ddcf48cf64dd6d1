"""Contact edges: edges of one polygon lying in another's plane, on its lit side (issue 14)."""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit


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
    caller. Cost: ``Q · K`` bounding-box tests.
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
    for i in range(q):
        n = normals[i]
        if not n[0] * n[0] + n[1] * n[1] + n[2] * n[2] > 0.5:
            continue  # a degenerate polygon (no normal) has no plane
        for e in range(k):
            j = edge_owner[e]
            if j == i:
                continue
            a = edge_a[e]
            b = edge_b[e]
            inside = True
            for d in range(3):
                if (max(a[d], b[d]) < lo[i, d] or min(a[d], b[d]) > hi[i, d]):
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
