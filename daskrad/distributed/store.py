"""The solution store ``OUT.zarr`` (docs/design.md §7, "The store"): the cluster's shared memory
and the run's result, readable with ``xarray.open_datatree``.

Only the client writes; workers open it read-only, so every chunk has one writer
(docs/stack.md: two writers of one chunk lose updates). Layout::

    vertices (vertex, xyz) f8                         the public results: every array has
    elements/{vertices,patch,material,area,normal,    zarr 3 dimension names and the
              reflectance,emission,radiosity,direct}  attributes units, description and
    patches/{polygon,unshot}                          sha256 (of its bytes, checked on read)
    materials/{diffuse,emission,specular,shininess,mirror}
    lights/{point_position,point_intensity,directional_direction,directional_irradiance}
    vertex_radiance, vertex_radiance_direct (vertex, rgb) f4, vertex_radiosity (vertex, rgb) f4
    internal/checkpoint/{0,1,2}                       the exact solver state (f8, and each
                                                      patch's row_kind, i1), three slots
                                                      written in turn
    internal/context/{shoot,direct,gather,render}/blob  what the worker tasks (and
                                                      ``daskrad render``/``export``) read,
                                                      each context's arrays in one blob
    internal/context/direct_state/blob                step 2's result (refined hierarchy,
                                                      vertex irradiance, light classes),
                                                      which a resume reads back

Root attributes: ``format``, ``daskrad`` (version), ``settings``, ``inputs`` (the fingerprint of
what the solution depends on, :func:`fingerprint`), ``generation``, ``iteration``,
``converged``, ``history`` (per batch: iteration, relative unshot RMS, seconds),
``checkpoint`` (the slot holding the last complete checkpoint), ``continue`` (the slot of the
last checkpoint a later run with other stopping criteria may continue from) and, once the image is
rendered, ``complete``, ``camera``, ``ambient`` and ``render`` (the render context's token).

Invariant of the checkpoint: a slot is written completely (arrays, then its own attributes,
which hold the sha256 of each array) before the root's ``checkpoint`` attribute names it, and
the previous checkpoint is left untouched meanwhile, as is the one named ``continue``, the
last state a run with a smaller tolerance or more iterations passes through (three slots).
Zarr replaces each chunk and ``zarr.json`` file atomically, so a client killed at any instant
leaves the last complete checkpoint readable. The public ``float32`` arrays are refreshed at
every checkpoint for users; a resume reads only the ``float64`` slot, so it continues from
exactly the bits the interrupted run held, after checking the slot's checksums and the store's
fingerprint.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import json
import math
import signal
import threading
from pathlib import Path

import numpy as np
import zarr

from daskrad import __version__
from daskrad.direct import DirectState
from daskrad.errors import StoreError
from daskrad.io.report import plain
from daskrad.mesh.types import Hierarchy
from daskrad.settings import Settings
from daskrad.solve import Solution

#: The store's format; a store of another format is refused (resume, render, export).
#: 5: a queued batch may name one-point rows (row key ``P + p``: ``--sample-share``), which
#: a reader of 4 would take for patch ids out of range.
#: 6: the unshot radiosity may be below zero (overshot: ``--relaxation``), which a reader of 5
#: would never shoot again.
#: 7: a checkpoint holds ``row_kind``, the row each patch keeps (:func:`daskrad.solve.row_keys`),
#: without which a resume would choose the rows of patches that shot already afresh.
FORMAT = "daskrad-solution/7"
#: The formats this daskrad reads: 6 is 7 without ``row_kind`` (a resume chooses each patch's
#: row again at its next shot, as 6 did at every shot), 5 is 6 solved without overshooting (no
#: ``relaxation`` in its settings: :data:`SINCE`), 4 is 5 without one-point rows (every queued
#: key is a patch id) and without ``sample_share``. An older store resumed is marked 7 before
#: anything of the new run is written to it.
READS = (FORMAT, "daskrad-solution/6", "daskrad-solution/5", "daskrad-solution/4")

#: A task context's arrays are packed into one uint8 array ``blob`` of chunks this size
#: (:meth:`Store.put_context`): zarr 3 costs ~5 ms to create an array, and a render context
#: has ~40 of them (0.3 s of a 4 s Cornell box run as one array each). Fields start on
#: ``BLOB_ALIGN``-byte offsets, so the arrays read back are aligned views of the blob.
BLOB_CHUNK = 8 << 20
BLOB_ALIGN = 64
#: Whether a blob is written chunk by chunk from its arrays (:func:`write_blob`); False joins
#: them into one array first, as before: ``benchmarks/bench_store.py --blobs``' reference arm
#: (a benchmark's switch; the bytes written are the same).
STREAM_BLOBS = True

#: Rows per chunk of the per-element arrays: ~1.5 MB of (E, 3) float64, big enough that a
#: checkpoint of 100k elements writes a handful of files, small enough for partial reads.
CHUNK_ROWS = 1 << 16

#: Settings that change the solution; a resume refuses a store written with other values.
SOLUTION_SETTINGS = ("method", "resolution", "edge_angle", "patch_size", "element_size",
                     "batch", "seed", "two_pass", "area_samples", "area_method", "subdivide",
                     "min_element_size", "sample_share", "relaxation")
#: Solution settings added since the format began, with the value a store written before them
#: was solved with (such a store resumes with that value).
SINCE = {"sample_share": 0.0, "relaxation": 1.0}
#: The stopping criteria: a resume may change them (:meth:`Store.load_checkpoint` picks a
#: checkpoint a straight run with the new criteria passes through).
STOPPING = ("tolerance", "max_iterations")

#: The public arrays: dimension names, units and a description (lengths are in the scene's
#: unit, written "m" below; radiometric units are per that unit of area).
SCHEMA = {
    "vertices": (("vertex", "xyz"), "m", "element corners (shared by the elements of a "
                 "polygon)"),
    "elements/vertices": (("element", "corner"), "1", "corner vertex ids, counter-clockwise "
                          "seen from the lit side; -1 as the fourth corner of a triangle"),
    "elements/patch": (("element",), "1", "the patch of each element"),
    "elements/material": (("element",), "1", "the material row of each element"),
    "elements/area": (("element",), "m2", "element area"),
    "elements/normal": (("element", "xyz"), "1", "unit normal, on the lit side"),
    "elements/reflectance": (("element", "rgb"), "1", "diffuse reflectance rho (Kd)"),
    "elements/emission": (("element", "rgb"), "W m-2", "emitted radiosity (exitance) pi Ke"),
    "elements/radiosity": (("element", "rgb"), "W m-2", "radiosity B, emission included "
                           "(the last checkpoint, rounded to float32)"),
    "elements/direct": (("element", "rgb"), "W m-2", "the part of B that is emission plus "
                        "first-bounce direct light"),
    "patches/polygon": (("patch",), "1", "the input polygon (face) of each patch"),
    "patches/unshot": (("patch", "rgb"), "W m-2", "unshot radiosity of each patch"),
    "materials/diffuse": (("material", "rgb"), "1", "Kd, diffuse reflectance"),
    "materials/emission": (("material", "rgb"), "W m-2 sr-1", "Ke, emitted radiance"),
    "materials/specular": (("material", "rgb"), "1", "Ks, Phong specular (mirror: reflected "
                           "fraction)"),
    "materials/shininess": (("material",), "1", "Ns, Phong exponent"),
    "materials/mirror": (("material",), "1", "illum 3: an ideal mirror in the per-pixel pass"),
    "lights/point_position": (("point_light", "xyz"), "m", "point light positions"),
    "lights/point_intensity": (("point_light", "rgb"), "W sr-1", "point light intensity"),
    "lights/directional_direction": (("directional_light", "xyz"), "1", "unit direction the "
                                     "light travels"),
    "lights/directional_irradiance": (("directional_light", "rgb"), "W m-2", "irradiance on a "
                                      "surface facing the light"),
    "vertex_radiance": (("vertex", "rgb"), "W m-2 sr-1", "radiance B/pi at the vertices, "
                        "ambient term added, T-vertices resolved (the solution's, before a "
                        "view's junction gather)"),
    "vertex_radiance_direct": (("vertex", "rgb"), "W m-2 sr-1", "the direct part of "
                               "vertex_radiance: (emission + rho H)/pi at the vertex"),
    "vertex_radiosity": (("vertex", "rgb"), "W m-2", "pi * vertex_radiance"),
}
#: Checkpoint slots: the last checkpoint, the last one a run with other stopping criteria can
#: continue from, and the one being written.
SLOTS = 3
_SLOT = {"radiosity": ("element", "rgb"), "direct": ("element", "rgb"),
         "unshot": ("patch", "rgb")}
#: The checkpoint's arrays that a store of an older format may lack (None when read from it).
_SLOT_SINCE = {"row_kind": ("patch",)}


def _chunks(shape: tuple) -> tuple:
    return (max(1, min(shape[0], CHUNK_ROWS)),) + tuple(max(1, s) for s in shape[1:])


def sha256(a: np.ndarray) -> str:
    """Hex sha256 of an array's dtype, shape and bytes (C order)."""
    a = np.ascontiguousarray(a)
    d = _sha256_of(a.dtype, a.shape)
    d.update(a.reshape(-1).view(np.uint8))
    return d.hexdigest()


