"""Area lights no shadow ray of an element can reach: the per-pixel pass skips their rays.

The other half of :mod:`daskrad.kernels.unshadowed`. A pixel on an element of the per-pixel
pass (paper eq. 9) traces ``samples²`` shadow rays to every area light it faces
(:func:`daskrad.kernels.direct.irradiance_one`). In a furnished interior most of those lights
are hidden from the whole element: RenderPark's office (``office3``, 68 one-sided emitters),
of the 197,718 pairs of a per-pixel element and a light in front of it, 159,713 (81 %) are
hidden from every corner of the element, against 31,694 partly visible. Their rays all end on
an occluder, adding ``π Le F · 0`` to the irradiance.

Each shadow ray of a hit ``p`` on element ``e`` runs from ``o = p + off·n_e`` to a point ``q``
of the light ``Λ``, for ``t`` in ``(off/|d|, 1 − off/|d|)``. A convex planar polygon ``Π`` (a
patch or a convex input polygon: the grid's triangles of its elements tile it) blocks every
such ray when

- every lifted corner of ``e`` lies on one side of ``Π``'s plane and every corner of ``Λ`` on
  the other, each further than ``2·off`` from it (so the crossing lies inside the traced part
  of the ray, and no ray is parallel to the plane), and
- the crossing of the segment from every lifted corner ``e_i`` to every light corner ``l_j``
  lies inside ``Π`` by ``δ``.

The crossing ``c(x, y)`` of a segment from ``x ∈ conv(e)`` to ``y ∈ conv(Λ)`` is the central
projection of ``x`` from ``y`` onto the plane, which maps ``conv(e)`` onto the hull of the
corners' projections; projecting each ``e_i`` from ``y ∈ conv(Λ)`` likewise stays in the hull
of the ``c(e_i, l_j)``. So every crossing lies in that hull, hence inside ``Π`` by ``δ``: the
ray test (Möller–Trumbore with an outward edge tolerance ``grid.eps``) finds a hit on one of
``Π``'s triangles, and the light adds exactly ``+0.0``, as when its rays are traced. ``δ``
covers a hit point that lies outside its element by the ray test's tolerance.

Candidates ``Π`` are the faces hit first by rays from the lifted centroid and corners of
``e`` towards the light's centroid: the hit patch's whole polygon when it is convex (its
patches tile it), else the patch. Anything not proved keeps its rays: the test only ever
answers "certainly hidden".
"""

from __future__ import annotations

import numpy as np
from numba import prange

from daskrad.kernels._jit import jit, jit_leaf, jit_parallel
from daskrad.kernels.geometry import orthonormal_basis, within_edges
from daskrad.kernels.grid import closest_hit_one


@jit_leaf
def patch_blocks(corners, n_corners, light, n_light, pv, n_pv, off, delta):
    """Whether the convex planar polygon ``pv[:n_pv] (k, 3)`` (counter-clockwise about its
    normal) blocks every segment from the hull of ``corners[:n_corners]`` to the hull of
    ``light[:n_light]`` (see the module docstring): both sides further than ``2·off`` from its
    plane, every corner-to-corner crossing inside it by ``delta`` (lengths)."""
    # Newell's normal of the polygon
    nx = 0.0
    ny = 0.0
    nz = 0.0
    for a in range(n_pv):
        b = a + 1 if a + 1 < n_pv else 0
        nx += (pv[a, 1] - pv[b, 1]) * (pv[a, 2] + pv[b, 2])
        ny += (pv[a, 2] - pv[b, 2]) * (pv[a, 0] + pv[b, 0])
        nz += (pv[a, 0] - pv[b, 0]) * (pv[a, 1] + pv[b, 1])
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    if not norm > 0.0:
        return False
    nx /= norm
    ny /= norm
    nz /= norm
    pd = nx * pv[0, 0] + ny * pv[0, 1] + nz * pv[0, 2]
    gap = 2.0 * off
    sign = 0.0
    for i in range(n_corners):
        s = nx * corners[i, 0] + ny * corners[i, 1] + nz * corners[i, 2] - pd
        if i == 0:
            sign = 1.0 if s > 0.0 else -1.0
        if not s * sign > gap:
            return False
    for j in range(n_light):
        s = nx * light[j, 0] + ny * light[j, 1] + nz * light[j, 2] - pd
        if not -s * sign > gap:
            return False
    for i in range(n_corners):
        di = nx * corners[i, 0] + ny * corners[i, 1] + nz * corners[i, 2] - pd
        for j in range(n_light):
            dj = nx * light[j, 0] + ny * light[j, 1] + nz * light[j, 2] - pd
            t = di / (di - dj)
            cx = corners[i, 0] + t * (light[j, 0] - corners[i, 0])
            cy = corners[i, 1] + t * (light[j, 1] - corners[i, 1])
            cz = corners[i, 2] + t * (light[j, 2] - corners[i, 2])
            # inside by delta (strictly beyond the ray test's outward edge tolerance)
            if not within_edges(pv, n_pv, cx, cy, cz, nx, ny, nz, delta):
                return False
    return True


