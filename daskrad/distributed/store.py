"""The solution store ``OUT.zarr`` (DESIGN §4, §7): the cluster's shared memory.

Only the client writes; workers open it read-only, so every chunk has one writer (STACK.md:
two writers of one chunk lose updates). Layout::

    vertices (V,3) f8, elements/{vertices,patch,area,reflectance,radiosity,direct},
    patches/{polygon,unshot}, vertex_radiosity (V,3) f4      the public schema of DESIGN §7
    checkpoint/0, checkpoint/1                                the exact solver state (f8), two
                                                              slots written in turn
    context/shoot, context/render                             what the worker tasks read

Root attributes: ``format``, ``settings``, ``generation``, ``iteration``, ``converged``,
``history`` (per batch: iteration, relative unshot RMS, seconds) and ``checkpoint`` (the slot
holding the last complete checkpoint).

Invariant of the checkpoint: a slot is written completely (arrays, then its own attributes)
before the root's ``checkpoint`` attribute names it, and the other slot — the previous
checkpoint — is left untouched meanwhile. Zarr replaces each chunk and ``zarr.json`` file
atomically, so a client killed at any instant leaves the last complete checkpoint readable.
The public ``float32`` arrays are refreshed at every checkpoint for users; a resume reads only
the ``float64`` slot, so it continues from exactly the bits the interrupted run held.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import importlib
import json
import math
import signal
import threading
from pathlib import Path

import numpy as np
import zarr

from daskrad.errors import OptionError
from daskrad.io.report import plain
from daskrad.mesh.types import Hierarchy
from daskrad.settings import Settings
from daskrad.solve import Solution

FORMAT = "daskrad-solution/1"

#: Rows per chunk of the per-element arrays: ~1.5 MB of (E, 3) float64, big enough that a
#: checkpoint of 100k elements writes a handful of files, small enough for partial reads.
CHUNK_ROWS = 1 << 16

#: Settings that change the solution; a resume refuses a store written with other values.
SOLUTION_SETTINGS = ("method", "resolution", "edge_angle", "patch_size", "element_size",
                     "tolerance", "max_iterations", "batch", "seed")


def _chunks(shape: tuple) -> tuple:
    return (max(1, min(shape[0], CHUNK_ROWS)),) + tuple(max(1, s) for s in shape[1:])


def _put(group, name: str, data: np.ndarray, dtype=None, compress: bool = True):
    """Write ``data`` as array ``name`` of ``group`` (replacing it), ``dtype`` if given;
    returns the array."""
    data = np.ascontiguousarray(data, dtype=dtype)
    *parents, name = name.split("/")
    for parent in parents:
        group = group.require_group(parent)
    arr = group.create_array(name, shape=data.shape, dtype=data.dtype,
                             chunks=_chunks(data.shape), overwrite=True,
                             **({} if compress else {"compressors": None}))
    if data.size:
        arr[...] = data
    return arr


def _jsonable(value):
    """Attributes as JSON: numpy scalars to Python numbers (float64 round-trips exactly);
    inf and nan stay floats (:func:`_encode` spells them out)."""
    return plain(value, keep_nonfinite=True)


@contextlib.contextmanager
def _uninterrupted():
    """Hold Ctrl-C (SIGINT) until the block ends, then deliver it.

    Zarr writes from its own event-loop thread; a KeyboardInterrupt raised in the waiting main
    thread abandons the write task mid-way, and the interpreter then prints "Task was destroyed
    but it is pending!" and a traceback on exit (CI; 6 of 20 Ctrl-C'd runs under load, 0 of 20
    since). A store call is short (milliseconds), so it finishes first and then the signal is
    raised again for the handler that was there before (Python's KeyboardInterrupt, or the
    caller's own). Off the main thread (signals reach the main thread only), inside an outer
    block, with SIGINT ignored or with a handler not set from Python, nothing changes.
    """
    previous = signal.getsignal(signal.SIGINT)
    if (threading.current_thread() is not threading.main_thread() or previous is _hold
            or previous is None or previous is signal.SIG_IGN):
        yield
        return
    _hold.caught = False
    signal.signal(signal.SIGINT, _hold)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if _hold.caught:              # deliver it now to whatever handled it before
            _hold.caught = False
            signal.raise_signal(signal.SIGINT)


def _hold(signum, frame) -> None:
    _hold.caught = True


_hold.caught = False


def _whole(method):
    """A :class:`Store` method that calls zarr runs whole: Ctrl-C waits for it
    (:func:`_uninterrupted`)."""
    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        with _uninterrupted():
            return method(*args, **kwargs)
    return wrapper


class Store:
    """The client's handle on ``OUT.zarr``.

    ``Store(path)`` only names the store; :meth:`open` creates it (or, with ``resume=True``,
    reopens it), :meth:`begin` writes the hierarchy and returns the checkpoint to resume from.
    """

    def __init__(self, path: str | Path, settings: Settings | None = None, *,
                 resume: bool = False):
        self.given = str(path)                       # as the user gave it (checked for --scheduler)
        self.path = str(Path(path).absolute())       # what workers open
        self.settings = settings or Settings()
        self.resume = resume
        self.group = None
        self._slot = None
        self.generation = 0
        self._arrays: dict = {}     # checkpoint arrays by path, rewritten in place (:meth:`_fill`)

    # --- creation, hierarchy, resume ------------------------------------------------------

    @_whole
    def open(self) -> Store:
        """Create the store (replacing an old one), or reopen it to resume; returns self."""
        if self.resume:
            self._reopen()
        else:
            self.group = zarr.open_group(self.path, mode="w")
            self.group.update_attributes({
                "format": FORMAT, "settings": _jsonable(self.settings.as_dict()),
                "generation": -1, "iteration": 0, "converged": False, "history": []})
        return self

    def begin(self, h: Hierarchy, reflectance: np.ndarray, sol: Solution) -> Solution:
        """Write the hierarchy once per mesh generation; the solution to start from.

        That is ``sol`` for a new run, the last checkpoint when resuming (``sol`` again if the
        interrupted run died before its first checkpoint).
        """
        if self.group is None:
            self.open()
        self.generation = int(h.generation)
        if self.resume:
            n = self.group.attrs.get("n_elements")
            if n is not None and n != h.n_elements:
                raise OptionError(f"cannot resume: the store holds a different mesh ({n} "
                                  f"elements, this run {h.n_elements})", self.given)
            restored = self.load_checkpoint(h)
            if restored is not None:
                return restored
        if self.group.attrs.get("generation") != h.generation:
            self.write_hierarchy(h, reflectance)
        return sol

    @_whole
    def _reopen(self) -> None:
        if not (Path(self.path) / "zarr.json").is_file():
            raise OptionError("no solution store to resume from (run once without --resume)",
                              self.given)
        try:
            self.group = zarr.open_group(self.path, mode="r+")
        except Exception as err:  # a damaged or foreign directory: the user's to fix
            raise OptionError(f"cannot open the solution store: {err}", self.given) from err
        attrs = self.group.attrs
        if attrs.get("format") != FORMAT:
            raise OptionError("not a daskrad solution store", self.given)
        old = attrs.get("settings", {})
        new = _jsonable(self.settings.as_dict())
        changed = [k for k in SOLUTION_SETTINGS if old.get(k) != new.get(k)]
        if changed:
            raise OptionError("cannot resume: the store was written with other settings ("
                              + ", ".join(f"{k}={old.get(k)!r}" for k in changed)
                              + "); use the same options or run without --resume", self.given)

    @_whole
    def write_hierarchy(self, h: Hierarchy, reflectance: np.ndarray) -> None:
        """The public geometry arrays of DESIGN §7, for mesh generation ``h.generation``."""
        g = self.group
        _put(g, "vertices", h.vertices, np.float64)
        el = g.require_group("elements")
        _put(el, "vertices", h.elem_verts, np.int32)
        _put(el, "patch", h.elem_patch, np.int32)
        _put(el, "area", h.elem_area, np.float64)
        _put(el, "reflectance", reflectance, np.float32)
        pa = g.require_group("patches")
        _put(pa, "polygon", h.patch_polygon, np.int32)
        g.update_attributes({"generation": int(h.generation), "n_elements": h.n_elements,
                             "n_patches": h.n_patches})

    # --- checkpoints ----------------------------------------------------------------------

    @_whole
    def checkpoint(self, sol: Solution) -> None:
        """Write the exact solver state into the slot not holding the last checkpoint."""
        g = self.group
        slot = 1 - int(g.attrs.get("checkpoint", 1)) if self._slot is None else 1 - self._slot
        for name in ("radiosity", "direct", "unshot"):
            self._fill(f"checkpoint/{slot}/{name}", getattr(sol, name), np.float64,
                       compress=False)
        s = g[f"checkpoint/{slot}"]
        state = {"generation": self.generation, "iteration": int(sol.iteration),
                 "initial_rms": float(sol.initial_rms), "seconds": float(sol.seconds),
                 "converged": bool(sol.converged), "history": _jsonable(sol.history),
                 "queued": _jsonable(sol.queued)}
        s.attrs.put(state)
        # only now is the slot complete: name it (one atomic zarr.json replacement; not
        # attrs.update, which zarr 3 writes key by key: a client killed between two keys left
        # "checkpoint" naming this slot beside the previous iteration and history)
        g.update_attributes({"iteration": state["iteration"], "converged": state["converged"],
                             "history": state["history"], "checkpoint": slot})
        self._slot = slot
        self._fill("elements/radiosity", sol.radiosity, np.float32)
        self._fill("elements/direct", sol.direct, np.float32)
        self._fill("patches/unshot", sol.unshot, np.float32)

    def _fill(self, path: str, data: np.ndarray, dtype, compress: bool = True) -> None:
        """Write ``data`` into the array at ``path``: in place when this store made it with
        the same shape (only its chunks are rewritten, each atomically: a checkpoint costs a
        quarter of recreating six arrays: 11 ms instead of 38 ms of CPU for the Cornell box),
        else created (:func:`_put`)."""
        data = np.ascontiguousarray(data, dtype=dtype)
        arr = self._arrays.get(path)
        if arr is not None and arr.shape == data.shape:
            if data.size:
                arr[...] = data
            return
        self._arrays[path] = _put(self.group, path, data, compress=compress)

    @_whole
    def load_checkpoint(self, h: Hierarchy) -> Solution | None:
        """The solver state of the last complete checkpoint, or None if there is none."""
        slot = self.group.attrs.get("checkpoint")
        if slot is None:
            return None
        s = self.group[f"checkpoint/{slot}"]
        a = s.attrs
        if a["generation"] != h.generation:
            return None
        self._slot = int(slot)
        return Solution(
            radiosity=s["radiosity"][...], direct=s["direct"][...], unshot=s["unshot"][...],
            initial_rms=a["initial_rms"], iteration=a["iteration"],
            history=[tuple(x) for x in a["history"]], converged=a["converged"],
            seconds=a["seconds"], queued=[list(q) for q in a["queued"]])

    @_whole
    def finish(self, vertex_radiosity: np.ndarray) -> None:
        """``vertex_radiosity (V, 3)``: B at the vertices as the image shows it (after the
        final checkpoint, which :class:`~daskrad.distributed.monitor.Watch` writes)."""
        _put(self.group, "vertex_radiosity", vertex_radiosity, np.float32)
        self.group.update_attributes({"complete": True})

    # --- task contexts --------------------------------------------------------------------

    @_whole
    def put_context(self, kind: str, ctx) -> str:
        """Write a task context (a dataclass or NamedTuple of arrays) as ``context/<kind>``.

        Returns its token, a digest of the whole content. Arrays already in the store with
        the same digest are not written again (the grid, when only the vertices changed), and
        nothing is written when the whole token matches (a resumed run).
        """
        if self.group is None:
            self.group = zarr.open_group(self.path, mode="a")
        arrays = {}
        meta = _encode(ctx, "", arrays)
        digests = {name: _digest(a) for name, a in sorted(arrays.items())}
        token = hashlib.blake2b(json.dumps([meta, digests], sort_keys=True).encode(),
                                digest_size=12).hexdigest()
        g = self.group.require_group("context").require_group(kind)
        if g.attrs.get("token") == token:
            return token
        old = g.attrs.get("digests", {})
        g.attrs.put({})            # no token while arrays change: a reader fails, never mixes
        for name, a in arrays.items():
            if old.get(name) != digests[name]:
                _put(g, name.replace(".", "/"), a)
        g.attrs.put({"meta": meta, "digests": digests, "token": token})
        return token


def _digest(a: np.ndarray) -> str:
    d = hashlib.blake2b(f"{a.dtype.str}{a.shape}".encode(), digest_size=12)
    d.update(np.ascontiguousarray(a).reshape(-1).view(np.uint8))
    return d.hexdigest()


def load_context(path: str, kind: str, token: str):
    """Read back a task context written by :meth:`Store.put_context` (worker side)."""
    g = zarr.open_group(path, mode="r")[f"context/{kind}"]
    if g.attrs.get("token") != token:
        raise RuntimeError(f"{path}: context/{kind} was replaced by another run "
                           f"(token {g.attrs.get('token')}, this run {token})")
    return _decode(g.attrs["meta"], g)


# Generic encoding of frozen dataclasses and NamedTuples: arrays become zarr arrays named by
# their field path, the rest JSON. Only daskrad's own types are rebuilt on the way back.

def _encode(obj, prefix: str, arrays: dict):
    if isinstance(obj, np.ndarray):
        arrays[prefix] = obj
        return {"array": prefix}
    if dataclasses.is_dataclass(obj) or (isinstance(obj, tuple) and hasattr(obj, "_fields")):
        names = ([f.name for f in dataclasses.fields(obj)] if dataclasses.is_dataclass(obj)
                 else list(obj._fields))
        return {"type": f"{type(obj).__module__}:{type(obj).__qualname__}",
                "fields": {n: _encode(getattr(obj, n), f"{prefix}.{n}".lstrip("."), arrays)
                           for n in names}}
    if isinstance(obj, (list, tuple)):
        return {"list": [_encode(v, f"{prefix}.{i}", arrays) for i, v in enumerate(obj)],
                "tuple": isinstance(obj, tuple)}
    if isinstance(obj, dict):
        return {"dict": {str(k): _encode(v, f"{prefix}.{k}", arrays) for k, v in obj.items()}}
    value = _jsonable(obj)
    if isinstance(value, float) and not math.isfinite(value):
        return {"float": repr(value)}         # inf and nan are not JSON
    return {"value": value}


def _decode(meta: dict, group):
    if "array" in meta:
        return group[meta["array"].replace(".", "/")][...]
    if "value" in meta:
        return meta["value"]
    if "float" in meta:
        return float(meta["float"])
    if "list" in meta:
        items = [_decode(m, group) for m in meta["list"]]
        return tuple(items) if meta["tuple"] else items
    if "dict" in meta:
        return {k: _decode(m, group) for k, m in meta["dict"].items()}
    module, _, name = meta["type"].partition(":")
    if not module.startswith("daskrad."):
        raise RuntimeError(f"refusing to build {meta['type']} from a store")
    cls = getattr(importlib.import_module(module), name)
    return cls(**{n: _decode(m, group) for n, m in meta["fields"].items()})
