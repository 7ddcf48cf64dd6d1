"""The written-out kernel twins give the same bits as their composed forms (issue 11, item 4).

Three hot loops write out, in one function, the bodies of smaller public kernels, because a numba
call per element costs more than a typical element's work (measured: ``inline='always'`` +23-56 %,
a plain shared helper +28-96 %). The comments beside them say "same arithmetic in the same
order"; these tests hold them to it, with ``np.array_equal`` (no tolerance) over random
configurations and edge cases:

- the hemisphere item buffer (``kernels/hemisphere.py``, the per-element loop of its shot) against
  :func:`project_element` (cull, horizon clip, edge split, projection), :func:`depth_coefficients`
  and :func:`fill_polygon` (scan conversion), composed below per element with the item buffer's
  one documented addition, the :data:`DEPTH_TIE` margin of its depth test;
- the hemicube (``kernels/hemicube.py``), whose per-face scan conversion is ``fill_polygon``'s
  body, against a composed shot: the same face frames and Sutherland-Hodgman clips (written here
  from their definition, since the hemicube's own are private), then ``fill_polygon`` itself.
  The composed shot clips every element against every face, without the hemicube's shortcuts
  (bounding-sphere cull, per-face outcodes), so it also checks that those skip nothing;
- Lambert's batch kernel (:func:`lambert_shots`, :func:`lambert_masked`), whose clip and contour
  sum are written out, against the single-polygon :func:`lambert_polygon`.

The scanline method has no twin: it calls ``project_element`` itself and its span sweep has no
counterpart.

What the comparison sees: the public outputs, bit for bit. The item buffer shows through the
``won`` and ``covered`` counts per element and the ``visible`` fraction (continuous in the
clipped corners, so it sees the clip's bits); the hemicube through its sums of delta form
factors. A projected outline moved by an ulp changes a count only where it passes exactly
through a pixel centre, which the closed box seen from its centre at odd resolutions provokes
(its grid lines project onto the axes). Deliberate changes were caught this way, each alone:
in the written-out bodies the clip's canonical endpoint, the span rounding at exact pixel
centres, the centroid's summation order and Lambert's contour term order; in the composed
form the split count and the depth tie. ``x / r`` → ``x * (1 / r)`` in a projection went
unseen: no output in these cases depends on those ulps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from daskrad import tolerances
from daskrad.kernels.geometry import element_planes, lex_less, scene_diagonal
from daskrad.kernels.hemicube import delta_form_factors, hemicube_shots, side_rows
from daskrad.kernels.hemisphere import (
    depth_coefficients,
    disc_pixels,
    edge_capacity,
    fill_polygon,
    hemisphere_visibility,
    local_frame,
    project_element,
    project_scratch,
    split_table,
)
from daskrad.kernels.lambert import lambert_masked, lambert_polygon, lambert_shots
from tests.helpers import closed_box, grid, merge

EDGE = math.radians(tolerances.EDGE_ANGLE_DEG)
HORIZON = tolerances.HORIZON_EPS
DEPTH_TIE = tolerances.DEPTH_TIE


# --- configurations -------------------------------------------------------------------------

def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def random_elements(rng, n, spread=2.0):
    """``n`` random elements around the origin, half triangles and half planar quads
    (parallelograms), sizes log-uniform over five decades (``1e-4`` to ``10``): tiny and huge
    beside each other. Returns ``vertices (V, 3)``, ``elem_verts (n, 4) int32``."""
    verts, elems = [], []
    for e in range(n):
        centre = rng.normal(size=3) * spread
        size = 10.0 ** rng.uniform(-4.0, 1.0)
        u = rng.normal(size=3) * size
        v = rng.normal(size=3) * size
        base = len(verts)
        if e % 2:
            verts += [centre, centre + u, centre + u + v, centre + v]
            elems.append([base, base + 1, base + 2, base + 3])
        else:
            verts += [centre, centre + u, centre + v]
            elems.append([base, base + 1, base + 2, -1])
    return np.array(verts), np.array(elems, dtype=np.int32)


def random_shooters(rng, n, spread=2.0):
    """``n`` random points and unit normals: ``points (n, 3)``, ``normals (n, 3)``."""
    return rng.normal(size=(n, 3)) * spread, _unit(rng.normal(size=(n, 3)))


def straddling(rng, n):
    """Elements around shooters at the origin facing ``+z``: every one crosses the tangent plane
    (corners above and below it), some through the shooter's own point, some lying in the
    plane. Returns ``vertices, elem_verts, points (4, 3), normals (4, 3)``."""
    verts, elems = random_elements(rng, n, spread=0.5)
    # shift each element along z so that the plane z = 0 cuts it (elements stay planar)
    verts = verts.copy()
    for ev in elems:
        k = ev[ev >= 0]
        lo, hi = verts[k, 2].min(), verts[k, 2].max()
        verts[k, 2] -= lo + (hi - lo) * rng.uniform(0.1, 0.9)
    # a triangle with a corner at the shooter, one lying in its tangent plane, one exactly
    # on the horizon with its other corners above
    extra = np.array([[0, 0, 0], [1, 0.2, 0.5], [0.3, 1, -0.4],
                      [0.2, 0.1, 0], [0.9, 0.3, 0], [0.4, 0.8, 0],
                      [-0.5, 0.2, 0], [-0.2, 0.6, 0.3], [-0.9, 0.4, 0.7]], float)
    base = len(verts)
    verts = np.concatenate([verts, extra])
    tris = np.array([[base, base + 1, base + 2, -1], [base + 3, base + 4, base + 5, -1],
                     [base + 6, base + 7, base + 8, -1]], dtype=np.int32)
    # each triangle twice, once per winding: one of the two faces the shooter
    elems = np.concatenate([elems, tris, tris[:, [0, 2, 1, 3]]])
    points = np.zeros((4, 3))
    points[1:, :2] = rng.normal(size=(3, 2)) * 0.1
    normals = np.tile([0.0, 0.0, 1.0], (4, 1))
    normals[3] = _unit([0.3, -0.2, 1.0])
    return verts, elems, points, normals


def box_shooters(rng, n_box):
    """Shooters on the floor of :func:`closed_box` (``n_box`` quads a side, even): random points,
    the centre (the box's grid lines through it project onto the axes, where an odd resolution
    has a column and a row of pixel centres: the half-open rules decide there), a grid vertex (a
    shared corner of four floor elements) and a point seeing box corners at exactly 45 degrees.
    Returns ``points (S, 3)``, ``normals (S, 3)``."""
    pts = np.column_stack([rng.uniform(0.05, 0.95, size=(4, 2)), np.zeros(4)])
    fixed = np.array([[0.5, 0.5, 0.0], [1.0 / n_box, 1.0 / n_box, 0.0], [0.25, 0.5, 0.0]])
    points = np.concatenate([pts, fixed])
    return points, np.tile([0.0, 0.0, 1.0], (len(points), 1))


def configurations(rng):
    """``(name, vertices, elem_verts, points, normals)`` of every case the twins are held to:
    random soups (tiny to huge elements, front and back facing), elements straddling the
    horizon, a closed box seen from its floor (shared edges, the floor coplanar with the
    shooter, exact 45 degree corners), two grids overlapping in one tilted plane (depth ties),
    and the box at 1e-6 and 1e4 of its size."""
    out = []
    for k in range(3):
        v, e = random_elements(rng, 40)
        p, n = random_shooters(rng, 4)
        out.append((f"soup {k}", v, e, p, n))
    out.append(("straddling", *straddling(rng, 30)))
    v, e = closed_box(4)
    p, n = box_shooters(rng, 4)
    out.append(("closed box", v, e, p, n))
    # two coplanar grids facing down, one shifted, turned by a random rotation: overlapping
    # elements tie in depth up to the round-off of their planes (the DEPTH_TIE rule decides)
    a = grid([0.0, 0.0, 1.0], [0, 1, 0], [1, 0, 0], 3)
    b = grid([0.17, 0.11, 1.0], [0, 1, 0], [1, 0, 0], 3)
    rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    rot *= np.sign(np.linalg.det(rot))
    v, e = merge(a, b)
    p = np.column_stack([rng.uniform(0.0, 1.0, size=(4, 2)), np.zeros(4)])
    out.append(("coplanar overlap", v @ rot.T, e, p @ rot.T,
                np.tile([0.0, 0.0, 1.0], (4, 1)) @ rot.T))
    for scale in (1e-6, 1e4):
        v, e = closed_box(2)
        p, n = box_shooters(rng, 2)
        out.append((f"box x{scale:g}", v * scale, e, p * scale, n))
    return out


CASES = ["soup 0", "soup 1", "soup 2", "straddling", "closed box", "coplanar overlap",
         "box x1e-06", "box x10000"]


@pytest.fixture
def cases(rng):
    return {c[0]: c[1:] for c in configurations(rng)}


# --- composed references --------------------------------------------------------------------

def nearness(e, d, p, frame, enrm, eoff):
    """``1/t`` along the local unit direction ``d`` to the plane of element ``e`` (0 when the
    shooter ``p`` lies in it); ``frame`` is ``(t1, t2, n)``."""
    c = eoff[e] - (enrm[e, 0] * p[0] + enrm[e, 1] * p[1] + enrm[e, 2] * p[2])
    if c == 0.0:
        return 0.0
    nl = [t[0] * enrm[e, 0] + t[1] * enrm[e, 1] + t[2] * enrm[e, 2] for t in frame]
    return (nl[0] * d[0] + nl[1] * d[1] + nl[2] * d[2]) / c


def centroid_visibility(e, g, p, frame, enrm, eoff, item, dz, r):
    """The item buffer's visible fraction of element ``e`` along the direction of its clipped
    corners' sum ``g`` (``hemisphere_visibility``): bilinear over the 2 x 2 pixel centres around
    it, a pixel counting visible when it is empty, outside the disc, or its winner's plane is not
    nearer than ``e``'s by more than ``DEPTH_TIE``."""
    norm = np.sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2])
    if not norm > 0.0:
        return 0.0
    d = (g[0] / norm, g[1] / norm, g[2] / norm)
    own = nearness(e, d, p, frame, enrm, eoff)
    pu = (d[0] + 1.0) * (0.5 * r) - 0.5
    pv = (d[1] + 1.0) * (0.5 * r) - 0.5
    fx, fy = pu - np.floor(pu), pv - np.floor(pv)
    frac = 0.0
    for dj in range(2):
        wy = fy if dj else 1.0 - fy
        if wy == 0.0:
            continue
        j = min(max(int(np.floor(pv)) + dj, 0), r - 1)
        for di in range(2):
            wx = fx if di else 1.0 - fx
            if wx == 0.0:
                continue
            i = min(max(int(np.floor(pu)) + di, 0), r - 1)
            w = item[j * r + i]
            vis = 1.0
            if dz[j * r + i] >= 0.0 and w >= 0:
                other = nearness(w, d, p, frame, enrm, eoff)
                vis = 0.0 if other > own * (1.0 + DEPTH_TIE) else 1.0
            frac += wx * wy * vis
    return frac


