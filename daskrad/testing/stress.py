"""The numerical stress cases of issue 7, shared by tests/test_stress.py, tests/test_penumbra.py
and benchmarks/bench_stress.py (the stress report).

Every case is a function returning a :class:`Result`: the measured error of one quantity and
the limit it must hold. The tests assert ``result.ok``; the stress report prints the table.

Scenes are small (a unit box of 2 × 2 quads per face, a coarse Cornell box, 48 × 48 images)
so the fast cases run in a few seconds on 2 shared cores.

The energy ledger (``ledger_error``) is the closed-scene power balance in a form that holds
after *every* shot, not only at convergence: a shot removes the shooter's unshot power
``ΔB_i A_i``, every receiver ``j`` absorbs ``(1 − ρ_j)`` and re-emits ``ρ_j`` of what it gets
(``ΔB_j = ρ_j · received``), and in a closed scene the row sums to 1, so

    Σ_j (1 − ρ_j)/ρ_j · (B_j − E_j) A_j  +  Σ_p ΔB_p A_p  =  Σ_j E_j A_j     (per channel)

(absorbed power plus unshot power equals emitted power). In an open scene the left side may
only be smaller (light escapes), never larger. It holds for overshot shots as well
(``--relaxation``): a shot of ``w ΔB_i`` leaves ``(1 − w) ΔB_i``, and what its receivers absorb
and re-emit is still what it sent.

The unshot power ``Σ_p |ΔB_p| A_p`` never grows with plain shots (a shot removes ``ΔB_i A_i``
and gives back at most ``ρ_max`` of it). Overshot, a shot of ``w ΔB_i`` with ``w = 1 + (ω − 1)
s`` (``s ≤ ρ_max`` the share its receivers reflect) leaves ``(w − 1) |ΔB_i| A_i`` and gives back
at most ``w s |ΔB_i| A_i``: the power cannot grow while ``ρ_max (1 + (ω − 1)(1 + ρ_max)) ≤ 1``
(:func:`unshot_contracts`; ρ_max up to 0.66 at ω = 1.3), and is not bounded batch by batch
beyond.

``B ≥ 0`` and ``B ≤ max(E)/(1 − ρ_max)`` are proved for plain shots only: every plain shot adds
a non-negative ``ρ_j ΔB_i F_ij A_i/A_j`` and the total stays below the Neumann series' bound.
Overshot, a later shot of a patch takes its excess back (a negative ``ΔB_i``), so a receiver
may in principle dip below what it had: :func:`safety` checks both at every ω as observed
facts of its scenes, not as consequences of the arithmetic. Each patch shoots through one row
for the whole solve (:func:`daskrad.solve.row_keys`), so light taken back leaves along the
rows the light came by; while a patch could switch rows at the sample gate, 19 of 1,400
random soups ended overshot with ``B < 0`` (none since).
"""

from __future__ import annotations

import math
import shutil
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from daskrad import solve
from daskrad.formfactor import shooting
from daskrad.mesh import build_hierarchy
from daskrad.run import run, solve_scene
from daskrad.scene import box_scene, scene_from_arrays
from daskrad.settings import Settings

#: The measured Cornell box of a source checkout (``scenes/`` is not installed with the
#: package): the units and light-level cases write scaled copies of it.
CORNELL = Path(__file__).resolve().parents[2] / "scenes" / "cornell_box.obj"

#: Furnace-style degenerate scenes: every face emits exitance 1 (radiance 1/π), ρ = 0.5.
RHO = 0.5
KE = 1.0 / math.pi

#: Shooting settings of the small box cases: everything is shot (no gathered direct light),
#: so the ledger above is exact; patches 1/4 and elements 1/8 of the unit box.
BOX = Settings(two_pass=False, resolution=64, patch_size=0.25, element_size=0.125,
               tolerance=1e-4, max_iterations=8000)


