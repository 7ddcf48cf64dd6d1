"""Compile the numba kernels ahead of time, and know when a run would have to (issue 12, item 4).

Every kernel is compiled on its first call and cached on disk by numba (``cache=True``,
:mod:`daskrad.kernels._jit`); a cold cache costs tens of seconds of silent compiling (~35 s of
CPU on the 2-core development machine), far more than a warm run of the Cornell box. So:

- :func:`warmup` (``daskrad warmup``, run by ``make install``) renders a tiny scene that holds
  every kind of light and material through the real pipeline, and calls every form-factor
  method and area-light method on it: the kernels are compiled for exactly the argument types
  a run passes, and numba writes them to its cache;
- it checks the leaves' contract on everything it compiled (:func:`leaf_violations`,
  :mod:`daskrad.kernels._jit`), and drops the cache and fails when a kernel breaks it;
- it then writes a marker (:data:`MARKER`) beside the cache naming the kernel sources' stamps
  (mtime and size, what numba's own cache checks, and the benchmarks' reference arms the
  kernels were compiled as, :data:`daskrad.kernels.REFERENCE_ARMS`) and the cache index files
  it found;
- :func:`is_warm` reads the marker back: cheap (one ``listdir`` and a ``stat`` per kernel
  file), it tells the command line whether a run would compile, so it can say so in one line
  on stderr (:func:`announce`) instead of sitting at 0 % for half a minute.

A kernel source changed since the marker (its stamp differs) makes the cache suspect as a
whole: numba notices an edit to a kernel's own file but not to a kernel it calls from another
file (the Makefile drops every cached kernel for the same reason), so :func:`warmup` drops
them all before compiling again.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import sys
import tempfile
import time
import types
from pathlib import Path

import numpy as np

#: The marker file, in the kernels' numba cache directory.
MARKER = "daskrad-warm.json"

#: Seconds a cold compile is announced as when no earlier warmup was timed: the whole warmup
#: on the 2-core development machine (100-111 s at the thirty-seventh stop's runs, 157 kernel
#: entries; it was 40 s when there were fewer kernels).
DEFAULT_SECONDS = 110

_OBJ = """\
# warmup scene: a box open at the front, an emitting panel (two patches: one lamp), a block,
# a glossy wall, a mirror
mtllib warm.mtl
v 0 0 0
v 0 0 2
v 2 0 2
v 2 0 0
v 0 2 0
v 0 2 2
v 2 2 2
v 2 2 0
v 0.7 1.99 0.8
v 0.7 1.99 1.2
v 1.3 1.99 1.2
v 1.3 1.99 0.8
v 0.5 0 0.5
v 0.5 0.6 0.5
v 1.0 0.6 0.5
v 1.0 0 0.5
v 0.5 0 1.0
v 0.5 0.6 1.0
v 1.0 0.6 1.0
v 1.0 0 1.0
usemtl white
f 1 2 3 4
f 5 8 7 6
usemtl red
f 1 5 6 2
usemtl glossy
f 2 6 7 3
usemtl mirror
f 3 7 8 4
usemtl light
f 9 12 11 10
usemtl white
f 13 14 15 16
f 16 15 19 20
f 20 19 18 17
f 17 18 14 13
f 14 18 19 15
f 13 16 20
"""

_MTL = """\
newmtl white
Kd 0.7 0.7 0.7
illum 1
newmtl red
Kd 0.6 0.1 0.1
illum 1
newmtl glossy
Kd 0.4 0.4 0.4
Ks 0.3 0.3 0.3
Ns 20
illum 2
newmtl mirror
Kd 0.1 0.1 0.1
Ks 0.8 0.8 0.8
illum 3
newmtl light
Kd 0 0 0
Ke 10 10 10
illum 1
"""

_TOML = """\
[camera]
eye = [1.0, 1.0, -3.0]
look_at = [1.0, 1.0, 1.0]
up = [0.0, 1.0, 0.0]
fov = 50.0
width = 24
height = 24

[[light]]
type = "point"
position = [1.5, 1.5, 1.5]
intensity = [1.0, 1.0, 1.0]

[[light]]
type = "directional"
direction = [0.2, -1.0, 0.3]
irradiance = [1.0, 1.0, 1.0]
"""


def cache_dir() -> Path:
    """Where numba keeps the kernels' compiled code (``daskrad/kernels/__pycache__`` in a
    writable source tree, else numba's user-wide cache; ``NUMBA_CACHE_DIR`` moves it)."""
    from daskrad.kernels import update

    try:
        return Path(update.apply_shot._cache._cache_path)
    except AttributeError:        # numba's cache locator is private API: fall back
        return Path(update.__file__).parent / "__pycache__"


