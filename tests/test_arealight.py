"""Area lights by the paper's window on the hemisphere base (issue 5, item 1; kernels/arealight)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from daskrad import cli, direct, tolerances
from daskrad.errors import OptionError
from daskrad.formfactor import analytic_rows
from daskrad.kernels.arealight import (
    HINT,
    SLABS,
    area_irradiance_stats,
    clip_planes,
    clip_polygon,
)
from daskrad.kernels.direct import irradiance_points
from daskrad.kernels.faces import (
    UNION_RAYS,
    Faces,
    face_hides,
    face_hides_fan,
    face_proves,
    no_faces,
)
from daskrad.kernels.geometry import orthonormal_basis
from daskrad.kernels.grid import build_grid, new_fan
from daskrad.kernels.lambert import lambert_polygon
from daskrad.mesh import build_hierarchy, hierarchy_triangles
from daskrad.scene import box_scene, scene_from_arrays

EDGE = math.radians(tolerances.EDGE_ANGLE_DEG)
OFF = 1e-7  # RAY_OFFSET × a scene diagonal of about 1 (absolute, like the pipeline's)
HZ = 1e-9

# A 2 × 2 light at y = 2 facing down (radiance 1, 2, 3), over a floor point p (normal +y).
LIGHT = np.array([[-1.0, 2, -1], [1, 2, -1], [1, 2, 1], [-1, 2, 1]])  # wound to face down
LE = np.array([1.0, 2.0, 3.0])
P = np.array([0.3, 0.0, 0.2])
UP = np.array([0.0, 1.0, 0.0])


def _quad_tris(q):
    return np.array([[q[0], q[1], q[2]], [q[0], q[2], q[3]]])


def _lights(corners):
    corners = np.asarray(corners, float)
    return (corners[None].copy(), np.array([len(corners)], np.int64),
            np.array([[0.0, -1.0, 0.0]]), LE[None].copy())


def _area(tris, points, normals, corners, resolution, faces=None):
    """The window method (``faces``: none) or the face test first, then the window."""
    grid = build_grid(np.ascontiguousarray(tris))
    faces = no_faces(len(tris)) if faces is None else faces
    return area_irradiance_stats(grid, faces, np.atleast_2d(points), np.atleast_2d(normals),
                                 OFF, HZ, *_lights(corners), resolution, EDGE)[:2]


def _lambert(p, n, corners):
    """Lambert's unoccluded form factor from ``p`` to the polygon ``corners`` (analytic)."""
    verts = np.asarray(corners, float)
    return analytic_rows(p[None], n[None], verts, np.arange(len(verts))[None])[0, 0]


def _window(p, n, corners, resolution):
    """The light's window on the disc (dense samples of its projected edges; the kernel's
    frame ``orthonormal_basis(n)``): its side lengths ``(wx, wy)`` and pixel ``(px, py)``."""
    t1x, t1y, t1z, t2x, t2y, t2z = orthonormal_basis(*n)
    c = np.asarray(corners, float)
    s = np.linspace(0.0, 1.0, 20001)[:, None]
    pts = np.concatenate([c[a] + s * (c[(a + 1) % len(c)] - c[a]) for a in range(len(c))]) - p
    d = pts / np.linalg.norm(pts, axis=1, keepdims=True)
    x = d @ np.array([t1x, t1y, t1z])
    y = d @ np.array([t2x, t2y, t2z])
    wx, wy = np.ptp(x), np.ptp(y)
    return wx, wy, wx / resolution, wy / resolution


def test_unoccluded_light_is_lambert_exactly():
    # floor and light only: no candidate occluder, V = 1, H = π Le F to the last bit of the
    # shadow-ray method (both use the same Lambert kernel and expression)
    floor = np.array([[-3.0, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]])
    tris = np.concatenate([_quad_tris(floor), _quad_tris(LIGHT)])
    pts = np.array([P, [0.0, 0, 0], [2.5, 0, -2.0], [-1.7, 0, 2.9]])
    H, work = _area(tris, pts, np.tile(UP, (4, 1)), LIGHT, 16)
    assert np.all(work == 0)
    F = np.array([_lambert(p, UP, LIGHT) for p in pts])
    np.testing.assert_allclose(H, math.pi * F[:, None] * LE, rtol=1e-12)  # analytic, round-off
    grid = build_grid(tris)
    rays = irradiance_points(grid, pts, pts, np.tile(UP, (4, 1)), np.arange(4), OFF,
                             np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)),
                             np.zeros((0, 3)), *_lights(LIGHT), np.ones(1) * 4.0, 4)[0]
    assert np.array_equal(H, rays)


def test_candidate_that_hides_no_pixel_leaves_lambert_exactly():
    # A speck inside the pyramid (a candidate, so the window is rasterized) too small to hold
    # a pixel centre of a 16 × 16 window: every light pixel stays visible, V = n/n = 1 exactly.
    speck = np.array([[[0.3, 1.0, 0.2], [0.3004, 1.0, 0.2], [0.3, 1.0, 0.2004]]])
    tris = np.concatenate([_quad_tris(LIGHT), speck + [0.01, 0, 0.013]])
    H, work = _area(tris, P, UP, LIGHT, 16)
    assert work[0] == 1
    F = lambert_polygon(*P, *UP, LIGHT, 4)  # the kernel's own Lambert: the same bits
    assert np.array_equal(H[0], np.pi * LE * F * 1.0)


@pytest.mark.parametrize("reach", [1.45, 1.05])
def test_a_triangle_beside_the_pyramid_is_no_candidate(reach):
    # A large triangle halfway up (y = 1), its near edge along x + z = reach. The pyramid's
    # section there is x in [-0.35, 0.65], z in [-0.4, 0.6]: its corner reaches x + z = 1.25.
    # No face plane of the pyramid separates the triangle (it spans the +x face's side and the
    # +z face's), nor does its own plane (the eye below, the light above). At 1.45 it meets no
    # ray to the light: no candidate, the light is wholly visible (exactly, class VISIBLE); at
    # 1.05 it cuts the corner off the light.
    from daskrad.kernels.direct import LIGHT_TRACE, LIGHT_VISIBLE

    tri = np.array([[[reach + 1.05, 1.0, -1.05], [-1.05, 1.0, reach + 1.05], [3.0, 1.0, 3.0]]])
    grid = build_grid(np.concatenate([_quad_tris(LIGHT), tri]))
    H, work, classes = area_irradiance_stats(grid, no_faces(3), P[None], UP[None], OFF, HZ,
                                             *_lights(LIGHT), 16, EDGE)
    F = lambert_polygon(*P, *UP, LIGHT, 4)
    if reach > 1.25:
        assert work[0] == 0 and classes[0, 0] == LIGHT_VISIBLE
        assert np.array_equal(H[0], np.pi * LE * F * 1.0)
    else:
        assert work[0] == 1 and classes[0, 0] == LIGHT_TRACE
        assert 0.5 < H[0, 0] / (np.pi * LE[0] * F) < 1.0


