"""Checks every scene goes through, from a file or from arrays (docs/design.md §6, §7).

Each refusal is a :class:`SceneError` naming the file and the problem; a user can fix it.
"""

from __future__ import annotations

import warnings

import numpy as np

from daskrad import tolerances
from daskrad.errors import SceneError
from daskrad.scene.overlap import coplanar_overlaps
from daskrad.scene.polygons import convex_planar, faces_to_polygons, polygon_area
from daskrad.scene.types import Camera, DirectionalLights, Materials, PointLights, Scene


def check_vertices(vertices, path: str) -> np.ndarray:
    """``(V, 3) float64`` copy of ``vertices``; refuses NaN or infinite coordinates."""
    try:
        v = np.array(vertices, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError("vertex coordinates are not numbers", path) from None
    if v.ndim != 2 or v.shape[1] != 3:
        raise SceneError(f"vertices must have shape (V, 3), got {v.shape}", path)
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise SceneError(
            f"{int(bad.sum())} vertices have NaN or infinite coordinates "
            f"(first: vertex {i + 1} = {v[i].tolist()})",
            path,
        )
    return v


def scale_of(vertices: np.ndarray, corners: np.ndarray) -> float:
    """Bounding-box diagonal of the vertices that ``corners`` use (``-1`` ignored)."""
    used = corners[corners >= 0]
    if used.size == 0:
        return 0.0
    v = vertices[np.unique(used)]
    return float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))


