"""Lambert's contour formula: point-to-polygon form factors without occlusion (docs/references.md).

For a differential area at ``p`` with unit normal ``n`` and a planar polygon with corners
``v_i``, ``R_i = v_i - p``::

    F = (1/2π) | Σ_i γ_i · n · (R_i × R_{i+1}) / |R_i × R_{i+1}| |,   γ_i = angle(R_i, R_{i+1})

The formula integrates the projected solid angle of the polygon and is valid only for the part
of the polygon above the point's tangent plane, so each polygon is first clipped to
``n · (x - p) >= 0``. Receivers are one-sided: a polygon whose lit side does not face ``p``
gives 0. This is the ground truth the rasterized methods are tested against.
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.geometry import element_planes, lex_less


@jit
def lambert_shots(points, normals, vertices, elem_verts):
    """Unoccluded form factor from every point to every element.

    Parameters
    ----------
    points : (S, 3) float64
        Positions of the differential shooting areas.
    normals : (S, 3) float64
        Their unit normals.
    vertices : (V, 3) float64
    elem_verts : (E, 4) int32
        Corner indices, counter-clockwise seen from the lit side; ``-1`` in column 3 for a
        triangle.

    Returns
    -------
    (S, E) float64
        ``F[s, e]``, the form factor from the differential area ``s`` to element ``e``
        (ignoring every other element), 0 for back-facing elements and those wholly below the
        horizon.
    """
    enrm, eoff = element_planes(vertices, elem_verts)
    return _lambert(points, normals, vertices, elem_verts, enrm, eoff,
                    np.ones((1, 1), dtype=np.bool_), False)


@jit
def lambert_masked(points, normals, vertices, elem_verts, enrm, eoff, mask):
    """:func:`lambert_shots` only where ``mask : (S, E) bool`` is set, 0 elsewhere;
    ``enrm (E, 3), eoff (E,)``: the elements' planes
    (:func:`daskrad.kernels.geometry.element_planes`), computed once per mesh by the caller.

    The anti-aliased hemisphere method multiplies Lambert's factor by a visible fraction, so it
    needs it only where that fraction is positive (hidden elements cost nothing). Where the mask
    is set the value is bit-identical to :func:`lambert_shots` (same code).
    """
    return _lambert(points, normals, vertices, elem_verts, enrm, eoff, mask, True)


@jit
def _lambert(points, normals, vertices, elem_verts, enrm, eoff, mask, use_mask):
    """Body of :func:`lambert_shots` / :func:`lambert_masked`; ``mask`` read only when
    ``use_mask``.

    The per-element clip and contour sum are written out here instead of calling the
    single-polygon twin :func:`lambert_polygon`: a numba call per element with array arguments
    cost ~45 ns, which took the 50k-element analytic row from 3.4 to 5.8 ms when tried. Keep
    the two in step (tests/test_kernel_twins.py asserts the same bits).
    """
    n_shot = points.shape[0]
    n_elem = elem_verts.shape[0]
    out = np.zeros((n_shot, n_elem))
    cx = np.empty(4)
    cy = np.empty(4)
    cz = np.empty(4)
    h = np.empty(4)
    px_ = np.empty(5)
    py_ = np.empty(5)
    pz_ = np.empty(5)
    inv_2pi = 0.5 / np.pi
    for s in range(n_shot):
        sx = points[s, 0]
        sy = points[s, 1]
        sz = points[s, 2]
        nx = normals[s, 0]
        ny = normals[s, 1]
        nz = normals[s, 2]
        for e in range(n_elem):
            if use_mask and not mask[s, e]:
                continue
            # One-sided receiver: p must lie strictly on the lit side of the element's plane.
            if enrm[e, 0] * sx + enrm[e, 1] * sy + enrm[e, 2] * sz - eoff[e] <= 0.0:
                continue
            k = 4 if elem_verts[e, 3] >= 0 else 3
            hmax = -1.0
            hmin = 1.0
            for c in range(k):
                vi = elem_verts[e, c]
                cx[c] = vertices[vi, 0] - sx
                cy[c] = vertices[vi, 1] - sy
                cz[c] = vertices[vi, 2] - sz
                h[c] = nx * cx[c] + ny * cy[c] + nz * cz[c]
                hmax = max(hmax, h[c])
                hmin = min(hmin, h[c])
            if hmax <= 0.0:
                continue
            # Sutherland–Hodgman against the tangent plane h = 0 (keep h >= 0).
            m = 0
            if hmin >= 0.0:
                for c in range(k):
                    px_[c] = cx[c]
                    py_[c] = cy[c]
                    pz_[c] = cz[c]
                m = k
            else:
                for c in range(k):
                    d = (c + 1) % k
                    if h[c] >= 0.0:
                        px_[m] = cx[c]
                        py_[m] = cy[c]
                        pz_[m] = cz[c]
                        m += 1
                    if (h[c] >= 0.0) != (h[d] >= 0.0):
                        # Interpolate from the canonical endpoint (bit-identical for the
                        # neighbour sharing this edge).
                        if lex_less(cx[c], cy[c], cz[c], cx[d], cy[d], cz[d]):
                            a = c
                            b = d
                        else:
                            a = d
                            b = c
                        t = h[a] / (h[a] - h[b])
                        px_[m] = cx[a] + t * (cx[b] - cx[a])
                        py_[m] = cy[a] + t * (cy[b] - cy[a])
                        pz_[m] = cz[a] + t * (cz[b] - cz[a])
                        m += 1
            total = 0.0
            for c in range(m):
                d = (c + 1) % m
                ax = px_[c]
                ay = py_[c]
                az = pz_[c]
                bx = px_[d]
                by = py_[d]
                bz = pz_[d]
                gx = ay * bz - az * by
                gy = az * bx - ax * bz
                gz = ax * by - ay * bx
                g = np.sqrt(gx * gx + gy * gy + gz * gz)
                if g == 0.0:
                    continue
                # atan2 instead of acos: accurate for the tiny angles of small, far edges.
                gamma = np.arctan2(g, ax * bx + ay * by + az * bz)
                total += gamma * (nx * gx + ny * gy + nz * gz) / g
            out[s, e] = abs(total) * inv_2pi
    return out


@jit
def lambert_polygon(px, py, pz, nx, ny, nz, corners, count):
    """Lambert's unoccluded form factor from the differential area ``(p, n)`` to the polygon
    ``corners[:count] (count, 3)``, clipped to ``n · (x − p) ≥ 0`` (docs/references.md).

    Orientation is not checked here (the caller decides one-sidedness). The batch twin over
    elements is :func:`_lambert`, written out for speed (tests/test_kernel_twins.py holds the
    two to the same bits). :func:`lambert_into` is the same with the caller's scratch.
    """
    return lambert_into(px, py, pz, nx, ny, nz, corners, count, np.empty((7, 5)))


@jit_leaf
def lambert_into(px, py, pz, nx, ny, nz, corners, count, sc):
    """:func:`lambert_polygon` with ``sc (7, 5) float64`` as its scratch: a loop calling it
    allocates nothing (the seven small arrays cost a third of a quad's 0.2 µs)."""
    cx = sc[0]
    cy = sc[1]
    cz = sc[2]
    h = sc[3]
    qx = sc[4]
    qy = sc[5]
    qz = sc[6]
    hmax = -1.0
    hmin = 1.0
    for c in range(count):
        cx[c] = corners[c, 0] - px
        cy[c] = corners[c, 1] - py
        cz[c] = corners[c, 2] - pz
        h[c] = nx * cx[c] + ny * cy[c] + nz * cz[c]
        hmax = max(hmax, h[c])
        hmin = min(hmin, h[c])
    if hmax <= 0.0:
        return 0.0
    m = 0
    for c in range(count):
        d = (c + 1) % count
        if h[c] >= 0.0:
            qx[m] = cx[c]
            qy[m] = cy[c]
            qz[m] = cz[c]
            m += 1
        if hmin < 0.0 and (h[c] >= 0.0) != (h[d] >= 0.0):
            if lex_less(cx[c], cy[c], cz[c], cx[d], cy[d], cz[d]):
                a, b = c, d
            else:
                a, b = d, c
            t = h[a] / (h[a] - h[b])
            qx[m] = cx[a] + t * (cx[b] - cx[a])
            qy[m] = cy[a] + t * (cy[b] - cy[a])
            qz[m] = cz[a] + t * (cz[b] - cz[a])
            m += 1
    total = 0.0
    for c in range(m):
        d = (c + 1) % m
        gx = qy[c] * qz[d] - qz[c] * qy[d]
        gy = qz[c] * qx[d] - qx[c] * qz[d]
        gz = qx[c] * qy[d] - qy[c] * qx[d]
        g = np.sqrt(gx * gx + gy * gy + gz * gz)
        if g == 0.0:
            continue
        gamma = np.arctan2(g, qx[c] * qx[d] + qy[c] * qy[d] + qz[c] * qz[d])
        total += gamma * (nx * gx + ny * gy + nz * gz) / g
    return abs(total) * (0.5 / np.pi)
