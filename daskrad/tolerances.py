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
    FAN_MARGIN,
    GRID_MARGIN,
    GRID_PAD,
    LEX_TIE,
    RAY_EPS,
    SHADOW_SHORTEN,
    SPHERE_PAD,
    WINDOW_CLIP_ANGLE,
    WINDOW_MIN,
)

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
#: tangent plane (hemisphere-base form factor, docs/design.md §2), so a polygon coplanar with the
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

#: A face lying on a larger face in one plane (a decal, a rug, a picture on a wall: a coplanar
#: overlap, see ``COPLANAR``) is lifted ``DECAL_LIFT * diag`` off the plane along its normal so
#: that it shows and the face under it is hidden there (issue 16); a decal on a decal twice as
#: far. 2e-5 is what the converted real-interior scenes (RenderPark's) used: 200 ×
#: ``RAY_OFFSET`` (the decal is above where the rays of the face under it start) and 2e4 ×
#: ``COPLANAR`` and ``HORIZON_EPS`` (the lifted face is another plane for every test), yet
#: 0.2 mm in a 10 m room.
DECAL_LIFT = 2e-5

#: Faces stacked more than this deep in one plane (decal on decal on ...) are refused: the
#: input is a soup of overlapping faces, not decals (16 levels lift 3.2e-4 · diag).
MAX_DECAL_DEPTH = 16

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

# --- limits on magnitudes (issue 13): refused at load time, in one line, instead of an inf or
# NaN image. float64 overflows at 1.8e308; these bounds leave room for the products the solver
# and renderer form, so nothing inside them can overflow on the way.

#: Largest accepted ``|coordinate|`` of a vertex or a point light. The direct-light kernel
#: divides by ``r⁴`` (``cos·cos / (r²)²``); with every coordinate within ±1e75 the scene's
#: diagonal is at most 3.5e75 and ``diag⁴`` at most 1.5e302.
MAX_COORDINATE = 1e75

#: Smallest accepted scene diagonal: lengths a billionth of the scene (the tolerances above)
#: to the fourth power must stay normal floats (``(1e-60 · 1e-9)⁴ = 1e-276``).
MIN_DIAGONAL = 1e-60

#: Largest accepted light level, in W/m² (the file's unit of area): a material's exitance
#: ``π·Ke``, a point light's irradiance at the scene's size ``I / diag²``, a directional
#: light's irradiance ``E``, and their sum. Images (OpenEXR) and the store hold float32
#: (largest 3.4e38): 1e30 leaves 1e8 for the gain of interreflections ``1 / (1 − ρ)`` and for
#: a point light nearer to a surface than the scene's size. Squared over areas up to
#: ``diag² ≤ 1.2e151`` (the unshot RMS) it stays below 1e212. No real scene comes near it: the
#: sun's exitance is 6e7 W/m².
MAX_LIGHT = 1e30

#: An edge of one polygon lies on another polygon's plane (a contact line, where a block stands
#: on the floor) when both its ends are within ``CONTACT * diag`` of that plane: the polygon is
#: then cut along it before meshing (:mod:`daskrad.mesh.contacts`). Looser than ``COPLANAR``:
#: a modelled block rests on the floor to the modeller's precision, not to round-off, and a
#: gap of a millionth of the scene lets no visible light through.
CONTACT = 1e-6

#: Quadrics and parametric surfaces (``[[shape]]`` in the sidecar, MGF's ``sph``, ``cyl``,
#: ``cone``, ``ring``, ``torus``) are tessellated so that no point of the true surface is
#: farther than ``CHORD_ERROR * diag`` from its facet (:mod:`daskrad.scene.shapes`): a
#: millimetre in a 1 m scene, a centimetre in a 10 m room.
CHORD_ERROR = 1e-3