@dataclass
class Result:
    """One measured figure of a case: ``error`` must be ``<= limit`` (``ok``)."""

    case: str
    quantity: str
    error: float
    limit: float
    note: str = ""
    extra: dict = field(default_factory=dict)
    measured_only: bool = False  # a figure for a choice (float32 drift), not a requirement

    @property
    def ok(self) -> bool:
        return bool(np.isfinite(self.error) and self.error <= self.limit)

    def __str__(self) -> str:
        return (f"{self.case}: {self.quantity} = {self.error:.3g} (limit {self.limit:g})"
                f"{' — ' + self.note if self.note else ''}")


# --- scenes ---------------------------------------------------------------------------------

def box_with(extra_vertices=(), extra_polygons=(), rho=RHO, ke=KE, subdivisions=2,
             flip: int | None = None, duplicate: int | None = None, path="<stress>"):
    """The unit furnace box (every face emits ``ke``, reflects ``rho``) plus extra polygons
    with the same material; ``flip`` reverses the winding of one box polygon, ``duplicate``
    appends a copy of one."""
    b = box_scene(diffuse=rho, emission_per_face=ke, subdivisions=subdivisions)
    v = b.vertices
    p = b.polygons.astype(np.int64)
    if flip is not None:
        p[flip] = p[flip][[3, 2, 1, 0]]
    if duplicate is not None:
        p = np.concatenate([p, p[duplicate][None]])
    ev = np.asarray(extra_vertices, float).reshape(-1, 3)
    ep = np.asarray(extra_polygons, np.int64).reshape(-1, 4)
    ep = np.where(ep >= 0, ep + len(v), -1)
    verts, polys = np.concatenate([v, ev]), np.concatenate([p, ep])
    return scene_from_arrays(verts, polys, np.zeros(len(polys), int), [[rho] * 3], [[ke] * 3],
                             path=path)


#: Extra polygons of the degenerate cases, added inside the furnace box.
SLIVER = ([[0.2, 0.3, 0.5], [0.5, 0.3, 0.5 + 6e-7], [0.8, 0.3, 0.5]],   # 0.6 long, 3e-7 high:
          [[0, 1, 2, -1]])                                                 # aspect 1e6, faces +y
#: A two-sided fin standing on the floor: its bottom edge is shared (geometrically) by the
#: floor and two faces, a non-manifold edge.
FIN = ([[0.5, 0, 0.2], [0.5, 0, 0.8], [0.5, 0.4, 0.8], [0.5, 0.4, 0.2]],
       [[0, 1, 2, 3], [3, 2, 1, 0]])
#: A "rug" lying exactly in the floor's plane, overlapping a quarter of it. As such it would
#: z-fight (the hidden copy shoots and receives nothing: furnace error 50 % measured before
#: issue 7 refused it). Since issue 16 the smaller face is lifted off the plane (a decal,
#: daskrad/scene/validate.py), unless the face under it emits: in the furnace box every face
#: emits, so :func:`coplanar_overlap_scene` is still refused; :func:`rug_scene` is resolved.
RUG = ([[0.1, 0, 0.1], [0.1, 0, 0.6], [0.6, 0, 0.6], [0.6, 0, 0.1]], [[0, 1, 2, 3]])


def coplanar_overlap_scene():
    """The furnace box with :data:`RUG`: raises the SceneError that refuses it (the floor
    under the rug emits)."""
    return box_with(*RUG, path="<rug>")


def rug_scene():
    """The closed unit box lit by its ceiling (exitance 1, everything reflects 0.5) with the
    :data:`RUG` in the floor's plane: the rug is lifted ``DECAL_LIFT`` of the diagonal."""
    b = box_scene(diffuse=RHO, emission_per_face=[0, 0, 0, KE, 0, 0], subdivisions=2)
    verts = np.concatenate([b.vertices, np.array(RUG[0], float)])
    polys = np.concatenate([b.polygons, np.array(RUG[1]) + len(b.vertices)])
    mat = np.concatenate([b.polygon_material, [6]])
    emission = np.zeros((7, 3))
    emission[3] = KE
    return scene_from_arrays(verts, polys, mat, np.full((7, 3), RHO), emission, path="<rug>")


