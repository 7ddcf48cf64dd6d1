"""Quadrics and parametric surfaces, tessellated into input polygons (issue 16, item 1).

Doi's system took polygons, quadrics and parametric surfaces and decomposed them all into
polygons before meshing; so does this module. Every generator works in a local frame (axis
``z``), returns shared vertices and one polygon per facet, and is placed by a 4×4 matrix:

* surfaces of revolution (sphere, cylinder, cone, disc/ring, torus) revolve a profile
  ``(ρ, z)`` about ``z``; a facet between two parallels and two meridians is an isosceles
  trapezoid, so it is kept as one planar convex quad; a pole or apex gives triangles;
* a bicubic Bézier patch is sampled on a uniform ``(u, v)`` grid; its cells are in general not
  planar and become two triangles each (:func:`daskrad.scene.polygons.faces_to_polygons`).

Resolution comes from a **chord error** ``ε`` (scene units): the largest distance allowed
between the true surface and a facet. Load time sets ``ε = tolerances.CHORD_ERROR · diag``.

* A circle of radius ``r`` cut into ``n`` chords has sagitta ``r (1 − cos(π/n))``:
  ``n = ⌈π / acos(1 − ε/r)⌉``.
* A sphere cell of ``δ × δ`` (longitude × latitude, both at most ``δ``) has its corners within
  the angle ``δ/√2`` of the cell's centre direction, so with ``δ = √2 · acos(1 − ε/r)`` every
  facet plane is at least ``r − ε`` from the centre (``tests/test_shapes.py`` measures it).
  The inscribed polyhedron then lies between the balls of radius ``r − ε`` and ``r``, which
  brackets its area and volume.
* A torus cell spends half the budget on each of its two circles.
* A Bézier patch's bilinear interpolant on cells of size ``h = 1/k`` is within
  ``(h²/8)(|S_uu| + 2|S_uv| + |S_vv|)`` of the surface; the second derivatives are bounded by
  the control net's second differences (``6 Δ²``, ``9 Δ_uΔ_v``), which sets ``k``.

Counts are clamped to ``[MIN_SEGMENTS, MAX_SEGMENTS]`` around a circle (a small object in a
large room still looks round; a huge one stays finite).

Orientation: facets wind counter-clockwise seen from outside (the project's one-sided
convention: light leaves and arrives on the normal's side); ``inside=True`` reverses every
facet (a sphere lit from inside, a furnace). A mirroring placement (negative determinant)
reverses the winding back, so "outward" survives any transform.
"""

from __future__ import annotations

import math

import numpy as np

from daskrad.errors import SceneError
from daskrad.scene.polygons import faces_to_polygons

#: Fewest chords around a full circle, whatever the chord error.
MIN_SEGMENTS = 8
#: Most chords around a full circle.
MAX_SEGMENTS = 512
#: Most cells along each parameter of a Bézier patch.
MAX_PATCH_CELLS = 128

SHAPE_TYPES = ("sphere", "cylinder", "cone", "disc", "ring", "torus", "bezier")


# --------------------------------------------------------------------------- resolution


def _clamp(n: float) -> int:
    return int(min(max(math.ceil(n), MIN_SEGMENTS), MAX_SEGMENTS))


def _half_angle(radius: float, chord_error: float) -> float:
    """Largest ``α`` with ``r (1 − cos α) ≤ ε`` (``π`` when the error exceeds the radius)."""
    if not radius > 0:
        return math.pi
    return math.acos(max(-1.0, 1.0 - chord_error / radius))


def circle_segments(radius: float, chord_error: float) -> int:
    """Chords around a full circle of ``radius`` so that the sagitta is at most ``chord_error``."""
    return _clamp(math.pi / max(_half_angle(radius, chord_error), 1e-12))


# --------------------------------------------------------------------------- revolution


def reverse(polygons: np.ndarray) -> np.ndarray:
    """``(Q, 4)`` polygons with their winding reversed (triangles keep ``-1`` in column 3)."""
    p = np.asarray(polygons, dtype=np.int64)
    tri = p[:, 3] < 0
    out = p[:, [0, 3, 2, 1]].copy()
    out[tri] = p[tri][:, [0, 2, 1, 3]]
    return out


