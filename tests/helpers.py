"""Everything the test modules share, in this one module (test modules import nothing from
each other): paths, exact answers, scenes with known shadows, bit-for-bit run comparison and
the render context of a solved scene. The geometry builders are :mod:`daskrad.testing`'s
(shared with the benchmarks), re-exported here.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from daskrad import direct, render, solve
from daskrad.distributed.executor import InProcess
from daskrad.io import read_exr
from daskrad.kernels.hemisphere import disc_pixels
from daskrad.preprocess import preprocess
from daskrad.run import solve_scene
from daskrad.scene import load_scene, scene_from_arrays
from daskrad.settings import Settings
from daskrad.testing import closed_box, grid, merge, square_above, triangle_soup

__all__ = [
    "CORNELL", "ORIGIN", "REPO", "SCENES", "SMALL_RUN", "UP", "assert_same_run",
    "blocker_scene", "closed_box", "corner_rectangle", "grid", "in_shadow", "merge",
    "projected_perimeter_px", "raster_bound", "render_context", "square_above", "steps_on",
    "store_arrays", "triangle_soup",
]


REPO = Path(__file__).resolve().parent.parent
#: The bundled scenes (also the ``scenes_dir`` fixture of conftest.py).
SCENES = REPO / "scenes"
CORNELL = SCENES / "cornell_box.obj"

#: The shooter of the single-point form-factor tests: the origin, facing +z.
ORIGIN = np.zeros(3)
UP = np.array([0.0, 0.0, 1.0])


# --- exact answers --------------------------------------------------------------------------

def corner_rectangle(a, b, c):
    """Differential area to a parallel a × b rectangle with one corner straight above at c."""
    ra, rb = a / c, b / c
    sa, sb = math.sqrt(1 + ra * ra), math.sqrt(1 + rb * rb)
    return (ra / sa * math.atan(rb / sa) + rb / sb * math.atan(ra / sb)) / (2 * math.pi)


def projected_perimeter_px(corners, resolution, point=ORIGIN, normal=UP):
    """Length in pixels of the projected outline of the part of a polygon above the horizon."""
    t1 = np.cross(normal, [1.0, 0, 0] if abs(normal[0]) < 0.9 else [0, 1.0, 0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(normal, t1)
    s = np.linspace(0.0, 1.0, 4001)[:, None]
    total = 0.0
    for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
        w = a + s * (b - a) - point
        z = w @ normal
        keep = z > 0
        d = w[keep] / np.linalg.norm(w[keep], axis=1)[:, None]
        xy = np.stack([d @ t1, d @ t2], -1)
        total += np.linalg.norm(np.diff(xy, axis=0), axis=1).sum()
    # the horizon cut (if any) lies on the rim: bounded by the rim term of the error model
    return total * resolution / 2


def raster_bound(f_exact, perimeter_px, resolution):
    """The item buffer's error model (tests/test_formfactor.py's module docstring): a pixel
    centre on each side of the outline within half a pixel of it may flip, plus the rim."""
    n_disc = disc_pixels(resolution)[2]
    rim = abs(math.pi * resolution**2 / 4 - n_disc)
    return (perimeter_px / 4 + 4 + f_exact * rim) / n_disc


# --- a shadow with an exact outline ---------------------------------------------------------

def blocker_scene(direction=(0.3, -1.0, 0.0)):
    """A 4 × 4 floor (y = 0, facing up), a 1 × 1 blocker at y = 1 facing down, a parallel
    light of irradiance 2 travelling along ``direction``."""
    v = np.array([[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2],
                  [0.13, 1, 0.21], [1.13, 1, 0.21], [1.13, 1, 1.21], [0.13, 1, 1.21]])
    d = np.asarray(direction, float)
    return scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]), [0, 0],
                             diffuse=[[0.5] * 3], emission=[[0, 0, 0]],
                             directional_lights=(d[None] / np.linalg.norm(d), [[2.0] * 3]))


def in_shadow(points, direction=(0.3, -1.0, 0.0)):
    """Exact for :func:`blocker_scene`: the blocker square shifted along the light to the floor;
    ``points (n, 3)`` → ``(n,) bool``."""
    d = np.asarray(direction, float)
    shift = d[[0, 2]] / -d[1]  # where a ray through y = 1 meets y = 0
    x = points[:, 0] - shift[0]
    z = points[:, 2] - shift[1]
    return (x > 0.13) & (x < 1.13) & (z > 0.21) & (z < 1.21)


# --- runs that must agree bit for bit -------------------------------------------------------

def store_arrays(path: Path) -> dict[str, np.ndarray]:
    """Every array of a solution store except the task contexts (a cache of what the client
    holds) and the older checkpoint slot; the active slot is named ``checkpoint/last``."""
    import zarr

    root = zarr.open_group(str(path), mode="r")
    active = str(root.attrs["checkpoint"])
    out = {}

    def walk(group, prefix):
        for name, member in group.members():
            full = prefix + name
            if full == "internal/context" or (prefix == "internal/checkpoint/"
                                              and name != active):
                continue
            if isinstance(member, zarr.Array):
                out[full.replace(f"internal/checkpoint/{active}/", "checkpoint/last/")] = (
                    member[...])
            else:
                walk(member, full + "/")

    walk(root, "")
    return out


def assert_same_run(a: Path, b: Path) -> None:
    """Bit-identical EXR and store arrays of two runs written to ``a`` and ``b`` (.exr)."""
    np.testing.assert_array_equal(read_exr(a), read_exr(b))
    sa, sb = store_arrays(a.with_suffix(".zarr")), store_arrays(b.with_suffix(".zarr"))
    assert sorted(sa) == sorted(sb)
    for name in sa:
        assert sa[name].dtype == sb[name].dtype, name
        np.testing.assert_array_equal(sa[name], sb[name], err_msg=name)


def render_context(scene, **opts):
    """``(ctx, h)``: the render context of ``scene`` solved with ``opts`` over the defaults
    patch 4, element 0.5, 1 sample per pixel (its centre: what the tests compare with exact
    values there, so no edge resampling), and its hierarchy."""
    settings = Settings(**{"patch_size": 4.0, "element_size": 0.5, "spp": 1, "edge_spp": 0,
                           **opts})
    h, _, sol, light = solve_scene(scene, settings)
    return render.for_view(render.context(scene, light, sol, settings, scene.camera)), h


#: Penumbra shooters (the Cornell box's blocks), re-shots from the row cache, subdivision
#: around the lights, per-pixel pixels and junction vertices to gather; small enough for a test.
SMALL_RUN = Settings(patch_size=150.0, element_size=75.0, resolution=64, tolerance=1e-2,
                     width=32, height=32, spp=2, workers=0, batch=8)


def steps_on(scene_name: str, threads: int, settings: Settings = SMALL_RUN):
    """``(scene, light, sol, image)``: the bundled scene ``scene_name`` through steps 1–4 at
    ``settings`` in-process, on ``threads`` threads (the executor closed after)."""
    scene = load_scene(SCENES / scene_name)
    ex = InProcess(threads=threads)
    try:
        light = direct.light(scene, preprocess(scene, settings), settings, ex)
        sol = solve.radiosity(light, settings, ex)
        image = render.image(scene, light, sol, settings, ex)
    finally:
        ex.close()
    return scene, light, sol, image
