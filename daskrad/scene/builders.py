"""Scenes built in code, for tests and benchmarks with exact answers (docs/references.md).

``box_scene`` is a closed axis-aligned box: six faces, each its own material, each face a grid
of ``subdivisions²`` quad polygons. The furnace (``B = E/(1 − ρ)``) and the six-patch cube are
built with it.
"""

from __future__ import annotations

import numpy as np

from daskrad.scene.types import Scene
from daskrad.scene.validate import scene_from_arrays

#: Face order of :func:`box_scene` (material rows 0..5): the box's side at min/max x, y, z.
#: With y up, ``"y-"`` is the floor and ``"y+"`` the ceiling.
BOX_FACES = ("x-", "x+", "y-", "y+", "z-", "z+")


def _per_face(value, name: str) -> np.ndarray:
    """Broadcast a scalar, an RGB triple, six scalars or six triples to ``(6, 3) float64``."""
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        return np.full((6, 3), float(a))
    if a.shape == (3,):
        return np.tile(a, (6, 1))
    if a.shape == (6,):
        return np.repeat(a[:, None], 3, axis=1)
    if a.shape == (6, 3):
        return a.copy()
    raise ValueError(f"{name}: expected a scalar, (3,), (6,) or (6, 3), got shape {a.shape}")


def box_scene(
    size=(1.0, 1.0, 1.0),
    diffuse=0.5,
    emission_per_face=0.0,
    inward: bool = True,
    subdivisions: int = 1,
    origin=(0.0, 0.0, 0.0),
    point_lights=None,
    directional_lights=None,
    camera=None,
    path: str = "<box>",
) -> Scene:
    """A closed box ``[origin, origin + size]``, six faces of quads.

    Parameters
    ----------
    size : (3,) float
    diffuse : scalar, (3,), (6,) or (6, 3)
        Reflectance per face (rows in :data:`BOX_FACES` order).
    emission_per_face : scalar, (3,), (6,) or (6, 3)
        Emitted radiance per face; e.g. ``[0, 0, 0, 1, 0, 0]`` lights the ceiling only.
    inward : bool
        Normals point into the box (an enclosure, lit inside) or out of it (a solid block).
    subdivisions : int
        Each face is a ``subdivisions × subdivisions`` grid of quad polygons (1: one polygon
        per face, the six-patch cube). Vertices are shared within a face, not across faces.

    Returns
    -------
    Scene
        Polygons of face ``k`` are rows ``k·s² … (k+1)·s² − 1``; ``polygon_material`` is the
        face number ``k``; material names are :data:`BOX_FACES`.
    """
    s = int(subdivisions)
    if s < 1:
        raise ValueError(f"subdivisions must be >= 1, got {subdivisions}")
    size = np.asarray(size, dtype=np.float64)
    origin = np.asarray(origin, dtype=np.float64)
    t = np.linspace(0.0, 1.0, s + 1)
    uu, vv = np.meshgrid(t, t, indexing="ij")  # (s+1, s+1) grid on the unit square
    verts, polys = [], []
    for k in range(6):
        axis, high = divmod(k, 2)
        # (u, v, axis) right-handed: u × v = +axis, so corners (0,0) (1,0) (1,1) (0,1)
        # wind counter-clockwise seen from +axis
        u_ax, v_ax = (axis + 1) % 3, (axis + 2) % 3
        p = np.zeros((s + 1, s + 1, 3))
        p[..., u_ax] = uu
        p[..., v_ax] = vv
        p[..., axis] = float(high)
        verts.append((origin + p * size).reshape(-1, 3))
        i = np.arange(s)[:, None] * (s + 1) + np.arange(s)[None, :]  # lower-left corner ids
        quad = np.stack([i, i + (s + 1), i + (s + 1) + 1, i + 1], axis=-1).reshape(-1, 4)
        # the normal of this winding is +axis; it must point into the box at the max face
        # (high) and out of it at the min face, so flip where that is wrong
        outward_is_plus = bool(high)
        if inward == outward_is_plus:
            quad = quad[:, ::-1]
        polys.append(quad + k * (s + 1) ** 2)
    return scene_from_arrays(
        np.concatenate(verts),
        np.concatenate(polys),
        np.repeat(np.arange(6), s * s),
        _per_face(diffuse, "diffuse"),
        _per_face(emission_per_face, "emission_per_face"),
        point_lights=point_lights,
        directional_lights=directional_lights,
        camera=camera,
        path=path,
        material_names=BOX_FACES,
    )
