"""Every numerical tolerance of daskrad, in one place.

Tolerances that depend on geometry are *relative to the scene's size* (the diagonal of its
bounding box), never fixed epsilons, so a scene in millimetres and the same scene in
kilometres behave the same (issue 7).

The kernels' own tolerances are defined in :mod:`daskrad.kernels.tolerances` (kernels import
nothing of the project outside ``daskrad.kernels``) and re-exported here, so
``from daskrad import tolerances`` gives every one of them.
"""

from daskrad.kernels.tolerances import (  # noqa: F401  (re-exported)
    COORD_ROUND,
    DEPTH_TIE,
    GRID_MARGIN,
    GRID_PAD,
    LEX_TIE,
    RAY_EPS,
    SHADOW_SHORTEN,
    SPHERE_PAD,
    WINDOW_MIN,
)

#: A face whose area is below ``DEGENERATE_AREA * diag**2`` is dropped as degenerate.
DEGENERATE_AREA = 1e-14

#: A quad is kept as a quad when its fourth corner lies within ``PLANAR_QUAD * diag`` of the
#: plane through the other three; otherwise it is split into two triangles.
PLANAR_QUAD = 1e-9

#: Shadow and secondary rays start ``RAY_OFFSET * diag`` off the surface along its normal.
RAY_OFFSET = 1e-7

#: Relative tolerance with which area sums are checked at every level of the hierarchy.
AREA_SUM_RTOL = 1e-9

#: Adaptive refinement (:mod:`daskrad.mesh.refine`) splits an element only while its longest
#: edge exceeds the smallest element size by more than this, relative: an edge equal to it up to
#: round-off is not split again.
SPLIT_SIZE_RTOL = 1e-9

#: The camera's ``up`` is refused as parallel to the view direction when the sine of the angle
#: between them is at most this (:func:`daskrad.scene.config.read_config`).
CAMERA_UP_SINE = 1e-9

#: Default threshold angle (degrees) a polyline piece of a projected edge may subtend (eq. 4).
EDGE_ANGLE_DEG = 1.0

#: Receiving polygons are clipped against the plane ``HORIZON_EPS * diag`` above the shooter's
#: tangent plane (hemisphere-base form factor, DESIGN §2), so a polygon coplanar with the
#: shooter (its own polygon, the floor it stands on) vanishes instead of rasterizing round-off.
HORIZON_EPS = 1e-9

#: Automatic edge-split threshold of the item-buffer methods (``edge_angle=None``, the default):
#: a polyline piece may lie at most this fraction of a pixel inside the projected arc it
#: replaces (sagitta ``<= θ²/8`` on the disc, a pixel ``2/R``: ``θ = sqrt(16 s / R)``, 11.5° at
#: R = 100). A quarter pixel is half the raster's own ±1/2-pixel sampling of an outline, and
#: the anti-aliased default takes an unoccluded element's size from Lambert's formula anyway.
EDGE_SAGITTA_PX = 0.25

#: Two faces facing the same way are coplanar when every corner of each lies within
#: ``COPLANAR * diag`` of the other's plane, and they overlap when they share a region wider
#: than that in every direction (issue 7: such a pair z-fights and is refused). As tight as
#: ``HORIZON_EPS``: the form factors tell two planes apart beyond it.
COPLANAR = 1e-9

#: Cell of the plane buckets in which :func:`daskrad.scene.overlap.coplanar_overlaps` looks for
#: such pairs: unit-normal components and offsets (over the scene diagonal). Mostly a
#: performance filter, the exact test decides; but two faces coplanar within ``COPLANAR`` with
#: normals more than ``COPLANAR_CELL / 5`` apart (only faces smaller than
#: ``COPLANAR · diag / (COPLANAR_CELL / 5)`` can be) are not compared.
COPLANAR_CELL = 1e-3

#: The anti-aliased hemisphere method (``formfactor.hemisphere_rows``) takes an element's
#: visibility from its pixel counts (``won / covered``) only when its exact projected area on
#: the base disc (Lambert's ``L · n_disc``, in pixels) is at least this; a smaller element takes
#: the bilinear visibility at its centroid's direction. Under a pixel of true area the covered
#: count is aliasing, and an element thinner than the outline's chord error (``EDGE_SAGITTA_PX``:
#: a sliver) covers centres that are chord artefacts shared with its coplanar neighbours, where
#: the item buffer's tie-break (lower index) made it lose whole pixels (furnace error 9.4 %).
SUBPIXEL_AREA_PX = 1.0

#: The back of a two-sided face is meshed as a one-sided face this far (relative to the
#: scene's diagonal) behind the front: 100 ray offsets, so shadow rays, probes and the item
#: buffer tell the two sides apart, and far below anything that changes the light (a coincident
#: back would z-fight its front: 303 of 3,440 elements of a two-sided test room got no light).
TWO_SIDED_GAP = 1e-5
