"""Every form-factor method on the configurations of issue 6, item 2, with its own error bound.

The reference is Lambert's contour formula (exact, unoccluded; tests/test_formfactor.py checks
it against Howell's closed forms), and for the occluded configuration the exact visible part:
a small square between the point and a large meshed square casts a *rectangular* shadow (central
projection, scale 2), so the visible part of every element is ``L(element) - L(element ∩
shadow)``, both rectangles, both exact.

Error analyses (``L`` the exact value, ``R`` the resolution, ``P`` the outline's length):

``hemisphere`` (default, anti-aliased)
    ``F = L · won/covered``: an unoccluded element gets ``L`` exactly (to round-off), whatever
    its size; issue 6 asks 2 % (1 % for large ones), we hold it to 1e-9. A partly occluded one
    errs only through the occluder's outline inside it: ``L · (P_occ,px/4 + 4) / covered``,
    held to the issue's 1 %.
``hemisphere-itembuffer``
    The raster model of tests/test_formfactor.py: ``(P_px/4 + 4)/n_disc + L·|πR²/4 -
    n_disc|/n_disc``.
``hemisphere-scanline``
    Exact spans in ``x``; in ``y`` the midpoint rule with step ``h = 2/N`` on the width function
    ``w(y)``. Per row cell ``|h w(y_j) - ∫ w| <= h · TV_cell(w)``, and the total variation of
    ``w`` is at most the outline's horizontal travel, ``<= P`` (disc units). With the weights
    ``1/S``, ``S = h Σ_j 2 w_j`` (the disc's own midpoint sum):
    ``|F - L| <= (h P + P δ²/8) / S + L |π/S - 1|``, ``δ²/8`` the sagitta of a polyline piece
    subtending ``δ`` (the edge angle).
``hemicube``
    The raster model on the cube: a pixel counts by its centre, so only pixels the outline
    crosses err, a quarter of a pixel per pixel of outline on average (plus 4 for corners), each
    pixel weighing at most ``max ΔF``; delta form factors taken at pixel centres err by the
    midpoint rule, relatively ``<= h² max|Δf|/(24 f) <= 4/R²`` on each face (``f = (1+r²)^-2``:
    ``|Δf/f| <= 12``), and the normalisation to a sum of 1 adds ``L |raw - 1|``:
    ``|F - L| <= (P_px/4 + 4) max ΔF + L (4/R² + |raw - 1|)``, ``P_px`` the outline's length on
    the cube's faces in pixels.
``raycast``
    ``F = L × (visible fraction of the sample points)``: an element whose samples all see the
    point gets ``L`` exactly, one wholly hidden 0, one straddling a shadow boundary anything in
    ``[0, L]``: the error is bounded by ``Σ L`` over the straddling elements.
``analytic``
    Exact without occlusion (1e-12); it has no occlusion, so the occluded case does not apply.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from daskrad import formfactor as ff
from daskrad.kernels.hemicube import delta_form_factors
from daskrad.kernels.hemisphere import disc_pixels
from tests.helpers import (
    ORIGIN,
    UP,
    closed_box,
    corner_rectangle,
    grid,
    merge,
    projected_perimeter_px,
    raster_bound,
    square_above,
    triangle_soup,
)

R = 256
METHODS = ("hemisphere", "hemisphere-itembuffer", "hemisphere-scanline", "hemicube", "raycast",
           "analytic")
EXACT_WITHOUT_OCCLUSION = ("hemisphere", "raycast", "analytic")


# --- configurations (issue 6, item 2) -----------------------------------------------------------

def tilted_quad():
    """A quad crossing the tangent plane (partly below the horizon), lit side towards 0."""
    corners = np.array([[1.0, -0.6, -0.5], [1.0, 0.7, -0.3], [0.4, 0.8, 0.9], [0.3, -0.5, 1.1]])
    elems = np.array([[0, 1, 2, 3]], np.int32)
    normal = np.cross(corners[1] - corners[0], corners[2] - corners[0])
    if normal @ (ORIGIN - corners[0]) < 0:
        elems = elems[:, ::-1].copy()
    return corners, elems


def wall(x, y0, y1, z0, z1):
    """A rectangle in the plane x = const facing -x (towards the origin)."""
    return grid([x, y0, z0], [0, 0, z1 - z0], [0, y1 - y0, 0])


CONFIGS = {
    # large: the unit square 1 above (F = 0.239), a 3 × 4 corner rectangle 0.5 above (F = 0.23)
    "large": square_above(-0.5, 0.5, -0.5, 0.5, 1.0),
    "large-near": square_above(0.0, 3.0, 0.0, 4.0, 0.5),
    # small: a 0.02 square, ~5 pixels at R = 256; far: a unit square 60 away, ~1 pixel
    "small": square_above(0.30, 0.32, -0.21, -0.19, 1.0),
    "far": square_above(20.0, 21.0, -0.5, 0.5, 56.0),
    # grazing: a wall 6 away seen 1°–6° above the horizon; a strip low over the horizon
    "grazing-wall": wall(6.0, -0.5, 0.5, 0.1, 0.6),
    "grazing-strip": square_above(-20.0, 20.0, 3.0, 4.0, 0.4),
    # partly below the horizon
    "below-horizon": tilted_quad(),
    # many small elements: a 6 × 6 plane 2 above, meshed 24 × 24 (each ~25 pixels)
    "mesh": square_above(-3.0, 3.0, -3.0, 3.0, 2.0, n=24),
}


def outline(verts, elems, e):
    idx = elems[e]
    return verts[idx[idx >= 0]]


# --- per-method bounds --------------------------------------------------------------------------

def scanline_bound(exact, perimeter_px, resolution, edge_angle_deg=1.0):
    h = 2.0 / resolution
    y = -1.0 + (2.0 * np.arange(resolution) + 1.0) / resolution
    s = h * (2.0 * np.sqrt(1.0 - y * y)).sum()
    perimeter = perimeter_px * 2.0 / resolution  # disc units
    sag = math.radians(edge_angle_deg) ** 2 / 8.0
    return (h * perimeter + perimeter * sag) / s + exact * abs(math.pi / s - 1.0)


def cube_perimeter_px(corners, resolution, point=ORIGIN):
    """Length of the outline projected onto the hemicube's faces, in pixels (R/2 per unit)."""
    s = np.linspace(0.0, 1.0, 4001)[:, None]
    total = 0.0
    for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
        w = a + s * (b - a) - point
        w = w[w[:, 2] > 0]
        if len(w) < 2:
            continue
        m = np.maximum(np.abs(w[:, :2]).max(axis=1), w[:, 2])
        cube = w / m[:, None]
        total += np.linalg.norm(np.diff(cube, axis=0), axis=1).sum()
    return total * resolution / 2


