"""The scanline variant of the hemisphere-base form factor (Doi, eq. 8; docs/design.md §2).

Each element is culled, clipped, edge-split and projected onto the base disc exactly as for the
item buffer (:func:`daskrad.kernels.hemisphere.project_element`). Instead of counting pixel
centres, each of ``N`` horizontal scanlines (``y_j = -1 + (2j + 1)/N``) is intersected with every
projected outline: the crossings, sorted and paired (even-odd, as the item buffer fills), give
exact **spans** ``[x_l, x_r)``, clipped to the disc's chord ``|x| < w_j = √(1 - y_j²)``.

Visibility is resolved **per span piece**: on one scanline all span end points are sorted; between
two consecutive end points the set of spans present is constant, and the piece goes to the span
whose element is nearest at the piece's midpoint (exact ``1/t``, or the paper's eq. 5 with
``plane_depth``). Two elements whose planes cross inside one piece (interpenetration) are
resolved at the midpoint only.

Weights (eq. 8): every unit of span length on every scanline weighs the same. The paper's
``Unit = 4/(π · N · 2)`` is replaced by ``1 / Σ_j 2 w_j``, the total chord length, so the whole
disc sums to exactly 1 like the item buffer: ``F_e = (Σ span lengths of e) / Σ_j 2 w_j``. In a
closed scene the pieces of every scanline tile its chord (neighbours share bit-identical
crossings), so each row sums to 1 up to round-off.

Error: in ``x`` the spans are exact (up to the polyline's sagitta, at most ``1 - cos(δ/2)`` for a
piece subtending ``δ``); in ``y`` the area is sampled by the midpoint rule with step ``h = 2/N``,
which errs by at most ``h`` times the total variation of the element's width over ``y`` (twice its
largest width for a convex outline). Small elements still alias in ``y``: an element thinner than
``h`` is either missed or counted with a whole row's height. ``both_axes`` averages the
horizontal and the vertical scanline passes, which halves neither bound but decorrelates the two
sampling errors.
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit
from daskrad.kernels.geometry import element_planes, scene_diagonal
from daskrad.kernels.hemisphere import (
    depth_coefficients,
    edge_capacity,
    in_frame,
    local_frame,
    project_element,
    project_scratch,
    split_table,
)


@jit
def _grow(arr, n):
    """A copy of ``arr`` with twice the capacity (the first ``n`` entries kept)."""
    out = np.empty(2 * arr.shape[0], dtype=arr.dtype)
    out[:n] = arr[:n]
    return out


@jit
def _shoot(sx, sy, sz, snx, sny, snz, vertices, elem_verts, enrm, eoff, hz, n_lines,
           cos_thr, tab, plane_depth, transpose, lx, ly, lz, xs, ys, xcross, coef, out):
    """One scanline pass of one shot; adds ``(span length of e) / Σ chords`` into ``out (E,)``.

    ``transpose`` swaps the roles of ``x`` and ``y`` (vertical scanlines).
    """
    t1x, t1y, t1z, t2x, t2y, t2z = local_frame(sx, sy, sz, snx, sny, snz, vertices, lx, ly, lz)
    yc = np.empty(n_lines)
    half_w = np.empty(n_lines)
    total = 0.0
    for j in range(n_lines):
        yc[j] = -1.0 + (2.0 * j + 1.0) / n_lines
        half_w[j] = np.sqrt(1.0 - yc[j] * yc[j])
        total += 2.0 * half_w[j]
    half_n = 0.5 * n_lines
    cap = 4 * n_lines + 256
    sp_row = np.empty(cap, dtype=np.int32)
    sp_e = np.empty(cap, dtype=np.int32)
    sp_l = np.empty(cap)
    sp_r = np.empty(cap)
    n_sp = 0
    cx, cy, cz, qx, qy, qz, qclip = project_scratch()
    n_elem = elem_verts.shape[0]
    for e in range(n_elem):
        m, mm, c = project_element(e, sx, sy, sz, elem_verts, enrm, eoff, lx, ly, lz, hz,
                                   cos_thr, tab, cx, cy, cz, qx, qy, qz, qclip, xs, ys)
        if mm == 0:
            continue
        nlx, nly, nlz = in_frame(t1x, t1y, t1z, t2x, t2y, t2z, snx, sny, snz, enrm[e, 0],
                                 enrm[e, 1], enrm[e, 2])
        da, db, dc, de = depth_coefficients(plane_depth, qx, qy, qz, m, nlx, nly, nlz, c)
        if transpose:
            for a in range(mm):
                t = xs[a]
                xs[a] = ys[a]
                ys[a] = t
            da, db = db, da
        coef[e, 0] = da
        coef[e, 1] = db
        coef[e, 2] = dc
        coef[e, 3] = de
        ymin = np.inf
        ymax = -np.inf
        for a in range(mm):
            ymin = min(ymin, ys[a])
            ymax = max(ymax, ys[a])
        j0 = max(int(np.ceil((ymin + 1.0) * half_n - 0.5)) - 1, 0)
        j1 = min(int(np.floor((ymax + 1.0) * half_n - 0.5)) + 1, n_lines - 1)
        for j in range(j0, j1 + 1):
            y = yc[j]
            nc = 0
            for a in range(mm):
                b = a + 1 if a + 1 < mm else 0
                ya = ys[a]
                yb = ys[b]
                # crossings from the lower endpoint: bit-identical for a shared edge
                if ya < yb:
                    if ya <= y < yb:
                        xcross[nc] = xs[a] + (y - ya) * (xs[b] - xs[a]) / (yb - ya)
                        nc += 1
                elif yb < ya:
                    if yb <= y < ya:
                        xcross[nc] = xs[b] + (y - yb) * (xs[a] - xs[b]) / (ya - yb)
                        nc += 1
            if nc < 2:
                continue
            for a in range(1, nc):
                x = xcross[a]
                b = a - 1
                while b >= 0 and xcross[b] > x:
                    xcross[b + 1] = xcross[b]
                    b -= 1
                xcross[b + 1] = x
            w = half_w[j]
            for a in range(0, nc - 1, 2):
                xl = max(xcross[a], -w)
                xr = min(xcross[a + 1], w)
                if not xr > xl:
                    continue
                if n_sp == sp_row.shape[0]:
                    sp_row = _grow(sp_row, n_sp)
                    sp_e = _grow(sp_e, n_sp)
                    sp_l = _grow(sp_l, n_sp)
                    sp_r = _grow(sp_r, n_sp)
                sp_row[n_sp] = j
                sp_e[n_sp] = e
                sp_l[n_sp] = xl
                sp_r[n_sp] = xr
                n_sp += 1
    if n_sp == 0:
        return
    # --- spans by scanline (counting sort), then a sweep per scanline ---------------------
    start = np.zeros(n_lines + 1, dtype=np.int64)
    for k in range(n_sp):
        start[sp_row[k] + 1] += 1
    for j in range(n_lines):
        start[j + 1] += start[j]
    order = np.empty(n_sp, dtype=np.int64)
    fill = start[:-1].copy()
    for k in range(n_sp):
        order[fill[sp_row[k]]] = k
        fill[sp_row[k]] += 1
    active = np.empty(n_sp, dtype=np.int64)
    inv_total = 1.0 / total
    for j in range(n_lines):
        k0 = start[j]
        k1 = start[j + 1]
        n = k1 - k0
        if n == 0:
            continue
        ids = order[k0:k1]
        lefts = np.empty(n)
        events = np.empty(2 * n)
        for a in range(n):
            lefts[a] = sp_l[ids[a]]
            events[2 * a] = sp_l[ids[a]]
            events[2 * a + 1] = sp_r[ids[a]]
        by_left = ids[np.argsort(lefts, kind="mergesort")]
        events.sort()
        y = yc[j]
        n_act = 0
        nxt = 0
        for ev in range(2 * n - 1):
            x0 = events[ev]
            x1 = events[ev + 1]
            # enter spans starting at or before x0, drop spans ending at or before x0
            while nxt < n and sp_l[by_left[nxt]] <= x0:
                active[n_act] = by_left[nxt]
                n_act += 1
                nxt += 1
            a = 0
            while a < n_act:
                if sp_r[active[a]] <= x0:
                    n_act -= 1
                    active[a] = active[n_act]
                else:
                    a += 1
            if not x1 > x0 or n_act == 0:
                continue
            xm = 0.5 * (x0 + x1)
            rz = np.sqrt(max(1.0 - xm * xm - y * y, 0.0))
            best = -np.inf
            win = -1
            for a in range(n_act):
                e = sp_e[active[a]]
                near = coef[e, 0] * xm + coef[e, 1] * y + coef[e, 2] + coef[e, 3] * rz
                if near > best or (near == best and e < win):
                    best = near
                    win = e
            out[win] += (x1 - x0) * inv_total


@jit
def scanline_shots(points, normals, vertices, elem_verts, n_lines, edge_angle, plane_depth,
                   horizon_eps, both_axes):
    """Scanline hemisphere-base form factors from each shooting point to all elements.

    Parameters
    ----------
    points, normals : (S, 3) float64
        Shooting points and unit normals.
    vertices : (V, 3) float64
    elem_verts : (E, 4) int32
        ``-1`` in column 3 for a triangle.
    n_lines : int
        Number of scanlines ``N`` across the disc.
    edge_angle : float
        Threshold angle (radians) of a projected edge piece (eq. 4).
    plane_depth : bool
        Depth by the paper's eq. 5 instead of the exact distance.
    horizon_eps : float
        Clip height above the tangent plane, relative to the scene diagonal.
    both_axes : bool
        Average horizontal and vertical scanlines.

    Returns
    -------
    (S, E) float64
        ``F[s, e] = (Σ visible span lengths of e) / Σ_j 2 w_j`` (eq. 8, normalised).
    """
    n_shot = points.shape[0]
    n_elem = elem_verts.shape[0]
    n_vert = vertices.shape[0]
    enrm, eoff = element_planes(vertices, elem_verts)
    hz = max(horizon_eps * scene_diagonal(vertices), 1e-300)
    lx = np.empty(n_vert)
    ly = np.empty(n_vert)
    lz = np.empty(n_vert)
    cap = edge_capacity(edge_angle)
    xs = np.empty(cap)
    ys = np.empty(cap)
    xcross = np.empty(cap)
    coef = np.zeros((n_elem, 4))
    out = np.zeros((n_shot, n_elem))
    cos_thr = np.cos(edge_angle)
    tab = split_table(edge_angle)
    n_pass = 2 if both_axes else 1
    for s in range(n_shot):
        for p in range(n_pass):
            _shoot(points[s, 0], points[s, 1], points[s, 2],
                   normals[s, 0], normals[s, 1], normals[s, 2],
                   vertices, elem_verts, enrm, eoff, hz, n_lines, cos_thr, tab,
                   plane_depth, p == 1, lx, ly, lz, xs, ys, xcross, coef, out[s])
        if n_pass == 2:
            for e in range(n_elem):
                out[s, e] *= 0.5
    return out
