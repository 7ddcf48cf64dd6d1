"""The uniform voxel grid for rays (docs/design.md §1 step 1; issue 2, item 5).

Every triangle is registered in each cell of a uniform grid it overlaps (exact triangle–box
overlap by the separating-axis theorem, Akenine-Möller 2001, on a box enlarged by a small
margin), stored as CSR: ``cell_items[cell_start[c]:cell_start[c + 1]]`` are the triangle ids of
cell ``c = (k * ny + j) * nx + i`` (x fastest), ids increasing. Rays walk the grid by 3-D DDA
(Amanatides & Woo 1987) and test each triangle of a cell with Möller–Trumbore in float64 with
an edge tolerance of ``eps`` (an absolute length), so a ray through a shared edge or vertex
hits at least one of the triangles that share it.

Invariants the traversal relies on:

- a triangle is registered in every cell that contains a point within ``margin`` of it, where
  ``margin`` (> 2 ``eps`` plus rounding of the coordinates) covers both the edge tolerance and
  the rounding of the DDA's cell boundaries, so a hit point always lies in a cell the DDA
  visits and whose list holds the triangle;
- a closest hit found in a cell is accepted only when its ``t`` is no later than the cell's
  exit ``t``; otherwise the walk continues with ``t`` as the upper bound (a triangle of a later
  cell may be closer: the classic grid bug);
- both sides of a triangle count; ``tmin < t < tmax`` strictly; a ray lying in a triangle's
  plane does not hit it.

The single-ray functions (:func:`closest_hit_one`, :func:`any_hit_one`) are ``@jit`` so other
kernels call them inside their own numba loops; their fan twins (:func:`closest_hit_fan`,
:func:`any_hit_fan`, one :func:`_walk`) serve the many rays leaving one point of a surface (a
junction gather, a hit's shadow rays) and skip the triangles lying wholly below that point's
tangent plane, decided once per point (:class:`Fan`): the same hits, fewer tests. The batch
functions wrap them for arrays of rays; the ``*_brute`` functions test every triangle and are
the reference for tests.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import prange

from daskrad.kernels._jit import WALK_REGISTERS, jit, jit_leaf, jit_parallel
from daskrad.kernels.tolerances import (
    COORD_ROUND,
    FAN_MARGIN,
    GRID_MARGIN,
    GRID_PAD,
    LOCATE_BARY,
    LOCATE_PLANE,
    RAY_EPS,
)

#: Largest number of cells along one axis.
MAX_DIM = 512

#: Default cells per triangle (λ in the classic heuristic cells ≈ λ·T). A sweep of λ from 0.5
#: to 8 on 10k/100k-triangle soups and height fields (bench_grid's scenes) gave speeds within
#: the machine's noise of each other; 2 was never far from the best on either kind of scene.
DEFAULT_DENSITY = 2.0

# The box padding, registration margin and coordinate rounding of the grid are GRID_PAD,
# GRID_MARGIN and COORD_ROUND in daskrad/kernels/tolerances.py.


class Grid(NamedTuple):
    """A uniform voxel grid over a triangle soup.

    origin : (3,) float64
        The grid's lower corner.
    cell : (3,) float64
        Cell size per axis.
    dims : (3,) int64
        Cells per axis ``(nx, ny, nz)``; ``C = nx * ny * nz``.
    cell_start : (C + 1,) int64
        CSR offsets into ``cell_items``; cell ``c = (k * ny + j) * nx + i``.
    cell_items : (K,) int32
        Triangle ids, increasing within a cell.
    triangles : (T, 3, 3) float64
        The triangles' vertices.
    eps : float
        Absolute edge tolerance of the ray–triangle test, ``rel_eps * diag``.
    """

    origin: np.ndarray
    cell: np.ndarray
    dims: np.ndarray
    cell_start: np.ndarray
    cell_items: np.ndarray
    triangles: np.ndarray
    eps: float


# ------------------------------------------------------------------------------------------
# Registration: separating-axis triangle–box overlap.


@jit_leaf
def _separated(ax, ay, az, p0x, p0y, p0z, p1x, p1y, p1z, p2x, p2y, p2z, hx, hy, hz):
    """Whether axis ``a`` separates the triangle ``p`` (box-centred) from the box ``±h``."""
    if ax == 0.0 and ay == 0.0 and az == 0.0:
        return False  # degenerate axis (parallel or zero-length edge): proves nothing
    q0 = ax * p0x + ay * p0y + az * p0z
    q1 = ax * p1x + ay * p1y + az * p1z
    q2 = ax * p2x + ay * p2y + az * p2z
    r = hx * abs(ax) + hy * abs(ay) + hz * abs(az)
    return min(q0, q1, q2) > r or max(q0, q1, q2) < -r


@jit_leaf
def _tri_box_overlap(tri, cx, cy, cz, hx, hy, hz):
    """Akenine-Möller's test: triangle ``tri (3, 3)`` against the box ``c ± h`` (13 axes)."""
    p0x = tri[0, 0] - cx
    p0y = tri[0, 1] - cy
    p0z = tri[0, 2] - cz
    p1x = tri[1, 0] - cx
    p1y = tri[1, 1] - cy
    p1z = tri[1, 2] - cz
    p2x = tri[2, 0] - cx
    p2y = tri[2, 1] - cy
    p2z = tri[2, 2] - cz
    # The box's own axes (the triangle's bounding box against the box).
    if min(p0x, p1x, p2x) > hx or max(p0x, p1x, p2x) < -hx:
        return False
    if min(p0y, p1y, p2y) > hy or max(p0y, p1y, p2y) < -hy:
        return False
    if min(p0z, p1z, p2z) > hz or max(p0z, p1z, p2z) < -hz:
        return False
    # The triangle's plane.
    f0x, f0y, f0z = p1x - p0x, p1y - p0y, p1z - p0z
    f1x, f1y, f1z = p2x - p1x, p2y - p1y, p2z - p1z
    f2x, f2y, f2z = p0x - p2x, p0y - p2y, p0z - p2z
    nx = f0y * f1z - f0z * f1y
    ny = f0z * f1x - f0x * f1z
    nz = f0x * f1y - f0y * f1x
    if _separated(nx, ny, nz, p0x, p0y, p0z, p1x, p1y, p1z, p2x, p2y, p2z, hx, hy, hz):
        return False
    # The nine cross products of a box axis with an edge: e_x × f = (0, -fz, fy), etc.
    for fx, fy, fz in ((f0x, f0y, f0z), (f1x, f1y, f1z), (f2x, f2y, f2z)):
        if _separated(0.0, -fz, fy, p0x, p0y, p0z, p1x, p1y, p1z, p2x, p2y, p2z, hx, hy, hz):
            return False
        if _separated(fz, 0.0, -fx, p0x, p0y, p0z, p1x, p1y, p1z, p2x, p2y, p2z, hx, hy, hz):
            return False
        if _separated(-fy, fx, 0.0, p0x, p0y, p0z, p1x, p1y, p1z, p2x, p2y, p2z, hx, hy, hz):
            return False
    return True