def revolve(rho, z, segments: int, closed_profile: bool = False):
    """Revolve a profile about the ``z`` axis.

    Parameters
    ----------
    rho, z : (m,) float
        Profile points (``ρ ≥ 0``). A point with ``ρ = 0`` is one vertex (a pole or apex).
        Facets face ``∂θ × ∂profile``: outward for a profile going up at positive ``ρ``
        (counter-clockwise in the ``(ρ, z)`` half-plane).
    segments : int
        Meridians, ``θ_i = 2π i / segments``.
    closed_profile : bool
        The last profile point joins the first (a torus's tube).

    Returns
    -------
    vertices : (V, 3) float64
    polygons : (Q, 4) int64
        Quads between consecutive parallels, triangles at a pole; ``-1`` in column 3.
    """
    rho = np.asarray(rho, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    n = int(segments)
    theta = 2.0 * np.pi * np.arange(n) / n
    c, s = np.cos(theta), np.sin(theta)
    verts, rings = [], []
    count = 0
    for r, h in zip(rho, z, strict=True):
        if r == 0.0:
            verts.append(np.array([[0.0, 0.0, h]]))
            rings.append(np.full(n, count))
            count += 1
        else:
            verts.append(np.column_stack([r * c, r * s, np.full(n, h)]))
            rings.append(count + np.arange(n))
            count += n
    pairs = list(zip(range(len(rho) - 1), range(1, len(rho)), strict=True))
    if closed_profile:
        pairs.append((len(rho) - 1, 0))
    polys = []
    nxt = (np.arange(n) + 1) % n
    for j, k in pairs:
        a, b = rings[j], rings[k]
        pole_a, pole_b = rho[j] == 0.0, rho[k] == 0.0
        if pole_a and pole_b:
            continue
        if pole_a:
            polys.append(np.column_stack([a, b[nxt], b, np.full(n, -1)]))
        elif pole_b:
            polys.append(np.column_stack([a, a[nxt], b, np.full(n, -1)]))
        else:
            polys.append(np.column_stack([a, a[nxt], b[nxt], b]))
    return np.concatenate(verts), np.concatenate(polys).astype(np.int64)


def sphere(radius: float, chord_error: float):
    """Sphere about the origin, facets facing out. Returns ``(vertices, polygons)``."""
    delta = math.sqrt(2.0) * _half_angle(radius, chord_error)
    n_lon = _clamp(2.0 * math.pi / delta)
    n_lat = max(int(math.ceil(math.pi / delta)), MIN_SEGMENTS // 2)
    n_lat = min(n_lat, MAX_SEGMENTS // 2)
    phi = np.linspace(-0.5 * np.pi, 0.5 * np.pi, n_lat + 1)
    rho = radius * np.cos(phi)
    rho[0] = rho[-1] = 0.0
    return revolve(rho, radius * np.sin(phi), n_lon)


def cone(radius0: float, radius1: float, height: float, chord_error: float):
    """Open truncated cone from radius ``radius0`` at ``z = 0`` to ``radius1`` at ``z = height``
    (``radius1 = radius0``: a cylinder; one radius 0: an apex), facets facing out."""
    n = circle_segments(max(radius0, radius1), chord_error)
    return revolve([radius0, radius1], [0.0, height], n)


def disc(radius: float, inner_radius: float, chord_error: float):
    """Disc (``inner_radius = 0``: a fan of triangles) or ring (trapezoids) in ``z = 0``,
    facing ``+z``."""
    n = circle_segments(radius, chord_error)
    return revolve([radius, inner_radius], [0.0, 0.0], n)


def torus(major: float, minor: float, chord_error: float):
    """Torus about the ``z`` axis, tube radius ``minor`` at distance ``major``, facing out."""
    n_u = circle_segments(major + minor, 0.5 * chord_error)
    n_v = circle_segments(minor, 0.5 * chord_error)
    v = 2.0 * np.pi * np.arange(n_v) / n_v
    return revolve(major + minor * np.cos(v), minor * np.sin(v), n_u, closed_profile=True)


# --------------------------------------------------------------------------- Bézier


def _bernstein(t: np.ndarray) -> np.ndarray:
    """``(len(t), 4)`` cubic Bernstein polynomials."""
    t = np.asarray(t, dtype=np.float64)[:, None]
    k = np.arange(4)
    binom = np.array([1.0, 3.0, 3.0, 1.0])
    return binom * t**k * (1.0 - t) ** (3 - k)


def bezier_point(control: np.ndarray, u, v) -> np.ndarray:
    """Points of the bicubic patch ``S(u, v) = Σ B_i(u) B_j(v) P_ij`` on the grid ``u × v``:
    ``(len(u), len(v), 3)``."""
    return np.einsum("ai,bj,ijk->abk", _bernstein(u), _bernstein(v), control)


def bezier_cells(control: np.ndarray, chord_error: float) -> int:
    """Cells along each parameter so that the bilinear cells stay within ``chord_error``."""
    p = np.asarray(control, dtype=np.float64)
    d_uu = np.linalg.norm(p[2:] - 2 * p[1:-1] + p[:-2], axis=-1).max()
    d_vv = np.linalg.norm(p[:, 2:] - 2 * p[:, 1:-1] + p[:, :-2], axis=-1).max()
    d_uv = np.linalg.norm(p[1:, 1:] - p[1:, :-1] - p[:-1, 1:] + p[:-1, :-1], axis=-1).max()
    bound = 6.0 * d_uu + 18.0 * d_uv + 6.0 * d_vv  # 8 h² ε ≥ h²(|S_uu| + 2|S_uv| + |S_vv|)
    k = math.ceil(math.sqrt(bound / (8.0 * chord_error))) if chord_error > 0 else MAX_PATCH_CELLS
    return int(min(max(k, 1), MAX_PATCH_CELLS))


def bezier(control, chord_error: float):
    """Bicubic Bézier patch from a ``(4, 4, 3)`` control net, facing ``∂S/∂u × ∂S/∂v``.

    Cells that are planar and convex stay quads; the others become two triangles."""
    control = np.asarray(control, dtype=np.float64).reshape(4, 4, 3)
    k = bezier_cells(control, chord_error)
    t = np.linspace(0.0, 1.0, k + 1)
    verts = bezier_point(control, t, t).reshape(-1, 3)
    i = (np.arange(k)[:, None] * (k + 1) + np.arange(k)[None, :]).reshape(-1)
    quads = np.column_stack([i, i + (k + 1), i + (k + 1) + 1, i + 1])
    scale = float(np.linalg.norm(verts.max(axis=0) - verts.min(axis=0)))
    polys, _ = faces_to_polygons(verts, quads.reshape(-1), np.full(len(quads), 4), scale)
    return verts, polys.astype(np.int64)


# --------------------------------------------------------------------------- placement


def rotation(degrees_xyz) -> np.ndarray:
    """``(3, 3)`` rotation about ``x``, then ``y``, then ``z`` (degrees, right-handed)."""
    ax, ay, az = np.radians(np.asarray(degrees_xyz, dtype=np.float64))
    cx, sx, cy, sy, cz, sz = np.cos(ax), np.sin(ax), np.cos(ay), np.sin(ay), np.cos(az), np.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def frame(origin, axis) -> np.ndarray:
    """``(4, 4)`` rigid placement taking the local ``z`` axis to ``axis`` at ``origin``."""
    w = np.asarray(axis, dtype=np.float64)
    w = w / np.linalg.norm(w)
    helper = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, w)
    u /= np.linalg.norm(u)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = u, np.cross(w, u), w, origin
    return m


def place(vertices: np.ndarray, polygons: np.ndarray, matrix: np.ndarray):
    """Apply a ``(4, 4)`` affine matrix (column vectors); a mirror reverses the winding back."""
    m = np.asarray(matrix, dtype=np.float64)
    v = vertices @ m[:3, :3].T + m[:3, 3]
    return v, (reverse(polygons) if np.linalg.det(m[:3, :3]) < 0 else polygons)


def max_stretch(matrix: np.ndarray) -> float:
    """Largest factor by which the matrix's linear part stretches a length."""
    return float(np.linalg.svd(np.asarray(matrix, dtype=np.float64)[:3, :3], compute_uv=False)[0])


# --------------------------------------------------------------------------- sidecar shapes

_PARAMS = {
    # type: (required numbers, optional numbers with defaults)
    "sphere": (("radius",), {}),
    "cylinder": (("radius", "height"), {}),
    "cone": (("radius", "height"), {"top_radius": 0.0}),
    "disc": (("radius",), {"inner_radius": 0.0}),
    "ring": (("radius", "inner_radius"), {}),
    "torus": (("major_radius", "minor_radius"), {}),
    "bezier": ((), {}),
}
_COMMON = {"type", "material", "inside", "caps", "translate", "rotate", "scale", "matrix",
           "chord_error", "control_points"}


def _number(table, key, where, path) -> float:
    x = table[key]
    if not (isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)):
        raise SceneError(f"{where}.{key} must be a finite number, got {x!r}", path)
    return float(x)


def _vector(table, key, where, path, n=3) -> np.ndarray:
    x = table[key]
    ok = isinstance(x, list) and len(x) == n and all(
        isinstance(e, int | float) and not isinstance(e, bool) and math.isfinite(e) for e in x)
    if not ok:
        raise SceneError(f"{where}.{key} must be an array of {n} finite numbers, got {x!r}", path)
    return np.array(x, dtype=np.float64)


def _matrix(table, where, path) -> np.ndarray:
    if "matrix" in table:
        if any(k in table for k in ("translate", "rotate", "scale")):
            raise SceneError(f"{where}: give either matrix or translate/rotate/scale", path)
        rows = table["matrix"]
        if not (isinstance(rows, list) and len(rows) == 4 and all(
                isinstance(r, list) and len(r) == 4 for r in rows)):
            raise SceneError(f"{where}.matrix must be 4 rows of 4 numbers", path)
        m = np.array([_vector({"row": r}, "row", f"{where}.matrix", path, 4) for r in rows])
        if not np.allclose(m[3], [0, 0, 0, 1]):
            raise SceneError(f"{where}.matrix: the last row must be [0, 0, 0, 1]", path)
    else:
        m = np.eye(4)
        if "scale" in table:
            s = table["scale"]
            scale = (_vector(table, "scale", where, path) if isinstance(s, list)
                     else np.full(3, _number(table, "scale", where, path)))
            m[:3, :3] = np.diag(scale)
        if "rotate" in table:
            m[:3, :3] = rotation(_vector(table, "rotate", where, path)) @ m[:3, :3]
        if "translate" in table:
            m[:3, 3] = _vector(table, "translate", where, path)
    if not abs(np.linalg.det(m[:3, :3])) > 0:
        raise SceneError(f"{where}: the transform is singular (flattens the shape)", path)
    return m


def parse_shape(table, where: str, path) -> dict:
    """Check one ``[[shape]]`` table of the sidecar; returns a plain dict (see README).

    Keys: ``type`` (one of :data:`SHAPE_TYPES`), ``material`` (a name from the MTL or a
    ``[[material]]``), the type's dimensions, optional ``inside`` (facets face inward),
    ``caps`` (cylinder and cone: close the ends with discs), ``chord_error`` (scene units,
    overriding the scene's default) and a placement: ``translate``/``rotate``/``scale`` (scale,
    then rotate about x, y, z in degrees, then translate) or a 4×4 ``matrix``.
    """
    if not isinstance(table, dict):
        raise SceneError(f"{where} must be a table", path)
    kind = table.get("type")
    if kind not in _PARAMS:
        raise SceneError(f"{where}: type must be one of {', '.join(SHAPE_TYPES)}, got {kind!r}",
                         path)
    required, optional = _PARAMS[kind]
    allowed = _COMMON | set(required) | set(optional)
    unknown = sorted(set(table) - allowed)
    if unknown:
        raise SceneError(f"unknown key {unknown[0]!r} in {where} (type {kind!r} takes: "
                         f"{', '.join(sorted(allowed))})", path)
    if kind != "bezier" and "control_points" in table:
        raise SceneError(f"{where}: control_points is for type \"bezier\"", path)
    if "caps" in table and kind not in ("cylinder", "cone"):
        raise SceneError(f"{where}: caps is for cylinder and cone", path)
    for key in ("material", *required):
        if key not in table:
            raise SceneError(f"{where} needs {key!r}", path)
    if not isinstance(table["material"], str):
        raise SceneError(f"{where}.material must be a material name", path)
    shape = {"type": kind, "material": table["material"], "where": where}
    for key in required:
        shape[key] = _number(table, key, where, path)
    for key, default in optional.items():
        shape[key] = _number(table, key, where, path) if key in table else default
    for key in ("inside", "caps"):
        value = table.get(key, False)
        if not isinstance(value, bool):
            raise SceneError(f"{where}.{key} must be true or false, got {value!r}", path)
        shape[key] = value
    if "chord_error" in table:
        shape["chord_error"] = _number(table, "chord_error", where, path)
        if not shape["chord_error"] > 0:
            raise SceneError(f"{where}.chord_error must be positive", path)
    if kind == "bezier":
        if "control_points" not in table:
            raise SceneError(f"{where} needs 'control_points' (16 points [x, y, z])", path)
        pts = table["control_points"]
        if not (isinstance(pts, list) and len(pts) == 16):
            raise SceneError(f"{where}.control_points must be 16 points [x, y, z] (4 rows of "
                             "4, row by row)", path)
        shape["control_points"] = np.array(
            [_vector({"p": p}, "p", f"{where}.control_points", path) for p in pts]
        ).reshape(4, 4, 3)
    for key in required + tuple(optional):
        if key.endswith("radius") or key == "height":
            value = shape[key]
            positive = key in ("radius", "major_radius", "minor_radius", "height")
            if value < 0 or (positive and value == 0):
                rule = "positive" if positive else "not negative"
                raise SceneError(f"{where}.{key} must be {rule}, got {value!r}", path)
    if kind in ("disc", "ring") and not shape["inner_radius"] < shape["radius"]:
        raise SceneError(f"{where}: inner_radius must be smaller than radius", path)
    if kind == "torus" and not shape["minor_radius"] < shape["major_radius"]:
        raise SceneError(f"{where}: minor_radius must be smaller than major_radius", path)
    shape["matrix"] = _matrix(table, where, path)
    return shape


def _local_corners(shape: dict) -> np.ndarray:
    """``(k, 3)`` points whose hull holds the shape in its local frame."""
    kind = shape["type"]
    if kind == "bezier":
        return shape["control_points"].reshape(-1, 3)  # convex-hull property
    if kind == "sphere":
        r, z0, z1 = shape["radius"], -shape["radius"], shape["radius"]
    elif kind == "torus":
        r = shape["major_radius"] + shape["minor_radius"]
        z0, z1 = -shape["minor_radius"], shape["minor_radius"]
    elif kind in ("disc", "ring"):
        r, z0, z1 = shape["radius"], 0.0, 0.0
    else:
        r, z0, z1 = max(shape["radius"], shape.get("top_radius", 0.0)), 0.0, shape["height"]
    g = np.array(np.meshgrid([-r, r], [-r, r], [z0, z1], indexing="ij")).reshape(3, -1).T
    return g


def shape_bounds(shape: dict) -> np.ndarray:
    """``(2, 3)`` box holding the placed shape (for the scene's size before tessellation)."""
    m = shape["matrix"]
    p = _local_corners(shape) @ m[:3, :3].T + m[:3, 3]
    return np.stack([p.min(axis=0), p.max(axis=0)])


def tessellate(shape: dict, chord_error: float):
    """Vertices and polygons of one parsed shape, placed, to ``chord_error`` (scene units;
    ``shape["chord_error"]`` wins when given). Returns ``(vertices, polygons)``."""
    eps = shape.get("chord_error", chord_error) / max_stretch(shape["matrix"])
    kind = shape["type"]
    if kind == "sphere":
        v, p = sphere(shape["radius"], eps)
    elif kind in ("cylinder", "cone"):
        r0 = shape["radius"]
        r1 = r0 if kind == "cylinder" else shape["top_radius"]
        h = shape["height"]
        v, p = cone(r0, r1, h, eps)
        if shape["caps"]:
            n = circle_segments(max(r0, r1), eps)
            parts = [(v, p)]
            for r, z, flip in ((r0, 0.0, True), (r1, h, False)):
                if r > 0:
                    # the same meridians as the side, so the cap's rim shares its corners' places
                    dv, dp = revolve([r, 0.0], [z, z], n)
                    parts.append((dv, reverse(dp) if flip else dp))
            v, p = _merge(parts)
    elif kind in ("disc", "ring"):
        v, p = disc(shape["radius"], shape["inner_radius"], eps)
    elif kind == "torus":
        v, p = torus(shape["major_radius"], shape["minor_radius"], eps)
    else:
        v, p = bezier(shape["control_points"], eps)
    if shape["inside"]:
        p = reverse(p)
    return place(v, p, shape["matrix"])


def _merge(parts):
    """Concatenate ``(vertices, polygons)`` pieces, offsetting the indices."""
    verts, polys, offset = [], [], 0
    for v, p in parts:
        verts.append(v)
        polys.append(np.where(p >= 0, p + offset, -1))
        offset += len(v)
    return np.concatenate(verts), np.concatenate(polys)

