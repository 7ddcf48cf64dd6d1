"""Uniform subdivision of input polygons into patches and elements (docs/design.md §1, step 1).

Two kernels, one per polygon kind, fill preallocated output arrays at per-polygon offsets that
the caller computed (``np.cumsum`` of the counts), so every polygon is independent and the
output order is: polygons in input order, patches of a polygon in turn, and the elements of one
patch contiguous (``elem_patch`` is non-decreasing).

Each polygon is cut into one fine lattice (``N × M`` quads, or ``K²`` triangles); patches are
blocks of that lattice (``eu × ev`` elements, or ``ke²``). Because elements and patches come from
the same lattice, every vertex exists once per polygon and patch corners are element corners:
no T-vertex inside a polygon, and Gouraud interpolation is continuous across patch boundaries.
"""

from __future__ import annotations

from daskrad.kernels._jit import jit_leaf


@jit_leaf
def subdivide_quads(corners, nu, nv, eu, ev, vert_start, elem_start, patch_start,
                    vertices, elem_verts, elem_patch, patch_verts):
    """Split planar convex quads into ``(nu·eu) × (nv·ev)`` bilinear grids of element quads.

    Parameters
    ----------
    corners : (Q, 4, 3) float64
        Quad corners ``c0 c1 c2 c3`` in winding order. ``u`` runs along ``c0 → c1`` (and
        ``c3 → c2``), ``v`` along ``c0 → c3`` (and ``c1 → c2``).
    nu, nv : (Q,) int64
        Patches along ``u`` and ``v``.
    eu, ev : (Q,) int64
        Elements per patch along ``u`` and ``v``.
    vert_start, elem_start, patch_start : (Q,) int64
        First row of each polygon in the outputs.
    vertices : (V, 3) float64, out
        ``(N+1)(M+1)`` grid points per quad, row ``j·(N+1) + i`` for ``(u, v) = (i/N, j/M)``.
    elem_verts : (E, 4) int32, out
    elem_patch : (E,) int32, out
    patch_verts : (P, 4) int32, out

    Notes
    -----
    A line of constant ``v`` of the bilinear map is the straight segment between the points at
    ``v`` on edges ``c0c3`` and ``c1c2``; its pieces have length ``|(1-v)(c1-c0) + v(c2-c3)|/N
    ≤ max(|c1-c0|, |c2-c3|)/N`` (the norm is convex). So the caller bounds every element edge by
    choosing ``N`` from the longer of the two opposite edges. Cells keep the quad's winding since
    the map preserves orientation on a convex quad.
    """
    for q in range(corners.shape[0]):
        n = nu[q] * eu[q]
        m = nv[q] * ev[q]
        c0 = corners[q, 0]
        c1 = corners[q, 1]
        c2 = corners[q, 2]
        c3 = corners[q, 3]
        v0 = vert_start[q]
        for j in range(m + 1):
            v = j / m
            for i in range(n + 1):
                u = i / n
                # The four weights are exactly 1 or 0 at a corner, so corners are reproduced
                # bit for bit and boundary points lie on the boundary edges.
                w0 = (1.0 - u) * (1.0 - v)
                w1 = u * (1.0 - v)
                w2 = u * v
                w3 = (1.0 - u) * v
                r = v0 + j * (n + 1) + i
                for k in range(3):
                    vertices[r, k] = w0 * c0[k] + w1 * c1[k] + w2 * c2[k] + w3 * c3[k]
        e = elem_start[q]
        p = patch_start[q]
        for pj in range(nv[q]):
            for pi in range(nu[q]):
                i0 = pi * eu[q]
                j0 = pj * ev[q]
                i1 = i0 + eu[q]
                j1 = j0 + ev[q]
                patch_verts[p, 0] = v0 + j0 * (n + 1) + i0
                patch_verts[p, 1] = v0 + j0 * (n + 1) + i1
                patch_verts[p, 2] = v0 + j1 * (n + 1) + i1
                patch_verts[p, 3] = v0 + j1 * (n + 1) + i0
                for j in range(j0, j1):
                    for i in range(i0, i1):
                        elem_verts[e, 0] = v0 + j * (n + 1) + i
                        elem_verts[e, 1] = v0 + j * (n + 1) + i + 1
                        elem_verts[e, 2] = v0 + (j + 1) * (n + 1) + i + 1
                        elem_verts[e, 3] = v0 + (j + 1) * (n + 1) + i
                        elem_patch[e] = p
                        e += 1
                p += 1


@jit_leaf
def _lattice(i, j, k):
    """Row of lattice point ``(i, j)`` (``i + j ≤ k``) in a triangle's vertex block."""
    return j * (k + 1) - (j * (j - 1)) // 2 + i


