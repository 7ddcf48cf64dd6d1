"""Form factors from differential shooting areas to receiving elements (docs/design.md §2).

Every method has one signature, so the solver and the Dask tasks pick one by name::

    fn(points, normals, vertices, elem_verts, resolution, **options) -> (S, E) float64

``points : (S, 3) float64`` and ``normals : (S, 3) float64`` are the shooters' sample points and
normals (normalized here), ``vertices : (V, 3) float64`` and ``elem_verts : (E, 4) int32``
(``-1`` in column 3 for a triangle) the receiving elements. Row ``s`` holds ``F[s, j]``, the form
factor from the differential area ``s`` to element ``j``. Receivers are one-sided: an element
whose lit side does not face the point gets 0.

Methods (:data:`METHODS`):

``"hemisphere"`` (the default)
    Anti-aliased hemisphere base: Doi's item buffer decides visibility, Lambert's formula the
    size, ``F_j = L_j · won_j / covered_j`` (:func:`hemisphere_rows`). Unoccluded elements of
    any size get their exact form factor; rows sum to at most 1, to exactly 1 in a closed
    scene. Options: ``edge_angle`` (degrees, eq. 4; default ``None`` = automatic from the
    resolution, :func:`auto_edge_angle`: the outline within a quarter pixel; ``1.0`` is the
    paper's) and ``depth`` (``"exact"``, default, or ``"plane"`` for the paper's eq. 5).
``"hemisphere-itembuffer"``
    The paper's item buffer as it is, ``F = won / n_disc`` (eqs. 6–7): every disc pixel
    weighs ``1/n_disc``; small or distant elements alias (:mod:`daskrad.kernels.hemisphere`).
``"hemisphere-scanline"``
    Exact span lengths on ``resolution`` scanlines, visibility per span (eq. 8,
    :mod:`daskrad.kernels.scanline`); option ``both_axes`` adds vertical scanlines. Its
    automatic ``edge_angle`` is the paper's 1°: its spans are exact in ``x``, so it keeps the
    fine outline (its error bound carries the sagitta ``δ²/8``).
``"hemicube"``
    Cohen & Greenberg's hemicube with normalised delta form factors
    (:mod:`daskrad.kernels.hemicube`), on the same rasterizer.
``"raycast"``
    Wallace et al.'s receiver-vertex method: Lambert × visibility of the element's sample
    points by shadow rays through the voxel grid (:mod:`daskrad.kernels.raycast`); option
    ``samples``; ``resolution`` is ignored.
``"analytic"``
    Lambert's contour formula, **no occlusion** (:mod:`daskrad.kernels.lambert`); the
    ground truth for unoccluded configurations. ``resolution`` is ignored.

Rows are returned dense: a float64 row of 50,000 elements is 400 kB, cheap next to the
rasterization. :func:`to_sparse` turns rows into the sparse form the Dask tasks ship
(docs/design.md §4: element ids and factors).
"""

from __future__ import annotations

import math
from contextlib import contextmanager
from contextvars import ContextVar

import numpy as np

from daskrad import tolerances
from daskrad.errors import OptionError, SceneError
from daskrad.kernels.geometry import element_planes, scene_diagonal
from daskrad.kernels.grid import build_grid
from daskrad.kernels.hemicube import hemicube_shots
from daskrad.kernels.hemisphere import (
    anti_aliased_rows,
    conserve_rows,
    hemisphere_shots,
    hemisphere_visibility,
)
from daskrad.kernels.lambert import lambert_masked, lambert_shots
from daskrad.kernels.raycast import raycast_visibility
from daskrad.kernels.scanline import scanline_shots
from daskrad.scene.corners import split_quads
from daskrad.settings import Settings

_DEPTHS = ("exact", "plane")

#: The item-buffer side ``R`` when none is given: the run's default (:class:`Settings`).
DEFAULT_RESOLUTION = Settings.resolution


#: Set (:func:`checked_geometry`) while the caller vouches for the geometry arrays it passes.
_CHECKED: ContextVar[bool] = ContextVar("daskrad_geometry_checked", default=False)