@jit_leaf
def _cell_range(lo, hi, origin, cell, n):
    """Indices of the first and last cell along one axis that ``[lo, hi]`` touches."""
    a = int(np.floor((lo - origin) / cell))
    b = int(np.floor((hi - origin) / cell))
    return max(0, min(n - 1, a)), max(0, min(n - 1, b))


@jit
def _tri_cells(triangles, t, origin, cell, dims, margin, exact, out, at, write):
    """The cells triangle ``t`` is registered in (those its bounding box, widened by
    ``margin``, touches and, when ``exact``, whose box widened by ``margin`` it overlaps), in
    the order ``k``, then ``j``, then ``i``: their number, written to ``out[at:]`` when
    ``write``."""
    nx, ny, nz = dims[0], dims[1], dims[2]
    hx = 0.5 * cell[0] + margin
    hy = 0.5 * cell[1] + margin
    hz = 0.5 * cell[2] + margin
    tri = triangles[t]
    i0, i1 = _cell_range(tri[:, 0].min() - margin, tri[:, 0].max() + margin,
                         origin[0], cell[0], nx)
    j0, j1 = _cell_range(tri[:, 1].min() - margin, tri[:, 1].max() + margin,
                         origin[1], cell[1], ny)
    k0, k1 = _cell_range(tri[:, 2].min() - margin, tri[:, 2].max() + margin,
                         origin[2], cell[2], nz)
    n = 0
    for k in range(k0, k1 + 1):
        cz = origin[2] + (k + 0.5) * cell[2]
        for j in range(j0, j1 + 1):
            cy = origin[1] + (j + 0.5) * cell[1]
            for i in range(i0, i1 + 1):
                if exact:
                    cx = origin[0] + (i + 0.5) * cell[0]
                    if not _tri_box_overlap(tri, cx, cy, cz, hx, hy, hz):
                        continue
                if write:
                    out[at + n] = (k * ny + j) * nx + i
                n += 1
    return n


@jit_parallel
def _cells(triangles, origin, cell, dims, margin, exact):
    """``(offsets (T + 1,), cells (offsets[-1],))``: the cells of triangle ``t`` are
    ``cells[offsets[t]:offsets[t + 1]]`` (:func:`_tri_cells`), the triangles taken side by
    side on numba's threads (each writes its own slice: the same arrays on any number of
    threads). It was one serial pass, counting then filling, and the largest serial kernel of
    a run's client (the 73,000-element Cornell box: ~0.3 s over its four grids)."""
    n = triangles.shape[0]
    counts = np.zeros(n, np.int64)
    none = np.zeros(0, np.int64)
    for t in prange(n):
        counts[t] = _tri_cells(triangles, t, origin, cell, dims, margin, exact, none, 0, False)
    offsets = np.zeros(n + 1, np.int64)
    for t in range(n):
        offsets[t + 1] = offsets[t] + counts[t]
    cells = np.empty(offsets[n], np.int64)
    for t in prange(n):
        _tri_cells(triangles, t, origin, cell, dims, margin, exact, cells, offsets[t], True)
    return offsets, cells


@jit
def _cell_lists(offsets, cells, n_cells):
    """The grid's CSR lists from :func:`_cells`'s pairs: ``(cell_start (C + 1,),
    cell_items)``, each cell's triangles in ascending order (a counting sort by cell, stable
    in the triangle)."""
    cell_start = np.zeros(n_cells + 1, np.int64)
    for p in range(cells.shape[0]):
        cell_start[cells[p] + 1] += 1
    for c in range(n_cells):
        cell_start[c + 1] += cell_start[c]
    cursor = cell_start[:-1].copy()
    items = np.empty(cells.shape[0], np.int32)
    for t in range(offsets.shape[0] - 1):
        for p in range(offsets[t], offsets[t + 1]):
            c = cells[p]
            items[cursor[c]] = t
            cursor[c] += 1
    return cell_start, items


def grid_dims(extent: np.ndarray, n_triangles: int, density: float) -> np.ndarray:
    """Cells per axis: ``≈ density · n_triangles`` cubic-ish cells over a box of ``extent``.

    An axis too thin for one cell of the common size (a flat scene) gets one cell, and the
    cell budget is spread over the other axes; each axis is clamped to ``[1, MAX_DIM]``.

    Returns (3,) int64.
    """
    extent = np.asarray(extent, dtype=np.float64)
    target = max(1.0, density * n_triangles)
    dims = np.ones(3, dtype=np.int64)
    active = extent > 0
    for _ in range(3):  # at most one axis drops out per round
        if not active.any():
            break
        side = (np.prod(extent[active]) / target) ** (1.0 / active.sum())
        n = extent / side
        thin = active & (n < 1.0)
        if thin.any():
            active &= ~thin
            continue
        dims[active] = np.clip(np.round(n[active]), 1, MAX_DIM).astype(np.int64)
        break
    return dims


