"""The hemisphere-base form factor (Doi; DESIGN §2): an item buffer on Nusselt's disc.

From a differential area at ``p`` with unit normal ``n``, every receiving element is projected
straight onto the base disc of the unit hemisphere over ``p``:

1. Local frame with ``z = n`` (:func:`daskrad.kernels.geometry.orthonormal_basis`).
2. Cull before any rasterizing: back-facing elements (receivers are one-sided: the element's
   lit side must face ``p``, ``(p - q)·n_e > 0``) and elements wholly at or below the horizon.
3. Clip against the plane ``z = h`` in 3-D (Sutherland–Hodgman), ``h = horizon_eps · diag`` a
   tiny height *above* the tangent plane, so polygons coplanar with the shooter (its own
   polygon, the rest of the floor it stands on) vanish instead of rasterizing round-off.
4. Split each edge by inserting points **on the edge in (local) world space** until each piece
   subtends less than the threshold angle (eq. 4). Instead of recursive midpoint insertion the
   number of pieces is computed directly, ``n = ceil(angle / threshold)``, and the inserted
   points are placed at *equal angles* as seen from ``p`` (law of sines:
   ``P_k = A + s_k (B - A)``, ``s_k = |A| sin(kδ) / (|A| sin(kδ) + |B| sin((n-k)δ))``,
   ``δ = angle/n``). They are still points of the world-space edge, so projecting them gives
   points exactly on the projected curve, as midpoint insertion does; but every piece subtends
   exactly ``angle/n <= threshold`` (equal steps in world space give unequal angles, the
   largest at the end nearest ``p``), and the count needs no recursion. ``s_k`` has two
   positive terms in its denominator, so it stays well conditioned even when the edge passes
   close to ``p`` (where slerp divides by ``sin(angle) ≈ 0``).
5. Project each point ``v`` to ``(x, y) = (v.x, v.y) / |v|`` (eqs. 1–3).
6. Scan-convert into an ``R × R`` item buffer over ``[-1, 1]²`` with a depth buffer; pixels
   whose centre lies outside the unit circle are ignored.

**Shape of the projected outline.** The projection of a convex planar polygon seen from a point
off its plane is a spherically convex region; its edges are great-circle arcs, and a great
circle projects orthographically onto the base as an ellipse centred on the origin with semi-major
axis 1. The region lies on one side of each arc: the side containing the pole is the inside of the
ellipse (locally convex), the other side the outside (locally *concave*). So the projection is
convex only when every edge has the pole on the polygon's side, e.g. when the polygon contains
the zenith; in general it is not. A long thin strip low over the horizon projects to a crescent
hugging the rim, which a horizontal scanline can cross twice. Hence the raster uses general
even-odd scanline filling (all edge crossings of each row, sorted), not a convex two-edge walk.
The polygon is still *simple* (the projection is injective on the upper hemisphere), so
even-odd and non-zero filling agree.

**Watertightness.** A pixel belongs to an element when its centre lies inside the polyline
(half-open rules: a crossing is counted when ``y0 <= y < y1``, a span covers centres in
``[x_left, x_right)``). Everything derived from an edge (clip points, inserted points, scanline
crossings) is computed from its canonical endpoint (:func:`lex_less`, or the lower ``y``), so two
elements sharing an edge produce bit-identical outlines and every pixel centre goes to exactly
one of them: a closed scene leaves no hole. The edge created by the horizon clip has no
neighbour on the other side; the true region extends down to the rim there, while a polyline
chord would cut inside the circle by ``1 - cos(δ/2)`` and miss the outermost pixel centres.
So a horizon edge is replaced by a chain pushed out of the disc (radial spikes at both ends and
the inserted points scaled by ``1/cos(δ/2)``, so every chord is outside the unit circle); what
lies outside the disc is ignored anyway.

**Depth.** By default exact: for pixel direction ``d = (x, y, sqrt(1 - x² - y²))`` the distance
to the element's plane is ``t = (n_e·q) / (n_e·d)``; the buffer stores ``1/t`` (larger is nearer),
which is linear in ``d`` and needs no division per pixel. ``plane_depth=True`` reproduces the
paper's eq. 5 instead: ``|v|`` interpolated over the disc by the plane through three projected
vertices (exact only as a ranking of well-separated surfaces). Ties go to the element with the
lower index (strict comparison), so results are deterministic.

**Weights.** Every disc pixel carries the same weight ``w = 1 / n_disc`` with ``n_disc`` the
number of pixel centres inside the unit circle (replacing the paper's ``4/(π R²)``, eqs. 6–7):
the weights sum to exactly 1, each pixel has one winner, so ``Σ_j F_j <= 1`` always, ``= 1`` in a
closed scene.
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit
from daskrad.kernels.geometry import element_planes, lex_less, orthonormal_basis, scene_diagonal
from daskrad.kernels.lambert import lambert_polygon


@jit
def disc_pixels(resolution):
    """Pixel-centre coordinates and the disc mask of an ``R × R`` buffer over ``[-1, 1]²``.

    Returns
    -------
    centre : (R,) float64
        ``-1 + (2i + 1)/R``, the x (column) and y (row) coordinate of pixel centres.
    dz : (R*R,) float64
        ``sqrt(1 - x² - y²)`` at each pixel centre (row-major, ``index = row*R + column``), or
        ``-1`` where the centre lies outside the unit circle. No centre lies exactly on the
        circle: with ``a = 2i + 1 - R`` a centre is ``(a, b)/R``; for even ``R``, ``a`` and ``b``
        are odd and ``a² + b² ≡ 2 (mod 4)`` while ``R² ≡ 0``; for odd ``R`` they are even and
        ``a² + b²`` is even while ``R²`` is odd. So inside/outside is never a round-off call.
    n_disc : int
        Number of centres strictly inside the unit circle.
    """
    r = resolution
    centre = np.empty(r)
    for i in range(r):
        centre[i] = -1.0 + (2.0 * i + 1.0) / r
    dz = np.empty(r * r)
    n_disc = 0
    for j in range(r):
        for i in range(r):
            q = 1.0 - centre[i] * centre[i] - centre[j] * centre[j]
            if q > 0.0:
                dz[j * r + i] = np.sqrt(q)
                n_disc += 1
            else:
                dz[j * r + i] = -1.0
    return centre, dz, n_disc


@jit
def split_table(edge_angle):
    """Table for :func:`_emit_edge`: ``[0]`` is ``sin(thr)``, ``[k]`` is ``cos(k·thr)`` for
    ``1 <= k < K`` and ``[K] = -2`` (``K = ceil(π/thr)``: no straight edge subtends more), so the
    piece count of an edge follows from its cosine by a search, with no trigonometry per edge.
    ``edge_angle`` (= thr) in radians, in ``(0, π/2]``."""
    k_max = int(np.ceil(np.pi / edge_angle))
    tab = np.empty(k_max + 1)
    tab[0] = np.sin(edge_angle)
    for k in range(1, k_max):
        tab[k] = np.cos(k * edge_angle)
    tab[k_max] = -2.0
    return tab


@jit
def unit(x, y, z):
    """``v / |v|``: the one expression every projection uses (eqs. 1–3), so a corner shared by
    two elements, or projected once per vertex and once after a clip, gives the same bits."""
    r = np.sqrt(x * x + y * y + z * z)
    if not r > 0.0:
        return 0.0, 0.0, 0.0  # the shooting point itself (on its own polygon): never projected
    return x / r, y / r, z / r


@jit
def unit_vectors(lx, ly, lz, ux, uy, uz):
    """Per-vertex directions :func:`unit` into ``ux, uy, uz (V,)``, once per shot (a vertex is
    shared by about four elements); ``(ux, uy)`` is the vertex's point on the disc."""
    for v in range(lx.shape[0]):
        ux[v], uy[v], uz[v] = unit(lx[v], ly[v], lz[v])


