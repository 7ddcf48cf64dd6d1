"""Step 4: the per-pixel pass — primary rays through the voxel grid, Gouraud-interpolated radiance.

Image values are **radiance** ``L = B / π`` (W·m⁻²·sr⁻¹ of the scene's unit), linear, so they
compare directly with a path tracer's output. Surfaces are one-sided: a ray that reaches the back
of a face sees black, as in Mitsuba and pbrt.

Camera convention (docs/design.md §6): ``forward = normalize(look_at − eye)``,
``right = normalize(forward × up)``, ``true_up = right × forward``; pixel column ``x`` grows along
``right``, row 0 is the top of the image; ``fov`` is horizontal.

The image is computed in tiles (:func:`render_tile`); in-process they run one after the other,
with Dask they are ``tile-<n>`` futures. Sample positions are a fixed stratified grid per pixel,
so a pixel's value does not depend on which tile or worker computed it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import NamedTuple

import numpy as np

from daskrad import direct, tolerances
from daskrad.direct import DirectLight, Lights
from daskrad.errors import SceneError
from daskrad.formfactor import edge_split_angle
from daskrad.kernels.direct import LIGHT_HIDDEN, LIGHT_TRACE, LIGHT_VISIBLE
from daskrad.kernels.grid import (
    NO_LOCATOR,
    Grid,
    build_grid,
    closest_hit,
    closest_hit_located_batch,
    located_triangles,
    locator,
)
from daskrad.kernels.shade import direct_at_hits, gouraud, pixel_modes, shade_hits
from daskrad.kernels.unshadowed import unshadowed_elements
from daskrad.kernels.view import view_hits_batch
from daskrad.mesh import default_sizes, vertex_average
from daskrad.mesh.refine import TVertices, resolve_tvertices
from daskrad.scene.corners import repeat_third
from daskrad.scene.types import Camera, Scene
from daskrad.settings import Settings
from daskrad.solve import Solution, ambient

#: Tile side in pixels for the per-pixel pass (a tile is one task).
TILE = 64


@dataclass(frozen=True)
class Junctions:
    """What the junction gather of a view needs (:func:`for_view`, :func:`plan_gather`,
    :func:`_gather_change`).

    points, normals : (V, 3) float64
        Where each vertex is evaluated (1e-5 of the diagonal inside its polygon) and its normal.
    offset : float
        Ray offset (length).
    elem_verts : (E, 4) int32
        Element corners (``-1``: a triangle's fourth).
    vertex_rho : (V, 3) float64
        Reflectance at each vertex (of an element it belongs to).
    vertex_indirect : (V, 3) float64
        The interpolated (indirect) part of the vertex radiance before the gather.
    exclude : (E, 3) float64
        Radiance taken off a hit on each element (its ``Ke`` when the direct pass lit the
        vertices with the emitters).
    gatherable : (V,) bool
        Vertices that may be gathered: corners of some element, not T-vertices.
    tv_vertex, tv_a, tv_b : (T,) int64
        The T-vertices and their edges' ends (:class:`daskrad.mesh.refine.TVertices`): a
        T-vertex takes the mean of its ends' gathered change, so no seam opens.
    reach : float
        How far another surface makes a vertex "beside a junction" (length).
    everywhere : bool
        Gather every vertex, not only those the view shows (a mirror may show any).
    """

    points: np.ndarray
    normals: np.ndarray
    offset: float
    elem_verts: np.ndarray
    vertex_rho: np.ndarray
    vertex_indirect: np.ndarray
    exclude: np.ndarray
    gatherable: np.ndarray
    tv_vertex: np.ndarray
    tv_a: np.ndarray
    tv_b: np.ndarray
    reach: float
    everywhere: bool


@dataclass(frozen=True)
class RenderContext:
    """What a tile task reads.

    grid : Grid
        The voxel grid over ``tri_verts``' triangles.
    tri_verts : (T, 3) int32
        Vertex ids of each grid triangle (elements split into triangles).
    tri_element : (T,) int32
        Element of each triangle.
    elem_normal : (E, 3) float64
    vertex_radiance : (V, 3) float64
        ``B / π`` at vertices, ambient included.
    camera : Camera
        With the final image ``width`` and ``height``.
    spp : int
        Samples per pixel (a stratified grid, or a rank-1 lattice for a count that is not a
        square: :func:`sample_offsets`).
    edge_spp : int, edge_step : float
        A pixel whose ``spp`` samples differ by more than ``edge_step`` (radiance, any
        channel) is sampled again with ``edge_spp`` samples instead (:func:`render_tile_stats`);
        ``edge_spp <= spp``: never.

    The per-pixel pass (paper eq. 9) and the specular part, optional (``None``: plain Gouraud):

    vertex_indirect : (V, 3) float64
        The interpolated part of ``vertex_radiance`` on elements whose direct light is
        recomputed per pixel (indirect light and the ambient term, radiance).
    elem_perpixel : (E,) bool
        Elements whose direct light is recomputed at every pixel (:func:`perpixel_elements`).
    elem_reflectance, elem_emission : (E, 3) float64
        ``ρ`` and ``Ke`` (emitted radiance) of each element.
    elem_specular : (E, 3) float64, elem_shininess : (E,) float64
        Phong ``Ks``, ``Ns`` (``Ks`` 0: no highlight). Mirrors get none: their reflected ray
        sees the lights that have a size, and a point light has none.
    elem_mirror : (E,) bool
        ``illum 3``: the pixel adds ``Ks`` times the radiance along the mirrored ray.
    lights : daskrad.direct.Lights
        The lights the direct pass used, with the shadow-ray offset and area samples.
    mirror_depth : int
        Mirror bounces followed per pixel ray.
    offset : float
        Ray offset off a mirror (an absolute length, ``RAY_OFFSET · diag``).

    Hard lights at every pixel (issue 14), optional:

    hard_lights : daskrad.direct.Lights
        The point and directional lights alone. Their direct light is one shadow ray per light
        and hit, so every hit (off the ``elem_perpixel`` elements, which recompute all lights)
        gets it exactly: a shadow edge crossing an element whose corners all agree, or a
        corner in shadow or under another surface, is then drawn where it lies.
    vertex_soft : (V, 3) float64
        ``vertex_radiance`` without the hard lights' direct radiance ``ρ H_hard / π``: what is
        interpolated under the exact hard light.

    junctions : Junctions, optional
        The final gather at vertices beside a junction, view-dependent like eq. 9: applied for
        the camera by :func:`for_view` (which every image goes through), so the context a
        store keeps is the solution's, and a new view gathers what it shows.
    elem_light_mode : (E, M) int8, optional
        Per element and area light of ``lights``, ``LIGHT_VISIBLE`` where every corner of the
        element sees the light whole (its hits cast no shadow ray for it), ``LIGHT_HIDDEN``
        where one patch is proved to hide it from the whole element (nor then;
        :func:`hidden_lights`), else ``LIGHT_TRACE`` (:func:`with_light_modes`); ``None``:
        every hit traces every light.
    occluders : Grid, optional
        The voxel grid over the scene's polygons (:func:`daskrad.preprocess.occluders`),
        which the shadow rays of the per-pixel pass walk instead of ``grid``
        (:data:`POLYGON_OCCLUDERS`);
        ``None`` (a store written before it): ``grid``.
    locator : (T, 13) float64, optional
        :func:`daskrad.kernels.grid.locator` of ``grid``'s triangles, set for a view by
        :func:`for_view`: the primary rays, mirror rays and the junction gather find their
        hits among ``occluders`` and locate them among the elements
        (:data:`POLYGON_HITS`); ``None``: they walk ``grid``.
    """

    grid: Grid
    tri_verts: np.ndarray
    tri_element: np.ndarray
    elem_normal: np.ndarray
    vertex_radiance: np.ndarray
    camera: Camera
    spp: int
    edge_spp: int = 0
    edge_step: float = math.inf
    # ---- the per-pixel pass (eq. 9) and specular light; all optional: a context without them
    # (the dashboard preview, a scene with no light but emitters that are shot) renders the
    # plain Gouraud image, and these fields cost nothing.
    vertex_indirect: np.ndarray | None = None
    elem_perpixel: np.ndarray | None = None
    elem_reflectance: np.ndarray | None = None
    elem_emission: np.ndarray | None = None
    elem_specular: np.ndarray | None = None
    elem_shininess: np.ndarray | None = None
    elem_mirror: np.ndarray | None = None
    lights: Lights | None = None
    mirror_depth: int = 0
    offset: float = 0.0
    # elements no shadow ray of the per-pixel pass can be blocked from (their rays are
    # skipped: the same bits, :mod:`daskrad.kernels.unshadowed`), and the grid without
    # occluders their direct light is evaluated with; None: every hit traces its rays
    elem_unshadowed: np.ndarray | None = None
    open_grid: Grid | None = None
    hard_lights: Lights | None = None
    vertex_soft: np.ndarray | None = None
    # the junction gather still to apply for this context's camera (:func:`for_view`)
    junctions: Junctions | None = None
    elem_light_mode: np.ndarray | None = None
    occluders: Grid | None = None
    locator: np.ndarray | None = None

    @property
    def extras(self) -> bool:
        """Whether any pixel may need more than Gouraud interpolation (else: the plain path)."""
        return bool(self.lights is not None and self.elem_perpixel is not None
                    and (self.elem_perpixel.any() or self.elem_specular.any())
                    or (self.elem_mirror is not None and self.mirror_depth > 0
                        and self.elem_mirror.any())
                    or self.hard_lights is not None)


def faces_inward(scene) -> bool:
    """Whether most of the scene's area faces the centre of its bounding box: an enclosure lit
    inside (a room), which a camera outside would see from behind, all black (issue 16)."""
    v, p = scene.vertices, scene.polygons
    corners = v[np.where(p >= 0, p, p[:, :1])]
    n_corners = np.where(p[:, 3] >= 0, 4, 3)
    corners[p[:, 3] < 0, 3] = 0.0
    centroid = corners.sum(axis=1) / n_corners[:, None]
    p3 = v[np.where(p[:, 3] >= 0, p[:, 3], p[:, 0])]
    # area vectors: ½ d₁ × d₂ for quads, ½ (v1 − v0) × (v2 − v0) for triangles
    quad = p[:, 3] >= 0
    area_vec = 0.5 * np.where(quad[:, None],
                              np.cross(v[p[:, 2]] - v[p[:, 0]], p3 - v[p[:, 1]]),
                              np.cross(v[p[:, 1]] - v[p[:, 0]], v[p[:, 2]] - v[p[:, 0]]))
    toward = np.einsum("ij,ij->i", area_vec, scene.bounds.mean(axis=0) - centroid)
    area = np.linalg.norm(area_vec, axis=1)
    return bool(area[toward > 0].sum() > 0.5 * area.sum())


def default_camera(bounds: np.ndarray, width: int = 256, height: int = 256,
                   fov: float = 40.0, inside: bool = False) -> Camera:
    """A camera on the −z side of the bounding box ``(2, 3)``, looking along +z, y up, framing
    the whole box (the usual placement for y-up OBJ scenes).

    ``inside=True`` (an enclosure, :func:`faces_inward`): the camera stands inside the box,
    5 % of its depth in front of the −z side, looking at the centre with a 70° field of view,
    since from outside it would see only the backs of one-sided walls.
    """
    centre = bounds.mean(axis=0)
    if inside:
        eye = centre - np.array([0.0, 0.0, 0.45 * (bounds[1, 2] - bounds[0, 2])])
        if not np.linalg.norm(centre - eye) > 0:  # a flat box: look along z anyway
            eye = centre - np.array([0.0, 0.0, 1.0])
        return Camera(eye=eye, look_at=centre, up=np.array([0.0, 1.0, 0.0]), fov=70.0,
                      width=width, height=height)
    radius = 0.5 * float(np.linalg.norm(bounds[1] - bounds[0])) or 1.0
    distance = 1.1 * radius / math.tan(math.radians(fov) / 2.0)
    eye = centre - np.array([0.0, 0.0, distance + (bounds[1, 2] - bounds[0, 2]) / 2.0])
    return Camera(eye=eye, look_at=centre, up=np.array([0.0, 1.0, 0.0]), fov=fov,
                  width=width, height=height)


def camera_frame(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(forward, right, true_up)``, unit vectors of the docs/design.md §6 convention."""
    forward = np.asarray(camera.look_at, float) - np.asarray(camera.eye, float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(camera.up, float))
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    return forward, right, true_up


def sample_offsets(spp: int) -> np.ndarray:
    """``(spp, 2)`` sub-pixel positions in [0, 1)².

    A square count: the cell centres of a ``√spp × √spp`` grid, row by row. Any other count: a
    rank-1 lattice, ``((k + ½) / n, ((k·g mod n) + ½) / n)`` with ``g`` coprime to ``n`` near
    ``n / φ`` (golden ratio): one sample in every row and every column of an ``n × n`` grid,
    spread over the pixel, centred on it (a trimmed grid left the last row short: at 2 samples
    both sat in the upper half)."""
    s = math.isqrt(spp)
    if s * s == spp:
        g = (np.arange(s) + 0.5) / s
        return np.stack(np.meshgrid(g, g, indexing="xy"), axis=-1).reshape(-1, 2)
    step = max(1, round(spp / ((1.0 + math.sqrt(5.0)) / 2.0)))
    while math.gcd(step, spp) != 1:
        step += 1
    k = np.arange(spp)
    return np.column_stack([(k + 0.5) / spp, ((k * step) % spp + 0.5) / spp])


def primary_rays(camera: Camera, rows: slice, cols: slice, spp: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Rays through the pixels ``rows × cols``: ``origins (n, 3)``, unit ``directions (n, 3)``,
    ordered (row, column, sample)."""
    r = np.arange(rows.start, rows.stop, dtype=float)
    c = np.arange(cols.start, cols.stop, dtype=float)
    return _rays(camera, r[:, None], c[None, :], spp)


def pixel_rays(camera: Camera, r: np.ndarray, c: np.ndarray, spp: int
               ) -> tuple[np.ndarray, np.ndarray]:
    """Rays through the pixels ``(r[k], c[k])``, ``spp`` each, ordered (pixel, sample): a
    pixel's rays are those :func:`primary_rays` casts through it, bit for bit."""
    return _rays(camera, np.asarray(r, float)[:, None], np.asarray(c, float)[:, None], spp)


def _rays(camera: Camera, r: np.ndarray, c: np.ndarray, spp: int):
    """Rays of the pixels at rows ``r`` and columns ``c`` (broadcast against each other)."""
    forward, right, true_up = camera_frame(camera)
    w, h = camera.width, camera.height
    tan_half = math.tan(math.radians(camera.fov) / 2.0)
    off = sample_offsets(spp)
    r, c = np.broadcast_arrays(r, c)
    px = c[..., None] + off[:, 0]
    py = r[..., None] + off[:, 1]
    x_ndc = 2.0 * px / w - 1.0
    y_ndc = 1.0 - 2.0 * py / h
    d = (forward[None, None, None, :]
         + (x_ndc * tan_half)[..., None] * right
         + (y_ndc * tan_half * h / w)[..., None] * true_up)
    d = d.reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(np.asarray(camera.eye, float), d.shape).copy()
    return o, d


def shade(ctx: RenderContext, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Radiance ``(n, 3)`` seen along each ray: Gouraud interpolation of vertex radiance on the
    first surface hit, black for misses and for the back of a face."""
    return _shade(ctx, origins, directions)[0]


def _shade(ctx: RenderContext, origins: np.ndarray, directions: np.ndarray):
    """:func:`shade` and the hits: ``(L, hit (n,) bool, t, tri, u, v, front (h,) bool)``."""
    t, tri, u, v = _closest(ctx, origins, directions)
    hit = tri >= 0
    out, front = shade_hits(ctx.vertex_radiance, ctx.tri_verts, ctx.tri_element,
                            ctx.elem_normal, np.ascontiguousarray(directions), tri, u, v)
    return out, hit, t, tri, u, v, front[hit]


def _closest(ctx: RenderContext, origins: np.ndarray, directions: np.ndarray):
    """``(t, tri, u, v)``: the first element triangles the rays meet (``t > 0``), found
    through the polygons where the context has its locator (:data:`POLYGON_HITS`)."""
    n = len(origins)
    tmin, tmax = np.zeros(n), np.full(n, np.inf)
    if _hit_polygons(ctx) is not None:
        if (VIEW_BINS and n > 1 and VIEW_RAYS * n >= len(ctx.occluders.triangles)
                and _one_origin(origins)):       # the camera's rays
            return view_hits_batch(ctx.occluders, ctx.locator, ctx.grid, origins[0],
                                   directions)
        return closest_hit_located_batch(ctx.occluders, ctx.locator, ctx.grid, origins,
                                         directions, tmin, tmax)
    return closest_hit(ctx.grid, origins, directions, tmin, tmax)


def _one_origin(origins: np.ndarray) -> bool:
    """Whether every ray leaves the same point, bit for bit (a signed zero apart too)."""
    o = np.ascontiguousarray(origins, dtype=np.float64).view(np.uint64)
    return bool((o == o[0]).all())


def _hit_polygons(ctx: RenderContext) -> Grid | None:
    """The polygons' grid the view's hits are found in (the context has its locator,
    :func:`with_locator`), else None: the element grid is walked."""
    return ctx.occluders if ctx.locator is not None else None


#: The primary rays, mirror rays and the junction gather's rays find their hits among the
#: scene's polygons (the occluders' grid, :func:`daskrad.preprocess.occluders`) and locate
#: them among the elements' triangles (:func:`daskrad.kernels.grid.closest_hit_located`)
#: instead of walking the elements' grid (:func:`for_view` sets the context's locator). The
#: same hits to round-off but where two one-sided faces coincide, back to back: the ray then
#: sees the one facing it, as the item buffers do, where the walk took whichever round-off
#: favoured (a black speck for a face seen from behind). Measured (``bench_hits``, 256 × 256,
#: 2 threads): the Cornell box's gather 0.93 → 0.67 s and tiles 0.45 → 0.36 s, the converted
#: office's gather 10.23 → 8.08 s. ``False`` is the benchmark's reference arm.
POLYGON_HITS = True

#: Rays that leave one point (the camera's primary rays) find their polygon by screen bins
#: instead of walking the polygons' grid (:func:`daskrad.kernels.view.view_hits_batch`: the
#: polygons projected into bins, each ray testing its bin's, nearest first): the same bits.
#: Measured (``bench_hits``' view table: every tile's primary rays at 4 samples a pixel, one
#: thread, 256 × 256): the Cornell box 0.130 → 0.053 s, the lit room 0.121 → 0.039 s,
#: RenderPark's classroom 0.247 → 0.098 s; its office by script (400 × 300) 0.519 → 0.379 s.
#: ``False`` is the benchmark's reference arm.
VIEW_BINS = True
#: ... for a batch of at least ``1 / VIEW_RAYS`` as many rays as polygon triangles: binning
#: costs ~65 ns a triangle (RenderPark's office, 53,460 of them), and a ray found by bins
#: saves ~0.5 µs of its walk there, so fewer rays (an edge pixel or two) walk.
VIEW_RAYS = 8


def with_locator(ctx: RenderContext, known: np.ndarray | None = None) -> RenderContext:
    """``ctx`` with its :attr:`RenderContext.locator` when it has polygons to find hits
    among (:data:`POLYGON_HITS`), else itself. ``known``: the locator of the same grid,
    made already."""
    if not POLYGON_HITS or ctx.occluders is None or ctx.locator is not None:
        return ctx
    return replace(ctx, locator=known if known is not None else locator(ctx.grid.triangles))


def perpixel_elements(elem_verts: np.ndarray, vertex_direct: np.ndarray,
                      vertex_total: np.ndarray, rdiff: float) -> np.ndarray:
    """``(E,) bool``: the elements whose direct light the per-pixel pass recomputes (eq. 9).

    ``max(Rmax − Rmin, Gmax − Gmin, Bmax − Bmin) > Rdiff`` over an element's corners, where the
    paper's colours are display values in ``[0, 1]``. Here radiance has the scene's units, so the
    colours are measured in units of the scene's white level, the 90th percentile of the
    vertices' brightest channel of ``vertex_total (V, 3)`` (robust to the few very bright
    emitter vertices): ``Rdiff = 0.1`` is then a step of 10 % of a bright wall, whatever the
    scene's units. The spread tested is that of ``vertex_direct (V, 3)`` only: indirect light
    is interpolated anyway, so an element whose spread is indirect gains nothing from the pass.
    ``elem_verts (E, 4) int`` with ``-1`` for a triangle's fourth corner.
    """
    ev = elem_verts
    if len(ev) == 0:
        return np.zeros(0, bool)
    c3 = np.where(ev[:, 3] >= 0, ev[:, 3], ev[:, 0])
    corners = np.stack([vertex_direct[ev[:, 0]], vertex_direct[ev[:, 1]],
                        vertex_direct[ev[:, 2]], vertex_direct[c3]], axis=1)
    spread = (corners.max(axis=1) - corners.min(axis=1)).max(axis=1)
    white = white_level(ev, vertex_total)
    if white <= 0.0:
        return np.zeros(len(ev), bool)
    return spread > rdiff * white


def white_level(elem_verts: np.ndarray, vertex_total: np.ndarray) -> float:
    """The scene's white level, radiance: the 90th percentile of the brightest channel of
    ``vertex_total (V, 3)`` over the elements' corners (robust to the few very bright
    emitter vertices); 0 for an empty or black scene."""
    used = np.unique(elem_verts[elem_verts >= 0])
    return float(np.percentile(vertex_total[used].max(axis=1), 90)) if len(used) else 0.0


#: A pixel whose samples differ by more than this fraction of the scene's white level
#: (:func:`white_level`) in any channel is sampled again at ``edge_spp`` samples
#: (:func:`render_tile_stats`).
EDGE_STEP = 0.3


def tiles(width: int, height: int, tile: int = TILE) -> list[tuple[slice, slice]]:
    """Row-major list of ``(rows, cols)`` tiles covering the image."""
    return [(slice(y, min(y + tile, height)), slice(x, min(x + tile, width)))
            for y in range(0, height, tile) for x in range(0, width, tile)]


def sample_ids(camera: Camera, rows: slice, cols: slice, spp: int) -> np.ndarray:
    """``(n,) int64`` global id of each pixel sample of ``rows × cols`` (the order of
    :func:`primary_rays`): ``(row · W + col) · spp + sample``. It seeds the per-pixel shadow
    rays, so a pixel gets the same bits whichever tile or worker computes it."""
    r = np.arange(rows.start, rows.stop, dtype=np.int64)
    c = np.arange(cols.start, cols.stop, dtype=np.int64)
    return _sample_ids(camera, r[:, None], c[None, :], spp)


def _sample_ids(camera: Camera, r: np.ndarray, c: np.ndarray, spp: int) -> np.ndarray:
    """The ids of :func:`sample_ids` for the pixels at rows ``r`` and columns ``c`` (int64,
    broadcast against each other), in the order of :func:`_rays`."""
    pix = r * camera.width + c
    return (pix[..., None] * spp + np.arange(spp, dtype=np.int64)).reshape(-1)


def render_tile(ctx: RenderContext, rows: slice, cols: slice) -> np.ndarray:
    """``(h, w, 3) float64`` radiance of one tile, box-filtered over ``ctx.spp`` samples."""
    return render_tile_stats(ctx, rows, cols)[0]


def render_tile_stats(ctx: RenderContext, rows: slice, cols: slice
                      ) -> tuple[np.ndarray, dict]:
    """:func:`render_tile` and what the per-pixel pass did: ``{"perpixel": samples whose
    direct light was recomputed, "hard": samples given exact point and directional light
    (the others), "specular": samples given a Phong term, "mirror": mirror rays traced,
    "edges": pixels sampled again at ``edge_spp``, "verdicts": sample-light pairs of those
    pixels settled by :data:`EDGE_VERDICTS`}`` (0 when the context asks for nothing beyond
    Gouraud). With edge resampling the sample counts include every sample cast: the
    one-pixel apron's (which the neighbouring tile casts too) and the edge pixels'.

    Edges: a pixel whose ``spp`` samples, with those of its 8 neighbours, differ by more than
    ``ctx.edge_step`` in any channel (a silhouette, the light's outline, a shadow's edge)
    takes the mean of ``ctx.edge_spp`` samples instead: the value a whole image at
    ``edge_spp`` gives that pixel, bit for bit (the same rays and shadow-ray seeds), at the
    cost of the edge pixels only; but with :data:`EDGE_VERDICTS` an area light that the base
    samples of the pixel and its neighbours agree on is taken as they found it. The fixed
    ``spp`` grid alone errs most there: the Cornell box at 128², off the light, against the
    path tracer: 0.077 relative RMS at 4 samples, 0.038 at 64 everywhere, 0.038 with 4 and 64
    on the 13 % of pixels on an edge.
    """
    stats = {"perpixel": 0, "hard": 0, "specular": 0, "mirror": 0, "edges": 0, "verdicts": 0}
    h, w = rows.stop - rows.start, cols.stop - cols.start
    if not ctx.edge_spp > ctx.spp:
        o, d = primary_rays(ctx.camera, rows, cols, ctx.spp)
        seeds = sample_ids(ctx.camera, rows, cols, ctx.spp)
        L = _samples(ctx, o, d, seeds, stats, ctx.spp)
        return L.reshape(h, w, ctx.spp, 3).mean(axis=2), stats
    # the tile and a one-pixel apron inside the image: an edge between a pixel's samples and
    # its border shows as a step to the neighbour's samples across it (the light's outline
    # crossing a row of pixels below their samples). The apron's samples are the bits its
    # own tile computes, so a pixel's decision does not depend on the tiling.
    cam = ctx.camera
    big_rows = slice(max(rows.start - 1, 0), min(rows.stop + 1, cam.height))
    big_cols = slice(max(cols.start - 1, 0), min(cols.stop + 1, cam.width))
    bh, bw = big_rows.stop - big_rows.start, big_cols.stop - big_cols.start
    o, d = primary_rays(cam, big_rows, big_cols, ctx.spp)
    seeds = sample_ids(cam, big_rows, big_cols, ctx.spp)
    record = {} if EDGE_VERDICTS else None
    L = _samples(ctx, o, d, seeds, stats, ctx.spp, record).reshape(bh, bw, ctx.spp, 3)
    dr, dc = rows.start - big_rows.start, cols.start - big_cols.start
    inner = (slice(dr, dr + h), slice(dc, dc + w))
    image = L[inner].mean(axis=2)
    hi, lo = _neighbourhood(L.max(axis=2), np.maximum), _neighbourhood(L.min(axis=2), np.minimum)
    r, c = np.nonzero(((hi - lo).max(axis=2) > ctx.edge_step)[inner])
    if len(r):
        r0, c0 = r + rows.start, c + cols.start
        o, d = pixel_rays(cam, r0, c0, ctx.edge_spp)
        seeds = _sample_ids(cam, r0.astype(np.int64)[:, None], c0.astype(np.int64)[:, None],
                            ctx.edge_spp)
        verdicts = None
        if record:
            # the base samples of each edge pixel and its 8 neighbours: rows of L in (big
            # tile, sample) order; neighbours outside the image count as no element
            rr = (r + dr)[:, None] + NEIGHBOURS[:, 0]
            cc = (c + dc)[:, None] + NEIGHBOURS[:, 1]
            inside = (rr >= 0) & (rr < bh) & (cc >= 0) & (cc < bw)
            base = ((np.where(inside, rr * bw + cc, 0) * ctx.spp)[:, :, None]
                    + np.arange(ctx.spp)).reshape(len(r), -1)
            elem = np.where(np.repeat(inside, ctx.spp, axis=1), record["elem"][base], -1)
            verdicts = Verdicts(np.repeat(np.arange(len(r), dtype=np.int64), ctx.edge_spp),
                                elem, record["classes"][base], ctx.spp)
        image[r, c] = _samples(ctx, o, d, seeds, stats, ctx.edge_spp, None, verdicts).reshape(
            len(r), ctx.edge_spp, 3).mean(axis=1)
        stats["edges"] += len(r)
    return image, stats


def _neighbourhood(a: np.ndarray, op) -> np.ndarray:
    """``op`` (``np.maximum`` or ``np.minimum``) of ``a (h, w, 3)`` over each pixel's 3 × 3
    neighbourhood (clipped at the borders)."""
    out = a.copy()
    op(out[1:], a[:-1], out=out[1:])
    op(out[:-1], a[1:], out=out[:-1])
    rows = out.copy()
    op(out[:, 1:], rows[:, :-1], out=out[:, 1:])
    op(out[:, :-1], rows[:, 1:], out=out[:, :-1])
    return out


def _samples(ctx: RenderContext, o: np.ndarray, d: np.ndarray, seeds: np.ndarray,
             stats: dict, spp: int, record: dict | None = None,
             verdicts: Verdicts | None = None) -> np.ndarray:
    """Radiance ``(n, 3)`` along primary rays, ``spp`` per pixel: :func:`_radiance`, or the
    plain Gouraud image's :func:`shade` when the context asks for no per-pixel work.

    Beyond :data:`LIGHT_SPP` samples per pixel an area light's shadow rays per sample shrink
    (:func:`shadow_side`), so that a pixel casts about as many as at ``LIGHT_SPP``: more
    samples resolve edges, not the light's noise, which the pixel's shadow rays already
    average. ``record``, ``verdicts``: :func:`_radiance`'s."""
    if not ctx.extras:
        return shade(ctx, o, d)
    if ctx.lights is not None and spp > LIGHT_SPP:
        ctx = replace(ctx, lights=replace(ctx.lights,
                                          samples=shadow_side(ctx.lights.samples, spp)))
    return _radiance(ctx, o, d, seeds, 0, stats, record, verdicts)


class Verdicts(NamedTuple):
    """What an edge pixel's base samples found of each area light
    (:func:`daskrad.kernels.shade.pixel_modes`, :data:`EDGE_VERDICTS`).

    pixel : (n,) int64
        The pixel (a row of the two others) of each of the edge samples.
    base_elem : (P, 9 spp) int64
        The element each base sample of each pixel and of its neighbours hit where its
        direct light was computed, -1 elsewhere.
    base_class : (P, 9 spp, M) int8
        Each area light's class at each base sample.
    own : int
        Base samples per pixel (``spp``): the pixel's own come first in each row, then its
        8 neighbours' (:data:`NEIGHBOURS`; -1 elements outside the image).
    """

    pixel: np.ndarray
    base_elem: np.ndarray
    base_class: np.ndarray
    own: int


#: A pixel and its 8 neighbours, ``(row, column)`` offsets, the pixel first.
NEIGHBOURS = np.array([(0, 0), (-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0),
                       (1, 1)])


#: An edge pixel's extra samples (``edge_spp``) take an area light as wholly visible or
#: wholly hidden, without shadow rays, where every base sample of the pixel lies on the
#: sample's element and found it so, and so did every base sample of the 8 neighbouring
#: pixels on that element (:func:`daskrad.kernels.shade.pixel_modes`). A pixel is an edge for
#: its outline or one light's shadow; its other lights mostly shine on all of it or on none.
#: A base sample's class comes from its own shadow rays (or, with :data:`SHADOW_PROBES`, the
#: four corner strata they agreed on). ``benchmarks/bench_edges.py``: RenderPark's office's
#: tiles 1.11× faster, the error against 4× the shadow rays 2.078e-3 → 2.082e-3.
#: ``False``: every extra sample traces every light (an edge pixel then has the bits of a
#: whole image at ``edge_spp``).
EDGE_VERDICTS = True


#: Samples per pixel up to which each sample casts the area lights' ``samples²`` shadow rays.
LIGHT_SPP = 4


def shadow_side(samples: int, spp: int) -> int:
    """Shadow rays per side (``n²`` per area light) of one of ``spp`` samples of a pixel:
    ``samples`` up to :data:`LIGHT_SPP`, then ``samples · √(LIGHT_SPP / spp)`` rounded, at
    least 1 (4 at 4 samples: 64 rays a pixel; 1 at 64 samples: 64)."""
    if spp <= LIGHT_SPP:
        return int(samples)
    return max(1, int(round(samples * math.sqrt(LIGHT_SPP / spp))))


def _radiance(ctx: RenderContext, o: np.ndarray, d: np.ndarray, seeds: np.ndarray, depth: int,
              stats: dict, record: dict | None = None,
              verdicts: Verdicts | None = None) -> np.ndarray:
    """Radiance along rays with the per-pixel pass, Phong highlights and mirrors.

    Every hit first gets the Gouraud value of :func:`shade` (bit for bit); then
    - with ``hard_lights``, on every other element the point and directional lights' part is
      replaced by its exact value at the hit: ``L = interp(vertex_soft) + ρ H_hard(p) / π``;
    - on an element of ``elem_perpixel`` (eq. 9) the direct part is replaced by its exact
      value at the hit: ``L = interp(vertex_indirect) + Ke + ρ H(p) / π``;
    - on a material with ``Ks`` (not a mirror) the Phong radiance of every light is added;
    - on a mirror (``illum 3``), ``Ks`` times the radiance along the mirrored ray, followed
      ``mirror_depth`` times at most.
    Secondary rays seed their shadow rays with ``seed + depth · SEED_STRIDE`` (distinct ids).

    ``record``: a dict that receives, for these rays' own hits, ``"elem" (n,) int64`` (the
    element where the direct light was computed, -1 elsewhere) and ``"classes" (n, M) int8``
    (each area light's class there). ``verdicts``: the base samples' record of the pixels
    these rays sample again (:class:`Verdicts`).
    """
    L, hit, t, tri, u, v, front = _shade(ctx, o, d)
    if not hit.any():
        return L
    idx = np.flatnonzero(hit)[front]
    tri_f = tri[idx]
    elem = ctx.tri_element[tri_f]
    lights = ctx.lights
    hard = ctx.hard_lights
    if hard is not None:
        sel = ~ctx.elem_perpixel[elem] & (ctx.elem_reflectance[elem] > 0).any(axis=1)
        if sel.any():
            a = idx[sel]
            e = elem[sel]
            p = o[a] + t[a, None] * d[a]
            H, _ = direct_at_hits(
                shadow_grid(ctx), np.ascontiguousarray(p),
                np.ascontiguousarray(ctx.elem_normal[e]),
                np.ascontiguousarray(-d[a]), np.ascontiguousarray(seeds[a]),
                np.zeros((len(a), 3)), np.zeros(len(a)), float(hard.offset), *hard.light_args,
                int(hard.samples), np.zeros((len(a), len(hard.emitter_corners)), np.int8))
            L[a] = (gouraud(ctx.vertex_soft, ctx.tri_verts, tri[a], u[a], v[a])
                    + ctx.elem_reflectance[e] * H / math.pi)
            stats["hard"] += int(sel.sum())
    if record is not None and lights is not None:
        record["elem"] = np.full(len(o), -1, np.int64)
        record["classes"] = np.zeros((len(o), len(lights.emitter_corners)), np.int8)
    if lights is not None and ctx.elem_perpixel is not None:
        mirror = ctx.elem_mirror[elem] if ctx.elem_mirror is not None else False
        pp = ctx.elem_perpixel[elem]
        ks = np.where(np.asarray(mirror)[..., None], 0.0, ctx.elem_specular[elem])
        sp = (ks > 0).any(axis=1)
        work = pp | sp
        if work.any():
            w = idx[work]
            ew = elem[work]
            p = o[w] + t[w, None] * d[w]
            H, S, C = _direct_at(ctx, lights, p, ew, -d[w], seeds[w], ks[work],
                                 None if verdicts is None else
                                 verdicts._replace(pixel=verdicts.pixel[w]), stats)
            if record is not None:
                record["elem"][w] = ew
                record["classes"][w] = C
            ppw = pp[work]
            if ppw.any():
                a = w[ppw]
                e = ew[ppw]
                L[a] = (gouraud(ctx.vertex_indirect, ctx.tri_verts, tri[a], u[a], v[a])
                        + ctx.elem_emission[e] + ctx.elem_reflectance[e] * H[ppw] / math.pi)
            spw = sp[work]
            L[w[spw]] += S[spw]
            stats["perpixel"] += int(ppw.sum())
            stats["specular"] += int(spw.sum())
    if ctx.elem_mirror is not None and depth < ctx.mirror_depth:
        m = ctx.elem_mirror[elem]
        if m.any():
            a = idx[m]
            nrm = ctx.elem_normal[elem[m]]
            dm = d[a] - 2.0 * np.einsum("ij,ij->i", d[a], nrm)[:, None] * nrm
            p = o[a] + t[a, None] * d[a] + ctx.offset * nrm
            Lr = _radiance(ctx, p, dm, seeds[a] + (depth + 1) * SEED_STRIDE, depth + 1, stats)
            L[a] += ctx.elem_specular[elem[m]] * Lr
            stats["mirror"] += int(m.sum())
    return L


#: The per-pixel pass probes each area light it traces from the four corner strata of its
#: ``s × s`` shadow rays first (``s ≥ 3``, :func:`daskrad.kernels.direct.irradiance_one`'s
#: ``probe``) and takes the light as wholly free or hidden when they agree: most traced pairs
#: of a hit lie wholly in light or in shadow even on an element its corners disagree on. What
#: it misses is a shadow or a gap that passes between the corner strata (a thin occluder seen
#: whole inside the light's outline). Measured (``bench_perpixel``, 192 × 144, both against
#: the same tiles at 4× the shadow rays without probes): RenderPark's ``office3`` tiles
#: 1.57× faster, relative RMS error 1.48e-3 → 1.49e-3, pixels more than 5 % off 1,076 →
#: 1,081 of 27,648 (259 pixels changed, by 16 % at most); the Cornell box 1.11×, 7.35e-4 →
#: 7.37e-4, 59 → 60 (37 changed, by 12 % at most).
SHADOW_PROBES = True

#: The per-pixel pass computes Lambert's ``F`` of an area light after its shadow rays, and only
#: for a light one of them reaches (:func:`daskrad.kernels.direct.irradiance_one`'s
#: ``lambert_first``): the same bits, as a light every ray finds blocked adds ``+0.0``. Most
#: lights a hit of a furnished interior traces are hidden from it. ``False``: ``F`` first, as
#: the vertex pass (``bench_perpixel`` compares the two).
LAMBERT_AFTER_RAYS = True


def _direct_at(ctx: RenderContext, lights: Lights, p: np.ndarray, elem: np.ndarray,
               views: np.ndarray, seeds: np.ndarray, ks: np.ndarray,
               verdicts: Verdicts | None = None, stats: dict | None = None):
    """:func:`direct_at_hits` at hits ``p (n, 3)`` on elements ``elem (n,)``: ``(H, S,
    classes (n, M) int8)``. Hits on an element of ``ctx.elem_unshadowed`` are evaluated
    without occluders (no shadow ray of theirs can be blocked, so the bits are those of
    tracing them), the rest through the grid. Each hit's value depends on the hit alone (and
    with ``verdicts``, whose ``pixel`` is (n,) for these hits, on its pixel's base samples),
    so the split changes nothing but the time. ``stats["verdicts"]`` counts the hit-light
    pairs the verdicts settled."""
    n_lights = len(lights.emitter_corners)

    def run(grid, sel):
        e = elem[sel]
        modes = (ctx.elem_light_mode[e] if ctx.elem_light_mode is not None
                 else np.zeros((len(e), n_lights), np.int8))
        if modes.shape != (len(e), n_lights):   # numba reads unchecked
            raise ValueError(f"light modes of shape {modes.shape} for {n_lights} area lights")
        if verdicts is not None:
            taken = pixel_modes(np.ascontiguousarray(modes), np.ascontiguousarray(e),
                                np.ascontiguousarray(verdicts.pixel[sel]), verdicts.base_elem,
                                verdicts.base_class, verdicts.own)
            if stats is not None:
                stats["verdicts"] += int((taken != modes).sum())
            modes = taken
        classes = np.zeros((len(e), n_lights), np.int8)
        H, S = direct_at_hits(
            grid, np.ascontiguousarray(p[sel]), np.ascontiguousarray(ctx.elem_normal[e]),
            np.ascontiguousarray(views[sel]), np.ascontiguousarray(seeds[sel]),
            np.ascontiguousarray(ks[sel]), np.ascontiguousarray(ctx.elem_shininess[e]),
            float(lights.offset), *lights.light_args, int(lights.samples),
            np.ascontiguousarray(modes), SHADOW_PROBES, not LAMBERT_AFTER_RAYS, SHADOW_CACHE,
            classes)
        return H, S, classes

    grid = shadow_grid(ctx)
    if ctx.elem_unshadowed is None:
        return run(grid, slice(None))
    free = ctx.elem_unshadowed[elem]
    if not free.any():
        return run(grid, slice(None))
    H = np.zeros((len(p), 3))
    S = np.zeros((len(p), 3))
    C = np.zeros((len(p), n_lights), np.int8)
    H[free], S[free], C[free] = run(ctx.open_grid, free)
    if not free.all():
        H[~free], S[~free], C[~free] = run(grid, ~free)
    return H, S, C


def shadow_grid(ctx: RenderContext) -> Grid:
    """The grid the per-pixel pass's shadow rays walk (:data:`POLYGON_OCCLUDERS`)."""
    return ctx.occluders if POLYGON_OCCLUDERS and ctx.occluders is not None else ctx.grid


#: The per-pixel pass's shadow rays walk the grid over the scene's polygons
#: (:func:`daskrad.preprocess.occluders`) instead of the grid over the elements
#: (``bench_perpixel``; docs/benchmarks.md has its figures; ``False`` is the benchmark's
#: reference arm).
POLYGON_OCCLUDERS = True

#: Each area light's shadow rays in a tile try the triangle that blocked the light's last ray
#: first (:func:`daskrad.kernels.shade.direct_at_hits`' ``cache``): the same bits. RenderPark's
#: office, 7 of its 35 tiles at 400 × 300: 74 % of the probe rays are blocked, and the last
#: blocker blocks again for 14 % of them through the element grid, 41 % through the polygons'
#: (``bench_perpixel`` measures the time).
SHADOW_CACHE = True


#: Seed offset between mirror bounces: above any pixel sample id of a 2¹⁶ × 2¹⁶ image at
#: 2¹⁰ samples per pixel, so a secondary hit never reuses a primary hit's jitter.
SEED_STRIDE = 1 << 42


def render(ctx: RenderContext) -> np.ndarray:
    """The whole image, ``(H, W, 3) float64``, tile by tile in-process (the junction gather
    applied for its camera, :func:`for_view`)."""
    return pixels(ctx)


def perpixel_context(ctx: RenderContext, elem_verts: np.ndarray, *, vertex_indirect: np.ndarray,
                     vertex_direct: np.ndarray, elem_reflectance: np.ndarray,
                     elem_emission: np.ndarray, elem_specular: np.ndarray,
                     elem_shininess: np.ndarray, elem_mirror: np.ndarray,
                     lights: Lights | None, rdiff: float | None, mirror_depth: int,
                     diagonal: float, direct_context=None, tvertices=None,
                     element_size: float | None = None) -> RenderContext:
    """``ctx`` with the per-pixel pass and specular light switched on where they apply.

    ``elem_verts (E, 4) int`` are the elements' corners; ``vertex_direct (V, 3)`` is the
    direct part of ``ctx.vertex_radiance`` (radiance); ``rdiff`` ``None`` switches the pass
    off. With the pass on and ``direct_context`` (the :class:`daskrad.direct.DirectContext`
    the vertices were lit with; ``tvertices`` its T-vertices) holding point or directional
    lights, those are evaluated exactly at every pixel (``hard_lights``; their vertex part,
    recomputed here as the direct pass did, is taken out of what is interpolated), and the
    elements of eq. 9 are selected by the spread of the remaining direct part (area lights).
    With the pass on and ``direct_context``, the context carries the junction gather
    (:class:`Junctions`), applied per view by :func:`for_view` (so a context may come back
    with it even when no pixel needs more than Gouraud; ``element_size``, the mesh's element
    size, sets how far a junction reaches, by default 1/32 of ``diagonal``).
    Arrays a scene does not need are left ``None``: no hard light, no qualifying element, no
    ``Ks`` and no mirror give back the plain context, so the tile tasks do exactly the work of
    a Gouraud image.
    """
    if lights is not None and lights.empty:
        lights = None
    junctions = None
    if rdiff is not None and direct_context is not None:
        # indirect light gathered at vertices beside a junction, where element averages miss
        # the near field (the foot of a block's face on a lit floor); applied per view
        junctions = _junctions(direct_context, tvertices, elem_verts, elem_reflectance,
                               elem_emission, vertex_indirect, diagonal, element_size,
                               mirror_depth, elem_mirror)
    hard, vertex_hard = None, None
    if rdiff is not None and lights is not None and direct_context is not None:
        hard, vertex_hard = _hard_part(direct_context, tvertices, elem_verts, elem_reflectance,
                                       lights)
    soft_direct = vertex_direct if vertex_hard is None else vertex_direct - vertex_hard
    pp = (perpixel_elements(elem_verts, soft_direct, ctx.vertex_radiance, rdiff)
          if rdiff is not None and lights is not None else None)
    spec = np.ascontiguousarray(elem_specular, dtype=np.float64)
    mirror = np.asarray(elem_mirror, bool)
    has_pp = pp is not None and pp.any()
    has_spec = lights is not None and bool((spec[~mirror] > 0).any())
    has_mirror = mirror_depth > 0 and bool(mirror.any())
    if not (has_pp or has_spec or has_mirror or hard is not None):
        return replace(ctx, junctions=junctions)
    E = len(elem_reflectance)
    if hard is not None:
        ctx = replace(ctx, hard_lights=hard, vertex_soft=np.ascontiguousarray(
            ctx.vertex_radiance - vertex_hard))
    return replace(
        ctx,
        vertex_indirect=np.ascontiguousarray(vertex_indirect, dtype=np.float64),
        elem_perpixel=pp if has_pp else np.zeros(E, bool),
        elem_reflectance=np.ascontiguousarray(elem_reflectance, dtype=np.float64),
        elem_emission=np.ascontiguousarray(elem_emission, dtype=np.float64),
        elem_specular=spec,
        elem_shininess=np.ascontiguousarray(elem_shininess, dtype=np.float64),
        elem_mirror=mirror,
        lights=lights if (has_pp or has_spec) else None,
        mirror_depth=int(mirror_depth) if has_mirror else 0,
        offset=tolerances.RAY_OFFSET * float(diagonal),
        junctions=junctions,
    )


def _junctions(direct_context, tvertices, elem_verts: np.ndarray, elem_reflectance: np.ndarray,
               elem_emission: np.ndarray, vertex_indirect: np.ndarray, diagonal: float,
               element_size: float | None, mirror_depth: int, elem_mirror: np.ndarray
               ) -> Junctions:
    """The :class:`Junctions` :func:`perpixel_context` gives a context (and
    :func:`geometry_context`): reaching one element size (1/32 of ``diagonal`` when not
    given, :data:`JUNCTION_REACH`), everywhere when a mirror may show any vertex."""
    size = diagonal / 32.0 if element_size is None else element_size
    return junctions_of(direct_context, tvertices, elem_verts, elem_reflectance, elem_emission,
                        vertex_indirect, JUNCTION_REACH * size,
                        mirror_depth > 0 and bool(np.asarray(elem_mirror, bool).any()))


def camera(scene: Scene, settings: Settings) -> Camera:
    """The scene's camera (or :func:`default_camera`) at the settings' image size."""
    cam = scene.camera or default_camera(scene.bounds, inside=faces_inward(scene))
    return replace(cam, width=settings.width or cam.width, height=settings.height or cam.height)


def context(scene: Scene, light: DirectLight, sol: Solution, settings: Settings,
            cam: Camera, split: tuple[np.ndarray, np.ndarray] | None = None) -> RenderContext:
    """The tile renderer's context for a solution.

    Vertex radiance is split into the part interpolated across elements (indirect light and
    the ambient term of an unconverged solution) and the direct part ``E + ρH``, exact at
    every vertex; T-vertices take both from their edge, so no seam shows. The per-pixel pass
    (eq. 9), Phong highlights and mirrors are switched on where the scene needs them
    (:func:`perpixel_context`). ``split``: :func:`vertex_split` of ``light`` and ``sol`` when
    the caller has it already. The junction gather is carried, not applied
    (:func:`for_view`).
    """
    mesh = light.mesh
    h, reflectance = mesh.hierarchy, mesh.reflectance
    indirect, direct_v = vertex_split(light, sol) if split is None else split
    ctx = RenderContext(grid=mesh.grid, tri_verts=mesh.tri_verts, tri_element=mesh.tri_element,
                        elem_normal=h.elem_normal, vertex_radiance=indirect + direct_v,
                        camera=cam, spp=settings.spp, edge_spp=settings.edge_spp,
                        edge_step=EDGE_STEP * white_level(h.elem_verts, indirect + direct_v),
                        occluders=mesh.occluders.grid)
    mats, mat = scene.materials, h.elem_material
    ctx = perpixel_context(
        ctx, h.elem_verts, vertex_indirect=indirect, vertex_direct=direct_v,
        elem_reflectance=reflectance, elem_emission=mats.emission[mat],
        elem_specular=mats.specular[mat], elem_shininess=mats.shininess[mat],
        elem_mirror=mats.mirror[mat],
        lights=(direct.lights_of(light.context)
                if light.irradiance is not None and light.context is not None else None),
        rdiff=settings.rdiff if settings.per_pixel else None,
        mirror_depth=settings.mirror_depth, diagonal=scene.diagonal,
        direct_context=light.context if light.irradiance is not None else None,
        tvertices=light.tvertices,
        element_size=settings.element_size or default_sizes(scene)[1])
    return with_light_modes(with_unshadowed(ctx, h), h, light.classes, light.tvertices)


def vertex_split(light: DirectLight, sol: Solution) -> tuple[np.ndarray, np.ndarray]:
    """``(indirect, direct)``, each ``(V, 3) float64`` radiance: vertex radiance split into
    the part interpolated across elements (indirect light and the ambient term of an
    unconverged solution) and the direct part ``(E + ρH) / π``, exact at every vertex (zero
    without gathered light: then it is all in ``indirect``). T-vertices take both from their
    edge (:func:`~daskrad.mesh.refine.resolve_tvertices`)."""
    mesh = light.mesh
    h, reflectance = mesh.hierarchy, mesh.reflectance
    amb = ambient(h, reflectance, sol.unshot)
    H = light.irradiance
    if H is None:
        indirect = vertex_average(h, sol.radiosity + reflectance * amb)
        direct_v = np.zeros_like(indirect)
    else:
        # the direct part is known exactly at every vertex: E + ρ H (one polygon per vertex);
        # with emitters shot, their direct light is part of `indirect`
        direct_v = (direct.vertex_reflectance(h, mesh.emission)
                    + direct.vertex_reflectance(h, reflectance) * H)
        indirect = vertex_average(h, sol.radiosity - sol.direct + reflectance * amb)
    return (resolve_tvertices(indirect, light.tvertices) / math.pi,
            resolve_tvertices(direct_v, light.tvertices) / math.pi)


#: :func:`with_unshadowed` first tries every this-many-th element it would test; when none of
#: them is proved unshadowed, it tests no other. A furnished room has an occluder near every
#: element's rays to some luminaire: the converted office proved none of 17,329 elements, for
#: 2.2 s of its render's serial part (0.85 s through the polygons' grid); the Cornell box
#: proves 433 of 964.
UNSHADOWED_PROBE = 16


def with_unshadowed(ctx: RenderContext, h) -> RenderContext:
    """``ctx`` with the elements of the per-pixel pass whose shadow rays cannot be blocked
    (:func:`daskrad.kernels.unshadowed.unshadowed_elements`, against the triangles those rays
    walk, :func:`shadow_grid`; tried on a sample first, :data:`UNSHADOWED_PROBE`). Cornell
    box: 433 of the 964 per-pixel elements (473 of 1,061 when measured: the tiles' CPU time
    1.49 -> 0.82 s), the same bits."""
    lights = ctx.lights
    if lights is None or ctx.elem_perpixel is None:
        return ctx
    wanted = ctx.elem_perpixel | ((ctx.elem_specular > 0).any(axis=1) & ~ctx.elem_mirror)
    if not wanted.any():
        return ctx

    def proved(elements):
        return unshadowed_elements(shadow_grid(ctx), h.vertices, h.elem_verts, h.elem_normal,
                                   elements, float(lights.offset), lights.point_position,
                                   np.ascontiguousarray(lights.dir_direction),
                                   lights.emitter_corners, lights.emitter_count,
                                   lights.emitter_normal)

    sample = np.zeros_like(wanted)
    sample[np.flatnonzero(wanted)[::UNSHADOWED_PROBE]] = True
    free = proved(sample)
    if not free.any():
        return ctx
    free |= proved(wanted & ~sample)
    return replace(ctx, elem_unshadowed=free, open_grid=build_grid(np.zeros((0, 3, 3))))


#: Largest ``elements × area lights`` for which the per-pixel pass keeps the lights' modes
#: (:func:`with_light_modes`, one byte each); beyond it every hit traces every light.
LIGHT_MODES_MAX = 2**26


def with_light_modes(ctx: RenderContext, h, classes: np.ndarray | None,
                     tvertices: TVertices | None = None) -> RenderContext:
    """``ctx`` with :func:`light_modes` of the vertex pass's ``classes (V, M) int8`` (the
    lights of ``ctx.lights``), when the per-pixel pass has area lights to evaluate; ``h`` the
    hierarchy. A light hidden from every corner of a per-pixel element is then marked
    ``LIGHT_HIDDEN`` where one patch is proved to block all its shadow rays from the element
    (:func:`hidden_lights`)."""
    lights = ctx.lights
    if (lights is None or classes is None or not len(lights.emitter_corners)
            or classes.shape[1] != len(lights.emitter_corners)
            or len(h.elem_verts) * classes.shape[1] > LIGHT_MODES_MAX):
        return ctx
    cls = _corner_classes(classes, tvertices)
    modes = _modes(h.elem_verts, cls)
    if ctx.elem_perpixel is not None:
        hidden = _every_corner(h.elem_verts, cls, LIGHT_HIDDEN)
        hidden &= ctx.elem_perpixel[:, None]
        modes[hidden_lights(ctx, h, hidden)] = LIGHT_HIDDEN
    return replace(ctx, elem_light_mode=modes)


def hidden_lights(ctx: RenderContext, h, candidates: np.ndarray) -> np.ndarray:
    """``(E, M) bool``: the pairs of ``candidates (E, M) bool`` (element, area light of
    ``ctx.lights``) for which one patch blocks every shadow ray of every hit on the element
    (:func:`daskrad.kernels.hidden.hidden_pairs`): its hits skip that light's rays with the
    same bits, the light adding ``+0.0`` either way.

    RenderPark's office (``office3``): 81 % of the pairs of a per-pixel element and a light
    in front of it are hidden from every corner (the floor under the desks, the desks' sides);
    the ones proved are the ones a single face shadows."""
    from daskrad.kernels.hidden import hidden_pairs, polygon_outlines

    out = np.zeros(candidates.shape, bool)
    e, m = np.nonzero(candidates)
    if not len(e):
        return out
    lights, grid = ctx.lights, ctx.grid
    # beyond the ray test's outward edge tolerance and the round-off of a hit point
    maxabs = float(np.abs(h.vertices).max()) if len(h.vertices) else 0.0
    delta = 16.0 * grid.eps + 16.0 * tolerances.COORD_ROUND * maxabs
    poly = np.asarray(h.patch_polygon, np.int64)
    order = np.argsort(poly, kind="stable")
    start = np.searchsorted(poly[order], np.arange(len(h.polygon_material) + 1))
    outline_start, outline = polygon_outlines(h.vertices, h.patch_verts, h.patch_area,
                                              h.patch_normal, order, start)
    proved = hidden_pairs(grid, np.ascontiguousarray(ctx.tri_element), h.elem_patch,
                          h.patch_verts, poly, outline_start, outline, h.vertices,
                          h.elem_verts, h.elem_normal, float(lights.offset), delta,
                          e.astype(np.int64), m.astype(np.int64), lights.emitter_corners,
                          lights.emitter_count)
    out[e[proved], m[proved]] = True
    return out


def _corner_classes(classes: np.ndarray, tvertices: TVertices | None) -> np.ndarray:
    """``classes (V, M) int8`` with a T-vertex that disagrees with an end of its edge sending
    both ends back to ``LIGHT_TRACE`` for that light: the coarse element along the edge does
    not have the T-vertex as a corner."""
    cls = np.array(classes, dtype=np.int8, copy=True)
    tv = tvertices if tvertices is not None else TVertices.empty()
    if len(tv.vertex):
        t, a, b = (np.asarray(x, np.int64) for x in (tv.vertex, tv.a, tv.b))
        bad = (classes[t] != classes[a]) | (classes[t] != classes[b])
        rows, lights = np.nonzero(bad)
        cls[a[rows], lights] = LIGHT_TRACE
        cls[b[rows], lights] = LIGHT_TRACE
    return cls


def _every_corner(elem_verts: np.ndarray, cls: np.ndarray, value: int) -> np.ndarray:
    """``(E, M) bool``: every corner of the element has class ``value`` for the light."""
    ev = repeat_third(elem_verts)
    out = cls[ev[:, 0]] == value
    for c in range(1, ev.shape[1]):
        out &= cls[ev[:, c]] == value
    return out


def light_modes(elem_verts: np.ndarray, classes: np.ndarray,
                tvertices: TVertices | None = None) -> np.ndarray:
    """``(E, M) int8``: per element and area light, ``LIGHT_VISIBLE`` when the vertex pass
    found the light wholly visible from every corner of the element, else ``LIGHT_TRACE``
    (:mod:`daskrad.kernels.direct`).

    Eq. 9 recomputes the direct light of an element whose corners differ; a light every corner
    sees whole is not what they differ by, and its hits take Lambert's exact unoccluded term
    instead of casting its shadow rays. What that misses, a shadow lying wholly inside the
    element between its corners, the Gouraud image misses on every element whose corners
    agree. RenderPark's office (192 × 144, 352 shots; ``bench_perpixel``): the per-pixel tiles
    24.2 → 19.4 s, 49 of 27,648 pixels changed (relative RMS 3.2e-4, at most 3.2 % in one
    pixel); the Cornell box's tiles 0.50 → 0.35 s, its image with the same bits. (Taking a
    light as visible wherever the corners' 32² windows showed it whole, occluders below the
    raster's resolution included: 88 pixels changed, up to 9 %.) A light hidden from every
    corner is traced still (but where :func:`hidden_lights` proves it): the office's papers,
    stacked and lifted off the desk, have corners under one another and lit interiors (taken
    as hidden: 543 pixels changed, up to 96 %).

    A T-vertex that disagrees with an end of its edge sends both ends' elements back to
    tracing that light (:func:`_corner_classes`).
    """
    return _modes(elem_verts, _corner_classes(classes, tvertices))


def _modes(elem_verts: np.ndarray, cls: np.ndarray) -> np.ndarray:
    """:func:`light_modes` of the corner classes ``cls`` (:func:`_corner_classes`)."""
    visible = _every_corner(elem_verts, cls, LIGHT_VISIBLE)
    out = np.full(visible.shape, LIGHT_TRACE, np.int8)
    out[visible] = LIGHT_VISIBLE
    return out


@dataclass(frozen=True)
class Image:
    """Step 4's result.

    pixels : (H, W, 3) float64
        Radiance, linear (W·m⁻²·sr⁻¹ of the scene's unit).
    context : RenderContext
        The solution's render context, its junction gather not yet applied (the tiles read
        :func:`for_view` of it); ``context.vertex_radiance (V, 3)`` is what the store keeps.
    ambient : (3,) float64
        The ambient term added for an unconverged solution (W/m², Cohen et al.).
    seconds : float
    vertex_direct : (V, 3) float64 or None
        The direct part of ``context.vertex_radiance`` (:func:`vertex_split`).
    stats : dict
        What the tiles did, summed (:func:`render_tile_stats`; ``"edges"``: pixels sampled
        again at ``edge_spp``; ``"verdicts"``: their sample-light pairs settled by
        :data:`EDGE_VERDICTS`).
    """

    pixels: np.ndarray
    context: RenderContext
    ambient: np.ndarray
    seconds: float = 0.0
    vertex_direct: np.ndarray | None = None
    stats: dict = field(default_factory=dict)

    @property
    def camera(self) -> Camera:
        return self.context.camera

    @property
    def perpixel_elements(self) -> int:
        """Elements whose direct light the per-pixel pass recomputes (eq. 9)."""
        pp = self.context.elem_perpixel
        return int(pp.sum()) if pp is not None else 0


def image(scene: Scene, light: DirectLight, sol: Solution, settings: Settings, executor=None,
          cam: Camera | None = None, ahead: GatherAhead | None = None) -> Image:
    """Step 4: render ``sol`` seen by ``cam`` (default :func:`camera`), tile by tile on
    ``executor`` (``tile-…`` futures; default this process); ``ahead``: the view's junction
    gather started during the solve (:func:`gather_ahead`)."""
    t = time.perf_counter()
    if ahead is not None:
        # its plan done first: the plan may cast the view's rays on numba's threads, and the
        # context below builds a grid on them (numba's workqueue layer takes one caller)
        ahead.plan()
    if not (np.isfinite(sol.radiosity).all() and np.isfinite(sol.unshot).all()):
        raise SceneError("the radiosity solution is not finite (NaN or inf): emission or "
                         "light intensities too large for a float64", scene.path)
    split = vertex_split(light, sol)
    ctx = context(scene, light, sol, settings, cam or camera(scene, settings), split)
    out, stats = pixels_stats(ctx, executor, ahead)
    if not np.isfinite(out).all():
        raise SceneError("the image is not finite (NaN or inf radiance)", scene.path)
    return Image(pixels=out, context=ctx,
                 ambient=ambient(light.mesh.hierarchy, light.mesh.reflectance, sol.unshot),
                 seconds=time.perf_counter() - t, vertex_direct=split[1], stats=stats)


def pixels(ctx: RenderContext, executor=None) -> np.ndarray:
    """``(H, W, 3) float64``: the image of ``ctx``, tile by tile on ``executor`` (``tile-…``
    futures; default this process). The same bits either way, and from a context read back
    from a store (``daskrad render``)."""
    return pixels_stats(ctx, executor)[0]


def pixels_stats(ctx: RenderContext, executor=None, ahead: GatherAhead | None = None
                 ) -> tuple[np.ndarray, dict]:
    """:func:`pixels` and the tiles' :func:`render_tile_stats`, summed (``ahead``:
    :func:`for_view`'s)."""
    ctx = for_view(ctx, executor, ahead)
    parts = tiles(ctx.camera.width, ctx.camera.height)
    out = np.zeros((ctx.camera.height, ctx.camera.width, 3))
    done = (executor.tiles(ctx, parts) if executor is not None
            else [render_tile_stats(ctx, rows, cols) for rows, cols in parts])
    stats: dict = {}
    for (rows, cols), (tile, counts) in zip(parts, done, strict=True):
        out[rows, cols] = tile
        for k, v in counts.items():
            stats[k] = stats.get(k, 0) + v
    return out, stats


def _hard_part(dctx, tvertices, elem_verts: np.ndarray, elem_reflectance: np.ndarray,
               lights: Lights):
    """``(Lights, (V, 3))``: the point and directional lights of ``lights`` and their direct
    radiance ``ρ H / π`` at the vertices of ``dctx``, T-vertices resolved as the renderer's
    vertex radiance is; ``(None, None)`` without such lights. The vertex values are computed
    by the direct pass's own function over the same points, so they are the hard part of the
    vertex irradiance to round-off."""
    from daskrad import direct

    if not (len(lights.point_position) or len(lights.dir_direction)):
        return None, None
    bare = direct.without_emitters(dctx)
    H = direct.compute(bare, 0, len(dctx.points))
    rho = direct.corner_values(elem_verts, len(H), elem_reflectance)
    tv = tvertices if tvertices is not None else TVertices.empty()
    vertex_hard = resolve_tvertices(rho * H, tv) / math.pi
    return direct.lights_of(bare), vertex_hard


#: A vertex is beside a junction when another surface lies within ``JUNCTION_REACH`` element
#: sizes in its hemisphere (one of 4 × 4 probe rays); its indirect light is then gathered.
#: The error gathered away is that of elements whose light changes within them, and it
#: reaches about two elements out from a junction (point-lit closed box, path-traced floor
#: points: the block's shadowed foot elements +60 %, the floor element beside them +18 %, the
#: next +10 %), so the reach scales with the element size: one element, whose vertices (with
#: the other corners of their elements) cover the two elements beside the junction. Measured
#: (bench_shadows, 24² rays): 0.64 element sizes (2 % of the diagonal at the automatic size)
#: left the point-lit box's worst contact row at +6.4 %, 1.0 gives +4.1 % (+5.5 % at 32²
#: rays: the row moves with the gather's own noise); the other scenes' figures and the
#: Cornell box's error do not move; the Cornell box's render takes ~12 % longer. At 73,000
#: elements a reach of 2 % of the diagonal (9 element sizes) gathered at 9,091 vertices for
#: 24 s of a 25 s render.
JUNCTION_REACH = 1.0
#: Measured against the path tracer (bench_shadows; Cornell box 128², off the light), side 16 /
#: 24 / 32 with two correction passes: sun-lit open box contact 4.1 / 4.3 / 4.2 %, point-lit
#: closed box worst contact row 7.0 / 6.4 / 7.2 %, Cornell box 0.07699 / 0.07694 / 0.07691:
#: equal within the references' noise, at 0.25 / 0.56 / 1 of the rays. 24, not 16: the
#: per-vertex noise shows along junctions before it shows in an RMS. Again with the reach of
#: one element size and the passes along the same rays (bench_shadows, side 12 / 16 / 24):
#: the point-lit box's worst contact row +14.8 / +6.7 / +4.1 % (target 5 %), the other
#: figures within 0.6 points of each other. The gather is ~3/4 of the Cornell box's render CPU.
GATHER_SIDE = 24

#: The disc's side: ~573 pixels on the disc (560–578 as the lattice is shifted per vertex), as
#: many directions as ``GATHER_SIDE²`` rays; and the side of a scene of at most
#: :data:`DISC_SIMPLE` polygon triangles, ~346 pixels (334–350). The directions are the
#: lattice's, turned and shifted per vertex, not jittered rays, so in a simple scene fewer err
#: no more than the rays did: per vertex, against the mean of a disc of side 100 and 64² rays
#: (``python -m benchmarks.bench_gather --sides 27 23 21 19 17``), sides 27 / 23 / 21 / 19 / 17
#: give the Cornell box's 2,663 junction vertices 1.30 / 1.60 / 1.93 / 2.20 / 2.57 % RMS (worst
#: vertex 9.0 / 10.8 / 12.3 / 16.9 / 18.7 %), where 24² rays give 2.13 % (worst 17.2 %); the lit
#: room 0.85 / 1.01 / 1.17 / 1.40 / 1.66 % against 1.26 %; the MGF cube (67 triangles) 1.02 % at
#: 27 and 1.50 % at 21 against 1.73 %. A furnished room needs the finer disc: MGF office2 (741
#: triangles) 4.17 % at 27 but 5.98 % at 21, against the rays' 5.22 %. The images at 21 against
#: 27 (``bench_shadows`` with the gather's seeds shifted four ways, runs not kept in a
#: benchmark): contact pixels of the sun-lit open box 4.44–4.54 % against 4.34–4.47 %, of the
#: point-lit closed box 2.17–2.22 % against 2.15–2.16 % (slightly worse at 21 on both; the rays
#: gave 4.52 % and 2.16–2.24 %), the closed box's worst contact row +4.7…+8.0 % against
#: +5.3…+7.6 % (rays −1.4…+10.6 %), the lit room's contact pixels 2.59–2.66 % both; the
#: Cornell box at 128² against the path tracer 0.03792 off the light either way. So side 21 is
#: no worse than the rays shipped before it, at two thirds of side 27's cost.
DISC_SIDE = 27
DISC_SIDE_SIMPLE = 21
#: The most polygon triangles of a scene whose disc has side :data:`DISC_SIDE_SIMPLE`: above
#: the simple rooms measured (the cube's 67), far below the furnished office2's 741; no scene
#: in between was measured.
DISC_SIMPLE = 100
#: The disc gathers for scenes of at most this many polygon triangles, the rays above: a
#: vertex costs the disc ~150 µs plus ~0.56 µs a triangle it projects, the rays ~400–620 µs
#: whatever the scene (the polygons' grid): equal near 800 (``bench_gather``: office2's 741
#: triangles 568 against 618 µs a vertex, at 4.2 % against 5.2 % error).
DISC_POLYGONS = 800
#: The projected edges of the disc's polygons are split so that each piece lies within
#: this fraction of a pixel of its arc (eq. 4): at the item buffers' quarter pixel
#: (:data:`daskrad.tolerances.EDGE_SAGITTA_PX`) the chords, always inside their arcs, took
#: 0.2 % off the Cornell box's gathered light; at 1/16 nothing measurable, at no cost seen.
DISC_SAGITTA_PX = 1.0 / 16.0


def gather_method(polygons: Grid | None) -> str:
    """The junction gather's method for a scene whose polygons are ``polygons`` (None: the
    rays walk the elements)."""
    if polygons is not None and len(polygons.triangles) <= DISC_POLYGONS:
        return "disc"
    return "rays"


def gather_side(polygons: Grid | None) -> int:
    """The junction gather's side for a scene whose polygons are ``polygons``
    (:func:`gather_method`): ``side²`` rays a vertex, or the disc's side ``R``, finer for a
    scene of more than :data:`DISC_SIMPLE` polygon triangles."""
    if gather_method(polygons) == "rays":
        return GATHER_SIDE
    return DISC_SIDE_SIMPLE if len(polygons.triangles) <= DISC_SIMPLE else DISC_SIDE


#: Correction passes after the first gather: each gathers the change the previous pass made
#: along the first pass's rays (the gather is linear in the radiance seen, so the rays are cast
#: once: :class:`GatherOperator`), so the two sides of a junction see each other's gathered
#: light. Closed
#: Cornell box with a point light (measured when each correction cast 12² rays of its own):
#: the RMS change falls 3.9e-3, 1.1e-3, 5.7e-4 over passes 1–3; the floor row at the short
#: block's foot goes +14 % → +1 % against the path tracer.
GATHER_PASSES = 2


#: A scene with at most this many vertices to gather gathers them all, whatever the view; one
#: with more gathers only those near what the view shows (:func:`for_view`). The whole gather
#: is the more accurate (a shown vertex sees hidden junctions corrected too: the lit room's
#: contact pixels 2.6 % against 3.4 % with the view's), the view's the cheaper in a furnished
#: interior (graz: the whole gather took 445 s of a 538 s render). 20,000 vertices are ~17
#: million rays, ~10 s on 2 cores; the Cornell box's default mesh gathers ~2,900.
GATHER_ALL = 20_000

#: The junction gather's tasks per worker (or thread) at least, when they hold more than
#: :data:`GATHER_BATCH` vertices each (:func:`gather_batch`).
GATHER_TASKS = 8


def gather_batch(n: int, executor=None) -> int:
    """Junction vertices per task of a gather of ``n``: :data:`GATHER_BATCH`, or more so that
    there are no more than :data:`GATHER_TASKS` tasks per worker of ``executor`` (its
    threads in-process): a task costs a Dask cluster milliseconds of scheduling, and a
    vertex's rows do not depend on the split."""
    cores = max(getattr(executor, "workers", 0) or getattr(executor, "threads", 1) or 1, 1)
    return max(GATHER_BATCH, math.ceil(n / (GATHER_TASKS * cores)))


#: Vertices searched at once for a surface nearby (:func:`_gathered`), between two looks at
#: whether more than :data:`GATHER_ALL` were found.
NEAR_PIECE = 16_384

#: Junction vertices per ``gather-…`` task at least (~0.02–0.1 s each: ~576 directions a
#: vertex; :func:`gather_batch`).
GATHER_BATCH = 128


@dataclass(frozen=True)
class GatherContext:
    """What a junction-gather task reads (:func:`gather_vertices`).

    grid, tri_verts, tri_element, elem_normal
        As :class:`RenderContext`.
    exclude : (E, 3) float64
        Radiance taken off a hit on each element (its ``Ke`` when the direct pass lit the
        vertices with the emitters, else 0).
    n_vertices : int
        ``V``, the mesh vertices the gathered radiance is interpolated from.
    points, normals : (n, 3) float64
        The junction vertices' evaluation points and normals; ``seeds : (n,) int64`` their
        vertex ids (the jitter is seeded per vertex, so any split gives the same bits).
    offset : float
        Ray offset (length); ``side``: ``side²`` rays per vertex.
    polygons : Grid or None, locator : (T, 13) float64 or None
        The grid over the scene's polygons and :func:`daskrad.kernels.grid.locator` of
        ``grid``'s triangles: a ray's hit is found among the polygons and located among the
        elements (:data:`POLYGON_HITS`); None: ``grid`` is walked.
    method : str
        A key of :data:`GATHER_METHODS` (``"disc"`` needs ``polygons`` and ``locator``);
        ``side`` is then the disc's side ``R``.
    """

    grid: Grid
    tri_verts: np.ndarray
    tri_element: np.ndarray
    elem_normal: np.ndarray
    exclude: np.ndarray
    n_vertices: int
    points: np.ndarray
    normals: np.ndarray
    seeds: np.ndarray
    offset: float
    side: int
    polygons: Grid | None = None
    locator: np.ndarray | None = None
    method: str = "rays"


class GatherOperator(NamedTuple):
    """Rows of the gather as a sparse operator (:func:`daskrad.kernels.gather.gather_operator`):
    the mean radiance seen from junction vertex ``i`` is ``G[i] · L − excluded[i]`` for a
    vertex radiance ``L (V, 3)``.

    indptr : (n + 1,) int64, cols : (nnz,) int64, weights : (nnz,) float64
        ``G`` in CSR form.
    excluded : (n, 3) float64
        The emission its rays saw on emitters (counted by the direct pass).
    """

    indptr: np.ndarray
    cols: np.ndarray
    weights: np.ndarray
    excluded: np.ndarray

    def rows(self, start: int, stop: int) -> GatherOperator:
        """Its rows ``[start, stop)``: what :func:`gather_vertices` gives for those vertices
        (a vertex's rows do not depend on the range it is computed in)."""
        lo, hi = self.indptr[start], self.indptr[stop]
        return GatherOperator(self.indptr[start:stop + 1] - lo, self.cols[lo:hi],
                              self.weights[lo:hi], self.excluded[start:stop])

    def mean_radiance(self, radiance: np.ndarray) -> np.ndarray:
        """``(n, 3)``: ``G · radiance`` (no emission taken off)."""
        from daskrad.kernels.gather import apply_operator

        return apply_operator(self.indptr, self.cols, self.weights,
                              np.ascontiguousarray(radiance, dtype=np.float64))


class GatherBlocks:
    """The gather's operator as the row blocks its tasks computed (:class:`GatherOperator`
    each), one after the other: what one operator of all their rows gives, without copying
    them into one. A view's operator holds ~600 nonzeros a vertex (RenderPark's classroom:
    15,477 junction vertices, 9.9 million nonzeros, 160 MB), and the joined copy cost the
    render time and as much memory again (``benchmarks/bench_operator.py``, ``for_view`` in
    fresh processes, medians of 4: the classroom 5.55 → 5.27 s and a peak of 537 → 389 MiB;
    the 73k box 0.85 → 0.84 s, 329 → 288 MiB; the same bits).

    excluded : (n, 3) float64
        The blocks' :attr:`GatherOperator.excluded`, in order.
    """

    def __init__(self, parts: list[GatherOperator]):
        self.parts = list(parts)
        self.excluded = (np.concatenate([p.excluded for p in self.parts]) if self.parts
                         else np.zeros((0, 3)))

    def mean_radiance(self, radiance: np.ndarray) -> np.ndarray:
        """``(n, 3)``: ``G · radiance``, block by block; each row summed in its stored order,
        so the bits of one operator of all the rows."""
        values = np.ascontiguousarray(radiance, dtype=np.float64)
        if not self.parts:
            return np.zeros((0, values.shape[1]))
        return np.concatenate([p.mean_radiance(values) for p in self.parts])


def gather_vertices(gctx: GatherContext, start: int, stop: int) -> GatherOperator:
    """The gather operator's rows of the junction vertices ``[start, stop)`` of ``gctx``, by
    its method (:data:`GATHER_METHODS`)."""
    return GATHER_METHODS[gctx.method](gctx, start, stop)


def _disc_rows(gctx: GatherContext, start: int, stop: int) -> GatherOperator:
    """:func:`daskrad.kernels.gather.disc_operator`'s rows of ``[start, stop)``."""
    from daskrad.kernels.gather import disc_operator

    if gctx.polygons is None or gctx.locator is None:
        raise ValueError("the disc gather needs the polygons and the locator")
    R = int(gctx.side)
    return GatherOperator(*disc_operator(
        gctx.grid, gctx.tri_verts, gctx.tri_element, gctx.elem_normal, gctx.exclude,
        int(gctx.n_vertices), gctx.points[start:stop], gctx.normals[start:stop],
        gctx.seeds[start:stop], float(gctx.offset), R, edge_split_angle(R, DISC_SAGITTA_PX),
        tolerances.HORIZON_EPS, gctx.polygons, gctx.locator))


def _rays_rows(gctx: GatherContext, start: int, stop: int) -> GatherOperator:
    """:func:`daskrad.kernels.gather.gather_operator`'s rows of ``[start, stop)``."""
    from daskrad.kernels.gather import gather_operator

    located = gctx.polygons is not None and gctx.locator is not None
    return GatherOperator(*gather_operator(
        gctx.grid, gctx.tri_verts, gctx.tri_element, gctx.elem_normal, gctx.exclude,
        int(gctx.n_vertices), gctx.points[start:stop], gctx.normals[start:stop],
        gctx.seeds[start:stop], float(gctx.offset), int(gctx.side),
        gctx.polygons if located else gctx.grid,
        gctx.locator if located else NO_LOCATOR, located))


#: The junction gather's methods by name (:attr:`GatherContext.method`), each giving the
#: operator rows of a range of junction vertices, the same shape and meaning:
#:
#: - ``"rays"``: ``GATHER_SIDE²`` stratified, jittered, cosine-distributed rays a vertex,
#:   each walking the polygons' grid (:func:`daskrad.kernels.gather.gather_operator`);
#: - ``"disc"``: the scene's polygons projected onto the base of the vertex's hemisphere,
#:   Doi's item buffer of the form factors, ``R × R`` pixels over the disc (:func:`gather_side`),
#:   each disc pixel a cosine-distributed direction (Nusselt's analog;
#:   :func:`daskrad.kernels.gather.disc_operator`). One projection of every polygon a vertex
#:   instead of a walk a ray: the cheaper up to ~800 triangles (:data:`DISC_POLYGONS`).
#:
#: Measured when the disc came, at side 27 (``bench_gather``: per-vertex error of the gathered
#: radiance against the mean of a disc of side 100 and 64² rays, one thread): the Cornell box's
#: 2,663 junction vertices, rays 2.13 % RMS in 1.22 s, disc 1.30 % in 0.47 s; the lit room
#: 1.26 / 0.85 %, 3.4× faster; the MGF cube 1.73 / 1.02 %, 478 / 206 µs a vertex. The Cornell
#: box's render at 128² took 0.83 → 0.44 s with the same error against the path tracer
#: (relative RMS 0.01797 both). The sides now: :data:`DISC_SIDE`.
GATHER_METHODS = {"rays": _rays_rows, "disc": _disc_rows}


def seen_elements(ctx: RenderContext) -> np.ndarray:
    """``(E,) bool``: the elements a primary ray of the image hits (every base sample of every
    pixel, the rays :func:`render_tile` casts before edge resampling), whichever side. The
    edge pixels' extra samples fall within the same pixels, on these elements or on elements
    beside them, which the region's ring of neighbours covers but for slivers."""
    E = len(ctx.elem_normal)
    seen = np.zeros(E, bool)
    for rows, cols in tiles(ctx.camera.width, ctx.camera.height):
        o, d = primary_rays(ctx.camera, rows, cols, ctx.spp)
        if _hit_polygons(ctx) is not None:     # the client casts these alone: every core
            tri = located_triangles(ctx.occluders, ctx.locator, ctx.grid, o, d, 0.0, np.inf)
        else:
            _, tri, _, _ = _closest(ctx, o, d)
        seen[ctx.tri_element[tri[tri >= 0]]] = True
    return seen


def junctions_of(dctx, tvertices, elem_verts: np.ndarray, elem_reflectance: np.ndarray,
                 elem_emission: np.ndarray, vertex_indirect: np.ndarray, reach: float,
                 everywhere: bool) -> Junctions:
    """The :class:`Junctions` of a solution: ``dctx`` the direct context its vertices were lit
    with (evaluation points, normals, offset, whether emitters were gathered), ``tvertices``
    its T-vertices (never gathered: they keep their edge's values, no seam)."""
    V = len(vertex_indirect)
    gatherable = _corners(elem_verts, elem_verts >= 0, V)
    tv = tvertices if tvertices is not None else TVertices.empty()
    gatherable[tv.vertex] = False
    rho = direct.corner_values(elem_verts, V, elem_reflectance)
    exclude = (np.ascontiguousarray(elem_emission, dtype=np.float64)
               if len(dctx.emitter_corners) else np.zeros((len(elem_reflectance), 3)))
    return Junctions(points=np.ascontiguousarray(dctx.area_points, dtype=np.float64),
                     normals=np.ascontiguousarray(dctx.normals, dtype=np.float64),
                     offset=float(dctx.offset),
                     elem_verts=np.ascontiguousarray(elem_verts, dtype=np.int32),
                     vertex_rho=rho,
                     vertex_indirect=np.ascontiguousarray(vertex_indirect, dtype=np.float64),
                     exclude=exclude, gatherable=gatherable,
                     tv_vertex=np.asarray(tv.vertex, np.int64),
                     tv_a=np.asarray(tv.a, np.int64), tv_b=np.asarray(tv.b, np.int64),
                     reach=float(reach), everywhere=bool(everywhere))


def for_view(ctx: RenderContext, executor=None, ahead=None) -> RenderContext:
    """``ctx`` with its junction gather applied for its camera (``ctx`` itself when it has
    none): the gathered change added to the vertex radiance and to its interpolated parts.
    Every image goes through it (:func:`pixels`), so a run and a re-render with the same
    camera give the same bits. ``executor`` casts the rays (threads or ``gather-…`` tasks).
    The view's rays find their hits among the polygons (:func:`with_locator`).

    ``ahead``: the gather's operator computed before the solution was known
    (:func:`gather_ahead`), taken when it was planned for this context's mesh and camera;
    the operator is geometry alone, so it is the one computed here, bit for bit."""
    plan = ahead.plan() if ahead is not None else None
    if plan is None or not plan.fits(ctx):
        if ahead is not None:
            ahead.stop()            # planned for another view: nothing more to compute
        plan, ahead = None, None
    ctx = with_locator(ctx, plan.locator if plan is not None else None)
    j = ctx.junctions
    if j is None:
        return ctx
    if plan is None:
        plan = plan_gather(ctx)
    G = ahead.operator() if ahead is not None else gather_operator_of(plan, executor)
    delta = _gather_change(ctx, j, plan.vertices, G)
    out = replace(ctx, vertex_radiance=ctx.vertex_radiance + delta, junctions=None)
    if ctx.vertex_indirect is not None:
        out = replace(out, vertex_indirect=ctx.vertex_indirect + delta)
    if ctx.vertex_soft is not None:
        out = replace(out, vertex_soft=ctx.vertex_soft + delta)
    return out


class GatherPlan(NamedTuple):
    """Which vertices a view's junction gather takes, and what its rows are computed with
    (:func:`plan_gather`). Geometry alone: planned before the solution is known, the rows
    may be computed while the solve runs (:func:`gather_ahead`).

    vertices : (n,) int64
        The junction vertices gathered.
    context : GatherContext or None
        What their rows are computed with (None when ``n`` is 0).
    grid, occluders : Grid, camera : Camera or None, spp : int
        The element and polygon grids, camera and samples per pixel of the context it was
        planned for, ``junctions`` its :class:`Junctions`, ``constants`` the module's
        settings that choose and gather the vertices (:meth:`fits`).
    locator : (T, 13) float64 or None
        That context's :attr:`RenderContext.locator`.
    """

    vertices: np.ndarray
    context: GatherContext | None
    grid: Grid
    camera: Camera | None
    spp: int
    locator: np.ndarray | None
    occluders: Grid | None
    junctions: Junctions
    constants: tuple

    def fits(self, ctx: RenderContext) -> bool:
        """Whether this is the plan :func:`plan_gather` makes of ``ctx``: the same mesh and
        polygons (the grids, the same objects), camera (the same object), samples per pixel,
        junctions (equal: the points, normals, reach and what may be gathered) and module
        settings."""
        j, k = ctx.junctions, self.junctions
        return (ctx.grid is self.grid and ctx.occluders is self.occluders
                and ctx.camera is self.camera and ctx.spp == self.spp and j is not None
                and self.constants == _plan_constants()
                and (j.offset, j.reach, j.everywhere) == (k.offset, k.reach, k.everywhere)
                and all(np.array_equal(getattr(j, f), getattr(k, f))
                        for f in ("gatherable", "points", "normals", "exclude", "elem_verts")))

    def ranges(self, executor=None, batch: int | None = None) -> list[tuple[int, int]]:
        """Ranges of :attr:`vertices`, one a task (:func:`gather_batch`, or ``batch``
        vertices each)."""
        n = len(self.vertices)
        return direct.batches(0, n, batch or gather_batch(n, executor)) if n else []


def _plan_constants() -> tuple:
    """The module settings a :class:`GatherPlan` depends on (a test or a benchmark may
    change them between a plan and its use)."""
    return (GATHER_ALL, POLYGON_HITS, DISC_POLYGONS, DISC_SIDE, DISC_SIDE_SIMPLE, DISC_SIMPLE,
            GATHER_SIDE, DISC_SAGITTA_PX)


def plan_gather(ctx: RenderContext) -> GatherPlan | None:
    """The :class:`GatherPlan` of ``ctx``'s view (None: the context has no junction
    gather). Reads the geometry of ``ctx`` and its junctions, never a radiance."""
    ctx = with_locator(ctx)
    j = ctx.junctions
    if j is None:
        return None
    everywhere = j.everywhere or ctx.camera is None      # no view: gather what any may show
    idx = _gathered_vertices(ctx, j, view=not everywhere)
    gctx = None
    if len(idx):
        polygons = _hit_polygons(ctx)
        method = gather_method(polygons)
        gctx = GatherContext(grid=ctx.grid, tri_verts=ctx.tri_verts,
                             tri_element=ctx.tri_element, elem_normal=ctx.elem_normal,
                             exclude=j.exclude, n_vertices=len(ctx.vertex_radiance),
                             points=np.ascontiguousarray(j.points[idx]),
                             normals=np.ascontiguousarray(j.normals[idx]),
                             seeds=idx.astype(np.int64), offset=j.offset,
                             side=gather_side(polygons),
                             polygons=polygons,
                             locator=ctx.locator if polygons is not None else None,
                             method=method)
    return GatherPlan(idx, gctx, ctx.grid, ctx.camera, ctx.spp, ctx.locator, ctx.occluders, j,
                      _plan_constants())


def gather_operator_of(plan: GatherPlan, executor=None) -> GatherBlocks | None:
    """The operator of ``plan``'s rows, cast by ``executor.gather`` (threads or
    ``gather-…`` tasks) when given; None when it gathers no vertex."""
    if plan.context is None:
        return None
    ranges = plan.ranges(executor)
    parts = (executor.gather(plan.context, ranges) if executor is not None
             else [gather_vertices(plan.context, a, b) for a, b in ranges])
    return GatherBlocks(parts)


#: Junction vertices per range of a gather computed ahead (:func:`gather_ahead`): a range
#: the render asks for while it is still being computed on an idle core is computed again
#: (the same bits), so short ranges waste little (~4 ms at the Cornell box's ~135 µs a vertex).
#: A cluster is sent the ranges left in tasks of :func:`gather_batch` (:func:`gather_merged`).
AHEAD_BATCH = 32


def gather_merged(gctx: GatherContext, ranges: list[tuple[int, int]], executor
                  ) -> list[GatherOperator]:
    """``[gather_vertices(gctx, a, b) for a, b in ranges]`` as ``executor.gather`` tasks of
    :func:`gather_batch` vertices: runs of adjacent ranges go as one task, whose operator is
    cut back into theirs (:meth:`GatherOperator.rows`; a vertex's rows do not depend on the
    range). A Dask task costs the scheduler and the client milliseconds, so the ranges a
    gather computed ahead left (:data:`AHEAD_BATCH` vertices each) are not sent one by one."""
    size = gather_batch(sum(b - a for a, b in ranges), executor)
    runs: list[list[int]] = []              # indices into ranges, each run adjacent
    for i, (a, b) in enumerate(ranges):
        if runs and ranges[runs[-1][-1]][1] == a \
                and b - ranges[runs[-1][0]][0] <= size:
            runs[-1].append(i)
        else:
            runs.append([i])
    parts = executor.gather(gctx, [(ranges[r[0]][0], ranges[r[-1]][1]) for r in runs])
    out = []
    for r, part in zip(runs, parts, strict=True):
        first = ranges[r[0]][0]
        out += [part.rows(ranges[i][0] - first, ranges[i][1] - first) for i in r]
    return out


class GatherAhead:
    """A view's junction gather computed before the render asks for it
    (:func:`gather_ahead`): :meth:`plan` and :meth:`operator`, as :func:`plan_gather` and
    :func:`gather_operator_of` give them, wherever they were computed."""

    def __init__(self, handle):
        self._handle = handle          # the executor's handle (its ahead(): an Ahead)

    def plan(self) -> GatherPlan | None:
        return self._handle.plan()

    def progress(self) -> tuple[int, int]:
        """``(ranges computed ahead, ranges)`` so far."""
        return self._handle.progress()

    def stop(self) -> None:
        """Compute nothing more ahead."""
        self._handle.stop()

    def join(self, timeout: float | None = None) -> bool:
        """Wait until nothing more is computed ahead; whether that is so."""
        return self._handle.join(timeout)

    def operator(self) -> GatherBlocks | None:
        parts = self._handle.result()
        return GatherBlocks(parts) if parts else None


def gather_ahead(scene: Scene, light: DirectLight, settings: Settings, cam: Camera,
                 executor) -> GatherAhead | None:
    """Start the junction gather of the view ``cam`` on the cores the solve leaves idle,
    while it runs (``executor.ahead``: an idle-priority thread of this process, the client's
    with Dask, :class:`daskrad.distributed.executor.Ahead`; None when the executor starts
    nothing, or the run has no junction gather): the gather reads the mesh and its direct
    context only, never a radiance (:class:`GatherPlan`). :func:`image` then takes it
    (:func:`for_view`)."""
    start = getattr(executor, "ahead", None)
    if start is None or not GATHER_AHEAD or not settings.per_pixel \
            or light.irradiance is None or light.context is None:
        return None

    def plan():
        return plan_gather(geometry_context(scene, light, settings, cam))

    handle = start("gather", plan, lambda p: p.context, lambda p: p.ranges(batch=AHEAD_BATCH))
    return GatherAhead(handle) if handle is not None else None


#: Whether a run computes its view's junction gather ahead, during the solve
#: (:func:`gather_ahead`); False computes it in the render, as before: the benchmark's
#: reference arm (``bench_gather``'s whole runs). The same bits either way.
GATHER_AHEAD = True


def geometry_context(scene: Scene, light: DirectLight, settings: Settings,
                     cam: Camera) -> RenderContext:
    """The render context of ``light``'s mesh seen by ``cam`` as far as geometry goes: grids,
    triangles, the camera and the junctions (:func:`junctions_of`, as :func:`context` makes
    them), with zero radiance; what :func:`plan_gather` reads."""
    mesh = light.mesh
    h = mesh.hierarchy
    zero = np.zeros((len(h.vertices), 3))
    ctx = RenderContext(grid=mesh.grid, tri_verts=mesh.tri_verts, tri_element=mesh.tri_element,
                        elem_normal=h.elem_normal, vertex_radiance=zero, camera=cam,
                        spp=settings.spp, occluders=mesh.occluders.grid)
    mats, mat = scene.materials, h.elem_material
    return replace(ctx, junctions=_junctions(
        light.context, light.tvertices, h.elem_verts, mesh.reflectance, mats.emission[mat],
        zero, scene.diagonal, settings.element_size or default_sizes(scene)[1],
        settings.mirror_depth, mats.mirror[mat]))


def _corners(elem_verts: np.ndarray, elements: np.ndarray, n_vertices: int) -> np.ndarray:
    """``(V,) bool``: the corners of the elements ``elements (E,) bool``."""
    out = np.zeros(n_vertices, bool)
    ev = elem_verts[elements]
    out[ev[ev >= 0]] = True
    return out


def _touching(elem_verts: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    """``(E,) bool``: the elements with a corner among ``vertices (V,) bool``."""
    valid = elem_verts >= 0
    return (vertices[np.where(valid, elem_verts, 0)] & valid).any(axis=1)


def _view_region(ctx: RenderContext, elem_verts: np.ndarray, n: int) -> np.ndarray:
    """``(n,) bool``: the corners of the elements the view shows (:func:`seen_elements`: the
    image's primary rays) and of every element sharing a corner with them."""
    shown = _corners(elem_verts, seen_elements(ctx), n)
    return _corners(elem_verts, _touching(elem_verts, shown), n)


def _gathered(ctx: RenderContext, j: Junctions, vertices: np.ndarray, n: int,
              stop_above: int | None = None) -> np.ndarray | None:
    """``(n,) bool``: the gatherable vertices the junction gather takes, as far as
    ``vertices (k,) int64`` decide it: those beside a junction (another surface within
    ``j.reach``, :func:`daskrad.kernels.gather.near_surface`, each point on its own) and the
    other corners of every element with such a vertex. ``stop_above``: None as soon as more
    than that many of ``vertices`` are found beside a junction (the search runs in pieces of
    :data:`NEAR_PIECE`; the vertices taken would be more still)."""
    from daskrad.kernels.gather import near_surface

    # through the polygons with the view's hits (the same surfaces: the same answers on the
    # Cornell box at 62,123 vertices, 0.38 -> 0.15 s)
    polygons = _hit_polygons(ctx)
    grid = polygons if polygons is not None else ctx.grid
    beside = np.zeros(n, bool)
    found = 0
    for a in range(0, len(vertices), NEAR_PIECE):
        part = vertices[a:a + NEAR_PIECE]
        near = near_surface(grid, j.points[part], j.normals[part], j.offset, j.reach, 4)
        beside[part[near]] = True
        found += int(near.sum())
        if stop_above is not None and found > stop_above:
            return None
    return _corners(j.elem_verts, _touching(j.elem_verts, beside), n) & j.gatherable


def _gathered_vertices(ctx: RenderContext, j: Junctions, view: bool = False) -> np.ndarray:
    """``(n,) int64``: the vertices the junction gather takes (:func:`_gather_change`): those
    beside a junction (another surface within ``j.reach``) and the other corners of every
    element with such a vertex. The elements along a junction have the wrong radiosity: a
    shooting patch gives every receiver its *average* radiosity, while a receiver beside the
    junction sees mostly the patch's part at the junction, darker than its average (the floor
    patch in front of a block lights the block's foot with the light of its far, brighter
    edge: closed Cornell box with a point light, the short block's shadowed foot elements
    60 % too bright, the floor's in front of it 18 %). A corner one element away from the
    junction averages those elements, and Gouraud interpolation carries their error across
    the whole element; gathered, the element is interpolated between gathered corners only.

    ``view``: when more than :data:`GATHER_ALL` vertices are to be gathered, only the corners
    of the region of the view are (the elements the image shows, :func:`seen_elements`, and
    every element sharing a corner with them: a shown corner's first pass then depends on
    nothing outside, as in a whole gather): the gather is then part of the view-dependent
    pass. An office's furniture puts most vertices beside a junction, and most are out of
    view (graz: the whole scene's gather took 445 s of a 538 s render, the view's 1.3 s of
    114 s). False: every vertex. Within the region the first pass is that of a whole
    gather; the correction passes gather the change at the region's vertices only, so a
    shown vertex near the frame's edge may differ from a whole gather's by what the change
    beyond the region would have sent it (the wall-on-floor test scene, zoomed from a 40° to
    a 15° view: up to 0.65 % at 6 of 9 vertices before the neighbours were added).
    Geometry alone decides (:class:`GatherPlan`).
    """
    V = len(ctx.vertex_radiance)
    elem_verts = j.elem_verts
    cand = np.flatnonzero(j.gatherable)
    if len(cand) == 0:
        return cand.astype(np.int64)
    gathered = None
    region = None
    whole = None
    if view and len(cand) > GATHER_ALL:
        # The view region first (the elements shown and their neighbours' corners): whether a
        # vertex of it is gathered depends only on the vertices of the elements touching it,
        # so the search for surfaces nearby runs on those alone (graz: 5.6 % of 285,255).
        # When the region alone has more than GATHER_ALL, so has the scene, and the answer is
        # the one the whole search would restrict to the region; else the whole search
        # decides, as below.
        region = _view_region(ctx, elem_verts, V)
        need = cand[_corners(elem_verts, _touching(elem_verts, region), V)[cand]]
        shown = _gathered(ctx, j, need, V) & region
        if shown.sum() > GATHER_ALL:
            gathered = shown
        else:
            # the whole search decides, but it stops once more than GATHER_ALL vertices are
            # beside a junction: the scene has too many, and the region's answer stands
            # (graz: 2 of its 18 pieces searched)
            whole = _gathered(ctx, j, cand, V, stop_above=GATHER_ALL)
            if whole is None:
                gathered = shown
    if gathered is None:
        gathered = whole if whole is not None else _gathered(ctx, j, cand, V)
        if view and gathered.sum() > GATHER_ALL:
            # too many for the whole scene: the view region's only (whether a vertex is
            # gathered does not depend on the region, only which are)
            gathered &= region if region is not None else _view_region(ctx, elem_verts, V)
    return np.flatnonzero(gathered).astype(np.int64)


def _gather_change(ctx: RenderContext, j: Junctions, idx: np.ndarray,
                   G: GatherBlocks | None) -> np.ndarray:
    """``(V, 3)``: the change of vertex radiance when the indirect light of the vertices
    ``idx`` (:func:`_gathered_vertices`) is gathered (:mod:`daskrad.kernels.gather`, the
    operator ``G`` of their rows, :func:`gather_operator_of`) instead of averaged from their
    elements: ``ρ · mean(L)`` over cosine-distributed directions from the vertex, ``L`` the
    radiance the solution shows (Gouraud of ``ctx.vertex_radiance``) less the emitters' ``Ke``
    when the direct pass lit the vertices with them (two-pass), minus the vertex's current
    indirect radiance. T-vertices take the mean of their edge's ends (no seam).

    The first pass is then corrected :data:`GATHER_PASSES` times by gathering the change the
    previous pass made (the gather is linear in the radiance seen): the two sides of a
    junction (floor and block face) light each other, and the first pass saw both with their
    averaged values. ``j.vertex_indirect`` and ``j.vertex_rho`` are the current indirect
    radiance and the reflectance at each vertex.
    """
    V = len(ctx.vertex_radiance)
    delta = np.zeros((V, 3))
    if G is None or len(idx) == 0:
        return delta
    tv = TVertices(j.tv_vertex, j.tv_a, j.tv_b)
    rho = j.vertex_rho
    delta[idx] = rho[idx] * (G.mean_radiance(ctx.vertex_radiance) - G.excluded) \
        - j.vertex_indirect[idx]
    delta = resolve_tvertices(delta, tv)      # a T-vertex follows its edge: no seam
    change = delta
    for _ in range(GATHER_PASSES):
        # the light the last pass's change sends to the gathered vertices, along the same
        # directions (a change holds no emission)
        change_at = G.mean_radiance(change)
        change = np.zeros((V, 3))
        change[idx] = rho[idx] * change_at
        change = resolve_tvertices(change, tv)
        delta = delta + change
    return delta
