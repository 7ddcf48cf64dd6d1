"""MGF, Greg Ward's Materials and Geometry Format (issue 16, item 2), read directly.

The radiosity literature's test scenes (RenderPark's, the LBL and TU Graz offices) are MGF.
What is read, following the specification (``mgfdoc``, version 1.0, LBL 1995):

* **entities** one per line, ``\\`` at the end of a line continues it, ``#`` is a comment;
* **named contexts** ``v``/``c``/``m`` with the four forms ``v``, ``v id``, ``v id =``,
  ``v id = template`` (the unnamed context starts from the defaults every time). Geometry takes
  the values in effect *when it is read*: changing a vertex or material later does not change
  earlier faces;
* **vertices** ``p``, ``n``; positions and normals are transformed by the transform in effect
  where the vertex is *used*, not where it was defined;
* **geometry** ``f`` (any corner count; concave faces are ear-clipped), ``sph``, ``cyl``,
  ``cone``, ``ring``, ``torus`` (tessellated by :mod:`daskrad.scene.shapes` to
  ``tolerances.CHORD_ERROR`` of the scene's diagonal; a negative radius faces inward) and
  ``prism`` (the end face outward, extruded against its normal; a negative length faces
  inward);
* **transforms** ``xf`` with ``-t -rx -ry -rz -s -mx -my -mz -i N -a N`` (arguments act in
  order; an enclosed transform is applied before the enclosing one; ``-a N`` repeats the
  enclosed entities N times); a mirroring transform keeps faces facing the way the file
  meant (their winding is reversed back);
* **includes** ``i file [transform]``, relative to the including file;
* **materials**: ``rd`` (diffuse reflectance) and ``ed`` (diffuse emittance, lm/m²) in the
  colour in effect (``c``, ``cxy``), ``sides``. Colour and units as RenderPark (and the shared
  scenes' converted OBJs): CIE xy → RGB with the primaries (0.64, 0.33), (0.29, 0.60),
  (0.15, 0.06) and the equal-energy white (1/3, 1/3), negative channels clipped;
  ``Kd = rd · rgb``, ``Ke = ed · rgb / (183.07 · π)`` (183.07 lm/W is the efficacy of
  equal-energy white; dividing by π turns the exitance into the radiance ``Ke`` is).
  ``rs``/``ts``/``td`` are dropped with one warning (daskrad's surfaces are diffuse), ``ir``
  is ignored;
* **sides**: MGF's default is two-sided, a property of the material here
  (``Scene.back_material``; the mesher gives the back a face of its own,
  :func:`daskrad.mesh.one_sided`). The sidecar's ``[mgf] one_sided = true`` makes every face
  one-sided (as RenderPark runs its examples).

Not supported: ``cspec``, ``cct``, ``cmix`` (only CIE xy colours) and ``ies`` luminaires are
refused with one line; unknown entities are skipped with one warning, as the specification's
standard parser does (the TU Graz office has stray lines of an exporter's comments).

Faces are numbered (for messages) in the order the geometric entities are read.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from daskrad import tolerances
from daskrad.errors import DaskradWarning, SceneError
from daskrad.scene import shapes as shp
from daskrad.scene.files import read_text
from daskrad.scene.polygons import faces_to_polygons

#: A reflectance whose RGB reaches 1 (``rd 1``, or a colour brighter in one channel than its
#: luminance) is scaled down to this largest channel: daskrad needs ``Kd < 1`` (a closed
#: scene would never converge), and the shared scenes' converted OBJs did the same.
MAX_REFLECTANCE = 0.999

#: Luminous efficacy of equal-energy white light, lm/W (RenderPark's ``WHITE_EFFICACY``).
WHITE_EFFICACY = 183.07


def _xyz_to_rgb() -> np.ndarray:
    """``(3, 3)``: CIE XYZ → RGB for the primaries above and white (1/3, 1/3)."""
    prim = np.array([[0.64, 0.33], [0.29, 0.60], [0.15, 0.06]])
    p = np.stack([prim[:, 0] / prim[:, 1], np.ones(3), (1 - prim.sum(axis=1)) / prim[:, 1]])
    white = np.array([1.0, 1.0, 1.0])  # x = y = 1/3: X = Y = Z
    return np.linalg.inv(p * np.linalg.solve(p, white))


XYZ_TO_RGB = _xyz_to_rgb()


def xy_to_rgb(cx: float, cy: float) -> np.ndarray:
    """``(3,)`` RGB of unit luminance (Y = 1) and chromaticity ``(cx, cy)``, clipped at 0."""
    xyz = np.array([cx / cy, 1.0, (1.0 - cx - cy) / cy])
    return np.maximum(XYZ_TO_RGB @ xyz, 0.0)


@dataclass
class MgfData:
    """What an MGF file (and its includes) holds, as input polygons.

    vertices : (V, 3) float64, world coordinates (transforms applied)
    polygons : (Q, 4) int64, ``-1`` in column 3 for triangles
    polygon_material : (Q,) int64
    polygon_face : (Q,) int64, the geometric entity each polygon came from (0-based)
    names : list of M str
    diffuse, emission : (M, 3) float64, ``Kd`` and ``Ke`` (radiance)
    two_sided : (M,) bool, materials whose faces are two-sided (MGF's ``sides 2``, the
        default): a property of the scene (:func:`daskrad.scene.validate.scene_from_arrays`)
    """

    vertices: np.ndarray
    polygons: np.ndarray
    polygon_material: np.ndarray
    polygon_face: np.ndarray
    names: list
    diffuse: np.ndarray
    emission: np.ndarray
    two_sided: np.ndarray | None = None


# --------------------------------------------------------------------------- contexts


class _Vertex:
    __slots__ = ("p", "n", "serial", "version")
    count = 0

    def __init__(self, template: _Vertex | None = None):
        _Vertex.count += 1
        self.serial = _Vertex.count
        self.version = 0
        self.p = (0.0, 0.0, 0.0) if template is None else template.p
        self.n = (0.0, 0.0, 0.0) if template is None else template.n


@dataclass
class _Color:
    cx: float = 1.0 / 3.0
    cy: float = 1.0 / 3.0

    def copy(self) -> _Color:
        return _Color(self.cx, self.cy)


@dataclass
class _Material:
    kd: tuple = (0.0, 0.0, 0.0)
    ke: tuple = (0.0, 0.0, 0.0)
    sides: int = 2
    dropped: set = field(default_factory=set)  # of "rs", "ts", "td" with a nonzero value

    def copy(self) -> _Material:
        return _Material(self.kd, self.ke, self.sides, set(self.dropped))


# --------------------------------------------------------------------------- transforms


def _axis_rotation(axis: int, degrees: float) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    m = np.eye(4)
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


_FLAGS = {"-t": 3, "-rx": 1, "-ry": 1, "-rz": 1, "-s": 1, "-mx": 0, "-my": 0, "-mz": 0,
          "-i": 1, "-a": 1}


def _parse_xform(args: list[str], err) -> list[tuple[str, int, np.ndarray]]:
    """Transform arguments → groups ``(kind, N, matrix)``: ``kind`` ``"i"`` (apply ``N``
    times) or ``"a"`` (an array of ``N`` instances: applied 0 … N−1 times). Arguments act in
    order, each on the result of the previous ones."""
    groups = [["i", 1, np.eye(4)]]
    k = 0
    while k < len(args):
        flag = args[k]
        if flag not in _FLAGS:
            err(f"unknown transform argument {flag!r} (expected -t -rx -ry -rz -s -mx -my -mz "
                "-i -a)")
        n = _FLAGS[flag]
        if n and k + n >= len(args):
            err(f"transform argument {flag} needs {n} number{'s' if n > 1 else ''}")
        vals = [_number(a, f"{flag}", err) for a in args[k + 1: k + 1 + n]]
        k += 1 + n
        if flag in ("-i", "-a"):
            count = vals[0]
            if count != int(count) or count < (1 if flag == "-a" else 0):
                err(f"{flag} needs a positive whole number, got {args[k - 1]!r}")
            groups.append([flag[1], int(count), np.eye(4)])
            continue
        m = np.eye(4)
        if flag == "-t":
            m[:3, 3] = vals
        elif flag == "-s":
            if vals[0] == 0:
                err("-s 0 flattens everything to a point")
            m[:3, :3] *= vals[0]
        elif flag in ("-rx", "-ry", "-rz"):
            m = _axis_rotation("xyz".index(flag[2]), vals[0])
        else:
            m[(("-mx", "-my", "-mz").index(flag),) * 2] = -1.0
        groups[-1][2] = m @ groups[-1][2]
    return [tuple(g) for g in groups]


def _instances(groups) -> list[np.ndarray]:
    """Every instance's matrix (one unless the transform has ``-a``), in array order."""
    out = [np.eye(4)]
    for kind, n, m in groups:
        if kind == "i":
            p = np.linalg.matrix_power(m, n)
            out = [p @ o for o in out]
        else:
            powers = [np.linalg.matrix_power(m, k) for k in range(n)]
            out = [p @ o for o in out for p in powers]
    return out


