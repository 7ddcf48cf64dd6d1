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

#: A vertex's direct light is the limit from inside its polygon: it is evaluated (and its shadow
#: rays start) ``VERTEX_NUDGE * diag`` from the vertex towards the polygon's centroid. 100 ray
#: offsets: a surface meeting the polygon at the vertex (a junction) then lies farther than the
#: offset from the ray's origin and blocks what would cross it, and the point moves by a
#: hundred-thousandth of the scene, which no light gradient resolves.
VERTEX_NUDGE = 1e-5

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

#: An edge of one polygon lies on another polygon's plane (a contact line, where a block stands
#: on the floor) when both its ends are within ``CONTACT * diag`` of that plane: the polygon is
#: then cut along it before meshing (:mod:`daskrad.mesh.contacts`). Looser than ``COPLANAR``:
#: a modelled block rests on the floor to the modeller's precision, not to round-off, and a
#: gap of a millionth of the scene lets no visible light through.
CONTACT = 1e-6

#: Two coordinates closer than this, relative to the points' magnitudes, tie when the raster
#: orders an edge's endpoints (:func:`daskrad.kernels.geometry.lex_less`: round-off must not
#: decide which end the polyline starts from). Defined beside the kernel, which imports
#: nothing of the project.
from daskrad.kernels.geometry import LEX_TIE  # noqa: E402, F401
