"""Step 3: progressive refinement shooting (Cohen et al. 1988, with Doi's form factors).

The client owns two arrays and is the only one to change them:

- ``radiosity : (E, 3) float64``, total radiosity ``B`` (exitance, W/m²) of every element,
  emission included;
- ``unshot : (P, 3) float64``, unshot radiosity ``ΔB`` of every patch.

A shot from patch ``i`` with form factors ``F_ij`` (from the shooter to element ``j``) adds, for
every element ``j`` (docs/design.md §4)::

    ΔB_j = ρ_j · ΔB_i · F_ij · A_i / A_j

to ``B_j`` and ``ΔB_j · A_j / A_p`` to the unshot radiosity of ``j``'s patch ``p``, then sets
``ΔB_i = 0``. Overshooting (``--relaxation ω``, after Gortler et al. 1994's overrelaxed
Southwell iteration): the shot sends ``w ΔB_i``, ``w = 1 + (ω − 1) Σ_j F_ij ρ_j`` per channel
(more by as much as its receivers can reflect back), and leaves ``(1 − w) ΔB_i`` unshot, below
zero for ``ω > 1``; a later shot of the patch takes the excess back (docs/design.md §4).

Form factors depend only on geometry, so they can be computed ahead of time by any number of
workers (:func:`daskrad.formfactor.shooting.shoot_rows`); the updates are applied here, in
order.

Batches: the next batch is the ``K`` patches with the largest unshot *power*
``Σ_rgb |ΔB_p| · A_p``, chosen from the state after the previous-but-one batch was applied and
excluding the batch still in flight. The rule depends only on the solution state, never on
timing, so the result is the same bits whether the rows come from this process or from 8
workers; it lets the next batch be computed while the client applies the last one.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from daskrad.direct import DirectLight
from daskrad.formfactor import shooting
from daskrad.kernels import update
from daskrad.mesh.types import Hierarchy
from daskrad.settings import Settings


@dataclass
class Solution:
    """The state of the solver; everything a checkpoint must hold.

    Attributes
    ----------
    radiosity : (E, 3) float64
        Total radiosity ``B`` per element (W/m² of the scene's unit), emission included.
    direct : (E, 3) float64
        The part of ``B`` that is emission plus first-bounce direct light (set by the direct
        pass; emission only when emitters are shot like any patch).
    unshot : (P, 3) float64
        Unshot radiosity per patch.
    initial_rms : float
        RMS unshot radiosity before the first shot (convergence is relative to it).
    iteration : int
        Shots applied so far.
    history : list of (iteration, relative unshot RMS, seconds since start)
    converged : bool
    """

    radiosity: np.ndarray
    direct: np.ndarray
    unshot: np.ndarray
    initial_rms: float
    iteration: int = 0
    history: list = field(default_factory=list)
    converged: bool = False
    seconds: float = 0.0
    queued: list = field(default_factory=list)
    """Row keys (:func:`row_keys`: shooter ids, ``+ P`` for a one-point row) of the batches
    chosen but not yet applied, in order. A checkpoint keeps them so a resumed run applies
    exactly the batches the uninterrupted run would have."""
    row_kind: np.ndarray | None = None
    """``(P,) int8``: the row each patch shoots through, fixed when it is first chosen to
    shoot (:func:`row_keys`): 1 its penumbra-sampled row, 0 its one-point row, -1 not chosen
    yet (None: no patch chosen yet). A checkpoint keeps it."""


def unshot_rms(unshot: np.ndarray, patch_area: np.ndarray) -> float:
    """Area-weighted RMS of the unshot radiosity over patches and channels
    (:func:`daskrad.kernels.update.unshot_rms`: one pass in patch order)."""
    return float(update.unshot_rms(np.ascontiguousarray(unshot, np.float64),
                                   np.ascontiguousarray(patch_area, np.float64)))


def initial_solution(h: Hierarchy, emission: np.ndarray, reflected: np.ndarray | None = None
                     ) -> Solution:
    """Start state: ``B = E + reflected direct``, unshot = what has not been shot yet.

    Parameters
    ----------
    emission : (E, 3) float64
        Exitance ``π · Ke`` per element.
    reflected : (E, 3) float64, optional
        Reflected direct light ``ρ · H_direct`` per element, computed by the direct pass. When
        given, emitters are not shot (their light has been gathered) and unshot starts as the
        reflected part only; otherwise emitters are shot like any patch.
    """
    if reflected is None:
        shot_source = emission
        direct = emission.copy()
    else:
        shot_source = reflected
        direct = emission + reflected
    radiosity = direct.copy()
    unshot = patch_average(h, shot_source)
    return Solution(radiosity=radiosity, direct=direct, unshot=unshot,
                    initial_rms=unshot_rms(unshot, h.patch_area))


def patch_average(h: Hierarchy, elem_values: np.ndarray) -> np.ndarray:
    """Area-weighted average over each patch's elements: ``(E, 3) → (P, 3)``.

    ``np.bincount`` sums in element order, so the result is deterministic.
    """
    weighted = elem_values * h.elem_area[:, None]
    out = np.empty((h.n_patches, elem_values.shape[1]))
    for c in range(elem_values.shape[1]):
        out[:, c] = np.bincount(h.elem_patch, weights=weighted[:, c], minlength=h.n_patches)
    return out / h.patch_area[:, None]


def ambient(h: Hierarchy, reflectance: np.ndarray, unshot: np.ndarray) -> np.ndarray:
    """Cohen et al.'s ambient term for displaying an unconverged solution, ``(3,)`` W/m².

    ``ambient = Σ_p ΔB_p A_p / Σ A_p · 1/(1 − ρ_avg)``; the image adds ``ρ_j · ambient``.
    """
    total = h.patch_area.sum()
    rho_avg = (reflectance * h.elem_area[:, None]).sum(axis=0) / total
    mean_unshot = (unshot * h.patch_area[:, None]).sum(axis=0) / total
    return mean_unshot / np.maximum(1.0 - rho_avg, 1e-6)


def next_batch(unshot: np.ndarray, patch_area: np.ndarray, k: int,
               exclude: np.ndarray | None = None) -> np.ndarray:
    """The ``k`` patches with the largest unshot power ``Σ_rgb |ΔB_p| · A_p``, largest first;
    ties by patch id (an overshot patch's negative unshot is light to take back: it ranks by
    its size).

    Patches with zero unshot power are never chosen. ``exclude`` (patch ids already in flight)
    are skipped.
    """
    power = np.abs(unshot).sum(axis=1) * patch_area
    if exclude is not None and len(exclude):
        power = power.copy()
        power[exclude] = 0.0
    k = min(k, int(np.count_nonzero(power > 0)))
    if k == 0:
        return np.zeros(0, np.int64)
    # the first k of a stable sort on -power (equal powers in patch-id order, whatever the
    # platform), without sorting all P: those above the k-th largest power, then the ties at
    # it by id (a full sort was a tenth of the client's time on 10,000 patches)
    kth = power[np.argpartition(-power, k - 1)[k - 1]] if k < len(power) else power.min()
    above = np.flatnonzero(power > kth)
    chosen = np.concatenate([above, np.flatnonzero(power == kth)[:k - len(above)]])
    return chosen[np.lexsort((chosen, -power[chosen]))].astype(np.int64)


#: A shooter whose patch has sent and holds less than this share of the brightest patch's power
#: before the first shot shoots from one point, not from the penumbra samples of
#: :func:`daskrad.formfactor.shooting.shooter_points` (a sixth of the work in a furnished room,
#: where nearly every patch has an occluder near it). The measure is the patch's exitance power
#: ``B̄_p · A_p`` (mean over channels) when the patch is first chosen to shoot, and it keeps the row
#: it was given for every re-shot (:func:`row_keys`). The gate is a share of the brightest patch (an
#: emitter, or the most directly lit surface), not of the scene's whole light: with dozens of
#: luminaires over 14,144 patches (RenderPark's classroom) no patch holds 1 % of the whole, and a
#: share of the whole that speeds up a box lit by one light sent every shot of the classroom from
#: one point (5.0e-2 from a converged solution). The error such a shot makes is the penumbra
#: sampling's (a few per cent of the shot's light, moved between receivers near an occluder, not
#: lost) times light that is small beside the brightest shooter's (``benchmarks/bench_share.py``,
#: 4,000 shots: the classroom 2.26× faster than sampling every shot, 1.83e-3 from a converged
#: solution against 1.56e-3; the Cornell box, 1,500 shots, 2.26× faster at 6.8e-4 against 6.3e-7,
#: its image against the path tracer unchanged in an earlier stop's measure).
SAMPLE_SHARE = 0.03        # the default of Settings.sample_share

#: The overshooting factor ``ω`` of every shot (the default of Settings.relaxation): a shot
#: sends ``w ΔB`` and leaves ``(1 − w) ΔB`` unshot, ``w = 1 + (ω − 1) s`` with ``s = Σ_j F_ij
#: ρ_j`` the share of the shot its receivers reflect (per channel;
#: :func:`daskrad.kernels.update.apply_shot`): the overrelaxed Southwell iteration (Gortler,
#: Cohen & Slusallek 1994), scaled by the light that can come back, so a shot towards nothing
#: that reflects (an open scene, black receivers) is a plain one and leaves nothing to take
#: back. Light a patch will receive again from its neighbours is sent ahead, so fewer re-shots
#: are needed; too large an ``ω`` makes the solve chase the negative unshot it leaves. A fixed
#: ``w = 1.15`` did as well in closed rooms, but left an open scene's patches a residual to
#: shoot again and again; Feda & Purgathofer's (1992) overshoot by the receivers' unshot
#: spared more shots and left the error of plain shots (bench_relaxation's scenes).
#: Measured (benchmarks/bench_relaxation.py, solves to the default tolerance, ω = 1 → 1.3):
#: shots, Cornell box 1,563 → 944, lit room 332 → 254, RenderPark's cube 1,711 → 1,246,
#: office2 5,300 → 3,749, office3 11,266 → 9,782; the distance of B from a solve converged
#: 30× further, 9.7e-5 → 3.0e-5, 1.2e-4 → 6.4e-5, 2.4e-4 → 9.7e-5, 2.2e-4 → 1.1e-4,
#: 1.42e-3 → 1.34e-3. Solve seconds 0.80–1.05 × plain (first shots, the rows, are most of a
#: solve, and overshooting does not spare them). 1.2 spares as many shots and is less
#: accurate but in the lit room; 1.5 spares fewer. The ambient term, a signed mean of the
#: unshot radiosity, may come out negative for an unconverged solve.
RELAXATION = 1.3


def patch_power(h: Hierarchy, radiosity: np.ndarray, ids: np.ndarray,
                members: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """``(k,) float64``: exitance power ``Σ_{e ∈ p} mean_rgb(B_e) · A_e`` of the patches
    ``ids``. ``members``: :func:`patch_members` of ``h``, made here when omitted."""
    order, start = patch_members(h) if members is None else members
    ids = np.asarray(ids, np.int64)
    if not len(ids):
        return np.zeros(0)
    lo, count = start[ids], start[ids + 1] - start[ids]      # every patch has an element
    first = np.cumsum(count) - count                          # each patch's run in `e`
    e = order[np.repeat(lo - first, count) + np.arange(count.sum())]
    return np.add.reduceat(radiosity[e].mean(axis=1) * h.elem_area[e], first)


def patch_members(h: Hierarchy) -> tuple[np.ndarray, np.ndarray]:
    """``(order (E,), start (P + 1,))``: the elements of patch ``p`` are
    ``order[start[p]:start[p + 1]]``."""
    order = np.argsort(h.elem_patch, kind="stable")
    start = np.searchsorted(h.elem_patch[order], np.arange(h.n_patches + 1))
    return order, start


def sample_gate(h: Hierarchy, initial: Solution, share: float | None = None) -> float:
    """The exitance power below which a shooter's row is taken from one point:
    ``share`` (default :data:`SAMPLE_SHARE`) of the brightest patch's power
    (:func:`patch_power`) in ``initial``, the state before the first shot (:func:`start`; a
    resumed solve passes that state again, not its checkpoint, so the gate is the same)."""
    share = SAMPLE_SHARE if share is None else share
    if share == 0.0 or h.n_patches == 0:
        return 0.0
    return share * float(patch_power(h, initial.radiosity, np.arange(h.n_patches)).max())


def row_keys(h: Hierarchy, sol: Solution, ids: np.ndarray, gate: float,
             members=None, fix: bool = True) -> np.ndarray:
    """``(k,) int64``: the row each shooter ``ids`` shoots through
    (:func:`daskrad.formfactor.shooting.row_key`). A patch keeps the row it was first given
    (``sol.row_kind``); a patch not given one yet gets its sampled row when its exitance
    power (:func:`patch_power`) is at least ``gate`` (:func:`sample_gate`), else its
    one-point row, and keeps it from now on (``fix``; False: only ask, as a prefetch does).

    Why a patch keeps its row: every shot of a patch then goes through the same form
    factors, so the light it takes back (a negative unshot, left by an overshoot, its own or
    its sources') leaves along the rows its light came by. A patch that first shot from one
    point and took light back through its sampled row sent light below zero to elements its
    one point cannot see (a random soup, overshot: B down to -2.5e-4 where the converged
    B is ~1e-4; 19 of 1,400 soups before, none since)."""
    ids = np.asarray(ids, np.int64)
    if sol.row_kind is None:
        sol.row_kind = np.full(h.n_patches, -1, np.int8)
    kind = sol.row_kind[ids]
    sampled = kind == 1
    new = kind < 0
    if new.any():
        sampled[new] = patch_power(h, sol.radiosity, ids[new], members) >= gate
    if fix:
        sol.row_kind[ids] = sampled
    return shooting.row_key(ids, sampled, h.n_patches).astype(np.int64)


def apply_shot(h: Hierarchy, reflectance: np.ndarray, sol: Solution, shooter: int,
               ids: np.ndarray, factors: np.ndarray, scratch: tuple | None = None,
               relaxation: float = 1.0) -> float:
    """Apply one shot in place: distribute the shooter's unshot radiosity over ``ids``,
    overshot by ``relaxation`` (:data:`RELAXATION`; 1: all of it, and none is left).

    ``factors[k]`` is ``F_ij`` from shooter patch ``i`` to element ``ids[k]``, with
    ``Σ factors ≤ 1`` (guaranteed by the form-factor task), so a shot never sends more energy
    than the shooter holds. The arithmetic is :func:`daskrad.kernels.update.apply_shot`;
    ``scratch``: its :func:`~daskrad.kernels.update.shot_scratch` for ``h``, made here when
    not given (a solve passes one for all its shots). Returns the change of
    ``Σ_p A_p |ΔB_p|²`` (:func:`daskrad.kernels.update.unshot_squares`).
    """
    if scratch is None:
        scratch = update.shot_scratch(h.n_patches)
    change = update.apply_shot(sol.radiosity, sol.unshot, int(shooter), ids, factors,
                               reflectance, h.elem_area, h.elem_patch, h.patch_area, *scratch,
                               float(relaxation))
    sol.iteration += 1
    return change


#: Within a batch the solve checks the exact unshot RMS only once the RMS it follows shot by
#: shot is below ``SURE ×`` the tolerance (:func:`solve`).
SURE = 1.01

#: Batches' worth of patches beyond those in flight whose rows :func:`solve` offers for
#: prefetching: near the top of the ranking most will shoot within a few batches. On 2 Dask
#: workers a short horizon ran dry between batches (a worker waits ~3–7 ms for the client's
#: next offer); solves, 2 thread workers, PREFETCH 2 → 8 (with two tasks ahead per worker,
#: :data:`daskrad.distributed.dask_executor.AHEAD_TASKS`): RenderPark's cube 5.07 → 4.48 s,
#: office3 (2,000 shots) 15.42 → 14.84 s, the 73,066-element Cornell box 9.02 → 8.79 s, graz
#: (2,000 shots) 34.5 / 33.7 → 35.4 / 33.2 s. In this process, alternating, medians: the
#: 73k box 8.50 → 7.79 s (of 3), the cube 3.90 → 3.92 s (of 3), graz 30.1 → 29.8 s (of 2).
PREFETCH = 8

#: Whether a patch keeps the row it was first given (:func:`row_keys`). False chooses it
#: afresh at every shot, as before: benchmarks/bench_relaxation.py's reference arm (a
#: benchmark's switch, not a setting: a solve resumed from a checkpoint follows the kinds it
#: holds either way).
KEEP_ROWS = True

# A batch executor takes (batch number, the shooters' row keys, :func:`row_keys`) and returns
# a handle whose result() is a list of (ids, factors) rows, one per shooter, in the same order.
Submit = Callable[[int, np.ndarray], object]


def solve(h: Hierarchy, reflectance: np.ndarray, sol: Solution, submit: Submit, *,
          batch: int, tolerance: float, max_iterations: int,
          on_batch: Callable[[Solution], None] | None = None,
          prefetch: Callable[[np.ndarray], None] | None = None,
          sample_gate: float = 0.0, relaxation: float = 1.0) -> Solution:
    """Shoot until the relative unshot RMS is below ``tolerance`` or ``max_iterations`` shots.

    ``submit(n, keys)`` starts the form-factor work of batch ``n`` (its shooters' row keys,
    :func:`row_keys`) and returns a handle
    with ``.result()``; in-process it computes at once, with Dask it is a future. Two batches
    are in flight: batch ``n + 1`` is chosen (excluding batch ``n``'s shooters) before batch
    ``n`` is applied. ``on_batch`` runs after each applied batch (progress, checkpoints).

    ``sample_gate``: the exitance power below which a shooter's row is taken from one point
    (:func:`sample_gate`, :func:`row_keys`; 0: every row sampled).

    ``relaxation``: the overshooting factor ``ω`` of every shot (:func:`apply_shot`; 1: plain
    progressive refinement, :data:`RELAXATION`: the run's default). Every state it passes
    through is the same linear system's: ``B − ΔB`` (per patch) is an estimate and ``ΔB`` its
    residual, so the stopping rule and the ambient term read it as they read a plain one.

    ``prefetch(keys)``, when given, hears after each batch the row keys of the patches that
    rank next after those in flight (:data:`PREFETCH` batches' worth, most unshot power first,
    no more than the shots left), and an empty list at the end: an executor may compute their
    rows ahead on cores the batches leave idle, and drop those no longer offered. A row is a
    pure function of the geometry and its key, so this changes when rows are computed, never
    which patches shoot or the bits.
    """
    start = time.perf_counter() - sol.seconds
    reference = sol.initial_rms if sol.initial_rms > 0 else 1.0

    def done() -> bool:
        return (unshot_rms(sol.unshot, h.patch_area) / reference <= tolerance
                or sol.iteration >= max_iterations)

    batch_no = len(sol.history) + len(sol.queued)
    members = patch_members(h)
    n_patches = h.n_patches
    scratch = update.shot_scratch(n_patches)

    def patches(keys):
        return np.asarray(keys, np.int64) % n_patches

    # batches already chosen before a checkpoint are submitted again, in their order; a
    # batch is its shooters' row keys (row_keys)
    pending: list[tuple[np.ndarray, object]] = [
        (np.asarray(keys, np.int64), submit(len(sol.history) + n, np.asarray(keys, np.int64)))
        for n, keys in enumerate(sol.queued)
    ]

    def queue(exclude):
        nonlocal batch_no
        room = max_iterations - sol.iteration - sum(len(p) for p, _ in pending)
        ids = next_batch(sol.unshot, h.patch_area, min(batch, room), exclude)
        if len(ids):
            keys = row_keys(h, sol, ids, sample_gate, members, fix=KEEP_ROWS)
            pending.append((keys, submit(batch_no, keys)))
            batch_no += 1

    if not done() and not pending:
        queue(None)
    while pending:
        keys, handle = pending.pop(0)
        ids = patches(keys)
        if not done():
            queue(ids)          # the next batch computes while this one is applied
        rows = handle.result()
        # the unshot RMS followed shot by shot from the change each shot reports, exact
        # again at every batch; the exact pass decides wherever the followed value says the
        # tolerance may be reached (it drifts from the exact one by round-off only, far
        # within SURE), so the solve stops at the shot the exact test would
        squares, area = update.unshot_squares(sol.unshot, h.patch_area)
        near = (tolerance * reference * SURE) ** 2 * 3.0 * area
        for shooter, (elem_ids, factors) in zip(ids, rows, strict=True):
            if sol.iteration >= max_iterations or (squares <= near and done()):
                break
            squares += apply_shot(h, reflectance, sol, int(shooter), elem_ids, factors,
                                  scratch, relaxation)
        rms = unshot_rms(sol.unshot, h.patch_area) / reference
        sol.seconds = time.perf_counter() - start
        sol.history.append((sol.iteration, rms, sol.seconds))
        if done():
            # drop the work in flight: it was chosen from a state that is now final
            pending.clear()
        elif not pending:
            queue(None)
        sol.queued = [keys.tolist() for keys, _ in pending]
        if prefetch is not None and pending:
            ahead = patches(np.concatenate([k for k, _ in pending]))
            room = min(PREFETCH * batch, max_iterations - sol.iteration - len(ahead))
            offer = next_batch(sol.unshot, h.patch_area, max(room, 0), ahead)
            prefetch(row_keys(h, sol, offer, sample_gate, members, fix=False))
        if on_batch is not None:
            on_batch(sol)
    if prefetch is not None:
        prefetch(np.zeros(0, np.int64))     # nothing more: rows still ahead are dropped
    sol.converged = unshot_rms(sol.unshot, h.patch_area) / reference <= tolerance
    return sol


def start(light: DirectLight) -> Solution:
    """The solution before the first shot, from step 2's direct light.

    Two-pass (area lights gathered): ``B = E + ρH``, and only the reflected direct light is
    unshot. One-pass: emitters are shot like any patch (``B = E``, unshot ``E``), with the
    gathered point and directional light added on top of both.
    """
    mesh = light.mesh
    h = mesh.hierarchy
    if light.irradiance is not None and not light.emitters_shot:
        return initial_solution(h, mesh.emission, light.reflected)
    sol = initial_solution(h, mesh.emission)
    if light.irradiance is not None:
        sol.radiosity += light.reflected
        sol.direct += light.reflected
        sol.unshot += patch_average(h, light.reflected)
        sol.initial_rms = unshot_rms(sol.unshot, h.patch_area)
    return sol


def radiosity(light: DirectLight, settings: Settings, executor, begin: Solution | None = None,
              on_batch: Callable[[Solution], None] | None = None) -> Solution:
    """Step 3: shoot until converged (:func:`solve`) on the mesh of ``light``.

    ``executor`` computes the form-factor rows (:mod:`daskrad.distributed.executor`: in this
    process, or Dask futures ``formfactor-…``); ``begin`` is the state to continue from
    (a resumed checkpoint), by default :func:`start`; ``on_batch`` observes every applied
    batch (progress bar, checkpoints, dashboard) and never changes the state.
    """
    mesh = light.mesh
    h = mesh.hierarchy
    settings = settings.with_patches(h.n_patches)
    executor.set_geometry(
        shooting.make_context(h, settings.method, settings.resolution, grid=mesh.grid,
                              tri_element=mesh.tri_element, edge_angle=settings.edge_angle),
        h.generation)
    initial = start(light)
    return solve(h, mesh.reflectance, initial if begin is None else begin,
                 executor.shots, batch=settings.batch, tolerance=settings.tolerance,
                 max_iterations=settings.max_iterations, on_batch=on_batch,
                 prefetch=getattr(executor, "prefetch", None),
                 sample_gate=sample_gate(h, initial, settings.sample_share),
                 relaxation=settings.relaxation)