def _number(token: str, what: str, err) -> float:
    try:
        x = float(token)
    except ValueError:
        err(f"{what}: {token!r} is not a number")
    if not math.isfinite(x):
        err(f"{what}: {token!r} is not a finite number")
    return x


# --------------------------------------------------------------------------- reading


def _entities(path: Path, err_path) -> list[tuple[int, list[str]]]:
    """``(line number, tokens)`` of every entity of one file (continuations joined)."""
    text = read_text(path, "MGF file", name=err_path)
    lines = text.replace("\r\n", "\n").replace("\r", "\n")
    out, pending, start = [], [], 0
    for lineno, raw in enumerate(lines.split("\n"), start=1):
        if not pending:
            start = lineno
        text = raw.rstrip()
        cont = text.endswith("\\")
        pending.append(text[:-1] if cont else text)
        if cont:
            continue
        tokens = " ".join(pending).split()
        pending = []
        if tokens and not tokens[0].startswith("#"):
            out.append((start, tokens))
    if pending:
        tokens = " ".join(pending).split()
        if tokens and not tokens[0].startswith("#"):
            out.append((start, tokens))
    return out


class _Reader:
    """The interpreter: walks entities with the MGF contexts, collecting faces."""

    def __init__(self, one_sided: bool):
        self.one_sided = one_sided
        self.vertices: dict[str, _Vertex] = {}
        self.colors: dict[str, _Color] = {}
        self.materials: dict[str, _Material] = {}
        self.vertex = _Vertex()
        self.color = _Color()
        self.material = _Material()
        self.material_name = "(unnamed)"
        self.stack = [(np.eye(4), 0)]  # (matrix, serial)
        self.xf_serial = 0
        self.files: dict[Path, list] = {}
        self.including: list[Path] = []
        # output
        self.points: list[np.ndarray] = []
        self.vertex_index: dict[tuple, int] = {}
        self.flat: list[int] = []
        self.counts: list[int] = []
        self.face_entity: list[int] = []
        self.face_mat: list[int] = []
        self.prims: list[tuple] = []  # (kind, args, matrix, material row, entity)
        self.mat_rows: dict[tuple, int] = {}
        self.mat_table: list[tuple] = []  # (name, kd, ke, sides, dropped)
        self.entity = 0
        self.unknown: list[tuple] = []
        self.file = Path()
        self.line = 0

    # -- helpers
    def err(self, message: str):
        raise SceneError(f"line {self.line}: {message}", self.file)

    def num(self, token: str, what: str) -> float:
        return _number(token, what, self.err)

    def lookup_vertex(self, name: str) -> _Vertex:
        v = self.vertices.get(name)
        if v is None:
            self.err(f"vertex {name!r} is not defined")
        return v

    def matrix(self) -> np.ndarray:
        return self.stack[-1][0]

    def point_index(self, v: _Vertex) -> int:
        key = (v.serial, v.version, self.stack[-1][1])
        idx = self.vertex_index.get(key)
        if idx is None:
            m = self.matrix()
            idx = len(self.points)
            self.points.append(m[:3, :3] @ np.array(v.p) + m[:3, 3])
            self.vertex_index[key] = idx
        return idx

    def material_row(self) -> int:
        m = self.material
        sides = 1 if self.one_sided else m.sides
        key = (self.material_name, m.kd, m.ke, sides)
        row = self.mat_rows.get(key)
        if row is None:
            row = len(self.mat_table)
            names = [t[0] for t in self.mat_table]
            name = self.material_name
            if name in names:  # the same name with other values (redefined or modified later)
                name = f"{name}#{row}"
            self.mat_table.append((name, m.kd, m.ke, sides, frozenset(m.dropped)))
            self.mat_rows[key] = row
        return row

    def add_face(self, points: list[int] | np.ndarray, row: int):
        flip = np.linalg.det(self.matrix()[:3, :3]) < 0
        corners = list(points)[::-1] if flip else list(points)
        self.flat.extend(corners)
        self.counts.append(len(corners))
        self.face_entity.append(self.entity)
        self.face_mat.append(row)

    # -- files and transforms
    def run_file(self, path: Path, where: Path | None = None):
        resolved = path.resolve()
        if resolved in self.including:
            self.err(f"include loop: {path.name} includes itself (through "
                     f"{' -> '.join(p.name for p in self.including)})")
        if resolved not in self.files:
            self.files[resolved] = _entities(path, path if where is None else where)
        outer = (self.file, self.line)
        self.including.append(resolved)
        self.file = path
        entities = self.files[resolved]
        self.run_range(entities, 0, len(entities))
        self.including.pop()
        self.file, self.line = outer

    def matching_end(self, entities, start: int, end: int) -> int:
        depth = 0
        for k in range(start, end):
            tokens = entities[k][1]
            if tokens[0] == "xf":
                depth += 1 if len(tokens) > 1 else -1
                if depth == 0:
                    return k
        self.line = entities[start][0]
        self.err("xf has no matching end (a line 'xf' alone) in this file")

    def with_transform(self, args: list[str], body):
        for m in _instances(_parse_xform(args, self.err)):
            self.xf_serial += 1
            self.stack.append((self.matrix() @ m, self.xf_serial))
            body()
            self.stack.pop()

    def run_range(self, entities, start: int, end: int):
        k = start
        while k < end:
            self.line, tokens = entities[k]
            key = tokens[0]
            if key == "xf":
                if len(tokens) == 1:
                    self.err("xf end without a matching xf in this file")
                stop = self.matching_end(entities, k, end)
                line = self.line
                self.with_transform(tokens[1:],
                                    lambda a=k + 1, b=stop: self.run_range(entities, a, b))
                self.line = line
                k = stop + 1
                continue
            self.entity_(key, tokens[1:])
            k += 1

    # -- entities
    def entity_(self, key: str, args: list[str]):
        handler = _HANDLERS.get(key)
        if handler is None:
            self.unknown.append((self.file, self.line, key))
            return
        handler(self, args)

    def e_include(self, args):
        if not args:
            self.err("i needs a file name")
        target = self.file.parent / args[0]
        if not target.is_file():
            self.err(f"included file {args[0]!r} not found (looked for {target})")
        line = self.line
        self.with_transform(args[1:], lambda: self.run_file(target))
        self.line = line

    def _context(self, args, table: dict, fresh, what: str):
        """The four forms of a named context; returns (object, name)."""
        if not args:
            return fresh(None), None
        name = args[0]
        if len(args) == 1:
            if name not in table:
                self.err(f"{what} {name!r} is not defined")
            return table[name], name
        if args[1] != "=" or len(args) > 3:
            self.err(f"expected '{what[0]} {name} = [template]', got {' '.join(args)!r}")
        if len(args) == 3:
            if args[2] not in table:
                self.err(f"{what} {args[2]!r} (template) is not defined")
            obj = fresh(table[args[2]])
        else:
            obj = fresh(None)
        table[name] = obj
        return obj, name

    def e_v(self, args):
        self.vertex, _ = self._context(args, self.vertices, lambda t: _Vertex(t), "vertex")

    def _triple(self, args, what):
        if len(args) != 3:
            self.err(f"{what} needs 3 numbers, got {len(args)}")
        return tuple(self.num(a, what) for a in args)

    def e_p(self, args):
        self.vertex.p = self._triple(args, "p")
        self.vertex.version += 1

    def e_n(self, args):
        self.vertex.n = self._triple(args, "n")
        self.vertex.version += 1

    def e_c(self, args):
        self.color, _ = self._context(
            args, self.colors, lambda t: _Color() if t is None else t.copy(), "color")

    def e_cxy(self, args):
        if len(args) != 2:
            self.err(f"cxy needs 2 numbers, got {len(args)}")
        x, y = (self.num(a, "cxy") for a in args)
        if not (x >= 0 and y > 0 and x + y <= 1):
            self.err(f"cxy {x} {y} is not a chromaticity (x >= 0, y > 0, x + y <= 1)")
        self.color.cx, self.color.cy = x, y

    def e_unsupported_color(self, args):
        self.err("only CIE xy colours (cxy) are supported, not cspec, cct or cmix")

    def e_m(self, args):
        self.material, name = self._context(
            args, self.materials, lambda t: _Material() if t is None else t.copy(), "material")
        self.material_name = name or "(unnamed)"

    def _one(self, args, what):
        if len(args) != 1:
            self.err(f"{what} needs 1 number, got {len(args)}")
        return self.num(args[0], what)

    def e_rd(self, args):
        rho = self._one(args, "rd")
        if not 0 <= rho <= 1:
            self.err(f"rd {rho} is outside [0, 1]")
        kd = rho * xy_to_rgb(self.color.cx, self.color.cy)
        if kd.max() >= 1.0:
            kd *= MAX_REFLECTANCE / kd.max()
            self.material.dropped.add("rd>=1")
        else:
            self.material.dropped.discard("rd>=1")
        self.material.kd = tuple(kd.tolist())

    def e_ed(self, args):
        e = self._one(args, "ed")
        if e < 0:
            self.err(f"ed {e} is negative")
        rgb = xy_to_rgb(self.color.cx, self.color.cy)
        self.material.ke = tuple((e * rgb / (WHITE_EFFICACY * math.pi)).tolist())

    def e_ir(self, args):
        if len(args) != 2:
            self.err(f"ir needs 2 numbers, got {len(args)}")
        for a in args:
            self.num(a, "ir")

    def e_sides(self, args):
        if args not in (["1"], ["2"]):
            self.err(f"sides must be 1 or 2, got {' '.join(args)!r}")
        self.material.sides = int(args[0])

    def e_o(self, args):
        pass  # object names group surfaces for the user; nothing to compute

    def e_ies(self, args):
        self.err("ies luminaires are not supported")

    def e_f(self, args):
        if len(args) < 3:
            self.err(f"a face needs at least 3 vertices, got {len(args)}")
        idx = [self.point_index(self.lookup_vertex(a)) for a in args]
        self.entity += 1
        self.add_face(idx, self.material_row())

    def e_prism(self, args):
        if len(args) < 4:
            self.err("prism needs at least 3 vertices and a length")
        length = self.num(args[-1], "prism length")
        if length == 0:
            self.err("prism length must not be zero")
        p = np.array([self.lookup_vertex(a).p for a in args[:-1]], dtype=np.float64)
        normal = 0.5 * np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0)
        norm = np.linalg.norm(normal)
        if not norm > 0:
            self.err("prism end face has no area")
        q = p - length * normal / norm
        m = self.matrix()
        base = len(self.points)
        self.points.extend(m[:3, :3] @ x + m[:3, 3] for x in np.concatenate([p, q]))
        n = len(p)
        row = self.material_row()
        self.entity += 1
        a = base + np.arange(n)
        b = a + n
        self.add_face(a, row)
        self.add_face(b[::-1], row)
        for i in range(n):
            j = (i + 1) % n
            self.add_face([a[i], b[i], b[j], a[j]], row)

    def _prim(self, kind, args, nargs, names):
        if len(args) != nargs:
            self.err(f"{kind} needs {nargs} arguments ({names}), got {len(args)}")
        self.entity += 1
        return args

    def _push_prim(self, kind, params):
        self.prims.append((kind, params, self.matrix().copy(), self.material_row(), self.entity))

    def e_sph(self, args):
        a = self._prim("sph", args, 2, "centre radius")
        v, r = self.lookup_vertex(a[0]), self.num(a[1], "sph radius")
        if r == 0:
            self.err("sph radius must not be zero")
        self._push_prim("sph", (np.array(v.p), r))

    def e_cyl(self, args):
        a = self._prim("cyl", args, 3, "v1 radius v2")
        v1, r, v2 = self.lookup_vertex(a[0]), self.num(a[1], "cyl radius"), self.lookup_vertex(a[2])
        if r == 0:
            self.err("cyl radius must not be zero")
        self._cone_like("cyl", v1, r, v2, r)

    def e_cone(self, args):
        a = self._prim("cone", args, 4, "v1 radius1 v2 radius2")
        v1, v2 = self.lookup_vertex(a[0]), self.lookup_vertex(a[2])
        r1, r2 = self.num(a[1], "cone radius1"), self.num(a[3], "cone radius2")
        if r1 * r2 < 0:
            self.err("cone radii must not have opposite signs")
        if r1 == 0 and r2 == 0:
            self.err("cone radii must not both be zero")
        self._cone_like("cone", v1, r1, v2, r2)

    def _cone_like(self, kind, v1, r1, v2, r2):
        p1, p2 = np.array(v1.p), np.array(v2.p)
        if not np.linalg.norm(p2 - p1) > 0:
            self.err(f"{kind} ends are the same point")
        self._push_prim("cone", (p1, p2, r1, r2))

    def _centre_normal(self, kind, name):
        v = self.lookup_vertex(name)
        n = np.array(v.n)
        if not np.linalg.norm(n) > 0:
            self.err(f"{kind} centre vertex {name!r} has no normal (n)")
        return np.array(v.p), n

    def e_ring(self, args):
        a = self._prim("ring", args, 3, "centre rmin rmax")
        c, n = self._centre_normal("ring", a[0])
        rmin, rmax = self.num(a[1], "ring rmin"), self.num(a[2], "ring rmax")
        if not 0 <= rmin < rmax:
            self.err(f"ring radii must satisfy 0 <= rmin < rmax, got {rmin} {rmax}")
        self._push_prim("ring", (c, n, rmin, rmax))

    def e_torus(self, args):
        a = self._prim("torus", args, 3, "centre rmin rmax")
        c, n = self._centre_normal("torus", a[0])
        rmin, rmax = self.num(a[1], "torus rmin"), self.num(a[2], "torus rmax")
        inward = rmax < 0
        ok = (rmin <= 0 and -rmax > -rmin) if inward else (0 <= rmin < rmax)
        if not ok:
            self.err(f"torus radii must satisfy 0 <= rmin < rmax (or both negative for an "
                     f"inward torus), got {rmin} {rmax}")
        self._push_prim("torus", (c, n, abs(rmin), abs(rmax), inward))