def build_grid(
    triangles: np.ndarray,
    rel_eps: float = RAY_EPS,
    density: float = DEFAULT_DENSITY,
    exact: bool = True,
) -> Grid:
    """Build the uniform grid over ``triangles``.

    triangles : (T, 3, 3) float64
        Vertices; finite.
    rel_eps : float
        Edge tolerance relative to the scene diagonal (default ``tolerances.RAY_EPS``).
    density : float
        Cells per triangle (λ); the grid has about ``density * T`` cells.
    exact : bool
        Register by exact triangle–box overlap (True) or by bounding box only (False).
    """
    tris = np.ascontiguousarray(triangles, dtype=np.float64)
    if tris.ndim != 3 or tris.shape[1:] != (3, 3):
        raise ValueError(f"triangles must have shape (T, 3, 3), not {tris.shape}")
    if not np.isfinite(tris).all():
        raise ValueError("triangles must be finite")
    if len(tris):
        lo = tris.min(axis=(0, 1))
        hi = tris.max(axis=(0, 1))
    else:
        lo = np.zeros(3)
        hi = np.zeros(3)
    diag = float(np.linalg.norm(hi - lo))
    scale = diag if diag > 0 else 1.0  # a single point: any positive scale will do
    maxabs = float(np.abs(np.concatenate([lo, hi])).max())
    eps = rel_eps * scale
    pad = GRID_PAD * scale + COORD_ROUND * maxabs
    origin = lo - pad
    extent = (hi + pad) - origin
    dims = grid_dims(extent, len(tris), density)
    cell = extent / dims
    margin = 2.0 * eps + GRID_MARGIN * scale + COORD_ROUND * maxabs
    n_cells = int(np.prod(dims))
    cell_start, cell_items = _cell_lists(*_cells(tris, origin, cell, dims, margin, exact),
                                         n_cells)
    return Grid(origin, cell, dims, cell_start, cell_items, tris, float(eps))


def locator(triangles: np.ndarray) -> np.ndarray:
    """``(T, 13) float64``: what :func:`closest_hit_located` needs to find a point in each of
    ``triangles (T, 3, 3)``: per row the first corner ``v0`` (3), the vectors ``a`` (3) and
    ``b`` (3) that give a point's barycentric coordinates ``u = (P − v0) · a`` (of corner 1)
    and ``v = (P − v0) · b`` (of corner 2) within the triangle's plane, its unit normal ``n``
    (3, the winding's) and its plane offset ``n · v0``. A degenerate triangle has zeros and
    an infinite offset: no point passes its plane test."""
    tris = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    v0 = tris[:, 0]
    e1 = tris[:, 1] - v0
    e2 = tris[:, 2] - v0
    normal = np.cross(e1, e2)
    nn = np.einsum("ij,ij->i", normal, normal)
    ok = nn > 0.0
    inv = np.where(ok, 1.0 / np.where(ok, nn, 1.0), 0.0)[:, None]
    # N·((P − v0) × e2) / |N|² and N·(e1 × (P − v0)) / |N|², as dot products with P − v0
    a = np.cross(e2, normal) * inv
    b = np.cross(normal, e1) * inv
    unit = normal * np.sqrt(inv)
    offset = np.where(ok, np.einsum("ij,ij->i", unit, v0), np.inf)
    return np.ascontiguousarray(np.column_stack([v0, a, b, unit, offset]))


# ------------------------------------------------------------------------------------------
# Ray–triangle test.


@jit_leaf
def _intersect(tris, k, ox, oy, oz, dx, dy, dz, tmin, tmax, eps):
    """Möller–Trumbore on triangle ``tris[k]`` with an edge tolerance: ``(hit, t, u, v)`` for
    ``tmin < t < tmax``.

    A hit point outside the triangle by at most ``eps`` (distance in its plane from the
    nearest edge line) still counts: the barycentric of the vertex opposite an edge is the
    distance from that edge's line over the triangle's height there, ``|n| / |edge|``.
    """
    miss = (False, np.inf, 0.0, 0.0)
    # Scalar reads, no per-triangle array view (a view per test costs more than the test).
    v0x, v0y, v0z = tris[k, 0, 0], tris[k, 0, 1], tris[k, 0, 2]
    e1x, e1y, e1z = tris[k, 1, 0] - v0x, tris[k, 1, 1] - v0y, tris[k, 1, 2] - v0z
    e2x, e2y, e2z = tris[k, 2, 0] - v0x, tris[k, 2, 1] - v0y, tris[k, 2, 2] - v0z
    px = dy * e2z - dz * e2y
    py = dz * e2x - dx * e2z
    pz = dx * e2y - dy * e2x
    det = e1x * px + e1y * py + e1z * pz
    if det == 0.0:  # ray parallel to the plane (or a degenerate triangle)
        return miss
    inv = 1.0 / det
    dd = dx * dx + dy * dy + dz * dz
    # Near-edge test: reject when even the lower bound |n| >= |det| / |d| (det = -d·n) puts the
    # point beyond eps, which settles almost every miss without |n|² = |e1 × e2|²; compute
    # |n|² only for points near an edge (nn < 0: not yet computed).
    nn = -1.0
    sx, sy, sz = ox - v0x, oy - v0y, oz - v0z
    u = (sx * px + sy * py + sz * pz) * inv
    if u < 0.0:
        ee = e2x * e2x + e2y * e2y + e2z * e2z
        if u * u * det * det > eps * eps * dd * ee:
            return miss
        nn = _cross_norm2(e1x, e1y, e1z, e2x, e2y, e2z)
        if u * u * nn > eps * eps * ee:
            return miss
    qx = sy * e1z - sz * e1y
    qy = sz * e1x - sx * e1z
    qz = sx * e1y - sy * e1x
    v = (dx * qx + dy * qy + dz * qz) * inv
    if v < 0.0:
        ee = e1x * e1x + e1y * e1y + e1z * e1z
        if v * v * det * det > eps * eps * dd * ee:
            return miss
        if nn < 0.0:
            nn = _cross_norm2(e1x, e1y, e1z, e2x, e2y, e2z)
        if v * v * nn > eps * eps * ee:
            return miss
    w = 1.0 - u - v
    if w < 0.0:
        fx, fy, fz = e2x - e1x, e2y - e1y, e2z - e1z
        ee = fx * fx + fy * fy + fz * fz
        if w * w * det * det > eps * eps * dd * ee:
            return miss
        if nn < 0.0:
            nn = _cross_norm2(e1x, e1y, e1z, e2x, e2y, e2z)
        if w * w * nn > eps * eps * ee:
            return miss
    t = (e2x * qx + e2y * qy + e2z * qz) * inv
    if not (t > tmin and t < tmax):
        return miss
    return True, t, u, v


