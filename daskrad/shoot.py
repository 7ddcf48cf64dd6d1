"""The form-factor task: sparse rows ``F_ij`` for a batch of shooting patches.

This is the unit of work the paper parallelised ("form factors for batches of a constant number
of patches"): it reads geometry only and returns small results, so it runs the same in-process
and on a Dask worker (:mod:`daskrad.distributed` calls :func:`shoot_rows` with a context it
caches per store generation).

Near field (DESIGN §2): a form factor sampled at one point of the shooter is exact only far
away. Where some receiver is close relative to the shooter's size, the shooter is sampled at
``s × s`` stratified points (sub-patch centroids, weighted by sub-patch area) and the rows are
averaged. Each sample's row sums to at most 1 (the hemisphere's disc weights sum to 1), so the
average does too: a shot never sends more energy than the shooter holds.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from daskrad import formfactor
from daskrad.mesh.types import Hierarchy

#: A receiver closer to the shooter's centroid than ``NEAR_FIELD × radius`` counts as near.
#: Point-sampling a shooter of radius r for a receiver at distance d errs by O((r/d)²); at
#: d = 4r that is a few per cent, beyond it less than the raster's own error at R = 256.
NEAR_FIELD = 4.0
#: Stratified samples per side for a shooter with near receivers (s² samples in all).
NEAR_SAMPLES = 4


@dataclass(frozen=True)
class ShootContext:
    """Everything a form-factor task reads: geometry arrays and the method's settings.

    Shapes follow :class:`daskrad.mesh.types.Hierarchy`. ``near_samples[p]`` is the number of
    samples per side for patch ``p`` (1 or ``NEAR_SAMPLES``), fixed once per mesh generation.
    """

    vertices: np.ndarray
    elem_verts: np.ndarray
    patch_verts: np.ndarray
    patch_normal: np.ndarray
    near_samples: np.ndarray
    method: str
    resolution: int
    options: dict


def near_samples(h: Hierarchy) -> np.ndarray:
    """``(P,) int64``: samples per side for each patch, from the distance to its nearest receiver.

    A receiver is an element of another polygon, in front of the shooter (centroid above the
    shooter's plane) and facing it. Vectorised over elements, looped over patches in chunks.
    """
    out = np.ones(h.n_patches, np.int64)
    corners = _patch_corners(h)
    radius = np.linalg.norm(corners - h.patch_centroid[:, None, :], axis=2).max(axis=1)
    elem_poly = h.elem_polygon
    for p in range(h.n_patches):
        d = h.elem_centroid - h.patch_centroid[p]
        height = d @ h.patch_normal[p]
        facing = np.einsum("ij,ij->i", -d, h.elem_normal) > 0
        mask = (height > 1e-9 * radius[p]) & facing & (elem_poly != h.patch_polygon[p])
        if not mask.any():
            continue
        dist = np.sqrt((d[mask] ** 2).sum(axis=1)).min()
        if dist < NEAR_FIELD * radius[p]:
            out[p] = NEAR_SAMPLES
    return out


def _patch_corners(h: Hierarchy) -> np.ndarray:
    """``(P, 4, 3)``: patch corners; a triangle repeats its third corner as the fourth."""
    pv = h.patch_verts.copy()
    tri = pv[:, 3] < 0
    pv[tri, 3] = pv[tri, 2]
    return h.vertices[pv]


def make_context(h: Hierarchy, method: str, resolution: int, **options) -> ShootContext:
    formfactor.get_method(method)  # refuse an unknown method before any work starts
    return ShootContext(
        vertices=h.vertices, elem_verts=h.elem_verts, patch_verts=h.patch_verts,
        patch_normal=h.patch_normal, near_samples=near_samples(h), method=method,
        resolution=resolution, options=dict(options),
    )


def sample_points(corners: np.ndarray, is_triangle: bool, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Stratified points on a planar patch and their area weights (summing to 1).

    ``corners : (4, 3)``. A quad is split bilinearly into ``s × s`` sub-quads, a triangle into
    ``s²`` similar sub-triangles; each sample is a sub-cell's centroid, weighted by its area.
    Returns ``points (n, 3)``, ``weights (n,)``.
    """
    if s == 1:
        if is_triangle:
            return corners[:3].mean(axis=0)[None], np.ones(1)
        cells = corners[None]
    elif is_triangle:
        a, b, c = corners[:3]
        cells = []
        for i in range(s):
            for j in range(s - i):
                p0 = a + (b - a) * i / s + (c - a) * j / s
                du, dv = (b - a) / s, (c - a) / s
                cells.append([p0, p0 + du, p0 + dv, p0 + dv])
                if i + j < s - 1:
                    cells.append([p0 + du, p0 + du + dv, p0 + dv, p0 + dv])
        cells = np.array(cells)
    else:
        t = np.linspace(0.0, 1.0, s + 1)
        a, b, c, d = corners
        grid = ((1 - t)[:, None, None] * ((1 - t)[None, :, None] * a + t[None, :, None] * b)
                + t[:, None, None] * ((1 - t)[None, :, None] * d + t[None, :, None] * c))
        cells = np.stack([grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]], axis=2)
        cells = cells.reshape(-1, 4, 3)
    points, areas = _cell_centroids(cells)
    return points, areas / areas.sum()


def _cell_centroids(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted centroids and areas of planar cells ``(n, 4, 3)`` (fan of two triangles;
    a triangle has its last corner repeated, giving a zero-area second half)."""
    a, b, c, d = (cells[:, k] for k in range(4))
    a1 = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    a2 = 0.5 * np.linalg.norm(np.cross(c - a, d - a), axis=1)
    g1 = (a + b + c) / 3.0
    g2 = (a + c + d) / 3.0
    area = a1 + a2
    return (g1 * a1[:, None] + g2 * a2[:, None]) / area[:, None], area


def shoot_rows(ctx: ShootContext, patch_ids: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Form-factor rows of the shooters ``patch_ids``, in that order.

    Returns a list of ``(ids (k,) int32, factors (k,) float64)``: the elements with a nonzero
    form factor from the shooter and the factors ``F_ij`` (patch-area average over the
    shooter's sample points), ``Σ factors ≤ 1``.
    """
    rows = []
    for p in np.asarray(patch_ids):
        pv = ctx.patch_verts[p]
        tri = pv[3] < 0
        corners = ctx.vertices[np.where(pv < 0, pv[2], pv)]
        points, weights = sample_points(corners, bool(tri), int(ctx.near_samples[p]))
        normals = np.broadcast_to(ctx.patch_normal[p], points.shape)
        F = formfactor.shooter_rows(points, np.ascontiguousarray(normals), ctx.vertices,
                                    ctx.elem_verts, method=ctx.method,
                                    resolution=ctx.resolution, **ctx.options)
        row = weights @ F
        ids = np.flatnonzero(row > 0).astype(np.int32)
        rows.append((ids, row[ids]))
    return rows