def _dropped(key: str):
    """Handler of ``rs``/``ts``/``td``: checked, then only remembered for one warning."""
    n = 1 if key == "td" else 2

    def handler(self: _Reader, args):
        if len(args) != n:
            self.err(f"{key} needs {n} number{'s' if n > 1 else ''}, got {len(args)}")
        vals = [self.num(a, key) for a in args]
        if vals[0] > 0:
            self.material.dropped.add(key)
        else:
            self.material.dropped.discard(key)
    return handler


_HANDLERS = {
    "i": _Reader.e_include, "v": _Reader.e_v, "p": _Reader.e_p, "n": _Reader.e_n,
    "c": _Reader.e_c, "cxy": _Reader.e_cxy, "cspec": _Reader.e_unsupported_color,
    "cct": _Reader.e_unsupported_color, "cmix": _Reader.e_unsupported_color,
    "m": _Reader.e_m, "rd": _Reader.e_rd, "ed": _Reader.e_ed, "rs": _dropped("rs"),
    "ts": _dropped("ts"), "td": _dropped("td"), "ir": _Reader.e_ir,
    "sides": _Reader.e_sides, "o": _Reader.e_o, "ies": _Reader.e_ies, "f": _Reader.e_f,
    "prism": _Reader.e_prism, "sph": _Reader.e_sph, "cyl": _Reader.e_cyl,
    "cone": _Reader.e_cone, "ring": _Reader.e_ring, "torus": _Reader.e_torus,
}


