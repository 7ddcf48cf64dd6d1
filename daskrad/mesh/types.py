"""The polygon → patch → element hierarchy as structure of arrays (docs/design.md §3)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Hierarchy:
    """Three levels: polygon (input face) → patch (shoots light) → element (receives light).

    Attributes
    ----------
    vertices : (V, 3) float64
        Element corners. Shared between the elements of one polygon, so vertex radiosity is
        continuous across them.
    elem_verts : (E, 4) int32
        Corner indices, counter-clockwise seen from the lit side; ``-1`` in column 3 for a
        triangle.
    elem_patch : (E,) int32
        Owning patch.
    patch_verts : (P, 4) int32
        Corner indices of each patch (patch corners are element corners), ``-1`` in column 3
        for a triangle.
    patch_polygon : (P,) int32
        Owning input polygon (a row of ``Scene.polygons``).
    polygon_material : (Q,) int32
        Material row per polygon.
    elem_area : (E,) float64
    elem_normal : (E, 3) float64, unit
    elem_centroid : (E, 3) float64
        Area-weighted centroid.
    patch_area : (P,) float64
        Exactly the sum of its elements' areas (to round-off).
    patch_normal : (P, 3) float64, unit
    patch_centroid : (P, 3) float64
    generation : int
        Bumped by every adaptive refinement; the Dask workers cache by it.
    """

    vertices: np.ndarray
    elem_verts: np.ndarray
    elem_patch: np.ndarray
    patch_verts: np.ndarray
    patch_polygon: np.ndarray
    polygon_material: np.ndarray
    elem_area: np.ndarray
    elem_normal: np.ndarray
    elem_centroid: np.ndarray
    patch_area: np.ndarray
    patch_normal: np.ndarray
    patch_centroid: np.ndarray
    generation: int = 0

    @property
    def n_elements(self) -> int:
        return len(self.elem_verts)

    @property
    def n_patches(self) -> int:
        return len(self.patch_polygon)

    @property
    def elem_polygon(self) -> np.ndarray:
        """``(E,) int32``: the input polygon of each element."""
        return self.patch_polygon[self.elem_patch]

    @property
    def elem_material(self) -> np.ndarray:
        """``(E,) int32``: the material row of each element."""
        return self.polygon_material[self.elem_polygon]