#: The walk's ray–triangle test (:func:`_intersect`), for kernels that test a grid's triangles
#: in an order of their own (:mod:`daskrad.kernels.view`): the same answer, bit for bit.
intersect = _intersect


@jit_leaf
def _cross_norm2(ax, ay, az, bx, by, bz):
    """``|a × b|²``."""
    cx = ay * bz - az * by
    cy = az * bx - ax * bz
    cz = ax * by - ay * bx
    return cx * cx + cy * cy + cz * cz


# ------------------------------------------------------------------------------------------
# Fans: many rays from one origin into one half-space.


class Fan(NamedTuple):
    """Rays from one origin ``o`` above a surface, all rising above the plane through ``o``
    with unit normal ``normal`` (a vertex's gather, a hit's shadow rays): no such ray can hit a
    triangle lying wholly below that plane, yet the cells near ``o`` hold the surface's own
    triangles, and every ray tested them (the Cornell box's junction gather: 35 of 62 tests a
    ray). A fan decides that once per triangle and origin, the first time a ray meets it.

    stamp : (T,) int32
        ``2 · key + 1``: triangle wholly below the current fan's plane; ``2 · key``: not;
        anything else: not decided yet for this fan.
    key : (1,) int32
        The current fan's number (``-1``: no fan); :func:`aim_fan` moves it on, so one stamp
        array serves every origin of a kernel call without clearing.
    origin, normal : (3,) float64
        The current fan's origin and plane normal.
    margin : (1,) float64
        How far below the plane a triangle's highest corner must lie (:func:`aim_fan`).
    blocker : (S,) int64
        Per cache slot (an area light of a shadow-ray kernel), the triangle that blocked the
        last shadow ray asked through it, or -1 (:func:`any_hit_cached`). It outlives
        :func:`aim_fan`: the next point (the next sample of a pixel, the next pixel of a
        tile) is most often hidden from the light by the same triangle.
    tested : (T,) int32, ray : (1,) int32
        The walk's mailbox: ``tested[t] == ray[0]`` when the current ray (each walk numbers
        its ray, :func:`_next_ray`) has tested triangle ``t`` already, in an earlier cell.
        Empty for :data:`NO_FAN` (and every fan when :data:`WALK_MARKS` is False), whose
        walks remember the last four triangles instead. A fan walks only the grid it was made
        for: its ``stamp`` and ``tested`` are indexed by that grid's triangles.
    """

    stamp: np.ndarray
    key: np.ndarray
    origin: np.ndarray
    normal: np.ndarray
    margin: np.ndarray
    blocker: np.ndarray
    tested: np.ndarray
    ray: np.ndarray


#: Whether a fan marks the triangles each of its rays tested (:attr:`Fan.tested`); False
#: (``DASKRAD_WALK_REGISTERS=1``, ``benchmarks/bench_leaves.py --reference registers``) makes
#: fans without marks, whose walks remember the last four triangles, as before.
WALK_MARKS = not WALK_REGISTERS


@jit
def new_fan(grid, slots=0):
    """A :class:`Fan` for ``grid``'s triangles, aimed nowhere yet, with ``slots`` blocker
    cache slots. It is scratch: one per thread, aimed (:func:`aim_fan`) at each origin in
    turn."""
    return Fan(np.full(grid.triangles.shape[0], -1, np.int32), np.full(1, -1, np.int32),
               np.zeros(3), np.zeros(3), np.zeros(1), np.full(slots, -1, np.int64),
               np.full(grid.triangles.shape[0] if WALK_MARKS else 0, -1, np.int32),
               np.zeros(1, np.int32))


#: A fan that culls nothing (``key`` -1): the plain walk of :func:`closest_hit_one`.
NO_FAN = Fan(np.full(0, -1, np.int32), np.full(1, -1, np.int32), np.zeros(3), np.zeros(3),
             np.zeros(1), np.full(0, -1, np.int64), np.full(0, -1, np.int32),
             np.zeros(1, np.int32))


#: The last ray number a fan's mailbox takes before it is cleared (int32's largest).
LAST_RAY = 2**31 - 1


@jit_leaf
def _next_ray(fan):
    """Number the next ray walked with ``fan``'s mailbox (``fan.tested``), clearing the
    mailbox when the numbers run out; returns the number."""
    r = fan.ray[0]
    if r >= LAST_RAY:
        for t in range(fan.tested.shape[0]):
            fan.tested[t] = -1
        r = -1
    fan.ray[0] = r + 1
    return r + 1