@contextmanager
def checked_geometry():
    """Within this block (this thread only), the methods take ``vertices`` and ``elem_verts``
    as valid (:func:`check_geometry` passed on them once): the solver's form-factor task calls
    them ~4 times a row with the whole mesh, and checking a 70,000-element mesh each time
    cost ~1 ms of a 5 ms row (RenderPark's classroom). Shooters are still checked."""
    token = _CHECKED.set(True)
    try:
        yield
    finally:
        _CHECKED.reset(token)


def check_geometry(vertices, elem_verts):
    """``(vertices (V, 3) float64, elem_verts (E, 4) int32)``, contiguous, after checking
    shapes, corner indices and finiteness (:class:`SceneError` naming the problem)."""
    vertices = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64))
    elem_verts = np.ascontiguousarray(np.asarray(elem_verts, dtype=np.int32))
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise SceneError(f"vertices must be a (V, 3) array, got {vertices.shape}")
    if elem_verts.ndim != 2 or elem_verts.shape[1] != 4:
        raise SceneError(f"elem_verts must be an (E, 4) array, got {elem_verts.shape}")
    if len(elem_verts) and (
        elem_verts[:, :3].min() < 0 or elem_verts.max() >= len(vertices)
        or elem_verts[:, 3].min() < -1
    ):
        raise SceneError("elem_verts holds a corner index outside the vertex array")
    if not np.isfinite(vertices).all():
        raise SceneError("points, normals and vertices must be finite (NaN or inf found)")
    return vertices, elem_verts


def _prepare(points, normals, vertices, elem_verts):
    """Validate and convert the inputs to contiguous float64 / int32 arrays (the geometry only
    converted within :func:`checked_geometry`)."""
    points = np.ascontiguousarray(np.atleast_2d(np.asarray(points, dtype=np.float64)))
    normals = np.ascontiguousarray(np.atleast_2d(np.asarray(normals, dtype=np.float64)))
    if points.ndim != 2 or points.shape[1] != 3 or normals.shape != points.shape:
        raise SceneError(
            f"points and normals must both be (S, 3) arrays, got {points.shape} and "
            f"{normals.shape}"
        )
    if _CHECKED.get():
        vertices = np.ascontiguousarray(vertices, dtype=np.float64)
        elem_verts = np.ascontiguousarray(elem_verts, dtype=np.int32)
    else:
        vertices, elem_verts = check_geometry(vertices, elem_verts)
    if not (np.isfinite(points).all() and np.isfinite(normals).all()):
        raise SceneError("points, normals and vertices must be finite (NaN or inf found)")
    length = np.linalg.norm(normals, axis=1)
    if len(length) and length.min() == 0.0:
        raise SceneError("a shooter normal has zero length")
    normals = np.ascontiguousarray(normals / length[:, None])
    return points, normals, vertices, elem_verts


def _check_resolution(resolution) -> int:
    if isinstance(resolution, bool) or int(resolution) != resolution or resolution < 2:
        raise OptionError(f"resolution must be an integer >= 2, got {resolution!r}")
    return int(resolution)


def edge_split_angle(resolution, sagitta_px: float = tolerances.EDGE_SAGITTA_PX) -> float:
    """The angle, **radians**, each projected edge piece of an ``R × R`` item buffer over the
    base disc may subtend for its outline to lie within ``sagitta_px`` of a pixel of the arc:
    ``θ = sqrt(16 s / R)`` (:func:`auto_edge_angle`)."""
    return math.sqrt(16.0 * sagitta_px / resolution)