def t_junction_box(rho=RHO, ke=KE):
    """The furnace box whose floor is one 1 × ½ quad beside two ½ × ½ quads: the corner of the
    small quads at (½, 0, ½) lies on the big quad's edge (a T-junction, an unshared vertex)."""
    b = box_scene(diffuse=rho, emission_per_face=ke, subdivisions=1)
    keep = b.polygon_material != 2                      # drop the floor ("y-")
    v = list(map(list, b.vertices))
    n = len(v)
    v += [[0, 0, 0], [0, 0, 0.5], [1, 0, 0.5], [1, 0, 0],           # big half, z in [0, ½]
          [0, 0, 0.5], [0, 0, 1], [0.5, 0, 1], [0.5, 0, 0.5],       # small quarter
          [0.5, 0, 0.5], [0.5, 0, 1], [1, 0, 1], [1, 0, 0.5]]       # small quarter
    floor = np.arange(12).reshape(3, 4) + n                # (x,z) winding gives normal +y
    polys = np.concatenate([b.polygons[keep], floor])
    return scene_from_arrays(np.array(v, float), polys, np.zeros(len(polys), int),
                             [[rho] * 3], [[ke] * 3], path="<t-junction>")


# --- measurements ---------------------------------------------------------------------------

def solve_recorded(scene, settings: Settings = BOX):
    """``solve_scene`` plus the total unshot power ``Σ_p |ΔB_p| A_p`` (per channel) after
    every batch, ``(batches, 3)``. Patches never change in the direct pass (it splits
    elements only), so the areas of the unrefined hierarchy weigh the unshot radiosity."""
    patch_area = build_hierarchy(scene, settings.patch_size, settings.element_size).patch_area
    powers = []
    h, reflectance, sol, _ = solve_scene(
        scene, settings, on_batch=lambda s: powers.append(np.abs(s.unshot).T @ patch_area))
    return h, reflectance, sol, np.array(powers)


def emission_of(scene, h) -> np.ndarray:
    """``(E, 3)`` exitance ``π Ke`` per element."""
    return math.pi * scene.materials.emission[h.elem_material]