def item_buffer_composed(points, normals, vertices, elem_verts, r, edge_angle, plane_depth,
                         horizon_eps):
    """``(won, covered, n_disc, visible)`` of the item buffer, composed per element from the
    public kernels: ``project_element`` → ``depth_coefficients`` → ``fill_polygon`` into the
    element's own buffer, then its nearness per pixel merged into the item buffer with the depth
    test ``near > z and (z = -inf or near - z > DEPTH_TIE |z|)`` in element order; once the
    buffer is complete, :func:`centroid_visibility` of every element drawn (1 when it won every
    pixel it covers). ``visible`` depends continuously on the clipped corners, so it sees the
    clip's bits, which the pixel counts see only where an outline passes exactly through a
    pixel centre."""
    n_elem = elem_verts.shape[0]
    enrm, eoff = element_planes(vertices, elem_verts)
    hz = max(horizon_eps * scene_diagonal(vertices), 1e-300)
    centre, dz, n_disc = disc_pixels(r)
    cap = edge_capacity(edge_angle)
    xs, ys = np.empty(cap), np.empty(cap)
    xcross = np.empty((r, cap))
    cnt = np.zeros(r, dtype=np.int64)
    lx, ly, lz = (np.empty(len(vertices)) for _ in range(3))
    cos_thr = np.cos(edge_angle)
    tab = split_table(edge_angle)
    cx, cy, cz, qx, qy, qz, qclip = project_scratch()
    won = np.zeros((len(points), n_elem), dtype=np.int32)
    covered = np.zeros((len(points), n_elem), dtype=np.int32)
    visible = np.zeros((len(points), n_elem))
    for s, (p, n) in enumerate(zip(points, normals, strict=True)):
        t1x, t1y, t1z, t2x, t2y, t2z = local_frame(*p, *n, vertices, lx, ly, lz)
        item = np.full(r * r, -1, dtype=np.int32)
        zbuf = np.full(r * r, -np.inf)
        drawn = []
        for e in range(n_elem):
            m, mm, c = project_element(e, *p, elem_verts, enrm, eoff, lx, ly, lz, hz, cos_thr,
                                       tab, cx, cy, cz, qx, qy, qz, qclip, xs, ys)
            if mm == 0:
                continue
            g = [0.0, 0.0, 0.0]
            for a in range(m):  # summed in corner order, as the kernel does
                g[0] += qx[a]
                g[1] += qy[a]
                g[2] += qz[a]
            drawn.append((e, g))
            nlx = t1x * enrm[e, 0] + t1y * enrm[e, 1] + t1z * enrm[e, 2]
            nly = t2x * enrm[e, 0] + t2y * enrm[e, 1] + t2z * enrm[e, 2]
            nlz = n[0] * enrm[e, 0] + n[1] * enrm[e, 1] + n[2] * enrm[e, 2]
            da, db, dc, de = depth_coefficients(plane_depth, qx, qy, qz, m, nlx, nly, nlz, c)
            own_item = np.full(r * r, -1, dtype=np.int32)
            own_z = np.full(r * r, -np.inf)
            covered[s, e] = fill_polygon(xs, ys, mm, e, centre, centre, r, r, -1.0, 0.5 * r,
                                         -1.0, 0.5 * r, dz, da, db, dc, de, xcross, cnt,
                                         own_item, own_z)
            # fill_polygon covers a pixel at most once per element, so the merge is per pixel
            idx = np.flatnonzero(own_item == e)
            near, zo = own_z[idx], zbuf[idx]
            wins = (near > zo) & ((zo == -np.inf) | (near - zo > DEPTH_TIE * np.abs(zo)))
            zbuf[idx[wins]] = near[wins]
            item[idx[wins]] = e
        won[s] = np.bincount(item[item >= 0], minlength=n_elem)
        frame = ((t1x, t1y, t1z), (t2x, t2y, t2z), tuple(n))
        for e, g in drawn:
            if covered[s, e] > 0 and won[s, e] == covered[s, e]:
                visible[s, e] = 1.0
            else:
                visible[s, e] = centroid_visibility(e, g, p, frame, enrm, eoff, item, dz, r)
    return won, covered, n_disc, visible


