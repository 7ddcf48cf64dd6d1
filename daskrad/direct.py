"""Step 2: direct light at element vertices (docs/design.md §1; issue 5, items 1 and 3).

Irradiance ``H`` from point lights, directional lights and area lights (the emitting patches)
is computed at every element vertex with shadow rays through the voxel grid
(:mod:`daskrad.kernels.direct`). An element's direct irradiance is the mean of its corners';
its reflected direct light ``ρ · H`` is the radiosity the two-pass start
(:func:`daskrad.solve.initial_solution` with ``reflected``) puts in ``B`` and in the patches'
unshot energy, so emitters are never shot again and shooting carries indirect light only.

The unit of work is :func:`vertex_light` over a vertex range (``H`` and each area light's
class at each vertex, which the per-pixel pass reads): a pure function of a
:class:`DirectContext` and ``(start, stop)``, deterministic per vertex (the area-light jitter is
seeded by the vertex id), so batches computed by any number of workers give the same bits. The
Dask layer runs it as ``direct-<generation>-<n>`` futures; in-process, :func:`compute` loops
over the same batches.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from daskrad import tolerances
from daskrad.errors import OptionError, SceneError
from daskrad.kernels.arealight import area_irradiance, patch_classes
from daskrad.kernels.direct import irradiance_points
from daskrad.kernels.faces import Faces, no_faces
from daskrad.kernels.grid import Grid
from daskrad.kernels.hidden import polygon_outlines
from daskrad.mesh import default_sizes
from daskrad.mesh.refine import MIN_SIZE_DIVISOR, TVertices, refine
from daskrad.mesh.types import Hierarchy
from daskrad.preprocess import Mesh
from daskrad.scene.corners import corner_count, repeat_third
from daskrad.scene.types import Scene
from daskrad.settings import Settings

#: Shadow rays per area light (one emitting patch) are ``AREA_SAMPLES²``, stratified and
#: jittered (the run's ``Settings.area_samples``). 4 × 4 keeps the visible fraction's error near
#: 1/16 in a penumbra and exact where the light is wholly visible or hidden, the only places a
#: vertex value must be exact; the per-pixel pass uses the same count per pixel sample.
AREA_SAMPLES = Settings.area_samples

#: Side ``R`` of the ``R × R`` raster over an area light's window on the hemisphere base
#: (the ``"hemisphere"`` area method, :mod:`daskrad.kernels.arealight`); set from
#: ``benchmarks/bench_arealight.py`` (see :data:`AREA_METHODS`).
AREA_RESOLUTION = 32

#: Largest ``vertices × area lights`` (bytes, one a class) for which the direct pass keeps
#: each light's class at each vertex (:class:`DirectLight`'s ``classes``, what lets the
#: per-pixel pass skip the shadow rays of lights an element's corners all see), judged on the
#: mesh before subdivision: a scene beyond it traces every light at every hit.
CLASSES_MAX = 2**26

#: The direct pass finds its occluders (shadow rays, the window method's candidates, the face
#: test) among the scene's polygons (``Mesh.occluders``, the grid the per-pixel pass's shadow
#: rays walk) instead of the elements that tile them. ``bench_arealight --scene``, 8,000
#: vertices: the face test and window 1.74× faster on the converted office (``graz.obj``),
#: 1.31× on the classroom, 1.23× on ``graz.mgf``, 1.02× on ``office3``; the irradiance moved
#: by a relative RMS of at most 2.5e-4, the 32² raster's own error (32² shadow rays give the
#: same value through either grid; at the 16 vertices that moved most, the elements' windows
#: are nearer to them on ``graz.obj``, the polygons' on ``graz.mgf``). ``False``: the
#: elements (the benchmark's reference arm).
POLYGON_OCCLUDERS = True

#: Vertices per ``direct-<generation>-<n>`` task at most: ~2,000 vertices × (lights + 16 rays
#: per emitting patch) is tens of milliseconds, well above Dask's ~2 ms per task.
BATCH_VERTICES = 2048
#: A range of vertices is cut into at least this many tasks of at least
#: :data:`MIN_BATCH_VERTICES` (:func:`batches`): a level of adaptive subdivision adds a few
#: hundred to a few thousand vertices, which in tasks of 2,048 ran on one core while the
#: other waited (the Cornell box's levels of 993 and 1,854 vertices: 0.17 s of its 0.18 s
#: pass on one core). 1 cuts at :data:`BATCH_VERTICES` alone, as before
#: (``benchmarks/bench_direct.py``'s reference arm).
BATCH_SPLIT = 8
MIN_BATCH_VERTICES = 256


@dataclass(frozen=True)
class LightArrays:
    """The light arrays shared by :class:`DirectContext` and :class:`Lights`.

    point_position, point_intensity : (L, 3) float64
    dir_direction, dir_irradiance : (D, 3) float64
        Unit travel directions; irradiance on a surface facing the light.
    emitter_corners : (M, 4, 3) float64
        Corners of the emitting patches (row 3 repeats row 2 for a triangle);
        ``emitter_count (M,) int64``, ``emitter_normal (M, 3)``, ``emitter_radiance (M, 3)``
        (``Ke``), ``emitter_area (M,)``.

    They are the first fields of both subclasses (dataclass fields of a base come first), so
    ``Lights(*ctx.light_args, ...)`` fills them positionally; the Dask layer ships both
    classes field by field, by name (:func:`daskrad.distributed.store.put_context`).
    """

    point_position: np.ndarray
    point_intensity: np.ndarray
    dir_direction: np.ndarray
    dir_irradiance: np.ndarray
    emitter_corners: np.ndarray
    emitter_count: np.ndarray
    emitter_normal: np.ndarray
    emitter_radiance: np.ndarray
    emitter_area: np.ndarray

    @property
    def light_args(self) -> tuple:
        """The light arrays in the order of :func:`daskrad.kernels.direct.irradiance_one`."""
        return (self.point_position, self.point_intensity, self.dir_direction,
                self.dir_irradiance, self.emitter_corners, self.emitter_count,
                self.emitter_normal, self.emitter_radiance, self.emitter_area)


@dataclass(frozen=True)
class DirectContext(LightArrays):
    """What a direct-light task reads.

    grid : Grid
        Voxel grid over the triangles that cast shadows (geometry never changes with
        refinement): the scene's polygons (:func:`daskrad.preprocess.occluders`,
        :data:`POLYGON_OCCLUDERS`) or the elements.
    faces : Faces
        The input polygons (convex planar faces) ``grid``'s triangles tile
        (:func:`daskrad.kernels.faces.face_hides`).
    points, normals : (V, 3) float64
        The vertices and the unit normal of each one's polygon.
    area_points : (V, 3) float64
        Where area lights are evaluated and every shadow ray starts (:func:`vertex_points`:
        the vertex moved :func:`vertex_nudge` into its polygon).
    offset : float
        Shadow-ray offset, ``RAY_OFFSET · diag`` (absolute length).
    point_position, ... emitter_area
        The lights (:class:`LightArrays`).
    samples : int
        Shadow rays per area light: ``samples²`` (area method ``"rays"``).
    area_method : str
        A key of :data:`AREA_METHODS`: how area lights are shadowed.
    area_resolution : int
        Window raster side of the ``"hemisphere"`` area method.
    generation : int
        The hierarchy generation the vertices belong to (names the Dask tasks).
    keep_classes : bool
        Whether :func:`vertex_light` returns the area lights' classes (``(n, M)``) or none
        (``(n, 0)``: a scene with too many vertices × lights to keep them, :data:`CLASSES_MAX`).
    lamps : Lamps or None
        The emitting polygons the window method evaluates instead of their patches
        (:func:`lamps_of`); ``None``: the patches themselves.
    """

    grid: Grid
    faces: Faces
    points: np.ndarray
    area_points: np.ndarray
    normals: np.ndarray
    offset: float
    samples: int = AREA_SAMPLES
    generation: int = 0
    area_method: str = Settings.area_method
    area_resolution: int = AREA_RESOLUTION
    keep_classes: bool = True
    lamps: Lamps | None = None


class Lamps(NamedTuple):
    """Area lights as whole emitting polygons, for the window method (:data:`MERGE_LAMPS`).

    corners : (P, 4, 3) float64
        Each lamp's outline, counter-clockwise about its normal (row 3 repeats row 2 for a
        triangle); ``count (P,) int64`` corners, ``normal (P, 3)``, ``radiance (P, 3)``.
    of : (M,) int64
        The lamp of each emitting patch (:class:`LightArrays`' ``emitter_*`` rows): the
        patches of a lamp tile its outline exactly.
    """

    corners: np.ndarray
    count: np.ndarray
    normal: np.ndarray
    radiance: np.ndarray
    of: np.ndarray


#: The window method evaluates an emitting polygon split into several patches as one light
#: (:func:`lamps_of`): one search of the pyramid to it and one raster instead of one per
#: patch. ``Lambert's F`` is additive and ``V`` is the visible part of the projected area,
#: so ``F V`` of the whole is the sum over its patches up to the raster's error, which grows
#: with the window's size (an ``R × R`` raster over the whole instead of one per patch).
#: ``benchmarks/bench_direct.py`` (step 2 alone, arms alternated, medians of 3): the Cornell
#: box 0.114 → 0.085 s, at element size 7 0.908 → 0.695 s, RenderPark's office converted
#: (``graz.obj``, 16 lamps of 32 patches) 20.08 → 15.21 s. ``bench_arealight``: the
#: Cornell box's penumbra vertices 2.2e-3 → 2.8e-3 relative RMS against the 1,024² window;
#: its image against the path tracer 0.03792 → 0.03790 off the light.
MERGE_LAMPS = True


@dataclass(frozen=True)
class Lights(LightArrays):
    """The lights alone, what the per-pixel pass (:mod:`daskrad.render`) evaluates at a point.

    The arrays of :class:`LightArrays` (``point_position``, ... ``emitter_area``), plus
    ``offset``, the absolute shadow-ray offset, and ``samples`` (``samples²`` stratified shadow
    rays per area light and point). No grid and no vertices: the render context has its own
    grid, and a tile task must not carry the mesh twice.
    """

    offset: float
    samples: int = AREA_SAMPLES

    @property
    def empty(self) -> bool:
        return not (len(self.point_position) or len(self.dir_direction)
                    or len(self.emitter_corners))


def without_emitters(ctx: DirectContext) -> DirectContext:
    """The direct-light context with no area light: point and directional lights only."""
    return replace(ctx, emitter_corners=np.zeros((0, 4, 3)),
                   emitter_count=np.zeros(0, np.int64), emitter_normal=np.zeros((0, 3)),
                   emitter_radiance=np.zeros((0, 3)), emitter_area=np.zeros(0), lamps=None)


def lights_of(ctx: DirectContext) -> Lights:
    """The :class:`Lights` of a direct-light context: its emitting patches, each a light of
    the per-pixel pass (the window method at the vertices saw them as lamps, whose classes
    map onto the patches)."""
    return Lights(*ctx.light_args, offset=float(ctx.offset), samples=int(ctx.samples))


def vertex_normals(h: Hierarchy) -> np.ndarray:
    """``(V, 3) float64``: the normal of each vertex's polygon (0 for an unused vertex)."""
    out = np.zeros((len(h.vertices), 3))
    ev = h.elem_verts
    used = ev >= 0
    owner = np.broadcast_to(np.arange(len(ev))[:, None], ev.shape)[used]
    out[ev[used]] = h.elem_normal[owner]
    return out


def vertex_points(h: Hierarchy, nudge: float) -> np.ndarray:
    """``(V, 3)``: each vertex moved ``nudge`` (a length) towards its polygon's centroid.

    Irradiance is discontinuous at a polygon's boundary: a vertex on the edge where the floor
    meets a wall sees that wall edge-on (form factor 0), while every point of the floor near
    the edge sees it fill half the hemisphere. A vertex value stands for the element around
    it, so it must be the limit from inside the polygon: the point is moved inside by a
    length far below anything that changes the light elsewhere (:func:`vertex_nudge`,
    ``VERTEX_NUDGE · diag``), yet 100 shadow-ray offsets, so that a surface through the vertex
    (the ceiling above a wall's top edge) blocks the rays that would cross it. The polygons
    are convex, so the centroid is inside and the move stays in the polygon.
    """
    ev = h.elem_verts
    used = ev >= 0
    owner = np.broadcast_to(np.arange(len(ev))[:, None], ev.shape)[used]
    poly = h.elem_polygon
    n_poly = len(h.polygon_material)
    w = h.elem_area
    tot = np.bincount(poly, weights=w, minlength=n_poly)
    cen = np.stack([np.bincount(poly, weights=w * h.elem_centroid[:, k], minlength=n_poly)
                    for k in range(3)], axis=1) / np.where(tot > 0, tot, 1.0)[:, None]
    target = np.zeros_like(h.vertices)
    target[ev[used]] = cen[poly[owner]]
    d = target - h.vertices
    length = np.linalg.norm(d, axis=1, keepdims=True)
    step = np.where(length > nudge, nudge / np.where(length > 0, length, 1.0), 0.0)
    return np.ascontiguousarray(h.vertices + step * d)


def scene_offset(h: Hierarchy) -> float:
    """The shadow-ray offset ``RAY_OFFSET · diag`` of the hierarchy's bounding box."""
    used = np.zeros(len(h.vertices), bool)      # a mask, not np.unique: no sort
    used[h.elem_verts[h.elem_verts >= 0]] = True
    v = h.vertices[used] if used.any() else np.zeros((1, 3))
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    return tolerances.RAY_OFFSET * (diag if diag > 0 else 1.0)


def vertex_nudge(h: Hierarchy) -> float:
    """How far a vertex is moved into its polygon, ``VERTEX_NUDGE · diag`` (100 ray offsets)."""
    return scene_offset(h) * (tolerances.VERTEX_NUDGE / tolerances.RAY_OFFSET)


def emitters(scene: Scene, h: Hierarchy) -> dict:
    """The emitting patches as area lights (arrays of :class:`DirectContext`), and with
    :data:`MERGE_LAMPS` their polygons as :class:`Lamps` (``lamps``; ``None`` where no
    polygon has more than one patch)."""
    Ke = scene.materials.emission[h.polygon_material[h.patch_polygon]]
    ids = np.flatnonzero((Ke > 0).any(axis=1))
    pv = h.patch_verts[ids]
    arrays = dict(
        emitter_corners=np.ascontiguousarray(h.vertices[repeat_third(pv)]),
        emitter_count=corner_count(pv),
        emitter_normal=np.ascontiguousarray(h.patch_normal[ids]),
        emitter_radiance=np.ascontiguousarray(Ke[ids], dtype=np.float64),
        emitter_area=np.ascontiguousarray(h.patch_area[ids]),
    )
    lamps = (lamps_of(arrays["emitter_corners"], arrays["emitter_count"],
                      arrays["emitter_normal"], arrays["emitter_radiance"],
                      arrays["emitter_area"], h.patch_polygon[ids]) if MERGE_LAMPS else None)
    return {**arrays, "lamps": lamps}


def lamps_of(corners: np.ndarray, count: np.ndarray, normal: np.ndarray,
             radiance: np.ndarray, area: np.ndarray, polygon: np.ndarray) -> Lamps | None:
    """The emitting patches ``corners (M, 4, 3)`` (``count``, ``normal``, ``radiance``,
    ``area``) of the polygons ``polygon (M,)`` (non-decreasing: patches are stored polygon
    by polygon) as :class:`Lamps`: each polygon's patches become one lamp, its outline the
    patches' convex hull (:func:`daskrad.kernels.hidden.polygon_outlines`), where that hull
    has 3 or 4 corners and the patches tile it (its area theirs, to ``1e-9``); otherwise,
    and for a polygon of one patch, each patch stays a lamp. ``None`` where no polygon
    merges (the patches themselves)."""
    m = len(polygon)
    if m == 0 or np.any(np.diff(polygon) < 0):
        return None
    pv = np.arange(4 * m, dtype=np.int64).reshape(m, 4)
    pv[count == 3, 3] = -1
    first = np.flatnonzero(np.r_[True, polygon[1:] != polygon[:-1]])
    start = np.r_[first, m].astype(np.int64)
    o_start, outline = polygon_outlines(np.ascontiguousarray(corners.reshape(-1, 3)), pv,
                                        np.ascontiguousarray(area, np.float64),
                                        np.ascontiguousarray(normal, np.float64),
                                        np.arange(m, dtype=np.int64), start)
    out_c, out_n, out_r, of = [], [], [], np.empty(m, np.int64)
    for q in range(len(first)):
        rows = np.arange(start[q], start[q + 1])
        k = o_start[q + 1] - o_start[q]
        if len(rows) > 1 and 3 <= k <= 4:
            # one material and one plane: the patches' radiance and normal are the polygon's
            of[rows] = len(out_c)
            out_c.append(outline[o_start[q]:o_start[q + 1]])
            out_n.append(normal[rows[0]])
            out_r.append(radiance[rows[0]])
            continue
        for r in rows:
            of[r] = len(out_c)
            out_c.append(corners[r, :count[r]])
            out_n.append(normal[r])
            out_r.append(radiance[r])
    if len(out_c) == m:
        return None
    n_c = np.array([len(c) for c in out_c], np.int64)
    full = np.array([np.concatenate([c, c[-1:].repeat(4 - len(c), axis=0)]) for c in out_c])
    return Lamps(np.ascontiguousarray(full, np.float64), n_c,
                 np.ascontiguousarray(out_n, np.float64),
                 np.ascontiguousarray(out_r, np.float64), of)


def has_lights(scene: Scene) -> bool:
    """Whether the scene has any light the direct pass handles (point, directional, area)."""
    return bool(len(scene.point_lights) or len(scene.directional_lights)
                or scene.emitting.any())


def make_context(scene: Scene, h: Hierarchy, grid: Grid, samples: int = AREA_SAMPLES,
                 method: str | None = None, resolution: int = AREA_RESOLUTION,
                 tri_element: np.ndarray | None = None,
                 faces: Faces | None = None) -> DirectContext:
    """The direct-light context of ``h`` (its vertices) lit by ``scene``'s lights, with the
    occluders of ``grid``.

    ``faces``: the convex faces ``grid``'s triangles tile (``Mesh.occluders.faces`` for
    ``Mesh.occluders.grid``). Or, for a grid over the elements, ``tri_element (T,)``: the
    element of each of its triangles (``Mesh.tri_element``), which names the polygon each
    lies in (:func:`polygon_faces`). Neither: no faces, every area light by the window method
    alone.

    ``method`` is a key of :data:`AREA_METHODS` (default: ``Settings.area_method``), with
    ``samples²`` shadow rays (``"rays"``) per area light (emitting patch) or an
    ``resolution²`` window raster (``"hemisphere"``) per lamp (emitting polygon,
    :func:`lamps_of`). An unknown name raises :class:`OptionError`.
    """
    method = check_area_method(Settings.area_method if method is None else method)
    if int(resolution) < 2:
        raise OptionError(f"area-light window resolution must be >= 2, got {resolution!r}")
    pl, dl = scene.point_lights, scene.directional_lights
    ddir = np.asarray(dl.direction, np.float64).reshape(-1, 3)
    norm = np.linalg.norm(ddir, axis=1, keepdims=True)
    ddir = ddir / np.where(norm > 0, norm, 1.0)
    if faces is None:
        faces = (no_faces(len(grid.triangles)) if tri_element is None
                 else polygon_faces(h, tri_element))
    return DirectContext(
        grid=grid,
        faces=faces,
        points=np.ascontiguousarray(h.vertices, dtype=np.float64),
        area_points=vertex_points(h, vertex_nudge(h)),
        normals=vertex_normals(h),
        offset=scene_offset(h),
        point_position=np.ascontiguousarray(pl.position, np.float64).reshape(-1, 3),
        point_intensity=np.ascontiguousarray(pl.intensity, np.float64).reshape(-1, 3),
        dir_direction=np.ascontiguousarray(ddir),
        dir_irradiance=np.ascontiguousarray(dl.irradiance, np.float64).reshape(-1, 3),
        samples=int(samples),
        generation=h.generation,
        area_method=method,
        area_resolution=int(resolution),
        **emitters(scene, h),
    )


def polygon_faces(h: Hierarchy, tri_element: np.ndarray) -> Faces:
    """The input polygons of ``h`` as the faces a light may hide behind whole.

    A polygon (a triangle or a planar convex quad) is the union of its patches, which are
    stored in polygon order; ``tri_element (T,)`` names the element, hence the polygon, of
    each triangle of the occluder grid.
    """
    if np.any(np.diff(h.patch_polygon) < 0):
        raise ValueError("patches must be in polygon order")
    start = np.searchsorted(h.patch_polygon, np.arange(len(h.polygon_material) + 1))
    pv = h.patch_verts
    corners = h.vertices[np.where(pv >= 0, pv, pv[:, :1])]
    return Faces(tri_face=h.patch_polygon[h.elem_patch[tri_element]].astype(np.int32),
                 start=start.astype(np.int64), corners=np.ascontiguousarray(corners),
                 count=np.where(pv[:, 3] >= 0, 4, 3).astype(np.int64))


def with_hierarchy(ctx: DirectContext, h: Hierarchy) -> DirectContext:
    """The same lights and grid over a refined hierarchy's vertices (new generation)."""
    return replace(ctx, points=np.ascontiguousarray(h.vertices, dtype=np.float64),
                   area_points=vertex_points(h, vertex_nudge(h)), normals=vertex_normals(h),
                   generation=h.generation)


def vertex_light(ctx: DirectContext, start: int, stop: int) -> tuple[np.ndarray, np.ndarray]:
    """Direct light at vertices ``start:stop``: ``H (stop − start, 3) float64``, the
    irradiance, and ``classes (stop − start, M) int8``, what is known of each area light
    there (:data:`daskrad.kernels.direct.LIGHT_VISIBLE`, ``LIGHT_HIDDEN`` or ``LIGHT_TRACE``;
    the per-pixel pass skips the shadow rays of a light every corner of an element agrees
    on, :func:`daskrad.render.light_modes`).

    The Dask task ``direct-<generation>-<n>``. A vertex's value depends on the context, its id
    (the jitter seed) and, by the window method's remembered faces, the vertices before it in
    the range (:mod:`daskrad.kernels.arealight`: only where the remembered face proves exactly
    what the raster would miss); callers use the fixed ranges of :func:`batches`, so the bits
    do not depend on the number of workers. Area lights are shadowed by
    ``AREA_METHODS[ctx.area_method]``.
    """
    H, classes = AREA_METHODS[ctx.area_method](ctx, start, stop)
    return H, (classes if ctx.keep_classes else np.zeros((len(H), 0), np.int8))


def direct_vertices(ctx: DirectContext, start: int, stop: int) -> np.ndarray:
    """``(stop − start, 3) float64``: the direct irradiance ``H`` of :func:`vertex_light`."""
    return vertex_light(ctx, start, stop)[0]


def _area_by_rays(ctx: DirectContext, start: int, stop: int):
    """Every light by shadow rays; area lights: Lambert × ``samples²`` stratified rays."""
    seeds = np.arange(start, stop, dtype=np.int64)
    return irradiance_points(ctx.grid, ctx.points[start:stop], ctx.area_points[start:stop],
                             ctx.normals[start:stop], seeds,
                             ctx.offset, *ctx.light_args, ctx.samples)


def _area_by_hemisphere(ctx: DirectContext, start: int, stop: int):
    """Point and directional lights by shadow rays; area lights by the paper's window on the
    hemisphere base (:mod:`daskrad.kernels.arealight`): Lambert × visible pixel fraction."""
    seeds = np.arange(start, stop, dtype=np.int64)
    none3 = np.zeros((0, 3))
    H, _ = irradiance_points(ctx.grid, ctx.points[start:stop], ctx.area_points[start:stop],
                             ctx.normals[start:stop], seeds, ctx.offset, ctx.point_position,
                             ctx.point_intensity, ctx.dir_direction, ctx.dir_irradiance,
                             np.zeros((0, 4, 3)), np.zeros(0, np.int64), none3, none3,
                             np.zeros(0), ctx.samples)
    classes = np.zeros((stop - start, len(ctx.emitter_corners)), np.int8)
    if len(ctx.emitter_corners):
        # The clip height of the hemisphere-base form factor, HORIZON_EPS · diag (the offset
        # is RAY_OFFSET · diag of the same box).
        hz = ctx.offset * (tolerances.HORIZON_EPS / tolerances.RAY_OFFSET)
        lamps = ctx.lamps or Lamps(ctx.emitter_corners, ctx.emitter_count, ctx.emitter_normal,
                                   ctx.emitter_radiance, None)
        H_area, classes = area_irradiance(
            ctx.grid, ctx.faces, ctx.area_points[start:stop], ctx.normals[start:stop],
            float(ctx.offset), float(hz), lamps.corners, lamps.count, lamps.normal,
            lamps.radiance, int(ctx.area_resolution), math.radians(tolerances.EDGE_ANGLE_DEG))
        H += H_area
        if lamps.of is not None and ctx.keep_classes:  # a lamp settled: so are its patches
            classes = patch_classes(ctx.area_points[start:stop], ctx.normals[start:stop],
                                    classes, lamps.of, ctx.emitter_corners, ctx.emitter_count,
                                    ctx.emitter_normal)
    return H, classes


#: How area lights are shadowed at vertices, by name (``--area-method``,
#: ``Settings.area_method``).
#: Each entry maps ``(ctx, start, stop)`` to the direct irradiance ``(stop − start, 3)`` of every
#: light at those vertices and the area lights' classes there (:func:`vertex_light`); point and
#: directional lights are shadow rays in both.
#:
#: - ``"rays"``: Lambert's unoccluded term × the visible fraction from ``samples²`` stratified,
#:   jittered shadow rays weighted by ``cos θ cos θ' / r²``.
#: - ``"hemisphere"`` (the paper's method): Lambert's term × the fraction of the light's pixels
#:   left visible in an ``R × R`` z-buffer over the light's min–max window on the hemisphere
#:   base, with the occluders the voxel grid finds inside the pyramid from the vertex to the
#:   light.
#:
#: Both are exact where the light is wholly visible or wholly hidden.
#:
#: **Default: ``"hemisphere"`` with a 32 × 32 window**, from ``benchmarks/bench_arealight.py``
#: (Cornell box, errors over the penumbra vertices against the window method at 1024², which
#: the 32 × 32-ray reference confirms to 1.6e-3, its own sampling noise). On the default mesh
#: (3,426 vertices) the window at 32² takes the time of the former default, 4 × 4 rays
#: (0.061 s vs 0.058 s), with 16 times less error (relative RMS 2.4e-3 vs 3.9e-2); rays need
#: more than 16 × 16 (0.81 s, 14 times longer) for that error. The window's error falls about
#: as R^-1.2 at a cost that grows slowly (the candidate search through the grid, not the
#: raster, dominates; 3/4 of the vertices have no candidate and are not rasterized at all),
#: the stratified rays' about as s^-1.4 at a cost ∝ s². On a 4 × finer mesh (12,553 vertices, more
#: triangles per grid cell) the window at 32² costs 1.6 × the 4 × 4 rays (0.43 s vs 0.26 s),
#: still at 1/16 of their error and at a twentieth of the time of rays of equal error. 32² is
#: where the window's time starts to rise above its search cost (64²: +40 % time for 2.5 ×
#: less error). Its errors are deterministic (aliasing along shadow edges, no noise), so
#: adaptive subdivision is not triggered by sampling noise.
AREA_METHODS = {"rays": _area_by_rays, "hemisphere": _area_by_hemisphere}


def _vertex_pass(scene: Scene, h: Hierarchy, ctx: DirectContext, settings: Settings,
                 executor) -> tuple:
    """Direct light at the vertices of ``h``, then adaptive subdivision, level by level:
    ``(hierarchy, H, classes, tvertices, levels)`` (:func:`light`)."""
    H, classes = compute_classes(ctx, 0, len(h.vertices), executor)
    new_classes = [classes]     # refine keeps H; the classes of new vertices follow in order
    diffuse = scene.materials.diffuse

    def evaluate(h2: Hierarchy, start: int, stop: int) -> np.ndarray:
        """H at the new vertices ``start:stop`` of a refined hierarchy."""
        H2, c2 = compute_classes(with_hierarchy(ctx, h2), start, stop, executor)
        new_classes.append(c2)
        return H2

    element_size = settings.element_size or default_sizes(scene)[1]
    h, H, tv, levels = refine(
        h, H, evaluate, scale=lambda h2: vertex_reflectance(h2, diffuse[h2.elem_material]),
        threshold=settings.subdivide,
        min_size=settings.min_element_size or element_size / MIN_SIZE_DIVISOR)
    return h, H, np.concatenate(new_classes), tv, levels


def _restored(state: DirectState, h: Hierarchy, ctx: DirectContext) -> tuple | None:
    """:func:`_vertex_pass`'s result from ``state`` if it fits the hierarchy ``h`` before
    subdivision (subdivision only appends vertices) and the lights of ``ctx``, else None."""
    r = state.hierarchy
    n = len(r.vertices)
    m = len(ctx.emitter_corners) if ctx.keep_classes else 0
    # subdivision appends vertices and T-vertices, and none without a level
    grown = n > len(h.vertices) if state.levels > 0 else (
        n == len(h.vertices) and len(state.tvertices.vertex) == 0)
    if not (state.version == STATE_VERSION and state.levels >= 0 and grown
            and np.array_equal(r.vertices[:len(h.vertices)], h.vertices)
            and state.irradiance.shape == (n, 3) and state.classes.shape == (n, m)):
        return None
    # no subdivision: the mesh's own hierarchy (the same arrays), so the mesh is kept whole
    kept = h if state.levels == 0 else r
    return kept, state.irradiance, state.classes, state.tvertices, int(state.levels)


def check_area_method(name: str) -> str:
    """``name`` if it is a key of :data:`AREA_METHODS`, else :class:`OptionError`."""
    if name not in AREA_METHODS:
        raise OptionError(f"unknown area-light method {name!r} "
                          f"(choose from {', '.join(sorted(AREA_METHODS))})")
    return name


def batches(start: int, stop: int, size: int | None = None) -> list[tuple[int, int]]:
    """The vertex ranges ``[(a, b), ...]`` covering ``start:stop`` in order, of ``size``
    vertices (the last one shorter). By default :data:`BATCH_VERTICES`, or fewer so that
    the range makes :data:`BATCH_SPLIT` tasks (at least :data:`MIN_BATCH_VERTICES` each): a
    function of ``start`` and ``stop`` alone, never of the executor, since a vertex's value
    can depend on the one before it in its range (the face test's hint: where it proves a
    light hidden that the raster let a pixel through, one vertex of graz's 293,004), so the
    bits are the same on any number of workers."""
    if size is None:
        size = min(BATCH_VERTICES,
                   max(MIN_BATCH_VERTICES, math.ceil((stop - start) / BATCH_SPLIT)))
    return [(a, min(a + size, stop)) for a in range(start, stop, size)]


def compute(ctx: DirectContext, start: int, stop: int, executor=None) -> np.ndarray:
    """Direct irradiance at vertices ``start:stop`` (:func:`compute_classes`'s ``H``)."""
    return compute_classes(ctx, start, stop, executor)[0]


def compute_classes(ctx: DirectContext, start: int, stop: int, executor=None
                    ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`vertex_light` at vertices ``start:stop``, batch by batch: ``H (n, 3)`` and the
    area lights' ``classes (n, M) int8``.

    When ``executor`` has a ``direct(ctx, ranges)`` method (the Dask executor, or threads),
    the batches run there; otherwise in this process. The result is the same bits either way.
    """
    ranges = batches(start, stop)
    run = getattr(executor, "direct", None)
    if run is not None:
        parts = run(ctx, ranges)
    else:
        parts = [vertex_light(ctx, a, b) for a, b in ranges]
    if not parts:
        m = len(ctx.emitter_corners) if ctx.keep_classes else 0
        return np.zeros((0, 3)), np.zeros((0, m), np.int8)
    return (np.concatenate([H for H, _ in parts]),
            np.concatenate([c for _, c in parts]))


def element_mean(h: Hierarchy, vertex_values: np.ndarray) -> np.ndarray:
    """``(E, k)``: the mean of each element's corner values (3 or 4 corners)."""
    ev = h.elem_verts
    quad = ev[:, 3] >= 0
    s = vertex_values[ev[:, 0]] + vertex_values[ev[:, 1]] + vertex_values[ev[:, 2]]
    s = s + np.where(quad[:, None], vertex_values[np.where(quad, ev[:, 3], 0)], 0.0)
    return s / np.where(quad, 4.0, 3.0)[:, None]


def vertex_reflectance(h: Hierarchy, reflectance: np.ndarray) -> np.ndarray:
    """``(V, 3)``: the reflectance of each vertex's polygon (elements of one polygon share it)."""
    return corner_values(h.elem_verts, len(h.vertices), reflectance)


def corner_values(elem_verts: np.ndarray, n_vertices: int, values: np.ndarray) -> np.ndarray:
    """``(n_vertices, k)``: each vertex takes ``values (E, k)`` of an element it is a corner
    of (the last in element order; 0 for a vertex of none). Meant for values an element shares
    with its neighbours at the vertex (a polygon's reflectance)."""
    out = np.zeros((n_vertices, values.shape[1]))
    used = elem_verts >= 0
    owner = np.broadcast_to(np.arange(len(elem_verts))[:, None], elem_verts.shape)[used]
    out[elem_verts[used]] = values[owner]
    return out


def total_power(scene: Scene) -> np.ndarray:
    """``(3,)``: power leaving the lights (``4π I`` per point light; ``π Ke A`` per emitter).

    Directional lights carry no finite power and are left out.
    """
    from daskrad.mesh import polygon_areas

    p = 4.0 * math.pi * np.asarray(scene.point_lights.intensity).reshape(-1, 3).sum(axis=0)
    Ke = scene.materials.emission[scene.polygon_material]
    return p + math.pi * (Ke * polygon_areas(scene)[:, None]).sum(axis=0)


@dataclass(frozen=True)
class DirectLight:
    """Step 2's result: direct light at every vertex of the refined mesh.

    Attributes
    ----------
    mesh : Mesh
        The mesh after adaptive subdivision (a later generation than step 1's when it split).
    irradiance : (V, 3) float64 or None
        Direct irradiance ``H`` (W/m²) at every vertex from the lights gathered here; ``None``
        when the scene has none (no point or directional light, and area lights are shot).
    reflected : (E, 3) float64
        ``ρ · H`` averaged over each element's corners: the first bounce of direct light.
    tvertices : TVertices
        Vertices refinement left in the middle of a neighbour's edge (interpolated from it).
    context : DirectContext or None
        The lights and shadow-ray settings the vertices saw; the per-pixel pass evaluates the
        same lights.
    levels : int
        Subdivision levels applied.
    emitters_shot : bool
        Whether area lights are left to the solve as patches with unshot energy (one-pass)
        instead of gathered here (two-pass, ``Settings.two_pass``).
    seconds : float
    classes : (V, M) int8 or None
        What the vertex pass found of each area light (``context``'s emitters) at every
        vertex: wholly visible, wholly hidden, or neither (:func:`vertex_light`); ``(V, 0)``
        beyond :data:`CLASSES_MAX`.
    """

    mesh: Mesh
    irradiance: np.ndarray | None
    reflected: np.ndarray
    tvertices: TVertices
    context: DirectContext | None
    levels: int
    emitters_shot: bool
    seconds: float = 0.0
    classes: np.ndarray | None = None


class DirectState(NamedTuple):
    """What step 2 computed, as a resumed run reads it back from the store instead of
    computing it again (:func:`light`'s ``state``; the store keeps it as the task context
    ``internal/context/direct_state``). The rest of a :class:`DirectLight` follows from it, the
    scene and the settings, which a resume has checked against the store.

    hierarchy : Hierarchy
        After adaptive subdivision.
    irradiance : (V, 3) float64
    classes : (V, M) int8
        :attr:`DirectLight.classes` (``(V, 0)`` beyond :data:`CLASSES_MAX`).
    tvertices : TVertices
    levels : int
    version : int
        :data:`STATE_VERSION` of the daskrad that computed it.
    """

    hierarchy: Hierarchy
    irradiance: np.ndarray
    classes: np.ndarray
    tvertices: TVertices
    levels: int
    version: int = 0


#: The version of step 2's answer: a change of the direct pass or of the subdivision that
#: changes any bit of a :class:`DirectState` must increase it, so that a resume computes step 2
#: again instead of taking an older daskrad's (the store's checks cover the inputs and the
#: settings, not the code; nor :data:`MERGE_LAMPS`, a module switch for benchmarks). 2: one
#: lamp per emitting polygon in the window method (the thirty-third stop).
STATE_VERSION = 2


def state_of(light: DirectLight) -> DirectState | None:
    """``light``'s :class:`DirectState`; None when step 2 gathered nothing (nothing to skip)."""
    if light.irradiance is None:
        return None
    return DirectState(light.mesh.hierarchy, light.irradiance, light.classes,
                       light.tvertices, int(light.levels), STATE_VERSION)


def light(scene: Scene, mesh: Mesh, settings: Settings, executor=None,
          state: DirectState | None = None) -> DirectLight:
    """Step 2: direct light at vertices, then adaptive subdivision (issue 5).

    With ``settings.two_pass`` area lights are gathered at the vertices and never shot;
    otherwise they are shot like any patch and only point and directional lights are gathered.
    Elements whose corners' reflected light ``ρH`` spreads by more than ``settings.subdivide``
    are split (down to ``min_element_size``) and the new vertices computed, level by level.
    ``executor`` runs the vertex batches (Dask futures ``direct-…``), else this process.

    ``state``: what an earlier run of the same scene and settings computed
    (:func:`state_of`, read back from its store by a resume), taken instead of the vertex
    pass and the subdivision: the same :class:`DirectLight`, bit for bit (graz: ~30 s of a
    resume saved). A state that does not fit ``mesh`` (the same vertices before subdivision)
    and the lights is not taken: the vertex pass runs.
    """
    t = time.perf_counter()
    h = mesh.hierarchy
    power = mesh.emission * h.elem_area[:, None]
    if not np.isfinite(power).all():
        raise SceneError("emitted power (π Ke × area) overflows a float64; scale the "
                         "emission or the scene's units down", scene.path)
    gathered = bool(len(scene.point_lights) or len(scene.directional_lights)
                    or (settings.two_pass and scene.emitting.any()))
    if not gathered:
        return DirectLight(mesh=mesh, irradiance=None, reflected=np.zeros_like(mesh.emission),
                           tvertices=TVertices.empty(), context=None, levels=0,
                           emitters_shot=True)
    if POLYGON_OCCLUDERS:
        ctx = make_context(scene, h, mesh.occluders.grid, settings.area_samples,
                           method=settings.area_method, faces=mesh.occluders.faces)
    else:
        ctx = make_context(scene, h, mesh.grid, settings.area_samples,
                           method=settings.area_method, tri_element=mesh.tri_element)
    if not settings.two_pass:  # emitters are shot: gather point and directional lights only
        ctx = without_emitters(ctx)
    if len(h.vertices) * len(ctx.emitter_corners) > CLASSES_MAX:
        ctx = replace(ctx, keep_classes=False)
    restored = _restored(state, h, ctx) if state is not None else None
    h, H, classes, tv, levels = restored or _vertex_pass(scene, h, ctx, settings, executor)
    if levels:
        ctx = with_hierarchy(ctx, h)
    if not np.isfinite(H).all():
        raise SceneError("direct irradiance overflows a float64 (a light's intensity or "
                         "irradiance is too large for the scene's units)", scene.path)
    if len(classes) != len(H):
        raise AssertionError("the area lights' classes lost step with the refined vertices")
    mesh = mesh.remeshed(scene, h)
    return DirectLight(mesh=mesh, irradiance=H,
                       reflected=mesh.reflectance * element_mean(h, H), tvertices=tv,
                       context=ctx, levels=levels, emitters_shot=not settings.two_pass,
                       seconds=time.perf_counter() - t, classes=classes)