@pytest.mark.parametrize("resolution", [64, 128, 256])
def test_half_hidden_light_within_the_window_bound(resolution):
    # A wide blocker at y = 1 over x > 0.4 (facing up, both sides block): from p = (0.3, 0,
    # 0.2) a light point (x, 2, z) is hidden iff the ray crosses y = 1 at (0.3 + x)/2 > 0.4,
    # i.e. x > 0.5. The visible part is the rectangle x ∈ [-1, 0.5]: H = π Le F(visible).
    blocker = np.array([[0.4, 1.0, -3], [0.4, 1, 3], [3, 1, 3], [3, 1, -3]])
    tris = np.concatenate([_quad_tris(LIGHT), _quad_tris(blocker)])
    H, work = _area(tris, P, UP, LIGHT, resolution)
    assert work[0] >= 1
    visible = np.array([[-1.0, 2, -1], [0.5, 2, -1], [0.5, 2, 1], [-1, 2, 1]])
    F_light = _lambert(P, UP, LIGHT)
    F_vis = _lambert(P, UP, visible)
    V = F_vis / F_light
    # Bound (kernels/arealight docstring): a pixel no outline crosses is counted exactly, so
    # |V_raster − V| <= (B_vis + V B_light) / N_light. Both regions project to convex sets
    # (each contains the zenith over p), whose outline crosses at most 2(w/px + h/py) + 12
    # pixels (4 monotone arcs, each Δx/px + Δy/py + 3); both lie in the window, w <= R px.
    # The light's pixels: N_light >= A/a − B_light, with A = π F (Nusselt) its area on the
    # disc and a = px·py. The 1° polyline's sagitta (4e-5) is far below half a pixel here,
    # so its misplaced centres lie in crossed pixels, already counted.
    wx, wy, px, py = _window(P, UP, LIGHT, resolution)
    b = 4 * resolution + 12
    n_light = math.pi * F_light / (px * py) - b
    bound = (b + V * b) / n_light
    assert bound < (1 - V) / 2  # the test can tell a lit light from a half-hidden one
    err = abs(H[0, 0] / (math.pi * LE[0] * F_light) - V)
    assert err <= bound
    np.testing.assert_allclose(H[0] / LE, H[0, 0] / LE[0], rtol=1e-15)  # one V for all colours


def _faces(quads):
    """Each quad of ``quads`` one face (both its triangles), itself its one piece: the
    triangles ``_quad_tris`` makes of them, in order, and their :class:`Faces`."""
    quads = np.asarray(quads, float)
    tris = np.concatenate([_quad_tris(q) for q in quads])
    return tris, Faces(np.repeat(np.arange(len(quads)), 2).astype(np.int32),
                       np.arange(len(quads) + 1, dtype=np.int64), quads.copy(),
                       np.full(len(quads), 4, np.int64))


def _at(y, x0, x1, z0, z1):
    """The quad ``[x0, x1] × [z0, z1]`` at height ``y``."""
    return [[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]]


def test_a_face_that_hides_the_whole_light_settles_it_by_one_ray():
    # A 3 × 3 board at y = 1 between the floor points and the 2 × 2 light at y = 2: from
    # every point below its middle the pyramid to the light passes through the board, whose
    # two triangles are one face. The face test proves V = 0 (work 1: no search, no raster);
    # the window method alone rasterizes the board and finds every light pixel hidden too.
    tris, faces = _faces([LIGHT, _at(1.0, -1.5, 1.5, -1.5, 1.5)])
    pts = np.array([[0.0, 0, 0], [0.3, 0, 0.2], [-0.45, 0, 0.4], [0.1, 0, -0.5]])
    up = np.tile(UP, (len(pts), 1))
    H, work = _area(tris, pts, up, LIGHT, 32, faces)
    assert np.all(H == 0.0) and np.all(work == 1)
    H_w, work_w = _area(tris, pts, up, LIGHT, 32)
    assert np.all(H_w == 0.0) and np.all(work_w >= 1)
    # the light's own face is never an occluder: with the board gone the corner rays reach
    # the light (less than 2 off before it), and V = 1
    H_open, work_open = _area(tris[:2], pts, up, LIGHT, 32, _faces([LIGHT])[1])
    F = np.array([lambert_polygon(*p, *UP, LIGHT, 4) for p in pts])
    assert np.all(work_open == 0)
    assert np.array_equal(H_open, np.pi * LE[None, :] * F[:, None] * 1.0)