#: The hemicube's face frames in the shooter's local frame (its module docstring): for each of
#: the 5 faces the (index, sign) of the local coordinate giving ``a``, ``b`` and ``c``.
FACES = (((0, 1.0), (1, 1.0), (2, 1.0)),     # top: a = x, b = y, c = z
         ((1, 1.0), (2, 1.0), (0, 1.0)),     # +x: a = y, b = z, c = x
         ((1, -1.0), (2, 1.0), (0, -1.0)),   # -x: a = -y, b = z, c = -x
         ((0, -1.0), (2, 1.0), (1, 1.0)),    # +y: a = -x, b = z, c = y
         ((0, 1.0), (2, 1.0), (1, -1.0)))    # -y: a = x, b = z, c = -y


def clip(poly, ka, kb, kc, off):
    """Sutherland-Hodgman: the part of the polygon ``poly`` (a list of ``(a, b, c)``) where
    ``ka a + kb b + kc c > off``, crossings interpolated from the edge's canonical endpoint
    (:func:`lex_less`) so that a shared edge clips to the same point from both sides."""
    out = []
    for i, pi in enumerate(poly):
        pj = poly[(i + 1) % len(poly)]
        fi = ka * pi[0] + kb * pi[1] + kc * pi[2] - off
        fj = ka * pj[0] + kb * pj[1] + kc * pj[2] - off
        if fi > 0.0:
            out.append(pi)
        if (fi > 0.0) != (fj > 0.0):
            if lex_less(*pi, *pj):
                p0, p1, f0, f1 = pi, pj, fi, fj
            else:
                p0, p1, f0, f1 = pj, pi, fj, fi
            t = f0 / (f0 - f1)
            out.append(tuple(p0[k] + t * (p1[k] - p0[k]) for k in range(3)))
    return out


