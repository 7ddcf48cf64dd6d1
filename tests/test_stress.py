"""Numerical stability under stress (issue 7): degenerate geometry, units, near field,
reflectance near 1, light levels, random scenes, long runs.

The cases live in daskrad/testing/stress.py (shared with benchmarks/bench_stress.py, the stress
report). Each assertion compares a measured figure against an exact answer: the furnace
``B = E/(1 − ρ)``, the bound ``max(E)/(1 − ρ_max)``, the closed-scene energy ledger (exact to
round-off after every shot), or bit/ulp identity of images that must not depend on units or
light level. ``make stress`` runs all of it; ``make test`` skips the ``slow`` cases.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from daskrad import solve, tolerances
from daskrad.errors import DaskradWarning, SceneError
from daskrad.run import solve_scene
from daskrad.scene import box_scene, scene_from_arrays
from daskrad.settings import Settings
from daskrad.testing import stress as sc


def _assert_ok(results):
    bad = [str(r) for r in results if not r.ok]
    assert not bad, "\n".join(bad)


def _safety_ok(results, furnace: bool):
    """In a furnace the exact answer *is* the bound ``E/(1 − ρ)``, so the bound may be exceeded
    by the furnace's own 1 % discretization error; elsewhere by round-off only."""
    if furnace:
        for r in results:
            if r.quantity.startswith("max B"):
                r.limit = 0.01
    _assert_ok(results)


# --- 1. degenerate geometry -----------------------------------------------------------------

DEGENERATE = sc.degenerate_scenes()
@pytest.mark.parametrize("relaxation", [1.0, solve.RELAXATION])
@pytest.mark.parametrize("case", [c for c in DEGENERATE if c != "flipped normal"])
def test_degenerate_geometry_keeps_the_invariants(case, relaxation):
    # finite, non-negative radiosity; unshot power never grows (ρ = 0.5: overshot too,
    # stress.unshot_contracts); the energy ledger holds to 1e-3 (measured: round-off,
    # < 1e-14); B within the bound (furnace: within its 1 %)
    results = sc.safety(case, DEGENERATE[case], sc.BOX.replace(relaxation=relaxation))
    _safety_ok(results, furnace=True)


@pytest.mark.parametrize("case", [c for c in DEGENERATE if c != "flipped normal"])
def test_degenerate_geometry_in_a_furnace_gives_E_over_one_minus_rho(case):
    # every face (the degenerate ones too) emits E = 1 and reflects 0.5 in a closed box:
    # B = 2 everywhere whatever the shape; 1 % as for the plain furnace (test_solve.py)
    r = sc.furnace_error(case, DEGENERATE[case])
    assert r.ok, r


def test_rug_on_an_emitting_floor_is_refused_naming_both_faces():
    # a "rug" lying exactly in the floor's plane z-fights with it (measured before issue 7
    # refused it: the hidden copy shoots and receives nothing, furnace error 50 %). In the
    # furnace the floor emits, so lifting the rug would leave the covered floor emitting
    # through the rug's back: refused in one line naming the file and the two faces (the rug
    # is the 25th, the floor piece the 9th)
    with pytest.raises(SceneError) as err:
        sc.coplanar_overlap_scene()
    line = err.value.line()
    assert "\n" not in line
    assert line.startswith("<rug>: face 25 lies on emitting face 9 in one plane"), line
    # the same rug facing down (back to back with the floor) is another surface: accepted
    rug_down = (sc.RUG[0], [[3, 2, 1, 0]])
    assert len(sc.box_with(*rug_down).polygons) == 25


def test_rug_on_a_floor_is_lifted_and_keeps_the_invariants():
    # issue 16: on a floor that does not emit, the rug is lifted DECAL_LIFT of the diagonal
    # and shows; the floor under it is hidden. The box stays closed: the ledger holds, the
    # radiosity stays bounded, the unshot power never grows
    with pytest.warns(DaskradWarning, match="1 faces lie on larger faces .*first face 25 on "
                      "face 9"):
        scene = sc.rug_scene()
    rug = scene.vertices[scene.polygons[24]]
    np.testing.assert_allclose(rug[:, 1], tolerances.DECAL_LIFT * np.sqrt(3), rtol=1e-12)
    _safety_ok(sc.safety("rug lifted off the floor", scene), furnace=False)


