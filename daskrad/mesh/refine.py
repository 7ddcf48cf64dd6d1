"""Adaptive subdivision around shadow boundaries (docs/design.md §1 step 2; issue 5, item 2).

An element whose corner values (the reflected direct light ``ρ · H`` at its vertices) spread by
more than ``threshold`` relative to the local level is split in four — a quad at its edge
midpoints and centre, a triangle at its edge midpoints — and the test is repeated on the
children until their longest edge is below ``min_size``. Direct light is computed only at the
vertices each level creates. Every level bumps ``Hierarchy.generation``.

Invariants:

- an edge midpoint is ``(a + b) / 2`` of its endpoints, created once per edge and shared by
  every element that later splits along that edge (a table of ``edge key → midpoint``), so
  neighbours split at different levels still share vertices;
- children keep the parent's patch, normal and winding; the elements of a patch stay
  contiguous (children replace their parent in place); patch areas are unchanged (children's
  areas add up to the parent's to round-off);
- a midpoint that lies on an edge some unsplit element still has is a **T-vertex**:
  :func:`resolve_tvertices` replaces its value by the mean of its edge's ends before Gouraud
  interpolation, so the two sides agree along the edge and no seam shows.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from daskrad import tolerances
from daskrad.kernels.refine import element_spreads, resolve_tvertices_kernel
from daskrad.mesh.types import Hierarchy

#: Default relative spread above which an element is split.
THRESHOLD = 0.5

#: Elements are split until their longest edge is at most ``element_size / MIN_SIZE_DIVISOR``
#: (two levels: 30 mm elements of the Cornell box end at 7.5 mm near a shadow's edge). Every
#: level multiplies the cost of a shot by the elements it adds (Cornell box: 3,712 elements,
#: 7,006 after two levels, 11,440 after three; shooting 5 s → 11 s → 27 s), and the per-pixel
#: pass sharpens what is left, so two levels is the default.
MIN_SIZE_DIVISOR = 4.0

#: Spreads are measured relative to ``max(local max, FLOOR × 90th percentile of all vertex
#: values)``: in the dark, tiny absolute differences do not trigger splits.
FLOOR = 0.05


@dataclass(frozen=True)
class TVertices:
    """Midpoints lying on an unsplit edge: ``vertex (T,) int64`` is the midpoint of
    ``a (T,)``–``b (T,)``, in increasing vertex order (ends are always older vertices)."""

    vertex: np.ndarray
    a: np.ndarray
    b: np.ndarray

    @staticmethod
    def empty() -> TVertices:
        z = np.zeros(0, np.int64)
        return TVertices(z, z, z)


def _edges(ev: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(E, 4)`` start and end vertex of each element's edges (triangles: edge 3 is c2→c0
    twice; callers mask it with ``ev[:, 3] < 0``)."""
    quad = ev[:, 3] >= 0
    c3 = np.where(quad, ev[:, 3], ev[:, 0])
    start = np.stack([ev[:, 0], ev[:, 1], ev[:, 2], c3], axis=1)
    end = np.stack([ev[:, 1], ev[:, 2], np.where(quad, ev[:, 3], ev[:, 0]),
                    np.where(quad, ev[:, 0], ev[:, 0])], axis=1)
    return start, end