def hemicube_composed(points, normals, vertices, elem_verts, r, horizon_eps):
    """``F (S, E)`` of the hemicube, composed per element and face: the face frame, the clips
    (horizon ``z > hz``, then the frustum ``|a| < c``, ``|b| < c`` on the top, ``b < c`` on the
    sides), the central projection ``(a/c, b/c)`` and :func:`fill_polygon` into the face's part
    of the buffer; each pixel's normalised delta form factor to its winner."""
    n_elem = elem_verts.shape[0]
    enrm, eoff = element_planes(vertices, elem_verts)
    hz = max(horizon_eps * scene_diagonal(vertices), 1e-300)
    h = side_rows(r)
    weights, _ = delta_form_factors(r)
    xc = -1.0 + (2.0 * np.arange(r) + 1.0) / r
    zc = (np.arange(h) + 0.5) / h
    mask = np.zeros(r * r)
    xs, ys = np.empty(12), np.empty(12)
    xcross = np.empty((r, 12))
    cnt = np.zeros(r, dtype=np.int64)
    lx, ly, lz = (np.empty(len(vertices)) for _ in range(3))
    out = np.zeros((len(points), n_elem))
    for s, (p, n) in enumerate(zip(points, normals, strict=True)):
        t1x, t1y, t1z, t2x, t2y, t2z = local_frame(*p, *n, vertices, lx, ly, lz)
        item = np.full(len(weights), -1, dtype=np.int32)
        zbuf = np.full(len(weights), -np.inf)
        for e in range(n_elem):
            c = eoff[e] - (enrm[e, 0] * p[0] + enrm[e, 1] * p[1] + enrm[e, 2] * p[2])
            corners = [v for v in elem_verts[e] if v >= 0]
            if not c < 0.0 or max(lz[corners]) <= hz:
                continue
            nl = (t1x * enrm[e, 0] + t1y * enrm[e, 1] + t1z * enrm[e, 2],
                  t2x * enrm[e, 0] + t2y * enrm[e, 1] + t2z * enrm[e, 2],
                  n[0] * enrm[e, 0] + n[1] * enrm[e, 1] + n[2] * enrm[e, 2])
            for f, ((ia, sa), (ib, sb), (ic, sc)) in enumerate(FACES):
                poly = [(sa * (lx[v], ly[v], lz[v])[ia], sb * (lx[v], ly[v], lz[v])[ib],
                         sc * (lx[v], ly[v], lz[v])[ic]) for v in corners]
                poly = clip(poly, 0.0, 0.0, 1.0, hz) if f == 0 else clip(poly, 0.0, 1.0, 0.0, hz)
                poly = clip(poly, -1.0, 0.0, 1.0, 0.0)
                poly = clip(poly, 1.0, 0.0, 1.0, 0.0)
                poly = clip(poly, 0.0, -1.0, 1.0, 0.0)
                if f == 0:
                    poly = clip(poly, 0.0, 1.0, 1.0, 0.0)
                m = len(poly)
                if m < 3:
                    continue
                for a, (qa, qb, qc) in enumerate(poly):
                    xs[a] = qa / qc
                    ys[a] = qb / qc
                o0 = 0 if f == 0 else r * r + (f - 1) * r * h
                nrow, y0, inv_py, ycs = (r, -1.0, 0.5 * r, xc) if f == 0 else (h, 0.0, h, zc)
                fill_polygon(xs, ys, m, e, xc, ycs, r, nrow, -1.0, 0.5 * r, y0, float(inv_py),
                             mask, sa * nl[ia] / c, sb * nl[ib] / c, sc * nl[ic] / c, 0.0,
                             xcross, cnt, item[o0:o0 + nrow * r], zbuf[o0:o0 + nrow * r])
        hit = item >= 0
        out[s] = np.bincount(item[hit], weights[hit], minlength=n_elem)
    return out