def test_the_face_that_hid_a_light_from_the_last_point_is_tried_before_the_ray():
    # The 3 × 3 board at y = 1 hides the light from both floor points. From q0 the ray to the
    # light's first corner hits the board, which proves it. From P that ray first meets a
    # small tile at y = 0.9, which covers too little of the pyramid to prove anything, so
    # without a remembered face P goes to the window method (more than one candidate); with
    # the board remembered from q0 (``hint``, what a direct task carries from vertex to
    # vertex) the board proves it at once. Either way V = 0: the same bits.
    tile = _at(0.9, -0.385, -0.185, -0.44, -0.24)
    tris, faces = _faces([LIGHT, _at(1.0, -1.5, 1.5, -1.5, 1.5), tile])
    grid = build_grid(np.ascontiguousarray(tris))
    pts = np.array([[0.0, 0.0, 0.6], P])
    up = np.tile(UP, (2, 1))

    def run(hint):       # one face at a time (union 0): the faces' rays would find the board
        return area_irradiance_stats(grid, faces, pts, up, OFF, HZ, *_lights(LIGHT), 32, EDGE,
                                     SLABS, hint, True, 0)[:2]

    (H, work), (H_plain, work_plain) = run(HINT), run(0)
    assert np.all(H == 0.0) and np.array_equal(H, H_plain)
    assert work_plain[0] == 1 and work_plain[1] > 1
    assert np.array_equal(work, [1, 1])
    # the kernel itself: from P the ray's face (the tile) proves nothing, the board does
    eye = P + OFF * UP
    args = (grid, faces, *eye, UP, LIGHT, 4, np.array([0.0, -1.0, 0.0]), OFF, HZ)
    board = 2   # the board's first triangle (each quad two, the light's first)
    assert face_hides(*args, -1, 0) == -1
    assert face_hides(*args, board, 0) == board
    assert face_hides(*args, 4, 0) == -1   # the tile remembered: declined, and the ray's too
    assert face_hides(*args) == 4   # with the faces the other corners' rays meet: proved
    # A remembered face is tested at every corner, the first included (no ray vouches for
    # it): a board at y = 1 notched along x + z = -0.55 holds the crossings towards corners
    # 1-3 but not corner 0's (-0.35, -0.4), 0.14 outside. It hides nothing wholly (the light
    # shows through the notch), so with it remembered the answer must still be -1.
    notch = [[-1.5, 1.0, 0.95], [0.95, 1.0, -1.5], [2.0, 1.0, 0.0], [0.0, 1.0, 2.0]]
    tris2, faces2 = _faces([LIGHT, notch])
    grid2 = build_grid(np.ascontiguousarray(tris2))
    assert face_hides(grid2, faces2, *args[2:], 2) == -1 == face_hides(grid2, faces2,
                                                                        *args[2:], 2, 0)
    H2 = area_irradiance_stats(grid2, faces2, P[None], UP[None], OFF, HZ, *_lights(LIGHT), 32,
                               EDGE)[0]
    assert 0.0 < H2[0, 0] < np.pi * LE[0] * lambert_polygon(*P, *UP, LIGHT, 4)


@pytest.mark.parametrize("case", ["two boards", "a board and a wall"])
def test_faces_that_hide_the_whole_light_together_settle_it_without_the_window(case):
    # Two boards at y = 1 meeting at x = 0.3; or a board at y = 1 up to x = 0.6 and a wall
    # x = 0.6 from y = 0.5 up through the light's plane (its plane does not separate the
    # point from the light: it hides only the light's part beyond it, x > 0.9 seen from p).
    # No face hides the light alone; together they do: V = 0 with one occluder (work 1),
    # the bits of the window method, which rasterizes them.
    if case == "two boards":
        quads = [LIGHT, _at(1.0, -3, 0.3, -3, 3), _at(1.0, 0.3, 3, -3, 3)]
    else:
        quads = [LIGHT, _at(1.0, -3, 0.6, -3, 3),
                 [[0.6, 0.5, -3], [0.6, 3.0, -3], [0.6, 3.0, 3], [0.6, 0.5, 3]]]
    tris, faces = _faces(quads)
    H, work = _area(tris, P, UP, LIGHT, 32, faces)
    H_w, work_w = _area(tris, P, UP, LIGHT, 32)
    assert H[0, 0] == 0.0 and np.array_equal(H, H_w)
    assert work[0] == 1 and work_w[0] > 1
    grid = build_grid(np.ascontiguousarray(tris))
    args = (grid, faces, *(P + OFF * UP), UP, LIGHT, 4, np.array([0.0, -1.0, 0.0]), OFF, HZ)
    assert all(face_proves(grid, faces, k, *args[2:], -1.0) is False
               for k in range(2, len(tris)))            # no single face would do
    assert face_hides(*args) >= 2


def test_faces_hide_only_lights_no_ray_reaches():
    # Random boards and walls between floor points and the light (two boards split at a
    # random x, overlapping or with a gap, at their own heights, and more at random):
    # wherever the face test (one face or several) says hidden, none of 48 x 48 stratified
    # shadow rays from the point to the light gets through; and it proves some that no
    # single face hides.
    from daskrad.kernels.grid import any_hit

    rng = np.random.default_rng(7)
    others = np.random.default_rng(11)          # more points per scene, for the fan's marks
    en = np.array([0.0, -1.0, 0.0])
    u = (np.arange(48) + 0.5) / 48
    uu, vv = (a.ravel() for a in np.meshgrid(u, u))
    q = np.column_stack([-1 + 2 * uu, np.full_like(uu, 2.0), -1 + 2 * vv])
    proved = several = 0
    for _ in range(60):
        xs = rng.uniform(-0.5, 0.8)
        quads = [LIGHT, _at(rng.uniform(0.5, 1.5), -3, xs + rng.uniform(-0.1, 0.05), -3, 3),
                 _at(rng.uniform(0.5, 1.5), xs + rng.uniform(-0.1, 0.05), 3, -3, 3)]
        for _ in range(rng.integers(0, 3)):
            x0, z0 = rng.uniform(-2.5, 0.5, 2)
            x1, z1 = x0 + rng.uniform(0.5, 3), z0 + rng.uniform(0.5, 3)
            if rng.random() < 0.7:
                quads.append(_at(rng.uniform(0.4, 1.8), x0, x1, z0, z1))
            else:                                   # a wall x = x0 from y0 to y1
                y0 = rng.uniform(0.0, 1.0)
                quads.append([[x0, y0, z0], [x0, y0 + 2.5, z0], [x0, y0 + 2.5, z1],
                              [x0, y0, z1]])
        tris, faces = _faces(quads)
        grid = build_grid(np.ascontiguousarray(tris))
        p = np.array([rng.uniform(-1, 1), 0.0, rng.uniform(-1, 1)])
        e = p + OFF * UP
        k = face_hides(grid, faces, *e, UP, LIGHT, 4, en, OFF, HZ)
        # the vertex pass's rays mark the triangles they tested, one fan for every point and
        # light (its marks numbered on from ray to ray): the same answers
        fan = new_fan(grid)
        for x, z in [e[[0, 2]], *others.uniform(-1, 1, (3, 2)), e[[0, 2]]]:
            f = np.array([x, e[1], z])
            assert face_hides_fan(grid, faces, *f, UP, LIGHT, 4, en, OFF, HZ, -1, UNION_RAYS,
                                  fan) == face_hides(grid, faces, *f, UP, LIGHT, 4, en, OFF, HZ)
        if k < 0:
            continue
        proved += 1
        several += not any(face_proves(grid, faces, j, *e, UP, LIGHT, 4, en, OFF, HZ, -1.0)
                           for j in range(2, len(tris)))
        d = q - e
        tmax = 1.0 - OFF / np.linalg.norm(d, axis=1)
        assert any_hit(grid, np.repeat(e[None], len(q), 0), d, 0.0, tmax).all()
    assert proved >= 10 and several >= 10