def _sha256_of(dtype: np.dtype, shape: tuple):
    """The sha256 of :func:`sha256` before any byte: its header names the dtype and shape."""
    return hashlib.sha256(f"{np.dtype(dtype).str}{tuple(int(n) for n in shape)}".encode())


#: Whether a chunk holding only the fill value is written (:func:`write_array`); False is zarr's
#: default, kept as benchmarks/bench_store.py's other arm.
WRITE_EMPTY_CHUNKS = True


def write_array(group, name: str, data: np.ndarray, dtype=None, compress: bool = True, *,
                dims: tuple | None = None, units: str = "1", description: str = "",
                chunks: tuple | None = None) -> None:
    """Write ``data`` as array ``name`` of the zarr ``group`` (replacing it), ``dtype`` if
    given, with its dimension names, units, description and the sha256 of what was written:
    every array of the store is written here (public, checkpoint slots) or by
    :func:`write_blob` (context blobs), which gives the same array."""
    data = np.ascontiguousarray(data, dtype=dtype)
    arr = _create(group, name, data.shape, data.dtype, sha256(data), compress, dims, units,
                  description, chunks or _chunks(data.shape))
    if data.size:
        arr[...] = data


def write_blob(group, name: str, parts: list[tuple[int, np.ndarray]], size: int, *,
               chunk: int, description: str = "") -> None:
    """Write the ``(size,) uint8`` array whose bytes are ``parts`` (``(offset, (n,) uint8)``
    in increasing offset order, not overlapping; zeros between them) as :func:`write_array`
    writes that array joined (uncompressed, chunks of ``chunk`` bytes, dimension ``byte``):
    the same bytes and attributes, its sha256 taken part by part, each chunk filled in an
    array of its own and written whole. The joined array is never made: for the 73k-element
    Cornell box's render context that was a copy of 34 MB into pages touched for the first
    time, and a writing process's peak 72 MiB higher instead of 23
    (``benchmarks/bench_store.py --blobs``)."""
    digest = _sha256_of(np.uint8, (size,))
    end = 0
    for offset, part in parts:
        digest.update(bytes(offset - end))
        digest.update(part)
        end = offset + len(part)
    digest.update(bytes(size - end))
    arr = _create(group, name, (size,), np.dtype(np.uint8), digest.hexdigest(), False,
                  ("byte",), "1", description, (chunk,))
    first = 0                       # the first part that may reach into this chunk
    for start in range(0, size, chunk):
        stop = min(start + chunk, size)
        # a chunk array of its own each time: zarr hands a whole chunk's buffer to the store
        # without a copy, and a store in memory keeps it (a reused buffer would be the last
        # chunk's bytes in every chunk)
        out = np.zeros(stop - start, np.uint8)
        while first < len(parts) and parts[first][0] + len(parts[first][1]) <= start:
            first += 1
        for offset, part in parts[first:]:
            if offset >= stop:
                break
            lo, hi = max(offset, start), min(offset + len(part), stop)
            out[lo - start:hi - start] = part[lo - offset:hi - offset]
        arr[start:stop] = out