@jit
def _emit_edge(ax, ay, az, uax, uay, uaz, bx, by, bz, ubx, uby, ubz, horizon, cos_thr, tab,
               xs, ys, m):
    """Append the projected polyline of the edge ``a → b`` (without ``b``) to ``xs, ys``.

    ``a, b`` are the endpoints in the local frame (their lexicographic order picks the canonical
    endpoint), ``ua, ub`` their directions :func:`unit` (computed by the same expression for
    every element, so shared corners project to bit-identical points). Returns the new length.
    ``horizon`` marks the edge made by the horizon clip, which is pushed out of the disc (see
    the module docstring). ``tab`` is :func:`split_table`.

    The edge subtends ``θ`` at the origin; it is split into ``n = ceil(θ/thr)`` pieces (eq. 4):
    points at the angles ``k·thr`` (``k < n``) from the canonical endpoint ``c``, so every piece
    subtends ``thr`` except the last, which subtends ``θ - (n-1) thr <= thr``. The point of the
    edge at angle ``φ`` from ``c`` projects to the unit vector ``cos φ ĉ + sin φ ê`` (``ê`` the unit
    vector perpendicular to ``ĉ`` in the plane through the edge and the origin), so the
    projection (eqs. 1–3) is just its ``(x, y)``: no point on the edge, no square root per point;
    ``cos(k·thr), sin(k·thr)`` follow by the rotation recurrence (round-off ``~k ε``).
    """
    xs[m] = uax
    ys[m] = uay
    m += 1
    cos_theta = uax * ubx + uay * uby + uaz * ubz  # symmetric in a, b: same for a neighbour
    split = cos_theta < cos_thr
    if not split and not horizon:
        return m
    # Canonical endpoint first, so a neighbour traversing b → a computes identical points.
    swap = lex_less(bx, by, bz, ax, ay, az)
    if swap:
        cx, cy, cz = ubx, uby, ubz
        dx, dy, dz_ = uax, uay, uaz
    else:
        cx, cy, cz = uax, uay, uaz
        dx, dy, dz_ = ubx, uby, ubz
    n = 1
    if split:
        # smallest n with cos θ >= cos(n·thr), i.e. θ <= n·thr (tab is decreasing)
        lo = 1
        hi = tab.shape[0] - 1
        while lo < hi:
            mid = (lo + hi) // 2
            if cos_theta >= tab[mid]:
                hi = mid
            else:
                lo = mid + 1
        n = max(lo, 2)
    if horizon:
        # Every chord of the pushed-out chain stays outside the unit circle: a chord
        # subtending φ lies cos(φ/2) from the centre, φ <= thr when split, θ otherwise.
        if split:
            scale = 1.0 / np.sqrt(0.5 * (1.0 + tab[1]))
        else:
            scale = 1.0 / np.sqrt(0.5 * (1.0 + min(cos_theta, 1.0)))
        # Radial spike out of a (in traversal order a first).
        xs[m] = scale * uax
        ys[m] = scale * uay
        m += 1
    else:
        scale = 1.0
    if n > 1:
        gx = cy * dz_ - cz * dy
        gy = cz * dx - cx * dz_
        gz = cx * dy - cy * dx
        g = np.sqrt(gx * gx + gy * gy + gz * gz)
        if g > 0.0:
            # ĉ and ê = (g × ĉ) / |g|, both unit; g = ĉ × d̂ is normal to the edge's plane.
            ex = (gy * cz - gz * cy) / g
            ey = (gz * cx - gx * cz) / g
            cd = tab[1]
            sd = tab[0]
            ck = 1.0
            sk = 0.0
            for k in range(1, n):
                ck, sk = ck * cd - sk * sd, sk * cd + ck * sd
                pos = m + (n - 1 - k if swap else k - 1)
                xs[pos] = scale * (ck * cx + sk * ex)
                ys[pos] = scale * (ck * cy + sk * ey)
            m += n - 1
    if horizon:
        # Radial spike back in to b (b itself is emitted by the next edge).
        xs[m] = scale * ubx
        ys[m] = scale * uby
        m += 1
    return m