def hemicube_bound(exact, perimeter_px, resolution):
    weights, raw = delta_form_factors(resolution)
    return ((perimeter_px / 4 + 4) * weights.max()
            + exact * (4.0 / resolution**2 + abs(raw - 1.0)))


def bound(method, exact, corners, resolution=R, point=ORIGIN):
    """The error bound of ``method`` for one unoccluded element (module docstring)."""
    if method in EXACT_WITHOUT_OCCLUSION:
        return 1e-9 * exact + 1e-15
    if method == "hemicube":
        return hemicube_bound(exact, cube_perimeter_px(corners, resolution, point), resolution)
    perim = projected_perimeter_px(corners, resolution, point)
    if method == "hemisphere-itembuffer":
        return raster_bound(exact, perim, resolution)
    return scanline_bound(exact, perim, resolution)


# --- unoccluded: every configuration, every method ----------------------------------------------

@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("config", sorted(CONFIGS))
def test_unoccluded_configurations(method, config):
    verts, elems = CONFIGS[config]
    exact = ff.analytic_point_to_elements(ORIGIN, UP, verts, elems)
    assert (exact > 0).all()
    f = ff.point_to_elements(ORIGIN, UP, verts, elems, method, R)
    bounds = np.array([bound(method, exact[e], outline(verts, elems, e))
                       for e in range(len(elems))])
    assert (np.abs(f - exact) <= bounds).all(), (f, exact, bounds)
    if method == "hemisphere":
        # issue 6 item 2: within 2 % for any element, 1 % for large ones (here: exact)
        np.testing.assert_allclose(f, exact, rtol=0.01 if config.startswith("large") else 0.02)