def _create(group, name: str, shape: tuple, dtype: np.dtype, digest: str, compress: bool,
            dims: tuple | None, units: str, description: str, chunks: tuple):
    """Array ``name`` of ``group`` made anew (a parent path's groups too), not yet written."""
    *parents, name = name.split("/")
    for parent in parents:
        group = group.require_group(parent)
    dims = tuple(dims) if dims is not None else tuple(f"{name}_{i}" for i in range(len(shape)))
    # every chunk is written, even one that holds only the fill value: zarr's default skips
    # those, and its test compares each chunk with a full array of the fill value first, which
    # was most of an uncompressed write (benchmarks/bench_store.py: the 73k box's context
    # blobs 0.38×, its checkpoint slots 0.83×)
    return group.create_array(name, shape=shape, dtype=dtype, chunks=chunks, overwrite=True,
                              dimension_names=dims,
                              attributes={"units": units, "description": description,
                                          "sha256": digest},
                              config={"write_empty_chunks": WRITE_EMPTY_CHUNKS},
                              **({} if compress else {"compressors": None}))


def _public(group, name: str, data: np.ndarray, dtype=None) -> None:
    dims, units, description = SCHEMA[name]
    write_array(group, name, data, dtype, dims=dims, units=units, description=description)


def read_checked(group, name: str, path: str) -> np.ndarray:
    """Array ``name`` of ``group``, its bytes checked against its ``sha256`` attribute;
    :class:`StoreError` naming the array if it is missing, unreadable or damaged."""
    try:
        arr = group[name]
        data = arr[...]
    except Exception as err:  # a truncated chunk, a missing zarr.json: one line, not a trace
        why = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise StoreError(f"cannot read {_where(group, name)}: {why}", path) from err
    if arr.attrs.get("sha256") != sha256(data):
        raise StoreError(f"{_where(group, name)} is damaged (its bytes do not match its "
                         "sha256); run again without --resume", path)
    return data


def _state_attrs(a: dict, n_patches: int, where: str, given: str) -> list[list[int]]:
    """The queued batches of checkpoint attributes ``a``, after checking that its state
    attributes have their types (a hand-edited or damaged zarr.json: :class:`StoreError`
    naming it, not a traceback mid-solve): ``iteration`` a count, ``queued`` batches of row
    keys below ``2P``, ``history`` rows of three numbers, ``seconds`` and ``initial_rms``
    finite numbers."""
    def count(x):
        return isinstance(x, int) and not isinstance(x, bool) and x >= 0

    def number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)

    try:      # a value of another type (an int where a list belongs) raises TypeError
        queued = [list(q) for q in a["queued"]]
        ok = (count(a["iteration"])
              and all(count(k) and k < 2 * n_patches for q in queued for k in q)
              and all(len(r) == 3 and all(number(x) for x in r) for r in a["history"])
              and number(a["seconds"]) and number(a["initial_rms"]))
    except (KeyError, TypeError):
        ok = False
    if not ok:
        raise StoreError(f"{where}/zarr.json does not hold a checkpoint's state (iteration, "
                         "queued batches, history); run again without --resume", given)
    return queued


def _state_digest(a: dict) -> str:
    """sha256 of checkpoint attributes ``a`` (all but ``state_sha256``) as canonical JSON."""
    doc = json.dumps({k: v for k, v in a.items() if k != "state_sha256"}, sort_keys=True,
                     separators=(",", ":"))
    return hashlib.sha256(doc.encode()).hexdigest()


def _sealed(a: dict) -> dict:
    """Checkpoint attributes ``a`` with their own checksum ``state_sha256``: the state a
    resume continues from (iteration, queued batches, history, which arrays the slot has)
    lives in these attributes, and an edit of them would resume to other bits, unseen by the
    arrays' checksums."""
    a = _jsonable(a)
    return {**a, "state_sha256": _state_digest(a)}


def _intact(a: dict) -> bool:
    """Whether checkpoint attributes ``a`` match their ``state_sha256``. A slot without one
    (written before slots were sealed, by a daskrad of this format or an older one) is taken
    as it is: the seal catches a damaged or hand-edited slot, not one whose seal was
    deleted too."""
    return "state_sha256" not in a or a["state_sha256"] == _state_digest(a)


def _check_groups(root: Path, given: str) -> None:
    """:class:`StoreError` naming the first group of the store at ``root`` whose ``zarr.json``
    is not a JSON object: the resume writes below every group (checkpoints, contexts, the
    public arrays), and zarr reads a group's metadata before it writes a child, so a damaged
    one stopped the run at its first checkpoint with a traceback. The checkpoint slots are
    checked when read (a torn older slot is skipped), and an array's metadata is written
    anew with its array."""
    for meta in sorted(root.rglob("zarr.json")):
        here = meta.parent
        rel = here.relative_to(root)
        if rel.parts[:2] == ("internal", "checkpoint") and len(rel.parts) > 2:
            continue
        if not any((child / "zarr.json").is_file() for child in here.iterdir()
                   if child.is_dir()):
            continue                    # an array (its chunks are not nodes)
        try:
            ok = isinstance(json.loads(meta.read_text()), dict)
        except (OSError, ValueError):
            ok = False
        if not ok:
            raise StoreError(f"{(rel / 'zarr.json').as_posix()} cannot be read (damaged); "
                             "run again without --resume", given)


def _where(group, name: str) -> str:
    return f"{group.path}/{name}".lstrip("/")


def _jsonable(value):
    """Attributes as JSON: numpy scalars to Python numbers (float64 round-trips exactly);
    inf and nan stay floats (:func:`_encode` spells them out)."""
    return plain(value, keep_nonfinite=True)


