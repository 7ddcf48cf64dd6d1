"""The numerical tolerances the kernels use, in one place beside them.

Kernels import nothing of the project outside ``daskrad.kernels`` (an import-linter contract),
so their tolerances are defined here, and :mod:`daskrad.tolerances` re-exports every one of them
with the tolerances of the rest of the package: ``from daskrad import tolerances`` gives them
all. Numba freezes a module global into the compiled code as a constant, so a name here costs
nothing over a literal in the kernel. For the same reason numba's on-disk cache does not notice
a changed value here (it checks only the kernel's own source file); the Makefile drops every
cached kernel when any file of ``daskrad/kernels/``, this one included, is newer than its stamp.

Relative tolerances are relative to the quantity named (the scene's diagonal, a coordinate's
magnitude, a nearness), never fixed epsilons, so a scene in millimetres and the same scene in
kilometres behave the same (issue 7).
"""

#: Two coordinates closer than this, relative to the points' magnitudes, tie when the raster
#: orders an edge's endpoints (:func:`daskrad.kernels.geometry.lex_less`: round-off must not
#: decide which end the polyline starts from).
LEX_TIE = 1e-12

#: Relative nearness difference below which two elements tie on the hemisphere base's item
#: buffer (and in the visibility test of elements that cover no pixel centre,
#: :mod:`daskrad.kernels.hemisphere`): coplanar elements compute the same plane to round-off
#: (~1e-15 relative), while distinct surfaces that close in depth along one direction meet at a
#: contact line, where either answer is right.
DEPTH_TIE = 1e-9

#: Rays hit triangles within ``RAY_EPS * diag`` of an edge (watertightness across shared edges):
#: the default ``rel_eps`` of :func:`daskrad.kernels.grid.build_grid`.
RAY_EPS = 1e-12

#: A fan of rays (:class:`daskrad.kernels.grid.Fan`) skips a triangle whose highest corner lies
#: more than half the rays' offset from their surface plus this many edge tolerances
#: (``RAY_EPS · diag``) below the plane the rays rise from: beyond the edge tolerance and the
#: round-off of the heights, while the surface's own triangles, a whole offset below
#: (``RAY_OFFSET``, 10⁵ edge tolerances), are the ones skipped.
FAN_MARGIN = 1000.0

#: A closest hit found among the scene's polygons is located among the elements' triangles
#: (:func:`daskrad.kernels.grid.closest_hit_located`) in the planes within this many edge
#: tolerances (``RAY_EPS · diag``) of the hit point, plus the round-off of its coordinates
#: (``COORD_ROUND``): ten times a quad's allowed twist (``PLANAR_QUAD · diag``: the elements
#: subdivide it bilinearly, the polygons split it along a diagonal), far below the gap between
#: the two sides of a two-sided surface (``TWO_SIDED_GAP``, 10⁷ edge tolerances). A point no
#: element holds within these is found by the walk of the elements instead.
LOCATE_PLANE = 10_000.0
#: ... and whose barycentric coordinates reach this far below 0 (a point on an edge two
#: triangles share lies in both, up to round-off).
LOCATE_BARY = 1e-9

#: The voxel grid's box is the scene's box padded by this fraction of the scene diagonal on every
#: side: a flat scene (zero extent on an axis) then still has a box of positive volume, and no
#: vertex lies on the box's boundary.
GRID_PAD = 1e-6

#: Triangles are registered in grid cells enlarged by this fraction of the scene diagonal (plus
#: 2·eps and rounding of the coordinates): far larger than the rounding of a DDA cell boundary
#: (~1e-16 of the coordinates' magnitude), far smaller than any cell.
GRID_MARGIN = 1e-9

#: Rounding of a coordinate, relative to the largest coordinate magnitude (a few ulps), for
#: scenes far from the origin where coordinate rounding dominates the diagonal-relative margins
#: of the grid.
COORD_ROUND = 1e-14

#: The hemicube's bounding sphere of an element is rounded up by this relative amount, so that
#: its horizon test never culls an element one of whose corners lies above the horizon
#: (:func:`daskrad.kernels.hemicube.element_spheres`).
SPHERE_PAD = 1e-12

#: An area light's window on the hemisphere base narrower than this (in disc units, the disc has
#: radius 1) on either axis holds no pixel worth rasterizing; its visibility is one ray to the
#: light's centroid instead (:mod:`daskrad.kernels.arealight`).
WINDOW_MIN = 1e-12

#: An occluder is clipped to the pyramid from the eye to its light, widened by this angle
#: (radians) on every side, before it is projected (:mod:`daskrad.kernels.arealight`): the
#: clip's own edges then project well outside the light's pixels (2° is ~900 times the
#: sagitta of the 1° polyline pieces, and a margin relative to the light's size was not
#: enough for a light seen edge-on), so only the occluder's own edges decide which light
#: pixels it hides. Measured (8,192 vertices each of RenderPark's office and classroom): the
#: direct pass's CPU 2.52 → 1.97 s / 3.31 → 2.62 s, the irradiance summed over the vertices
#: within 2e-5 of the unclipped one's, the vertices that moved most as close to 4,096 shadow
#: rays as before.
WINDOW_CLIP_ANGLE = 2.0 * 3.141592653589793 / 180.0

#: The reference path tracer's shadow ray to a point of a light stops this fraction of the
#: distance short of it (besides the absolute ray offset), so the light's own triangle does not
#: block it (:mod:`daskrad.kernels.pathtrace`).
SHADOW_SHORTEN = 1e-9