def _free_rays(grid, e, q):
    """How many of the segments from ``e`` to the points ``q (m, 3)`` no triangle meets."""
    from daskrad.kernels.grid import any_hit

    d = q - e
    return int((~any_hit(grid, np.repeat(e[None], len(q), 0), d, 0.0, 1.0 - 1e-9)).sum())


def test_faces_hide_declines_when_the_eye_is_behind_the_light():
    # A vertex within off of the light's plane whose eye e = p + off n lies just behind it
    # (a tilted normal): the light's edge rule t < 1 - 2 off / h would pass every crossing
    # if h < 0 were let through (c1 > 1), so a wall beyond the light (the tile beside one
    # corner takes no part) would "hide" a light that 666 of 1600 shadow rays reach. The
    # several-faces proof must decline (union 4; with union 0 face_proves decides, which
    # already refused h < 0).
    wall = [[0.4, -1, -1], [3.4, 2, -1], [3.4, 2, 1], [0.4, -1, 1]]     # x = y + 1.4
    tile = [[0.99, 0.48, -0.02], [0.99, 0.52, -0.02], [0.99, 0.52, 0.02], [0.99, 0.48, 0.02]]
    tris, faces = _faces([wall, tile])
    grid = build_grid(np.ascontiguousarray(tris))
    light = np.array([[1, -0.5, 0], [1, 0.5, 0], [2, 0.5, 0], [2, -0.5, 0]], float)
    en = np.array([0.0, 0.0, -1.0])
    off, hz = 1e-4, 1e-7
    n = np.array([math.sin(math.radians(60)), 0.0, math.cos(math.radians(60))])
    e = np.array([0.0, 0.0, -1e-5]) + off * n
    assert en @ (e - light[0]) < 0.0 < en @ (e - off * n - light[0])
    u = (np.arange(40) + 0.5) / 40
    uu, vv = (a.ravel()[:, None] for a in np.meshgrid(u, u))
    q = light[0] + uu * (light[3] - light[0]) + vv * (light[1] - light[0])
    assert _free_rays(grid, e, q) > 0
    for union in (0, 4):
        assert face_hides(grid, faces, *e, n, light, 4, en, off, hz, -1, union) == -1


@pytest.mark.parametrize("gap_eps", [150.0, 2.2, 1.9, 1.5])
def test_faces_hide_counts_the_edge_tolerance_in_the_face_plane(gap_eps):
    # Two boards in z = 0 with a slit gap_eps * eps wide at x = 1, seen at a grazing angle
    # (eye 0.01 above, 2 away) by a light beyond. The ray test closes a slit narrower than
    # 2 eps (a hit within eps of a triangle's edge counts), so 1.5 and 1.9 eps are proved
    # hidden, no ray through; 2.2 and 150 eps are open: the edges' margin must be eps within
    # the boards' plane (~100 eps per edge at this angle when it was eps from the plane
    # through the eye and the edge, closing slits up to ~200 eps), so the proof declines.
    # The slit's edges are 3 long (not 1), so a margin missing the edge's length shows.
    def boards(g):
        return _faces([[[0, -1, 0], [1, -1, 0], [1, 2, 0], [0, 2, 0]],
                       [[1 + g, -1, 0], [2, -1, 0], [2, 2, 0], [1 + g, 2, 0]]])

    g = gap_eps * build_grid(np.ascontiguousarray(boards(0.0)[0])).eps
    tris, faces = boards(g)
    grid = build_grid(np.ascontiguousarray(tris))
    assert abs(g / grid.eps - gap_eps) < 1e-3 * gap_eps
    e = np.array([-1.0, 0.5, 0.01])
    n, en = np.array([1.0, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0])
    light = np.array([[3, 0.3, -0.008], [3, 0.7, -0.008], [3, 0.7, -0.025], [3, 0.3, -0.025]])
    # light points whose rays cross z = 0 at x = xc, across the slit and either side of it
    xc = 1.0 + np.linspace(-2.0 * g, 3.0 * g, 401)
    q = np.column_stack([np.full_like(xc, 3.0), np.full_like(xc, 0.5), 0.01 - 0.04 / (xc + 1)])
    assert np.all((q[:, 2] > -0.025) & (q[:, 2] < -0.008))
    free = _free_rays(grid, e, q)
    k = face_hides(grid, faces, *e, n, light, 4, en, 1e-4, 1e-6, -1, 4)
    if gap_eps > 2.0:
        assert free > 0 and k == -1
    else:
        assert free == 0 and k >= 0


@pytest.mark.parametrize("case", ["partial", "two boards with a gap", "below horizon",
                                  "at the light"])
def test_the_face_test_proves_nothing_it_cannot(case):
    # Where no face or faces hide the whole light the face test must decline, and the window
    # method decides, with the bits it has without faces.
    p, n = P, UP
    if case == "partial":        # the board hides x > 0.4 only: V ≈ 0.56, not 0
        quads = [LIGHT, _at(1.0, 0.4, 3, -3, 3)]
    elif case == "two boards with a gap":  # 0.05 between them at x = 0.3: V > 0
        quads = [LIGHT, _at(1.0, -3, 0.3, -3, 3), _at(1.0, 0.35, 3, -3, 3)]
    elif case == "below horizon":  # a point on a wall z = 0, half the light behind it
        quads = [LIGHT, _at(1.5, -3, 3, -3, 3)]
        p, n = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    else:                        # a board within off of the light hides nothing
        quads = [LIGHT, _at(2.0 - 0.5 * OFF, -1.5, 1.5, -1.5, 1.5)]
    tris, faces = _faces(quads)
    H, work = _area(tris, p, n, LIGHT, 32, faces)
    H_w, work_w = _area(tris, p, n, LIGHT, 32)
    assert np.array_equal(H, H_w) and np.array_equal(work, work_w)
    F = lambert_polygon(*p, *n, LIGHT, 4)
    V = H[0, 0] / (np.pi * LE[0] * F)
    assert {"partial": 0.3 < V < 0.8, "two boards with a gap": 0.0 < V < 0.1,
            "below horizon": F > 0 and V == 0.0, "at the light": V == 1.0}[case]


def _clip(tri, planes, count):
    poly = np.zeros((6, 8))
    poly[:3, :len(tri)] = np.asarray(tri, float).T
    n = clip_polygon(poly, len(tri), planes, count)
    return poly[:3, :n].T.copy()