def fingerprint(scene) -> dict[str, str]:
    """What the solution depends on in a loaded scene, one digest per part.

    ``geometry`` (vertices, polygons), ``materials`` (polygon materials, ``Kd``, ``Ke``) and
    ``lights`` (point and directional). Digests of what was *loaded*, not of the files' bytes:
    every byte of the OBJ, MTL, glTF buffers or TOML that changes the answer changes one of
    them, while a comment, the camera or a specular coefficient (which only the image, rendered
    again on every run, reads) does not refuse a resume; and a refusal can say which part
    differs.
    """
    def digest(*arrays) -> str:
        d = hashlib.sha256()
        for a in arrays:
            d.update(sha256(np.asarray(a)).encode())
        return d.hexdigest()[:32]

    m, pl, dl = scene.materials, scene.point_lights, scene.directional_lights
    return {"geometry": digest(scene.vertices, scene.polygons),
            "materials": digest(scene.polygon_material, m.diffuse, m.emission),
            "lights": digest(pl.position, pl.intensity, dl.direction, dl.irradiance)}


#: The signals a store call holds until it is done: Ctrl-C, and SIGTERM, which the CLI turns
#: into the same stop (:class:`daskrad.errors.Terminated`).
HELD_SIGNALS = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def _uninterrupted():
    """Hold Ctrl-C (SIGINT) and SIGTERM until the block ends, then deliver them.

    Zarr writes from its own event-loop thread; a KeyboardInterrupt raised in the waiting main
    thread abandons the write task mid-way, and the interpreter then prints "Task was destroyed
    but it is pending!" and a traceback on exit (CI; 6 of 20 Ctrl-C'd runs under load, 0 of 20
    since). A store call is short (milliseconds), so it finishes first and then each signal
    caught is raised again for the handler that was there before (Python's KeyboardInterrupt,
    the CLI's SIGTERM handler, the default action, or the caller's own). Off the main thread
    (signals reach the main thread only) or inside an outer block nothing changes, nor for a
    signal that is ignored or has a handler not set from Python.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in HELD_SIGNALS}
    held = [s for s, h in previous.items()
            if h is not _hold and h is not None and h is not signal.SIG_IGN]
    _hold.caught.difference_update(held)
    installed: list = []
    try:
        # inside the try: a signal whose handler raises between two installs (SIGTERM's
        # before it is held, SIGINT's already) still has the held ones put back
        for s in held:
            signal.signal(s, _hold)
            installed.append(s)
        yield
    finally:
        _restore([(s, previous[s]) for s in installed])
        # SIGTERM first: when both came, the stop is a termination (a raising handler ends
        # the deliveries; the other signal asked for the same stop)
        due = [s for s in sorted(installed, key=lambda s: s != signal.SIGTERM)
               if s in _hold.caught]
        _hold.caught.difference_update(installed)
        for s in due:                 # deliver it now to whatever handled it before
            signal.raise_signal(s)


def _restore(handlers: list) -> None:
    """Put back ``handlers`` (``[(signal, handler)]``), each even when a signal delivered
    while an earlier one is put back raises (nested ``finally``: no handler is left as
    :func:`_hold`, which would swallow every later signal)."""
    if handlers:
        (s, h), rest = handlers[0], handlers[1:]
        try:
            signal.signal(s, h)
        finally:
            _restore(rest)


def _hold(signum, frame) -> None:
    _hold.caught.add(signum)


_hold.caught = set()


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
    ``scene`` (the loaded scene) gives the fingerprint a resume compares, and the materials and
    lights written beside the results.
    """

    def __init__(self, path: str | Path, settings: Settings | None = None, *,
                 resume: bool = False, scene=None, shown: str | Path | None = None):
        # as the user gave it (checked for --scheduler), or ``shown`` where the messages should
        # name another path (a resume's copy of the finished store: the finished one)
        self.given = str(shown if shown is not None else path)
        self.path = str(Path(path).absolute())       # what workers open
        self.settings = settings or Settings()
        self.resume = resume
        self.scene = scene
        self.inputs = fingerprint(scene) if scene is not None else None
        self.group = None
        self._slot = None
        self._written = None                         # (iteration, batches) of that slot
        self.generation = 0

    # --- creation, hierarchy, resume ------------------------------------------------------

    @_whole
    def open(self) -> Store:
        """Create the store (replacing an old one), or reopen it to resume; returns self."""
        if self.resume:
            self._reopen()
        else:
            self.group = zarr.open_group(self.path, mode="w")
            self.group.update_attributes({
                "format": FORMAT, "daskrad": __version__,
                "description": "daskrad radiosity solution (docs/design.md §7, 'The store')",
                "settings": _jsonable(self.settings.as_dict()), "inputs": self.inputs,
                "generation": -1, "iteration": 0, "converged": False, "history": []})
        return self

    def begin(self, h: Hierarchy, reflectance: np.ndarray, sol: Solution,
              direct: DirectState | None = None) -> Solution:
        """Write the hierarchy once per mesh generation, and step 2's ``direct`` state (a
        resume reads it back: :meth:`direct_state`); the solution to start from.

        That is ``sol`` for a new run, the checkpoint to continue from when resuming (``sol``
        again if the interrupted run died before its first checkpoint). A resume writes the
        public geometry again (the same bits), so a damaged public chunk is repaired.
        """
        if self.group is None:
            self.open()
        if self._resolve(h) and not self.resume:
            self.group.update_attributes({"settings": _jsonable(self.settings.as_dict())})
        self.generation = int(h.generation)
        restored = None
        if self.resume:
            n = self.group.attrs.get("n_elements")
            if n is not None and n != h.n_elements:
                raise StoreError(f"cannot resume: the store holds a different mesh ({n} "
                                 f"elements, this run {h.n_elements})", self.given)
            restored = self.load_checkpoint(h)
            # every check passed: from here the store describes this run (its stopping
            # criteria), not yet complete
            self.group.update_attributes({"settings": _jsonable(self.settings.as_dict()),
                                          "complete": False})
            self.write_hierarchy(h, reflectance)
        elif self.group.attrs.get("generation") != h.generation:
            self.write_hierarchy(h, reflectance)
        if direct is not None:
            self.put_context("direct_state", direct)      # nothing written when it is there
        return restored if restored is not None else sol

    @_whole
    def direct_state(self) -> DirectState | None:
        """Step 2's state as a run of this store wrote it (:meth:`begin`), for a resume to
        take instead of its direct pass; None when there is none (a store of an older
        daskrad, or a run stopped before its solve began). A resume has checked the store's
        scene and settings against its own (:meth:`open`), so the state is the one its own
        direct pass would compute."""
        try:
            # the token covers the JSON (levels, generation) as the digests cover the arrays
            a = zarr.open_group(self.path, mode="r")["internal/context/direct_state"].attrs
            if _token(a["meta"], a["digests"]) != a["token"]:
                return None
            state = load_context(self.path, "direct_state", a["token"])
        except Exception:  # noqa: BLE001 - missing or damaged: the direct pass runs again,
            return None    # which gives the same bits
        return state if isinstance(state, DirectState) else None

    def _resolve(self, h: Hierarchy) -> bool:
        """Resolve the default shot cap for ``h`` (:meth:`Settings.with_patches`); whether it
        was the default (a run resolves it before it makes its store)."""
        if self.settings.max_iterations is not None:
            return False
        self.settings = self.settings.with_patches(h.n_patches)
        return True

    @_whole
    def _reopen(self) -> None:
        if not (Path(self.path) / "zarr.json").is_file():
            raise StoreError("no solution store to resume from (run once without --resume)",
                             self.given)
        try:
            self.group = zarr.open_group(self.path, mode="r+")
        except Exception as err:  # a damaged or foreign directory: the user's to fix
            raise StoreError(f"cannot open the solution store: {err}", self.given) from err
        attrs = self.group.attrs
        _check_format(attrs.get("format"), self.given)
        _check_groups(Path(self.path), self.given)
        old = {**SINCE, **attrs.get("settings", {})}
        new = _jsonable(self.settings.as_dict())
        changed = [k for k in SOLUTION_SETTINGS if old.get(k) != new.get(k)]
        if changed:
            raise StoreError("cannot resume: the store was written with other settings ("
                             + ", ".join(f"{k}={old.get(k)!r}, this run {new.get(k)!r}"
                                         for k in changed)
                             + "); use the same options or run without --resume", self.given)
        stored = attrs.get("inputs")
        if self.inputs is not None and stored != self.inputs:
            parts = [k for k in self.inputs if (stored or {}).get(k) != self.inputs[k]]
            raise StoreError("cannot resume: the scene's " + " and ".join(parts)
                             + " changed since the store was written; run without --resume",
                             self.given)
        self._refuse_looser()
        if attrs.get("format") != FORMAT:    # every check passed: the run writes as 7
            self.group.update_attributes({"format": FORMAT})

    @_whole
    def write_hierarchy(self, h: Hierarchy, reflectance: np.ndarray) -> None:
        """The public geometry (and, with a scene, the materials and lights) for mesh
        generation ``h.generation``."""
        g = self.group
        _public(g, "vertices", h.vertices, np.float64)
        _public(g, "elements/vertices", h.elem_verts, np.int32)
        _public(g, "elements/patch", h.elem_patch, np.int32)
        _public(g, "elements/material", h.elem_material, np.int32)
        _public(g, "elements/area", h.elem_area, np.float64)
        _public(g, "elements/normal", h.elem_normal, np.float64)
        _public(g, "elements/reflectance", reflectance, np.float32)
        _public(g, "patches/polygon", h.patch_polygon, np.int32)
        if self.scene is not None:
            m = self.scene.materials
            _public(g, "elements/emission", math.pi * m.emission[h.elem_material], np.float32)
            for name in ("diffuse", "emission", "specular", "shininess"):
                _public(g, f"materials/{name}", getattr(m, name), np.float64)
            _public(g, "materials/mirror", m.mirror, np.bool_)
            g["materials"].update_attributes({"names": list(m.names)})
            pl, dl = self.scene.point_lights, self.scene.directional_lights
            _public(g, "lights/point_position", np.reshape(pl.position, (-1, 3)), np.float64)
            _public(g, "lights/point_intensity", np.reshape(pl.intensity, (-1, 3)), np.float64)
            _public(g, "lights/directional_direction", np.reshape(dl.direction, (-1, 3)),
                    np.float64)
            _public(g, "lights/directional_irradiance", np.reshape(dl.irradiance, (-1, 3)),
                    np.float64)
        g.update_attributes({"generation": int(h.generation), "n_elements": h.n_elements,
                             "n_patches": h.n_patches})

    # --- checkpoints ----------------------------------------------------------------------

    def continuable(self, sol: Solution) -> bool:
        """Whether a run with a smaller tolerance or more iterations could continue from
        ``sol`` (it is the state of a straight run that had not stopped: :func:`_open`)."""
        return _open(sol, self.settings)

    @_whole
    def checkpoint(self, sol: Solution) -> None:
        """Write the exact solver state into the slot not holding the last checkpoint.

        The same state again (the final batch, then :meth:`finish` of the monitor) only
        updates that slot's attributes: the arrays are the same bits, and the slot before it
        stays as it was — often the state a resume with a tighter tolerance continues from.
        """
        g = self.group
        s_ = self.settings
        state = {"generation": self.generation, "iteration": int(sol.iteration),
                 "initial_rms": float(sol.initial_rms), "seconds": float(sol.seconds),
                 "converged": bool(sol.converged), "history": _jsonable(sol.history),
                 "queued": _jsonable(sol.queued),
                 # what a later run with other stopping criteria may continue from
                 "tolerance": float(s_.tolerance), "max_iterations": int(s_.max_iterations),
                 "open": _open(sol, s_)}
        key = (int(sol.iteration), len(sol.history))
        if self._slot is not None and self._written == key:
            slot = self._slot
            s = g[f"internal/checkpoint/{slot}"]
            s.attrs.put(_sealed({**state, "sha256": s.attrs["sha256"]}))
        else:
            # never the last checkpoint, nor the last one a resume with a smaller tolerance
            # or more iterations can continue from (``continue``): three slots
            busy = {g.attrs.get("checkpoint"), g.attrs.get("continue"), self._slot}
            slot = min(x for x in range(SLOTS) if x not in busy)
            # made anew: the slot is free, and what it held may be damaged (a garbled
            # zarr.json that the resume skipped would stop require_group with a traceback)
            s = g.require_group("internal").require_group("checkpoint").create_group(
                str(slot), overwrite=True)
            arrays = {n: np.asarray(a, np.float64) for n, a in
                      (("radiosity", sol.radiosity), ("direct", sol.direct),
                       ("unshot", sol.unshot))}
            for name, a in arrays.items():
                write_array(s, name, a, compress=False, dims=_SLOT[name],
                            units="W m-2", description=f"exact solver state: {name}")
            if sol.row_kind is not None:
                arrays["row_kind"] = np.asarray(sol.row_kind, np.int8)
                write_array(s, "row_kind", arrays["row_kind"], compress=False,
                            dims=_SLOT_SINCE["row_kind"], description="the row each patch "
                            "shoots through: 1 penumbra-sampled, 0 one point, -1 not chosen yet")
            s.attrs.put(_sealed({**state, "sha256": {n: sha256(a) for n, a in arrays.items()}}))
        # only now is the slot complete: name it (one atomic zarr.json replacement; not
        # attrs.update, which zarr 3 writes key by key: a client killed between two keys left
        # "checkpoint" naming this slot beside the previous iteration and history)
        root = {"iteration": state["iteration"], "converged": state["converged"],
                "history": state["history"], "checkpoint": slot}
        if state["open"]:
            root["continue"] = slot
        g.update_attributes(root)
        self._slot, self._written = slot, key
        _public(g, "elements/radiosity", sol.radiosity, np.float32)
        _public(g, "elements/direct", sol.direct, np.float32)
        _public(g, "patches/unshot", sol.unshot, np.float32)

    @_whole
    def load_checkpoint(self, h: Hierarchy) -> Solution | None:
        """The solver state to continue from, or None if there is none.

        The last complete checkpoint, when it was written with this run's stopping criteria.
        With other criteria (``--tolerance``, ``--max-iterations``), the latest slot that a
        straight run with the new criteria passes through (see :func:`_open`);
        none: :class:`StoreError`. The slot's arrays are checked against their sha256: a
        damaged last checkpoint is refused, a torn older slot is skipped.
        """
        self._resolve(h)
        latest = self.group.attrs.get("checkpoint")
        if latest is None:
            return None
        latest = int(latest)
        tol, maxit = float(self.settings.tolerance), int(self.settings.max_iterations)
        tried = []
        tighter = False
        damaged: StoreError | None = None    # an older slot this resume could have used
        others = [x for x in range(SLOTS) if x != latest]
        cont = self.group.attrs.get("continue")
        if cont in others:                  # the last open checkpoint first, then the other
            others.remove(cont)
            others.insert(0, cont)
        for slot in (latest, *others):
            try:
                a = self.group[f"internal/checkpoint/{slot}"].attrs.asdict()
            except KeyError:
                if slot == latest:
                    raise StoreError(f"internal/checkpoint/{slot}, the last checkpoint, is "
                                     "missing; run again without --resume",
                                     self.given) from None
                continue
            except Exception as err:  # noqa: BLE001 - a garbled zarr.json: one line
                if slot == latest:
                    raise StoreError(f"internal/checkpoint/{slot}/zarr.json, the last "
                                     f"checkpoint's, cannot be read ({type(err).__name__}); "
                                     "run again without --resume", self.given) from None
                continue
            if not _intact(a):
                err = StoreError(f"internal/checkpoint/{slot}/zarr.json does not match its "
                                 "checksum (edited or damaged); run again without --resume",
                                 self.given)
                if slot == latest:
                    raise err
                damaged = damaged or err
                continue
            if a.get("generation") != h.generation:
                if slot == latest:
                    return None
                continue
            same = a.get("tolerance") == tol and a.get("max_iterations") == maxit
            if slot == latest:
                # only a smaller tolerance or more iterations than the last run's continue
                # it (an older slot may hold an early state a looser run passes through;
                # resuming to it would throw the store's answer away)
                tighter = not _looser(a, tol, maxit)
            usable = tighter and (same or (a.get("open") and tol <= a["tolerance"]
                                           and _fits(a["iteration"], a["queued"],
                                                     self.settings)))
            tried.append(a)
            if not usable:
                continue
            try:
                sol = self._read_slot(slot, a, h.n_patches)
            except StoreError as err:
                if slot == latest:
                    raise
                damaged = damaged or err
                continue                     # torn while written: the older slot only
            self._slot, self._written = slot, (int(a["iteration"]), len(a["history"]))
            return sol
        if damaged is not None:
            # the slot these criteria continue from is unreadable: say so, not that the
            # criteria are past the store's answer
            raise StoreError(f"cannot resume with tolerance={tol:g}, max_iterations={maxit}: "
                             f"the checkpoint it would continue from, {damaged.message}",
                             self.given)
        raise self._past(tried[0] if tried else {})

    def _past(self, a: dict) -> StoreError:
        """The refusal of a resume whose stopping criteria a straight run would have met
        before the checkpoint ``a`` (its slot's attributes)."""
        tol, maxit = float(self.settings.tolerance), int(self.settings.max_iterations)
        return StoreError(
            f"cannot resume with tolerance={tol:g}, max_iterations={maxit}: the store's "
            f"checkpoints (iteration {a.get('iteration')}, written with tolerance="
            f"{a.get('tolerance')!r}, max_iterations={a.get('max_iterations')!r}) are past "
            "where a run with these criteria would have stopped; only a smaller tolerance or "
            "more iterations continue a store; run without --resume", self.given)

    def _refuse_looser(self) -> None:
        """Refuse at once, before the scene's direct pass, a resume :meth:`load_checkpoint`
        would refuse for its stopping criteria: looser than the last checkpoint's (a larger
        tolerance or fewer iterations), so no slot is one a straight run passes through (on a
        furnished room the direct pass came first: ~16 s before the one line). Only with the
        shot cap resolved (a run resolves it from the patches before it opens its store);
        anything unreadable is left to :meth:`load_checkpoint`, which names it."""
        latest = self.group.attrs.get("checkpoint")
        if latest is None or self.settings.max_iterations is None:
            return
        try:
            a = self.group[f"internal/checkpoint/{int(latest)}"].attrs.asdict()
        except Exception:  # noqa: BLE001 - missing or garbled: load_checkpoint says which
            return
        if not _intact(a):
            return
        tol, maxit = float(self.settings.tolerance), int(self.settings.max_iterations)
        if not _looser(a, tol, maxit):
            return
        raise self._past(a)

    def _read_slot(self, slot: int, a: dict, n_patches: int) -> Solution:
        s = self.group[f"internal/checkpoint/{slot}"]
        names = [*_SLOT, *(n for n in _SLOT_SINCE if n in a.get("sha256", {}))]
        arrays = {n: read_checked(s, n, self.given) for n in names}
        for n, x in arrays.items():
            if a.get("sha256", {}).get(n) != sha256(x):
                raise StoreError(f"internal/checkpoint/{slot}/{n} does not match its "
                                 "checkpoint's checksum; run again without --resume",
                                 self.given)
            if not np.isfinite(x).all():
                raise StoreError(f"internal/checkpoint/{slot}/{n} holds NaN or infinite "
                                 "values; run again without --resume", self.given)
        queued = _state_attrs(a, n_patches, f"internal/checkpoint/{slot}", self.given)
        kind = arrays.get("row_kind")
        if kind is None:
            # a format-6 checkpoint: the patches of the batches in flight keep the rows they
            # were queued with; the others are chosen at their next shot
            kind = np.full(n_patches, -1, np.int8)
            keys = np.asarray([k for q in queued for k in q], np.int64)
            kind[keys % n_patches] = keys < n_patches
        if (arrays["unshot"].shape != (n_patches, 3) or kind.shape != (n_patches,)
                or not np.isin(kind, (-1, 0, 1)).all()):
            raise StoreError(f"internal/checkpoint/{slot} does not hold the state of this "
                             f"mesh's {n_patches} patches; run again without --resume",
                             self.given)
        return Solution(
            radiosity=arrays["radiosity"], direct=arrays["direct"], unshot=arrays["unshot"],
            initial_rms=a["initial_rms"], iteration=a["iteration"],
            history=[tuple(x) for x in a["history"]], converged=a["converged"],
            seconds=a["seconds"], queued=queued, row_kind=kind)

    @_whole
    def finish(self, image) -> None:
        """The rendered result (after the final checkpoint, which
        :class:`~daskrad.distributed.monitor.Watch` writes): the vertex radiance (the
        solution's, before the view's junction gather) and its direct part, the camera and the
        render context (``daskrad render`` and ``daskrad export`` read it back; it carries the
        gather, applied per view), then ``complete``."""
        ctx = image.context
        vertex_direct = image.vertex_direct
        g = self.group
        _public(g, "vertex_radiance", ctx.vertex_radiance, np.float32)
        _public(g, "vertex_radiance_direct", vertex_direct, np.float32)
        _public(g, "vertex_radiosity", ctx.vertex_radiance * math.pi, np.float32)
        token = self.put_context("render", ctx)
        cam = ctx.camera
        g.update_attributes({
            "complete": True, "render": token, "ambient": _jsonable(image.ambient),
            "camera": {"eye": _jsonable(cam.eye), "look_at": _jsonable(cam.look_at),
                       "up": _jsonable(cam.up), "fov": float(cam.fov),
                       "width": int(cam.width), "height": int(cam.height)}})

    # --- task contexts --------------------------------------------------------------------

    @_whole
    def put_context(self, kind: str, ctx) -> str:
        """Write a task context (a dataclass or NamedTuple of arrays) as
        ``internal/context/<kind>``.

        Returns its token, a digest of the whole content; nothing is written when the whole
        token matches (a resumed run). The arrays are packed into one uint8 array ``blob``
        (``layout`` in the attributes gives each field's dtype, shape and byte offset), each
        checked against its digest when read.
        """
        if self.group is None:
            self.group = zarr.open_group(self.path, mode="a")
        arrays = {}
        meta = _encode(ctx, "", arrays)
        digests = {name: _digest(a) for name, a in sorted(arrays.items())}
        token = _token(meta, digests)
        g = self.group.require_group("internal").require_group("context").require_group(kind)
        if g.attrs.get("token") == token:
            return token
        g.attrs.put({})            # no token while the blob changes: a reader fails, never mixes
        layout, parts, offset = {}, [], 0
        for name in sorted(arrays):
            a = np.ascontiguousarray(arrays[name])
            offset += -offset % BLOB_ALIGN
            layout[name] = {"dtype": a.dtype.str, "shape": list(a.shape), "offset": offset}
            parts.append((offset, a.reshape(-1).view(np.uint8)))
            offset += a.nbytes
        chunk = max(1, min(offset, BLOB_CHUNK))
        about = f"task context {kind}: its arrays, packed (the group's layout)"
        if STREAM_BLOBS:
            write_blob(g, "blob", parts, offset, chunk=chunk, description=about)
        else:
            write_array(g, "blob", _joined(parts, offset), compress=False, dims=("byte",),
                        chunks=(chunk,), description=about)
        g.attrs.put({"meta": meta, "digests": digests, "layout": layout, "token": token})
        return token