@jit_leaf
def aim_fan(fan, grid, o, n, lift):
    """Make ``fan`` the rays from ``o (3,)`` that rise above the plane through it with unit
    normal ``n (3,)``; ``o`` lies ``lift`` (the rays' offset, a length) above its surface.

    A triangle is skipped only when its highest corner lies more than ``lift / 2`` plus
    ``FAN_MARGIN`` edge tolerances (and the rounding of the coordinates) below the plane: the
    surface's own triangles, ``lift`` below, are. A ray ``o + t d`` with ``d · n > 0`` and
    ``t >= 0`` never goes below the plane, and the ray–triangle test's edge tolerance
    (``grid.eps``, measured from each edge's line) reaches past a corner of angle ``α`` by
    about ``2 eps / sin α``: within the margin but for slivers with an angle under ~1e-5
    radian, where the plain walk's hit would be the edge tolerance's artefact anyway."""
    fan.key[0] += 1
    for a in range(3):
        fan.origin[a] = o[a]
        fan.normal[a] = n[a]
    fan.margin[0] = (0.5 * lift + FAN_MARGIN * grid.eps
                     + COORD_ROUND * (abs(o[0]) + abs(o[1]) + abs(o[2])))


@jit_leaf
def _below(fan, tris, tri, key):
    """Whether triangle ``tri`` lies wholly below ``fan``'s plane (decided once per fan)."""
    s = fan.stamp[tri]
    if s == 2 * key + 1:
        return True
    if s == 2 * key:
        return False
    o, n = fan.origin, fan.normal
    top = -np.inf
    for a in range(3):
        top = max(top, (tris[tri, a, 0] - o[0]) * n[0] + (tris[tri, a, 1] - o[1]) * n[1]
                  + (tris[tri, a, 2] - o[2]) * n[2])
    below = top < -fan.margin[0]
    fan.stamp[tri] = 2 * key + (1 if below else 0)
    return below


# ------------------------------------------------------------------------------------------
# Traversal.


@jit_leaf
def _slab(o, d, lo, hi, t0, t1):
    """Clip ``[t0, t1]`` to the slab ``lo <= o + t d <= hi`` of one axis (empty: t0 > t1)."""
    if d == 0.0:
        if o < lo or o > hi:
            return 1.0, 0.0
        return t0, t1
    ta = (lo - o) / d
    tb = (hi - o) / d
    if ta > tb:
        ta, tb = tb, ta
    return max(t0, ta), min(t1, tb)


@jit_leaf
def _start(o, d, t0, origin, cell, n):
    """Cell index at ``t0`` along one axis, its step, and the next boundary plane's index."""
    i = int(np.floor((o + t0 * d - origin) / cell)) if d != 0.0 else int(
        np.floor((o - origin) / cell))
    i = max(0, min(n - 1, i))
    if d > 0.0:
        return i, 1, 1
    if d < 0.0:
        return i, -1, 0
    return i, 0, 0


@jit_leaf
def _next_t(o, inv, i, plane_off, origin, cell):
    """``t`` at which the ray leaves cell ``i`` along one axis (inf when parallel); ``inv``
    is ``1 / d`` (0 when the ray is parallel to the axis's planes)."""
    if inv == 0.0:
        return np.inf
    # Recomputed from the plane's index every step (no accumulated tDelta), so the cell
    # boundaries the walk uses are those of registration up to two roundings (a product by
    # 1/d: a division's latency on every step of the walk was its dearest part), far within
    # GRID_MARGIN.
    return (origin + (i + plane_off) * cell - o) * inv


@jit_leaf
def _culls(fan, ox, oy, oz, dx, dy, dz, tmin):
    """Whether ``fan``'s cull holds for the ray: from its origin, rising above its plane,
    ``t >= 0``."""
    return (fan.key[0] >= 0 and tmin >= 0.0 and ox == fan.origin[0] and oy == fan.origin[1]
            and oz == fan.origin[2]
            and (dx * fan.normal[0] + dy * fan.normal[1] + dz * fan.normal[2]) > 0.0)