def auto_edge_angle(resolution) -> float:
    """The automatic edge-split threshold of the item-buffer methods, **degrees** (eq. 4).

    A polyline piece subtending ``θ`` on the unit hemisphere lies at most ``1 - cos(θ/2) <=
    θ²/8`` inside the great-circle arc it replaces, and the orthographic projection onto the
    base disc only shortens distances, so on the disc the outline errs by at most ``θ²/8``. A
    pixel of the ``R × R`` buffer over ``[-1, 1]²`` is ``2/R`` wide; asking for at most
    :data:`daskrad.tolerances.EDGE_SAGITTA_PX` of a pixel gives ``θ = sqrt(16 s / R)``, with
    ``s = 1/4``: ``θ = 2/sqrt(R)`` rad, 11.5° at ``R = 100``, 7.2° at ``R = 256`` (capped at
    90°). The paper's fixed 1° (``edge_angle=1.0``) moves the outline by at most 0.005 pixel at
    ``R = 256``, far below the ±1/2 pixel of the raster's own sampling, at up to 7× the points.
    """
    return min(math.degrees(edge_split_angle(resolution)), 90.0)


def _raster_args(resolution, edge_angle=None, depth="exact", auto=True, grid=None,
                 planes=None):
    """Validated ``(R, edge angle in radians, plane_depth)`` of the hemisphere methods.

    ``edge_angle`` ``None`` or ``"auto"``: :func:`auto_edge_angle` when ``auto``, else the
    paper's :data:`daskrad.tolerances.EDGE_ANGLE_DEG` (the scanline method, whose spans are
    exact in ``x``, keeps the fine outline).
    """
    resolution = _check_resolution(resolution)
    if depth not in _DEPTHS:
        raise OptionError(f"depth must be one of {', '.join(_DEPTHS)}, got {depth!r}")
    if edge_angle is None or edge_angle == "auto":
        edge_angle = auto_edge_angle(resolution) if auto else tolerances.EDGE_ANGLE_DEG
    try:
        angle = float(edge_angle)
    except (TypeError, ValueError):
        angle = math.nan
    if not (0.0 < angle <= 90.0):
        raise OptionError(
            f"edge_angle must be in (0, 90] degrees or 'auto', got {edge_angle!r}")
    return resolution, math.radians(angle), depth == "plane"


def hemisphere_counts(points, normals, vertices, elem_verts, resolution=DEFAULT_RESOLUTION,
                      edge_angle=None, depth="exact"):
    """Raw pixel counts of the hemisphere-base item buffer.

    Returns
    -------
    won : (S, E) int32
        Disc pixels each element owns after hidden-surface removal.
    covered : (S, E) int32
        Disc pixels each element's projection covers before the depth test; the
        anti-aliased default uses ``analytic × won / covered``.
    n_disc : int
        Pixel centres inside the unit circle: ``F = won / n_disc``.
    """
    r, angle, plane = _raster_args(resolution, edge_angle, depth)
    points, normals, vertices, elem_verts = _prepare(points, normals, vertices, elem_verts)
    won, covered, n_disc = hemisphere_shots(points, normals, vertices, elem_verts, r, angle,
                                            plane, tolerances.HORIZON_EPS)
    return won, covered, int(n_disc)


def _conserve(rows, closed=None):
    """:func:`daskrad.kernels.hemisphere.conserve_rows` of ``rows`` (in place, returned);
    ``closed`` None: no row is marked closed."""
    rows = np.ascontiguousarray(rows, dtype=np.float64)
    flags = (np.zeros(len(rows), dtype=np.bool_) if closed is None
             else np.ascontiguousarray(closed, dtype=np.bool_))
    return conserve_rows(rows, flags)


