"""Step 4: the per-pixel pass — primary rays through the voxel grid, Gouraud-interpolated radiance.

Image values are **radiance** ``L = B / π`` (W·m⁻²·sr⁻¹ of the scene's unit), linear, so they
compare directly with a path tracer's output. Surfaces are one-sided: a ray that reaches the back
of a face sees black, as in Mitsuba and pbrt.

Camera convention (DESIGN §6): ``forward = normalize(look_at − eye)``,
``right = normalize(forward × up)``, ``true_up = right × forward``; pixel column ``x`` grows along
``right``, row 0 is the top of the image; ``fov`` is horizontal.

The image is computed in tiles (:func:`render_tile`); in-process they run one after the other,
with Dask they are ``tile-<n>`` futures. Sample positions are a fixed stratified grid per pixel,
so a pixel's value does not depend on which tile or worker computed it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from daskrad.kernels.grid import Grid, closest_hit
from daskrad.scene.types import Camera

#: Tile side in pixels for the per-pixel pass (a tile is one task).
TILE = 64


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
        Samples per pixel (a ``⌈√spp⌉``-wide stratified grid, trimmed row-major to ``spp``).
    """

    grid: Grid
    tri_verts: np.ndarray
    tri_element: np.ndarray
    elem_normal: np.ndarray
    vertex_radiance: np.ndarray
    camera: Camera
    spp: int


def default_camera(bounds: np.ndarray, width: int = 256, height: int = 256,
                   fov: float = 40.0) -> Camera:
    """A camera on the −z side of the bounding box ``(2, 3)``, looking along +z, y up, framing
    the whole box (the usual placement for y-up OBJ scenes)."""
    centre = bounds.mean(axis=0)
    radius = 0.5 * float(np.linalg.norm(bounds[1] - bounds[0])) or 1.0
    distance = 1.1 * radius / math.tan(math.radians(fov) / 2.0)
    eye = centre - np.array([0.0, 0.0, distance + (bounds[1, 2] - bounds[0, 2]) / 2.0])
    return Camera(eye=eye, look_at=centre, up=np.array([0.0, 1.0, 0.0]), fov=fov,
                  width=width, height=height)


def camera_frame(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(forward, right, true_up)``, unit vectors of the DESIGN §6 convention."""
    forward = np.asarray(camera.look_at, float) - np.asarray(camera.eye, float)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(camera.up, float))
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    return forward, right, true_up


def sample_offsets(spp: int) -> np.ndarray:
    """``(spp, 2)`` sub-pixel positions in [0, 1)²: cell centres of a ``⌈√spp⌉²`` grid."""
    s = math.ceil(math.sqrt(spp))
    g = (np.arange(s) + 0.5) / s
    xy = np.stack(np.meshgrid(g, g, indexing="xy"), axis=-1).reshape(-1, 2)
    return xy[:spp]


def primary_rays(camera: Camera, rows: slice, cols: slice, spp: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Rays through the pixels ``rows × cols``: ``origins (n, 3)``, unit ``directions (n, 3)``,
    ordered (row, column, sample)."""
    forward, right, true_up = camera_frame(camera)
    w, h = camera.width, camera.height
    tan_half = math.tan(math.radians(camera.fov) / 2.0)
    r = np.arange(rows.start, rows.stop, dtype=float)
    c = np.arange(cols.start, cols.stop, dtype=float)
    off = sample_offsets(spp)
    px = (c[None, :, None] + off[None, None, :, 0]) * np.ones((len(r), 1, 1))
    py = (r[:, None, None] + off[None, None, :, 1]) * np.ones((1, len(c), 1))
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
    n = len(origins)
    t, tri, u, v = closest_hit(ctx.grid, origins, directions, np.zeros(n), np.full(n, np.inf))
    out = np.zeros((n, 3))
    hit = tri >= 0
    if not hit.any():
        return out
    tri_h = tri[hit]
    elem = ctx.tri_element[tri_h]
    front = np.einsum("ij,ij->i", directions[hit], ctx.elem_normal[elem]) < 0.0
    corners = ctx.tri_verts[tri_h]
    uh, vh = u[hit][:, None], v[hit][:, None]
    L = ((1.0 - uh - vh) * ctx.vertex_radiance[corners[:, 0]]
         + uh * ctx.vertex_radiance[corners[:, 1]]
         + vh * ctx.vertex_radiance[corners[:, 2]])
    out[hit] = np.where(front[:, None], L, 0.0)
    return out


def tiles(width: int, height: int, tile: int = TILE) -> list[tuple[slice, slice]]:
    """Row-major list of ``(rows, cols)`` tiles covering the image."""
    return [(slice(y, min(y + tile, height)), slice(x, min(x + tile, width)))
            for y in range(0, height, tile) for x in range(0, width, tile)]


def render_tile(ctx: RenderContext, rows: slice, cols: slice) -> np.ndarray:
    """``(h, w, 3) float64`` radiance of one tile, box-filtered over ``ctx.spp`` samples."""
    o, d = primary_rays(ctx.camera, rows, cols, ctx.spp)
    L = shade(ctx, o, d)
    h, w = rows.stop - rows.start, cols.stop - cols.start
    return L.reshape(h, w, ctx.spp, 3).mean(axis=2)


def render(ctx: RenderContext) -> np.ndarray:
    """The whole image, ``(H, W, 3) float64``, tile by tile in-process."""
    cam = ctx.camera
    image = np.zeros((cam.height, cam.width, 3))
    for rows, cols in tiles(cam.width, cam.height):
        image[rows, cols] = render_tile(ctx, rows, cols)
    return image
