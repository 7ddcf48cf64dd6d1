"""Per-pixel lighting: direct light and Phong highlights at ray hits
(docs/design.md §1 step 4, eq. 9).

The renderer interpolates vertex radiance everywhere, then calls :func:`direct_at_hits` on the
few hits that need more: hits on elements whose vertex colours spread more than ``Rdiff``
(paper eq. 9: their direct light is recomputed at the hit as at a vertex) and hits on
materials with a specular part (a Phong lobe from every light). Both go through
:func:`daskrad.kernels.direct.irradiance_one`, so a pixel and a vertex at the same place get the
same direct light, with the same robust shadow-ray offset, through the same grid over the
scene's polygons (:func:`daskrad.preprocess.occluders`; both passes' ``POLYGON_OCCLUDERS``
flags, and the grid over the elements for a store written before it); only an area light
every corner of the hit's element sees whole is taken as visible without its shadow rays
(``modes``, :func:`daskrad.render.light_modes`), and with ``probe`` a traced light whose four
corner strata agree is taken as they are (:func:`daskrad.kernels.direct.irradiance_one`).

Area-light shadow rays are stratified and jittered by a hash of the hit's ``seed`` (its pixel
sample id, see :func:`daskrad.render.sample_ids`): a pixel's value depends on the pixel, never
on the tile or the worker that computed it, and a penumbra comes out as fine noise, not bands.
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.direct import LIGHT_TRACE, irradiance_one, new_scratch
from daskrad.kernels.grid import new_fan


@jit
def direct_at_hits(grid, points, normals, views, seeds, ks, ns, off, pl_pos, pl_int, dl_dir,
                   dl_irr, em_corners, em_count, em_normal, em_radiance, em_area, samples,
                   modes, probe=False, lambert_first=False, cache=True, out_class=None):
    """Direct irradiance and Phong radiance at ray hits.

    Parameters
    ----------
    points, normals : (n, 3) float64
        Hit points and the unit normal of the lit side of the surface hit.
    views : (n, 3) float64
        Unit directions from each hit back along its ray (towards the eye).
    seeds : (n,) int64
        Jitter seed of each hit (its pixel sample id), ≥ 0.
    ks : (n, 3) float64, ns : (n,) float64
        Phong ``Ks``, ``Ns`` of the material hit; a row of zeros skips the specular work.
    off : float
        Shadow-ray offset, an absolute length.
    pl_pos ... em_area, samples
        The lights, as :func:`daskrad.kernels.direct.irradiance_one` takes them.
    modes : (n, M) int8
        Per hit and area light, trace its shadow rays, take it as wholly visible or skip it
        as proved hidden (:data:`daskrad.kernels.direct.LIGHT_TRACE`, ``LIGHT_VISIBLE``,
        ``LIGHT_HIDDEN``).
    probe : bool
        Probe each traced area light from its corner strata first (``irradiance_one``'s
        ``probe``; the renderer passes :data:`daskrad.render.SHADOW_PROBES`).
    lambert_first : bool
        Lambert's ``F`` of each area light before its rays (``irradiance_one``'s; ``False``,
        after them and only for a light one of them reaches: the same bits, faster).
    cache : bool
        Each area light's shadow rays try the triangle that blocked its last ray first
        (:func:`daskrad.kernels.grid.any_hit_cached`; the hits of a tile come pixel by pixel,
        so the next is most often hidden by the same triangle): the same bits, faster.
    out_class : (n, M) int8, optional
        Receives each area light's class at each hit (``irradiance_one``'s ``out_class``:
        ``LIGHT_VISIBLE`` where no shadow ray was blocked or ``modes`` takes the light as
        visible, ``LIGHT_HIDDEN`` where every ray was, with probes the class the corner
        strata agreed on; ``LIGHT_TRACE`` otherwise and for a light ``modes`` skips).

    Returns ``H (n, 3)``, the irradiance (W per unit area), and ``S (n, 3)``, the Phong
    radiance ``Σ_lights Ks (Ns+2)/(2π) max(0, r·v)^Ns dH``.
    """
    n = points.shape[0]
    H = np.zeros((n, 3))
    S = np.zeros((n, 3))
    fan = new_fan(grid, em_corners.shape[0] if cache else 0)   # a cache slot per area light
    if out_class is None:       # pruned at compile time: one specialization each
        classes = np.zeros((n, em_corners.shape[0]), np.int8)
    else:
        classes = out_class
    work = new_scratch()
    for i in range(n):
        irradiance_one(grid, fan, work, points[i], points[i], normals[i], off, seeds[i], pl_pos,
                       pl_int, dl_dir, dl_irr, em_corners, em_count, em_normal, em_radiance,
                       em_area, samples, views[i], ks[i], ns[i], modes[i], H[i], S[i],
                       classes[i], probe, lambert_first)
    return H, S


@jit
def pixel_modes(modes, elem, pixel, base_elem, base_class, own):
    """The area lights' modes at an edge pixel's extra samples, from what the base samples
    around it found.

    An edge pixel (:func:`daskrad.render.render_tile_stats`) is sampled again at many
    positions; most of its area lights shine on all of it or on none, and only the light or
    the outline that made it an edge changes across it. An extra sample on element ``e``
    takes a light as wholly visible or wholly hidden, without shadow rays, where every base
    sample of its pixel lies on ``e`` and found the light so (``LIGHT_VISIBLE``: no shadow ray
    blocked; ``LIGHT_HIDDEN``: every one; probes included), and so did every base sample of
    the 8 neighbouring pixels that lies on ``e`` (a shadow's edge that flagged the pixel
    from beside it, and may cross it between its samples, shows there).

    Parameters
    ----------
    modes : (n, M) int8
        The extra samples' modes from their elements (:func:`daskrad.render.light_modes`);
        only ``LIGHT_TRACE`` entries change.
    elem : (n,) int64
        The element each extra sample hit.
    pixel : (n,) int64
        Its pixel, a row of ``base_elem``.
    base_elem : (P, s) int64
        The element each base sample hit where its direct light was computed (-1 elsewhere):
        the pixel's own ``own`` samples first, then its neighbours'.
    base_class : (P, s, M) int8
        Each light's class at each base sample (:func:`direct_at_hits`' ``out_class``).
    own : int
        Base samples per pixel.

    Returns ``(n, M) int8``: ``modes`` with the lights so agreed on taken as they were found.
    """
    out = modes.copy()
    on = np.empty(base_elem.shape[1], np.int64)    # the base samples on the sample's element
    for i in range(modes.shape[0]):
        k = pixel[i]
        cnt = 0
        for s in range(base_elem.shape[1]):
            if base_elem[k, s] == elem[i]:
                on[cnt] = s
                cnt += 1
            elif s < own:
                cnt = 0             # a sample of the pixel itself elsewhere: no verdict
                break
        if cnt == 0:
            continue
        for m in range(modes.shape[1]):
            if modes[i, m] != LIGHT_TRACE:
                continue
            c = base_class[k, on[0], m]
            if c == LIGHT_TRACE:
                continue
            same = True
            for j in range(1, cnt):
                if base_class[k, on[j], m] != c:
                    same = False
                    break
            if same:
                out[i, m] = c
    return out


@jit_leaf
def _interpolate(values, tri_verts, t, u, v, out, k):
    """``out[k] = (1 − u − v) values[a] + u values[b] + v values[c]``, ``(a, b, c) =
    tri_verts[t]``, summed in that order (inlined by LLVM: the same time as written out)."""
    a = tri_verts[t, 0]
    b = tri_verts[t, 1]
    c = tri_verts[t, 2]
    w = 1.0 - u - v
    for ch in range(3):
        out[k, ch] = w * values[a, ch] + u * values[b, ch] + v * values[c, ch]


@jit
def gouraud(values, tri_verts, tri, u, v):
    """``(n, 3) float64``: ``values (V, 3)`` interpolated at the points ``(u[k], v[k])`` of the
    triangles ``tri[k]`` (rows of ``tri_verts (T, 3)``): ``(1 − u − v) values[a] + u values[b]
    + v values[c]``, summed in that order (Gouraud shading, one pass without NumPy's
    temporaries and without the GIL)."""
    n = tri.shape[0]
    out = np.empty((n, 3))
    for k in range(n):
        _interpolate(values, tri_verts, tri[k], u[k], v[k], out, k)
    return out


@jit
def shade_hits(values, tri_verts, tri_element, elem_normal, directions, tri, u, v):
    """``(L (n, 3), front (n,) bool)`` along rays of unit ``directions (n, 3)`` that met
    triangles ``tri (n,)`` (-1: none) at ``(u, v)``: the :func:`gouraud` radiance of
    ``values (V, 3)`` where the ray meets the front of the triangle's element (``d · n < 0``,
    ``elem_normal[tri_element[tri]]``, summed left to right), 0 for a miss or the back of a
    face (one-sided surfaces); ``front`` says which."""
    n = tri.shape[0]
    out = np.zeros((n, 3))
    front = np.zeros(n, np.bool_)
    for k in range(n):
        t = tri[k]
        if t < 0:
            continue
        e = tri_element[t]
        if not (directions[k, 0] * elem_normal[e, 0] + directions[k, 1] * elem_normal[e, 1]
                + directions[k, 2] * elem_normal[e, 2]) < 0.0:
            continue
        front[k] = True
        _interpolate(values, tri_verts, t, u[k], v[k], out, k)
    return out, front