def hemisphere_rows(points, normals, vertices, elem_verts, resolution=DEFAULT_RESOLUTION,
                    planes=None, **options):
    """``(S, E) float64``: the default, anti-aliased hemisphere-base form factors.

    The item buffer decides **visibility**, Lambert's contour formula the **size** (issue 6,
    item 2): ``F_j = L_j · won_j / covered_j``, the exact unoccluded form factor times the
    fraction of the element's disc pixels it wins after hidden-surface removal. An element
    that covers no pixel centre, or whose exact projected area ``L_j · n_disc`` is under
    :data:`daskrad.tolerances.SUBPIXEL_AREA_PX` pixels, gets ``L_j`` times the fraction of the
    2 x 2 pixels around its centroid's direction where it lies in front (a coplanar winner
    ties: visible), weighted bilinearly by the direction's position, so ``F_j`` is continuous
    in the geometry and the units (:func:`daskrad.kernels.hemisphere.hemisphere_visibility`).
    The area test matters for slivers: an element thinner than the polyline's chord error
    (up to ``EDGE_SAGITTA_PX`` of a pixel with the automatic edge angle) projects to a
    crescent of chord artefacts, stacked on its coplanar neighbours' crescents; the pixel
    centres it "covers" are not its own and go to the lowest index on the depth tie, so
    ``won / covered`` gave 0 for the others (stress case ``sliver``: furnace error 9.4 %).

    Error: an unoccluded element gets ``L_j`` exactly, whatever its size, distance or angle (no
    aliasing). A partly occluded one errs only through the pixels along the *occluder's*
    outline inside it: ``|ΔF_j| <= L_j · (P_px/4 + 4) / covered_j`` with the item buffer's
    error model (tests/test_formfactor.py). Conservation: a row is scaled to 1 when it sums to
    more (overlapping elements) and to exactly 1 when every disc pixel is won (a closed view),
    so ``Σ_j F_j <= 1`` always and ``= 1`` in a closed scene (:func:`_conserve`).
    Options: ``edge_angle`` (degrees, eq. 4), ``depth`` (``"exact"`` or ``"plane"``, eq. 5);
    ``planes``: the elements' planes (:func:`element_planes` of the same geometry), computed
    here when not given.
    """
    _check_options(options, ("edge_angle", "depth"))
    r, angle, plane = _raster_args(resolution, **options)
    points, normals, vertices, elem_verts = _prepare(points, normals, vertices, elem_verts)
    enrm, eoff = element_planes(vertices, elem_verts) if planes is None else planes
    won, covered, n_disc, visible = hemisphere_visibility(
        points, normals, vertices, elem_verts, enrm, eoff, r, angle, plane,
        tolerances.HORIZON_EPS)
    # Lambert only where the visible fraction can be positive (a pixel won, or the bilinear
    # test, set for every drawn element that does not win all it covers, above 0): hidden
    # and culled elements get F = 0 whatever their size
    lam = lambert_masked(points, normals, vertices, elem_verts, enrm, eoff,
                         (won > 0) | (visible > 0.0))
    # pixel counts measure visibility only for an element of at least SUBPIXEL_AREA_PX of
    # true area (Lambert's projected area in pixels): below, the count is aliasing or, for an
    # element thinner than the polyline's chord error, artefacts it shares with its coplanar
    # neighbours and loses to them on ties; the bilinear test at its centroid counts ties visible
    # (:func:`daskrad.kernels.hemisphere.anti_aliased_rows`: won / covered where that
    # measures, then conserved; one pass without the GIL where a dozen
    # numpy operations held it: graz's first 600 shots, alternating, in-process 13.84 / 13.56
    # → 13.01 / 12.79 s, on 2 thread workers 16.22 / 14.63 → 14.06 / 14.09 s)
    return anti_aliased_rows(won, covered, visible, lam, int(n_disc),
                             float(tolerances.SUBPIXEL_AREA_PX))


def itembuffer_rows(points, normals, vertices, elem_verts, resolution=DEFAULT_RESOLUTION,
                    **options):
    """``(S, E) float64``: the paper's item buffer, ``F = won / n_disc`` (eqs. 6–7).

    Every pixel centre inside the unit circle weighs the same ``1/n_disc`` (this replaces the
    paper's ``4/(π R²)`` so the weights sum to exactly 1), and each pixel has one winner, so
    ``Σ_j F[s, j] <= 1``, with equality (to round-off) when every direction above the horizon
    sees some element, i.e. in a closed scene. A small element aliases: its count errs by about
    a quarter of its outline's length in pixels. Options: ``edge_angle`` (degrees), ``depth``
    (``"exact"`` or ``"plane"``).
    """
    _check_options(options, ("edge_angle", "depth"))
    options.pop("grid", None)
    options.pop("planes", None)
    won, _, n_disc = hemisphere_counts(points, normals, vertices, elem_verts, resolution,
                                       **options)
    return won / float(n_disc)