def test_zero_area_faces_are_dropped_with_a_warning():
    with pytest.warns(UserWarning, match="dropped 2 zero-area faces"):
        scene = sc.box_with([[0.2, 0.5, 0.2], [0.4, 0.5, 0.2], [0.6, 0.5, 0.2],
                             [0.3, 0.6, 0.3]], [[0, 1, 2, -1], [3, 3, 0, -1]])
    assert scene.dropped_degenerate == 2
    assert len(scene.polygons) == 24


def test_duplicated_faces_are_dropped_with_a_warning_back_to_back_faces_made_two_sided():
    with pytest.warns(UserWarning, match="dropped 1 duplicated faces"):
        scene = sc.box_with(duplicate=3)
    assert len(scene.polygons) == 24
    # the same corners from another starting corner, and unwelded copies of the vertices,
    # are the same face; the reverse winding is the other side: one two-sided face (issue 16)
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0.0]])
    polys = [[0, 1, 2, 3], [2, 3, 0, 1], [0, 4, 5, 3], [3, 2, 1, 0]]
    with pytest.warns(UserWarning, match="dropped 2 duplicated faces"):
        s = scene_from_arrays(v, polys, [0, 0, 0, 0], [[0.5] * 3], [[1.0] * 3])
    np.testing.assert_array_equal(s.polygons, [[0, 1, 2, 3]])
    assert s.two_sided.tolist() == [True]


def test_flipped_normal_is_a_hole_one_sided_and_creates_no_energy():
    # Surfaces are one-sided (docs/design.md §6): a face wound the wrong way is seen from its back,
    # so from inside the box it is a hole. It must receive nothing (B = E on it), and the
    # light that leaves through it is lost, never created: the open-scene ledger.
    scene = DEGENERATE["flipped normal"]
    results = sc.safety("flipped normal", scene)
    h, reflectance, sol, _ = sc.solve_recorded(scene)
    flipped = h.elem_polygon == 0
    np.testing.assert_allclose(sol.radiosity[flipped], 1.0, rtol=1e-12)
    assert sc.ledger_error(scene, h, reflectance, sol, closed=False) <= 1e-12
    assert sc.ledger_error(scene, h, reflectance, sol, closed=True) > 0.05  # it does leak
    _safety_ok([r for r in results if not r.quantity.startswith("energy")], furnace=True)


# --- 2. units and placement -----------------------------------------------------------------

@pytest.fixture(scope="module")
def cornell_reference(tmp_path_factory):
    return sc.render_cornell(tmp_path_factory.mktemp("units") / "ref")


@pytest.mark.parametrize("scale, offset", [
    (1e-3, 0.0),
    (1e3, 0.0),
    (1e6, 0.0),
    (1.0, 1e6),
])
def test_same_image_whatever_the_units_and_placement(cornell_reference, tmp_path, scale,
                                                     offset):
    # Radiance does not depend on units: with sizes given in the scene's units and the same
    # number of shots, only round-off may differ (1e-4 relative per pixel, issue 7)
    r = sc.units_case(tmp_path, cornell_reference, scale, offset)
    assert r.ok, r


# --- 3. near field --------------------------------------------------------------------------

@pytest.mark.parametrize("gap", [1e-6])
def test_near_field_shots_conserve_energy(gap):
    # receivers sharing an edge or a corner with the shooter, a plate 1e-6 of the scene above
    # the floor, a 1e-3 square 1e-6 in front of it: every row sums to <= 1 (+ round-off),
    # no element above max(E)/(1 - rho_max) (this scene is no furnace: round-off only),
    # ledger 1e-3
    _safety_ok(sc.near_field_cases(gap), furnace=False)