def _area3(poly):
    """Area of a planar polygon ``(n, 3)`` (fan of cross products)."""
    return 0.5 * np.linalg.norm(sum(np.cross(poly[i] - poly[0], poly[i + 1] - poly[0])
                                    for i in range(1, len(poly) - 1)))


def test_occluders_are_clipped_to_the_widened_pyramid_exactly():
    # kernels/arealight draws only an occluder's part inside the pyramid from the eye to the
    # light widened by WINDOW_CLIP_ANGLE (a wall near the eye subtends tens of degrees, the
    # light a few). The widened pyramid holds the whole light with the margin, and the clip is
    # the exact intersection: a triangle cut by one plane keeps the analytic area; one wholly
    # inside is unchanged, one wholly outside vanishes.
    eye = P + OFF * UP
    planes = np.zeros((5, 5))
    delta = tolerances.WINDOW_CLIP_ANGLE
    clip_planes(*eye, LIGHT, 4, delta, planes)
    rng = np.random.default_rng(3)
    uv = rng.random((500, 2))
    inside = (LIGHT[0] + uv[:, :1] * (LIGHT[1] - LIGHT[0]) + uv[:, 1:] * (LIGHT[3] - LIGHT[0]))
    for a in range(4):
        k, kd = planes[a, :3], planes[a, 3]
        assert abs(np.linalg.norm(k) - 1.0) < 1e-12
        # every point of the light is inside by at least sin(delta) times its distance from
        # the edge's line seen from the eye (exactly that on the edge itself)
        assert np.all(inside @ k - kd > 0.0)
        edge = LIGHT[a] + np.linspace(0, 1, 11)[:, None] * (LIGHT[(a + 1) % 4] - LIGHT[a])
        d = edge - eye
        along = (LIGHT[(a + 1) % 4] - LIGHT[a]) / np.linalg.norm(LIGHT[(a + 1) % 4] - LIGHT[a])
        perp = np.linalg.norm(d - (d @ along)[:, None] * along, axis=1)
        np.testing.assert_allclose(d @ k, perp * math.sin(delta), rtol=1e-12)
    # an eye just below the middle of the light (2e-3 of its size, where turning a plane
    # through it by delta would cut the far side off): every plane kept holds the light
    low = np.array([0.0, 2.0 - 4e-3, 0.0])
    near = np.zeros((5, 5))
    clip_planes(*low, LIGHT, 4, delta, near)
    kept = [a for a in range(4) if np.any(near[a, :3] != 0.0)]
    assert all(np.all(inside @ near[a, :3] - near[a, 3] > 0.0) for a in kept)
    assert len(kept) < 4          # the turned planes that would cut the light clip nothing
    # one plane: x >= 1 cuts the triangle (0,0,0) (2,0,0) (0,2,0) to (1,0,0) (2,0,0) (1,1,0)
    one = np.zeros((5, 5))
    one[0, :4] = [1.0, 0.0, 0.0, 1.0]
    tri = [[0.0, 0, 0], [2, 0, 0], [0, 2, 0]]
    cut = _clip(tri, one, 1)
    assert len(cut) == 3 and _area3(cut) == pytest.approx(0.5, rel=1e-15)
    assert np.array_equal(_clip([[1.5, 0, 0], [2, 0, 0], [1.5, 1, 0]], one, 1),
                          np.array([[1.5, 0, 0], [2, 0, 0], [1.5, 1, 0]]))
    assert len(_clip([[0.0, 0, 0], [0.5, 0, 0], [0, 0.5, 0]], one, 1)) < 3
    # two triangles sharing an edge meet the plane at the same bits there, whichever way
    # round they walk the edge (their projections stay watertight)
    # (computed from either end, this crossing differs in its last bits)
    other = np.zeros((5, 5))
    other[0, :4] = [1.0, 0.0, 0.0, 1.37]
    u, v = [0.1, 0.3, 0.7], [2.3, 1.1, -0.4]
    a = _clip([u, v, [0.2, 1.9, 0.1]], other, 1)
    b = _clip([v, u, [1.9, -1.0, 0.3]], other, 1)
    line = np.array(u) + np.outer((1.37 - 0.1) / 2.2, np.subtract(v, u))
    on_edge = [q for q in a if np.allclose(q, line[0], rtol=0, atol=1e-12)]
    assert len(on_edge) == 1 and any(np.array_equal(on_edge[0], q) for q in b)


def _blocked_light(half, patch_size, element_size, method="hemisphere"):
    """A 2 × 2 floor (ρ 0.5), a 0.5 × 0.5 emitter at y = 1 facing down (radiance 3) and a black
    square blocker of half-side ``half`` at y = 0.5: ``(hierarchy, triangles, direct
    context)``."""
    b = half
    v = np.array([[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1],
                  [-0.25, 1, -0.25], [0.25, 1, -0.25], [0.25, 1, 0.25], [-0.25, 1, 0.25],
                  [-b, 0.5, -b], [-b, 0.5, b], [b, 0.5, b], [b, 0.5, -b]])
    scene = scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11]]),
                              [0, 1, 0], diffuse=[[0.5] * 3, [0, 0, 0]],
                              emission=[[0] * 3, [3.0] * 3])
    h = build_hierarchy(scene, patch_size, element_size)
    tris, _, tri_element = hierarchy_triangles(h)
    ctx = direct.make_context(scene, h, build_grid(tris), method=method,
                              tri_element=tri_element)
    return h, tris, ctx


def test_fully_hidden_light_gives_zero_through_the_pipeline():
    # A blocker wider than the emitter (test_direct's scene): floor vertices under the
    # blocker's middle see no light at all, exactly 0.
    h, tris, ctx = _blocked_light(0.5, 2.0, 0.25)
    H = direct.compute(ctx, 0, len(h.vertices))
    floor = (direct.vertex_normals(h)[:, 1] > 0.5) & (h.vertices[:, 1] < 0.25)
    below = floor & (np.abs(h.vertices[:, 0]) < 0.2) & (np.abs(h.vertices[:, 2]) < 0.2)
    assert below.any() and np.all(H[below] == 0.0)
    # there the blocker, one polygon, hides every emitter patch by itself (the face test);
    # the window method alone finds the same zeros
    window = direct.compute(replace(ctx, faces=no_faces(len(tris))), 0, len(h.vertices))
    assert np.all(window[below] == 0.0)
    # and the floor outside the blocker's shadow gets light (the method is not all zeros)
    assert (H[floor & (np.abs(h.vertices[:, 0]) > 0.99)] > 0).all()


