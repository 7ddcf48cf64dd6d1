"""The pipeline as public steps (issue 11): frozen results, one composition, early validation."""

from __future__ import annotations

import dataclasses
import subprocess
import sys

import numpy as np
import pytest

from daskrad import direct, render, solve
from daskrad.distributed.executor import InProcess
from daskrad.errors import OptionError
from daskrad.formfactor import METHODS
from daskrad.io import read_exr
from daskrad.preprocess import preprocess
from daskrad.run import run
from daskrad.scene import box_scene, load_scene
from daskrad.settings import Settings
from tests.conftest import REPO

CORNELL = REPO / "scenes" / "cornell_box.obj"
SMALL = Settings(patch_size=150.0, element_size=75.0, resolution=64, tolerance=1e-2,
                 width=24, height=24, spp=1, workers=0)


@pytest.fixture(scope="module")
def steps():
    """The Cornell box through the five steps, composed by hand."""
    scene = load_scene(CORNELL)
    mesh = preprocess(scene, SMALL)
    light = direct.light(scene, mesh, SMALL, InProcess())
    sol = solve.radiosity(light, SMALL, InProcess())
    image = render.image(scene, light, sol, SMALL, InProcess())
    return scene, mesh, light, sol, image


def test_step_results_are_frozen(steps):
    _, mesh, light, _, image = steps
    for result, field in ((mesh, "grid"), (light, "irradiance"), (image, "pixels")):
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(result, field, None)


def test_run_is_the_composition_of_the_steps(steps, tmp_path):
    # run() adds only observers (store, progress) and the output files: the same bits
    *_, image = steps
    report = run(CORNELL, tmp_path / "c.exr", SMALL, progress=False)
    np.testing.assert_array_equal(read_exr(tmp_path / "c.exr"),
                                  image.pixels.astype(np.float32))
    assert report["counts"]["perpixel_elements"] == image.perpixel_elements


def test_grid_and_triangles_are_built_once_and_carried(steps):
    # the shooters' occluder probes, the ray-cast method and the renderer read the mesh's own
    # grid: no second grid over the same triangles
    scene, mesh, light, _, image = steps
    ex = InProcess()
    solve.radiosity(light, SMALL.replace(max_iterations=1), ex)
    assert ex.shoot_ctx.grid is light.mesh.grid
    assert image.context.grid is light.mesh.grid
    assert light.context is None or light.context.grid is mesh.grid


def test_refined_mesh_rebuilds_its_triangles():
    # a point light over a floor splits elements: the refined mesh's triangles are its own
    scene = box_scene(size=(1.0, 1.0, 1.0), diffuse=0.5, emission_per_face=0.0,
                      point_lights=(np.array([[0.2, 0.5, 0.2]]), np.array([[1.0, 1.0, 1.0]])))
    s = Settings(patch_size=0.5, element_size=0.25, resolution=32)
    mesh = preprocess(scene, s)
    light = direct.light(scene, mesh, s)
    assert light.levels > 0
    refined = light.mesh
    assert refined.hierarchy.n_elements > mesh.hierarchy.n_elements
    h = refined.hierarchy
    assert len(refined.tri_element) == (h.elem_verts[:, 3] >= 0).sum() + h.n_elements
    assert len(light.irradiance) == len(h.vertices)


BAD = {
    "method": dict(method="hemisphre"),
    "area_method": dict(area_method="window"),
    "resolution low": dict(resolution=1),
    "resolution high": dict(resolution=100_000),
    "image": dict(width=100_000, height=100_000),
    "spp": dict(spp=0),
    "tolerance": dict(tolerance=float("nan")),
    "element size": dict(element_size=-1.0),
    "dashboard": dict(dashboard="notaport"),
    "scheduler": dict(scheduler="notanaddress"),
    "edge angle": dict(edge_angle=120.0),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_validate_refuses_bad_settings(case):
    with pytest.raises(OptionError):
        Settings(**BAD[case]).validate()


def test_defaults_are_valid_and_stated_once():
    assert Settings().validate() == Settings()
    assert Settings().method in METHODS
    # the form-factor functions' default resolution is the run's
    from daskrad.formfactor import DEFAULT_RESOLUTION
    assert DEFAULT_RESOLUTION == Settings().resolution
    assert direct.AREA_SAMPLES == Settings().area_samples


@pytest.mark.parametrize("option", [["--method", "hemisphre"], ["--resolution", "100000"],
                                    ["--area-method", "window"],
                                    ["--width", "100000", "--height", "100000"],
                                    ["--dashboard", "notaport"]])
def test_bad_option_fails_at_once_and_leaves_earlier_outputs(tmp_path, option):
    # validated before the scene is loaded and before the old store is touched
    out = tmp_path / "c.exr"
    for suffix, data in ((".exr", b"old image"), (".json", b"{}")):
        out.with_suffix(suffix).write_bytes(data)
    (tmp_path / "c.zarr").mkdir()
    (tmp_path / "c.zarr" / "keep").write_bytes(b"mine")
    proc = subprocess.run([sys.executable, "-m", "daskrad", "run", str(CORNELL), "-o", str(out),
                           "-q", *option], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("daskrad: error:"), proc.stderr
    assert option[0] in lines[0]
    assert out.read_bytes() == b"old image"
    assert (tmp_path / "c.zarr" / "keep").read_bytes() == b"mine"