@jit_leaf
def _walk(grid, ox, oy, oz, dx, dy, dz, tmin, tmax, any_mode, fan):
    """Walk the grid: closest hit ``(t, tri, u, v)``, or the first hit found if ``any_mode``.

    ``fan``: a :class:`Fan` of this grid, whose triangles wholly below its plane are skipped
    (when the ray rises above that plane) and whose marks keep the ray from testing a
    triangle twice (:attr:`Fan.tested`), or :data:`NO_FAN`. No triangle is tested twice in
    a row of four either way; the answer is the same bits with or without a fan."""
    miss = (np.inf, -1, 0.0, 0.0)
    if not (np.isfinite(ox) and np.isfinite(oy) and np.isfinite(oz) and np.isfinite(dx)
            and np.isfinite(dy) and np.isfinite(dz)):
        return miss
    if dx == 0.0 and dy == 0.0 and dz == 0.0:
        return miss
    if not (tmin < tmax):  # also catches NaN limits
        return miss
    origin, cell, dims = grid.origin, grid.cell, grid.dims
    nx, ny, nz = dims[0], dims[1], dims[2]
    t0, t1 = _slab(ox, dx, origin[0], origin[0] + nx * cell[0], tmin, tmax)
    t0, t1 = _slab(oy, dy, origin[1], origin[1] + ny * cell[1], t0, t1)
    t0, t1 = _slab(oz, dz, origin[2], origin[2] + nz * cell[2], t0, t1)
    if t0 > t1:
        return miss
    i, si, oi = _start(ox, dx, t0, origin[0], cell[0], nx)
    j, sj, oj = _start(oy, dy, t0, origin[1], cell[1], ny)
    k, sk, ok = _start(oz, dz, t0, origin[2], cell[2], nz)
    cell_start, cell_items, tris, eps = grid.cell_start, grid.cell_items, grid.triangles, grid.eps
    best_t, best_tri, best_u, best_v = tmax, -1, 0.0, 0.0
    key = fan.key[0]
    cull = _culls(fan, ox, oy, oz, dx, dy, dz, tmin)
    # 1/d, 0 for an axis the ray does not cross (|d| so small that 1/d would overflow to
    # inf, and inf · 0 make a NaN boundary, is taken as parallel: it moves the ray by less
    # than 1e-300 of t along that axis)
    ix = 1.0 / dx if abs(dx) >= 1e-300 else 0.0
    iy = 1.0 / dy if abs(dy) >= 1e-300 else 0.0
    iz = 1.0 / dz if abs(dz) >= 1e-300 else 0.0
    tx = _next_t(ox, ix, i, oi, origin[0], cell[0])
    ty = _next_t(oy, iy, j, oj, origin[1], cell[1])
    tz = _next_t(oz, iz, k, ok, origin[2], cell[2])
    # A triangle met again in a later cell is not tested again. Its answer could not change:
    # a miss stays a miss (the range only shrinks), and a hit is the best so far or behind
    # it. A large polygon lies in many cells: two thirds of the tests of graz's free shadow
    # rays were repeats (35 tests and 78 cells a ray). A fan's rays mark every triangle they
    # test (fan.tested, numbered per ray); other walks remember the last four, in registers
    # (they catch two thirds of the repeats; the marks catch all: RenderPark's classroom's
    # free shadow rays test 40 triangles where the four left 63). A fan belongs to the grid
    # it was made for (its stamp and marks are indexed by that grid's triangles); the size
    # test only keeps a fan without marks (NO_FAN, WALK_MARKS False) on the registers.
    marked = fan.tested.shape[0] == tris.shape[0] and tris.shape[0] > 0
    ray = _next_ray(fan) if marked else 0
    r0 = r1 = r2 = r3 = -1
    while True:
        t_exit = min(tx, ty, tz)
        c = (k * ny + j) * nx + i
        for m in range(cell_start[c], cell_start[c + 1]):
            tri = cell_items[m]
            if marked:
                if fan.tested[tri] == ray:
                    continue
                fan.tested[tri] = ray
            elif tri == r0 or tri == r1 or tri == r2 or tri == r3:
                continue
            if cull and _below(fan, tris, tri, key):
                continue
            if not marked:            # a culled triangle takes no register (as before marks)
                r3, r2, r1, r0 = r2, r1, r0, tri
            hit, t, u, v = _intersect(tris, tri, ox, oy, oz, dx, dy, dz, tmin, best_t, eps)
            if hit:
                if any_mode:
                    return t, tri, u, v
                best_t, best_tri, best_u, best_v = t, tri, u, v
        # Stop once the segment ends in this cell or a hit lies no later than its exit: any
        # closer hit lies in a cell already visited. A hit beyond the exit is only a bound.
        if t_exit >= min(t1, best_t):
            break
        if tx <= ty and tx <= tz:
            i += si
            if i < 0 or i >= nx:
                break
            tx = _next_t(ox, ix, i, oi, origin[0], cell[0])
        elif ty <= tz:
            j += sj
            if j < 0 or j >= ny:
                break
            ty = _next_t(oy, iy, j, oj, origin[1], cell[1])
        else:
            k += sk
            if k < 0 or k >= nz:
                break
            tz = _next_t(oz, iz, k, ok, origin[2], cell[2])
    if best_tri < 0:
        return miss
    return best_t, best_tri, best_u, best_v


@jit_leaf
def closest_hit_one(grid, o, d, tmin, tmax):
    """Closest hit of one ray ``o + t d``, ``tmin < t < tmax``: ``(t, tri, u, v)``.

    o, d : (3,) float64; ``d`` need not be unit (``t`` is in units of ``|d|``). On a miss
    ``t`` is inf and ``tri`` is -1. ``P = (1 - u - v) V0 + u V1 + v V2``.
    """
    return _walk(grid, o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax, False, NO_FAN)


@jit_leaf
def any_hit_one(grid, o, d, tmin, tmax):
    """Whether the ray ``o + t d`` hits any triangle with ``tmin < t < tmax`` (shadow ray)."""
    return _walk(grid, o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax, True, NO_FAN)[1] >= 0


@jit_leaf
def closest_hit_fan(grid, fan, o, d, tmin, tmax):
    """:func:`closest_hit_one` for a ray of ``fan`` (:func:`aim_fan` at ``o``): the same
    answer, without testing the triangles it has found wholly below its plane."""
    return _walk(grid, o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax, False, fan)


@jit_leaf
def closest_hit_located(polygons, fan, grid, loc, o, d, tmin, tmax):
    """:func:`closest_hit_fan` through ``grid`` (the elements' triangles), found through
    ``polygons`` (a grid over the surfaces those triangles tile, :func:`daskrad.preprocess.
    occluders`): ``(t, tri, u, v)`` with ``tri`` a triangle of ``grid``.

    The polygons are fewer and larger: a ray walks their grid past fewer triangles (the
    converted office's gather rays, 3.2 µs against 6.0 µs a ray). The point it hits is then
    located in the cell of ``grid`` that holds it: among the triangles registered there, one
    whose plane passes within ``LOCATE_PLANE`` edge tolerances of the point and whose
    barycentric coordinates (``loc``, :func:`locator`) hold it, up to ``LOCATE_BARY``. ``t`` is
    the polygon's. Where two surfaces coincide (two one-sided faces back to back, as an
    office's converted papers are), the one facing the ray is taken, as the item buffers
    take it (they cull faces turned away); a walk of the elements took whichever the
    round-off of ``t`` favoured. A point no element holds within the tolerances (a polygon's
    part the elements leave out, a quad twisted within ``PLANAR_QUAD``) gets the walk of
    ``grid``'s answer. ``fan``: aimed at ``o`` for ``polygons`` (:func:`aim_fan`), or
    :data:`NO_FAN`."""
    tp, ptri, _, _ = _walk(polygons, o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax, False,
                           fan)
    if ptri < 0:
        return np.inf, -1, 0.0, 0.0
    return locate_hit(grid, loc, o, d, tp, tmin, tmax)


