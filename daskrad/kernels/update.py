"""The client's radiosity update for one shot (docs/design.md §4), one pass over the receivers.

Replaces a NumPy version that gathered, multiplied and ran three ``bincount`` passes per shot:
the update is the client's share of a shot's time, and on a 2-core machine the client competes
with the workers for the cores (issue 4's scaling benchmark).
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit_leaf


@jit_leaf
def apply_shot(radiosity, unshot, shooter, ids, factors, reflectance, elem_area, elem_patch,
               patch_area, acc, touched, order, relaxation):
    """Shoot patch ``shooter``'s unshot radiosity ``ΔB_i``, overshot, through the row
    ``(ids, factors)``, in place.

    The shot sends ``w ΔB_i`` per channel, ``w = 1 + (ω − 1) · Σ_k F_ik ρ_k`` with ``ω`` the
    ``relaxation``: the overshoot is in proportion to the share of the shot its receivers
    reflect, the light that can come back (none, and the shot is a plain one: nothing is left
    to take back where no receiver reflects). For every receiver ``j = ids[k]``:
    ``ΔB_j = ρ_j · w ΔB_i · F_ij · A_i / A_j`` is added to ``radiosity[j]`` and
    ``ΔB_j · A_j / A_p`` to the unshot radiosity of its patch ``p``; the shooter's unshot
    becomes ``(1 − w) ΔB_i`` first (exactly 0 for plain shooting, ``ω = 1``; below zero when
    overshot: :func:`daskrad.solve.solve`). Patch sums are accumulated in receiver
    order into ``acc`` and then added once to each patch the row reached, so the result does
    not depend on anything but the row. Only the row's patches are visited (not all ``P``: on 10,000
    patches that pass was most of a re-shot's time).

    radiosity : (E, 3) float64, unshot : (P, 3) float64 (updated)
    ids : (k,) int32, factors : (k,) float64, reflectance : (E, 3) float64
    elem_area : (E,) float64, elem_patch : (E,) int32, patch_area : (P,) float64
    acc : (P, 3) float64 zero, touched : (P,) int32 −1, order : (P,) int32: scratch
    (:func:`shot_scratch`), left as they were found

    Returns the change of ``Σ_p A_p |ΔB_p|²`` (:func:`unshot_squares`), so the solve can
    follow the unshot RMS shot by shot without a pass over every patch.
    """
    # the share of the shot the receivers reflect, per channel (ρ-weighted row sum)
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    if relaxation != 1.0:
        for k in range(len(ids)):
            j = ids[k]
            s0 += factors[k] * reflectance[j, 0]
            s1 += factors[k] * reflectance[j, 1]
            s2 += factors[k] * reflectance[j, 2]
    over = relaxation - 1.0
    u0 = unshot[shooter, 0]
    u1 = unshot[shooter, 1]
    u2 = unshot[shooter, 2]
    dB0 = (1.0 + over * s0) * u0    # what is shot; exactly the unshot when relaxation is 1
    dB1 = (1.0 + over * s1) * u1
    dB2 = (1.0 + over * s2) * u2
    unshot[shooter, 0] = u0 - dB0
    unshot[shooter, 1] = u1 - dB1
    unshot[shooter, 2] = u2 - dB2
    area_i = patch_area[shooter]
    change = area_i * (unshot[shooter, 0] * unshot[shooter, 0]
                       + unshot[shooter, 1] * unshot[shooter, 1]
                       + unshot[shooter, 2] * unshot[shooter, 2]
                       - (u0 * u0 + u1 * u1 + u2 * u2))
    n_touched = 0
    for k in range(len(ids)):
        j = ids[k]
        s = factors[k] * (area_i / elem_area[j])
        p = elem_patch[j]
        w = elem_area[j] / patch_area[p]
        d0 = reflectance[j, 0] * (s * dB0)
        d1 = reflectance[j, 1] * (s * dB1)
        d2 = reflectance[j, 2] * (s * dB2)
        radiosity[j, 0] += d0
        radiosity[j, 1] += d1
        radiosity[j, 2] += d2
        if touched[p] < 0:                 # first touch: listed once
            touched[p] = n_touched
            order[n_touched] = p
            n_touched += 1
        acc[p, 0] += d0 * w
        acc[p, 1] += d1 * w
        acc[p, 2] += d2 * w
    for t in range(n_touched):
        p = order[t]
        before = unshot[p, 0] * unshot[p, 0] + unshot[p, 1] * unshot[p, 1] \
            + unshot[p, 2] * unshot[p, 2]
        unshot[p, 0] += acc[p, 0]
        unshot[p, 1] += acc[p, 1]
        unshot[p, 2] += acc[p, 2]
        change += patch_area[p] * (unshot[p, 0] * unshot[p, 0] + unshot[p, 1] * unshot[p, 1]
                                   + unshot[p, 2] * unshot[p, 2] - before)
        acc[p, 0] = 0.0
        acc[p, 1] = 0.0
        acc[p, 2] = 0.0
        touched[p] = -1
    return change


def shot_scratch(n_patches: int):
    """``(acc, touched, order)`` for :func:`apply_shot` on ``n_patches`` patches."""
    return (np.zeros((n_patches, 3)), np.full(n_patches, -1, np.int32),
            np.zeros(n_patches, np.int32))


@jit_leaf
def unshot_squares(unshot, patch_area):
    """``(Σ_p A_p |ΔB_p|², Σ_p A_p)`` of ``unshot : (P, 3)``, ``patch_area : (P,)``, summed
    in patch order."""
    total = 0.0
    sq = 0.0
    for p in range(unshot.shape[0]):
        a = patch_area[p]
        total += a
        sq += a * (unshot[p, 0] * unshot[p, 0] + unshot[p, 1] * unshot[p, 1]
                   + unshot[p, 2] * unshot[p, 2])
    return sq, total


@jit_leaf
def unshot_rms(unshot, patch_area):
    """Area-weighted RMS of ``unshot : (P, 3)`` over patches and channels, ``patch_area :
    (P,)``; 0 when the area is 0 (one pass: numpy's temporaries made it a third of the
    client's time on 10,000 patches, asked after every shot)."""
    sq, total = unshot_squares(unshot, patch_area)
    if not total > 0.0:
        return 0.0
    return np.sqrt(sq / (3.0 * total))