@jit
def polygon_outlines(vertices, patch_verts, patch_area, patch_normal, order, start):
    """The outline of every convex polygon, from its patches: ``(outline_start (Q + 1,)
    int64, outline (n, 3) float64)``, polygon ``q``'s corners counter-clockwise about its
    normal in ``outline[outline_start[q]:outline_start[q + 1]]`` (none for a polygon that is
    not convex, or has a hole).

    ``order (P,)`` lists the patches polygon by polygon, polygon ``q``'s in
    ``order[start[q]:start[q + 1]]``; ``patch_verts (P, 4)`` (``-1``: a triangle) index
    ``vertices (V, 3)``, ``patch_area (P,)``, ``patch_normal (P, 3)`` unit. The outline is
    the convex hull of the patches' corners in the polygon's plane (Andrew's monotone chain,
    collinear corners dropped); the polygon is convex exactly when that hull's area is the
    sum of its patches' areas (the patches tile the polygon), to ``1e-9`` relative."""
    n_poly = start.shape[0] - 1
    counts = np.zeros(n_poly + 1, np.int64)
    cap = 0
    for q in range(n_poly):
        cap = max(cap, 4 * (start[q + 1] - start[q]))
    px = np.empty(cap)
    py = np.empty(cap)
    ids = np.empty(cap, np.int64)
    hull = np.empty(2 * cap + 1, np.int64)
    keep = np.empty((max(1, n_poly), 16), np.int64)
    for q in range(n_poly):
        a, b = start[q], start[q + 1]
        if b == a:
            continue
        nrm = patch_normal[order[a]]
        # (u, v, n) right-handed: counter-clockwise in (u, v) is counter-clockwise about n
        ux, uy, uz, vx, vy, vz = orthonormal_basis(nrm[0], nrm[1], nrm[2])
        k = 0
        area = 0.0
        for i in range(a, b):
            p = order[i]
            area += patch_area[p]
            for c in range(4):
                vi = patch_verts[p, c]
                if vi < 0:
                    continue
                ids[k] = vi
                px[k] = (vertices[vi, 0] * ux + vertices[vi, 1] * uy + vertices[vi, 2] * uz)
                py[k] = (vertices[vi, 0] * vx + vertices[vi, 1] * vy + vertices[vi, 2] * vz)
                k += 1
        # sort by (x, y): a stable sort by y, then by x
        by_y = np.argsort(py[:k], kind="mergesort")
        by_x = np.argsort(px[:k][by_y], kind="mergesort")
        srt = by_y[by_x]
        h = 0
        for pass_ in range(2):
            lo = h
            for jj in range(k):
                j = srt[jj] if pass_ == 0 else srt[k - 1 - jj]
                while h >= lo + 2:
                    o_ = hull[h - 2]
                    m_ = hull[h - 1]
                    cr = ((px[m_] - px[o_]) * (py[j] - py[o_])
                          - (py[m_] - py[o_]) * (px[j] - px[o_]))
                    if cr > 0.0:
                        break
                    h -= 1
                hull[h] = j
                h += 1
            h -= 1          # the last point is the first of the other chain
        if h < 3 or h > 16:
            continue
        hull_area = 0.0
        for i in range(h):
            j = hull[i + 1] if i + 1 < h else hull[0]
            hull_area += px[hull[i]] * py[j] - px[j] * py[hull[i]]
        hull_area *= 0.5
        if not abs(hull_area - area) <= 1e-9 * area:
            continue
        counts[q + 1] = h
        for i in range(h):
            keep[q, i] = ids[hull[i]]
    outline_start = np.cumsum(counts)
    outline = np.empty((outline_start[-1], 3))
    for q in range(n_poly):
        for i in range(outline_start[q + 1] - outline_start[q]):
            for x in range(3):
                outline[outline_start[q] + i, x] = vertices[keep[q, i], x]
    return outline_start, outline