# --------------------------------------------------------------------------- assembly


def _primitive(kind, params, eps):
    """Local ``(vertices, polygons)`` and the placement of one MGF primitive."""
    if kind == "sph":
        centre, r = params
        v, p = shp.sphere(abs(r), eps)
        return v, (shp.reverse(p) if r < 0 else p), shp.frame(centre, (0.0, 0.0, 1.0))
    if kind == "cone":
        p1, p2, r1, r2 = params
        v, p = shp.cone(abs(r1), abs(r2), float(np.linalg.norm(p2 - p1)), eps)
        return v, (shp.reverse(p) if r1 < 0 or r2 < 0 else p), shp.frame(p1, p2 - p1)
    if kind == "ring":
        centre, normal, rmin, rmax = params
        v, p = shp.disc(rmax, rmin, eps)
        return v, p, shp.frame(centre, normal)
    centre, normal, rmin, rmax, inward = params
    v, p = shp.torus(0.5 * (rmin + rmax), 0.5 * (rmax - rmin), eps)
    return v, (shp.reverse(p) if inward else p), shp.frame(centre, normal)


def _prim_bounds(kind, params, m) -> np.ndarray:
    """``(k, 3)`` world points whose box holds the primitive (its centre(s) ± its radius)."""
    if kind == "sph":
        pts, r = [params[0]], abs(params[1])
    elif kind == "cone":
        pts, r = [params[0], params[1]], max(abs(params[2]), abs(params[3]))
    else:
        pts, r = [params[0]], abs(params[3])
    pts = np.array(pts) @ m[:3, :3].T + m[:3, 3]
    r *= shp.max_stretch(m)
    return np.concatenate([pts - r, pts + r])