def _key(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    a = a.astype(np.int64)
    b = b.astype(np.int64)
    return np.minimum(a, b) * n + np.maximum(a, b)


def needs_split(h: Hierarchy, vertex_values: np.ndarray, threshold: float,
                min_size: float) -> np.ndarray:
    """``(E,) bool``: elements to split: relative spread above ``threshold`` and longest edge
    above ``min_size`` (so refined elements end with edges of at most ``min_size``).

    The spread of an element is the largest per-channel difference between its corner
    values, relative to ``max(its largest corner value, FLOOR × the 90th percentile of the
    corners' largest values over all elements)`` (:func:`element_spreads`, one pass)."""
    ev = h.elem_verts
    values = np.ascontiguousarray(vertex_values, dtype=np.float64)
    local, sp, edge = element_spreads(np.ascontiguousarray(ev), values,
                                      np.ascontiguousarray(h.vertices, dtype=np.float64))
    used = ev[ev >= 0]
    # each element's corners once (a vertex counts once for every element it is a corner
    # of), the largest channel of each
    ref = float(np.percentile(values.max(axis=1)[used], 90)) if len(used) else 0.0
    level = np.maximum(local, FLOOR * ref)
    # an edge equal to min_size up to round-off is not split again
    return ((sp > threshold * level) & (level > 0)
            & (edge > min_size * (1.0 + tolerances.SPLIT_SIZE_RTOL)))


def split_elements(h: Hierarchy, split: np.ndarray, mid_keys: np.ndarray,
                   mid_vertex: np.ndarray) -> tuple[Hierarchy, np.ndarray, np.ndarray]:
    """Split the elements ``split (E,) bool`` in four.

    ``mid_keys (K,) int64`` (sorted) and ``mid_vertex (K,)`` are the midpoints made so far,
    keyed by edge ``min(a, b) · N + max(a, b)`` with ``N`` a fixed bound on vertex ids.
    Returns the new hierarchy (``generation + 1``) and the updated midpoint table. New
    vertices are appended after the old ones, in increasing order of edge key (then the quad
    centres in element order), so the result does not depend on how the work is batched.
    """
    from daskrad.mesh.hierarchy import _areas_centroids

    ev = h.elem_verts
    nv = len(h.vertices)
    N = np.int64(1) << np.int64(31)
    ids = np.flatnonzero(split)
    sev = ev[ids]
    quad = sev[:, 3] >= 0
    start, end = _edges(sev)
    valid = np.ones_like(start, dtype=bool)
    valid[~quad, 3] = False
    keys = _key(start, end, N)
    need = np.unique(keys[valid])
    pos = np.searchsorted(mid_keys, need)
    known = (pos < len(mid_keys)) & (mid_keys[np.minimum(pos, len(mid_keys) - 1)] == need) \
        if len(mid_keys) else np.zeros(len(need), bool)
    new_keys = need[~known]
    a, b = new_keys // N, new_keys % N
    new_mid = (h.vertices[a] + h.vertices[b]) * 0.5
    new_ids = nv + np.arange(len(new_keys), dtype=np.int64)
    # the updated table, sorted by key
    all_keys = np.concatenate([mid_keys, new_keys])
    all_vert = np.concatenate([mid_vertex, new_ids])
    order = np.argsort(all_keys, kind="stable")
    all_keys, all_vert = all_keys[order], all_vert[order]
    # (S, 4) midpoints; a triangle's unused fourth edge has no entry (clipped, then masked)
    at = np.minimum(np.searchsorted(all_keys, keys), len(all_keys) - 1)
    m = np.where(valid, all_vert[at], -1)
    # quad centres: the mean of the four corners (in the plane of a planar quad)
    qids = np.flatnonzero(quad)
    centre = h.vertices[sev[qids]].mean(axis=1)
    centre_ids = nv + len(new_keys) + np.arange(len(qids), dtype=np.int64)
    vertices = np.concatenate([h.vertices, new_mid, centre])

    children = np.full((len(ids), 4, 4), -1, np.int64)
    c0, c1, c2, c3 = sev[:, 0], sev[:, 1], sev[:, 2], sev[:, 3]
    m01, m12, m23, m30 = m[:, 0], m[:, 1], m[:, 2], m[:, 3]
    ctr = np.full(len(ids), -1, np.int64)
    ctr[qids] = centre_ids
    neg = np.full(len(ids), -1, np.int64)
    # quads: corner quads around the centre, each wound like the parent
    q_children = np.stack([np.stack([c0, m01, ctr, m30], 1), np.stack([m01, c1, m12, ctr], 1),
                           np.stack([ctr, m12, c2, m23], 1), np.stack([m30, ctr, m23, c3], 1)],
                          axis=1)
    # triangles (a, b, c): edge midpoints m01, m12 and m20 (= column 2 for a triangle)
    t_children = np.stack([np.stack([c0, m01, m23, neg], 1), np.stack([m01, c1, m12, neg], 1),
                           np.stack([m23, m12, c2, neg], 1), np.stack([m01, m12, m23, neg], 1)],
                          axis=1)
    children = np.where(quad[:, None, None], q_children, t_children)

    # children replace their parent in place: patches stay contiguous
    count = np.where(split, 4, 1)
    new_ev = np.repeat(ev.astype(np.int64), count, axis=0)
    first = np.concatenate([[0], np.cumsum(count)[:-1]])
    slots = (first[ids][:, None] + np.arange(4)[None, :]).reshape(-1)
    new_ev[slots] = children.reshape(-1, 4)
    new_ev = new_ev.astype(np.int32)
    elem_patch = np.repeat(h.elem_patch, count)
    elem_normal = np.repeat(h.elem_normal, count, axis=0)
    area, centroid = _areas_centroids(vertices, new_ev, elem_normal)
    h2 = replace(h, vertices=vertices, elem_verts=new_ev, elem_patch=elem_patch,
                 elem_normal=elem_normal, elem_area=area, elem_centroid=centroid,
                 generation=h.generation + 1)
    return h2, all_keys, all_vert


def tvertices(h: Hierarchy, mid_keys: np.ndarray, mid_vertex: np.ndarray) -> TVertices:
    """The midpoints that lie on an edge some element of ``h`` still has unsplit."""
    if len(mid_keys) == 0:
        return TVertices.empty()
    N = np.int64(1) << np.int64(31)
    ev = h.elem_verts
    start, end = _edges(ev)
    valid = np.ones_like(start, dtype=bool)
    valid[ev[:, 3] < 0, 3] = False
    edge_keys = np.unique(_key(start, end, N)[valid])
    on = np.isin(mid_keys, edge_keys)
    v = mid_vertex[on]
    order = np.argsort(v, kind="stable")
    k = mid_keys[on][order]
    return TVertices(v[order], k // N, k % N)


def resolve_tvertices(values: np.ndarray, tv: TVertices) -> np.ndarray:
    """``values (V, k)`` with every T-vertex set to the mean of its edge's ends (in vertex
    order, so a T-vertex whose ends are T-vertices uses their resolved values)."""
    out = np.ascontiguousarray(values, dtype=np.float64).copy()
    if len(tv.vertex):
        flat = out.reshape(len(out), -1)
        resolve_tvertices_kernel(flat, tv.vertex, tv.a, tv.b)
    return out


def refine(h: Hierarchy, vertex_values: np.ndarray,
           evaluate: Callable[[Hierarchy, int, int], np.ndarray], *,
           scale: Callable[[Hierarchy], np.ndarray] | None = None,
           threshold: float = THRESHOLD, min_size: float, max_levels: int = 8
           ) -> tuple[Hierarchy, np.ndarray, TVertices, int]:
    """Split elements whose corner values differ too much, level by level.

    Parameters
    ----------
    vertex_values : (V, k) float64
        The value at every vertex of ``h`` (the direct irradiance ``H``).
    evaluate : callable
        ``evaluate(h_new, start, stop) → (stop − start, k)`` computes the value at the new
        vertices ``start:stop`` of the refined hierarchy (the direct pass on them only).
    scale : callable, optional
        ``scale(h) → (V, k)``, a factor per vertex applied before the spread is tested (the
        reflectance: what must be smooth is the light that leaves, ``ρH``); default 1.
    threshold : float
        Relative spread (see :func:`needs_split`); ``0`` or less disables refinement.
    min_size : float
        Elements whose longest edge is at most this are not split (scene units).

    Returns ``(hierarchy, vertex_values, t_vertices, levels)``: the values at every vertex of
    the refined hierarchy, unscaled.
    """
    values = np.asarray(vertex_values, dtype=np.float64)
    keys = np.zeros(0, np.int64)
    verts = np.zeros(0, np.int64)
    levels = 0
    if threshold <= 0:
        return h, values, TVertices.empty(), 0
    while levels < max_levels:
        tested = values if scale is None else scale(h) * values
        split = needs_split(h, tested, threshold, min_size)
        if not split.any():
            break
        nv = len(h.vertices)
        h, keys, verts = split_elements(h, split, keys, verts)
        values = np.concatenate([values, evaluate(h, nv, len(h.vertices))])
        levels += 1
    return h, values, tvertices(h, keys, verts), levels