def duplicated_polygons(vertices: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """``(Q,) bool``: polygons whose corners repeat an earlier polygon's, by position (so
    unwelded copies count), in the same cyclic order from any starting corner.

    The opposite winding is a different polygon (the other side of a two-sided surface).
    """
    # one id per distinct position (+ 0.0 turns -0.0 into 0.0, which unique would tell apart)
    _, vid = np.unique(vertices + 0.0, axis=0, return_inverse=True)
    vid = vid.reshape(-1)
    ids = np.where(polygons >= 0, vid[np.maximum(polygons, 0)], -1).astype(np.int64)
    n = np.where(polygons[:, 3] >= 0, 4, 3)
    # rotate each polygon to start at its smallest id, keeping the cyclic order
    start = np.argmin(np.where(ids >= 0, ids, np.iinfo(np.int64).max), axis=1)
    canon = np.take_along_axis(ids, (start[:, None] + np.arange(4)) % n[:, None], axis=1)
    canon[n == 3, 3] = -1
    _, first = np.unique(canon, axis=0, return_index=True)
    repeated = np.ones(len(polygons), bool)
    repeated[first] = False
    return repeated


def _refuse_coplanar_overlaps(v, poly, origin, diag, path: str) -> None:
    """One line naming the first pair of faces (1-based, in file order) that z-fight."""
    pairs = coplanar_overlaps(v, poly, diag)
    if len(pairs) == 0:
        return
    a, b = sorted(int(origin[i]) + 1 for i in pairs[0])
    more = f" ({len(pairs) - 1} more such pairs)" if len(pairs) > 1 else ""
    raise SceneError(
        f"faces {a} and {b} lie in one plane, face the same way and overlap, so they would "
        f"z-fight{more}: remove one, cut it out of the other, or lift it off the plane",
        path,
    )


def _rgb_table(values, m: int, name: str, path: str) -> np.ndarray:
    try:
        a = np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError(f"{name} values are not numbers", path) from None
    if a.shape != (m, 3):
        raise SceneError(f"{name} must have shape ({m}, 3), got {a.shape}", path)
    return a


def _first_bad(mask: np.ndarray, table: np.ndarray, names, what: str, rule: str, path: str):
    if mask.any():
        row, ch = np.argwhere(mask)[0]
        raise SceneError(
            f"material {names[row]!r}: {what} {'RGB'[ch]} = {table[row, ch]!r} {rule}", path
        )


def _as_lights(lights, cls, fields: tuple[str, str], path: str):
    if lights is None:
        return cls()
    if isinstance(lights, cls):
        a, b = getattr(lights, fields[0]), getattr(lights, fields[1])
    else:
        a, b = lights
    try:
        a = np.array(a, dtype=np.float64).reshape(-1, 3)
        b = np.array(b, dtype=np.float64).reshape(-1, 3)
    except (TypeError, ValueError):
        raise SceneError(f"{cls.__name__}: expected (L, 3) arrays", path) from None
    if len(a) != len(b):
        raise SceneError(f"{cls.__name__}: {fields[0]} and {fields[1]} differ in length", path)
    if not (np.isfinite(a).all() and np.isfinite(b).all()):
        raise SceneError(f"{cls.__name__}: values must be finite", path)
    if (b < 0).any():
        raise SceneError(f"{cls.__name__}: {fields[1]} must not be negative", path)
    if fields[0] == "direction":
        norm = np.linalg.norm(a, axis=1)
        if (norm == 0).any():
            raise SceneError("directional light with a zero direction", path)
        a = a / norm[:, None]
    return cls(a, b)


def scene_from_arrays(
    vertices,
    polygons,
    polygon_material,
    diffuse,
    emission,
    specular=None,
    shininess=None,
    mirror=None,
    point_lights=None,
    directional_lights=None,
    camera: Camera | None = None,
    path: str = "<arrays>",
    material_names=None,
    polygon_face=None,
) -> Scene:
    """Build a :class:`Scene` from arrays, with every check :func:`load_scene` makes.

    Parameters
    ----------
    vertices : (V, 3) float
    polygons : (Q, 4) int, or (Q, 3) for triangles only
        ``-1`` in column 3 for a triangle; corners counter-clockwise seen from the lit side.
    polygon_material : (Q,) int
    diffuse, emission : (M, 3) float
        Reflectance in ``[0, 1)``; emitted radiance ``≥ 0``.
    specular : (M, 3) float, optional (default 0), in ``[0, 1]``
    shininess : (M,) float, optional (default 0), ``≥ 0``
    mirror : (M,) bool, optional (default False)
    point_lights : PointLights or (position, intensity), optional
    directional_lights : DirectionalLights or (direction, irradiance), optional
        Directions are normalized here.
    camera : Camera, optional
    path : str
        Named in every error message and kept as ``Scene.path``.
    material_names : sequence of M str, optional
    polygon_face : (Q,) int, optional
        The input face (0-based, in file order) each polygon came from, for messages;
        default: the polygon's own row.

    Zero-area polygons (below ``DEGENERATE_AREA * diag²``) are dropped with a warning and
    counted in ``Scene.dropped_degenerate``. A polygon that repeats an earlier one (the same
    corner positions in the same cyclic order) is dropped with a warning: two coincident
    copies would both shoot their emission and split what they receive (issue 7).
    Back-to-back copies (the opposite winding, a two-sided surface) are kept.
    Two faces that lie in one plane, face the same way and overlap (beyond sharing an edge)
    are refused, naming both faces: they z-fight (:mod:`daskrad.scene.overlap`).
    A scene with no emitting polygon and no light with
    positive power is refused.
    """
    path = str(path)
    v = check_vertices(vertices, path)
    try:
        poly = np.array(polygons, dtype=np.int64)
    except (TypeError, ValueError):
        raise SceneError("polygon corner indices are not integers", path) from None
    if poly.ndim == 2 and poly.shape[1] == 3:
        poly = np.column_stack([poly, np.full(len(poly), -1)])
    if poly.ndim != 2 or poly.shape[1] != 4:
        raise SceneError(f"polygons must have shape (Q, 4), got {poly.shape}", path)
    if len(poly) == 0:
        raise SceneError("no faces in the scene", path)
    if (poly[:, :3] < 0).any() or (poly[:, 3] < -1).any() or (poly >= len(v)).any():
        raise SceneError(f"polygon corner index out of range ({len(v)} vertices)", path)
    origin = (np.arange(len(poly)) if polygon_face is None
              else np.array(polygon_face, dtype=np.int64).reshape(-1))
    if len(origin) != len(poly):
        raise SceneError(f"{len(origin)} face numbers for {len(poly)} polygons", path)

    try:
        kd = np.array(diffuse, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError("diffuse values are not numbers", path) from None
    if kd.ndim != 2 or kd.shape[1] != 3 or len(kd) == 0:
        raise SceneError(f"diffuse must have shape (M, 3), M >= 1, got {kd.shape}", path)
    m = len(kd)
    names = (
        tuple(str(n) for n in material_names)
        if material_names is not None
        else tuple(f"material{i}" for i in range(m))
    )
    if len(names) != m:
        raise SceneError(f"{len(names)} material names for {m} materials", path)
    ke = _rgb_table(emission, m, "emission", path)
    ks = np.zeros((m, 3)) if specular is None else _rgb_table(specular, m, "specular", path)
    ns = np.zeros(m) if shininess is None else np.array(shininess, dtype=np.float64).reshape(m)
    mir = np.zeros(m, bool) if mirror is None else np.array(mirror, dtype=bool).reshape(m)
    # NaN fails every comparison, so each rule is written as "not (good)"
    _first_bad(~((kd >= 0) & (kd < 1)), kd, names, "diffuse reflectance Kd",
               "is outside [0, 1)", path)
    _first_bad(~((ke >= 0) & np.isfinite(ke)), ke, names, "emission Ke",
               "must be finite and not negative", path)
    _first_bad(~((ks >= 0) & (ks <= 1)), ks, names, "specular reflectance Ks",
               "is outside [0, 1]", path)
    if not ((ns >= 0) & np.isfinite(ns)).all():
        row = int(np.flatnonzero(~((ns >= 0) & np.isfinite(ns)))[0])
        raise SceneError(f"material {names[row]!r}: shininess Ns = {ns[row]!r} is not >= 0", path)

    pm = np.array(polygon_material, dtype=np.int64).reshape(-1)
    if len(pm) != len(poly):
        raise SceneError(f"{len(pm)} polygon materials for {len(poly)} polygons", path)
    if ((pm < 0) | (pm >= m)).any():
        raise SceneError(f"polygon material index out of range ({m} materials)", path)

    points = _as_lights(point_lights, PointLights, ("position", "intensity"), path)
    directional = _as_lights(
        directional_lights, DirectionalLights, ("direction", "irradiance"), path
    )

    diag = scale_of(v, poly)
    if not np.isfinite(diag**2):
        raise SceneError("coordinates are too large (the bounding box overflows float64)", path)
    # a quad that is not planar and convex is split into two triangles, as a file's would be
    quad = poly[:, 3] >= 0
    if quad.any():
        bad = np.flatnonzero(quad)[~convex_planar(v, poly[quad], diag)]
        if len(bad):
            split, which = faces_to_polygons(v, poly[bad].reshape(-1), np.full(len(bad), 4), diag)
            keep = np.ones(len(poly), bool)
            keep[bad] = False
            face = np.concatenate([np.flatnonzero(keep), bad[which]])
            order = np.argsort(face, kind="stable")
            poly = np.concatenate([poly[keep], split])[order]
            pm = pm[face[order]]
            origin = origin[face[order]]
    area = polygon_area(v, poly)
    degenerate = ~(area > tolerances.DEGENERATE_AREA * diag**2)
    dropped = int(degenerate.sum())
    if dropped == len(poly):
        raise SceneError(f"no faces in the scene (all {dropped} have zero area)", path)
    if dropped:
        warnings.warn(f"{path}: dropped {dropped} zero-area faces", stacklevel=2)
        poly, pm, origin = poly[~degenerate], pm[~degenerate], origin[~degenerate]
    repeated = duplicated_polygons(v, poly)
    if repeated.any():
        warnings.warn(f"{path}: dropped {int(repeated.sum())} duplicated faces (same corners "
                      "and winding as an earlier face; the first is kept)", stacklevel=2)
        poly, pm, origin = poly[~repeated], pm[~repeated], origin[~repeated]
    _refuse_coplanar_overlaps(v, poly, origin, diag, path)

    emits = (ke[pm] > 0).any()
    lit = (points.intensity > 0).any() or (directional.irradiance > 0).any()
    if not (emits or lit):
        raise SceneError(
            "no light: no face emits (Ke > 0) and no [[light]] is given in a TOML config", path
        )

    materials = Materials(names=names, diffuse=kd, emission=ke, specular=ks, shininess=ns,
                          mirror=mir)
    return Scene(
        path=path,
        vertices=np.ascontiguousarray(v),
        polygons=np.ascontiguousarray(poly, dtype=np.int32),
        polygon_material=np.ascontiguousarray(pm, dtype=np.int32),
        materials=materials,
        point_lights=points,
        directional_lights=directional,
        camera=camera,
        dropped_degenerate=dropped,
    )