@jit
def project_element(e, sx, sy, sz, elem_verts, enrm, eoff, lx, ly, lz, ux, uy, uz, hz,
                    cos_thr, tab, cx, cy, cz, qx, qy, qz, qclip, wu, xs, ys):
    """Steps 2–5 for element ``e``: cull, clip at ``z = hz``, split edges, project.

    ``lx, ly, lz : (V,) float64`` are the vertices in the shooter's local frame and ``ux, uy, uz``
    their directions (:func:`unit_vectors`); ``cx, cy, cz (5,)`` and ``wu (3, 5)`` are scratch.
    On return ``qx, qy, qz, qclip (5,)`` hold the ``m`` clipped corners (local frame; ``qclip``
    marks points made by the horizon clip) and ``xs, ys`` the ``mm`` points of the projected
    polyline (eqs. 1–4).

    Returns ``(m, mm, c)`` with ``c = n_e · (q - p) < 0`` for a front-facing element; ``mm = 0``
    when the element is culled (back-facing, at or below the horizon, degenerate after clip).
    """
    # c = n_e · (q - p) < 0  <=>  p on the lit side (one-sided receiver).
    c = eoff[e] - (enrm[e, 0] * sx + enrm[e, 1] * sy + enrm[e, 2] * sz)
    if not c < 0.0:
        return 0, 0, c
    k = 4 if elem_verts[e, 3] >= 0 else 3
    zmax = -np.inf
    zmin = np.inf
    for a in range(k):
        z = lz[elem_verts[e, a]]
        zmax = max(zmax, z)
        zmin = min(zmin, z)
    if zmax <= hz:
        return 0, 0, c
    # --- clip against z = hz (keep z > hz) ------------------------------------------------
    m = 0
    if zmin > hz:
        # wholly above (the common case): the per-vertex directions as they are
        for a in range(k):
            vi = elem_verts[e, a]
            qx[a] = lx[vi]
            qy[a] = ly[vi]
            qz[a] = lz[vi]
            qclip[a] = False
            wu[0, a] = ux[vi]
            wu[1, a] = uy[vi]
            wu[2, a] = uz[vi]
        m = k
    else:
        for a in range(k):
            vi = elem_verts[e, a]
            cx[a] = lx[vi]
            cy[a] = ly[vi]
            cz[a] = lz[vi]
        for a in range(k):
            b = a + 1 if a + 1 < k else 0
            ina = cz[a] > hz
            if ina:
                qx[m] = cx[a]
                qy[m] = cy[a]
                qz[m] = cz[a]
                qclip[m] = False
                m += 1
            if ina != (cz[b] > hz):
                if lex_less(cx[a], cy[a], cz[a], cx[b], cy[b], cz[b]):
                    i0 = a
                    i1 = b
                else:
                    i0 = b
                    i1 = a
                t = (hz - cz[i0]) / (cz[i1] - cz[i0])
                qx[m] = cx[i0] + t * (cx[i1] - cx[i0])
                qy[m] = cy[i0] + t * (cy[i1] - cy[i0])
                qz[m] = hz
                qclip[m] = True
                m += 1
        # kept corners get the bits of unit_vectors (same expression, same inputs)
        for a in range(m):
            wu[0, a], wu[1, a], wu[2, a] = unit(qx[a], qy[a], qz[a])
    if m < 3:
        return m, 0, c
    # --- projected polyline (eqs. 1–4) ----------------------------------------------------
    mm = 0
    for a in range(m):
        b = a + 1 if a + 1 < m else 0
        mm = _emit_edge(qx[a], qy[a], qz[a], wu[0, a], wu[1, a], wu[2, a],
                        qx[b], qy[b], qz[b], wu[0, b], wu[1, b], wu[2, b],
                        qclip[a] and qclip[b], cos_thr, tab, xs, ys, mm)
    return m, mm, c