def _joined(parts: list[tuple[int, np.ndarray]], size: int) -> np.ndarray:
    """The blob of :func:`write_blob`'s ``parts`` as one array (:data:`STREAM_BLOBS` off)."""
    pieces, end = [], 0
    for offset, part in parts:
        if offset > end:
            pieces.append(np.zeros(offset - end, np.uint8))
        pieces.append(part)
        end = offset + len(part)
    if size > end:
        pieces.append(np.zeros(size - end, np.uint8))
    return np.concatenate(pieces) if pieces else np.zeros(0, np.uint8)


def _looser(a: dict, tol: float, maxit: int) -> bool:
    """Whether the criteria ``tol``, ``maxit`` would have stopped a straight run before the
    checkpoint ``a``: neither the same as its own nor a smaller tolerance with as many
    iterations or more."""
    same = a.get("tolerance") == tol and a.get("max_iterations") == maxit
    return not (same or (tol <= a.get("tolerance", -1.0)
                         and maxit >= a.get("max_iterations", 1 << 62)))


def _open(sol: Solution, settings: Settings) -> bool:
    """Whether a straight run with a smaller tolerance or more iterations passes through
    ``sol``: batches are still queued (the solve had not stopped: a stop clears the queue and
    may cut a batch short), and no batch so far was shortened to fit ``max_iterations``
    (:func:`_fits`)."""
    return bool(sol.queued) and _fits(sol.iteration, sol.queued, settings)