def test_the_raster_methods_alias_where_the_default_does_not():
    # The bounds above are not vacuous for the raster methods: a ~5-pixel element is off by
    # far more than 2 %, while the default gets Lambert's value.
    verts, elems = CONFIGS["small"]
    exact = ff.analytic_point_to_elements(ORIGIN, UP, verts, elems)[0]
    errors = {m: abs(ff.point_to_elements(ORIGIN, UP, verts, elems, m, R)[0] - exact) / exact
              for m in ("hemisphere-itembuffer", "hemicube", "hemisphere")}
    assert errors["hemisphere-itembuffer"] > 0.02
    assert errors["hemicube"] > 0.02
    assert errors["hemisphere"] < 1e-9


@pytest.mark.parametrize("resolution", [64, 512])
def test_bounds_shrink_with_resolution(resolution):
    # Each raster method stays within its bound at other resolutions too (large element).
    verts, elems = CONFIGS["large"]
    exact = ff.analytic_point_to_elements(ORIGIN, UP, verts, elems)[0]
    for method in ("hemisphere-itembuffer", "hemisphere-scanline", "hemicube"):
        f = ff.point_to_elements(ORIGIN, UP, verts, elems, method, resolution)[0]
        assert abs(f - exact) <= bound(method, exact, verts[elems[0]], resolution), method


def test_hemicube_top_face_is_the_square_over_it():
    # The 2 × 2 square 1 above covers exactly the top face: F = Σ top-face weights, and the
    # normalised weights make that Lambert's value up to the midpoint rule's O(1/R²).
    verts, elems = square_above(-1.0, 1.0, -1.0, 1.0, 1.0)
    exact = ff.analytic_point_to_elements(ORIGIN, UP, verts, elems)[0]
    assert exact == pytest.approx(4 * corner_rectangle(1.0, 1.0, 1.0), rel=1e-12)
    weights, raw = delta_form_factors(R)
    f = ff.point_to_elements(ORIGIN, UP, verts, elems, "hemicube", R)[0]
    assert f == pytest.approx(weights[:R * R].sum(), rel=1e-12)
    assert abs(raw - 1.0) < 4.0 / R**2
    assert f == pytest.approx(exact, rel=4.0 / R**2 + abs(raw - 1.0))


# --- occluded: a meshed square behind a small occluder -----------------------------------------

def occluded_scene(n=4):
    """A 2 × 2 square at height 2 meshed n × n, a 0.4 square at height 1 between: its shadow on
    the big plane is the 0.8 square [0.1, 0.9] × [-0.6, 0.2]. Returns the scene, the big square's
    elements as (x0, x1, y0, y1) boxes, and the exact visible form factor of each."""
    big = square_above(-1.0, 1.0, -1.0, 1.0, 2.0, n=n)
    small = square_above(0.05, 0.45, -0.3, 0.1, 1.0)
    verts, elems = merge(big, small)
    shadow = (0.1, 0.9, -0.6, 0.2)
    boxes, exact = [], []
    for e in range(n * n):
        c = big[0][big[1][e]]
        x0, x1, y0, y1 = c[:, 0].min(), c[:, 0].max(), c[:, 1].min(), c[:, 1].max()
        full = ff.analytic_point_to_elements(ORIGIN, UP, *square_above(x0, x1, y0, y1, 2.0))[0]
        ix0, ix1 = max(x0, shadow[0]), min(x1, shadow[1])
        iy0, iy1 = max(y0, shadow[2]), min(y1, shadow[3])
        hidden = 0.0
        if ix1 > ix0 and iy1 > iy0:
            hidden = ff.analytic_point_to_elements(
                ORIGIN, UP, *square_above(ix0, ix1, iy0, iy1, 2.0))[0]
        boxes.append((x0, x1, y0, y1, full, hidden))
        exact.append(full - hidden)
    return verts, elems, np.array(boxes), np.array(exact)


