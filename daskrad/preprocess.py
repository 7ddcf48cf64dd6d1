"""Step 1, preprocessing: polygons → patches → elements, their triangles and the voxel grid.

The scene has been loaded, validated and triangulated (:func:`daskrad.scene.load_scene`);
here it is meshed into the paper's three-level hierarchy and everything later steps read about
the mesh is built **once**: the elements as triangles (quads split along 0–2,
:func:`daskrad.scene.corners.split_quads`), the uniform voxel grid over them (3-D DDA, shadow
and primary rays, the shooters' occluder probes, the ray-cast form factor) and the per-element
emission and reflectance. Adaptive subdivision (step 2) makes a new :class:`Mesh` with
:meth:`Mesh.remeshed`; nothing is cached anywhere else.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from daskrad.errors import OptionError
from daskrad.kernels.grid import Grid, build_grid
from daskrad.mesh import (
    Hierarchy,
    build_hierarchy,
    default_sizes,
    hierarchy_triangles,
    polygon_areas,
)
from daskrad.scene.types import Scene
from daskrad.settings import Settings


@dataclass(frozen=True)
class Mesh:
    """The meshed scene (step 1's result; step 2 may refine it).

    Attributes
    ----------
    hierarchy : Hierarchy
        Polygons → patches → elements (``elem_verts : (E, 4) int32``, ``-1`` fourth corner).
    triangles : (T, 3, 3) float64
        Every element as one triangle or two, wound like the element, in element order.
    tri_verts : (T, 3) int32
        Vertex ids of the triangles' corners (Gouraud interpolation of vertex values).
    tri_element : (T,) int32
        The element of each triangle, non-decreasing.
    grid : Grid
        The uniform voxel grid over ``triangles``.
    emission : (E, 3) float64
        Emitted radiosity (exitance) ``π · Ke`` per element, W/m²; ``Ke`` is a radiance.
    reflectance : (E, 3) float64
        Diffuse reflectance ``ρ`` per element, in ``[0, 1)``.
    """

    hierarchy: Hierarchy
    triangles: np.ndarray
    tri_verts: np.ndarray
    tri_element: np.ndarray
    grid: Grid
    emission: np.ndarray
    reflectance: np.ndarray

    @classmethod
    def of(cls, scene: Scene, h: Hierarchy) -> Mesh:
        """The mesh of hierarchy ``h`` of ``scene``: its triangles, grid and materials."""
        triangles, tri_verts, tri_element = hierarchy_triangles(h)
        materials = scene.materials
        return cls(hierarchy=h, triangles=triangles, tri_verts=tri_verts,
                   tri_element=tri_element, grid=build_grid(triangles),
                   emission=math.pi * materials.emission[h.elem_material],
                   reflectance=materials.diffuse[h.elem_material])

    def remeshed(self, scene: Scene, h: Hierarchy) -> Mesh:
        """This mesh after refinement to ``h`` (itself when ``h`` is its own hierarchy)."""
        return self if h is self.hierarchy else Mesh.of(scene, h)


#: Elements a run may make at most (before adaptive subdivision). Each element costs about
#: 1 kB over the run (hierarchy, solution, dense form-factor rows of every shot in flight,
#: the row cache, the store); 4 million is a few GiB, the most a 24 GiB machine with two
#: workers solves, and far beyond the paper's 53,430.
MAX_ELEMENTS = 4_000_000


def estimated_elements(scene: Scene, settings: Settings) -> int:
    """About how many elements ``settings.element_size`` makes of ``scene`` (total area over
    the element's area; exact for squares that tile their polygons)."""
    size = settings.element_size or default_sizes(scene)[1]
    area = polygon_areas(scene)
    area = float(area.sum() + area[scene.two_sided].sum())   # a two-sided polygon twice
    return int(math.ceil(area / size**2))


def preprocess(scene: Scene, settings: Settings) -> Mesh:
    """Mesh ``scene`` with ``settings.patch_size`` and ``settings.element_size`` (scene units;
    ``None``: from the scene's size, :func:`daskrad.mesh.default_sizes`).

    Two-sided polygons are meshed as two one-sided ones (:func:`daskrad.mesh.one_sided`).
    Refuses
    (:class:`OptionError`, before any work) an element size that would make more than
    :data:`MAX_ELEMENTS` elements.
    """
    check_size(scene, settings)
    return Mesh.of(scene, build_hierarchy(scene, settings.patch_size, settings.element_size))


def check_size(scene: Scene, settings: Settings) -> None:
    """:class:`OptionError` if meshing ``scene`` with ``settings`` would make more than
    :data:`MAX_ELEMENTS` elements (checked before any work or output)."""
    n = estimated_elements(scene, settings)
    if n > MAX_ELEMENTS:
        raise OptionError(f"--element-size {settings.element_size or default_sizes(scene)[1]:.4g}"
                          f" would make about {n:,} elements, more than the {MAX_ELEMENTS:,} a "
                          "run may hold; choose a larger --element-size", scene.path)

