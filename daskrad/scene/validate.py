"""Checks every scene goes through, from a file or from arrays (docs/design.md §6, §7).

Each refusal is a :class:`SceneError` naming the file and the problem; a user can fix it.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np

from daskrad import tolerances
from daskrad.errors import DaskradWarning, SceneError
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
    far = ~(np.abs(v) <= tolerances.MAX_COORDINATE).all(axis=1)
    if far.any():
        i = int(np.flatnonzero(far)[0])
        raise SceneError(
            f"{int(far.sum())} vertices have coordinates beyond ±{tolerances.MAX_COORDINATE:g}, "
            f"where lengths to the fourth power overflow (first: vertex {i + 1} = "
            f"{v[i].tolist()})",
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


def centre_of(vertices: np.ndarray, corners: np.ndarray, diag: float) -> np.ndarray:
    """``(3,) float64``: the origin of the coordinates a scene is worked in.

    The bounding-box centre of the used vertices, rounded to a multiple of ``2^k >= diag``:
    subtracting it is exact (Sterbenz), so a scene far from the world's origin (a unit box at
    10¹²) is meshed, lit and solved exactly as the same scene at the origin, and a scene
    within its own size of the world's origin is not moved at all (origin 0, its bits as
    they were).
    """
    used = corners[corners >= 0]
    if used.size == 0 or not diag > 0:
        return np.zeros(3)
    v = vertices[np.unique(used)]
    step = 2.0 ** math.ceil(math.log2(diag))
    return np.round((v.min(axis=0) + v.max(axis=0)) / 2.0 / step) * step


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


def reversed_twins(vertices: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """``(Q,) int64``: for each polygon, the earlier polygon it is the back of (the same corner
    positions in the reversed cyclic order: one two-sided surface given as two faces, as OBJ
    files and converters write it), else ``-1``."""
    _, vid = np.unique(vertices + 0.0, axis=0, return_inverse=True)
    vid = vid.reshape(-1)
    ids = np.where(polygons >= 0, vid[np.maximum(polygons, 0)], -1).astype(np.int64)
    n = np.where(polygons[:, 3] >= 0, 4, 3)
    big = np.iinfo(np.int64).max

    def canonical(rows):
        start = np.argmin(np.where(rows >= 0, rows, big), axis=1)
        out = np.take_along_axis(rows, (start[:, None] + np.arange(4)) % n[:, None], axis=1)
        out[n == 3, 3] = -1
        return out

    forward = canonical(ids)
    backward = ids.copy()                  # the same corners walked the other way
    backward[n == 4] = ids[n == 4][:, ::-1]
    backward[n == 3, :3] = ids[n == 3][:, 2::-1]
    backward = canonical(backward)
    first: dict[bytes, int] = {}
    for i, row in enumerate(forward):
        first.setdefault(row.tobytes(), i)
    out = np.full(len(polygons), -1, np.int64)
    for i, row in enumerate(backward):
        j = first.get(row.tobytes(), -1)
        if 0 <= j < i and out[j] < 0:     # each front takes one back, the first after it
            out[i] = j
    return out


def _overlap_message(pairs, origin, more: str) -> str:
    a, b = sorted(int(origin[i]) + 1 for i in pairs[0])
    extra = f" ({len(pairs) - 1} more such pairs)" if len(pairs) > 1 else ""
    return (f"faces {a} and {b} lie in one plane, face the same way and overlap, so they would "
            f"z-fight{extra}: {more}")


def _resolve_coplanar_overlaps(v, poly, pm, origin, ke, diag, path: str):
    """Lift every face that lies on a larger face in one plane (issue 16: decals, rugs).

    For each overlapping pair (:func:`coplanar_overlaps`) the larger face is below, the smaller
    on top (equal areas: the later face in the file, as a painter would). A face's level is one
    more than the highest level of the faces it lies on; it moves ``level · DECAL_LIFT · diag``
    along its unit normal, on new vertices (the one below keeps its own). Refused, naming two
    faces: an emitting face under another (its covered part would still emit, through the
    back of the one-sided face on top: cut it out instead), stacks deeper than
    ``MAX_DECAL_DEPTH``, and overlaps that remain after lifting.

    Returns ``(vertices, polygons, message)``; ``message`` is ``None`` when nothing overlaps.
    """
    pairs = coplanar_overlaps(v, poly, diag)
    if len(pairs) == 0:
        return v, poly, None
    area = polygon_area(v, poly)
    a, b = pairs[:, 0], pairs[:, 1]                       # a < b: a comes first in the file
    a_below = area[a] >= area[b]
    below, above = np.where(a_below, a, b), np.where(a_below, b, a)
    lit = (ke[pm[below]] > 0).any(axis=1)
    if lit.any():
        k = int(np.flatnonzero(lit)[0])
        raise SceneError(
            f"face {int(origin[above[k]]) + 1} lies on emitting face {int(origin[below[k]]) + 1} "
            "in one plane, facing the same way: the covered part would still emit through it; "
            "cut it out of the emitting face", path)
    # longest chains below each face; below → above always goes to a smaller face (or a later
    # one of equal area), so there is no cycle and depth + 1 passes settle it
    level = np.zeros(len(poly), np.int64)
    for _ in range(tolerances.MAX_DECAL_DEPTH + 1):
        new = level.copy()
        np.maximum.at(new, above, level[below] + 1)
        if (new == level).all():
            break
        level = new
    if level.max() > tolerances.MAX_DECAL_DEPTH:
        raise SceneError(_overlap_message(pairs, origin, f"faces stack more than "
                                          f"{tolerances.MAX_DECAL_DEPTH} deep in one plane, "
                                          "which is no decal: remove the overlaps"), path)
    lifted = np.flatnonzero(level > 0)
    corners = np.where(poly[lifted] >= 0, poly[lifted], poly[lifted, 2:3])  # (k, 4)
    p = v[corners]
    normal = np.where((poly[lifted, 3] >= 0)[:, None],
                      np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 1]),
                      np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    shift = (level[lifted] * tolerances.DECAL_LIFT * diag)[:, None] * normal
    new_v = (p + shift[:, None, :]).reshape(-1, 3)
    new_idx = (len(v) + np.arange(4 * len(lifted))).reshape(-1, 4)
    poly = poly.copy()
    poly[lifted] = np.where(poly[lifted] >= 0, new_idx, -1)
    v = np.concatenate([v, new_v])
    left = coplanar_overlaps(v, poly, diag)
    if len(left):
        raise SceneError(_overlap_message(left, origin, "they still overlap after lifting the "
                                          "smaller faces: remove one, or cut it out of the "
                                          "other"), path)
    first = int(np.flatnonzero(level[above] == 1)[0])
    deepest = int(level.max())
    message = (f"{path}: {len(lifted)} faces lie on larger faces in one plane (coplanar "
               f"overlaps, first face {int(origin[above[first]]) + 1} on face "
               f"{int(origin[below[first]]) + 1}): lifted {tolerances.DECAL_LIFT:g} × the scene "
               "diagonal off the plane along their normals"
               + (f" ({deepest} levels where stacked)" if deepest > 1 else "")
               + " so that they show")
    return v, poly, message


def _check_magnitudes(pm, ke, names, points, directional, diag, path: str) -> None:
    """Refuse light levels beyond ``tolerances.MAX_LIGHT`` and point lights beyond
    ``tolerances.MAX_COORDINATE``: nothing the solver and the outputs form can overflow.

    ``pm : (Q,)`` polygon materials, ``ke : (M, 3)`` radiance, ``diag`` the scene's scale.
    Products are formed with overflow allowed (an inf compares as too large) so that no numpy
    warning is printed before the one line.
    """
    limit = tolerances.MAX_LIGHT
    far = ~(np.abs(points.position) <= tolerances.MAX_COORDINATE).all(axis=1)
    if far.any():
        i = int(np.flatnonzero(far)[0])
        raise SceneError(f"point light {i + 1} at {points.position[i].tolist()} lies beyond "
                         f"±{tolerances.MAX_COORDINATE:g}", path)
    used = np.zeros(len(ke), bool)
    used[pm] = True
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        tables = (
            (np.where(used[:, None], np.pi * ke, 0.0), "material {name!r}: Ke", ke,
             "exitance π·Ke"),
            (points.intensity / diag**2, "point light {i}: intensity", points.intensity,
             "its irradiance at the scene's size, intensity/diagonal²,"),
            (directional.irradiance, "directional light {i}: irradiance",
             directional.irradiance, "irradiance"),
        )
        total = sum(float(t.sum()) for t, *_ in tables)
    for scale, what, value, formula in tables:
        bad = ~(scale <= limit)
        if bad.any():
            row, ch = np.argwhere(bad)[0]
            what = what.format(name=names[row] if len(names) > row else "", i=row + 1)
            raise SceneError(
                f"{what} {'RGB'[ch]} = {value[row, ch]:.3g} is out of range: {formula} "
                f"{scale[row, ch]:.3g} W/m² is beyond {limit:g} (images and the store hold "
                "float32)", path)
    if not total <= limit:
        raise SceneError(f"the lights together are out of range: {total:.3g} W/m² is beyond "
                         f"{limit:g} (images and the store hold float32)", path)


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
    two_sided=None,
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
    two_sided : (M,) bool, optional
        Materials whose faces are two-sided (light leaves and arrives on both sides, with the
        same material); default: none (MGF's ``sides 2`` is the default of that format).

    Zero-area polygons (below ``DEGENERATE_AREA * diag²``) are dropped with a warning and
    counted in ``Scene.dropped_degenerate``. A polygon that repeats an earlier one (the same
    corner positions in the same cyclic order) is dropped with a warning: two coincident
    copies would both shoot their emission and split what they receive (issue 7).
    Back-to-back copies (the opposite winding at the same place) are one two-sided face: the
    first is kept with the second's material for its back (``Scene.back_material``).
    Two faces that lie in one plane, face the same way and overlap (beyond sharing an edge)
    would z-fight (:mod:`daskrad.scene.overlap`): the smaller is lifted off the plane so that
    it shows (a decal; ``tolerances.DECAL_LIFT``), or the scene is refused naming both faces
    when that cannot resolve it (an emitter under another face, stacks deeper than
    ``tolerances.MAX_DECAL_DEPTH``). Every change is one line in ``Scene.warnings``, also
    issued as a :class:`DaskradWarning`.
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

    if camera is not None:
        for name in ("eye", "look_at"):
            at = np.asarray(getattr(camera, name), dtype=np.float64)
            if not (np.abs(at) <= tolerances.MAX_COORDINATE).all():
                raise SceneError(f"camera {name} {at.tolist()} lies beyond "
                                 f"±{tolerances.MAX_COORDINATE:g}", path)
    diag = scale_of(v, poly)  # finite: check_vertices bounded every coordinate
    if 0 < diag < tolerances.MIN_DIAGONAL:
        raise SceneError(f"the scene is {diag:.3g} across, below {tolerances.MIN_DIAGONAL:g} "
                         "(its tolerances would underflow): scale it up", path)
    shift = centre_of(v, poly, diag)
    if shift.any():   # every later step works relative to the scene's centre (issue 13)
        v = v - shift
        points = replace(points, position=np.asarray(points.position, np.float64) - shift)
        if camera is not None:
            camera = replace(camera, eye=np.asarray(camera.eye, np.float64) - shift,
                             look_at=np.asarray(camera.look_at, np.float64) - shift)
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
    notes: list[str] = []
    if dropped:
        notes.append(f"{path}: dropped {dropped} zero-area faces")
        poly, pm, origin = poly[~degenerate], pm[~degenerate], origin[~degenerate]
    repeated = duplicated_polygons(v, poly)
    if repeated.any():
        notes.append(f"{path}: dropped {int(repeated.sum())} duplicated faces (same corners "
                     "and winding as an earlier face; the first is kept)")
        poly, pm, origin = poly[~repeated], pm[~repeated], origin[~repeated]
    # a face and its reverse at the same place are one two-sided surface: keep the front, its
    # material and the back's (issue 16: coincident twins fight in the item buffer and rays)
    sides2 = np.zeros(m, bool) if two_sided is None else np.asarray(two_sided, bool).reshape(m)
    back = np.where(sides2[pm], pm, -1).astype(np.int64)
    twin_of = reversed_twins(v, poly)
    twins = twin_of >= 0
    if twins.any():
        back[twin_of[twins]] = pm[twins]
        keep = ~twins
        poly, pm, origin, back = poly[keep], pm[keep], origin[keep], back[keep]
        notes.append(f"{path}: {int(twins.sum())} pairs of coincident back-to-back faces "
                     "made two-sided faces")
    v, poly, lifted = _resolve_coplanar_overlaps(v, poly, pm, origin, ke, diag, path)
    if lifted:
        notes.append(lifted)
    for note in notes:
        warnings.warn(note, DaskradWarning, stacklevel=2)
    _check_magnitudes(pm, ke, names, points, directional, diag, path)

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
        origin=shift,
        back_material=np.ascontiguousarray(back, dtype=np.int32),
        warnings=tuple(notes),
    )
