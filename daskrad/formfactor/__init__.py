"""Form factors from differential shooting areas to receiving elements (DESIGN §2).

Every method has one signature, so the solver and the Dask tasks pick one by name::

    fn(points, normals, vertices, elem_verts, resolution, **options) -> (S, E) float64

``points : (S, 3) float64`` and ``normals : (S, 3) float64`` are the shooters' sample points and
normals (normalized here), ``vertices : (V, 3) float64`` and ``elem_verts : (E, 4) int32``
(``-1`` in column 3 for a triangle) the receiving elements. Row ``s`` holds ``F[s, j]``, the form
factor from the differential area ``s`` to element ``j``. Receivers are one-sided: an element
whose lit side does not face the point gets 0.

Methods (:data:`METHODS`):

``"hemisphere"``
    Doi's hemisphere-base item buffer with occlusion among the elements
    (:mod:`daskrad.kernels.hemisphere`). Options: ``edge_angle`` (degrees, default
    :data:`daskrad.tolerances.EDGE_ANGLE_DEG`, eq. 4) and ``depth`` (``"exact"``, default, or
    ``"plane"`` for the paper's eq. 5). Every disc pixel weighs ``1/n_disc``, so each row sums
    to at most 1, and to exactly 1 (to round-off) in a closed scene.
``"analytic"``
    Lambert's contour formula, **no occlusion** (:mod:`daskrad.kernels.lambert`); the
    ground truth for unoccluded configurations. ``resolution`` is ignored.

Rows are returned dense: a float64 row of 50,000 elements is 400 kB, cheap next to the
rasterization. :func:`to_sparse` turns rows into the sparse form the Dask tasks ship
(DESIGN §4: element ids and factors).
"""

from __future__ import annotations

import math

import numpy as np

from daskrad import tolerances
from daskrad.errors import OptionError, SceneError
from daskrad.kernels.hemisphere import hemisphere_shots
from daskrad.kernels.lambert import lambert_shots

__all__ = [
    "METHODS",
    "analytic_point_to_elements",
    "analytic_rows",
    "get_method",
    "hemisphere_counts",
    "hemisphere_rows",
    "point_to_elements",
    "shooter_rows",
    "to_sparse",
]

_DEPTHS = ("exact", "plane")


def _prepare(points, normals, vertices, elem_verts):
    """Validate and convert the inputs to contiguous float64 / int32 arrays."""
    points = np.ascontiguousarray(np.atleast_2d(np.asarray(points, dtype=np.float64)))
    normals = np.ascontiguousarray(np.atleast_2d(np.asarray(normals, dtype=np.float64)))
    vertices = np.ascontiguousarray(np.asarray(vertices, dtype=np.float64))
    elem_verts = np.ascontiguousarray(np.asarray(elem_verts, dtype=np.int32))
    if points.ndim != 2 or points.shape[1] != 3 or normals.shape != points.shape:
        raise SceneError(
            f"points and normals must both be (S, 3) arrays, got {points.shape} and "
            f"{normals.shape}"
        )
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise SceneError(f"vertices must be a (V, 3) array, got {vertices.shape}")
    if elem_verts.ndim != 2 or elem_verts.shape[1] != 4:
        raise SceneError(f"elem_verts must be an (E, 4) array, got {elem_verts.shape}")
    if len(elem_verts) and (
        elem_verts[:, :3].min() < 0 or elem_verts.max() >= len(vertices)
        or elem_verts[:, 3].min() < -1
    ):
        raise SceneError("elem_verts holds a corner index outside the vertex array")
    if not (np.isfinite(points).all() and np.isfinite(normals).all()
            and np.isfinite(vertices).all()):
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


def hemisphere_counts(points, normals, vertices, elem_verts, resolution=256,
                      edge_angle=tolerances.EDGE_ANGLE_DEG, depth="exact"):
    """Raw pixel counts of the hemisphere-base item buffer.

    Returns
    -------
    won : (S, E) int32
        Disc pixels each element owns after hidden-surface removal.
    covered : (S, E) int32
        Disc pixels each element's projection covers before the depth test; an
        anti-aliased variant uses ``analytic × won / covered``.
    n_disc : int
        Pixel centres inside the unit circle: ``F = won / n_disc``.
    """
    resolution = _check_resolution(resolution)
    if depth not in _DEPTHS:
        raise OptionError(f"depth must be one of {', '.join(_DEPTHS)}, got {depth!r}")
    if not (0.0 < float(edge_angle) <= 90.0):
        raise OptionError(f"edge_angle must be in (0, 90] degrees, got {edge_angle!r}")
    points, normals, vertices, elem_verts = _prepare(points, normals, vertices, elem_verts)
    won, covered, n_disc = hemisphere_shots(
        points, normals, vertices, elem_verts, resolution, math.radians(float(edge_angle)),
        depth == "plane", tolerances.HORIZON_EPS,
    )
    return won, covered, int(n_disc)


def hemisphere_rows(points, normals, vertices, elem_verts, resolution=256, **options):
    """``(S, E) float64``: hemisphere-base form factors with occlusion (DESIGN §2).

    ``F[s, j] = won[s, j] / n_disc``: every pixel centre inside the unit circle weighs the same
    ``1/n_disc`` (this replaces the paper's ``4/(π R²)`` of eqs. 6–7 so the weights sum to
    exactly 1), and each pixel has one winner, so ``Σ_j F[s, j] <= 1``, with equality (to
    round-off) when every direction above the horizon sees some element, i.e. in a closed
    scene. Options: ``edge_angle`` (degrees), ``depth`` (``"exact"`` or ``"plane"``).
    """
    _check_options(options, ("edge_angle", "depth"))
    won, _, n_disc = hemisphere_counts(points, normals, vertices, elem_verts, resolution,
                                       **options)
    return won / float(n_disc)


def analytic_rows(points, normals, vertices, elem_verts, resolution=None, **options):
    """``(S, E) float64``: Lambert's contour formula, no occlusion.

    ``resolution`` and the raster options (``edge_angle``, ``depth``) are accepted and ignored,
    so one set of run settings works with every method; other options are refused.
    """
    _check_options(options, ("edge_angle", "depth"))
    points, normals, vertices, elem_verts = _prepare(points, normals, vertices, elem_verts)
    return lambert_shots(points, normals, vertices, elem_verts)


def _check_options(options, known):
    unknown = sorted(set(options) - set(known))
    if unknown:
        allowed = ", ".join(known) if known else "none"
        raise OptionError(f"unknown form-factor option(s) {', '.join(unknown)}; "
                          f"known: {allowed}")


#: Form-factor methods by name; every value has the signature
#: ``fn(points, normals, vertices, elem_verts, resolution, **options) -> (S, E) float64``.
METHODS = {
    "hemisphere": hemisphere_rows,
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


def shooter_rows(points, normals, vertices, elem_verts, method="hemisphere", resolution=256,
                 **options):
    """Form factors from a batch of shooters: ``(S, E) float64``, dense rows.

    The entry point of the solver and of the Dask form-factor tasks; ``to_sparse`` gives the
    ``(indptr, ids, values)`` form for shipping.
    """
    return get_method(method)(points, normals, vertices, elem_verts, resolution, **options)


def point_to_elements(point, normal, vertices, elem_verts, method="hemisphere", resolution=256,
                      **options):
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