def test_same_bits_for_any_batching_and_close_to_rays():
    scene = box_scene(size=(1.0, 1.0, 1.0), diffuse=0.5,
                      emission_per_face=[0, 0, 0, 1.0, 0, 0],
                      point_lights=(np.array([[0.3, 0.5, 0.6]]), np.ones((1, 3))))
    # a blocker inside the box so some vertices rasterize occluders
    h = build_hierarchy(scene, 0.5, 0.1)
    tris = np.concatenate([hierarchy_triangles(h)[0],
                           _quad_tris(np.array([[0.3, 0.6, 0.3], [0.3, 0.6, 0.7],
                                                [0.7, 0.6, 0.7], [0.7, 0.6, 0.3]]))])
    ctx = direct.make_context(scene, h, build_grid(tris), method="hemisphere", resolution=12)
    n = len(h.vertices)
    whole = direct.direct_vertices(ctx, 0, n)
    parts = np.concatenate([direct.direct_vertices(ctx, a, b)
                            for a, b in direct.batches(0, n, 37)])
    assert np.array_equal(whole, parts)
    # The two methods estimate the same V. Per emitter patch (the light is 4 patches) and
    # vertex: 32 × 32 stratified rays miss V by at most the strata a straight shadow edge
    # crosses, 2·32/1024 ≈ 6 %; a 128 window by (4·128 + 12)·2 / N_light ≈ 13 % (N_light ≈
    # half the window); so at most (6 + 13) % / 4 ≈ 5 % of the brightest vertex overall. In
    # fact they agree to ~1e-4: the bounds only guard gross errors, e.g. a missing shadow.
    hemi = direct.direct_vertices(replace(ctx, area_resolution=128), 0, n)
    rays = direct.direct_vertices(replace(ctx, area_method="rays", samples=32), 0, n)
    unblocked = direct.direct_vertices(replace(ctx, grid=build_grid(hierarchy_triangles(h)[0])),
                                      0, n)
    scale = np.abs(rays).max()
    assert np.abs(hemi - rays).max() < 0.05 * scale
    assert np.abs(hemi - unblocked).max() > 0.1 * scale  # the blocker matters