def scanline_rows(points, normals, vertices, elem_verts, resolution=DEFAULT_RESOLUTION,
                  **options):
    """``(S, E) float64``: hemisphere base by exact span lengths on ``resolution`` scanlines.

    Eq. 8 with visibility per span piece (:mod:`daskrad.kernels.scanline`); the span-length
    unit is normalised so the whole disc sums to exactly 1 (``Σ_j F_j <= 1``, ``= 1`` in a closed
    scene). Options: ``edge_angle``, ``depth``, ``both_axes`` (average horizontal and vertical
    scanlines).
    """
    _check_options(options, ("edge_angle", "depth", "both_axes"))
    both_axes = options.pop("both_axes", False)
    r, angle, plane = _raster_args(resolution, auto=False, **options)
    points, normals, vertices, elem_verts = _prepare(points, normals, vertices, elem_verts)
    return scanline_shots(points, normals, vertices, elem_verts, r, angle, plane,
                          tolerances.HORIZON_EPS, bool(both_axes))


def hemicube_rows(points, normals, vertices, elem_verts, resolution=DEFAULT_RESOLUTION,
                  **options):
    """``(S, E) float64``: Cohen & Greenberg's hemicube (:mod:`daskrad.kernels.hemicube`).

    ``resolution`` is the top face's side ``R`` (sides ``R × R//2``); delta form factors are
    normalised to sum to exactly 1 over the cube. ``edge_angle`` and ``depth`` are accepted and
    ignored (central projection keeps edges straight and depth linear).
    """
    _check_options(options, ("edge_angle", "depth"))
    r = _check_resolution(resolution)
    points, normals, vertices, elem_verts = _prepare(points, normals, vertices, elem_verts)
    return hemicube_shots(points, normals, vertices, elem_verts, r, tolerances.HORIZON_EPS)


def element_grid(vertices, elem_verts):
    """``(grid, tri_elem)``: the voxel grid over the elements' triangles (quads split along
    0–2, :func:`daskrad.scene.corners.split_quads`) and ``tri_elem : (T,) int64``, the element
    of each triangle. The pipeline builds it once per mesh (:class:`daskrad.preprocess.Mesh`)
    and hands it to the methods as the ``grid`` option; a direct call builds it here."""
    tri, owner = split_quads(elem_verts)
    return build_grid(vertices[tri], rel_eps=tolerances.RAY_EPS), owner


def raycast_rows(points, normals, vertices, elem_verts, resolution=None, samples=2, grid=None,
                 **options):
    """``(S, E) float64``: Wallace et al.'s ray-cast form factor (receiver vertices).

    ``F_j = L_j × (visible fraction of the element's sample points)``: Lambert's exact
    unoccluded term times visibility by shadow rays from the shooting point through the voxel
    grid (:mod:`daskrad.kernels.raycast`). ``samples``: ``1`` the centroid, ``n >= 2`` an
    ``n × n`` lattice including the corners (``2``: the receiver vertices, the default).
    ``grid``: the voxel grid over the elements' triangles (any triangle order), built here when
    not given. ``resolution``, ``edge_angle`` and ``depth`` are accepted and ignored. A row
    summing to more than 1 (an over-estimated partly hidden element) is scaled to 1.
    """
    _check_options(options, ("edge_angle", "depth"))
    if isinstance(samples, bool) or int(samples) != samples or not 1 <= samples <= 64:
        raise OptionError(f"samples must be an integer in [1, 64], got {samples!r}")
    points, normals, vertices, elem_verts = _prepare(points, normals, vertices, elem_verts)
    lam = lambert_shots(points, normals, vertices, elem_verts)
    if not len(elem_verts):
        return lam
    if grid is None:
        grid, _ = element_grid(vertices, elem_verts)
    offset = tolerances.RAY_OFFSET * max(scene_diagonal(vertices), 1e-300)
    vis = raycast_visibility(points, normals, vertices, elem_verts, lam > 0.0, grid,
                             int(samples), offset)
    return _conserve(lam * vis)


