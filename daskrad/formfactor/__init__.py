"""Form factors (docs/design.md §2): the methods side by side with the patch's rows.

- :mod:`daskrad.formfactor.methods`: form factors from differential areas to every element,
  one function per method, chosen by name from :data:`METHODS` (Doi's hemisphere base, its
  item-buffer and scanline variants, the hemicube, ray casting, Lambert's exact formula).
- :mod:`daskrad.formfactor.shooting`: a shooting patch's sparse row ``F_pj``, the unit of work of
  the solve (near field by reciprocity, penumbra sampling, the per-process row cache).
"""

from daskrad.formfactor.methods import (
    DEFAULT_RESOLUTION,
    METHODS,
    analytic_point_to_elements,
    analytic_rows,
    auto_edge_angle,
    check_geometry,
    checked_geometry,
    edge_split_angle,
    element_grid,
    get_method,
    hemicube_rows,
    hemisphere_counts,
    hemisphere_rows,
    itembuffer_rows,
    point_to_elements,
    raycast_rows,
    scanline_rows,
    shooter_rows,
    to_sparse,
)

__all__ = [
    "DEFAULT_RESOLUTION",
    "METHODS",
    "analytic_point_to_elements",
    "analytic_rows",
    "auto_edge_angle",
    "check_geometry",
    "checked_geometry",
    "edge_split_angle",
    "element_grid",
    "get_method",
    "hemicube_rows",
    "hemisphere_counts",
    "hemisphere_rows",
    "itembuffer_rows",
    "point_to_elements",
    "raycast_rows",
    "scanline_rows",
    "shooter_rows",
    "to_sparse",
]