@jit
def depth_coefficients(plane_depth, qx, qy, qz, m, nlx, nly, nlz, c):
    """Nearness (larger is nearer) at disc point ``(x, y)`` as ``da x + db y + dc + de √(1-x²-y²)``.

    Exact (default): ``1/t = (n_l · d) / c`` with ``n_l = (nlx, nly, nlz)`` the element's normal
    in the local frame and ``c = n_e · (q - p)``. ``plane_depth``: minus the paper's eq. 5, ``|v|``
    interpolated linearly over the disc through three well-spread projected corners of the
    clipped polygon ``q (m,)``. Returns ``(da, db, dc, de)``.
    """
    if not plane_depth:
        return nlx / c, nly / c, 0.0, nlz / c
    dep0 = np.sqrt(qx[0] ** 2 + qy[0] ** 2 + qz[0] ** 2)
    x0 = qx[0] / dep0
    y0 = qy[0] / dep0
    best = -1.0
    i1 = 1
    for a in range(1, m):
        ra_ = np.sqrt(qx[a] ** 2 + qy[a] ** 2 + qz[a] ** 2)
        d2 = (qx[a] / ra_ - x0) ** 2 + (qy[a] / ra_ - y0) ** 2
        if d2 > best:
            best = d2
            i1 = a
    dep1 = np.sqrt(qx[i1] ** 2 + qy[i1] ** 2 + qz[i1] ** 2)
    x1 = qx[i1] / dep1 - x0
    y1 = qy[i1] / dep1 - y0
    best = -1.0
    i2 = 2
    for a in range(1, m):
        ra_ = np.sqrt(qx[a] ** 2 + qy[a] ** 2 + qz[a] ** 2)
        ar = abs(x1 * (qy[a] / ra_ - y0) - y1 * (qx[a] / ra_ - x0))
        if ar > best:
            best = ar
            i2 = a
    dep2 = np.sqrt(qx[i2] ** 2 + qy[i2] ** 2 + qz[i2] ** 2)
    x2 = qx[i2] / dep2 - x0
    y2 = qy[i2] / dep2 - y0
    det = x1 * y2 - x2 * y1
    if det != 0.0:
        da = ((dep1 - dep0) * y2 - (dep2 - dep0) * y1) / det
        db = (x1 * (dep2 - dep0) - x2 * (dep1 - dep0)) / det
    else:
        da = 0.0
        db = 0.0
    dc = dep0 - da * x0 - db * y0
    # nearness = -depth
    return -da, -db, -dc, 0.0


@jit
def _holds_centre(lo, hi, cen, n, origin, inv_p):
    """Whether a pixel centre ``cen[i]`` lies in ``[lo - w, hi + w]``, ``w = 1e-9 (hi - lo) +
    1e-12`` (``cen[i] = origin + (i + 1/2) / inv_p``)."""
    w = 1e-9 * (hi - lo) + 1e-12
    lo -= w
    hi += w
    t = min(max((lo - origin) * inv_p - 0.5, 0.0), n - 1.0)  # clamped before int(): no overflow
    i = int(np.ceil(t))
    while i > 0 and cen[i - 1] >= lo:
        i -= 1
    while i < n and cen[i] < lo:
        i += 1
    return i < n and cen[i] <= hi