def test_near_field_with_no_gap_is_a_coplanar_overlap_and_resolved():
    # gap 0: the plate's two faces are back to back at the floor's height: one two-sided
    # plate (issue 16), whose back the mesher puts TWO_SIDED_GAP above its front, so it no
    # longer lies in the floor's plane; the tiny square lies on the plate's lower face and is
    # lifted (before two-sided faces: the four floor quads were lifted too)
    with pytest.warns(DaskradWarning) as said:
        scene = sc.near_field_scene(0.0)
    lines = [str(w.message) for w in said]
    assert lines[0] == "<near field>: 1 pairs of coincident back-to-back faces made two-sided faces"
    assert lines[1].startswith("<near field>: 1 faces lie on larger faces")
    assert scene.two_sided.sum() == 1


# --- 4. reflectance near 1 ------------------------------------------------------------------

@pytest.mark.parametrize("rho, budget", [(0.9, 3000), (0.99, 30000), (0.999, 60000)])
def test_furnace_with_reflectance_near_one(rho, budget):
    # one patch per face: ~ 6 · log(1e-3)/log(rho) shots reach tolerance 1e-3, which leaves
    # an error of ~ 1e-3 of E/(1 - rho) (the remaining unshot light), well inside 1 %
    sol, err = sc.furnace_rho(rho, budget)
    assert sol.converged
    assert np.isfinite(sol.radiosity).all()
    assert err <= 0.01, err


def test_furnace_budget_ended_is_reported(tmp_path, capsys):
    # rho = 0.999 needs ~ 40,000 shots; with 600 the run must say so on the terminal and in
    # the report, and the image (ambient term added) is still E/(1 - rho) within 1 %: in a
    # furnace the unshot light is uniform, so the ambient term is exact
    rho = 0.999
    report, image = sc.furnace_run(tmp_path, rho, 600)
    err = capsys.readouterr().err
    assert "not converged after 600 shots" in err
    assert report["converged"] is False and report["iterations"] == 600
    saved = json.loads((tmp_path / "furnace.json").read_text())
    assert saved["converged"] is False
    expected = 1.0 / (1.0 - rho)  # radiance: Ke / (1 - rho) with Ke = 1
    assert np.isfinite(image).all()
    np.testing.assert_allclose(image, expected, rtol=0.01)


# --- 5. light levels ------------------------------------------------------------------------

@pytest.fixture(scope="module")
def light_reference(tmp_path_factory):
    return sc.render_cornell(tmp_path_factory.mktemp("light") / "ref", point_light=1.5e5)


@pytest.mark.parametrize("k", [1e-6, 1e-3, 1e3, 1e9])
def test_image_scales_linearly_with_light_level(light_reference, tmp_path, k):
    # emission and the point light both scaled by k: every step is linear in the light
    # (the stopping rule is relative), so image/k equals the reference up to float64
    # round-off and the float32 rounding of the EXR: 2 ulp of float32 = 2.4e-7 relative
    image = sc.render_cornell(tmp_path, ke_scale=k, point_light=1.5e5 * k)
    assert np.isfinite(image).all()
    mask = light_reference > 0
    rel = np.abs(image[mask] / k - light_reference[mask]) / light_reference[mask]
    assert rel.max() <= 2.4e-7, rel.max()
    assert (image[~mask] == 0).all()
    import zarr

    store = zarr.open_group(str(tmp_path / "cb.zarr"), mode="r")
    for name in ("elements/radiosity", "vertex_radiosity", "patches/unshot"):
        a = np.asarray(store[name][...])
        assert np.isfinite(a).all(), name


# --- 6. random scenes -----------------------------------------------------------------------