def test_unknown_method_is_an_option_error(capsys):
    scene = box_scene(size=(1.0, 1.0, 1.0), diffuse=0.5, emission_per_face=[0, 0, 0, 1, 0, 0])
    h = build_hierarchy(scene, 1.0, 0.5)
    grid = build_grid(hierarchy_triangles(h)[0])
    with pytest.raises(OptionError, match="area-light method"):
        direct.make_context(scene, h, grid, method="magic")
    assert set(direct.AREA_METHODS) == {"rays", "hemisphere"}
    # refused by Settings.validate() before the scene is read or anything written
    assert cli.main(["run", "no-such-scene.obj", "--area-method", "magic"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "area-light method" in err
    args = cli.build_parser().parse_args(["run", "scene.obj", "--area-method", "hemisphere"])
    assert args.area_method == "hemisphere"


def _box_quads(lo, hi):
    """The 6 quads of the closed axis-aligned box ``[lo, hi]`` (occluders are two-sided, so
    their winding does not matter)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c = np.array([[hi[0] if i & 1 else lo[0], hi[1] if i & 2 else lo[1],
                   hi[2] if i & 4 else lo[2]] for i in range(8)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return [c[list(f)] for f in faces]


def _square_lights(centres, normals, half):
    """``(n, 4, 3)``: squares of half-side ``half (n,)`` about ``centres (n, 3)`` in the
    planes of the unit ``normals (n, 3)``, counter-clockwise about them."""
    corners = np.empty((len(centres), 4, 3))
    for m in range(len(centres)):
        t1x, t1y, t1z, t2x, t2y, t2z = orthonormal_basis(*normals[m])
        t1, t2 = np.array([t1x, t1y, t1z]), np.array([t2x, t2y, t2z])
        corners[m] = centres[m] + half[m] * np.array([-t1 - t2, t1 - t2, t1 + t2, -t1 + t2])
    return corners


def test_early_stop_gives_the_same_bits_as_drawing_every_occluder():
    # A 4 × 3 × 4 room with 48 small lights facing every way, 8 of them shut inside closed
    # boxes, desks and pillars between them, and 400 points facing every way: the window
    # method with its slab search and early stop (slabs = SLABS) against the reference that
    # searches each pyramid whole and draws every candidate (slabs = 0). A hidden pixel never
    # becomes visible again and the candidate set does not depend on the walk order, so the
    # answer is the same bits, not merely close.
    from daskrad.kernels.arealight import SLABS

    rng = np.random.default_rng(12)
    room = _box_quads([0, 0, 0], [4, 3, 4])
    blockers = [_box_quads([0.5, 0.7, 0.5], [1.7, 0.75, 1.3]),     # desks
                _box_quads([2.2, 0.7, 2.4], [3.5, 0.75, 3.2]),
                _box_quads([1.9, 0.0, 0.4], [2.1, 3.0, 0.6]),       # pillars
                _box_quads([0.9, 0.0, 2.9], [1.1, 3.0, 3.1])]
    n_lights = 48
    centres = rng.uniform([0.3, 0.3, 0.3], [3.7, 2.7, 3.7], size=(n_lights, 3))
    normals = rng.normal(size=(n_lights, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    corners = _square_lights(centres, normals, 0.06 + 0.1 * rng.random(n_lights))
    shut = np.arange(8)  # the first 8 lights sit inside closed boxes of their own
    boxes = [_box_quads(centres[m] - 0.25, centres[m] + 0.25) for m in shut]
    tris, faces = _faces([*room, *sum(blockers, []), *sum(boxes, []), *corners])
    grid = build_grid(np.ascontiguousarray(tris))
    pts = rng.uniform([0.05, 0.05, 0.05], [3.95, 2.95, 3.95], size=(400, 3))
    outside = np.all([np.abs(pts - centres[m]).max(axis=1) > 0.3 for m in shut], axis=0)
    pts = np.ascontiguousarray(pts[outside])
    nrm = rng.normal(size=pts.shape)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    lights = (corners, np.full(n_lights, 4, np.int64), normals,
              np.tile(LE, (n_lights, 1)))
    R = 16
    none = no_faces(len(tris))  # the window method alone

    def run(ls, slabs, hint=HINT):
        return area_irradiance_stats(grid, none, pts, nrm, OFF, HZ, *ls, R, EDGE, slabs,
                                     hint)[:2]

    H, work = run(lights, SLABS)
    H_ref, work_ref = run(lights, 0)
    assert np.array_equal(H, H_ref)
    # the occluders that hid a light from the last point, searched first: the same bits; on
    # points in a row (as a direct task lights a polygon's vertices) the boxes around the shut
    # lights settle with fewer candidates found (the test can fail: random points, each far
    # from the last, gain nothing)
    H_plain, work_plain = run(lights, SLABS, 0)
    assert np.array_equal(H_plain, H_ref)
    shut_lights = tuple(a[shut] for a in lights)
    row = np.ascontiguousarray(np.column_stack([np.linspace(0.1, 3.9, 60), np.full(60, 0.05),
                                                np.full(60, 2.0)]))
    up = np.tile([0.0, 1.0, 0.0], (60, 1))
    by_row = [area_irradiance_stats(grid, none, row, up, OFF, HZ, *shut_lights, R, EDGE, SLABS,
                                    h)
              for h in (HINT, 0)]
    assert np.array_equal(by_row[0][0], by_row[1][0]) and not by_row[0][0].any()
    assert by_row[0][1].sum() < by_row[1][1].sum()
    for slabs in (1, 3):  # any slab count, same bits
        assert np.array_equal(run(lights, slabs)[0], H_ref)
    # The early stop did happen (fewer candidates found), and the scene has every kind of
    # vertex-light pair: wholly hidden with candidates, partly hidden, wholly visible.
    assert work.sum() < work_ref.sum()
    kinds = set()
    for m in range(n_lights):
        one = tuple(a[m:m + 1] for a in lights)
        Hm = run(one, SLABS)[0][:, 0]
        assert np.array_equal(Hm, run(one, 0)[0][:, 0])
        F = np.array([lambert_polygon(*p, *n, corners[m], 4)
                      if normals[m] @ (p - corners[m, 0]) > 0 else 0.0
                      for p, n in zip(pts, nrm, strict=True)])
        V = Hm / np.where(F > 0, math.pi * LE[0] * F, 1.0)
        lit = F > 0
        if m in shut:  # analytic: a closed box around the light hides it from every point
            assert np.all(Hm == 0.0) and lit.any()
        kinds |= {"hidden"} if (lit & (V == 0)).any() else set()
        kinds |= {"partial"} if (lit & (V > 0) & (V < 1)).any() else set()
        kinds |= {"visible"} if (lit & (V == 1)).any() else set()
    assert kinds == {"hidden", "partial", "visible"}
    # The face test first (each quad of the room one face) settles pairs by one ray and
    # changes no bit here: where it proves a light hidden, the 16 × 16 raster finds every
    # light pixel hidden too (it can differ only where the raster lets a pixel through a face
    # that covers the whole light, which this room does not have)
    H_f, work_f, _ = area_irradiance_stats(grid, faces, pts, nrm, OFF, HZ, *lights, R, EDGE)
    assert work_f.sum() < work.sum()
    assert np.array_equal(H_f, H)


def test_walking_only_the_rows_and_cells_the_pyramid_reaches_finds_the_same_candidates():
    # A dust of 20,000 tiny triangles in a unit cube (each in one cell of the grid, so a
    # candidate is found through one row only), 24 lights facing every way and 150 points:
    # each pyramid searched whole (slabs = 0, every candidate counted in ``work``) with the
    # rows and empty cells of its box pruned and without. A row or a cell the pruning dropped
    # wrongly would lose its candidates, so the counts per point, and the irradiance, must be
    # equal; and the scene must hold candidates at all.
    rng = np.random.default_rng(5)
    centres = rng.uniform(0.0, 1.0, size=(20000, 1, 3))
    tris = np.ascontiguousarray(centres + rng.uniform(-1e-4, 1e-4, size=(20000, 3, 3)))
    grid = build_grid(tris)
    n_lights = 24
    normals = rng.normal(size=(n_lights, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    corners = _square_lights(rng.uniform(0.1, 0.9, (n_lights, 3)), normals,
                             np.full(n_lights, 0.05))
    lights = (corners, np.full(n_lights, 4, np.int64), normals, np.tile(LE, (n_lights, 1)))
    pts = rng.uniform(0.0, 1.0, size=(150, 3))
    nrm = rng.normal(size=pts.shape)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    none = no_faces(len(tris))
    out = {prune: area_irradiance_stats(grid, none, pts, nrm, OFF, HZ, *lights, 8, EDGE, 0, 0,
                                        prune)
           for prune in (True, False)}
    assert out[False][1].sum() > 10 * len(pts)
    for a, b in zip(out[True], out[False], strict=True):
        assert np.array_equal(a, b)


@pytest.mark.parametrize("method", ["hemisphere", "rays"])
def test_vertex_classes_say_exactly_which_lights_are_wholly_visible_or_hidden(method):
    # The fully-hidden scene (a blocker between the floor and a 4-patch emitter, one lamp):
    # per vertex and emitter patch, LIGHT_VISIBLE only where that patch gives π Le F (V = 1),
    # LIGHT_HIDDEN only where it gives 0 with F > 0, LIGHT_TRACE elsewhere (a penumbra,
    # or F = 0); the classes do not depend on the batching.
    from daskrad.kernels.direct import LIGHT_HIDDEN, LIGHT_VISIBLE

    h, _, ctx = _blocked_light(0.3, 0.25, 0.125, method)
    n, M = len(h.vertices), len(ctx.emitter_corners)
    assert M == 4
    H, classes = direct.vertex_light(ctx, 0, n)
    assert classes.shape == (n, M) and classes.dtype == np.int8
    parts = [direct.vertex_light(ctx, a, b)[1] for a, b in direct.batches(0, n, 29)]
    assert np.array_equal(np.concatenate(parts), classes)
    P, N = ctx.area_points, ctx.normals
    full = np.array([[math.pi * 3.0 * lambert_polygon(*P[i], *N[i], ctx.emitter_corners[m],
                                                       int(ctx.emitter_count[m]))
                      if ctx.emitter_normal[m] @ (P[i] - ctx.emitter_corners[m, 0]) > 0 else 0.0
                      for m in range(M)] for i in range(n)])               # (n, M): π Le F
    vis, hid, other = (classes == LIGHT_VISIBLE), (classes == LIGHT_HIDDEN), (classes == 0)
    assert np.all(full[vis | hid] > 0)          # a class is only given to a light with F > 0
    # where every light with F > 0 has a class, H is the sum of the visible ones' π Le F
    settled = ~(other & (full > 0)).any(axis=1)
    np.testing.assert_allclose(H[settled, 0], (full * vis).sum(axis=1)[settled], rtol=1e-12)
    assert vis.any() and hid.any() and (other & (full > 0)).any()   # every class occurs
    if method == "hemisphere":
        # patch by patch (no lamps), the window settles each light alone: a light's class and
        # part of H ignore the others; the lamp's classes are the patches' where they say
        # something (a lamp partly shadowed is traced though a patch of it may be free)
        assert ctx.lamps is not None and len(ctx.lamps.corners) == 1
        H_p, classes_p = direct.vertex_light(replace(ctx, lamps=None), 0, n)
        said = classes != 0
        assert np.array_equal(classes[said], classes_p[said]) and (classes_p[~said] != 0).any()
        np.testing.assert_allclose(H_p[settled, 0], H[settled, 0], rtol=1e-12)
        for m in range(M):
            one = replace(ctx, lamps=None, **{f: getattr(ctx, f)[m:m + 1] for f in (
                "emitter_corners", "emitter_count", "emitter_normal", "emitter_radiance",
                "emitter_area")})
            Hm, cm = direct.vertex_light(one, 0, n)
            assert np.array_equal(cm[:, 0], classes_p[:, m])
            vis_m, hid_m = classes_p[:, m] == LIGHT_VISIBLE, classes_p[:, m] == LIGHT_HIDDEN
            np.testing.assert_allclose(Hm[vis_m, 0], full[vis_m, m], rtol=1e-12)
            assert np.all(Hm[hid_m] == 0.0)
            pen = (classes_p[:, m] == 0) & (full[:, m] > 0)
            assert np.all((Hm[pen, 0] > 0) & (Hm[pen, 0] < full[pen, m] * (1 - 1e-12)))


def test_an_emitting_polygon_split_into_patches_is_one_lamp_only_where_they_tile_it():
    # The window method takes an emitting polygon whole (one search, one raster): its lamp is
    # the patches' convex hull, counter-clockwise about their normal, where the patches tile
    # a triangle or quad; two squares with a gap, or an L of three, stay three lamps
    def square(x, z, s=1.0):
        return [[x, 1, z], [x, 1, z + s], [x + s, 1, z + s], [x + s, 1, z]]   # faces -y

    def lamps(squares, polygon):
        corners = np.array(squares, float)
        m = len(corners)
        return direct.lamps_of(corners, np.full(m, 4, np.int64), np.tile([0.0, -1, 0], (m, 1)),
                               np.tile([2.0, 2, 2], (m, 1)), np.full(m, 1.0),
                               np.asarray(polygon))

    one = lamps([square(0, 0), square(1, 0), square(0, 1), square(1, 1)], [5, 5, 5, 5])
    assert len(one.corners) == 1 and one.count[0] == 4 and one.of.tolist() == [0] * 4
    c = one.corners[0]
    assert {tuple(p) for p in c} == {(0, 1, 0), (2, 1, 0), (2, 1, 2), (0, 1, 2)}
    newell = sum(np.cross(c[i], c[(i + 1) % 4]) for i in range(4))
    assert newell @ [0.0, -1, 0] == pytest.approx(8.0)          # area 4, the patches' side
    assert lamps([square(0, 0), square(1.5, 0)], [3, 3]) is None            # a gap
    assert lamps([square(0, 0), square(1, 0), square(0, 1)], [3, 3, 3]) is None   # an L
    two = lamps([square(0, 0), square(1, 0), square(5, 5)], [1, 1, 2])      # two polygons
    assert len(two.corners) == 2 and two.of.tolist() == [0, 0, 1]
    assert np.array_equal(two.corners[1], np.array(square(5, 5), float))
    # a triangle in four (its midpoints): one lamp of three corners, the third repeated
    a, b, c = np.array([0.0, 1, 0]), np.array([0.0, 1, 2]), np.array([2.0, 1, 0])
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    tris = [[a, ab, ca, ca], [ab, b, bc, bc], [ca, bc, c, c], [ab, bc, ca, ca]]
    tri = direct.lamps_of(np.array(tris), np.full(4, 3, np.int64), np.tile([0.0, -1, 0], (4, 1)),
                          np.tile([2.0, 2, 2], (4, 1)), np.full(4, 0.5), np.zeros(4, np.int64))
    assert tri.count.tolist() == [3] and np.array_equal(tri.corners[0, 3], tri.corners[0, 2])
    assert {tuple(p) for p in tri.corners[0]} == {tuple(a), tuple(b), tuple(c)}


def test_a_patch_takes_its_lamps_class_only_where_it_faces_the_point():
    # A lamp of two patches on a ceiling (y = 1, facing down), x in [0, 1] and [1, 2]. From a
    # point whose tangent plane is x = 1 (normal -x) only the first patch is above the
    # horizon: the lamp's class goes to it, the second (F = 0) stays LIGHT_TRACE; above the
    # ceiling both are behind; a lamp with no class gives none
    from daskrad.kernels.arealight import patch_classes
    from daskrad.kernels.direct import LIGHT_HIDDEN, LIGHT_TRACE, LIGHT_VISIBLE

    corners = np.array([[[0.0, 1, 0], [0, 1, 1], [1, 1, 1], [1, 1, 0]],
                        [[1.0, 1, 0], [1, 1, 1], [2, 1, 1], [2, 1, 0]]])
    count, down = np.array([4, 4], np.int64), np.tile([0.0, -1, 0], (2, 1))
    of = np.array([0, 0], np.int64)
    points = np.array([[1.0, 0.5, 0.5], [1.5, 0.2, 0.5], [1.0, 1.5, 0.5], [1.5, 0.2, 0.5]])
    normals = np.array([[-1.0, 0, 0], [0, 1, 0], [0, 1, 0], [0, 1, 0]])
    lamp = np.array([[LIGHT_VISIBLE], [LIGHT_HIDDEN], [LIGHT_VISIBLE], [LIGHT_TRACE]], np.int8)
    got = patch_classes(points, normals, lamp, of, corners, count, down)
    assert got.tolist() == [[LIGHT_VISIBLE, LIGHT_TRACE], [LIGHT_HIDDEN, LIGHT_HIDDEN],
                            [LIGHT_TRACE, LIGHT_TRACE], [LIGHT_TRACE, LIGHT_TRACE]]
