"""The form-factor task: sparse rows ``F_ij`` for a batch of shooting patches.

This is the unit of work the paper parallelised ("form factors for batches of a constant number
of patches"): it reads geometry only and returns small results, so it runs the same in-process
and on a Dask worker (:mod:`daskrad.distributed` calls :func:`shoot_rows` with a context it
caches per store generation).

Near field (DESIGN §2). A form factor sampled at the shooter's centroid is exact only far away:
for a receiver at distance ``d`` from a shooter of radius ``r`` it errs by O((r/d)²), which is
the error that dominates flat radiosity along junctions (wall meets ceiling). For receivers
closer than ``NEAR_FIELD · r`` the shooter is not point-sampled: by reciprocity
``F_ij = F_ji · A_j / A_i``, and ``F_ji`` — from the receiver's centroid to the *whole* shooter
polygon — is Lambert's contour integral, exact in the shooter's extent. Occlusion is taken from
the method's own row at the centroid: the visible fraction of receiver ``j`` is its factor over
Lambert's unoccluded one from the same point (``won / covered`` for the default hemisphere
method), so one form-factor pass serves both. The near receivers' factors are then scaled so
that together they take exactly the share of energy the hemisphere pass gave them: the row sum
stays that of the hemisphere (≤ 1, and = 1 in a closed scene), so a shot never sends more
energy than the shooter holds, and only the distribution among near receivers changes.

``F_ji`` itself is an area average over the receiver (:func:`receiver_average`): a receiver
that shares an edge or a corner with the shooter sees it from a point-to-polygon factor that
varies as fast as the distance to the shared edge, so its centroid is not enough there.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from daskrad import formfactor
from daskrad.mesh.types import Hierarchy

#: A receiver closer to the shooter's centroid than ``NEAR_FIELD × radius`` is near: there the
#: point-sampled factor errs by more than a few per cent, (r/d)² > 1/16.
NEAR_FIELD = 4.0

#: A near receiver closer to the shooter than ``CLOSE ×`` its own size (``√A_j``) averages
#: ``F_ji`` over ``STRATA²`` points per triangle instead of taking it at its centroid.
CLOSE = 2.0
STRATA = 2


@dataclass(frozen=True)
class ShootContext:
    """Everything a form-factor task reads: geometry arrays and the method's settings.

    Shapes follow :class:`daskrad.mesh.types.Hierarchy`; ``patch_radius : (P,)`` is the largest
    distance from a patch's centroid to its corners.
    """

    vertices: np.ndarray
    elem_verts: np.ndarray
    elem_area: np.ndarray
    elem_centroid: np.ndarray
    elem_normal: np.ndarray
    elem_polygon: np.ndarray
    patch_verts: np.ndarray
    patch_polygon: np.ndarray
    patch_area: np.ndarray
    patch_centroid: np.ndarray
    patch_normal: np.ndarray
    patch_radius: np.ndarray
    method: str
    resolution: int
    options: dict


def make_context(h: Hierarchy, method: str, resolution: int, **options) -> ShootContext:
    """The task context of a hierarchy; refuses an unknown method before any work starts."""
    formfactor.get_method(method)
    pv = np.where(h.patch_verts < 0, h.patch_verts[:, 2:3], h.patch_verts)
    radius = np.linalg.norm(h.vertices[pv] - h.patch_centroid[:, None, :], axis=2).max(axis=1)
    return ShootContext(
        vertices=h.vertices, elem_verts=h.elem_verts, elem_area=h.elem_area,
        elem_centroid=h.elem_centroid, elem_normal=h.elem_normal, elem_polygon=h.elem_polygon,
        patch_verts=h.patch_verts, patch_polygon=h.patch_polygon, patch_area=h.patch_area,
        patch_centroid=h.patch_centroid, patch_normal=h.patch_normal, patch_radius=radius,
        method=method, resolution=resolution, options=dict(options),
    )


def shoot_row(ctx: ShootContext, p: int) -> np.ndarray:
    """``(E,) float64``: the form factors ``F_pj`` from patch ``p`` to every element."""
    point = ctx.patch_centroid[p][None]
    normal = ctx.patch_normal[p][None]
    row = formfactor.shooter_rows(point, normal, ctx.vertices, ctx.elem_verts,
                                  method=ctx.method, resolution=ctx.resolution,
                                  **ctx.options)[0]
    offset = ctx.elem_centroid - ctx.patch_centroid[p]
    near = ((np.einsum("ij,ij->i", offset, offset) < (NEAR_FIELD * ctx.patch_radius[p]) ** 2)
            & (ctx.elem_polygon != ctx.patch_polygon[p]))
    near &= row > 0
    if not near.any():
        return row
    ids = np.flatnonzero(near)
    # the method's own visibility of each near receiver: its factor over the unoccluded one
    # from the same point (won/covered for the default hemisphere method, exactly)
    unoccluded = formfactor.analytic_rows(point, normal, ctx.vertices, ctx.elem_verts[ids])[0]
    visible = np.clip(row[ids] / np.where(unoccluded > 0, unoccluded, np.inf), 0.0, 1.0)
    visible[unoccluded <= 0] = 1.0
    # F_ji from each near receiver to the whole shooter polygon (Lambert, exact in the
    # shooter's extent, averaged over the receiver), then F_ij = F_ji · A_j / A_i by reciprocity
    F_ji = receiver_average(ctx, p, ids)
    exact = F_ji * ctx.elem_area[ids] / ctx.patch_area[p] * visible
    share = row[ids].sum()
    if exact.sum() > 0:
        row[ids] = exact * (share / exact.sum())
    return row


def _strata(s: int) -> np.ndarray:
    """``(s², 3) float64``: barycentric centroids of the ``s²`` congruent sub-triangles of a
    triangle cut ``s`` times along each edge (equal areas, so equal weights)."""
    i, j = np.meshgrid(np.arange(s), np.arange(s), indexing="ij")
    up, down = i + j <= s - 1, i + j <= s - 2
    a = np.concatenate([i[up] + 1 / 3, i[down] + 2 / 3]) / s
    b = np.concatenate([j[up] + 1 / 3, j[down] + 2 / 3]) / s
    return np.column_stack([1.0 - a - b, a, b])


def receiver_average(ctx: ShootContext, p: int, ids: np.ndarray) -> np.ndarray:
    """``(k,) float64``: ``F_ji`` from each receiver element ``ids`` to the whole patch ``p``
    (Lambert's contour integral, no occlusion), averaged over the receiver's area.

    ``F_ji = (1/A_j) ∫_{A_j} F(x → i) dx``; far from the shooter the centroid is enough, but
    for a receiver within ``CLOSE`` of its own sizes of the shooter (sharing an edge or a
    corner with it, or a small gap) ``F(x → i)`` varies over the receiver as fast as the
    distance does, so the integral is taken over ``STRATA²`` stratified points of each of the
    receiver's triangles (a quad is two), area-weighted.
    """
    c = ctx.elem_centroid[ids]
    nrm = ctx.elem_normal[ids]
    shooter = ctx.patch_verts[p:p + 1]
    rel = c - ctx.patch_centroid[p]
    # a lower bound of the distance from the centroid to the shooter polygon
    dist = np.maximum(np.abs(rel @ ctx.patch_normal[p]),
                      np.linalg.norm(rel, axis=1) - ctx.patch_radius[p])
    close = dist < CLOSE * np.sqrt(ctx.elem_area[ids])
    F = np.empty(len(ids))
    if (~close).any():
        F[~close] = formfactor.analytic_rows(c[~close], nrm[~close], ctx.vertices,
                                             shooter)[:, 0]
    if close.any():
        ev = ctx.elem_verts[ids[close]]
        ev = np.where(ev < 0, ev[:, 2:3], ev)             # a triangle: second half empty
        corners = ctx.vertices[ev]                        # (m, 4, 3)
        halves = corners[:, [[0, 1, 2], [0, 2, 3]]]       # (m, 2, 3, 3)
        area = 0.5 * np.linalg.norm(np.cross(halves[:, :, 1] - halves[:, :, 0],
                                             halves[:, :, 2] - halves[:, :, 0]), axis=2)
        bary = _strata(STRATA)
        pts = np.einsum("kc,mhcx->mhkx", bary, halves).reshape(-1, 3)
        k = 2 * len(bary)
        f = formfactor.analytic_rows(pts, np.repeat(nrm[close], k, axis=0), ctx.vertices,
                                     shooter)[:, 0].reshape(-1, 2, len(bary))
        F[close] = (f.mean(axis=2) * area).sum(axis=1) / area.sum(axis=1)
    return F


def shoot_rows(ctx: ShootContext, patch_ids: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Form-factor rows of the shooters ``patch_ids``, in that order.

    Returns a list of ``(ids (k,) int32, factors (k,) float64)``: the elements with a nonzero
    form factor from the shooter and the factors ``F_ij``, ``Σ factors ≤ 1``.
    """
    rows = []
    for p in np.asarray(patch_ids):
        row = shoot_row(ctx, int(p))
        ids = np.flatnonzero(row > 0).astype(np.int32)
        rows.append((ids, row[ids]))
    return rows