def _fits(iteration: int, queued: list, settings: Settings) -> bool:
    """No batch up to this state was cut to fit ``settings.max_iterations``, and none would be
    before it: the solve sizes a batch ``min(batch, max_iterations − shots applied − shots in
    flight)``, so a full batch after the queued ones still fits."""
    return (int(iteration) + sum(len(q) for q in queued) + settings.batch
            <= settings.max_iterations)


def _token(meta, digests: dict) -> str:
    """A task context's token: the digest of its JSON and of its arrays' digests."""
    return hashlib.blake2b(json.dumps([meta, digests], sort_keys=True).encode(),
                           digest_size=12).hexdigest()


def _digest(a: np.ndarray) -> str:
    d = hashlib.blake2b(f"{a.dtype.str}{a.shape}".encode(), digest_size=12)
    d.update(np.ascontiguousarray(a).reshape(-1).view(np.uint8))
    return d.hexdigest()


def load_context(path: str, kind: str, token: str | None = None):
    """Read back a task context written by :meth:`Store.put_context` (worker side; ``token``
    None: whichever is there). Every array is checked against its digest."""
    g = zarr.open_group(path, mode="r")[f"internal/context/{kind}"]
    if token is not None and g.attrs.get("token") != token:
        raise RuntimeError(f"{path}: internal/context/{kind} was replaced by another run "
                           f"(token {g.attrs.get('token')}, this run {token})")
    digests, layout = g.attrs["digests"], g.attrs["layout"]
    blob = g["blob"][...]

    def array(name: str) -> np.ndarray:
        try:
            f = layout[name]
            dtype = np.dtype(f["dtype"])
            if dtype.kind not in "biuf":     # numbers only: bytes never become objects
                raise TypeError(dtype)
            shape = [int(n) for n in f["shape"]]
            offset = int(f["offset"])
            nbytes = math.prod(shape) * dtype.itemsize
            if min(shape, default=0) < 0 or offset < 0 or offset + nbytes > len(blob):
                raise ValueError("outside the blob")
            a = blob[offset:offset + nbytes].view(dtype).reshape(shape)
        except (KeyError, TypeError, ValueError, OverflowError) as err:
            raise StoreError(f"internal/context/{kind}: field {name} is missing or does not "
                             "fit its blob", path) from err
        if _digest(a) != digests.get(name):
            raise StoreError(f"internal/context/{kind}: field {name} is damaged "
                             "(its bytes do not match their digest)", path)
        return a

    return _decode(g.attrs["meta"], array)


