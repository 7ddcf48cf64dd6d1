"""One convex face that hides a whole area light (issue 12, item 5: the direct light of
interiors with many luminaires).

Most vertex-light pairs of a furnished interior are wholly hidden (RenderPark's office: 83 %),
and about two thirds of those by a single wall, floor or desk top. :func:`face_hides` proves
such a pair hidden by one ray and a few point-in-polygon tests, exactly, where the window
method (:mod:`daskrad.kernels.arealight`) searches the pyramid to the light and rasterizes its
occluders. Where it proves nothing, the window method runs as before. The face that last hid a
light is tried first, without the ray (:func:`face_hides`'s ``hint``): RenderPark's office's
direct pass (``graz.obj``, 293,004 vertices × 32 emitter patches, 2 threads, two alternated
runs each) went 25.3 / 25.1 → 21.4 / 21.2 s, and the one vertex whose irradiance changed
(1.5e-4 → 0) lost the raster's error: 200 × 200 shadow rays find that light hidden.

Not used by the shadow rays: at RenderPark's office's vertices it saved 7 % of the ``rays``
area method's time (hidden lights block their rays early, cheaply), and at the per-pixel
pass's hits, mostly lit by the lights of the room in view, it proved 4 % of the pairs and
cost more than it saved (+4 %).

A face is an input polygon (a triangle or a planar convex quad). The direct pass's occluder
grid holds the polygons' own triangles, one piece per face
(:func:`daskrad.preprocess.occluders`); over a grid of the elements, a face is the union of its
patches (:func:`daskrad.direct.polygon_faces`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from daskrad.kernels._jit import jit
from daskrad.kernels.geometry import within_edges
from daskrad.kernels.grid import closest_hit_one


class Faces(NamedTuple):
    """The convex planar faces the occluder grid's triangles tile (:func:`face_hides`).

    tri_face : (T,) int32
        The face of each of the grid's triangles; ``-1``: none (proves nothing).
    start : (F + 1,) int64
        Face ``f`` is the union of the convex pieces ``start[f]:start[f + 1]``.
    corners : (P, 4, 3) float64
        The pieces (the polygon itself, or its patches), counter-clockwise about their
        face's normal; ``count (P,) int64`` corners each (3 or 4).
    """

    tri_face: np.ndarray
    start: np.ndarray
    corners: np.ndarray
    count: np.ndarray


def no_faces(n_triangles: int) -> Faces:
    """Faces that prove nothing: the window method alone."""
    return Faces(np.full(n_triangles, -1, np.int32), np.zeros(1, np.int64),
                 np.zeros((0, 4, 3)), np.zeros(0, np.int64))


@jit
def _in_face(faces, f, x, y, z, nx, ny, nz, eps):
    """Whether the point ``(x, y, z)`` in face ``f``'s plane (unit normal ``n``) lies in one of
    its pieces, within ``eps`` of its edges (a point on an edge two pieces share is in both)."""
    for q in range(faces.start[f], faces.start[f + 1]):
        if within_edges(faces.corners[q], faces.count[q], x, y, z, nx, ny, nz, -eps):
            return True
    return False


@jit
def face_hides(grid, faces, ex, ey, ez, n, corners, count, en, off, hz, hint=-1):
    """The triangle of a convex face of the scene that hides the whole light from the eye
    ``e``, or -1 when none is found.

    ``faces``: :class:`Faces` (none: -1 at once). The ray from ``e`` to the light's first
    corner is traced to its closest hit, a triangle of face ``f``; then
    :func:`face_proves`. ``hint``: a triangle of the grid whose face is tried first, without
    the ray (the face that last hid this light from a point nearby: a wall hides a luminaire
    of the next room from every vertex of the wall, and one ray costs as much as 40 tests of
    a face); -1: none. Any face that passes the test hides the light, whether or not it is
    the nearest, so a proof through the hint is as exact as one through the ray. What the hint
    changes: the time, and, where the remembered face proves a light hidden that the ray's
    face does not, ``V = 0`` instead of the window method's raster (which can let a pixel
    through a face that covers the whole light).

    One ray and three point-in-face tests instead of the pyramid's search: in a furnished
    interior most vertex-light pairs are wholly hidden (RenderPark's office: 83 %) and about
    two thirds of those by a single wall, floor or desk top. -1 whenever it cannot prove
    it; the caller then runs the window method.
    """
    if faces.corners.shape[0] == 0:
        return -1
    for a in range(count):
        if not (n[0] * (corners[a, 0] - ex) + n[1] * (corners[a, 1] - ey)
                + n[2] * (corners[a, 2] - ez)) > hz:
            return -1
    if hint >= 0 and face_proves(grid, faces, hint, ex, ey, ez, n, corners, count, en, off,
                                 hz, -1.0):
        return hint
    o = np.empty(3)
    d = np.empty(3)
    o[0] = ex
    o[1] = ey
    o[2] = ez
    d[0] = corners[0, 0] - ex
    d[1] = corners[0, 1] - ey
    d[2] = corners[0, 2] - ez
    t, k, _, _ = closest_hit_one(grid, o, d, 0.0, 1.0)
    if k < 0:
        return -1
    if face_proves(grid, faces, k, ex, ey, ez, n, corners, count, en, off, hz, t):
        return k
    return -1


@jit
def face_proves(grid, faces, k, ex, ey, ez, n, corners, count, en, off, hz, t0):
    """Whether the face of the grid's triangle ``k`` hides the whole light from ``e``.

    When every corner's ray crosses the face's plane inside the face, above the horizon
    (height over ``e`` along ``n`` above ``hz``) and nearer than the light, the plane
    separates ``e`` from the whole light and the pyramid's section by it, the convex hull of
    the crossings, lies in the convex face: every ray from ``e`` to the light is blocked,
    ``V = 0`` exactly. The gap to the light along any such ray is at least ``(1 − max t) h``,
    ``t`` the crossings' parameters (``1/t`` is affine over the light, so ``t`` is largest at
    a corner) and ``h`` the eye's height over the light's plane; it must exceed ``2 off`` (the
    raster's rule: an occluder hides only what lies more than ``off`` in front of the light).
    The caller has checked that the light lies wholly above the horizon, so that the window
    method would see all of it.

    ``t0``: the parameter where the ray to the first corner hits triangle ``k`` (that corner's
    crossing, known inside the face), or negative to test that corner like the others.
    """
    f = faces.tri_face[k]
    if f < 0:
        return False
    tri = grid.triangles[k]
    ux = tri[1, 0] - tri[0, 0]
    uy = tri[1, 1] - tri[0, 1]
    uz = tri[1, 2] - tri[0, 2]
    vx = tri[2, 0] - tri[0, 0]
    vy = tri[2, 1] - tri[0, 1]
    vz = tri[2, 2] - tri[0, 2]
    fx = uy * vz - uz * vy
    fy = uz * vx - ux * vz
    fz = ux * vy - uy * vx
    fl = np.sqrt(fx * fx + fy * fy + fz * fz)
    if not fl > 0.0:
        return False
    fx /= fl
    fy /= fl
    fz /= fl
    fd = fx * tri[0, 0] + fy * tri[0, 1] + fz * tri[0, 2] - (fx * ex + fy * ey + fz * ez)
    t_max = 0.0
    for a in range(count):
        dx = corners[a, 0] - ex
        dy = corners[a, 1] - ey
        dz = corners[a, 2] - ez
        if a > 0 or not t0 >= 0.0:
            dn = fx * dx + fy * dy + fz * dz
            if dn == 0.0:
                return False
            t = fd / dn
            if not (t > 0.0 and t < 1.0):
                return False
            if not _in_face(faces, f, ex + t * dx, ey + t * dy, ez + t * dz, fx, fy, fz,
                            grid.eps):
                return False
        else:
            t = t0
        if not t * (n[0] * dx + n[1] * dy + n[2] * dz) > hz:
            return False
        t_max = max(t_max, t)
    h = en[0] * (ex - corners[0, 0]) + en[1] * (ey - corners[0, 1]) + en[2] * (ez - corners[0, 2])
    return (1.0 - t_max) * h > 2.0 * off