def _check_random(scene, closed: bool):
    s = sc.box_settings_for(scene)
    h, reflectance, sol, powers = sc.solve_recorded(scene, s)
    assert np.isfinite(sol.radiosity).all() and np.isfinite(sol.unshot).all()
    assert (sol.radiosity >= 0).all()
    # unshot power never grows where no shot can make it (stress.unshot_contracts: plain
    # shots; overshot, with every ρ up to 0.66, which random ρ in [0.05, 0.95] seldom are):
    # the same scene solved with plain shots holds it whatever its ρ
    if sc.unshot_contracts(s.relaxation, float(reflectance.max())):
        assert sc.unshot_growth(powers) <= 1e-12
    plain = sc.solve_recorded(scene, s.replace(relaxation=1.0))[3]
    assert sc.unshot_growth(plain) <= 1e-12
    assert sc.ledger_error(scene, h, reflectance, sol, closed=closed) <= 1e-3
    return h, sol


# Derandomized: the same seeds every run, so that CI's answer does not depend on the draw. A
# random draw found the soup below, kept as its own (failing) case.
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow],
          derandomize=True)
@given(seed=st.integers(0, 2**32 - 1))
def test_random_closed_boxes(seed):
    _check_random(sc.random_box(np.random.default_rng(seed)), closed=True)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.too_slow],
          derandomize=True)
@given(seed=st.integers(0, 2**32 - 1))
def test_random_triangle_soups(seed):
    _check_random(sc.random_soup(np.random.default_rng(seed)), closed=False)


@pytest.mark.parametrize("seed", [160, 351, 1428])
def test_random_soups_keep_radiosity_non_negative_when_overshot(seed):
    # overshot (relaxation 1.3), these soups ended with B < 0 (down to -2.5e-4 against a
    # largest B of ~5) while a patch could take light back through another row than its
    # light came by (solve.row_keys): every patch now keeps its first row
    scene = sc.random_soup(np.random.default_rng(seed))
    s = sc.box_settings_for(scene)
    assert (sc.solve_recorded(scene, s.replace(relaxation=1.0))[2].radiosity >= 0).all()
    assert (sc.solve_recorded(scene, s)[2].radiosity >= 0).all()


def test_random_scene_same_bits_for_0_and_2_workers(rng, cluster_client):
    from daskrad.distributed.dask_executor import DaskExecutor

    for scene in (sc.random_box(rng), sc.random_soup(rng)):
        s = sc.box_settings_for(scene)
        _, _, a, _ = solve_scene(scene, s)
        _, _, b, _ = solve_scene(scene, s, DaskExecutor(cluster_client))
        np.testing.assert_array_equal(a.radiosity, b.radiosity)
        np.testing.assert_array_equal(a.unshot, b.unshot)


# --- 7. long runs ---------------------------------------------------------------------------

def test_accumulation_is_float64_and_drifts_below_1e5():
    # the solver's state is float64; replaying the same shots in extended precision, its
    # drift stays far below 1e-5 (measured ~1e-15 over 2,000 shots)
    scene = box_scene(emission_per_face=[0, 0, 0, sc.KE, 0, 0])
    sol = solve.initial_solution(sc.build_hierarchy(scene, 1.0, 1.0),
                                 np.zeros((6, 3)))
    assert sol.radiosity.dtype == np.float64 and sol.unshot.dtype == np.float64
    drift = sc.accumulation_drift(2000, 8)
    assert drift["float64"] <= 1e-5, drift


@pytest.mark.slow
def test_long_run_drift_10000_shots_50000_elements():
    # issue 7: 10,000 shots on a 50,000-element scene; float64 holds 1e-5 (float32 is
    # measured and reported by benchmarks/bench_stress.py)
    drift = sc.accumulation_drift(10000, 92)
    assert drift["elements"] >= 50000
    assert drift["float64"] <= 1e-5, drift


# --- a scene that no light reaches ------------------------------------------------------------