# Generic encoding of frozen dataclasses and NamedTuples: arrays become zarr arrays named by
# their field path, the rest JSON. Only the types of :func:`_known_types` are rebuilt.

def _known_types() -> dict:
    """The types a store's JSON may name: the task contexts and what they hold. Nothing else
    is ever built from a store (a crafted store cannot call an arbitrary function)."""
    from daskrad.direct import DirectContext, Lamps, Lights
    from daskrad.formfactor.shooting import ShootContext
    from daskrad.kernels.faces import Faces
    from daskrad.kernels.grid import Grid
    from daskrad.mesh.refine import TVertices
    from daskrad.render import GatherContext, Junctions, RenderContext
    from daskrad.scene.types import Camera

    return {f"{t.__module__}:{t.__qualname__}": t
            for t in (DirectContext, Lamps, Lights, ShootContext, Grid, Faces, RenderContext,
                      GatherContext, Junctions, Camera, DirectState, Hierarchy, TVertices)}


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


def _decode(meta: dict, array, types: dict | None = None):
    """Rebuild what :func:`_encode` wrote; ``array(name)`` reads an array."""
    types = _known_types() if types is None else types
    if "array" in meta:
        return array(meta["array"])
    if "value" in meta:
        return meta["value"]
    if "float" in meta:
        return float(meta["float"])
    if "list" in meta:
        items = [_decode(m, array, types) for m in meta["list"]]
        return tuple(items) if meta["tuple"] else items
    if "dict" in meta:
        return {k: _decode(m, array, types) for k, m in meta["dict"].items()}
    cls = types.get(meta.get("type"))
    if cls is None:
        raise StoreError(f"refusing to build {meta.get('type')!r} from a store (not one of "
                         "the types daskrad writes)")
    return cls(**{n: _decode(m, array, types) for n, m in meta["fields"].items()})