@pytest.mark.parametrize("n", [2, 3, 4])
@pytest.mark.parametrize("method", [m for m in METHODS if m != "analytic"])
def test_partly_occluded(method, n):
    verts, elems, boxes, exact = occluded_scene(n)
    f = ff.point_to_elements(ORIGIN, UP, verts, elems, method, R)
    l_small = ff.analytic_point_to_elements(ORIGIN, UP, verts, elems)[-1]
    full, hidden = boxes[:, 4], boxes[:, 5]
    straddling = (hidden > 0) & (hidden < full * (1 - 1e-12))
    assert straddling.sum() >= 2  # the shadow's outline crosses several elements
    occ_corners = verts[elems[-1]]
    if method == "raycast":
        # lit elements exact, the occluder exact, straddling ones anywhere in [0, L]
        np.testing.assert_allclose(f[:-1][~straddling], exact[~straddling], rtol=1e-9,
                                   atol=1e-15)
        assert (f[:-1][straddling] >= 0).all()
        assert (f[:-1][straddling] <= full[straddling] * (1 + 1e-9)).all()
        assert f[-1] == pytest.approx(l_small, rel=1e-9)
        assert abs(f[:-1].sum() - exact.sum()) <= full[straddling].sum()
        return
    occ_px = projected_perimeter_px(occ_corners, R)
    _, covered, _ = ff.hemisphere_counts(ORIGIN, UP, verts, elems, R)
    for e in range(n * n):
        corners = verts[elems[e]]
        if method == "hemisphere":
            # only the occluder's outline inside the element errs, in the visible fraction:
            # |ΔF| <= L (P_occ/4 + 4) / covered (raster model; the whole outline is a bound
            # for the part inside), and 0 for elements the outline does not cross
            b = full[e] * (occ_px / 4 + 4) / covered[0, e] if straddling[e] else 1e-9 * full[e]
            assert abs(f[e] - exact[e]) <= b + 1e-15, e
            if n == 2:
                # issue 6: within 1 % (of the element's form factor) for elements of ~3,500
                # pixels (measured: 0.35 %). Smaller elements are held to the bound above:
                # at n = 3 (~1,700 pixels) the worst is 0.99 %, at n = 4 (~800) 1.1 %.
                assert abs(f[e] - exact[e]) <= 0.01 * full[e], e
        else:
            # the element's own outline, plus the shadow's where it crosses the element
            b = bound(method, full[e], corners)
            if straddling[e]:
                b += _outline_term(method, occ_corners)
            assert abs(f[e] - exact[e]) <= b, (e, f[e], exact[e], b)
    if method == "hemisphere":
        # the visible part of the big square as a whole: within 1 %
        assert abs(f[:-1].sum() - exact.sum()) <= 0.01 * exact.sum()
    # the occluder itself is unoccluded
    assert abs(f[-1] - l_small) <= bound(method, l_small, occ_corners)


def _outline_term(method, corners):
    """The part of a method's bound due to one more outline crossing an element."""
    if method == "hemicube":
        return (cube_perimeter_px(corners, R) / 4 + 4) * delta_form_factors(R)[0].max()
    perim = projected_perimeter_px(corners, R)
    if method == "hemisphere-itembuffer":
        return (perim / 4 + 4) / disc_pixels(R)[2]
    if method == "hemisphere-scanline":
        return scanline_bound(0.0, perim, R)
    return 0.0


@pytest.mark.parametrize("method", ["hemisphere", "hemisphere-scanline"])
def test_plane_depth_option_resolves_the_occluder(method):
    verts, elems, boxes, exact = occluded_scene(4)
    f_exact = ff.point_to_elements(ORIGIN, UP, verts, elems, method, R)
    f_plane = ff.point_to_elements(ORIGIN, UP, verts, elems, method, R, depth="plane")
    # eq. 5 ranks these well-separated planes the same way as the exact depth
    np.testing.assert_allclose(f_plane, f_exact, rtol=1e-12, atol=1e-15)


