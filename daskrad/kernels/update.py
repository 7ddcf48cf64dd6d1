"""The client's radiosity update for one shot (docs/design.md §4), one pass over the receivers.

Replaces a NumPy version that gathered, multiplied and ran three ``bincount`` passes per shot:
the update is the client's share of a shot's time, and on a 2-core machine the client competes
with the workers for the cores (issue 4's scaling benchmark).
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit


@jit
def apply_shot(radiosity, unshot, shooter, ids, factors, reflectance, elem_area, elem_patch,
               patch_area):
    """Shoot patch ``shooter``'s unshot radiosity through the row ``(ids, factors)``, in place.

    For every receiver ``j = ids[k]``: ``ΔB_j = ρ_j · ΔB_i · F_ij · A_i / A_j`` is added to
    ``radiosity[j]`` and ``ΔB_j · A_j / A_p`` to the unshot radiosity of its patch ``p``; the
    shooter's unshot is zeroed first. Patch sums are accumulated in receiver order into a zero
    array and then added, so the result does not depend on anything but the row.

    radiosity : (E, 3) float64, unshot : (P, 3) float64 (updated)
    ids : (k,) int32, factors : (k,) float64, reflectance : (E, 3) float64
    elem_area : (E,) float64, elem_patch : (E,) int32, patch_area : (P,) float64
    """
    dB0 = unshot[shooter, 0]
    dB1 = unshot[shooter, 1]
    dB2 = unshot[shooter, 2]
    unshot[shooter, 0] = 0.0
    unshot[shooter, 1] = 0.0
    unshot[shooter, 2] = 0.0
    area_i = patch_area[shooter]
    acc = np.zeros(unshot.shape)
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
        acc[p, 0] += d0 * w
        acc[p, 1] += d1 * w
        acc[p, 2] += d2 * w
    for p in range(unshot.shape[0]):
        unshot[p, 0] += acc[p, 0]
        unshot[p, 1] += acc[p, 1]
        unshot[p, 2] += acc[p, 2]