class Result:
    """A finished store, read-only: what ``daskrad render`` and ``daskrad export`` read.

    Opening and reading never writes (``mode="r"``); every array read is checked against its
    checksum, so a damaged store is refused with one line instead of rendering zeros.
    """

    def __init__(self, path: str | Path):
        self.given = str(path)
        p = Path(path)
        if not (p / "zarr.json").is_file():
            raise StoreError("not a solution store (no zarr.json; give the OUT.zarr a run "
                             "wrote)", self.given)
        try:
            self.group = zarr.open_group(str(p), mode="r")
        except Exception as err:
            raise StoreError(f"cannot open the solution store: {err}", self.given) from err
        self.attrs = self.group.attrs.asdict()
        _check_format(self.attrs.get("format"), self.given)
        if not self.attrs.get("complete"):
            raise StoreError("the store holds no finished solution (the run was interrupted: "
                             "finish it with daskrad run ... --resume)", self.given)
        for name in SCHEMA:               # the results, all of them checked (a few MB)
            read_checked(self.group, name, self.given)

    def render_context(self):
        """The :class:`~daskrad.render.RenderContext` the run's image was rendered from."""
        try:
            ctx = load_context(str(Path(self.given).absolute()), "render",
                               self.attrs.get("render"))
        except StoreError:
            raise
        except Exception as err:
            why = str(err).splitlines()[0] if str(err) else type(err).__name__
            raise StoreError(f"cannot read the render context: {why}", self.given) from err
        return ctx

    def array(self, name: str) -> np.ndarray:
        """A public array, checked."""
        return read_checked(self.group, name, self.given)


def _check_format(found, given) -> None:
    """Refuse a store whose ``format`` attribute is not one of :data:`READS`."""
    if found not in READS:
        raise StoreError(f"not a daskrad solution store of this version (format {found!r}, "
                         f"this daskrad reads {' or '.join(map(repr, READS))})", given)