@jit
def fill_polygon(xs, ys, mm, e, xc, yc, ncol, nrow, x0, inv_px, y0, inv_py, mask,
                 da, db, dc, de, xcross, cnt, item, zbuf):
    """Even-odd scan conversion of the closed polyline ``xs, ys (mm,)`` into a z-buffer.

    The shared rasterizer of the hemisphere base and the hemicube faces. The buffer has
    ``nrow × ncol`` pixels, row-major; pixel ``(j, i)`` has its centre at ``(xc[i], yc[j])``,
    ``xc[i] = x0 + (i + 1/2) / inv_px`` (likewise ``y``). A pixel whose ``mask`` is negative is
    skipped (outside the unit disc); the nearness there is ``da x + db y + dc + de mask``
    (``mask = √(1-x²-y²)`` on the disc, so :func:`depth_coefficients` applies as is). Nearer
    (strictly larger) wins, so ties go to the element drawn first. Half-open rules make shared
    edges watertight (module docstring). ``xcross (nrow, >= mm)`` and ``cnt (nrow,)`` are
    scratch: each segment drops its crossings into the rows it spans (an edge table), so the
    cost is the number of segments plus crossings, not segments × rows. Returns the number of
    unmasked pixels covered.
    """
    xmin = np.inf
    xmax = -np.inf
    ymin = np.inf
    ymax = -np.inf
    for a in range(mm):
        xmin = min(xmin, xs[a])
        xmax = max(xmax, xs[a])
        ymin = min(ymin, ys[a])
        ymax = max(ymax, ys[a])
    # Bounding-box reject: a covered centre lies in [min, max) on both axes. Only a box that
    # holds no centre column or no centre row even when widened by 1e-9 of its size (far
    # above the round-off of the crossings) is rejected, so the decision never differs from
    # the exact half-open rules below.
    if not _holds_centre(xmin, xmax, xc, ncol, x0, inv_px):
        return 0
    if not _holds_centre(ymin, ymax, yc, nrow, y0, inv_py):
        return 0
    j0 = max(int(np.ceil((ymin - y0) * inv_py - 0.5)) - 1, 0)
    j1 = min(int(np.floor((ymax - y0) * inv_py - 0.5)) + 1, nrow - 1)
    if j0 > j1:
        return 0
    for j in range(j0, j1 + 1):
        cnt[j] = 0
    for a in range(mm):
        b = a + 1 if a + 1 < mm else 0
        # the lower endpoint first: a shared edge gives bit-identical crossings both ways
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
        # candidate rows with one row of slack; the half-open test below decides exactly
        ja = max(int(np.ceil((ylo - y0) * inv_py - 0.5)) - 1, j0)
        jb = min(int(np.floor((yhi - y0) * inv_py - 0.5)) + 1, j1)
        for j in range(ja, jb + 1):
            ycj = yc[j]
            if ylo <= ycj < yhi:
                xcross[j, cnt[j]] = xs[lo] + (ycj - ylo) * slope
                cnt[j] += 1
    cov = 0
    for j in range(j0, j1 + 1):
        nc = cnt[j]
        if nc < 2:
            continue
        for a in range(1, nc):  # insertion sort: nc is almost always 2
            x = xcross[j, a]
            b = a - 1
            while b >= 0 and xcross[j, b] > x:
                xcross[j, b + 1] = xcross[j, b]
                b -= 1
            xcross[j, b + 1] = x
        row = j * ncol
        rowterm = db * yc[j] + dc
        for a in range(0, nc - 1, 2):
            i_lo = max(int(np.ceil((xcross[j, a] - x0) * inv_px - 0.5)), 0)
            i_hi = min(int(np.ceil((xcross[j, a + 1] - x0) * inv_px - 0.5)) - 1, ncol - 1)
            for i in range(i_lo, i_hi + 1):
                idx = row + i
                mv = mask[idx]
                if mv < 0.0:
                    continue
                cov += 1
                near = da * xc[i] + rowterm + de * mv
                if near > zbuf[idx]:
                    zbuf[idx] = near
                    item[idx] = e
    return cov


@jit
def local_frame(sx, sy, sz, snx, sny, snz, vertices, lx, ly, lz):
    """Vertices in the shooter's frame ``(t1, t2, n)`` into ``lx, ly, lz (V,)``; returns the
    tangents ``(t1x, t1y, t1z, t2x, t2y, t2z)``."""
    t1x, t1y, t1z, t2x, t2y, t2z = orthonormal_basis(snx, sny, snz)
    for v in range(vertices.shape[0]):
        wx = vertices[v, 0] - sx
        wy = vertices[v, 1] - sy
        wz = vertices[v, 2] - sz
        lx[v] = t1x * wx + t1y * wy + t1z * wz
        ly[v] = t2x * wx + t2y * wy + t2z * wz
        lz[v] = snx * wx + sny * wy + snz * wz
    return t1x, t1y, t1z, t2x, t2y, t2z


