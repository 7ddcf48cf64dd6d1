"""The hemicube form factor (Cohen & Greenberg 1985), for comparison with the hemisphere base.

Around the shooting point ``p`` (local frame ``t1, t2, n`` as in
:mod:`daskrad.kernels.hemisphere`) stands half of a cube of half-side 1: a top face at ``n = 1``
with ``R × R`` pixels over ``[-1, 1]²`` and four side faces of ``R × R/2`` pixels each (height
``[0, 1]`` above the tangent plane). Each receiving element is

1. culled (back-facing, wholly at or below the horizon) exactly as on the hemisphere base,
2. for each face, transformed into the face's frame ``(a, b, c)`` (``c`` along the face's outward
   axis), clipped in 3-D by Sutherland–Hodgman against the horizon (``z > hz`` as on the base)
   and the face's frustum ``|a| <= c``, ``|b| <= c``,
3. projected centrally, ``(a/c, b/c)``: straight edges stay straight, so no edge splitting,
4. scan-converted with the rasterizer the hemisphere base uses
   (:func:`daskrad.kernels.hemisphere.fill_polygon`, its body written out in the per-element
   loop exactly as the hemisphere base's item buffer does, so both pay no call per element
   and face) into the face's z-buffer; the nearness
   ``1/t`` for the direction ``(x, y, 1)`` of the face is linear in ``(x, y)``.

Every pixel carries its **delta form factor** (Cohen & Greenberg): on the top face
``ΔA / (π (x² + y² + 1)²)``, on a side face ``ΔA · z / (π (1 + u² + z²)²)`` with ``z`` the height
and ``u`` the horizontal coordinate of the pixel centre. Evaluated at pixel centres they sum to
``1 + O(1/R²)``; they are normalised here so the whole cube sums to exactly 1 (like the item
buffer's ``1/n_disc``), so ``Σ_j F_j <= 1`` always and ``= 1`` to round-off in a closed scene.

Watertightness follows the same rules as the base: clip points are computed from an edge's
canonical endpoint (:func:`daskrad.kernels.geometry.lex_less`), crossings from the lower
endpoint, half-open pixel rules, so elements sharing an edge share every pixel boundary.
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.geometry import element_planes, lex_less, scene_diagonal
from daskrad.kernels.hemisphere import in_frame, local_frame
from daskrad.kernels.tolerances import SPHERE_PAD

#: Face axes in the shooter's local frame: for each of the 5 faces, (index, sign) of the local
#: coordinate giving ``a``, ``b`` and ``c``. Face 0 is the top; 1–4 the sides, whose ``b`` is the
#: height ``z`` above the tangent plane.
_FACE_AXES = np.array([
    [[0, 1], [1, 1], [2, 1]],     # top: a = x, b = y, c = z
    [[1, 1], [2, 1], [0, 1]],     # +x: a = y, b = z, c = x
    [[1, -1], [2, 1], [0, -1]],   # -x: a = -y, b = z, c = -x
    [[0, -1], [2, 1], [1, 1]],    # +y: a = -x, b = z, c = y
    [[0, 1], [2, 1], [1, -1]],    # -y: a = x, b = z, c = -y
], dtype=np.int64)


@jit
def element_spheres(vertices, elem_verts):
    """Bounding sphere of every element, per call (it does not depend on the shooter).

    Returns ``centre : (E, 3) float64`` (the mean of the corners) and ``radius : (E,) float64``
    (the largest corner distance, rounded up by the relative ``SPHERE_PAD`` so that the sphere
    test never culls an element one of whose corners lies above the horizon).
    """
    n_elem = elem_verts.shape[0]
    centre = np.empty((n_elem, 3))
    radius = np.empty(n_elem)
    for e in range(n_elem):
        k = 4 if elem_verts[e, 3] >= 0 else 3
        mx = 0.0
        my = 0.0
        mz = 0.0
        for a in range(k):
            vi = elem_verts[e, a]
            mx += vertices[vi, 0]
            my += vertices[vi, 1]
            mz += vertices[vi, 2]
        mx /= k
        my /= k
        mz /= k
        r2 = 0.0
        for a in range(k):
            vi = elem_verts[e, a]
            r2 = max(r2, (vertices[vi, 0] - mx) ** 2 + (vertices[vi, 1] - my) ** 2
                     + (vertices[vi, 2] - mz) ** 2)
        centre[e, 0] = mx
        centre[e, 1] = my
        centre[e, 2] = mz
        radius[e] = np.sqrt(r2) * (1.0 + SPHERE_PAD) + 1e-300
    return centre, radius


@jit_leaf
def side_rows(resolution):
    """Pixel rows of a side face: ``R // 2`` (at least 1) over the height ``[0, 1]``."""
    return max(resolution // 2, 1)


@jit
def delta_form_factors(resolution):
    """Normalised delta form factors of the five faces, concatenated row-major.

    Returns
    -------
    weights : (R² + 4 R h,) float64
        Top face first (``R × R``), then the four sides (``h × R`` each, ``h = R // 2``, row 0
        at the horizon); ``Σ weights = 1`` exactly up to round-off.
    raw_sum : float
        The sum before normalisation, ``1 + O(1/R²)`` (midpoint rule on the exact integrands).
    """
    r = resolution
    h = side_rows(r)
    w = np.empty(r * r + 4 * r * h)
    da_top = (2.0 / r) ** 2
    da_side = (2.0 / r) * (1.0 / h)
    for j in range(r):
        y = -1.0 + (2.0 * j + 1.0) / r
        for i in range(r):
            x = -1.0 + (2.0 * i + 1.0) / r
            q = x * x + y * y + 1.0
            w[j * r + i] = da_top / (np.pi * q * q)
    off = r * r
    for _face in range(4):
        for j in range(h):
            z = (j + 0.5) / h
            for i in range(r):
                u = -1.0 + (2.0 * i + 1.0) / r
                q = 1.0 + u * u + z * z
                w[off + j * r + i] = da_side * z / (np.pi * q * q)
        off += r * h
    total = 0.0
    for k in range(w.shape[0]):
        total += w[k]
    for k in range(w.shape[0]):
        w[k] /= total
    return w, total


@jit_leaf
def _clip(n, pa, pb, pc, ka, kb, kc, off, oa, ob, oc):
    """Sutherland–Hodgman: keep ``ka a + kb b + kc c > off`` of the polygon ``p (n,)`` into
    ``o``; returns the new count. Crossings are computed from the canonical endpoint."""
    m = 0
    for i in range(n):
        j = i + 1 if i + 1 < n else 0
        fi = ka * pa[i] + kb * pb[i] + kc * pc[i] - off
        fj = ka * pa[j] + kb * pb[j] + kc * pc[j] - off
        ini = fi > 0.0
        if ini:
            oa[m] = pa[i]
            ob[m] = pb[i]
            oc[m] = pc[i]
            m += 1
        if ini != (fj > 0.0):
            if lex_less(pa[i], pb[i], pc[i], pa[j], pb[j], pc[j]):
                i0, i1, f0, f1 = i, j, fi, fj
            else:
                i0, i1, f0, f1 = j, i, fj, fi
            t = f0 / (f0 - f1)
            oa[m] = pa[i0] + t * (pa[i1] - pa[i0])
            ob[m] = pb[i0] + t * (pb[i1] - pb[i0])
            oc[m] = pc[i0] + t * (pc[i1] - pc[i0])
            m += 1
    return m


@jit_leaf
def _shoot(sx, sy, sz, snx, sny, snz, vertices, elem_verts, enrm, eoff, sctr, srad, hz,
           resolution, weights, mask, xc, zc, lx, ly, lz, item, zbuf, xs, ys, xcross, cnt,
           loc, pa, pb, pc, qa, qb, qc, nl, out):
    """One shot: add each element's delta form factors into ``out (E,)``.

    The same generic savings as the hemisphere base: culling by one dot product each
    (back-facing, bounding sphere below the horizon) and no allocation per shot; plus the
    hemicube's own standard trick, per-face outcodes: a face whose frustum has all corners
    outside one of its planes is skipped, and one with every corner inside all of them is
    projected without clipping (``loc, pa … nl`` are scratch)."""
    r = resolution
    h = side_rows(r)
    half_r = 0.5 * r
    t1x, t1y, t1z, t2x, t2y, t2z = local_frame(sx, sy, sz, snx, sny, snz, vertices, lx, ly, lz)
    for k in range(item.shape[0]):
        item[k] = -1
        zbuf[k] = -np.inf
    sdotn = snx * sx + sny * sy + snz * sz
    n_elem = elem_verts.shape[0]
    for e in range(n_elem):
        c = eoff[e] - (enrm[e, 0] * sx + enrm[e, 1] * sy + enrm[e, 2] * sz)
        if not c < 0.0:
            continue
        if snx * sctr[e, 0] + sny * sctr[e, 1] + snz * sctr[e, 2] - sdotn + srad[e] <= hz:
            continue
        k = 4 if elem_verts[e, 3] >= 0 else 3
        zmax = -np.inf
        for a in range(k):
            zmax = max(zmax, lz[elem_verts[e, a]])
        if zmax <= hz:
            continue
        nl[0], nl[1], nl[2] = in_frame(t1x, t1y, t1z, t2x, t2y, t2z, snx, sny, snz,
                                       enrm[e, 0], enrm[e, 1], enrm[e, 2])
        for f in range(5):
            ia = _FACE_AXES[f, 0, 0]
            sa = float(_FACE_AXES[f, 0, 1])
            ib = _FACE_AXES[f, 1, 0]
            sb = float(_FACE_AXES[f, 1, 1])
            ic = _FACE_AXES[f, 2, 0]
            sc = float(_FACE_AXES[f, 2, 1])
            # outcodes, one bit per plane: the face's frustum |a| < c, |b| < c (top) or b < c
            # (sides), and the horizon (c > hz on the top, b > hz on the sides)
            all_out = 31
            any_out = 0
            for a in range(k):
                vi = elem_verts[e, a]
                loc[0] = lx[vi]
                loc[1] = ly[vi]
                loc[2] = lz[vi]
                pa[a] = sa * loc[ia]
                pb[a] = sb * loc[ib]
                pc[a] = sc * loc[ic]
                code = 0
                if not pc[a] - pa[a] > 0.0:
                    code |= 1
                if not pc[a] + pa[a] > 0.0:
                    code |= 2
                if not pc[a] - pb[a] > 0.0:
                    code |= 4
                if f == 0:
                    if not pc[a] + pb[a] > 0.0:
                        code |= 8
                    if not pc[a] > hz:
                        code |= 16
                elif not pb[a] > hz:
                    code |= 16
                all_out &= code
                any_out |= code
            if all_out != 0:
                continue  # every corner outside one plane: nothing on this face
            if any_out == 0:
                # every corner strictly inside: the clips below would return it unchanged
                m = k
                for a in range(m):
                    qa[a] = pa[a]
                    qb[a] = pb[a]
                    qc[a] = pc[a]
            else:
                # horizon (z > hz: c on the top face, b on the sides), then the frustum
                if f == 0:
                    m = _clip(k, pa, pb, pc, 0.0, 0.0, 1.0, hz, qa, qb, qc)
                else:
                    m = _clip(k, pa, pb, pc, 0.0, 1.0, 0.0, hz, qa, qb, qc)
                m = _clip(m, qa, qb, qc, -1.0, 0.0, 1.0, 0.0, pa, pb, pc)
                m = _clip(m, pa, pb, pc, 1.0, 0.0, 1.0, 0.0, qa, qb, qc)
                m = _clip(m, qa, qb, qc, 0.0, -1.0, 1.0, 0.0, pa, pb, pc)
                if f == 0:
                    m = _clip(m, pa, pb, pc, 0.0, 1.0, 1.0, 0.0, qa, qb, qc)
                else:
                    for a in range(m):
                        qa[a] = pa[a]
                        qb[a] = pb[a]
                        qc[a] = pc[a]
            if m < 3:
                continue
            for a in range(m):
                xs[a] = qa[a] / qc[a]
                ys[a] = qb[a] / qc[a]
            # nearness 1/t along (x, y, 1) in the face frame: (n_f · d) / c, linear in x, y
            na = sa * nl[ia]
            nb = sb * nl[ib]
            nc = sc * nl[ic]
            # fill_polygon's body written out (as in the hemisphere base's _shoot): the call
            # passing a dozen arrays costs more than a small element's pixels
            if f == 0:
                o0 = 0
                nrow = r
                y0 = -1.0
                inv_py = half_r
                ycs = xc
            else:
                o0 = r * r + (f - 1) * r * h
                nrow = h
                y0 = 0.0
                inv_py = float(h)
                ycs = zc
            da = na / c
            db = nb / c
            dc = nc / c
            ymin = np.inf
            ymax = -np.inf
            for a in range(m):
                ymin = min(ymin, ys[a])
                ymax = max(ymax, ys[a])
            j0 = max(int(np.ceil((ymin - y0) * inv_py - 0.5)) - 1, 0)
            j1 = min(int(np.floor((ymax - y0) * inv_py - 0.5)) + 1, nrow - 1)
            if j0 > j1:
                continue
            for j in range(j0, j1 + 1):
                cnt[j] = 0
            for a in range(m):
                b = a + 1 if a + 1 < m else 0
                if ys[a] < ys[b]:
                    lo = a
                    hi = b
                elif ys[b] < ys[a]:
                    lo = b
                    hi = a
                else:
                    continue
                ylo = ys[lo]
                yhi = ys[hi]
                slope = (xs[hi] - xs[lo]) / (yhi - ylo)
                ja = max(int(np.ceil((ylo - y0) * inv_py - 0.5)) - 1, j0)
                jb = min(int(np.floor((yhi - y0) * inv_py - 0.5)) + 1, j1)
                for j in range(ja, jb + 1):
                    ycj = ycs[j]
                    if ylo <= ycj < yhi:
                        xcross[j, cnt[j]] = xs[lo] + (ycj - ylo) * slope
                        cnt[j] += 1
            for j in range(j0, j1 + 1):
                ncr = cnt[j]
                if ncr < 2:
                    continue
                for a in range(1, ncr):
                    x = xcross[j, a]
                    b = a - 1
                    while b >= 0 and xcross[j, b] > x:
                        xcross[j, b + 1] = xcross[j, b]
                        b -= 1
                    xcross[j, b + 1] = x
                row = o0 + j * r
                rowterm = db * ycs[j] + dc
                for a in range(0, ncr - 1, 2):
                    i_lo = max(int(np.ceil((xcross[j, a] + 1.0) * half_r - 0.5)), 0)
                    i_hi = min(int(np.ceil((xcross[j, a + 1] + 1.0) * half_r - 0.5)) - 1, r - 1)
                    for i in range(i_lo, i_hi + 1):
                        idx = row + i
                        # every face pixel counts (the mask is 0 everywhere on the cube)
                        near = da * xc[i] + rowterm
                        if near > zbuf[idx]:
                            zbuf[idx] = near
                            item[idx] = e
    for k in range(item.shape[0]):
        if item[k] >= 0:
            out[item[k]] += weights[k]


@jit
def hemicube_shots(points, normals, vertices, elem_verts, resolution, horizon_eps):
    """Hemicube form factors from each shooting point to all elements.

    Parameters
    ----------
    points : (S, 3) float64
    normals : (S, 3) float64
        Unit normals.
    vertices : (V, 3) float64
    elem_verts : (E, 4) int32
        ``-1`` in column 3 for a triangle.
    resolution : int
        Side ``R`` of the top face (the sides have ``R × R//2`` pixels).
    horizon_eps : float
        Clip height above the tangent plane, relative to the scene diagonal.

    Returns
    -------
    (S, E) float64
        ``F[s, e]``: the sum of the normalised delta form factors of the pixels ``e`` wins.
    """
    n_shot = points.shape[0]
    n_elem = elem_verts.shape[0]
    n_vert = vertices.shape[0]
    r = resolution
    h = side_rows(r)
    enrm, eoff = element_planes(vertices, elem_verts)
    sctr, srad = element_spheres(vertices, elem_verts)
    hz = max(horizon_eps * scene_diagonal(vertices), 1e-300)
    weights, _ = delta_form_factors(r)
    n_pix = weights.shape[0]
    mask = np.zeros(n_pix)  # every face pixel counts; the nearness needs no extra term
    xc = np.empty(r)
    for i in range(r):
        xc[i] = -1.0 + (2.0 * i + 1.0) / r
    zc = np.empty(h)
    for j in range(h):
        zc[j] = (j + 0.5) / h
    item = np.empty(n_pix, dtype=np.int32)
    zbuf = np.empty(n_pix)
    lx = np.empty(n_vert)
    ly = np.empty(n_vert)
    lz = np.empty(n_vert)
    xs = np.empty(12)
    ys = np.empty(12)
    xcross = np.empty((r, 12))
    cnt = np.zeros(r, dtype=np.int64)
    loc = np.empty(3)
    pa = np.empty(12)
    pb = np.empty(12)
    pc = np.empty(12)
    qa = np.empty(12)
    qb = np.empty(12)
    qc = np.empty(12)
    nl = np.empty(3)
    out = np.zeros((n_shot, n_elem))
    for s in range(n_shot):
        _shoot(points[s, 0], points[s, 1], points[s, 2],
               normals[s, 0], normals[s, 1], normals[s, 2],
               vertices, elem_verts, enrm, eoff, sctr, srad, hz, r, weights, mask, xc, zc,
               lx, ly, lz, item, zbuf, xs, ys, xcross, cnt, loc, pa, pb, pc, qa, qb, qc, nl,
               out[s])
    return out