@jit_parallel
def hidden_pairs(grid, tri_element, elem_patch, patch_verts, patch_polygon, outline_start,
                 outline, vertices, elem_verts, elem_normal, off, delta, pair_elem, pair_light,
                 em_corners, em_count):
    """``(n,) bool``: for each pair (element ``pair_elem[k]``, area light ``pair_light[k]``),
    whether one face is proved to block every shadow ray from the element (lifted by ``off``)
    to the light (:func:`patch_blocks`). Candidates: the faces first hit from the lifted
    centroid and corners towards the light's centroid; a face is the hit patch's whole
    polygon when it is convex (:func:`polygon_outlines`: ``outline_start``, ``outline``),
    else the patch.

    ``tri_element (T,)`` maps the grid's triangles to elements, ``elem_patch (E,)`` elements to
    patches, ``patch_polygon (P,)`` patches to polygons; ``patch_verts (P, 4)`` and
    ``elem_verts (E, 4)`` index ``vertices (V, 3)`` (``-1`` fourth corner: a triangle);
    ``em_corners (M, 4, 3)``, ``em_count (M,)``. Each pair is decided alone (any split gives
    the same answers)."""
    n = pair_elem.shape[0]
    out = np.zeros(n, np.bool_)
    for k in prange(n):
        e = pair_elem[k]
        m = pair_light[k]
        kc = 4 if elem_verts[e, 3] >= 0 else 3
        corners = np.empty((4, 3))
        for a in range(kc):
            for x in range(3):
                corners[a, x] = vertices[elem_verts[e, a], x] + off * elem_normal[e, x]
        nl = em_count[m]
        target = np.zeros(3)
        for j in range(nl):
            for x in range(3):
                target[x] += em_corners[m, j, x] / nl
        pv = np.empty((4, 3))
        o = np.empty(3)
        d = np.empty(3)
        tried = np.full(kc + 1, -(1 << 62), np.int64)
        for c in range(kc + 1):
            for x in range(3):
                if c == 0:     # the lifted centroid first
                    o[x] = 0.0
                    for a in range(kc):
                        o[x] += corners[a, x] / kc
                else:
                    o[x] = corners[c - 1, x]
                d[x] = target[x] - o[x]
            _, tri, _, _ = closest_hit_one(grid, o, d, 0.0, 1.0)
            if tri < 0:
                continue
            p = elem_patch[tri_element[tri]]
            q = patch_polygon[p]
            a0, a1 = outline_start[q], outline_start[q + 1]
            key = q if a1 > a0 else -1 - p
            seen = False
            for i in range(c):
                seen = seen or tried[i] == key
            tried[c] = key
            if seen:
                continue
            if a1 > a0:
                ok = patch_blocks(corners, kc, em_corners[m], nl, outline[a0:a1], a1 - a0,
                                  off, delta)
            else:
                npv = 4 if patch_verts[p, 3] >= 0 else 3
                for a in range(npv):
                    for x in range(3):
                        pv[a, x] = vertices[patch_verts[p, a], x]
                ok = patch_blocks(corners, kc, em_corners[m], nl, pv, npv, off, delta)
            if ok:
                out[k] = True
                break
    return out