def ledger_error(scene, h, reflectance, sol, closed: bool) -> float:
    """Relative violation of the energy ledger (module docstring), worst channel."""
    E = emission_of(scene, h)
    A = h.elem_area[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        absorbed = np.where(reflectance > 0, (1 - reflectance) / reflectance, 0.0)
    absorbed = (absorbed * (sol.radiosity - E) * A).sum(axis=0)
    unshot = (sol.unshot * h.patch_area[:, None]).sum(axis=0)
    emitted = (E * A).sum(axis=0)
    lit = emitted > 0
    rel = (absorbed + unshot - emitted)[lit] / emitted[lit]
    return float(np.abs(rel).max() if closed else max(rel.max(), 0.0))


def bound_excess(scene, h, reflectance, sol) -> float:
    """How far the largest radiosity exceeds ``max(E)/(1 − ρ_max)``, relative (0: within)."""
    E = emission_of(scene, h)
    bound = E.max() / (1.0 - reflectance.max())
    return float(max(sol.radiosity.max() / bound - 1.0, 0.0))


def unshot_contracts(relaxation: float, rho_max: float) -> bool:
    """Whether no shot can make the unshot power ``Σ_p |ΔB_p| A_p`` grow (module docstring)."""
    return relaxation == 1.0 or rho_max * (1.0 + (relaxation - 1.0) * (1.0 + rho_max)) <= 1.0


def unshot_growth(powers: np.ndarray) -> float:
    """The largest growth of :func:`solve_recorded`'s ``powers`` from one batch to the next,
    relative to the first batch's (0 when it never grows)."""
    if len(powers) < 2:
        return 0.0
    return max(float(np.diff(powers, axis=0).max() / powers[0].max()), 0.0)


def safety(case: str, scene, settings: Settings = BOX, closed: bool = True) -> list[Result]:
    """The invariants every scene must keep: finite, non-negative, bounded radiosity; the
    unshot power's (:func:`unshot_growth`); the energy ledger."""
    h, reflectance, sol, powers = solve_recorded(scene, settings)
    B = sol.radiosity
    finite = bool(np.isfinite(B).all() and np.isfinite(sol.unshot).all())
    # the power may not grow where no shot can make it (every plain solve)
    bound = 1e-12 if unshot_contracts(settings.relaxation, float(reflectance.max())) else math.inf
    return [
        Result(case, "non-finite or negative B (count)",
               float((~np.isfinite(B)).sum() + (B < 0).sum()), 0.0),
        Result(case, "max B over max(E)/(1-rho_max), excess", bound_excess(scene, h,
               reflectance, sol) if finite else math.inf, 1e-9),
        Result(case, "unshot power growth per batch (relative)", unshot_growth(powers), bound),
        Result(case, "energy ledger (relative)", ledger_error(scene, h, reflectance, sol,
               closed), 1e-3, extra={"shots": sol.iteration, "converged": sol.converged}),
    ]


def furnace_error(case: str, scene, settings: Settings = BOX, rho=RHO) -> Result:
    """Worst relative deviation of element radiosity from ``E/(1 − ρ)`` (E = 1)."""
    h, _, sol, _ = solve_recorded(scene, settings)
    err = float(np.abs(sol.radiosity / (1.0 / (1.0 - rho)) - 1.0).max())
    return Result(case, "furnace |B/(E/(1-rho)) - 1|", err, 0.01,
                  extra={"shots": sol.iteration, "converged": sol.converged})


def max_row_sum(scene, settings: Settings = BOX) -> float:
    """Largest ``Σ_j F_ij`` over every patch of ``scene``'s hierarchy (a shot sends
    ``Σ_j F_ij`` of what the shooter holds)."""
    h = build_hierarchy(scene, settings.patch_size, settings.element_size)
    ctx = shooting.make_context(h, settings.method, settings.resolution,
                             edge_angle=settings.edge_angle)
    return max(float(f.sum()) for _, f in shooting.shoot_rows(ctx, np.arange(h.n_patches)))


# --- 1. degenerate geometry -----------------------------------------------------------------

def degenerate_scenes() -> dict:
    """name → scene for the degenerate-geometry cases."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {
            "sliver (aspect 1e6)": box_with(*SLIVER),
            "zero-area faces": box_with([[0.2, 0.5, 0.2], [0.4, 0.5, 0.2], [0.6, 0.5, 0.2],
                                         [0.3, 0.6, 0.3]],
                                        [[0, 1, 2, -1], [3, 3, 0, -1]]),
            "duplicated face": box_with(duplicate=0),
            "T-junction": t_junction_box(),
            "non-manifold edge (fin)": box_with(*FIN),
            "flipped normal": box_with(flip=0),
        }


# --- 2. units and placement -----------------------------------------------------------------

def write_cornell(directory: Path, scale: float = 1.0, offset: float = 0.0,
                  ke_scale: float = 1.0, size: int = 48, point_light: float = 0.0) -> Path:
    """The bundled Cornell box with coordinates ``x·scale + offset`` (camera moved with it)
    and emitted radiance ``Ke·ke_scale``, as OBJ + MTL + TOML in ``directory``;
    ``point_light > 0`` adds a point light of that intensity (W/sr) under the ceiling."""
    directory.mkdir(parents=True, exist_ok=True)
    lines = []
    for line in CORNELL.read_text().splitlines():
        if line.startswith("v "):
            x = np.array(line.split()[1:], float) * scale + offset
            line = "v " + " ".join(repr(float(a)) for a in x)
        lines.append(line)
    obj = directory / "cb.obj"
    obj.write_text("\n".join(lines) + "\n")
    mtl = CORNELL.with_suffix(".mtl").read_text()
    if ke_scale != 1.0:
        mtl = mtl.replace("Ke 17 12 4", "Ke " + " ".join(repr(k * ke_scale)
                                                           for k in (17.0, 12.0, 4.0)))
    (directory / "cornell_box.mtl").write_text(mtl)
    eye = np.array([278.0, 273.0, -800.0]) * scale + offset
    look = np.array([278.0, 273.0, 0.0]) * scale + offset
    light = ""
    if point_light:
        where = np.array([278.0, 450.0, 279.5]) * scale + offset
        light = (f'[[light]]\ntype = "point"\nposition = {where.tolist()}\n'
                 f"intensity = {[point_light] * 3}\n")
    (directory / "cb.toml").write_text(
        f"[camera]\neye = {eye.tolist()}\nlook_at = {look.tolist()}\nup = [0.0, 1.0, 0.0]\n"
        f"fov = 39.3077\nwidth = {size}\nheight = {size}\n" + light)
    return obj


def cornell_settings(scale: float = 1.0) -> Settings:
    """Coarse Cornell box settings with sizes in the scene's units; a fixed number of shots
    (tolerance 0) so every variant applies the same shots."""
    return Settings(resolution=32, tolerance=0.0, max_iterations=60, spp=1, area_samples=2,
                    patch_size=240.0 * scale, element_size=80.0 * scale)


def render_cornell(directory: Path, scale=1.0, offset=0.0, ke_scale=1.0,
                   point_light=0.0) -> np.ndarray:
    """``(48, 48, 3) float64`` image (read back from the EXR) of a transformed Cornell box."""
    from daskrad.io import read_exr

    obj = write_cornell(directory, scale, offset, ke_scale, point_light=point_light)
    out = directory / "cb.exr"
    run(obj, out, cornell_settings(scale), progress=False)
    return read_exr(out).astype(np.float64)


def image_difference(image: np.ndarray, reference: np.ndarray) -> float:
    """Worst per-pixel relative difference over pixels brighter than 1 % of the mean (a black
    pixel has no relative error to speak of)."""
    mask = reference > 0.01 * reference.mean()
    return float((np.abs(image - reference)[mask] / reference[mask]).max())


def units_case(tmp: Path, reference: np.ndarray, scale=1.0, offset=0.0) -> Result:
    image = render_cornell(tmp, scale, offset)
    name = f"Cornell box scaled {scale:g}" if offset == 0 else f"Cornell box moved {offset:g}"
    return Result(name, "max per-pixel relative image difference",
                  image_difference(image, reference), 1e-4)


# --- 3. near field --------------------------------------------------------------------------

def near_field_scene(gap: float = 1e-6):
    """A closed unit box lit by its ceiling plus, inside: a large plate hovering ``gap`` (of
    the scene size) above the floor and facing it, a tiny 1e-3 square ``gap`` in front of the
    plate's top face, and an L of two quads sharing an edge plus one touching it at a corner.

    Everything reflects 0.5; the ceiling emits exitance 1.
    """
    d = gap * math.sqrt(3.0)  # the box diagonal is √3
    v = [
        # plate, 0.6 × 0.6 at height d, facing down (towards the floor) ...
        [0.2, d, 0.2], [0.8, d, 0.2], [0.8, d, 0.8], [0.2, d, 0.8],
        # ... and its top face at the same height, facing up
        [0.2, d, 0.2], [0.2, d, 0.8], [0.8, d, 0.8], [0.8, d, 0.2],
        # tiny square just above the plate, facing down onto it
        [0.5, 2 * d, 0.5], [0.501, 2 * d, 0.5], [0.501, 2 * d, 0.501], [0.5, 2 * d, 0.501],
        # L: a floor-like quad at y=0.5 facing up and a wall quad sharing its edge x=0.3
        [0.1, 0.5, 0.1], [0.1, 0.5, 0.4], [0.3, 0.5, 0.4], [0.3, 0.5, 0.1],
        [0.3, 0.5, 0.1], [0.3, 0.5, 0.4], [0.3, 0.7, 0.4], [0.3, 0.7, 0.1],
        # a quad touching the L's corner (0.3, 0.5, 0.4), facing up
        [0.3, 0.5, 0.4], [0.3, 0.5, 0.6], [0.5, 0.5, 0.6], [0.5, 0.5, 0.4],
    ]
    polys = np.arange(24).reshape(6, 4)
    b = box_scene(diffuse=RHO, emission_per_face=[0, 0, 0, KE, 0, 0], subdivisions=2)
    verts = np.concatenate([b.vertices, np.array(v, float)])
    allp = np.concatenate([b.polygons, polys + len(b.vertices)])
    mat = np.concatenate([b.polygon_material, np.full(6, 6)])
    diffuse = np.full((7, 3), RHO)
    emission = np.zeros((7, 3))
    emission[3] = KE
    return scene_from_arrays(verts, allp, mat, diffuse, emission, path="<near field>")


NEAR = BOX.replace(patch_size=0.2, element_size=0.05, tolerance=1e-5, max_iterations=20000)


def near_field_cases(gap: float = 1e-6) -> list[Result]:
    scene = near_field_scene(gap)
    out = safety(f"near field, gap {gap:g}", scene, NEAR)
    out.append(Result(f"near field, gap {gap:g}", "max row sum - 1 (a shot's share)",
                      max(max_row_sum(scene, NEAR) - 1.0, 0.0), 1e-12))
    return out


# --- 4. reflectance near 1 ------------------------------------------------------------------

def furnace_rho(rho: float, max_iterations: int, tolerance: float = 1e-3) -> tuple:
    """Furnace box with one patch per face (element 1/4): returns (solution, error)."""
    scene = box_scene(diffuse=rho, emission_per_face=KE, subdivisions=1)
    settings = Settings(two_pass=False, resolution=32, patch_size=1.0, element_size=0.5,
                        tolerance=tolerance, max_iterations=max_iterations)
    h, _, sol, _ = solve_scene(scene, settings)
    err = float(np.abs(sol.radiosity * (1.0 - rho) - 1.0).max())
    return sol, err


def furnace_run(tmp: Path, rho: float, max_iterations: int) -> tuple[dict, np.ndarray]:
    """``run`` on a furnace box written as OBJ: (report, image)."""
    from daskrad.io import read_exr

    tmp.mkdir(parents=True, exist_ok=True)
    obj = tmp / "furnace.obj"
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
    faces = [[3, 4, 2, 1], [6, 8, 7, 5], [2, 6, 5, 1], [7, 8, 4, 3], [5, 7, 3, 1],
             [4, 8, 6, 2]]  # 1-based, wound so (v1 - v0) × (v2 - v0) points into the box
    obj.write_text("mtllib furnace.mtl\nusemtl f\n"
                   + "".join(f"v {a} {b} {c}\n" for a, b, c in corners)
                   + "".join("f " + " ".join(map(str, f)) + "\n" for f in faces))
    (tmp / "furnace.mtl").write_text(f"newmtl f\nKd {rho} {rho} {rho}\nKe 1 1 1\nillum 1\n")
    (tmp / "furnace.toml").write_text(
        "[camera]\neye = [0.5, 0.5, 0.05]\nlook_at = [0.5, 0.5, 1.0]\nup = [0.0, 1.0, 0.0]\n"
        "fov = 60.0\nwidth = 16\nheight = 16\n")
    out = tmp / "furnace.exr"
    report = run(obj, out, Settings(two_pass=False, resolution=32, patch_size=1.0,
                                    element_size=0.5, tolerance=1e-3,
                                    max_iterations=max_iterations, spp=1), progress=False)
    return report, read_exr(out).astype(np.float64)


# --- 6. random scenes -----------------------------------------------------------------------

def random_box(rng: np.random.Generator):
    """A closed box with random size, per-face reflectance in [0.05, 0.95] and emission."""
    size = rng.uniform(0.2, 3.0, 3)
    emission = rng.uniform(0.0, 1.0, (6, 3)) * (rng.random(6) < 0.5)[:, None]
    emission[rng.integers(6)] += 0.1
    return box_scene(size=size, diffuse=rng.uniform(0.05, 0.95, (6, 3)),
                     emission_per_face=emission, subdivisions=int(rng.integers(1, 3)))


def random_soup(rng: np.random.Generator, n: int = 12):
    """``n`` random triangles in the unit cube, random materials, at least one emitter."""
    v = rng.uniform(0.0, 1.0, (3 * n, 3))
    m = 3
    emission = np.zeros((m, 3))
    emission[0] = rng.uniform(0.1, 2.0, 3)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return scene_from_arrays(v, np.arange(3 * n).reshape(n, 3), np.arange(n) % m,
                                 rng.uniform(0.05, 0.95, (m, 3)), emission, path="<soup>")


def box_settings_for(scene) -> Settings:
    d = scene.diagonal
    return BOX.replace(patch_size=d / 4, element_size=d / 8, tolerance=1e-3,
                       max_iterations=600)


# --- 7. long runs: float32 vs float64 accumulation ------------------------------------------

def accumulation_drift(n_shots: int, subdivisions: int, method: str = "analytic",
                       resolution: int = 32) -> dict:
    """Apply ``n_shots`` shots of a closed box (every face ρ = 0.7, ceiling emits) in float64
    (the solver's own :func:`daskrad.solve.apply_shot`), and replay the same rows accumulating
    in float32 and in extended precision (``np.longdouble``, the reference).

    Returns the relative max-norm drift of float64 and float32 radiosity from the reference.
    """
    emission = np.zeros((6, 3))
    emission[3] = KE
    scene = box_scene(diffuse=0.7, emission_per_face=emission, subdivisions=subdivisions)
    size = 1.001 / subdivisions  # one patch and one element per polygon, round-off aside
    h = build_hierarchy(scene, size, size)
    rho = scene.materials.diffuse[h.elem_material]
    sol = solve.initial_solution(h, emission_of(scene, h))
    ctx = shooting.make_context(h, method, resolution)
    states = {t: (sol.radiosity.astype(t), sol.unshot.astype(t)) for t in
              (np.float32, np.longdouble)}
    for _ in range(n_shots):
        p = int(solve.next_batch(sol.unshot, h.patch_area, 1)[0])
        ids, f = shooting.shoot_rows(ctx, [p])[0]
        for t, (B, U) in states.items():
            dB = U[p].copy()
            U[p] = 0
            scale = (f * (h.patch_area[p] / h.elem_area[ids])).astype(t)
            delta = rho[ids].astype(t) * (scale[:, None] * dB[None, :])
            B[ids] += delta
            w = h.elem_area[ids] / h.patch_area[h.elem_patch[ids]]
            # one shot's sum per patch in float64; the accumulation over shots is in `t`
            part = (delta * w[:, None]).astype(np.float64)
            for c in range(3):
                U[:, c] += np.bincount(h.elem_patch[ids], weights=part[:, c],
                                       minlength=h.n_patches).astype(t)
        solve.apply_shot(h, rho, sol, p, ids, f)
    ref = states[np.longdouble][0]
    scale = float(np.abs(ref).max())
    return {
        "elements": h.n_elements, "shots": n_shots,
        "float64": float(np.abs(sol.radiosity - ref).max() / scale),
        "float32": float(np.abs(states[np.float32][0] - ref).max() / scale),
    }


def copy_tree(src: Path, dst: Path) -> None:
    shutil.copytree(src, dst, dirs_exist_ok=True)


# --- 7. big inputs (issue 13) ---------------------------------------------------------------

def disc_obj(directory: Path, n: int, star: bool = False) -> Path:
    """An OBJ: one face of ``n`` corners on the unit circle in the floor plane ``y = 0``,
    facing up (a star alternating radii 1 and 0.9 when ``star``), under a 2 × 2 lamp at
    ``y = 2`` facing down."""
    a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    r = np.where(np.arange(n) % 2, 0.9, 1.0) if star else np.ones(n)
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "disc.mtl").write_text("newmtl lamp\nKd 0.5 0.5 0.5\nKe 1 1 1\n"
                                        "newmtl floor\nKd 0.5 0.5 0.5\n")
    lines = ["mtllib disc.mtl", "usemtl floor"]
    lines += [f"v {x:.17g} 0 {z:.17g}" for x, z in zip(r * np.cos(a), -r * np.sin(a), strict=True)]
    lines += ["v -1 2 -1", "v 1 2 -1", "v 1 2 1", "v -1 2 1"]
    lines += ["f " + " ".join(str(i + 1) for i in range(n)), "usemtl lamp",
              f"f {n + 1} {n + 4} {n + 3} {n + 2}"]
    path = directory / "disc.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


def big_polygon_case(directory: Path, n: int = 10_000) -> list[Result]:
    """Load and mesh (default sizes) a convex face of ``n`` corners: time, element count and
    area against the exact ``n/2 · sin(2π/n)`` (measured before issue 13: 806,644 elements
    and 462 s for ``n = 10⁴``)."""
    import time

    from daskrad.scene import load_scene

    path = disc_obj(directory, n)
    start = time.perf_counter()
    scene = load_scene(path)
    h = build_hierarchy(scene)
    seconds = time.perf_counter() - start
    disc = scene.polygon_material[h.elem_polygon] == 0   # material rows in order of first use
    area = float(h.elem_area[disc].sum())
    exact = 0.5 * n * math.sin(2.0 * math.pi / n)
    name = f"polygon of {n:,} corners"
    return [
        Result(name, "elements per corner", float(disc.sum()) / n, 2.0,
               note=f"{int(disc.sum()):,} elements"),
        Result(name, "meshed area vs exact (relative)", abs(area / exact - 1.0), 1e-12),
        Result(name, "seconds to load and mesh", seconds, 60.0),
    ]


def coplanar_soup_case(n: int = 100_000) -> list[Result]:
    """:func:`daskrad.scene.overlap.coplanar_overlaps` on ``n`` triangles tiling one plane (no
    overlap) and on ``n`` small triangles scattered in one plane (measured before issue 13:
    10,000 took 14.6 s, 100,000 more than 300 s)."""
    import time

    from daskrad.scene.overlap import coplanar_overlaps

    k = int(math.ceil(math.sqrt(n / 2)))
    i, j = np.divmod(np.arange(k * k), k)
    corner = np.column_stack([i / k, j / k, np.zeros(k * k)])
    d = 1.0 / k
    v = np.concatenate([corner, corner + [d, 0, 0], corner + [d, d, 0], corner + [0, d, 0]])
    m = np.arange(k * k)
    tiles = np.concatenate([np.stack([m, m + k * k, m + 2 * k * k], axis=1),
                            np.stack([m, m + 2 * k * k, m + 3 * k * k], axis=1)])[:n]
    rng = np.random.default_rng(13)
    centre = rng.random((n, 2))
    angle = rng.random(n)[:, None] * 2 * math.pi + np.array([0.0, 2.1, 4.2])
    pts = centre[:, None, :] + 1e-3 * np.stack([np.cos(angle), np.sin(angle)], axis=-1)
    scattered = np.concatenate([pts.reshape(-1, 2), np.zeros((3 * n, 1))], axis=1)
    out = []
    for name, verts, tris in ((f"{n:,} triangles tiling a plane", v, tiles),
                              (f"{n:,} small triangles scattered in a plane", scattered,
                               np.arange(3 * n).reshape(n, 3))):
        polys = np.column_stack([tris, np.full(len(tris), -1)])
        diag = float(np.linalg.norm(verts.max(axis=0) - verts.min(axis=0)))
        start = time.perf_counter()
        pairs = coplanar_overlaps(verts, polys, diag)
        seconds = time.perf_counter() - start
        out.append(Result(name, "seconds for the coplanar-overlap check", seconds, 30.0,
                          note=f"{len(pairs):,} overlapping pairs"))
        if "tiling" in name:
            out.append(Result(name, "overlapping pairs found in a tiling", float(len(pairs)),
                              0.0))
    return out
