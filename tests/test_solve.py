"""Whole-scene answers for progressive refinement (docs/references.md, "Whole-scene answers")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from daskrad import solve
from daskrad.run import solve_scene
from daskrad.scene import box_scene
from daskrad.settings import Settings

# docs/references.md: closed unit cube of six single patches, ceiling E = 1 (exitance)
CUBE = {0.5: (1.090909, 0.181746, 0.181836), 0.8: (1.551724, 0.689551, 0.689681)}


def _patch_mean(h, values):
    return solve.patch_average(h, values)


def _face_mean(h, values, face_of_polygon):
    """Area-weighted mean of element values over each of the six box faces, ``(6, 3)``."""
    face = face_of_polygon[h.elem_polygon]
    out = np.zeros((6, values.shape[1]))
    for c in range(values.shape[1]):
        out[:, c] = np.bincount(face, weights=values[:, c] * h.elem_area, minlength=6)
    area = np.bincount(face, weights=h.elem_area, minlength=6)
    return out / area[:, None]


@pytest.mark.parametrize("relaxation", [1.0, solve.RELAXATION])
@pytest.mark.parametrize("rho", [0.5, 0.9])
def test_furnace_converges_to_E_over_one_minus_rho(rho, relaxation):
    # Every face emits E and reflects rho: B = E / (1 - rho) everywhere, whatever the shape.
    # The hemisphere's disc weights sum to exactly 1 inside a closed box, so the only error
    # left is the unshot remainder, below tolerance · (initial RMS) / (1 - rho) ≪ 1 %.
    Ke = 1.0 / math.pi  # radiance; exitance E = π Ke = 1
    scene = box_scene(size=(1.0, 1.5, 2.0), diffuse=rho, emission_per_face=Ke)
    settings = Settings(patch_size=0.5, element_size=0.25, resolution=128, tolerance=1e-4,
                        max_iterations=20000, relaxation=relaxation)
    h, _, sol, _ = solve_scene(scene, settings)
    assert sol.converged
    expected = 1.0 / (1.0 - rho)
    np.testing.assert_allclose(sol.radiosity, expected, rtol=0.01)


@pytest.mark.parametrize("rho", [0.5, 0.8])
def test_six_patch_cube_matches_exact_solution(rho):
    # One patch per face, elements finer; the patch-average radiosity obeys the 6-patch system
    # with our form factors, so it matches the exact answers within the form-factor error
    # (near-field shooter sampling + raster: about 1 % at R = 256), well inside 2 %.
    emission = np.zeros((6, 3))
    emission[3] = 1.0 / math.pi  # ceiling (y+) exitance 1
    scene = box_scene(diffuse=rho, emission_per_face=emission)
    settings = Settings(patch_size=1.0, element_size=1.0 / 8, tolerance=1e-6,
                        max_iterations=20000)
    h, _, sol, _ = solve_scene(scene, settings)
    assert h.n_patches == 6
    B = _face_mean(h, sol.radiosity, np.arange(6))[:, 0]
    ceiling, floor, wall = CUBE[rho]
    np.testing.assert_allclose(B[3], ceiling, rtol=0.02)
    np.testing.assert_allclose(B[2], floor, rtol=0.02)
    np.testing.assert_allclose(B[[0, 1, 4, 5]], wall, rtol=0.02)


@pytest.mark.parametrize("relaxation", [1.0, solve.RELAXATION])
def test_power_balance_and_unshot_never_grows(relaxation):
    # Closed box, ceiling light, coloured walls. Power balance: Σ B A = Σ E A + Σ ρ H A where
    # H A = received power; equivalently the total power emitted plus reflected equals what
    # left, so  Σ (B − E) A = Σ ρ · (incident) A  ⇔  Σ_j ΔB_j A_j sums the shots exactly.
    # We check the closed-scene form: with uniform ρ, Σ B A → Φ_e / (1 − ρ) (0.1 %).
    # Overshot (ω > 1) the balance holds as well: a shot of w ΔB_i changes Σ B A by
    # ρ w ΔB_i A_i and Σ ΔB A by −(1 − ρ) w ΔB_i A_i, so Σ B A + ρ/(1 − ρ) Σ ΔB A stays.
    rho = 0.6
    emission = np.zeros((6, 3))
    emission[3] = [1.0, 0.5, 0.25]
    scene = box_scene(size=(2.0, 1.0, 1.5), diffuse=rho, emission_per_face=emission)
    settings = Settings(patch_size=0.5, element_size=0.125, resolution=128, tolerance=1e-5,
                        max_iterations=50000, batch=4, relaxation=relaxation)
    unshot = []
    h, refl, sol, _ = solve_scene(scene, settings,
                                  on_batch=lambda s: unshot.append(s.unshot.copy()))
    powers = [float((np.abs(u).sum(axis=1) * h.patch_area).sum()) for u in unshot]
    assert len(powers) > 10
    # unshot power Σ |ΔB|·A never grows from one batch to the next (ρ < 1, Σ F ≤ 1; overshot
    # too at ρ = 0.6: daskrad.testing.stress.unshot_contracts)
    assert all(b <= a * (1 + 1e-12) for a, b in zip(powers, powers[1:], strict=False))
    if relaxation != 1.0:
        # overshot: patches hold light to take back, and their later shots take it
        assert min(float(u.min()) for u in unshot) < 0.0
    E = math.pi * scene.materials.emission[h.elem_material]
    phi_e = (E * h.elem_area[:, None]).sum(axis=0)
    total = (sol.radiosity * h.elem_area[:, None]).sum(axis=0)
    # what is still unshot has not been reflected yet: add its eventual contribution
    remaining = (sol.unshot * h.patch_area[:, None]).sum(axis=0) * rho / (1 - rho)
    np.testing.assert_allclose(total + remaining, phi_e / (1 - rho), rtol=1e-3)


def test_next_batch_is_deterministic_and_skips_in_flight():
    unshot = np.array([[1.0, 1, 1], [3, 3, 3], [3, 3, 3], [0, 0, 0], [2, 2, 2]])
    area = np.ones(5)
    np.testing.assert_array_equal(solve.next_batch(unshot, area, 3), [1, 2, 4])
    np.testing.assert_array_equal(solve.next_batch(unshot, area, 3, exclude=np.array([1])),
                                  [2, 4, 0])
    # patches without unshot power are never chosen
    assert len(solve.next_batch(unshot, area, 10)) == 4
    # an overshot patch's light to take back ranks by its size, and a patch whose channels
    # cancel is not empty
    unshot[3] = [-4.0, -4.0, -4.0]
    unshot[0] = [1.0, -1.0, 0.0]
    np.testing.assert_array_equal(solve.next_batch(unshot, area, 5), [3, 1, 2, 4, 0])


def _perpendicular_squares(n: int):
    """Shoot context: a unit-square patch in y = 0 facing +y, and the unit square x, y in
    [0, 1] at z = 0 facing +z that shares its edge, split into n × n receiver elements."""
    from daskrad.formfactor import shooting

    g = np.linspace(0.0, 1.0, n + 1)
    x, y = np.meshgrid(g, g, indexing="ij")
    v = np.concatenate([[[0, 0, 0], [0, 0, 1], [1, 0, 1], [1, 0, 0]],
                        np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])])
    i, j = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    corner = 4 + i * (n + 1) + j
    ev = np.column_stack([corner, corner + n + 1, corner + n + 2, corner + 1]).astype(np.int32)
    return shooting.ShootContext(
        vertices=v.astype(float), elem_verts=ev, elem_area=np.full(n * n, 1.0 / n**2),
        elem_centroid=v[ev].mean(axis=1), elem_normal=np.tile([0.0, 0.0, 1.0], (n * n, 1)),
        elem_polygon=np.ones(n * n, np.int32), patch_verts=np.array([[0, 1, 2, 3]], np.int32),
        patch_polygon=np.zeros(1, np.int32), patch_area=np.ones(1),
        patch_centroid=np.array([[0.5, 0.0, 0.5]]), patch_normal=np.array([[0.0, 1.0, 0.0]]),
        patch_radius=np.array([math.sqrt(0.5)]), elem_radius=np.full(n * n, math.sqrt(0.5) / n),
        polygon_sides=np.full(2, -1, np.int8),
        polygon_two_sided=np.zeros(2, bool), eps=1e-9, method="analytic", resolution=32,
        options={})


@pytest.mark.parametrize("n", [1, 2])
def test_near_receiver_sharing_an_edge_averages_F_ji_over_its_area(n):
    # Howell: perpendicular unit squares sharing an edge, F = 0.200044 either way. The near
    # field takes F_ji from each receiver element to the whole shooter; summed over the
    # receiver's elements (area-weighted) it must give Howell's factor. At the centroid alone
    # it errs by 5.0 % (n = 1) and 1.0 % (n = 2), the integrand varying fast near the shared
    # edge; stratified (2 × 2 per triangle) it measured 0.66 % and 0.16 %: limit 1 % / 0.3 %.
    from daskrad.formfactor import shooting

    ctx = _perpendicular_squares(n)
    F = shooting.receiver_average(ctx, 0, np.arange(n * n))
    assert np.all(F > 0)
    np.testing.assert_allclose((F * ctx.elem_area).sum(), 0.200044,
                               rtol={1: 0.01, 2: 0.003}[n])


def test_row_keys_sample_a_shooter_by_its_share_of_the_brightest_and_it_keeps_that_row(rng):
    # the gate is share · the brightest patch's Σ_e∈p mean_rgb(B_e)·A_e before the first shot;
    # a patch first chosen is sampled (key p) exactly when its power is at or above it, one
    # point (key P + p) below, and keeps that row whatever its B becomes (a re-shot, or the
    # light an overshoot takes back, leaves along the rows its light came by); asking
    # (fix=False, a prefetch) fixes nothing
    scene = box_scene(size=(1.0, 1.5, 2.0), diffuse=0.5, emission_per_face=0.1)
    settings = Settings(patch_size=0.5, element_size=0.25, resolution=32, max_iterations=0)
    h = solve_scene(scene, settings).hierarchy
    radiosity = rng.uniform(0.0, 1.0, (h.n_elements, 3)) ** 4
    sol = solve.Solution(radiosity=radiosity, direct=radiosity.copy(),
                         unshot=np.zeros((h.n_patches, 3)), initial_rms=0.3)
    power = np.bincount(h.elem_patch, radiosity.mean(axis=1) * h.elem_area,
                        minlength=h.n_patches)
    np.testing.assert_allclose(solve.patch_power(h, radiosity, np.arange(h.n_patches)), power,
                               rtol=1e-12)
    share = float(np.median(power) / power.max())
    gate = solve.sample_gate(h, sol, share)
    assert gate == pytest.approx(np.median(power), rel=1e-12)
    assert solve.sample_gate(h, sol, 0.0) == 0.0
    ids = rng.permutation(h.n_patches)
    sampled = power[ids] >= gate
    assert 0 < sampled.sum() < len(ids)
    expect = np.where(sampled, ids, ids + h.n_patches)
    np.testing.assert_array_equal(solve.row_keys(h, sol, ids, gate, fix=False), expect)
    assert (sol.row_kind == -1).all()                      # only asked
    half = len(ids) // 2
    assert not sampled[:half].all()
    np.testing.assert_array_equal(solve.row_keys(h, sol, ids[:half], gate), expect[:half])
    np.testing.assert_array_equal(sol.row_kind[ids[:half]], sampled[:half])
    sol.radiosity = radiosity * 100.0                      # every patch above the gate now
    np.testing.assert_array_equal(solve.row_keys(h, sol, ids, gate),
                                  np.concatenate([expect[:half], ids[half:]]))
    np.testing.assert_array_equal(solve.row_keys(h, sol, ids, 0.0),
                                  np.concatenate([expect[:half], ids[half:]]))


def test_the_default_shot_cap_follows_the_patch_count():
    # None: SHOTS_PER_PATCH a patch, at least MIN_SHOTS; a number given is kept as it is
    from daskrad.settings import MIN_SHOTS, SHOTS_PER_PATCH

    s = Settings()
    assert s.max_iterations is None and s.validate() is s
    assert s.with_patches(10).max_iterations == MIN_SHOTS
    big = MIN_SHOTS // SHOTS_PER_PATCH + 1000
    assert s.with_patches(big).max_iterations == SHOTS_PER_PATCH * big > MIN_SHOTS
    assert s.replace(max_iterations=7).with_patches(big).max_iterations == 7
    scene = box_scene(size=(1.0, 1.5, 2.0), diffuse=0.5, emission_per_face=0.1)
    solved = solve_scene(scene, Settings(patch_size=0.5, element_size=0.25, resolution=32,
                                         tolerance=0.0, batch=64))
    assert solved.solution.iteration == MIN_SHOTS   # tolerance 0: the cap stops it


def test_next_batch_is_the_head_of_a_stable_sort_by_power(rng):
    # many equal powers (rounded), zeros and exclusions: the k chosen are the first k of a
    # stable sort on -power (ties by patch id), whatever k
    for _ in range(50):
        n = int(rng.integers(1, 60))
        unshot = np.round(rng.uniform(-1.0, 3.0, (n, 3)) * rng.integers(0, 2, (n, 1)), 0)
        area = rng.choice([0.5, 1.0, 2.0], n)
        exclude = rng.choice(n, int(rng.integers(0, n + 1)), replace=False)
        power = np.abs(unshot).sum(axis=1) * area        # overshot light ranks by its size
        power[exclude] = 0.0
        expected = np.argsort(-power, kind="stable")
        for k in (1, 3, n, n + 5):
            got = solve.next_batch(unshot, area, k, exclude)
            np.testing.assert_array_equal(got, expected[:min(k, np.count_nonzero(power > 0))])


@pytest.mark.parametrize("relaxation", [1.0, solve.RELAXATION, 1.9])
def test_a_shot_updates_only_its_patches_and_reports_the_change_of_the_squares(rng, relaxation):
    # the update kernel against a plain numpy statement of docs/design.md §4: w ΔB sent,
    # w = 1 + (ω − 1) Σ_k F_ik ρ_k (the share the receivers reflect), (1 − w) ΔB left (exactly
    # 0 at ω = 1); bit for bit but for the order of that share's sum; the change it returns is
    # the change of Σ A_p |ΔB_p|², and its scratch is left clean
    from daskrad.kernels import update

    n_elem, n_patch = 40, 9
    elem_patch = np.sort(rng.integers(0, n_patch, n_elem)).astype(np.int32)
    elem_patch[:n_patch] = np.arange(n_patch)
    elem_area = rng.uniform(0.1, 1.0, n_elem)
    patch_area = np.bincount(elem_patch, elem_area, minlength=n_patch)
    rho = rng.uniform(0.0, 0.9, (n_elem, 3))
    radiosity = rng.uniform(0.0, 1.0, (n_elem, 3))
    unshot = rng.uniform(-0.2, 1.0, (n_patch, 3))       # overshot patches hold some below 0
    shooter = 4
    ids = np.flatnonzero(elem_patch != shooter)[::2].astype(np.int32)
    factors = rng.uniform(0.0, 1.0 / len(ids), len(ids))
    # reference: the sums in receiver order, per patch, added once
    B, U = radiosity.copy(), unshot.copy()
    w = 1.0 + (relaxation - 1.0) * (factors[:, None] * rho[ids]).sum(axis=0)
    dB = w * U[shooter]
    U[shooter] = U[shooter] - dB
    acc = np.zeros_like(U)
    for j, f in zip(ids, factors, strict=True):
        d = rho[j] * (f * (patch_area[shooter] / elem_area[j]) * dB)
        B[j] += d
        acc[elem_patch[j]] += d * (elem_area[j] / patch_area[elem_patch[j]])
    U += acc
    scratch = update.shot_scratch(n_patch)
    before = update.unshot_squares(unshot, patch_area)[0]
    change = update.apply_shot(radiosity, unshot, shooter, ids, factors, rho, elem_area,
                               elem_patch, patch_area, *scratch, relaxation)
    if relaxation == 1.0:
        assert not U[shooter].any()
        np.testing.assert_array_equal(radiosity, B)
        np.testing.assert_array_equal(unshot, U)
    else:
        np.testing.assert_allclose(radiosity, B, rtol=1e-13, atol=0)
        np.testing.assert_allclose(unshot, U, rtol=1e-12, atol=1e-15)
    after = update.unshot_squares(unshot, patch_area)[0]
    assert change == pytest.approx(after - before, rel=1e-12, abs=1e-15)
    assert not scratch[0].any() and (scratch[1] == -1).all()
    # the RMS kernel is numpy's formula
    expected = np.sqrt((patch_area[:, None] * unshot**2).sum() / (3 * patch_area.sum()))
    assert solve.unshot_rms(unshot, patch_area) == pytest.approx(expected, rel=1e-14)


def test_an_overshot_shot_to_receivers_that_reflect_nothing_is_a_plain_one(rng):
    # nothing can come back from black receivers: the shot sends exactly ΔB and leaves 0, as
    # at ω = 1 (a floor under a black emitter converges in one shot, with no residual)
    from daskrad.kernels import update

    n_elem, n_patch = 12, 3
    elem_patch = np.repeat(np.arange(n_patch), 4).astype(np.int32)
    elem_area = rng.uniform(0.1, 1.0, n_elem)
    patch_area = np.bincount(elem_patch, elem_area, minlength=n_patch)
    rho = rng.uniform(0.1, 0.9, (n_elem, 3))
    rho[4:] = 0.0                                  # patches 1 and 2 are black
    ids = np.arange(4, n_elem, dtype=np.int32)
    factors = rng.uniform(0.0, 1.0 / len(ids), len(ids))
    results = []
    for relaxation in (1.0, solve.RELAXATION):
        radiosity = np.ones((n_elem, 3))
        unshot = rng.uniform(0.1, 1.0, (n_patch, 3)) if not results else results[0][2].copy()
        start = unshot.copy()
        update.apply_shot(radiosity, unshot, 0, ids, factors, rho, elem_area, elem_patch,
                          patch_area, *update.shot_scratch(n_patch), relaxation)
        results.append((radiosity, unshot, start))
    (b1, u1, _), (b2, u2, _) = results
    assert not u1[0].any() and not u2[0].any()
    np.testing.assert_array_equal(b1, b2)
    np.testing.assert_array_equal(u1, u2)


@pytest.mark.parametrize("tolerance, mid_batch", [(4e-3, False), (7e-4, True)])
def test_the_solve_stops_at_the_shot_the_exact_rms_test_would(monkeypatch, tolerance,
                                                              mid_batch):
    # the solve follows the unshot RMS from each shot's change and asks the exact pass only
    # near the tolerance (SURE); asking it at every shot (SURE inf) stops at the same shot,
    # with the same bits, also where that shot lies inside a batch (7e-4: 192 shots of
    # batches of 5, overshot by default; 4e-3: 165, a batch's end)
    scene = box_scene(size=(1.0, 1.5, 2.0), diffuse=0.6, emission_per_face=0.1)
    settings = Settings(patch_size=0.5, element_size=0.25, resolution=32, two_pass=False,
                        tolerance=tolerance, batch=5)
    followed = solve_scene(scene, settings).solution
    monkeypatch.setattr(solve, "SURE", math.inf)
    exact = solve_scene(scene, settings).solution
    assert followed.iteration == exact.iteration and followed.converged
    assert (followed.iteration % settings.batch != 0) is mid_batch
    np.testing.assert_array_equal(followed.radiosity, exact.radiosity)
    np.testing.assert_array_equal(followed.unshot, exact.unshot)
