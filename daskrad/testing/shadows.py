"""Scenes with hard lights, written from ``scenes/cornell_box.obj`` (issue 14); shared by
``tests/test_shadows.py`` and ``benchmarks/bench_shadows.py``.

Each builder writes an OBJ, its MTL and a TOML sidecar (camera and light) into a directory the
caller owns (a pytest ``tmp_path``, a temporary directory), so nothing generated lands in the
repository. The Cornell box's groups are read from its OBJ by name: ``ceiling`` (eight quads
around the light's hole), ``light`` (the emitting quad filling that hole), walls, floor, blocks.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np

SCENES = Path(__file__).resolve().parents[2] / "scenes"   # the source checkout's
CORNELL = SCENES / "cornell_box.obj"

#: The sun of issue 14: irradiance 3 W/m² (on a surface facing it), travelling along
#: normalize(0.3, −1, 0.25), through the open top of the box.
SUN_DIRECTION = (0.3, -1.0, 0.25)
SUN_IRRADIANCE = (3.0, 3.0, 3.0)

#: A point light inside the closed box, in place of the area light (W/sr). ``Ke · 11,000``
#: of the ceiling light: about the area light's irradiance on the floor below (1.1e4 mm² ≈
#: a quarter of its 130 × 105 mm area, the 1/4π of the power a point light spreads evenly).
POINT_POSITION = (278.0, 450.0, 279.6)
POINT_INTENSITY = (187_000.0, 132_000.0, 44_000.0)

#: A point light above the closed box's ceiling (y = 548.8), outside the room.
OUTSIDE_POSITION = (278.0, 700.0, 279.6)


def _camera_toml() -> str:
    text = (SCENES / "cornell_box.toml").read_text()
    return text[text.index("[camera]"):]


def _groups(path: Path = CORNELL) -> tuple[list[str], dict[str, list[str]]]:
    """``(header lines up to the first group, {group: its lines})`` of an OBJ, in order."""
    header, groups, current = [], {}, None
    for line in path.read_text().splitlines():
        if line.startswith("g "):
            current = line[2:].strip()
            groups[current] = [line]
        elif current is None:
            header.append(line)
        else:
            groups[current].append(line)
    return header, groups


def _write(directory: Path, name: str, header, groups, toml: str) -> Path:
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(SCENES / "cornell_box.mtl", directory / "cornell_box.mtl")
    lines = [ln for ln in header if not ln.startswith("#")]
    for g in groups.values():
        lines += g
    obj = directory / f"{name}.obj"
    obj.write_text("\n".join(lines) + "\n")
    obj.with_suffix(".toml").write_text(toml)
    return obj


def _light_toml(kind: str, a, b) -> str:
    if kind == "point":
        return (f'\n[[light]]\ntype = "point"\nposition = {list(map(float, a))}\n'
                f"intensity = {list(map(float, b))}\n")
    return (f'\n[[light]]\ntype = "directional"\ndirection = {list(map(float, a))}\n'
            f"irradiance = {list(map(float, b))}\n")


def open_box_sun(directory) -> Path:
    """The Cornell box without its ceiling and light, lit by the sun through the open top."""
    header, groups = _groups()
    del groups["ceiling"], groups["light"]
    d = np.asarray(SUN_DIRECTION) / np.linalg.norm(SUN_DIRECTION)
    return _write(directory, "open_box_sun", header, groups,
                  _camera_toml() + _light_toml("directional", d, SUN_IRRADIANCE))


def closed_box(groups) -> dict:
    """The groups with the light quad made white ceiling: a closed box, no emitter."""
    groups = dict(groups)
    groups["light"] = [("usemtl white" if ln.startswith("usemtl") else ln)
                       for ln in groups["light"]]
    return groups


def closed_box_point(directory, position=POINT_POSITION, intensity=POINT_INTENSITY,
                     name: str = "closed_box_point") -> Path:
    """The closed Cornell box (its light quad white ceiling) lit by one point light."""
    header, groups = _groups()
    return _write(directory, name, header, closed_box(groups),
                  _camera_toml() + _light_toml("point", position, intensity))


def closed_box_outside(directory) -> Path:
    """The closed box with a point light above its ceiling: no surface inside can be lit."""
    return closed_box_point(directory, OUTSIDE_POSITION, POINT_INTENSITY,
                            name="closed_box_outside")


def block_feet(path: Path = CORNELL) -> list[np.ndarray]:
    """``[(4, 3) float64]``: the floor corners of each block of the Cornell box (its
    ``short_block`` and ``tall_block`` side faces' corners at ``y = 0``), in order around it."""
    verts = []
    feet = []
    _, groups = _groups(path)
    for line in path.read_text().splitlines():
        if line.startswith("v "):
            verts.append([float(x) for x in line.split()[1:4]])
    verts = np.array(verts)
    for name in ("short_block", "tall_block"):
        ids = []
        for ln in groups[name]:
            if ln.startswith("f "):
                ids += [int(t.split("/")[0]) - 1 for t in ln.split()[1:]]
        pts = np.unique(verts[ids][verts[ids][:, 1] == 0.0], axis=0)
        c = pts.mean(axis=0)
        order = np.argsort(np.arctan2(pts[:, 2] - c[2], pts[:, 0] - c[0]))
        feet.append(pts[order])
    return feet


def sun_direction() -> np.ndarray:
    d = np.asarray(SUN_DIRECTION, float)
    return d / math.sqrt(float(d @ d))