@jit_leaf
def locate_hit(grid, loc, o, d, tp, tmin, tmax):
    """The triangle of ``grid`` that holds the point ``o + tp d`` a ray found on a polygon
    (:func:`closest_hit_located`'s second half, also for hits found by an item buffer over
    the polygons): ``(tp, tri, u, v)``, the triangle facing the ray where two coincide, or
    the walk of ``grid`` from ``o`` along ``d`` over ``(tmin, tmax)`` when no triangle holds
    the point within the tolerances."""
    px = o[0] + tp * d[0]
    py = o[1] + tp * d[1]
    pz = o[2] + tp * d[2]
    origin, cell, dims = grid.origin, grid.cell, grid.dims
    nx, ny, nz = dims[0], dims[1], dims[2]
    i = _cell_range(px, px, origin[0], cell[0], nx)[0]
    j = _cell_range(py, py, origin[1], cell[1], ny)[0]
    k = _cell_range(pz, pz, origin[2], cell[2], nz)[0]
    c = (k * ny + j) * nx + i
    ptol = LOCATE_PLANE * grid.eps + COORD_ROUND * (abs(px) + abs(py) + abs(pz))
    away, away_u, away_v = -1, 0.0, 0.0
    for m in range(grid.cell_start[c], grid.cell_start[c + 1]):
        tri = grid.cell_items[m]
        if abs(loc[tri, 9] * px + loc[tri, 10] * py + loc[tri, 11] * pz - loc[tri, 12]) > ptol:
            continue
        wx = px - loc[tri, 0]
        wy = py - loc[tri, 1]
        wz = pz - loc[tri, 2]
        u = wx * loc[tri, 3] + wy * loc[tri, 4] + wz * loc[tri, 5]
        if u < -LOCATE_BARY:
            continue
        v = wx * loc[tri, 6] + wy * loc[tri, 7] + wz * loc[tri, 8]
        if v < -LOCATE_BARY or u + v > 1.0 + LOCATE_BARY:
            continue
        if loc[tri, 9] * d[0] + loc[tri, 10] * d[1] + loc[tri, 11] * d[2] < 0.0:
            return tp, tri, u, v
        if away < 0:
            away, away_u, away_v = tri, u, v
    if away >= 0:
        return tp, away, away_u, away_v
    # no element holds the point within the tolerances (a polygon's part the elements leave
    # out, a quad twisted within PLANAR_QUAD, an edge tolerance's reach): the elements' walk
    # answers, exactly as without the polygons
    return _walk(grid, o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax, False, NO_FAN)


@jit_leaf
def any_hit_fan(grid, fan, o, d, tmin, tmax):
    """:func:`any_hit_one` for a ray of ``fan`` (:func:`aim_fan` at ``o``)."""
    return _walk(grid, o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax, True, fan)[1] >= 0


@jit_leaf
def any_hit_cached(grid, fan, o, d, tmin, tmax, slot):
    """:func:`any_hit_fan`, trying first the triangle that blocked the last ray of cache
    ``slot`` (``fan.blocker``; a slot out of its range caches nothing). The same answer: a
    triangle the ray meets within ``(tmin, tmax)`` (and the fan does not cull) lies in a cell
    the walk visits and holds it (the grid's registration margin), so the walk would have
    answered blocked too; only its cost changes (Haines & Greenberg's shadow cache)."""
    cached = 0 <= slot < fan.blocker.shape[0]
    if cached:
        tri = fan.blocker[slot]
        if tri >= 0 and not (_culls(fan, o[0], o[1], o[2], d[0], d[1], d[2], tmin)
                             and _below(fan, grid.triangles, tri, fan.key[0])):
            if _intersect(grid.triangles, tri, o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax,
                          grid.eps)[0]:
                return True
    tri = _walk(grid, o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax, True, fan)[1]
    if tri < 0:
        return False
    if cached:
        fan.blocker[slot] = tri
    return True


@jit_leaf
def closest_hit_brute_one(grid, o, d, tmin, tmax):
    """:func:`closest_hit_one` by testing every triangle, in id order (ties: lowest id)."""
    tris, eps = grid.triangles, grid.eps
    best_t, best_tri, best_u, best_v = tmax, -1, 0.0, 0.0
    for k in range(tris.shape[0]):
        hit, t, u, v = _intersect(tris, k, o[0], o[1], o[2], d[0], d[1], d[2], tmin, best_t, eps)
        if hit:
            best_t, best_tri, best_u, best_v = t, k, u, v
    if best_tri < 0:
        return np.inf, -1, 0.0, 0.0
    return best_t, best_tri, best_u, best_v


@jit_leaf
def any_hit_brute_one(grid, o, d, tmin, tmax):
    """:func:`any_hit_one` by testing every triangle."""
    tris, eps = grid.triangles, grid.eps
    for k in range(tris.shape[0]):
        if _intersect(tris, k, o[0], o[1], o[2], d[0], d[1], d[2], tmin, tmax, eps)[0]:
            return True
    return False


# ------------------------------------------------------------------------------------------
# Batches of rays.


