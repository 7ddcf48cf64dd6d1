"""Step 1, preprocessing: polygons → patches → elements, their triangles and the voxel grid.

The scene has been loaded, validated and triangulated (:func:`daskrad.scene.load_scene`);
here it is meshed into the paper's three-level hierarchy and everything later steps read about
the mesh is built **once**: the elements as triangles (quads split along 0–2,
:func:`daskrad.scene.corners.split_quads`), the uniform voxel grid over them (3-D DDA, primary
rays, the shooters' occluder probes, the ray-cast form factor, the junction gather), the grid
over the scene's own polygons that the direct light's shadows are found in
(:func:`occluders`) and the per-element emission and reflectance. Adaptive subdivision (step 2)
makes a new :class:`Mesh` with :meth:`Mesh.remeshed`; nothing is cached anywhere else.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from daskrad.errors import OptionError
from daskrad.kernels.faces import Faces
from daskrad.kernels.grid import DEFAULT_DENSITY, Grid, build_grid
from daskrad.mesh import (
    Hierarchy,
    build_hierarchy,
    default_sizes,
    hierarchy_triangles,
    one_sided,
    polygon_areas,
)
from daskrad.scene.corners import split_quads
from daskrad.scene.types import Scene
from daskrad.settings import Settings


class Occluders(NamedTuple):
    """What blocks the direct light's shadow rays and windows (:func:`occluders`).

    grid : Grid
        The voxel grid over the scene's polygons as triangles, backs of two-sided ones
        included.
    faces : Faces
        Those polygons as the convex faces the grid's triangles tile, one piece each
        (:func:`daskrad.kernels.faces.face_hides`).
    """

    grid: Grid
    faces: Faces


#: Cells a polygon triangle at most in the occluders' grid (:func:`occluders`). The elements'
#: cells put hundreds on each of a box's few large polygons (the Cornell box: 24³ cells for 46
#: triangles), which rays then walk empty. Capped (11³ there), alternated in one process,
#: medians of 3, the same bits (the direct light, its classes and the image; the Cornell box,
#: the lit room, RenderPark's cube): the Cornell box's direct pass 0.234 → 0.181 s, its gather
#: 0.786 → 0.700 s; the cube's (132 triangles, 37 × 36 × 37 → 16³ cells) 0.69 → 0.47 s and
#: 2.19 → 1.83 s. 8 measured the same. Furnished interiors keep the elements' cells (about 6
#: a triangle in the converted office).
OCCLUDER_DENSITY_MAX = 32.0


def occluders(scene: Scene, cells_for: int) -> Occluders:
    """The scene's polygons as triangles (quads split along 0–2, as loaded), with the back of
    every two-sided polygon as the mesh makes it (:func:`daskrad.mesh.one_sided`,
    ``TWO_SIDED_GAP`` behind the front): what blocks a shadow ray, and the convex faces they
    tile (every input polygon is a triangle or a planar convex quad).

    The elements subdivide these polygons in their planes (patches, elements, adaptive
    subdivision, cuts at contacts), so both sets of triangles cover the same surfaces (up to
    the rounding of a back's corners, moved along the normal of the whole polygon rather than
    of a cut piece), and a shadow ray, which asks only whether something lies between, gets
    the same answer from either but along an edge the elements add inside a polygon (the edge
    tolerance, ``grid.eps``, is absolute). The polygons are fewer and larger (RenderPark's
    office: 53,460 triangles against 154,495), so a cell holds a polygon instead of its
    elements: the per-pixel pass's shadow rays and the direct pass's windows
    (``bench_perpixel``, ``bench_arealight``; docs/benchmarks.md has the figures) find their
    occluders faster, with the same shadows to the rays' and the raster's precision. The
    geometry never changes with refinement, so a refined mesh keeps its occluders.

    ``cells_for``: the grid has the cells of a grid over that many triangles (the
    elements'), not of one over the polygons: measured on 7 of the converted office's 35
    tiles (400 × 300) and all of ``office3``'s (192 × 144), tiles through the element grid
    16.18 / 6.90 s, through a polygon grid of its own density (a quarter and a ninth of the
    cells) 12.32 / 7.77 s, of the elements' cells 11.73 / 6.16 s, the same image in each:
    coarse cells hold pieces of many polygons, and a large polygon is tested again in every
    cell a ray crosses. (Those runs sized it from the refined mesh; it is sized from the mesh
    before refinement now, built before the direct pass: ``graz.obj`` 154,495 triangles
    against ~190,000, and its whole run's render did not slow, 51.2 → 48.8 s.) A scene of few
    polygons meshed finely gets at most :data:`OCCLUDER_DENSITY_MAX` cells a polygon triangle."""
    scene = one_sided(scene)
    poly = scene.polygons
    tri, owner = split_quads(poly)
    density = DEFAULT_DENSITY * max(cells_for, 1) / max(len(tri), 1)
    grid = build_grid(np.ascontiguousarray(scene.vertices[tri], dtype=np.float64),
                      density=min(density, OCCLUDER_DENSITY_MAX))
    corners = scene.vertices[np.where(poly >= 0, poly, poly[:, :1])]
    faces = Faces(tri_face=owner.astype(np.int32),
                  start=np.arange(len(poly) + 1, dtype=np.int64),
                  corners=np.ascontiguousarray(corners, dtype=np.float64),
                  count=np.where(poly[:, 3] >= 0, 4, 3).astype(np.int64))
    return Occluders(grid, faces)


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
    occluders : Occluders
        The scene's polygons as shadow casters (:func:`occluders`), with the cells of
        ``grid`` before refinement; kept by :meth:`remeshed`.
    """

    hierarchy: Hierarchy
    triangles: np.ndarray
    tri_verts: np.ndarray
    tri_element: np.ndarray
    grid: Grid
    emission: np.ndarray
    reflectance: np.ndarray
    occluders: Occluders

    @classmethod
    def of(cls, scene: Scene, h: Hierarchy, shadows: Occluders | None = None) -> Mesh:
        """The mesh of hierarchy ``h`` of ``scene``: its triangles, grids and materials
        (``shadows``: the occluders to keep, else built)."""
        triangles, tri_verts, tri_element = hierarchy_triangles(h)
        materials = scene.materials
        return cls(hierarchy=h, triangles=triangles, tri_verts=tri_verts,
                   tri_element=tri_element, grid=build_grid(triangles),
                   emission=math.pi * materials.emission[h.elem_material],
                   reflectance=materials.diffuse[h.elem_material],
                   occluders=shadows if shadows is not None
                   else occluders(scene, len(triangles)))

    def remeshed(self, scene: Scene, h: Hierarchy) -> Mesh:
        """This mesh after refinement to ``h`` (itself when ``h`` is its own hierarchy); the
        polygons, hence the occluders, are the same."""
        return self if h is self.hierarchy else Mesh.of(scene, h, self.occluders)


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