def kernel_stamps() -> dict[str, list[int]]:
    """``{file name: [mtime_ns, size]}`` of every kernel source, what numba's cache checks."""
    here = Path(__file__).parent / "kernels"
    out = {}
    for entry in os.scandir(here):
        if entry.name.endswith(".py"):
            st = entry.stat()
            out[entry.name] = [st.st_mtime_ns, st.st_size]
    return out


def environment() -> dict:
    import numba

    from daskrad.kernels import REFERENCE_ARMS

    return {"numba": numba.__version__, "python": sys.version.split()[0],
            "stamps": kernel_stamps(), **REFERENCE_ARMS}


def _read_marker(directory: Path) -> dict | None:
    try:
        return json.loads((directory / MARKER).read_text())
    except (OSError, ValueError):
        return None


def is_warm() -> bool:
    """Whether the kernels a run uses are compiled in numba's cache: the marker of the last
    :func:`warmup` matches the kernel sources and numba, and its cache files are all there."""
    directory = cache_dir()
    marker = _read_marker(directory)
    if not marker or marker.get("environment") != environment():
        return False
    try:
        present = set(os.listdir(directory))
    except OSError:
        return False
    return set(marker.get("index", [])) <= present and bool(marker.get("index"))


def expected_seconds() -> int:
    """How long a cold compile is expected to take (the last warmup's time, or a default)."""
    marker = _read_marker(cache_dir()) or {}
    return int(round(marker.get("seconds", DEFAULT_SECONDS)))


def announce(file=None) -> None:
    """The one line a run prints before it compiles."""
    print(f"daskrad: compiling kernels (first run, ~{expected_seconds()} s)...",
          file=file or sys.stderr, flush=True)


def drop_cache(directory: Path | None = None) -> int:
    """Delete the kernels' cached code (``*.nbi``, ``*.nbc``) and the marker; returns how many
    files went."""
    directory = directory or cache_dir()
    n = 0
    try:
        names = os.listdir(directory)
    except OSError:
        return 0
    for name in names:
        if name.endswith((".nbi", ".nbc")) or name == MARKER:
            try:
                os.unlink(directory / name)
                n += 1
            except OSError:
                pass
    return n


def compile_all() -> None:
    """Run every kernel once with the argument types of a real run: the pipeline on the tiny
    scene (two-pass, per-pixel pass, Phong, mirror, point and directional light), then each
    form-factor method and each area-light method on its mesh, the coplanar-overlap test and
    the hidden-light proof of the per-pixel pass."""
    from daskrad import direct, formfactor
    from daskrad.formfactor import shooting
    from daskrad.preprocess import preprocess
    from daskrad.run import run
    from daskrad.scene import load_scene
    from daskrad.settings import Settings

    # the tiny scene's runs are not meant to converge: their warnings are noise here
    with (tempfile.TemporaryDirectory(prefix="daskrad-warmup-") as tmp,
          contextlib.redirect_stderr(io.StringIO())):
        d = Path(tmp)
        (d / "warm.obj").write_text(_OBJ)
        (d / "warm.mtl").write_text(_MTL)
        (d / "warm.toml").write_text(_TOML)
        settings = Settings(workers=0, patch_size=0.5, element_size=0.25, max_iterations=24,
                            width=24, height=24)
        run(d / "warm.obj", d / "out.exr", settings, progress=False)
        run(d / "warm.obj", d / "out.exr", settings.replace(two_pass=False, area_method="rays"),
            progress=False)
        scene = load_scene(d / "warm.obj")
        mesh = preprocess(scene, settings)
        light = direct.light(scene, mesh, settings.replace(area_method="rays"))
        h = mesh.hierarchy
        for method in formfactor.METHODS:
            ctx = shooting.make_context(h, method, 16 if method != "hemicube" else 8,
                                        grid=mesh.grid, tri_element=mesh.tri_element)
            shooting.shoot_rows(ctx, [0, h.n_patches - 1], shooting.RowCache())
        # the exact test of the coplanar-overlap check runs only where two faces of one plane
        # meet: two overlapping squares (and one overlap, found), as most real scenes have
        from daskrad.scene.overlap import coplanar_overlaps

        sq = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0], [1, 1, 0], [3, 1, 0],
                       [3, 3, 0], [1, 3, 0]], float)
        coplanar_overlaps(sq, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]), 4.25)
        # the proof that one face hides a light from a per-pixel element runs only for a light
        # hidden from every corner of one (the Cornell box's blocks): every pair asked here
        from daskrad import render

        lights = direct.lights_of(light.context)
        lit = light.mesh            # refined by the direct pass: not `mesh` any more
        view = render.RenderContext(grid=lit.grid, tri_verts=lit.tri_verts,
                                    tri_element=lit.tri_element,
                                    elem_normal=lit.hierarchy.elem_normal,
                                    vertex_radiance=None, camera=None, spp=1, lights=lights)
        render.hidden_lights(view, lit.hierarchy, np.ones(
            (lit.hierarchy.n_elements, len(lights.emitter_corners)), bool))
        # the view region's primary rays run only beyond render.GATHER_ALL junction vertices
        from daskrad.kernels.grid import located_triangles, locator

        loc = locator(lit.grid.triangles)
        located_triangles(lit.occluders.grid, loc, lit.grid,
                          np.ones((1, 3)), -np.ones((1, 3)), 0.0, np.inf)
        # the runs gathered by the tiny scene's method: every other method too (a scene of
        # many polygons gathers by rays)
        points = lit.hierarchy.vertices[:2]
        for method in render.GATHER_METHODS:
            render.gather_vertices(render.GatherContext(
                grid=lit.grid, tri_verts=lit.tri_verts, tri_element=lit.tri_element,
                elem_normal=lit.hierarchy.elem_normal,
                exclude=np.zeros((lit.hierarchy.n_elements, 3)),
                n_vertices=len(lit.hierarchy.vertices), points=points,
                normals=np.tile([0.0, 0.0, 1.0], (len(points), 1)),
                seeds=np.arange(len(points), dtype=np.int64), offset=1e-6, side=4,
                polygons=lit.occluders.grid, locator=loc, method=method), 0, len(points))