def read_mgf(path: str | Path, one_sided: bool = False) -> MgfData:
    """Read an MGF file and its includes into input polygons (see the module docstring).

    Raises
    ------
    SceneError
        ``file: line N: problem`` for an undefined vertex, material or colour, a bad number
        or argument count, an unsupported entity (``cspec``, ``cct``, ``cmix``, ``ies``), a
        missing include, an include loop, an unbalanced ``xf``; ``no faces`` for a file
        without geometry.
    """
    path = Path(path)
    reader = _Reader(one_sided)
    reader.run_file(path)

    if reader.unknown:
        f, line, key = reader.unknown[0]
        more = f" and {len(reader.unknown) - 1} more" if len(reader.unknown) > 1 else ""
        warnings.warn(f"{f}: line {line}: unknown MGF entity {key!r} skipped{more}",
                      DaskradWarning, stacklevel=2)
    if not reader.counts and not reader.prims:
        raise SceneError("no faces in the file", path)

    points = np.array(reader.points, dtype=np.float64).reshape(-1, 3)
    boxes = [points] + [_prim_bounds(k, prm, m) for k, prm, m, _, _ in reader.prims]
    allpts = np.concatenate(boxes)
    if not np.isfinite(allpts).all():
        raise SceneError("coordinates are not finite after the transforms", path)
    diag = float(np.linalg.norm(allpts.max(axis=0) - allpts.min(axis=0)))

    flat = np.array(reader.flat, dtype=np.int64)
    counts = np.array(reader.counts, dtype=np.int64)
    if len(counts):
        polys, which = faces_to_polygons(points, flat, counts, diag)
        mat = np.array(reader.face_mat, dtype=np.int64)[which]
        face = np.array(reader.face_entity, dtype=np.int64)[which] - 1
    else:
        polys, mat, face = np.zeros((0, 4), np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    parts_v, parts_p, parts_m, parts_f = [points], [polys.astype(np.int64)], [mat], [face]
    offset = len(points)
    eps = tolerances.CHORD_ERROR * diag
    for kind, params, m, row, entity in reader.prims:
        v, p, local = _primitive(kind, params, eps / shp.max_stretch(m))
        v, p = shp.place(v, p, m @ local)
        parts_v.append(v)
        parts_p.append(np.where(p >= 0, p + offset, -1))
        parts_m.append(np.full(len(p), row))
        parts_f.append(np.full(len(p), entity - 1))
        offset += len(v)
    vertices = np.concatenate(parts_v)
    polygons = np.concatenate(parts_p)
    material = np.concatenate(parts_m)
    face = np.concatenate(parts_f)

    table = reader.mat_table
    two_sided = np.array([t[3] == 2 for t in table], dtype=bool)
    used = np.unique(material)
    clamped = [table[r][0] for r in used if "rd>=1" in table[r][4]]
    if clamped:
        warnings.warn(f"{path}: diffuse reflectance of {len(clamped)} materials reaches 1 in "
                      f"a channel (first: {clamped[0]!r}): scaled down to "
                      f"{MAX_REFLECTANCE}", DaskradWarning, stacklevel=2)
    dropped = sorted({k for r in used for k in table[r][4] if k != "rd>=1"})
    if dropped:
        n = sum(1 for r in used if table[r][4] - {"rd>=1"})
        warnings.warn(f"{path}: {', '.join(dropped)} (specular/transmission) of {n} materials "
                      "ignored: daskrad's surfaces are diffuse", DaskradWarning, stacklevel=2)
    return MgfData(
        vertices=vertices,
        polygons=polygons,
        polygon_material=material,
        polygon_face=face,
        names=[t[0] for t in table],
        diffuse=np.array([t[1] for t in table], dtype=np.float64).reshape(-1, 3),
        emission=np.array([t[2] for t in table], dtype=np.float64).reshape(-1, 3),
        two_sided=two_sided,
    )