def lambert_composed(points, normals, vertices, elem_verts):
    """``F (S, E)``: :func:`lambert_polygon` per element on its lit side, 0 behind it."""
    enrm, eoff = element_planes(vertices, elem_verts)
    out = np.zeros((len(points), len(elem_verts)))
    for s, (p, n) in enumerate(zip(points, normals, strict=True)):
        for e, ev in enumerate(elem_verts):
            if enrm[e, 0] * p[0] + enrm[e, 1] * p[1] + enrm[e, 2] * p[2] - eoff[e] <= 0.0:
                continue
            corners = np.ascontiguousarray(vertices[ev[ev >= 0]])
            out[s, e] = lambert_polygon(*p, *n, corners, len(corners))
    return out


# --- the tests ------------------------------------------------------------------------------

@pytest.mark.parametrize("case", CASES)
@pytest.mark.parametrize("plane_depth", [False, True])
def test_item_buffer_matches_project_fill_polygon(cases, case, plane_depth):
    verts, elems, points, normals = cases[case]
    for r, edge in ((96, EDGE), (61, 0.3)):  # fine splits, coarse splits, odd R
        enrm, eoff = element_planes(verts, elems)
        won, covered, n_disc, visible = hemisphere_visibility(points, normals, verts, elems,
                                                              enrm, eoff, r, edge, plane_depth,
                                                              HORIZON)
        ref = item_buffer_composed(points, normals, verts, elems, r, edge, plane_depth, HORIZON)
        assert n_disc == ref[2]
        assert np.array_equal(covered, ref[1])
        assert np.array_equal(won, ref[0])
        assert np.array_equal(visible, ref[3])
        assert covered.sum() > 0  # the case draws something
        if case.startswith("soup"):  # and the soups hide parts of some elements
            assert ((visible > 0) & (visible < 1)).any()


@pytest.mark.parametrize("case", CASES)
def test_hemicube_matches_clip_and_fill_polygon(cases, case):
    verts, elems, points, normals = cases[case]
    for r in (64, 37):
        f = hemicube_shots(points, normals, verts, elems, r, HORIZON)
        ref = hemicube_composed(points, normals, verts, elems, r, HORIZON)
        assert np.array_equal(f, ref)
        assert f.sum() > 0


@pytest.mark.parametrize("case", CASES)
def test_lambert_batch_matches_lambert_polygon(cases, case, rng):
    verts, elems, points, normals = cases[case]
    ref = lambert_composed(points, normals, verts, elems)
    assert np.array_equal(lambert_shots(points, normals, verts, elems), ref)
    mask = rng.random(ref.shape) < 0.5
    enrm, eoff = element_planes(verts, elems)
    assert np.array_equal(lambert_masked(points, normals, verts, elems, enrm, eoff, mask),
                          np.where(mask, ref, 0.0))
    assert (ref > 0).any()