def _callees(fn):
    """``(name, object)`` of everything ``fn``'s code may call: its globals, the attributes
    of a module among them, what a tuple among them holds, its defaults, and the same in
    its nested code."""
    globals_ = fn.py_func.__globals__

    def named(code):
        for name in code.co_names:
            target = globals_.get(name)
            if isinstance(target, types.ModuleType):
                for attr in code.co_names:
                    if hasattr(target, attr):
                        yield f"{name}.{attr}", getattr(target, attr)
            elif isinstance(target, tuple):
                yield from ((f"{name}[{i}]", t) for i, t in enumerate(target))
            else:
                yield name, target
        for const in code.co_consts:
            if isinstance(const, types.CodeType):
                yield from named(const)

    yield from named(fn.py_func.__code__)
    yield from (("a default", d) for d in fn.py_func.__defaults__ or ())


def leaf_violations(modules=None) -> list[str]:
    """Where the kernels of ``modules`` (default: every module of :mod:`daskrad.kernels`) break
    the leaves' contract (:mod:`daskrad.kernels._jit`): a leaf that may call a counted kernel
    (:func:`_callees`), and what :func:`daskrad.kernels.leaf_faults` finds in a leaf compiled
    in this process. Empty when they keep it."""
    import importlib
    import pkgutil

    import daskrad.kernels
    from daskrad.kernels import is_leaf, leaf_faults

    if modules is None:
        modules = [importlib.import_module(f"daskrad.kernels.{info.name}")
                   for info in pkgutil.iter_modules(daskrad.kernels.__path__)]
    out = []
    for module in modules:
        for name, fn in vars(module).items():
            if not (is_leaf(fn) and fn.__module__ == module.__name__):
                continue
            where = f"{module.__name__.rsplit('.', 1)[-1]}.{name}"
            out += [f"{where} calls the counted kernel {called}"
                    for called, target in _callees(fn)
                    if hasattr(target, "py_func") and not is_leaf(target)]
            out += [f"{where} {fault}" for fault in leaf_faults(fn)]
    return out


def warmup(verbose: bool = True) -> float:
    """Compile every kernel into numba's cache and write the marker; returns the seconds.

    A stale cache (kernel sources changed since the last warmup, or no marker) is dropped
    first, since numba misses edits to kernels called across files.
    """
    t = time.perf_counter()
    directory = cache_dir()
    marker = _read_marker(directory)
    if marker is None or marker.get("environment") != environment():
        drop_cache(directory)
    if verbose:
        print("daskrad: compiling kernels...", file=sys.stderr, flush=True)
    compile_all()
    broken = leaf_violations()
    if broken:      # a leaf returning an array corrupts the heap: keep none of this cache
        drop_cache(directory)
        raise RuntimeError("kernels break the leaves' contract: " + "; ".join(broken))
    seconds = time.perf_counter() - t
    index = sorted(n for n in os.listdir(directory) if n.endswith(".nbi"))
    payload = {"environment": environment(), "index": index, "seconds": seconds}
    tmp = directory / f".{MARKER}.{os.getpid()}"
    try:
        tmp.write_text(json.dumps(payload, indent=1))
        os.replace(tmp, directory / MARKER)     # atomic: a reader sees the old or the new
    except OSError:                             # a read-only cache: compiled, not marked
        pass
    if verbose:
        print(f"daskrad: {len(index)} kernel entries compiled and cached in {seconds:.1f} s "
              f"({directory})", file=sys.stderr)
    return seconds