@jit
def _closest_batch(grid, origins, directions, tmin, tmax, brute, polygons, loc, located):
    """Closest hits of a batch: by brute force, by the walk of ``grid``, or (``located``)
    found through ``polygons`` and located among ``grid``'s triangles (``loc``)."""
    n = origins.shape[0]
    t_out = np.empty(n, dtype=np.float64)
    tri_out = np.empty(n, dtype=np.int32)
    u_out = np.empty(n, dtype=np.float64)
    v_out = np.empty(n, dtype=np.float64)
    for r in range(n):
        if located:
            t, tri, u, v = closest_hit_located(polygons, NO_FAN, grid, loc, origins[r],
                                               directions[r], tmin[r], tmax[r])
        elif brute:
            t, tri, u, v = closest_hit_brute_one(grid, origins[r], directions[r], tmin[r], tmax[r])
        else:
            t, tri, u, v = closest_hit_one(grid, origins[r], directions[r], tmin[r], tmax[r])
        t_out[r] = t
        tri_out[r] = tri
        u_out[r] = u
        v_out[r] = v
    return t_out, tri_out, u_out, v_out


@jit
def _any_batch(grid, origins, directions, tmin, tmax, brute):
    n = origins.shape[0]
    out = np.empty(n, dtype=np.bool_)
    for r in range(n):
        if brute:
            out[r] = any_hit_brute_one(grid, origins[r], directions[r], tmin[r], tmax[r])
        else:
            out[r] = any_hit_one(grid, origins[r], directions[r], tmin[r], tmax[r])
    return out


def _rays(origins, directions, tmin, tmax):
    """Contiguous float64 copies of a batch of rays; ``tmin``/``tmax`` may be scalars."""
    o = np.ascontiguousarray(origins, dtype=np.float64)
    d = np.ascontiguousarray(directions, dtype=np.float64)
    if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
        raise ValueError(f"origins and directions must be (n, 3), not {o.shape}, {d.shape}")
    n = o.shape[0]
    lo = np.ascontiguousarray(np.broadcast_to(np.asarray(tmin, dtype=np.float64), (n,)))
    hi = np.ascontiguousarray(np.broadcast_to(np.asarray(tmax, dtype=np.float64), (n,)))
    return o, d, lo, hi


#: The locator of no triangle (the kernels' argument when they walk instead).
NO_LOCATOR = np.zeros((0, 13))


@jit
def _located_batch(polygons, grid, loc, origins, directions, tmin, tmax):
    """:func:`_closest_batch`'s located hits: called with a literal ``True``, numba compiles
    that branch alone (the three branches in one compiled loop made the Cornell box's tiles
    0.54 s against 0.37 s)."""
    return _closest_batch(grid, origins, directions, tmin, tmax, False, polygons, loc, True)


@jit_parallel
def _located_triangles(polygons, grid, loc, origins, directions, tmin, tmax):
    """``(n,) int32``: the triangle each ray of :func:`_located_batch` hits (-1: none), the
    rays taken side by side on numba's threads (each its own answer: the same on any number
    of threads)."""
    n = origins.shape[0]
    out = np.empty(n, dtype=np.int32)
    for r in prange(n):
        out[r] = closest_hit_located(polygons, NO_FAN, grid, loc, origins[r], directions[r],
                                     tmin[r], tmax[r])[1]
    return out


def closest_hit_located_batch(polygons: Grid, loc: np.ndarray, grid: Grid, origins, directions,
                              tmin, tmax):
    """:func:`closest_hit` of ``grid``'s triangles for a batch of rays, each found through
    ``polygons`` and located among them (:func:`closest_hit_located`; ``loc``:
    :func:`locator` of ``grid.triangles``)."""
    return _located_batch(polygons, grid, np.ascontiguousarray(loc, dtype=np.float64),
                          *_rays(origins, directions, tmin, tmax))


def located_triangles(polygons: Grid, loc: np.ndarray, grid: Grid, origins, directions,
                      tmin, tmax) -> np.ndarray:
    """``(n,) int32``: the triangles of :func:`closest_hit_located_batch`'s hits (-1 on a
    miss), on every core: for a batch the caller casts alone (the client's view region of a
    furnished room, 480,000 primary rays on one core)."""
    return _located_triangles(polygons, grid, np.ascontiguousarray(loc, dtype=np.float64),
                              *_rays(origins, directions, tmin, tmax))


def closest_hit(grid: Grid, origins, directions, tmin, tmax):
    """Closest hits of a batch of rays through the grid.

    origins, directions : (n, 3) float64
    tmin, tmax : (n,) float64 (or scalars)

    Returns ``t (n,) float64`` (inf on a miss), ``tri (n,) int32`` (-1 on a miss),
    ``u, v (n,) float64``: barycentrics of vertices 1 and 2 of the hit triangle,
    ``P = (1 - u - v) V0 + u V1 + v V2``; a hit within ``eps`` outside an edge has a
    barycentric slightly below 0 (by at most ``eps`` over the triangle's height there).
    """
    return _closest_batch(grid, *_rays(origins, directions, tmin, tmax), False, grid, NO_LOCATOR,
                          False)


def any_hit(grid: Grid, origins, directions, tmin, tmax):
    """Shadow rays: ``(n,) bool``, True when some triangle is hit with ``tmin < t < tmax``."""
    return _any_batch(grid, *_rays(origins, directions, tmin, tmax), False)


def closest_hit_brute(grid: Grid, origins, directions, tmin, tmax):
    """:func:`closest_hit` by testing every triangle (reference; ties go to the lowest id)."""
    return _closest_batch(grid, *_rays(origins, directions, tmin, tmax), True, grid, NO_LOCATOR,
                          False)


def any_hit_brute(grid: Grid, origins, directions, tmin, tmax):
    """:func:`any_hit` by testing every triangle (reference)."""
    return _any_batch(grid, *_rays(origins, directions, tmin, tmax), True)