def _plate_run(tmp_path, light_y: float):
    """``run`` on one 1 × 1 plate in y = 0 facing -y, lit by a point light at height
    ``light_y``: (report, stderr text)."""
    from daskrad.run import run
    from daskrad.settings import Settings

    tmp_path.mkdir(parents=True, exist_ok=True)
    obj = tmp_path / "plate.obj"
    obj.write_text("mtllib plate.mtl\nusemtl w\nv 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\n"
                   "f 1 2 3 4\n")  # (v1 - v0) × (v2 - v0) = -y
    (tmp_path / "plate.mtl").write_text("newmtl w\nKd 0.7 0.7 0.7\nillum 1\n")
    (tmp_path / "plate.toml").write_text(
        f'[camera]\neye = [0.5, -2.0, 0.5]\nlook_at = [0.5, 0.0, 0.5]\nup = [0.0, 0.0, 1.0]\n'
        f'fov = 40.0\nwidth = 8\nheight = 8\n[[light]]\ntype = "point"\n'
        f"position = [0.5, {light_y}, 0.5]\nintensity = [1.0, 1.0, 1.0]\n")
    return run(obj, tmp_path / "plate.exr", Settings(resolution=32, spp=1), progress=False)


def test_scene_no_light_reaches_warns_on_stderr_and_in_the_report(tmp_path, capsys):
    # the light is behind the plate (one-sided surfaces): nothing receives anything, the
    # image is black; that must not pass silently
    report = _plate_run(tmp_path / "behind", 1.0)
    err = capsys.readouterr().err
    lines = [x for x in err.splitlines() if "no surface receives any light" in x]
    assert len(lines) == 1 and lines[0].startswith("daskrad: warning: "), err
    assert len(report["warnings"]) == 1 and "no surface receives" in report["warnings"][0]
    saved = json.loads((tmp_path / "behind" / "plate.json").read_text())
    assert saved["warnings"] == report["warnings"]
    # in front of it: lit, no warning (irradiance I/d² = 1 at the centre)
    report = _plate_run(tmp_path / "front", -1.0)
    assert report["warnings"] == []
    assert "no surface receives" not in capsys.readouterr().err


# --- 7. big inputs (issue 13) ---------------------------------------------------------------

def test_polygon_of_10000_corners_meshes_in_seconds_with_a_sane_element_count(tmp_path):
    # a convex disc of 10⁴ corners: cut into ear strips, not a fan of 10⁴ slivers each meshed
    # like a triangle as long as the disc (806,644 elements and 462 s before); its area is
    # kept exactly (the triangles tile the polygon)
    _assert_ok(sc.big_polygon_case(tmp_path, 10_000))


def test_concave_polygon_of_10000_corners_is_refused_at_once(tmp_path):
    # ear clipping is O(n²) Python steps: past MAX_CLIPPED_CORNERS the face is refused in one
    # line before any work
    import time

    from daskrad.scene import load_scene
    from daskrad.scene.polygons import MAX_CLIPPED_CORNERS

    path = sc.disc_obj(tmp_path, 10_000, star=True)
    start = time.perf_counter()
    with pytest.raises(SceneError, match=f"face 1 has 10000 corners .* more than "
                       f"{MAX_CLIPPED_CORNERS} corners"):
        load_scene(path)
    assert time.perf_counter() - start < 30.0


def test_coplanar_overlap_check_of_100000_triangles_in_seconds():
    # 100,000 triangles tiling one plane (no overlap found) and 100,000 small ones scattered
    # in one plane: each checked in seconds (10,000 took 14.6 s before)
    _assert_ok(sc.coplanar_soup_case(100_000))


@pytest.mark.parametrize("offset", [1e6, 1e9, 1e12])
def test_a_box_far_from_the_origin_is_the_box_at_the_origin(offset):
    # issue 13: a unit box moved to 1e12 came out 8 % off (at 1e9 the element count changed).
    # Worked relative to its centre (an exact shift), it is the same scene: within 1e-6
    def box(at):
        return box_scene(size=(1.0, 1.0, 1.0), diffuse=0.5,
                         emission_per_face=[0, 0, 0, 1, 0, 0], origin=np.full(3, at))

    s = Settings(patch_size=0.5, element_size=0.25, resolution=32, tolerance=1e-3)
    near, far = solve_scene(box(0.0), s), solve_scene(box(offset), s)
    assert far.hierarchy.n_elements == near.hierarchy.n_elements
    np.testing.assert_allclose(far.solution.radiosity, near.solution.radiosity, rtol=1e-6)
