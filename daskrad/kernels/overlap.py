"""The exact test of :mod:`daskrad.scene.overlap`: do two faces in one plane overlap?

One loop over candidate pairs (found by the caller's plane buckets and box sweep). For a plane
tiled by 10⁵ faces the candidates are about ten per face, and the same test written with numpy
arrays of shape ``(k, 8, 8)`` took most of the check's time (issue 13).
"""

from __future__ import annotations

import math

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf


@jit_leaf
def _pair_overlaps(c, n, centre, i, j, eps):
    """One pair of :func:`coplanar_overlap`."""
    for q in range(4):
        di = 0.0
        dj = 0.0
        for x in range(3):
            di += (c[j, q, x] - centre[i, x]) * n[i, x]
            dj += (c[i, q, x] - centre[j, x]) * n[j, x]
        if abs(di) > eps or abs(dj) > eps:
            return False
    for f in range(2):
        face = i if f == 0 else j
        for e in range(4):
            e1 = (e + 1) % 4
            ex = c[face, e1, 0] - c[face, e, 0]
            ey = c[face, e1, 1] - c[face, e, 1]
            ez = c[face, e1, 2] - c[face, e, 2]
            # in-plane normal of the edge: edge × n[i]
            ax = ey * n[i, 2] - ez * n[i, 1]
            ay = ez * n[i, 0] - ex * n[i, 2]
            az = ex * n[i, 1] - ey * n[i, 0]
            length = math.sqrt(ax * ax + ay * ay + az * az)
            if length == 0.0:
                continue  # a triangle's empty fourth edge
            ax /= length
            ay /= length
            az /= length
            lo_i = math.inf
            hi_i = -math.inf
            lo_j = math.inf
            hi_j = -math.inf
            for q in range(4):
                si = c[i, q, 0] * ax + c[i, q, 1] * ay + c[i, q, 2] * az
                sj = c[j, q, 0] * ax + c[j, q, 1] * ay + c[j, q, 2] * az
                lo_i = min(lo_i, si)
                hi_i = max(hi_i, si)
                lo_j = min(lo_j, sj)
                hi_j = max(hi_j, sj)
            if min(hi_i, hi_j) - max(lo_i, lo_j) <= eps:
                return False
    return True


@jit
def sweep_overlaps(face, end, lo, hi, c, n, centre, eps):
    """Overlapping pairs among the runs of a sorted sweep, without listing the candidates.

    Parameters
    ----------
    face : (m,) int64
        The face at each position of the sweep order (sorted by strip, then by the low end of
        the box along the sweep axis; a face may appear in two strips).
    end : (m,) int64
        Position ``s`` meets the positions ``s + 1 .. end[s] - 1`` along the sweep axis.
    lo, hi : (Q, 3) float64
        Bounding boxes.
    c, n, centre, eps
        As :func:`coplanar_overlap`.

    Returns
    -------
    (k, 2) int64
        ``(min, max)`` face pairs whose boxes meet within ``eps``, that face the same way and
        pass :func:`coplanar_overlap`; a pair may repeat (the caller removes repeats).
    """
    hits = []
    for s in range(len(face)):
        i = face[s]
        for t in range(s + 1, end[s]):
            j = face[t]
            if i == j:
                continue
            meet = True
            for x in range(3):
                if lo[i, x] > hi[j, x] + eps or lo[j, x] > hi[i, x] + eps:
                    meet = False
                    break
            if not meet:
                continue
            if n[i, 0] * n[j, 0] + n[i, 1] * n[j, 1] + n[i, 2] * n[j, 2] <= 0.0:
                continue
            if _pair_overlaps(c, n, centre, i, j, eps):
                hits.append((min(i, j), max(i, j)))
    out = np.empty((len(hits), 2), np.int64)
    for k in range(len(hits)):
        out[k, 0] = hits[k][0]
        out[k, 1] = hits[k][1]
    return out


@jit
def coplanar_overlap(c, n, centre, a, b, eps):
    """``(k,) bool``: faces ``a[k]`` and ``b[k]`` lie in one plane and overlap.

    Parameters
    ----------
    c : (Q, 4, 3) float64
        Corners; a triangle repeats its third corner.
    n : (Q, 3) float64
        Unit normals (the caller pairs only faces facing the same way).
    centre : (Q, 3) float64
        A point of each face's plane (the corners' mean).
    a, b : (k,) int64
        Candidate pairs.
    eps : float
        Coplanar: every corner of each within ``eps`` of the other's plane. Overlap: the two
        convex polygons share a region wider than ``eps`` along every separating axis (the
        in-plane normals ``edge × n[a]`` of their edges); touching along an edge or at a corner
        leaves an axis with overlap ``<= eps``.
    """
    k = len(a)
    out = np.zeros(k, np.bool_)
    for p in range(k):
        out[p] = _pair_overlaps(c, n, centre, a[p], b[p], eps)
    return out
