"""Direct light at points: point, directional and area lights with shadow rays
(docs/design.md §1 step 2).

One function, :func:`irradiance_one`, computes the irradiance ``H`` (W per unit area) arriving
at a point ``p`` with unit normal ``n`` from every light, with shadows through the voxel grid;
the vertex pass (:func:`irradiance_points`) and the per-pixel pass (eq. 9, the renderer) both
call it, so a vertex and a pixel at the same place get the same light (the per-pixel pass may
take a light every corner of the element sees whole as visible, without its shadow rays).

- **Point light** ``I`` (W/sr) at ``q``: ``H = I cos θ / r²`` when the segment is free.
- **Directional light** travelling along unit ``w`` with irradiance ``E`` on a surface facing
  it: ``H = E · max(0, −w · n)`` when the ray towards ``−w`` escapes the scene.
- **Area light** (an emitting polygon of radiance ``Le``, one-sided along its normal):
  ``H = π Le F · V``, where ``F`` is Lambert's unoccluded point-to-polygon form factor (exact,
  the polygon clipped to the point's tangent plane) and ``V`` the visible fraction estimated by
  ``s × s`` stratified shadow rays weighted by the kernel ``cos θ cos θ' / r²``, so ``V = 1``
  exactly when nothing blocks the light and the unoccluded answer is exact.

Shadow rays start ``off`` (an absolute length, ``RAY_OFFSET · diag``) above the surface along
its normal and ignore hits within ``off`` of that origin and of the light, so a surface never
shadows itself (no acne), while anything farther than ``off`` blocks. A vertex's rays start
from its point moved ``VERTEX_NUDGE · diag`` (100 offsets) into its polygon
(:func:`daskrad.direct.vertex_points`): a surface meeting the polygon at the vertex (the
ceiling over a wall's top edge) is then met beyond ``off`` and blocks the light that would
have to cross it (issue 14: no light through a closed surface).

Sample positions inside the strata are jittered by a hash of ``(seed, sample)``: the result
depends only on the point's seed (its vertex id, or its pixel sample id), never on batching or
workers, and soft shadows come out as fine noise instead of bands.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.grid import aim_fan, any_hit_cached, any_hit_fan, new_fan
from daskrad.kernels.lambert import lambert_into

_INV_2_53 = 1.0 / 9007199254740992.0

#: What is known of an area light at a point (``int8`` codes). As a vertex's class: the
#: light's form factor is positive and it is wholly visible (``LIGHT_VISIBLE``) or wholly
#: hidden (``LIGHT_HIDDEN``), exactly as the vertex pass computed it; ``LIGHT_TRACE``: neither
#: (a penumbra, or the light below the vertex's horizon). As a mode of the per-pixel pass
#: (:func:`irradiance_one`'s ``modes``): take the light as visible (Lambert's exact unoccluded
#: term, no shadow ray) or trace its shadow rays (:func:`daskrad.render.light_modes`).
LIGHT_TRACE = 0
LIGHT_VISIBLE = 1
LIGHT_HIDDEN = 2


class Scratch(NamedTuple):
    """:func:`irradiance_one`'s working arrays, made once per batch of points
    (:func:`new_scratch`): a leaf allocates nothing (:mod:`daskrad.kernels._jit`)."""

    o: np.ndarray       #: (3,) float64: where the point's shadow rays start
    d: np.ndarray       #: (3,) float64: a shadow ray's direction
    q: np.ndarray       #: (3,) float64: a light's sample point
    seen: np.ndarray    #: (4,) int8: the probed corner strata (-1 untraced, 0 blocked, 1 free)
    poly: np.ndarray    #: (7, 5) float64: :func:`daskrad.kernels.lambert.lambert_into`'s


@jit
def new_scratch():
    """A :class:`Scratch` for :func:`irradiance_one`."""
    return Scratch(np.empty(3), np.empty(3), np.empty(3), np.full(4, -1, np.int8),
                   np.empty((7, 5)))


@jit_leaf
def hash01(seed, k):
    """A uniform number in ``[0, 1)`` from two non-negative integers (splitmix64 finaliser)."""
    z = (np.uint64(seed) * np.uint64(0x9E3779B97F4A7C15)
         + np.uint64(k) * np.uint64(0xD1B54A32D192ED03) + np.uint64(0x632BE59BD9B4E019))
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    z = z ^ (z >> np.uint64(31))
    return float(z >> np.uint64(11)) * _INV_2_53


@jit_leaf
def _sample_polygon(corners, count, u, v, out):
    """A point of the polygon for ``(u, v) ∈ [0,1)²``, written to ``out (3,)``: bilinear on a
    quad, the square-root warp on a triangle (both uniform in area for a parallelogram / any
    triangle). Into a buffer: a new array per shadow ray cost more than the ray itself where
    the blocker cache settles it at its first triangle."""
    if count == 4:
        for k in range(3):
            out[k] = ((1 - u) * (1 - v) * corners[0, k] + u * (1 - v) * corners[1, k]
                      + u * v * corners[2, k] + (1 - u) * v * corners[3, k])
    else:
        su = np.sqrt(u)
        for k in range(3):
            out[k] = ((1.0 - su) * corners[0, k] + su * (1.0 - v) * corners[1, k]
                      + su * v * corners[2, k])


#: Strata per side from which the per-pixel pass probes an area light (``probe``): with fewer
#: the four corner strata are most of the samples.
PROBE_SIDE = 3


@jit_leaf
def _stratum_point(corners, count, seed, m, ss, samples, k, out):
    """The jittered point of stratum ``k`` (of ``samples²``) of area light ``m``, written to
    ``out (3,)``."""
    inv_s = 1.0 / samples
    u = ((k % samples) + hash01(seed, 2 * (m * ss + k))) * inv_s
    v = ((k // samples) + hash01(seed, 2 * (m * ss + k) + 1)) * inv_s
    _sample_polygon(corners, count, u, v, out)


@jit_leaf
def _kernel(p, n, en, q):
    """``cos θ cos θ' / r⁴`` (the weight of a sample ``q`` of a light with normal ``en`` seen
    from ``p`` with normal ``n``; ``1/r²`` more than the point-to-point kernel, for the
    normalised visible fraction), 0 when either side faces away."""
    rx = q[0] - p[0]
    ry = q[1] - p[1]
    rz = q[2] - p[2]
    r2 = rx * rx + ry * ry + rz * rz
    if r2 == 0.0:
        return 0.0
    cos_p = n[0] * rx + n[1] * ry + n[2] * rz
    cos_q = -(en[0] * rx + en[1] * ry + en[2] * rz)
    if cos_p <= 0.0 or cos_q <= 0.0:
        return 0.0
    return cos_p * cos_q / (r2 * r2)


@jit_leaf
def _unblocked(grid, fan, o, q, off, d, slot=-1):
    """Whether the shadow ray from ``o`` to ``q`` is free (``d``: scratch for its direction);
    hits within ``off`` of either end do not count. ``slot``: the fan's blocker cache slot
    (:func:`daskrad.kernels.grid.any_hit_cached`: the light's index; -1 none)."""
    d[0] = q[0] - o[0]
    d[1] = q[1] - o[1]
    d[2] = q[2] - o[2]
    dl = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    return not (dl > 2.0 * off
                and any_hit_cached(grid, fan, o, d, off / dl, 1.0 - off / dl, slot))


@jit_leaf
def _corner_stratum(c, samples):
    """Stratum of corner ``c`` (0–3) of the ``samples × samples`` grid."""
    i = 0 if c % 2 == 0 else samples - 1
    j = 0 if c < 2 else samples - 1
    return j * samples + i


@jit_leaf
def _which_corner(k, samples):
    """Which corner stratum (0–3) stratum ``k`` is, or −1."""
    i = k % samples
    j = k // samples
    if (i != 0 and i != samples - 1) or (j != 0 and j != samples - 1):
        return -1
    return (0 if i == 0 else 1) + (0 if j == 0 else 2)


@jit_leaf
def irradiance_one(grid, fan, work, p, pa, n, off, seed, pl_pos, pl_int, dl_dir, dl_irr,
                   em_corners, em_count, em_normal, em_radiance, em_area, samples,
                   view, ks, ns, modes, out_h, out_spec, out_class, probe=False,
                   lambert_first=True):
    """Direct irradiance at one point, added to ``out_h (3,)``.

    Parameters
    ----------
    grid : Grid
    fan : Fan
        Scratch of :func:`daskrad.kernels.grid.new_fan` for ``grid``: the shadow rays leave
        from one origin above the surface, so its own triangles are tested once, not per ray;
        with a blocker cache slot per area light (``new_fan(grid, M)``), a ray first tries
        the triangle that blocked the last ray to its light (the same answer, sooner).
    work : Scratch
        Working arrays (:func:`new_scratch`), overwritten.
    p, n : (3,) float64
        The point and its unit normal (the lit side).
    pa : (3,) float64
        Where area lights are evaluated and every shadow ray starts (offset ``off`` along
        ``n``): ``p`` itself, or for a vertex on a polygon's boundary ``p`` moved a hair into
        the polygon (the limit from inside). Point lights' ``cos θ / r²`` is taken at ``p``.
    off : float
        Shadow-ray offset, an absolute length.
    seed : int
        Jitter seed of this point (≥ 0).
    pl_pos, pl_int : (L, 3) float64
        Point lights: positions, intensities (W/sr).
    dl_dir, dl_irr : (D, 3) float64
        Directional lights: unit travel directions, irradiance facing the light.
    em_corners : (M, 4, 3) float64
        Emitting polygons (row 3 unused for a triangle); ``em_count (M,) int64`` corners,
        ``em_normal (M, 3)`` unit emitting side, ``em_radiance (M, 3)`` ``Le``, ``em_area (M,)``.
    samples : int
        Shadow rays per area light: ``samples²``, stratified.
    view : (3,) float64
        Unit direction from ``p`` to the eye, for the specular term.
    ks : (3,) float64, ns : float
        Phong ``Ks`` and ``Ns``; when ``ks`` is all 0 no specular work is done.
    modes : (M,) int8
        Per area light: ``LIGHT_TRACE`` (shadow rays), ``LIGHT_VISIBLE`` (taken as wholly
        visible: the rays are not cast, so ``V = 1``; the same bits as tracing them where no
        ray would have been blocked) or ``LIGHT_HIDDEN`` (skipped: the same bits as tracing
        them where every ray would have been blocked).
    out_spec : (3,) float64
        Receives the Phong radiance ``Ks (Ns+2)/(2π) max(0, r·v)^Ns dH`` summed over lights
        (``r`` the light direction mirrored about ``n``).
    out_class : (M,) int8
        Receives each area light's class at the point: ``LIGHT_VISIBLE`` when ``F > 0`` and
        no shadow ray was blocked, ``LIGHT_HIDDEN`` when ``F > 0`` and every ray was (with
        ``lambert_first=False``: when a sample of the light faces the point and every ray
        was blocked, ``F`` not computed), ``LIGHT_TRACE`` otherwise.
    probe : bool
        With ``samples >= PROBE_SIDE``, trace a light's four corner strata first; when all four
        face both ways and agree (all free, or all blocked), the other strata are taken as
        they are, untraced (``samples² − 4`` rays spared). A disagreement traces
        the rest as without probing (the corners' own rays are reused), so the answer then
        has the same bits; an agreement is wrong only where a shadow or a gap falls wholly
        between the corner strata, and ``out_class`` then reports the class assumed. On a
        triangle light the square-root warp puts two corner strata beside its first vertex,
        so three of its corners are probed. The per-pixel pass probes (:data:`daskrad.render.
        SHADOW_PROBES`); the vertex pass does not (a vertex's classes must be exact).
    lambert_first : bool
        Lambert's ``F`` of an area light before its shadow rays (``out_class`` needs it: a
        light is hidden only where ``F > 0``). ``False`` (the per-pixel pass): where there is
        no specular term, ``F`` is computed after the rays, and only when one of them is
        free: a light every ray finds blocked adds ``π Le F · 0 = +0.0`` whatever ``F`` is,
        so the irradiance has the same bits; ``out_class`` is then ``LIGHT_HIDDEN`` where a
        sample of the light faces the point (``F`` itself is not computed). Most lights a
        pixel of a furnished interior traces are hidden (RenderPark's office: ``F`` took a
        quarter of an edge sample's time).
    """
    spec = ks[0] > 0.0 or ks[1] > 0.0 or ks[2] > 0.0
    norm_spec = (ns + 2.0) / (2.0 * np.pi)
    # shadow rays of every light leave from pa: for a vertex on a junction (a wall's top edge
    # under the ceiling) a surface through the vertex is then met beyond the offset and
    # blocks, instead of letting light through the closed surface
    o = work.o
    for k in range(3):
        o[k] = pa[k] + off * n[k]
    aim_fan(fan, grid, o, n, off)
    d = work.d
    q = work.q            # a light's sample point
    # ---- point lights
    for li in range(pl_pos.shape[0]):
        # cos θ / r² from the surface point itself (not the offset origin): exact I cosθ/r²
        rx = pl_pos[li, 0] - p[0]
        ry = pl_pos[li, 1] - p[1]
        rz = pl_pos[li, 2] - p[2]
        r2 = rx * rx + ry * ry + rz * rz
        if r2 == 0.0:
            continue
        r = np.sqrt(r2)
        cos = (n[0] * rx + n[1] * ry + n[2] * rz) / r
        if cos <= 0.0:
            continue
        if not _unblocked(grid, fan, o, pl_pos[li], off, d):
            continue
        g = cos / r2
        for c in range(3):
            out_h[c] += pl_int[li, c] * g
        if spec:
            _phong(n, rx / r, ry / r, rz / r, view, ks, ns, norm_spec, g, pl_int[li], out_spec)
    # ---- directional lights
    for li in range(dl_dir.shape[0]):
        cos = -(n[0] * dl_dir[li, 0] + n[1] * dl_dir[li, 1] + n[2] * dl_dir[li, 2])
        if cos <= 0.0:
            continue
        d[0] = -dl_dir[li, 0]
        d[1] = -dl_dir[li, 1]
        d[2] = -dl_dir[li, 2]
        if any_hit_fan(grid, fan, o, d, off, np.inf):
            continue
        for c in range(3):
            out_h[c] += dl_irr[li, c] * cos
        if spec:
            _phong(n, d[0], d[1], d[2], view, ks, ns, norm_spec, cos, dl_irr[li], out_spec)
    # ---- area lights, from pa
    if em_corners.shape[0] == 0:
        return
    p = pa
    ss = samples * samples
    # probing (the per-pixel pass): the light's four corner strata are traced first
    probing = probe and samples >= PROBE_SIDE
    seen = work.seen      # per corner: -1 untraced, 0 blocked, 1 free (only when probing)
    # F after the rays where nothing else needs it (lambert_first)
    lazy = not (lambert_first or spec)
    for m in range(em_corners.shape[0]):
        out_class[m] = LIGHT_TRACE
        if modes[m] == LIGHT_HIDDEN:
            # proved hidden from the point (daskrad.kernels.hidden): every ray would be
            # blocked and the light add +0.0; its class is left LIGHT_TRACE
            continue
        trace = modes[m] != LIGHT_VISIBLE
        cnt = em_count[m]
        en = em_normal[m]
        # one-sided emitter: p must lie strictly on its emitting side
        side = (en[0] * (p[0] - em_corners[m, 0, 0]) + en[1] * (p[1] - em_corners[m, 0, 1])
                + en[2] * (p[2] - em_corners[m, 0, 2]))
        if side <= 0.0:
            continue
        F = 0.0
        if not lazy:
            F = lambert_into(p[0], p[1], p[2], n[0], n[1], n[2], em_corners[m], cnt,
                             work.poly)
            if F <= 0.0:
                continue
        # agree: -1 trace every stratum; 0 / 1: the four corner strata all face both ways and
        # were all blocked / all free, so the others are taken as they, untraced
        agree = -1
        if trace and probing:
            free = 0
            blocked = 0
            for c in range(4):
                k = _corner_stratum(c, samples)
                _stratum_point(em_corners[m], cnt, seed, m, ss, samples, k, q)
                seen[c] = -1
                if _kernel(p, n, en, q) > 0.0:
                    seen[c] = 1 if _unblocked(grid, fan, o, q, off, d, m) else 0
                    free += seen[c]
                    blocked += 1 - seen[c]
            if free == 4:
                agree = 1
            elif blocked == 4:
                agree = 0
        wsum = 0.0
        wvis = 0.0
        for k in range(ss):
            _stratum_point(em_corners[m], cnt, seed, m, ss, samples, k, q)
            w = _kernel(p, n, en, q)
            if w <= 0.0:
                continue
            wsum += w
            if trace:
                if agree >= 0:
                    visible = agree == 1
                else:
                    c = _which_corner(k, samples) if probing else -1
                    visible = (seen[c] == 1 if c >= 0
                               else _unblocked(grid, fan, o, q, off, d, m))
                if not visible:
                    continue
            wvis += w
            if spec:
                # the sample stands for area/ss of the light: dH = Le cos cos' dA / r²
                rx = q[0] - p[0]
                ry = q[1] - p[1]
                rz = q[2] - p[2]
                r = np.sqrt(rx * rx + ry * ry + rz * rz)
                g = w * em_area[m] / ss
                _phong(n, rx / r, ry / r, rz / r, view, ks, ns, norm_spec, g, em_radiance[m],
                       out_spec)
        if wsum <= 0.0:
            continue
        if lazy:
            if wvis == 0.0:
                # every ray blocked: +0.0 whatever F is. A sample of the light faces the
                # point (wsum > 0), so some of it is above the horizon: hidden.
                out_class[m] = LIGHT_HIDDEN
                continue
            F = lambert_into(p[0], p[1], p[2], n[0], n[1], n[2], em_corners[m], cnt,
                             work.poly)
            if F <= 0.0:
                continue
        if wvis == wsum:
            out_class[m] = LIGHT_VISIBLE
        elif wvis == 0.0:
            out_class[m] = LIGHT_HIDDEN
        vis = wvis / wsum
        for c in range(3):
            out_h[c] += np.pi * em_radiance[m, c] * F * vis


@jit_leaf
def _phong(n, lx, ly, lz, view, ks, ns, norm_spec, g, power, out_spec):
    """Add ``Ks (Ns+2)/(2π) max(0, r·v)^Ns · g · power`` (``r``: ``l`` mirrored about ``n``)."""
    dn = lx * n[0] + ly * n[1] + lz * n[2]
    rx = 2.0 * dn * n[0] - lx
    ry = 2.0 * dn * n[1] - ly
    rz = 2.0 * dn * n[2] - lz
    c = rx * view[0] + ry * view[1] + rz * view[2]
    if c <= 0.0:
        return
    f = norm_spec * c ** ns * g
    for k in range(3):
        out_spec[k] += ks[k] * f * power[k]


@jit
def irradiance_points(grid, points, area_points, normals, seeds, off, pl_pos, pl_int, dl_dir,
                      dl_irr, em_corners, em_count, em_normal, em_radiance, em_area, samples):
    """Direct irradiance ``H (n, 3) float64`` at ``points (n, 3)`` with unit ``normals (n, 3)``,
    and each area light's class there, ``(n, M) int8`` (:func:`irradiance_one`'s
    ``out_class``); area lights are evaluated at ``area_points (n, 3)``; ``seeds (n,) int64``
    jitter the area-light samples (see :func:`irradiance_one`)."""
    npts = points.shape[0]
    n_em = em_corners.shape[0]
    out = np.zeros((npts, 3))
    classes = np.zeros((npts, n_em), np.int8)
    spec = np.zeros(3)
    ks = np.zeros(3)
    view = np.zeros(3)
    modes = np.full(n_em, LIGHT_TRACE, np.int8)
    fan = new_fan(grid, n_em)      # a blocker cache slot per area light
    work = new_scratch()
    for i in range(npts):
        irradiance_one(grid, fan, work, points[i], area_points[i], normals[i], off, seeds[i],
                       pl_pos, pl_int, dl_dir, dl_irr, em_corners, em_count, em_normal,
                       em_radiance, em_area, samples, view, ks, 0.0, modes, out[i], spec,
                       classes[i])
    return out, classes
