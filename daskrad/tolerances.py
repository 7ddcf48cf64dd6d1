"""Every numerical tolerance of daskrad, in one place.

Tolerances that depend on geometry are *relative to the scene's size* (the diagonal of its
bounding box), never fixed epsilons, so a scene in millimetres and the same scene in
kilometres behave the same (issue 7).
"""

#: A face whose area is below ``DEGENERATE_AREA * diag**2`` is dropped as degenerate.
DEGENERATE_AREA = 1e-14

#: A quad is kept as a quad when its fourth corner lies within ``PLANAR_QUAD * diag`` of the
#: plane through the other three; otherwise it is split into two triangles.
PLANAR_QUAD = 1e-9

#: Shadow and secondary rays start ``RAY_OFFSET * diag`` off the surface along its normal.
RAY_OFFSET = 1e-7

#: Rays hit triangles within ``RAY_EPS * diag`` of an edge (watertightness across shared edges).
RAY_EPS = 1e-12

#: Relative tolerance with which area sums are checked at every level of the hierarchy.
AREA_SUM_RTOL = 1e-9

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

#: The anti-aliased hemisphere method (``formfactor.hemisphere_rows``) takes an element's
#: visibility from its pixel counts (``won / covered``) only when its exact projected area on
#: the base disc (Lambert's ``L · n_disc``, in pixels) is at least this; a smaller element takes
#: the bilinear visibility at its centroid's direction. Under a pixel of true area the covered
#: count is aliasing, and an element thinner than the outline's chord error (``EDGE_SAGITTA_PX``:
#: a sliver) covers centres that are chord artefacts shared with its coplanar neighbours, where
#: the item buffer's tie-break (lower index) made it lose whole pixels (furnace error 9.4 %).
SUBPIXEL_AREA_PX = 1.0

#: Quadrics and parametric surfaces (``[[shape]]`` in the sidecar, MGF's ``sph``, ``cyl``,
#: ``cone``, ``ring``, ``torus``) are tessellated so that no point of the true surface is
#: farther than ``CHORD_ERROR * diag`` from its facet (:mod:`daskrad.scene.shapes`): a
#: millimetre in a 1 m scene, a centimetre in a 10 m room.
CHORD_ERROR = 1e-3

#: MGF's two-sided faces become the face plus a reversed twin this far behind it
#: (``* diag``), as the shared scenes' converted OBJs do: far enough apart that the item
#: buffer and shadow rays (``RAY_OFFSET``) tell the two apart, far below anything visible.
TWIN_OFFSET = 1e-5

#: Two coordinates closer than this, relative to the points' magnitudes, tie when the raster
#: orders an edge's endpoints (:func:`daskrad.kernels.geometry.lex_less`: round-off must not
#: decide which end the polyline starts from). Defined beside the kernel, which imports
#: nothing of the project.
from daskrad.kernels.geometry import LEX_TIE  # noqa: E402, F401
