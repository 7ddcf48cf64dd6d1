"""The polygon → patch → element hierarchy (docs/design.md §1 step 1, §3)."""

from daskrad.mesh.hierarchy import (
    build_hierarchy,
    default_sizes,
    element_vertex_adjacency,
    hierarchy_triangles,
    one_sided,
    polygon_areas,
    vertex_average,
    vertex_polygon,
)
from daskrad.mesh.types import Hierarchy

__all__ = [
    "Hierarchy",
    "build_hierarchy",
    "default_sizes",
    "element_vertex_adjacency",
    "hierarchy_triangles",
    "one_sided",
    "polygon_areas",
    "vertex_average",
    "vertex_polygon",
]
