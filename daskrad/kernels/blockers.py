"""Which shooters have an occluder close enough to cast a penumbra their centroid cannot see.

A form factor whose visibility is sampled at the shooter's centroid puts every receiver either
in light or in shadow; the true visibility from an area shooter of radius ``r`` past an edge at
distance ``d`` has a penumbra ``~ r/d`` radians wide. The solver samples the shooter at more
points where ``d`` is a few ``r`` or less
(:func:`daskrad.formfactor.shooting.shooter_points`); this kernel finds ``d`` for one shooter.

An element ``b`` can block a segment from a shooter point ``s`` to a receiver point ``x`` only
if ``s`` and ``x`` lie strictly on opposite sides of ``b``'s plane. So ``b`` counts when it
lies (partly) in front of the shooter, the shooter reaches strictly to one side of ``b``'s
plane, and the scene reaches strictly to the other (``sides``, per polygon). A closed convex
room has no blockers at all: every wall's plane has the whole scene on its front side.
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.geometry import orthonormal_basis
from daskrad.kernels.grid import closest_hit_one

#: ``sides`` bits: the scene has points strictly in front of / behind a polygon's plane;
#: ``UNKNOWN`` until the polygon is first met as a candidate blocker.
FRONT = 1
BEHIND = 2
UNKNOWN = -1


@jit_leaf
def plane_sides(vertices, point, normal, eps):
    """``FRONT | BEHIND`` bits: on which sides of the plane (``point``, ``normal``) some of
    ``vertices : (V, 3)`` lie by more than ``eps``. Stops as soon as both are found."""
    flags = 0
    for k in range(vertices.shape[0]):
        d = ((vertices[k, 0] - point[0]) * normal[0] + (vertices[k, 1] - point[1]) * normal[1]
             + (vertices[k, 2] - point[2]) * normal[2])
        if d > eps:
            flags |= FRONT
        elif d < -eps:
            flags |= BEHIND
        if flags == FRONT | BEHIND:
            break
    return flags


@jit_leaf
def _folded_away(corners, normal, point, enormal, eps, grazing):
    """Whether the element plane (``point``, ``enormal``) meets the shooter's plane at a
    dihedral angle ``α`` with ``sin²α <= grazing`` and passes at or below the shooter's plane
    everywhere over the shooter (``corners``, convex): then the element rises only beyond the
    line where the planes meet, at an elevation of at most ``α`` from every point of the
    shooter (a slightly folded neighbour, as the measured Cornell box's red wall). A parallel
    element above the shooter, or one overhanging it, is not folded away.
    """
    cx = normal[1] * enormal[2] - normal[2] * enormal[1]
    cy = normal[2] * enormal[0] - normal[0] * enormal[2]
    cz = normal[0] * enormal[1] - normal[1] * enormal[0]
    if cx * cx + cy * cy + cz * cz > grazing:
        return False
    nn = normal[0] * enormal[0] + normal[1] * enormal[1] + normal[2] * enormal[2]
    for k in range(corners.shape[0]):
        # height of the element's plane above corner k, along the shooter's normal
        t = ((point[0] - corners[k, 0]) * enormal[0] + (point[1] - corners[k, 1]) * enormal[1]
             + (point[2] - corners[k, 2]) * enormal[2]) / nn
        if t > eps:
            return False
    return True


@jit_leaf
def nearest_blocker(corners, centroid, normal, polygon, vertices, elem_verts,
                    elem_centroid, elem_normal, elem_radius, elem_polygon, sides, eps, grazing,
                    side_eps, reach):
    """Distance from a shooter's centroid to the nearest element that may occlude some receiver
    from some point of the shooter, less that element's radius; ``inf`` when none can within
    ``reach`` (a length; ``inf``: anywhere).

    ``reach`` is what makes the search cheap where nothing occludes: an element farther is
    passed over on its distance alone, before its corners and its polygon's sides are looked
    at. The solver asks only whether a blocker lies within ``PENUMBRA`` radii, and the answer
    is the same either way; measured with that reach, per patch: a closed box of 53,248
    elements (no blocker at all: every element was tested in full) 2.94 → 0.08 ms, of a row
    of ~14.5 ms; RenderPark's office3, 24,994 elements, 0.20 → 0.05 ms.

    ``corners : (k, 3)`` the shooter's corners (a convex polygon), ``centroid, normal : (3,)``,
    ``polygon`` its input polygon (whose elements never block it); ``vertices : (V, 3)`` the
    scene's; element arrays as in the hierarchy, ``elem_radius : (E,)`` the largest
    centroid-to-corner distance; ``sides : (Q,) int8`` per polygon, ``UNKNOWN`` or
    :func:`plane_sides`, filled in here as polygons are met (a pure function of the geometry:
    racing threads write the same value);
    ``eps`` a length (the scene's coplanarity tolerance); ``side_eps >= eps`` the distance
    within which the scene counts as lying in an element's plane (:func:`plane_sides`: the back
    of a two-sided face, a small gap behind its front, is not "scene behind" the front). An
    element folded away from the
    shooter by less than ``asin(√grazing)`` (:func:`_folded_away`) hides only directions that
    carry less than ``grazing`` of a cosine-weighted hemisphere and is not counted.
    """
    best = np.inf
    limit = reach                   # min(best, reach): nearer candidates only
    for j in range(elem_centroid.shape[0]):
        if elem_polygon[j] == polygon:
            continue
        dx = elem_centroid[j, 0] - centroid[0]
        dy = elem_centroid[j, 1] - centroid[1]
        dz = elem_centroid[j, 2] - centroid[2]
        dist = np.sqrt(dx * dx + dy * dy + dz * dz) - elem_radius[j]
        if dist >= limit:
            continue
        # in front of the shooter: a corner above its plane
        above = False
        for k in range(4):
            v = elem_verts[j, k]
            if v < 0:
                break
            if ((vertices[v, 0] - centroid[0]) * normal[0] + (vertices[v, 1] - centroid[1])
                    * normal[1] + (vertices[v, 2] - centroid[2]) * normal[2]) > eps:
                above = True
                break
        if not above:
            continue
        if _folded_away(corners, normal, elem_centroid[j], elem_normal[j], eps, grazing):
            continue
        lo = np.inf
        hi = -np.inf
        for k in range(corners.shape[0]):
            d = ((corners[k, 0] - elem_centroid[j, 0]) * elem_normal[j, 0]
                 + (corners[k, 1] - elem_centroid[j, 1]) * elem_normal[j, 1]
                 + (corners[k, 2] - elem_centroid[j, 2]) * elem_normal[j, 2])
            lo = min(lo, d)
            hi = max(hi, d)
        if hi <= eps and lo >= -eps:
            continue                               # coplanar with the shooter
        g = elem_polygon[j]
        if sides[g] == UNKNOWN:
            sides[g] = plane_sides(vertices, elem_centroid[j], elem_normal[j], side_eps)
        if (hi > eps and sides[g] & BEHIND) or (lo < -eps and sides[g] & FRONT):
            best = max(dist, 0.0)
            limit = best
    return best


@jit
def enclosed_points(grid, tri_element, elem_normal, two_sided, elem_polygon, points, normal,
                    lift, probes):
    """``(k,) bool``: the points ``points (k, 3)`` of a shooter with unit ``normal (3,)`` that
    lie inside a closed object: every probe ray, from the point lifted by ``lift`` along the
    normal in the directions ``probes (m, 3)`` of the shooter's frame (``t1, t2, n`` of
    :func:`daskrad.kernels.geometry.orthonormal_basis`), first meets the back of a one-sided
    face (an element of grid triangle ``tri_element``, facing along ``elem_normal``, whose
    polygon ``elem_polygon`` is not in ``two_sided``). A miss or a front face answers
    "open" at once (:func:`daskrad.formfactor.shooting._enclosed` gives the why)."""
    t1x, t1y, t1z, t2x, t2y, t2z = orthonormal_basis(normal[0], normal[1], normal[2])
    m = probes.shape[0]
    dirs = np.empty((m, 3))
    for j in range(m):
        a = probes[j, 0]
        b = probes[j, 1]
        c = probes[j, 2]
        dirs[j, 0] = a * t1x + b * t2x + c * normal[0]
        dirs[j, 1] = a * t1y + b * t2y + c * normal[1]
        dirs[j, 2] = a * t1z + b * t2z + c * normal[2]
    out = np.zeros(points.shape[0], np.bool_)
    o = np.empty(3)
    for i in range(points.shape[0]):
        for x in range(3):
            o[x] = points[i, x] + lift * normal[x]
        inside = True
        for j in range(m):
            tri = closest_hit_one(grid, o, dirs[j], 0.0, np.inf)[1]
            if tri < 0:
                inside = False
                break
            e = tri_element[tri]
            if not (elem_normal[e, 0] * dirs[j, 0] + elem_normal[e, 1] * dirs[j, 1]
                    + elem_normal[e, 2] * dirs[j, 2]) > 0.0 or two_sided[elem_polygon[e]]:
                inside = False
                break
        out[i] = inside
    return out