@jit
def element_spheres(vertices, elem_verts):
    """Bounding sphere of every element, per call (it does not depend on the shooter).

    Returns ``centre : (E, 3) float64`` (the mean of the corners) and ``radius : (E,) float64``
    (the largest corner distance, rounded up by a relative 1e-12 so that the sphere test below
    never culls an element one of whose corners lies above the horizon).
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
        radius[e] = np.sqrt(r2) * (1.0 + 1e-12) + 1e-300
    return centre, radius


@jit
def _shoot(sx, sy, sz, snx, sny, snz, vertices, elem_verts, enrm, eoff, sctr, srad, hz,
           resolution, centre, dz, cos_thr, tab, plane_depth, want_f,
           lx, ly, lz, ux, uy, uz, item, zbuf, xs, ys, xcross, cnt, gx, gy, gz, scr, qclip,
           wu, won, covered, visible, f):
    """One shot: fill ``won (E,)``, ``covered (E,)`` (int32) and ``visible (E,)`` (bool), all
    zeroed by the caller; ``gx, gy, gz (E,)``, ``scr (12, 5)`` and ``qclip (5,) bool`` are
    scratch.

    With ``want_f`` also the anti-aliased form factors into ``f (E,)`` (zeroed by the caller):
    ``L · won/covered``, or ``L`` for a visible element too small to cover a pixel centre; Lambert's
    ``L`` (:func:`daskrad.kernels.lambert.lambert_polygon`, in the local frame) is evaluated only
    for the elements that won a pixel or passed that sub-pixel test, after the buffer is complete.
    Returns the number of disc pixels won by some element (``n_disc``: a closed view).

    Culling before any per-element work: back-facing (one dot product with the element's
    plane) and bounding sphere at or below the horizon (one dot product), then the corners.
    """
    r = resolution
    half_r = 0.5 * r
    t1x, t1y, t1z, t2x, t2y, t2z = local_frame(sx, sy, sz, snx, sny, snz, vertices, lx, ly, lz)
    unit_vectors(lx, ly, lz, ux, uy, uz)
    sdotn = snx * sx + sny * sy + snz * sz
    for k in range(r * r):
        item[k] = -1
        zbuf[k] = -np.inf
    cx = scr[0]
    cy = scr[1]
    cz = scr[2]
    qx = scr[3]
    qy = scr[4]
    qz = scr[5]
    n_elem = elem_verts.shape[0]
    n_small = 0
    for e in range(n_elem):
        # back-facing: p not strictly on the lit side (one-sided receiver)
        c = eoff[e] - (enrm[e, 0] * sx + enrm[e, 1] * sy + enrm[e, 2] * sz)
        if not c < 0.0:
            continue
        # bounding sphere at or below the horizon z = hz: no corner above it
        if snx * sctr[e, 0] + sny * sctr[e, 1] + snz * sctr[e, 2] - sdotn + srad[e] <= hz:
            continue
        m, mm, c = project_element(e, sx, sy, sz, elem_verts, enrm, eoff, lx, ly, lz, ux, uy,
                                   uz, hz, cos_thr, tab, cx, cy, cz, qx, qy, qz, qclip, wu,
                                   xs, ys)
        if m < 3:
            continue
        cov = 0
        if mm > 0:
            nlx = t1x * enrm[e, 0] + t1y * enrm[e, 1] + t1z * enrm[e, 2]
            nly = t2x * enrm[e, 0] + t2y * enrm[e, 1] + t2z * enrm[e, 2]
            nlz = snx * enrm[e, 0] + sny * enrm[e, 1] + snz * enrm[e, 2]
            da, db, dc, de = depth_coefficients(plane_depth, qx, qy, qz, m, nlx, nly, nlz, c)
            cov = fill_polygon(xs, ys, mm, e, centre, centre, r, r, -1.0, half_r, -1.0, half_r,
                               dz, da, db, dc, de, xcross, cnt, item, zbuf)
        covered[e] = cov
        if cov == 0:
            # Too small to hold a pixel centre: remember the direction of its (clipped)
            # centroid for the visibility test below, once the buffer is complete.
            mx = 0.0
            my = 0.0
            mz = 0.0
            for a in range(m):
                mx += qx[a]
                my += qy[a]
                mz += qz[a]
            gx[n_small] = mx
            gy[n_small] = my
            gz[n_small] = mz
            covered[e] = -1 - n_small  # temporary marker: slot of the direction
            n_small += 1
    n_won = 0
    for k in range(r * r):
        if item[k] >= 0:
            won[item[k]] += 1
            n_won += 1
    if n_small > 0:
        _small_visibility(n_small, sx, sy, sz, snx, sny, snz, t1x, t1y, t1z, t2x, t2y, t2z,
                          enrm, eoff, r, dz, item, gx, gy, gz, covered, visible)
    if want_f:
        for e in range(n_elem):
            if won[e] > 0:
                frac = won[e] / covered[e]
            elif covered[e] == 0 and visible[e]:
                frac = 1.0
            else:
                continue
            k = 4 if elem_verts[e, 3] >= 0 else 3
            for a in range(k):
                vi = elem_verts[e, a]
                cx[a] = lx[vi]
                cy[a] = ly[vi]
                cz[a] = lz[vi]
            lam = lambert_polygon(cx, cy, cz, k, 0.0, 0.0, 1.0, scr[7], scr[8], scr[9], scr[10])
            f[e] = lam * frac
    return n_won


@jit
def _small_visibility(n_small, sx, sy, sz, snx, sny, snz, t1x, t1y, t1z, t2x, t2y, t2z,
                      enrm, eoff, r, dz, item, gx, gy, gz, covered, visible):
    """Elements that cover no pixel centre (``covered`` holds ``-1 - slot``): visible when no
    other element's plane lies nearer along the direction of their centroid, at the pixel
    nearest to it. Both nearnesses are exact (1/t along the same direction), also with
    plane_depth, so a small element lying in the plane of the pixel's winner (a neighbour on
    the same wall) ties and counts visible. Resets ``covered`` to 0 for them."""
    half_r = 0.5 * r
    for e in range(covered.shape[0]):
        if covered[e] >= 0:
            continue
        slot = -1 - covered[e]
        covered[e] = 0
        mx = gx[slot]
        my = gy[slot]
        mz = gz[slot]
        norm = np.sqrt(mx * mx + my * my + mz * mz)
        if not norm > 0.0:
            continue
        mx /= norm
        my /= norm
        mz /= norm
        i = min(max(int(np.floor((mx + 1.0) * half_r)), 0), r - 1)
        j = min(max(int(np.floor((my + 1.0) * half_r)), 0), r - 1)
        w = item[j * r + i]
        if dz[j * r + i] < 0.0 or w < 0:
            visible[e] = True  # no information there (the rim, or an empty pixel)
            continue
        own = _nearness(e, mx, my, mz, sx, sy, sz, enrm, eoff, t1x, t1y, t1z, t2x, t2y, t2z,
                        snx, sny, snz)
        other = _nearness(w, mx, my, mz, sx, sy, sz, enrm, eoff, t1x, t1y, t1z, t2x, t2y,
                          t2z, snx, sny, snz)
        visible[e] = not (other > own * (1.0 + 1e-9))


@jit
def _nearness(e, dx, dy, dz_, sx, sy, sz, enrm, eoff, t1x, t1y, t1z, t2x, t2y, t2z,
              snx, sny, snz):
    """``1/t`` along the local unit direction ``d`` to the plane of element ``e`` (<= 0 when
    the plane lies behind)."""
    c = eoff[e] - (enrm[e, 0] * sx + enrm[e, 1] * sy + enrm[e, 2] * sz)
    if c == 0.0:
        return 0.0
    nlx = t1x * enrm[e, 0] + t1y * enrm[e, 1] + t1z * enrm[e, 2]
    nly = t2x * enrm[e, 0] + t2y * enrm[e, 1] + t2z * enrm[e, 2]
    nlz = snx * enrm[e, 0] + sny * enrm[e, 1] + snz * enrm[e, 2]
    return (nlx * dx + nly * dy + nlz * dz_) / c


@jit
def edge_capacity(edge_angle):
    """Length of the polyline buffers: a straight edge subtends < 180°, so it gives at most
    ``ceil(π/thr)`` pieces, plus the two spikes of a horizon edge; a clipped quad has at most
    5 edges."""
    per_edge = int(np.ceil(np.pi / edge_angle)) + 3
    return 5 * per_edge + 8


@jit
def _hemisphere_pass(points, normals, vertices, elem_verts, resolution, edge_angle,
                     plane_depth, horizon_eps, want_f):
    """Every shot of one call; buffers and per-element data are set up once per call."""
    n_shot = points.shape[0]
    n_elem = elem_verts.shape[0]
    n_vert = vertices.shape[0]
    r = resolution
    enrm, eoff = element_planes(vertices, elem_verts)
    sctr, srad = element_spheres(vertices, elem_verts)
    hz = max(horizon_eps * scene_diagonal(vertices), 1e-300)
    centre, dz, n_disc = disc_pixels(r)
    # Buffers allocated once per call, reused by every shot and element.
    item = np.empty(r * r, dtype=np.int32)
    zbuf = np.empty(r * r)
    lx = np.empty(n_vert)
    ly = np.empty(n_vert)
    lz = np.empty(n_vert)
    ux = np.empty(n_vert)
    uy = np.empty(n_vert)
    uz = np.empty(n_vert)
    wu = np.empty((3, 5))
    cap = edge_capacity(edge_angle)
    xs = np.empty(cap)
    ys = np.empty(cap)
    xcross = np.empty((r, cap))
    cnt = np.zeros(r, dtype=np.int64)
    gx = np.empty(n_elem)
    gy = np.empty(n_elem)
    gz = np.empty(n_elem)
    scr = np.zeros((12, 5))
    qclip = np.zeros(5, dtype=np.bool_)
    won = np.zeros((n_shot, n_elem), dtype=np.int32)
    covered = np.zeros((n_shot, n_elem), dtype=np.int32)
    visible = np.zeros((n_shot, n_elem), dtype=np.bool_)
    f = np.zeros((n_shot if want_f else 1, n_elem))
    closed = np.zeros(n_shot, dtype=np.bool_)
    cos_thr = np.cos(edge_angle)
    tab = split_table(edge_angle)
    for s in range(n_shot):
        row = s if want_f else 0
        n_won = _shoot(points[s, 0], points[s, 1], points[s, 2],
                       normals[s, 0], normals[s, 1], normals[s, 2],
                       vertices, elem_verts, enrm, eoff, sctr, srad, hz, r, centre, dz,
                       cos_thr, tab, plane_depth, want_f, lx, ly, lz, ux, uy, uz, item, zbuf,
                       xs, ys, xcross, cnt, gx, gy, gz, scr, qclip, wu, won[s], covered[s],
                       visible[s],
                       f[row])
        closed[s] = n_won == n_disc
    return won, covered, n_disc, visible, f, closed


@jit
def hemisphere_visibility(points, normals, vertices, elem_verts, resolution, edge_angle,
                          plane_depth, horizon_eps):
    """:func:`hemisphere_shots` plus ``visible : (S, E) bool``.

    ``visible[s, e]`` is set only for elements that cover no pixel centre (``covered == 0``)
    but reach above the horizon: whether the element is in front at the pixel nearest to the
    direction of its centroid (see :func:`_small_visibility`). It lets the anti-aliased method
    give such elements their analytic form factor instead of 0.

    Returns ``(won, covered, n_disc, visible)``.
    """
    won, covered, n_disc, visible, _, _ = _hemisphere_pass(
        points, normals, vertices, elem_verts, resolution, edge_angle, plane_depth,
        horizon_eps, False)
    return won, covered, n_disc, visible


@jit
def hemisphere_factors(points, normals, vertices, elem_verts, resolution, edge_angle,
                       plane_depth, horizon_eps):
    """Anti-aliased hemisphere-base form factors (the default method), fused in one pass.

    ``F[s, e] = L · won / covered`` (``L`` for a visible element covering no pixel centre, 0
    for a hidden one), with Lambert's ``L`` evaluated only where ``F`` can be nonzero
    (:func:`_shoot`). Arguments as :func:`hemisphere_shots`.

    Returns
    -------
    f : (S, E) float64
        Before the conservation scaling of :func:`daskrad.formfactor.hemisphere_rows`.
    closed : (S,) bool
        Every disc pixel won by some element: a closed view, whose exact row sums to 1.
    """
    _, _, _, _, f, closed = _hemisphere_pass(points, normals, vertices, elem_verts,
                                             resolution, edge_angle, plane_depth,
                                             horizon_eps, True)
    return f, closed


@jit
def hemisphere_shots(points, normals, vertices, elem_verts, resolution, edge_angle,
                     plane_depth, horizon_eps):
    """Hemisphere-base item buffer from each shooting point to all elements (DESIGN §2).

    Parameters
    ----------
    points : (S, 3) float64
        Positions of the differential shooting areas.
    normals : (S, 3) float64
        Their unit normals.
    vertices : (V, 3) float64
    elem_verts : (E, 4) int32
        Corner indices, counter-clockwise seen from the lit side (planar convex polygons);
        ``-1`` in column 3 for a triangle.
    resolution : int
        Side ``R`` of the item buffer over ``[-1, 1]²``.
    edge_angle : float
        Threshold angle, **radians**, each polyline piece of a projected edge may subtend
        (eq. 4).
    plane_depth : bool
        Depth by the paper's eq. 5 instead of the exact ray–plane distance.
    horizon_eps : float
        Clip height above the tangent plane, relative to the scene's bounding-box diagonal.

    Returns
    -------
    won : (S, E) int32
        Pixels each element owns after hidden-surface removal; ``F = won / n_disc``.
    covered : (S, E) int32
        Disc pixels each element covers before the depth test (``won <= covered``).
    n_disc : int
        Pixel centres inside the unit circle; every disc pixel weighs ``1/n_disc``, so the
        weights sum to exactly 1 (``Σ_j F_j <= 1``, ``= 1`` in a closed scene).
    """
    won, covered, n_disc, _ = hemisphere_visibility(points, normals, vertices, elem_verts,
                                                    resolution, edge_angle, plane_depth,
                                                    horizon_eps)
    return won, covered, n_disc