@jit_leaf
def _put_tri(elem_verts, elem_patch, e, p, v0, k, i, j, up):
    """Write fine triangle ``(i, j)`` (upward or inverted) as element ``e`` of patch ``p``.

    Upward ``(i,j), (i+1,j), (i,j+1)`` and inverted ``(i+1,j), (i+1,j+1), (i,j+1)`` both turn
    the same way as ``c0, c1, c2`` in lattice coordinates, so elements keep the polygon's winding.
    """
    if up:
        elem_verts[e, 0] = v0 + _lattice(i, j, k)
        elem_verts[e, 1] = v0 + _lattice(i + 1, j, k)
        elem_verts[e, 2] = v0 + _lattice(i, j + 1, k)
    else:
        elem_verts[e, 0] = v0 + _lattice(i + 1, j, k)
        elem_verts[e, 1] = v0 + _lattice(i + 1, j + 1, k)
        elem_verts[e, 2] = v0 + _lattice(i, j + 1, k)
    elem_verts[e, 3] = -1
    elem_patch[e] = p


@jit_leaf
def subdivide_triangles(corners, kp, ke, vert_start, elem_start, patch_start,
                        vertices, elem_verts, elem_patch, patch_verts):
    """Split triangles into ``kp²`` similar patch triangles of ``ke²`` similar elements each.

    Parameters
    ----------
    corners : (Q, 3, 3) float64
        Triangle corners ``c0 c1 c2`` in winding order.
    kp : (Q,) int64
        Patch subdivisions per edge.
    ke : (Q,) int64
        Element subdivisions per patch edge; the fine lattice has ``K = kp·ke`` per edge.
    vert_start, elem_start, patch_start : (Q,) int64
        First row of each polygon in the outputs.
    vertices : (V, 3) float64, out
        ``(K+1)(K+2)/2`` lattice points per triangle, point ``(i, j)`` at
        ``((K-i-j) c0 + i c1 + j c2) / K``.
    elem_verts : (E, 4) int32, out
        Column 3 is ``-1``.
    elem_patch : (E,) int32, out
    patch_verts : (P, 4) int32, out
        Column 3 is ``-1``.

    Notes
    -----
    Every edge of the fine lattice is parallel to a triangle edge and ``1/K`` of it. A patch is
    either an upward coarse triangle or an inverted one; the inverted one is the upward shape
    mirrored through its corner ``((I+1)ke, (J+1)ke)``, so its elements are enumerated in
    mirrored coordinates (mirrored upward cells are fine inverted cells and vice versa).
    """
    for q in range(corners.shape[0]):
        k = kp[q] * ke[q]
        c0 = corners[q, 0]
        c1 = corners[q, 1]
        c2 = corners[q, 2]
        v0 = vert_start[q]
        for j in range(k + 1):
            for i in range(k + 1 - j):
                w1 = i / k
                w2 = j / k
                w0 = (k - i - j) / k
                r = v0 + _lattice(i, j, k)
                for d in range(3):
                    vertices[r, d] = w0 * c0[d] + w1 * c1[d] + w2 * c2[d]
        e = elem_start[q]
        p = patch_start[q]
        s = ke[q]
        for pj in range(kp[q]):
            for pi in range(kp[q] - pj):
                # upward patch (pi, pj)
                patch_verts[p, 0] = v0 + _lattice(pi * s, pj * s, k)
                patch_verts[p, 1] = v0 + _lattice((pi + 1) * s, pj * s, k)
                patch_verts[p, 2] = v0 + _lattice(pi * s, (pj + 1) * s, k)
                patch_verts[p, 3] = -1
                for b in range(s):
                    for a in range(s - b):
                        _put_tri(elem_verts, elem_patch, e, p, v0, k, pi * s + a, pj * s + b,
                                 True)
                        e += 1
                        if a + b <= s - 2:
                            _put_tri(elem_verts, elem_patch, e, p, v0, k, pi * s + a,
                                     pj * s + b, False)
                            e += 1
                p += 1
                if pi + pj <= kp[q] - 2:
                    # inverted patch (pi, pj), mirrored about its corner (x, y)
                    x = (pi + 1) * s
                    y = (pj + 1) * s
                    patch_verts[p, 0] = v0 + _lattice(x, pj * s, k)
                    patch_verts[p, 1] = v0 + _lattice(x, y, k)
                    patch_verts[p, 2] = v0 + _lattice(pi * s, y, k)
                    patch_verts[p, 3] = -1
                    for b in range(s):
                        for a in range(s - b):
                            _put_tri(elem_verts, elem_patch, e, p, v0, k, x - a - 1, y - b - 1,
                                     False)
                            e += 1
                            if a + b <= s - 2:
                                _put_tri(elem_verts, elem_patch, e, p, v0, k, x - a - 1,
                                         y - b - 1, True)
                                e += 1
                    p += 1