def analytic_rows(points, normals, vertices, elem_verts, resolution=None, **options):
    """``(S, E) float64``: Lambert's contour formula, no occlusion.

    ``resolution`` and the raster options (``edge_angle``, ``depth``) are accepted and ignored,
    so one set of run settings works with every method; other options are refused.
    """
    _check_options(options, ("edge_angle", "depth"))
    points, normals, vertices, elem_verts = _prepare(points, normals, vertices, elem_verts)
    return lambert_shots(points, normals, vertices, elem_verts)


def _check_options(options, known):
    """Refuse options a method does not know. ``grid`` (the voxel grid over the elements'
    triangles) and ``planes`` (the elements' planes, :func:`element_planes`), both built once
    per mesh, are offered to every method: the grid is used by those that trace rays, the
    planes by the default method (a one-point row of a 114k-element office computed them
    twice, ~2.5 of its ~21 ms), like ``resolution`` by those that rasterize."""
    unknown = sorted(set(options) - set(known) - {"grid", "planes"})
    if unknown:
        allowed = ", ".join(known) if known else "none"
        raise OptionError(f"unknown form-factor option(s) {', '.join(unknown)}; "
                          f"known: {allowed}")


#: Form-factor methods by name; every value has the signature
#: ``fn(points, normals, vertices, elem_verts, resolution, **options) -> (S, E) float64``.
METHODS = {
    "hemisphere": hemisphere_rows,
    "hemisphere-itembuffer": itembuffer_rows,
    "hemisphere-scanline": scanline_rows,
    "hemicube": hemicube_rows,
    "raycast": raycast_rows,
    "analytic": analytic_rows,
}


def get_method(name):
    """The function registered under ``name`` in :data:`METHODS`; :class:`OptionError` if none."""
    try:
        return METHODS[name]
    except (KeyError, TypeError):
        raise OptionError(
            f"unknown form-factor method {name!r}; known methods: {', '.join(sorted(METHODS))}"
        ) from None


def shooter_rows(points, normals, vertices, elem_verts, method="hemisphere",
                 resolution=DEFAULT_RESOLUTION, **options):
    """Form factors from a batch of shooters: ``(S, E) float64``, dense rows.

    The entry point of the solver and of the Dask form-factor tasks; ``to_sparse`` gives the
    ``(indptr, ids, values)`` form for shipping.
    """
    return get_method(method)(points, normals, vertices, elem_verts, resolution, **options)


def point_to_elements(point, normal, vertices, elem_verts, method="hemisphere",
                      resolution=DEFAULT_RESOLUTION, **options):
    """``(E,) float64``: form factors from one differential area (``point``, ``normal``, both
    ``(3,)``) to every element, with occlusion among the elements for the rasterized methods."""
    return shooter_rows(np.reshape(point, (1, 3)), np.reshape(normal, (1, 3)), vertices,
                        elem_verts, method, resolution, **options)[0]


def analytic_point_to_elements(point, normal, vertices, elem_verts):
    """``(E,) float64``: unoccluded point-to-element form factors by Lambert's formula."""
    return analytic_rows(np.reshape(point, (1, 3)), np.reshape(normal, (1, 3)), vertices,
                         elem_verts)[0]


def to_sparse(rows):
    """Sparse (CSR) form of ``rows : (S, E) float64``.

    Returns ``indptr : (S + 1,) int64``, ``ids : (nnz,) int32`` and ``values : (nnz,) float64``:
    the nonzeros of row ``s`` are ``ids[indptr[s]:indptr[s+1]]`` (ascending) with
    ``values[indptr[s]:indptr[s+1]]``.
    """
    rows = np.atleast_2d(np.asarray(rows, dtype=np.float64))
    s_idx, ids = np.nonzero(rows)
    indptr = np.zeros(len(rows) + 1, dtype=np.int64)
    np.cumsum(np.bincount(s_idx, minlength=len(rows)), out=indptr[1:])
    return indptr, ids.astype(np.int32), rows[s_idx, ids]
