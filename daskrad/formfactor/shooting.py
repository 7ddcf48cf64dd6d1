"""The form-factor task: sparse rows ``F_ij`` for a batch of shooting patches.

This is the unit of work the paper parallelised ("form factors for batches of a constant number
of patches"): it reads geometry only and returns small results, so it runs the same in-process
and on a Dask worker (:mod:`daskrad.distributed` calls :func:`shoot_rows` with a context it
caches per store generation).

Near field (docs/design.md §2). A form factor sampled at the shooter's centroid is exact only
far away: for a receiver at distance ``d`` from a shooter of radius ``r`` it errs by O((r/d)²),
which is the error that dominates flat radiosity along junctions (wall meets ceiling). For receivers
closer than ``NEAR_FIELD · r`` the shooter is not point-sampled: by reciprocity
``F_ij = F_ji · A_j / A_i``, and ``F_ji`` — from the receiver's centroid to the *whole* shooter
polygon — is Lambert's contour integral, exact in the shooter's extent. Occlusion is taken from
the method's own row at the centroid: the visible fraction of receiver ``j`` is its factor over
Lambert's unoccluded one from the same point (``won / covered`` for the default hemisphere
method), so one form-factor pass serves both. The near receivers' factors are then scaled so
that together they take exactly the share of energy the hemisphere pass gave them: the row sum
stays that of the hemisphere (≤ 1, and = 1 in a closed scene), so a shot never sends more
energy than the shooter holds, and only the distribution among near receivers changes.

``F_ji`` itself is an area average over the receiver (:func:`receiver_average`): a receiver
that shares an edge or a corner with the shooter sees it from a point-to-polygon factor that
varies as fast as the distance to the shared edge, so its centroid is not enough there.

Penumbrae (issue 7). Visibility taken at the centroid alone puts each receiver wholly in light
or in shadow, but an occluder at distance ``d`` from a shooter of radius ``r`` casts a penumbra
``~ r/d`` radians wide; summed over a scene the error breaks reciprocity (a two-sided fin on
the floor of a furnace box: column sums of F off by ±2.4 %, furnace error 1.3 %). A shooter
with an occluder within ``PENUMBRA`` radii (:mod:`daskrad.kernels.blockers`: only an element
whose plane has the shooter on one side and part of the scene on the other can occlude) is
sampled at stratified points and its row and visible fractions are area averages over them
(:func:`shooter_points`). Shooters without one, every shooter of a convex room among them,
keep the single centroid pass, bit for bit. A shot carrying little light beside the brightest
patch's leaves from one point even so (:data:`daskrad.solve.SAMPLE_SHARE`): the solve asks
for that row by another key (:func:`row_key`).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from daskrad import formfactor, tolerances
from daskrad.kernels.blockers import UNKNOWN, enclosed_points, nearest_blocker
from daskrad.kernels.geometry import element_planes, scene_diagonal
from daskrad.kernels.grid import Grid
from daskrad.kernels.nearfield import near_field, receiver_factors
from daskrad.mesh.types import Hierarchy
from daskrad.scene.corners import QUAD_HALVES, real_corners, repeat_third

#: A receiver closer to the shooter's centroid than ``NEAR_FIELD × radius`` is near: there the
#: point-sampled factor errs by more than a few per cent, (r/d)² > 1/16.
NEAR_FIELD = 4.0

#: A near receiver closer to the shooter than ``CLOSE ×`` its own size (``√A_j``) averages
#: ``F_ji`` over ``STRATA²`` points per triangle instead of taking it at its centroid.
CLOSE = 2.0
STRATA = 2


def _cyclic(a: float, b: float) -> np.ndarray:
    """``(3, 3) float64`` barycentric points: the cyclic permutations of ``(a, b, 1-a-b)``,
    whose mean is the centroid exactly, whatever ``a`` and ``b``."""
    c = 1.0 - a - b
    return np.array([(a, b, c), (c, a, b), (b, c, a)])


#: A shooter with an occluder closer than ``PENUMBRA`` radii is sampled at
#: :data:`SHOOTER_POINTS` in each of its triangles (6 for a quad), else at its centroid alone.
#: Measured (fin furnace error; Cornell box, plain Gouraud, RMS/white against the path tracer;
#: sample points per patch there): 4 radii and 3 points per triangle: 0.35 %, 0.0152, 4.0;
#: adding 6 per triangle within 2 radii: 0.30 %, 0.0156, 5.8; 3 radii: 0.47 %, 0.0152, 3.2;
#: centroid only: 1.28 %, 0.0172, 1.
PENUMBRA = 4.0

#: Barycentric sample points per triangle of a shooter with a near occluder. Not simple
#: fractions: a point at ½ or ⅓ of a patch lines up with the vertices the hierarchy puts at
#: the same fractions, and exact alignments are where round-off breaks ties in the raster.
SHOOTER_POINTS = _cyclic(0.6180, 0.2134)

#: An element folded away from the shooter by a dihedral angle of less than ``asin(√GRAZING)``
#: (1.8°), passing below the shooter's plane over the shooter, is not an occluder: seen from
#: any point of the shooter it rises less than that, hiding at most this fraction of the
#: cosine-weighted hemisphere. The measured Cornell box's red wall is two triangles folded by
#: about 0.3°, which would otherwise count as occluders of each other.
GRAZING = 1e-3


@dataclass(frozen=True)
class ShootContext:
    """Everything a form-factor task reads: geometry arrays and the method's settings.

    Shapes follow :class:`daskrad.mesh.types.Hierarchy`; ``patch_radius : (P,)`` and
    ``elem_radius : (E,)`` are the largest distances from a centroid to the corners,
    ``polygon_sides : (Q,) int8`` where the scene lies about each polygon's plane, filled in
    lazily (:func:`daskrad.kernels.blockers.nearest_blocker`), ``polygon_two_sided : (Q,) bool``
    (:func:`two_sided_polygons`), ``eps`` the coplanarity tolerance and ``gap`` the distance
    between the two sides of a two-sided face (lengths). ``grid`` is
    the voxel grid over the elements' triangles and ``tri_element : (T,) int`` the element of
    each of its triangles: the mesh's own (:class:`daskrad.preprocess.Mesh`), built once.
    ``diagonal`` is the scene's bounding-box diagonal (0 in a context made by hand: computed
    where needed). ``plane_normal : (E, 3)`` and ``plane_offset : (E,)`` are the elements'
    planes (:func:`daskrad.kernels.geometry.element_planes`), once per mesh rather than twice
    a row (None in a context made by hand: computed by each row). :func:`make_context` checks
    the geometry once; the rows trust it (:func:`daskrad.formfactor.checked_geometry`).
    """

    vertices: np.ndarray
    elem_verts: np.ndarray
    elem_area: np.ndarray
    elem_centroid: np.ndarray
    elem_normal: np.ndarray
    elem_polygon: np.ndarray
    patch_verts: np.ndarray
    patch_polygon: np.ndarray
    patch_area: np.ndarray
    patch_centroid: np.ndarray
    patch_normal: np.ndarray
    patch_radius: np.ndarray
    elem_radius: np.ndarray
    polygon_sides: np.ndarray
    polygon_two_sided: np.ndarray
    eps: float
    method: str
    resolution: int
    options: dict
    grid: Grid | None = None
    tri_element: np.ndarray | None = None
    gap: float = 0.0
    diagonal: float = 0.0       # the scene's bounding-box diagonal (0: not given)
    plane_normal: np.ndarray | None = None
    plane_offset: np.ndarray | None = None


def make_context(h: Hierarchy, method: str, resolution: int, grid: Grid | None = None,
                 tri_element: np.ndarray | None = None, **options) -> ShootContext:
    """The task context of a hierarchy; refuses an unknown method before any work starts.

    ``grid`` and ``tri_element`` are the voxel grid over ``h``'s element triangles and the
    element of each triangle (the pipeline passes the mesh's own); built here when omitted.
    """
    formfactor.get_method(method)
    # once: the rows trust both (the near field reads the patches' corners as an element's)
    formfactor.check_geometry(h.vertices, h.elem_verts)
    formfactor.check_geometry(h.vertices, h.patch_verts)
    if grid is None or tri_element is None:
        grid, tri_element = formfactor.element_grid(h.vertices, h.elem_verts)

    def radius(verts, centroid):
        corners = h.vertices[repeat_third(verts)]
        return np.linalg.norm(corners - centroid[:, None, :], axis=2).max(axis=1)

    diagonal = scene_diagonal(h.vertices)
    plane_normal, plane_offset = element_planes(h.vertices, h.elem_verts)
    eps = tolerances.COPLANAR * diagonal
    gap = tolerances.TWO_SIDED_GAP * diagonal
    return ShootContext(
        vertices=h.vertices, elem_verts=h.elem_verts, elem_area=h.elem_area,
        elem_centroid=h.elem_centroid, elem_normal=h.elem_normal, elem_polygon=h.elem_polygon,
        patch_verts=h.patch_verts, patch_polygon=h.patch_polygon, patch_area=h.patch_area,
        patch_centroid=h.patch_centroid, patch_normal=h.patch_normal,
        patch_radius=radius(h.patch_verts, h.patch_centroid),
        elem_radius=radius(h.elem_verts, h.elem_centroid),
        polygon_sides=np.full(len(h.polygon_material), UNKNOWN, np.int8),
        polygon_two_sided=two_sided_polygons(h, eps, gap), eps=eps, gap=gap,
        method=method, resolution=resolution, options=dict(options),
        grid=grid, tri_element=np.asarray(tri_element), diagonal=diagonal,
        plane_normal=plane_normal, plane_offset=plane_offset,
    )


def shooter_points(ctx: ShootContext, p: int) -> tuple[np.ndarray, np.ndarray]:
    """``points (k, 3), weights (k,)``: where patch ``p`` is sampled (``PENUMBRA``).

    The centroid with weight 1 when no occluder is within ``PENUMBRA`` radii; else
    :data:`SHOOTER_POINTS` in each of the patch's triangles, weighted by the triangle's area
    (Σ = 1, mean = centroid), less the points inside a closed object (:func:`_enclosed`).
    """
    reach = PENUMBRA * ctx.patch_radius[p]
    if not occluder_distance(ctx, p, reach) < reach:
        return ctx.patch_centroid[p][None], np.ones(1)
    corners = real_corners(ctx.patch_verts[p])
    bary = SHOOTER_POINTS
    halves = ctx.vertices[corners[QUAD_HALVES[:len(corners) - 2]]]
    area = 0.5 * np.linalg.norm(np.cross(halves[:, 1] - halves[:, 0],
                                         halves[:, 2] - halves[:, 0]), axis=1)
    points = np.einsum("kc,hcx->hkx", bary, halves).reshape(-1, 3)
    weights = np.repeat(area / area.sum() / len(bary), len(bary))
    open_ = ~_enclosed(ctx, points, ctx.patch_normal[p])
    if open_.any() and not open_.all():
        points, weights = points[open_], weights[open_] / weights[open_].sum()
    return points, weights


def occluder_distance(ctx: ShootContext, p: int, reach: float = np.inf) -> float:
    """Distance from patch ``p``'s centroid to its nearest possible occluder, less that
    element's radius; ``inf`` when nothing can occlude it within ``reach``
    (:func:`daskrad.kernels.blockers.nearest_blocker`)."""
    return nearest_blocker(ctx.vertices[real_corners(ctx.patch_verts[p])], ctx.patch_centroid[p],
                           ctx.patch_normal[p], ctx.patch_polygon[p], ctx.vertices,
                           ctx.elem_verts, ctx.elem_centroid, ctx.elem_normal, ctx.elem_radius,
                           ctx.elem_polygon, ctx.polygon_sides, ctx.eps, GRAZING,
                           max(ctx.eps, 2.0 * ctx.gap), float(reach))


def _probes() -> np.ndarray:
    """``(13, 3)`` directions probed by :func:`_enclosed`, in the shooter's frame: the normal,
    4 at 60° from it and 8 at 85° (so that a point under an overhang open at the sides sees
    out)."""
    out = [[0.0, 0.0, 1.0]]
    for polar, n in ((60.0, 4), (85.0, 8)):
        t = np.radians(polar)
        for k in range(n):
            a = 2.0 * np.pi * k / n
            out.append([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)])
    return np.array(out)


_PROBES = _probes()


def _enclosed(ctx: ShootContext, points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """``(k,) bool``: points of a shooter inside a closed object, where every probe ray first
    meets the back of a one-sided face (the floor under a block standing on it).

    Light arrives at a point from a direction only if the first face that way faces the point:
    a face seen from behind is a front face for the light coming towards the point, and stops
    it. So no light, hence none of the patch's energy, is at such a point; yet shot from there
    it would go out through the block (one-sided faces seen from behind do not occlude: a
    flipped face is a hole). Measured on the Cornell box: the blocks' faces by the floor 14 %
    too dark, the floor patches partly under a block shooting past them. A two-sided face (two
    coincident faces, :func:`two_sided_polygons`) always faces the point.
    """
    grid, tri_elem = ctx.grid, ctx.tri_element
    if grid is None:        # a context made by hand, without the mesh's grid
        grid, tri_elem = formfactor.element_grid(ctx.vertices, ctx.elem_verts)
    lift = tolerances.RAY_OFFSET * (ctx.diagonal or scene_diagonal(ctx.vertices))
    return enclosed_points(grid, np.asarray(tri_elem, np.int32), ctx.elem_normal,
                           ctx.polygon_two_sided, ctx.elem_polygon,
                           np.ascontiguousarray(points, dtype=np.float64),
                           np.ascontiguousarray(normal, dtype=np.float64), float(lift), _PROBES)


def two_sided_polygons(h: Hierarchy, eps: float, gap: float = 0.0) -> np.ndarray:
    """``(Q,) bool``: the two sides of a two-sided face: polygons with a twin facing the other
    way ``gap`` behind them (:func:`daskrad.mesh.one_sided`; 0: coincident twins): the same
    element bounding box, moved half the gap back, and area to ``eps``, opposite normals.
    Neither counts as a back: each is the front its side sees."""
    q = len(h.polygon_material)
    corners = h.vertices[np.where(h.elem_verts < 0, h.elem_verts[:, :1], h.elem_verts)]
    corners = corners - 0.5 * gap * h.elem_normal[:, None, :]     # both sides: the mid-plane
    lo = np.full((q, 3), np.inf)
    hi = np.full((q, 3), -np.inf)
    np.minimum.at(lo, h.elem_polygon, corners.min(axis=1))
    np.maximum.at(hi, h.elem_polygon, corners.max(axis=1))
    area = np.bincount(h.elem_polygon, h.elem_area, minlength=q)
    normal = np.zeros((q, 3))
    normal[h.patch_polygon] = h.patch_normal
    used = np.isfinite(lo[:, 0])
    key = np.round(np.column_stack([lo, hi, np.sqrt(area)[:, None]]) / eps).astype(np.int64)
    out = np.zeros(q, bool)
    groups: dict = {}
    for g in np.flatnonzero(used):
        groups.setdefault(key[g].tobytes(), []).append(g)
    for members in groups.values():
        for i, a in enumerate(members):
            for b in members[i + 1:]:
                if normal[a] @ normal[b] < 0.0:
                    out[a] = out[b] = True
    return out


def _average(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``Σ_k w_k values[k]`` summed row by row in a fixed order (not BLAS, whose blocking may
    depend on the thread count: the bits must not depend on the worker)."""
    return (weights[:, None] * values).sum(axis=0)


def row_key(patch: int | np.ndarray, sampled: bool | np.ndarray, n_patches: int):
    """The name of a row: the patch id ``p`` for its penumbra-sampled row
    (:func:`shooter_points`), ``P + p`` for its one-point row. Executors and row caches keep
    rows by key, so the two rows of a patch never stand in for each other."""
    return np.where(sampled, patch, np.asarray(patch) + n_patches)


def key_patch(key: int, n_patches: int) -> tuple[int, bool]:
    """``(patch id, sampled)`` of a row key (:func:`row_key`)."""
    return (key, True) if key < n_patches else (key - n_patches, False)


def one_point(points: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The one point a low-power shot leaves from (:data:`daskrad.solve.SAMPLE_SHARE`): the
    weighted mean of :func:`shooter_points`, so the centroid, or the mean of the points not
    inside a closed object (a convex combination of points of a convex patch: on it)."""
    if len(points) == 1:
        return points, weights
    return _average(points, weights)[None], np.ones(1)


def shoot_row(ctx: ShootContext, p: int, sampled: bool = True) -> np.ndarray:
    """``(E,) float64``: the form factors ``F_pj`` from patch ``p`` to every element; from
    the one point of :func:`one_point` unless ``sampled``."""
    points, weights = shooter_points(ctx, p)
    if not sampled:
        points, weights = one_point(points, weights)
    normals = np.repeat(ctx.patch_normal[p][None], len(points), axis=0)
    planes = None if ctx.plane_normal is None else (ctx.plane_normal, ctx.plane_offset)
    rows = formfactor.shooter_rows(points, normals, ctx.vertices, ctx.elem_verts,
                                   method=ctx.method, resolution=ctx.resolution,
                                   grid=ctx.grid, planes=planes, **ctx.options)
    row = rows[0] if len(points) == 1 else _average(rows, weights)
    # near receivers: F_ij by reciprocity from F_ji, the exact factor from each to the whole
    # shooter polygon (Lambert, averaged over the receiver where it is close), times the
    # method's own visibility of it (its factor over the unoccluded one from the same points:
    # won/covered for the default hemisphere method, exactly, at one point), rescaled to the
    # share of the row they had (:func:`daskrad.kernels.nearfield.near_field`)
    near_field(row, points, np.ascontiguousarray(weights, dtype=np.float64), ctx.vertices,
               ctx.elem_verts, ctx.elem_centroid, ctx.elem_normal, ctx.elem_area,
               ctx.elem_polygon, ctx.patch_verts[p], ctx.patch_centroid[p],
               ctx.patch_normal[p], float(ctx.patch_radius[p]), float(ctx.patch_area[p]),
               int(ctx.patch_polygon[p]), NEAR_FIELD * float(ctx.patch_radius[p]), CLOSE,
               _STRATA)
    return row


def strata(s: int) -> np.ndarray:
    """``(s², 3) float64``: barycentric centroids of the ``s²`` congruent sub-triangles of a
    triangle cut ``s`` times along each edge (equal areas, so equal weights)."""
    i, j = np.meshgrid(np.arange(s), np.arange(s), indexing="ij")
    up, down = i + j <= s - 1, i + j <= s - 2
    a = np.concatenate([i[up] + 1 / 3, i[down] + 2 / 3]) / s
    b = np.concatenate([j[up] + 1 / 3, j[down] + 2 / 3]) / s
    return np.column_stack([1.0 - a - b, a, b])


#: The barycentric points of :data:`STRATA` (:func:`receiver_average`).
_STRATA = strata(STRATA)


def receiver_average(ctx: ShootContext, p: int, ids: np.ndarray) -> np.ndarray:
    """``(k,) float64``: ``F_ji`` from each receiver element ``ids`` to the whole patch ``p``
    (Lambert's contour integral, no occlusion), averaged over the receiver's area.

    ``F_ji = (1/A_j) ∫_{A_j} F(x → i) dx``; far from the shooter the centroid is enough, but
    for a receiver within ``CLOSE`` of its own sizes of the shooter (sharing an edge or a
    corner with it, or a small gap) ``F(x → i)`` varies over the receiver as fast as the
    distance does, so the integral is taken over ``STRATA²`` stratified points of each of the
    receiver's triangles (a quad is two), area-weighted
    (:func:`daskrad.kernels.nearfield.receiver_factors`, which :func:`shoot_row` runs).
    """
    return receiver_factors(ctx.vertices, ctx.elem_verts, ctx.elem_centroid, ctx.elem_normal,
                            ctx.elem_area, np.asarray(ids, dtype=np.int64), ctx.patch_verts[p],
                            ctx.patch_centroid[p], ctx.patch_normal[p],
                            float(ctx.patch_radius[p]), CLOSE, _STRATA)


#: Bytes of finished rows a process keeps for re-shots when nothing sizes it
#: (:class:`RowCache`; the pipeline sizes it with :func:`row_cache_bytes`).
ROW_CACHE_BYTES = 256 * 2**20
#: Share of a process's memory the row cache may take: the rest holds the geometry, the
#: context copies and a task's dense ``(S, E)`` buffers.
ROW_CACHE_SHARE = 0.25
#: Bytes a kept row costs per nonzero factor (an int32 element id and a float64 factor).
ROW_BYTES_PER_FACTOR = 12


def row_cache_bytes(ctx: ShootContext, memory: int) -> int:
    """The row cache's budget for ``ctx`` in a process with ``memory`` bytes: every row when
    they fit, else ``ROW_CACHE_SHARE`` of the memory. A row has at most ``E`` nonzeros and a
    patch has at most two rows (sampled and from one point: a patch keeps the one it is first
    given, :func:`daskrad.solve.row_keys`, but a row computed ahead may guess the other), so
    ``12 · 2P · E`` bytes bound them all (the Cornell box's 309 × 7,295: 54 MB). Rows beyond
    the budget are computed again when their patch shoots again (the same bits, more time)."""
    everything = ROW_BYTES_PER_FACTOR * 2 * len(ctx.patch_area) * len(ctx.elem_area)
    return int(max(0, min(everything, ROW_CACHE_SHARE * memory)))


class RowCache:
    """Finished form-factor rows of one geometry, kept for when their patch shoots again.

    A converging solve shoots each patch several times (the Cornell box: 1,320 shots from 251
    patches), and a row is a pure function of the context and the patch, so a kept row has the
    bits a recomputation would give: the cache changes the time, never the result. Rows are
    kept sparse, ``12 × nonzeros`` bytes, least recently used dropped beyond ``max_bytes``.
    Thread-safe (a worker may run form-factor tasks in several threads).
    """

    def __init__(self, max_bytes: int = ROW_CACHE_BYTES):
        self.max_bytes = max_bytes
        self.nbytes = 0
        self.hits = 0
        self.misses = 0
        self._rows: OrderedDict = OrderedDict()
        self._lock = threading.Lock()

    def get(self, p: int):
        with self._lock:
            row = self._rows.get(p)
            if row is None:
                self.misses += 1
            else:
                self.hits += 1
                self._rows.move_to_end(p)
            return row

    def usage(self) -> dict:
        """``{"row_cache_mib": kept, "row_cache_limit_mib": budget}`` (the run report's
        memory section)."""
        return {"row_cache_mib": self.nbytes / 2**20,
                "row_cache_limit_mib": self.max_bytes / 2**20}

    def has(self, p: int) -> bool:
        """Whether patch ``p``'s row is kept (no hit or miss counted)."""
        with self._lock:
            return p in self._rows

    def put(self, p: int, row: tuple[np.ndarray, np.ndarray]) -> None:
        size = row[0].nbytes + row[1].nbytes
        if size > self.max_bytes:
            return
        for a in row:
            a.flags.writeable = False       # shared with every later shot of this patch
        with self._lock:
            if p in self._rows:
                return
            self._rows[p] = row
            self.nbytes += size
            while self.nbytes > self.max_bytes:
                _, (ids, f) = self._rows.popitem(last=False)
                self.nbytes -= ids.nbytes + f.nbytes


def shoot_rows(ctx: ShootContext, patch_ids: np.ndarray, cache: RowCache | None = None
               ) -> list[tuple[np.ndarray, np.ndarray]]:
    """Form-factor rows of the shooters ``patch_ids``, in that order: row keys
    (:func:`row_key`; a patch id is its sampled row).

    Returns a list of ``(ids (k,) int32, factors (k,) float64)``: the elements with a nonzero
    form factor from the shooter and the factors ``F_ij``, ``Σ factors ≤ 1``. ``cache``: rows
    already computed for ``ctx`` (read-only arrays then).
    """
    rows = []
    for p in np.asarray(patch_ids):
        p = int(p)
        found = cache.get(p) if cache is not None else None
        if found is None:
            with formfactor.checked_geometry():          # make_context checked it
                row = shoot_row(ctx, *key_patch(p, len(ctx.patch_area)))
            ids = np.flatnonzero(row > 0).astype(np.int32)
            found = (ids, row[ids])
            if cache is not None:
                cache.put(p, found)
        rows.append(found)
    return rows