def test_small_elements_behind_and_in_front_of_an_occluder():
    # Elements too small to hold a pixel centre: the default decides their visibility at the
    # pixel nearest their centroid. Behind a big square they get 0, in front of it Lambert.
    big = square_above(-1.0, 1.0, -1.0, 1.0, 1.0)
    behind = square_above(0.2, 0.2005, 0.1, 0.1005, 3.0)
    front = square_above(0.4, 0.4003, -0.3, -0.2997, 0.5)
    verts, elems = merge(big, behind, front)
    won, covered, _ = ff.hemisphere_counts(ORIGIN, UP, verts, elems, R)
    assert covered[0, 1] == 0 and covered[0, 2] == 0
    f = ff.point_to_elements(ORIGIN, UP, verts, elems, "hemisphere", R)
    lam = ff.analytic_point_to_elements(ORIGIN, UP, verts, elems)
    assert f[1] == 0.0
    assert f[2] == pytest.approx(lam[2], rel=1e-12)
    # the big square loses only the pixels its small occluder wins (none here)
    assert f[0] == pytest.approx(lam[0], rel=1e-12)


# --- conservation --------------------------------------------------------------------------------

@pytest.mark.parametrize("method", METHODS)
def test_closed_box_rows_sum_to_one(rng, method):
    verts, elems = closed_box(5)
    points = rng.uniform(0.05, 0.95, (6, 3))
    normals = rng.normal(size=(6, 3))
    points = np.vstack([points, [[0.5, 0.5, 0.0], [1e-4, 0.37, 0.0]]])
    normals = np.vstack([normals, [UP, UP]])
    f = ff.shooter_rows(points, normals, verts, elems, method, 100)
    # every direction sees the box: the weights (pixels, spans, delta form factors, Lambert's
    # exact row) sum to 1, only round-off remains
    np.testing.assert_allclose(f.sum(1), 1.0, atol=1e-9)
    assert (f >= 0).all()


def test_closed_box_with_an_occluder_sums_to_one(rng):
    # A box inside the box: occlusion everywhere, yet the default's rows still sum to exactly 1
    # (renormalised to the item buffer's total, which is 1 in a closed view).
    outer = closed_box(4)
    inner_v, inner_e = closed_box(2, size=0.3)
    inner = (inner_v + 0.35, inner_e[:, ::-1].copy())  # lit sides outwards
    verts, elems = merge(outer, inner)
    points = np.array([[0.5, 0.5, 0.0], [0.1, 0.2, 0.0], [0.2, 0.0, 0.6]])
    normals = np.array([UP, UP, [0.0, 1.0, 0.0]])
    for method in ("hemisphere", "hemisphere-itembuffer", "hemisphere-scanline", "hemicube"):
        f = ff.shooter_rows(points, normals, verts, elems, method, 128)
        np.testing.assert_allclose(f.sum(1), 1.0, atol=1e-9, err_msg=method)
    f = ff.shooter_rows(points, normals, verts, elems, "raycast", 128)
    assert (f.sum(1) <= 1.0 + 1e-12).all()


@pytest.mark.parametrize("method", METHODS[:-1])
def test_random_soups_never_exceed_one(rng, method):
    for _ in range(3):
        verts, elems, points, normals = triangle_soup(rng, 150)
        f = ff.shooter_rows(points, normals, verts, elems, method, 64)
        assert (f >= 0).all()
        assert (f.sum(1) <= 1.0 + 1e-12).all()
        assert f.sum() > 0.0


def test_options_of_the_new_methods():
    from daskrad.errors import OptionError
    verts, elems = CONFIGS["large"]
    with pytest.raises(OptionError):
        ff.point_to_elements(ORIGIN, UP, verts, elems, "raycast", samples=0)
    with pytest.raises(OptionError):
        ff.point_to_elements(ORIGIN, UP, verts, elems, "hemicube", both_axes=True)
    f1 = ff.point_to_elements(ORIGIN, UP, verts, elems, "hemisphere-scanline", 128)[0]
    f2 = ff.point_to_elements(ORIGIN, UP, verts, elems, "hemisphere-scanline", 128,
                              both_axes=True)[0]
    exact = ff.analytic_point_to_elements(ORIGIN, UP, verts, elems)[0]
    b = bound("hemisphere-scanline", exact, verts[elems[0]], 128)
    assert abs(f1 - exact) <= b and abs(f2 - exact) <= b
    # more ray samples: still exact for an unoccluded element
    f3 = ff.point_to_elements(ORIGIN, UP, verts, elems, "raycast", samples=5)[0]
    assert f3 == pytest.approx(exact, rel=1e-12)
