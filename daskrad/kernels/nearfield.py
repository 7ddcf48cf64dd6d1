"""The near-field correction of a shooter's form-factor row (docs/design.md §2).

A receiver element near the shooting patch sees the patch under a large angle, and the factor
from one point of the patch (or a few) to it is not the factor from the whole patch: the row
gives it ``F_ij`` from the point, while the patch's light reaches it from the whole of its
area. :func:`near_field` replaces the near receivers' factors by reciprocity from ``F_ji``,
each receiver's exact unoccluded factor to the whole patch (Lambert's contour integral,
averaged over the receiver where it is close, :func:`receiver_factors`), times the visible
fraction the raster measured, and rescales them to the share of the row they had (the
shot's power is conserved).

One kernel for what was a dozen numpy operations a row under the GIL (the Cornell box's
one-point rows, ~525 near receivers each, 3.2 → 2.3 ms on one thread), so threads and Dask
workers run it side by side. Pure: the same bits for a row wherever it is computed. Against
the numpy formulas it replaces (tests/test_penumbra.py) it differs by round-off only: it sums
in order where numpy summed pairwise, and takes the element normals as stored where
``analytic_rows`` renormalised them (1.3e-16 on the Cornell box, 1.8e-14 on a triangle soup).
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.geometry import element_planes
from daskrad.kernels.lambert import lambert_into


@jit_leaf
def _corners(vertices, verts, out):
    """The polygon ``verts (4,) int`` (``-1`` fourth for a triangle) as ``out (4, 3)``;
    returns its corner count."""
    k = 4 if verts[3] >= 0 else 3
    for c in range(k):
        for a in range(3):
            out[c, a] = vertices[verts[c], a]
    return k


@jit_leaf
def _one_sided(px, py, pz, nx, ny, nz, plane_n, plane_d, corners, count, sc):
    """Lambert's factor from ``(p, n)`` to a one-sided polygon with the plane
    ``plane_n · x = plane_d`` (0 where ``p`` is not strictly on its lit side), as
    :func:`daskrad.kernels.lambert.lambert_shots` gives it."""
    if plane_n[0] * px + plane_n[1] * py + plane_n[2] * pz - plane_d <= 0.0:
        return 0.0
    return lambert_into(px, py, pz, nx, ny, nz, corners, count, sc)


@jit
def receiver_factors(vertices, elem_verts, elem_centroid, elem_normal, elem_area, ids,
                     shooter, centroid, normal, radius, close, bary):
    """``(k,) float64``: ``F_ji`` from each receiver element ``ids (k,)`` to the whole
    shooter polygon ``shooter (4,) int32`` (no occlusion), averaged over the receiver's area.

    ``F_ji = (1/A_j) ∫_{A_j} F(x → i) dx``. Far from the shooter the centroid is enough; a
    receiver within ``close`` of its own size ``√A_j`` of the shooter (the lower bound
    ``max(|rel · n_i|, |rel| − radius)`` of the distance from its centroid, ``rel`` from the
    shooter's ``centroid``) takes the mean over ``bary (s, 3)`` barycentric points of each of
    its triangles (a quad is two, halves ``(0, 1, 2)`` and ``(0, 2, 3)``), weighted by their
    areas: there ``F(x → i)`` varies over the receiver as fast as the distance does.
    """
    k = ids.shape[0]
    out = np.zeros(k)
    sv = np.empty((1, 4), np.int32)
    for a in range(4):
        sv[0, a] = shooter[a]
    plane_n, plane_d = element_planes(vertices, sv)
    pn = plane_n[0]
    pd = plane_d[0]
    corners = np.empty((4, 3))
    count = _corners(vertices, shooter, corners)
    sc = np.empty((7, 5))
    quad = np.empty((4, 3))
    pt = np.empty(3)
    halves = ((0, 1, 2), (0, 2, 3))
    for m in range(k):
        e = ids[m]
        c = elem_centroid[e]
        nrm = elem_normal[e]
        rx = c[0] - centroid[0]
        ry = c[1] - centroid[1]
        rz = c[2] - centroid[2]
        dist = max(abs(rx * normal[0] + ry * normal[1] + rz * normal[2]),
                   np.sqrt(rx * rx + ry * ry + rz * rz) - radius)
        if not dist < close * np.sqrt(elem_area[e]):
            out[m] = _one_sided(c[0], c[1], c[2], nrm[0], nrm[1], nrm[2], pn, pd, corners,
                                count, sc)
            continue
        if _corners(vertices, elem_verts[e], quad) == 3:
            quad[3, :] = quad[2, :]     # a triangle's second half (0, 2, 3) is empty
        num = 0.0
        den = 0.0
        for h in range(2):
            i0, i1, i2 = halves[h]
            ux = quad[i1, 0] - quad[i0, 0]
            uy = quad[i1, 1] - quad[i0, 1]
            uz = quad[i1, 2] - quad[i0, 2]
            wx = quad[i2, 0] - quad[i0, 0]
            wy = quad[i2, 1] - quad[i0, 1]
            wz = quad[i2, 2] - quad[i0, 2]
            gx = uy * wz - uz * wy
            gy = uz * wx - ux * wz
            gz = ux * wy - uy * wx
            area = 0.5 * np.sqrt(gx * gx + gy * gy + gz * gz)
            f = 0.0
            for s in range(bary.shape[0]):
                for a in range(3):
                    pt[a] = (bary[s, 0] * quad[i0, a] + bary[s, 1] * quad[i1, a]
                             + bary[s, 2] * quad[i2, a])
                f += _one_sided(pt[0], pt[1], pt[2], nrm[0], nrm[1], nrm[2], pn, pd,
                                corners, count, sc)
            num += f / bary.shape[0] * area
            den += area
        out[m] = num / den if den > 0.0 else 0.0
    return out


@jit
def near_field(row, points, weights, vertices, elem_verts, elem_centroid, elem_normal,
               elem_area, elem_polygon, shooter, centroid, normal, radius, area, polygon,
               reach, close, bary):
    """Correct ``row (E,) float64``, the factors from ``points (S, 3)`` (weights ``(S,)``,
    summing to 1; unit ``normal (3,)``) of the shooting patch, in place, for its near
    receivers; returns how many there were.

    The near receivers are the elements ``j`` with ``F_ij > 0``, their centroid within
    ``reach`` (a length) of the patch's ``centroid``, and not on the patch's own ``polygon``.
    Each gets ``F_ij ∝ F_ji · A_j / A_i · visible_j`` (reciprocity, ``A_i`` the patch's
    ``area``), ``F_ji`` from :func:`receiver_factors` (``shooter``, ``radius``, ``close``,
    ``bary`` as there) and ``visible_j`` the method's own visibility: the row's factor over
    the unoccluded one from the same points (for several points, the ratio of the weighted
    means, a point behind the receiver's plane adding nothing to either), in ``[0, 1]``, 1
    where the unoccluded factor is 0. Scaled so that they keep the sum they had (when any is
    positive).
    """
    n_elem = row.shape[0]
    if not area > 0.0:          # no patch of a mesh; a context made by hand is left as it is
        return 0
    reach2 = reach * reach
    ids = np.empty(n_elem, np.int64)
    k = 0
    for e in range(n_elem):
        if row[e] > 0.0 and elem_polygon[e] != polygon:
            dx = elem_centroid[e, 0] - centroid[0]
            dy = elem_centroid[e, 1] - centroid[1]
            dz = elem_centroid[e, 2] - centroid[2]
            if dx * dx + dy * dy + dz * dz < reach2:
                ids[k] = e
                k += 1
    if k == 0:
        return 0
    ids = ids[:k]
    ev = np.empty((k, 4), np.int32)
    for m in range(k):
        for a in range(4):
            ev[m, a] = elem_verts[ids[m], a]
    plane_n, plane_d = element_planes(vertices, ev)
    corners = np.empty((4, 3))
    sc = np.empty((7, 5))
    n_pts = points.shape[0]
    F_ji = receiver_factors(vertices, elem_verts, elem_centroid, elem_normal, elem_area, ids,
                            shooter, centroid, normal, radius, close, bary)
    exact = np.empty(k)
    share = 0.0
    total = 0.0
    for m in range(k):
        e = ids[m]
        count = _corners(vertices, ev[m], corners)
        seen = 0.0
        for s in range(n_pts):
            f = _one_sided(points[s, 0], points[s, 1], points[s, 2], normal[0], normal[1],
                           normal[2], plane_n[m], plane_d[m], corners, count, sc)
            seen += weights[s] * max(f, 0.0) if n_pts > 1 else f
        visible = 1.0
        if seen > 0.0:
            visible = min(max(row[e] / seen, 0.0), 1.0)
        exact[m] = F_ji[m] * elem_area[e] / area * visible
        share += row[e]
        total += exact[m]
    if total > 0.0:
        scale = share / total
        for m in range(k):
            row[ids[m]] = exact[m] * scale
    return k
