"""The pipeline as public steps (issue 11): frozen results, one composition, early validation."""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from daskrad import direct, render, solve
from daskrad.distributed.executor import InProcess
from daskrad.errors import OptionError
from daskrad.formfactor import METHODS
from daskrad.io import read_exr
from daskrad.preprocess import preprocess
from daskrad.run import run, solve_scene
from daskrad.scene import box_scene, load_scene
from daskrad.settings import Settings
from tests.helpers import REPO

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
    # grid: no second grid over the same triangles; the direct pass and the per-pixel pass's
    # shadow rays read the one grid over the polygons, which refinement keeps
    scene, mesh, light, _, image = steps
    ex = InProcess()
    solve.radiosity(light, SMALL.replace(max_iterations=1), ex)
    assert ex.shoot_ctx.grid is light.mesh.grid
    assert image.context.grid is light.mesh.grid
    assert light.mesh.occluders is mesh.occluders
    assert image.context.occluders is mesh.occluders.grid
    assert light.context is None or light.context.grid is mesh.occluders.grid


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
    "tolerance of 1": dict(tolerance=1.0),       # would stop before the first shot
    "element size": dict(element_size=-1.0),
    "dashboard": dict(dashboard="notaport"),
    "scheduler": dict(scheduler="notanaddress"),
    "edge angle": dict(edge_angle=120.0),
    "relaxation low": dict(relaxation=0.9),
    "relaxation high": dict(relaxation=2.0),
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
    assert solve.SAMPLE_SHARE == Settings().sample_share
    assert solve.RELAXATION == Settings().relaxation


@pytest.fixture(scope="module")
def earlier(tmp_path_factory):
    """The results of a finished run (EXR, PNG, JSON, store) in a folder of their own."""
    folder = tmp_path_factory.mktemp("earlier")
    run(CORNELL, folder / "c.exr", SMALL, progress=False)
    return folder


def tree(folder: Path) -> dict:
    """Every file below ``folder`` with its bytes."""
    return {p.relative_to(folder): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def cli_run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "daskrad", "run", str(CORNELL), "-q", *args],
                          capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("option", [["--method", "hemisphre"], ["--resolution", "100000"],
                                    ["--area-method", "window"],
                                    ["--width", "100000", "--height", "100000"],
                                    ["--dashboard", "notaport"],
                                    ["--scheduler", "notanaddress"],
                                    ["--element-size", "0.01"],
                                    ["--processes", "--workers", "0"],
                                    ["--relaxation", "2"], ["--tolerance", "2"]])
def test_bad_option_fails_at_once_and_leaves_earlier_outputs(earlier, tmp_path, option):
    # validated before the scene is loaded and before the old store is touched
    shutil.copytree(earlier, tmp_path / "out")
    before = tree(tmp_path / "out")
    folder = (tmp_path / "out").stat().st_mtime_ns
    proc = cli_run("-o", str(tmp_path / "out" / "c.exr"), *option)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("daskrad: error:"), proc.stderr
    assert option[1] in lines[0]          # the bad value is named
    assert tree(tmp_path / "out") == before
    if option[0] != "--element-size":     # a size needs the scene: checked once it is loaded
        # nothing was even made and removed there (the outputs' writability probe, the lock)
        assert (tmp_path / "out").stat().st_mtime_ns == folder


@pytest.mark.parametrize("kind", ["directory", "file", "symlink"])
def test_a_foreign_store_path_is_refused_and_kept(tmp_path, kind):
    # issue 13: `-o X.exr` with X.zarr not a daskrad store deleted it (the scene itself)
    foreign = tmp_path / "c.zarr"
    if kind == "directory":
        foreign.mkdir()
        (foreign / "scene.obj").write_text("v 0 0 0\n")
    elif kind == "file":
        foreign.write_text("mine")
    else:
        (tmp_path / "target").write_text("mine")
        foreign.symlink_to(tmp_path / "target")
    before = tree(tmp_path)
    proc = cli_run("-o", str(tmp_path / "c.exr"))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "c.zarr" in lines[0] and "not a daskrad solution store" in lines[0]
    assert tree(tmp_path) == before and foreign.is_symlink() == (kind == "symlink")


def test_a_new_run_replaces_earlier_results_and_says_so(earlier, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(earlier, out)
    proc = cli_run("-o", str(out / "c.exr"), "--width", "16", "--height", "16",
                   "--patch-size", "150", "--element-size", "75", "--resolution", "64",
                   "--tolerance", "1e-2", "--spp", "1")
    assert proc.returncode == 0, proc.stderr
    assert f"replaced the earlier results c.exr, c.png, c.json, c.zarr in {out}\n" in proc.stderr
    assert read_exr(out / "c.exr").shape == (16, 16, 3)
    # the new store was swapped in whole; nothing partial is left beside it
    assert [p.name for p in out.iterdir() if p.name.startswith(".")] == []


def test_a_failed_run_keeps_the_earlier_results(earlier, tmp_path, monkeypatch):
    # a failure after solving (here: the renderer) leaves the earlier results as they were
    # and removes its own partial store
    out = tmp_path / "out"
    shutil.copytree(earlier, out)
    before = tree(out)

    def broken(*args, **kwargs):
        raise MemoryError("no room for the image")

    monkeypatch.setattr(render, "image", broken)
    with pytest.raises(MemoryError):
        run(CORNELL, out / "c.exr", SMALL, progress=False)
    assert tree(out) == before


def test_a_second_run_on_the_same_outputs_is_refused(tmp_path):
    from daskrad.output import Outputs

    outputs = Outputs.of(tmp_path / "c.exr")
    with outputs.lock():
        proc = cli_run("-o", str(tmp_path / "c.exr"))
    assert proc.returncode == 2
    assert "another daskrad run is writing these outputs" in proc.stderr
    assert not (tmp_path / "c.exr").exists()


def test_runs_that_end_leave_no_lock_file_and_keep_one_that_is_not_daskrads(tmp_path):
    # a refused run (no store to resume) and a run of a missing scene take and drop the lock
    for scene, args in ((CORNELL, ["--resume"]), (tmp_path / "none.obj", [])):
        proc = subprocess.run([sys.executable, "-m", "daskrad", "run", str(scene), "-q",
                               "-o", str(tmp_path / "c.exr"), *args],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == 2, proc.stderr
        assert list(tmp_path.iterdir()) == [], proc.stderr
    # a file of the lock's name with bytes in it is the user's: used, never removed
    (tmp_path / ".c.lock").write_text("mine")
    from daskrad.output import Outputs

    with Outputs.of(tmp_path / "c.exr").lock():
        pass
    assert (tmp_path / ".c.lock").read_text() == "mine"


def test_numbers_too_large_for_float64_are_one_line(tmp_path):
    # issue 13: Ke 1e308 gave an all-NaN image and exit 0
    body = (REPO / "scenes" / "cornell_box.obj").read_text()
    mtl = (REPO / "scenes" / "cornell_box.mtl").read_text()
    import re

    (tmp_path / "s.obj").write_text(body.replace("cornell_box.mtl", "s.mtl"))
    (tmp_path / "s.mtl").write_text(re.sub(r"Ke [0-9. ]+", "Ke 1e308 1e308 1e308", mtl))
    proc = subprocess.run([sys.executable, "-m", "daskrad", "run", str(tmp_path / "s.obj"),
                           "-o", str(tmp_path / "s.exr"), "-q"], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "s.obj" in lines[0] and "Ke" in lines[0], proc.stderr
    assert not (tmp_path / "s.exr").exists() and not (tmp_path / "s.zarr").exists()
    assert not list(tmp_path.glob(".s.zarr.partial"))


def test_a_scene_far_from_the_origin_renders_as_at_the_origin(tmp_path):
    # issue 13: a unit box moved to 1e12 came out 8 % off; in coordinates relative to its
    # centre it is the same scene
    def box(offset):
        return box_scene(size=(1.0, 1.0, 1.0), diffuse=0.5,
                         emission_per_face=[0, 0, 0, 1, 0, 0], origin=offset)

    s = Settings(patch_size=0.5, element_size=0.25, resolution=32, tolerance=1e-3)
    near = solve_scene(box(np.zeros(3)), s).solution.radiosity
    far = solve_scene(box(np.full(3, 1e12)), s).solution.radiosity
    np.testing.assert_allclose(far, near, rtol=1e-6, atol=0)
    assert box(np.zeros(3)).origin.tolist() == [0.0, 0.0, 0.0]
    assert box(np.full(3, 1e12)).origin.tolist() == [1e12, 1e12, 1e12]


def test_an_output_on_a_special_file_system_is_one_line(tmp_path):
    proc = cli_run("-o", "/proc/out.exr")
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    # the directory given, not a hidden file daskrad would have made in it (its lock)
    assert lines == [lines[0]] and lines[0].startswith(
        "daskrad: error: /proc: cannot write in this directory ("), proc.stderr


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs Linux's /proc")
def test_every_output_in_a_directory_that_refuses_files_names_the_directory(tmp_path):
    # root may "access" /proc for writing, yet no file can be made there: the check makes one
    from daskrad.io.mesh import write_mesh
    from daskrad.output import Outputs

    tri = (np.eye(3), np.array([[0, 1, 2]]), np.ones((3, 3)))
    for attempt in (lambda: Outputs.of("/proc/x.exr"),
                    lambda: write_mesh("/proc/e.ply", *tri)):
        with pytest.raises(OptionError) as info:
            attempt()
        assert info.value.path == "/proc"
        assert info.value.message.startswith("cannot write in this directory (")
    afile = tmp_path / "x.obj"
    afile.write_text("")
    with pytest.raises(OptionError, match="not a directory for the output"):
        Outputs.of(afile / "a.exr")
    with pytest.raises(OptionError, match="no such directory for the export"):
        write_mesh(tmp_path / "none" / "e.ply", *tri)
    Outputs.of(tmp_path / "ok.exr")             # a directory that takes files: probed
    write_mesh(tmp_path / "ok.ply", *tri)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ok.ply", "x.obj"]   # no probe left


def test_a_full_disk_is_one_line_and_leaves_nothing_half_written(earlier, tmp_path, capsys,
                                                                 monkeypatch):
    import errno

    import OpenEXR

    from daskrad import cli

    out = tmp_path / "out"
    shutil.copytree(earlier, out)
    before = tree(out)

    real = OpenEXR.File

    class Full:
        """A full disk for writes; reads (the check that the earlier image is daskrad's) see
        the real file."""

        def __new__(cls, *args, **kwargs):
            if len(args) == 1:
                return real(*args, **kwargs)
            return super().__new__(cls)

        def __init__(self, *args, **kwargs):
            pass

        def write(self, path):
            Path(path).write_bytes(b"half")          # what a full disk leaves
            raise OSError(errno.ENOSPC, "No space left on device", path)

    monkeypatch.setattr(OpenEXR, "File", Full)
    code = cli.main(["run", str(CORNELL), "-o", str(out / "c.exr"), "-q", "--width", "24",
                     "--height", "24", "--patch-size", "150", "--element-size", "75",
                     "--resolution", "64", "--tolerance", "1e-2", "--spp", "1"])
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "No space left on device" in err[0]
    after = tree(out)
    # the earlier image is untouched and no temporary image is left; the store was swapped in
    assert after[Path("c.exr")] == before[Path("c.exr")]
    assert not [p for p in after if ".partial" in str(p)]


def test_a_dashboard_open_to_the_network_is_said(tmp_path, capsys):
    # issue 13: --dashboard 0.0.0.0:PORT bound every interface while printing a 127.0.0.1 link
    run(CORNELL, tmp_path / "c.exr", SMALL.replace(workers=2, dashboard="0.0.0.0:0"),
        progress=False)
    err = capsys.readouterr().err
    assert "daskrad: warning: the dashboard listens on 0.0.0.0 (0.0.0.0:0)" in err
    run(CORNELL, tmp_path / "d.exr", SMALL.replace(workers=2, dashboard="127.0.0.1:0"),
        progress=False)
    err = capsys.readouterr().err
    assert "dashboard listens" not in err and "was in use" not in err and "daskrad: dash" in err


def test_a_busy_dashboard_port_is_one_line_naming_it(tmp_path, capsys, recwarn):
    # Dask serves the dashboard on another port and warned in several lines of its own
    import socket

    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        run(CORNELL, tmp_path / "c.exr",
            SMALL.replace(workers=2, dashboard=f"127.0.0.1:{port}"), progress=False)
    err = capsys.readouterr().err
    line, = [x for x in err.splitlines() if x.startswith("daskrad: dashboard")]
    assert line.endswith(f"/daskrad; port {port} was in use)"), err
    assert f":{port}/" not in line
    assert "already in use" not in err
    assert not [w for w in recwarn if "already in use" in str(w.message)]


def test_a_resume_with_a_relative_output_keeps_its_store(tmp_path):
    # a resumed run solves in its finished store, named relatively on the command line and
    # absolutely inside: it must not be swapped out for itself (found trying the README)
    small = ["--width", "16", "--height", "16", "--patch-size", "150", "--element-size",
             "75", "--resolution", "64", "--spp", "1", "-q"]

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "daskrad", "run", str(CORNELL), "-o",
                               "c.exr", *small, *args], capture_output=True, text=True,
                              timeout=300, cwd=tmp_path,
                              env={**os.environ, "PYTHONPATH": str(REPO)})

    first = cli("--tolerance", "1e-2")
    assert first.returncode == 0, first.stderr
    shots = json.loads((tmp_path / "c.json").read_text())["iterations"]
    assert json.loads((tmp_path / "c.json").read_text())["resumed_from"] is None
    again = cli("--tolerance", "5e-3", "--resume")
    assert again.returncode == 0, again.stderr
    from daskrad.output import is_store

    assert is_store(tmp_path / "c.zarr")
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    report = json.loads((tmp_path / "c.json").read_text())
    assert report["converged"] and report["unshot_rms_history"][-1]["relative_unshot_rms"] <= 5e-3
    # continued from the last state of the first run a straight run passes through (its stop
    # inside a batch is not one: the batch is applied whole in a longer run)
    assert 0 < report["resumed_from"] <= shots < report["iterations"]


def test_a_log_hears_the_step_now_running_every_heartbeat(tmp_path, monkeypatch):
    # a stderr that is a file (a batch job's log) heard nothing from the start of a furnished
    # room's run to its end: now a line every HEARTBEAT_SECONDS names the step running
    import io
    import re

    from daskrad import progress
    from daskrad.solve import Solution

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    steps = [r"loading and meshing the scene", r"direct light at [\d,]+ vertices",
             r"shooting: shot [\d,]+, relative unshot RMS \d\.\de[-+]\d\d \(tolerance 0\.001\)",
             rf"rendering {SMALL.width} x {SMALL.height}", r"writing the image and the report",
             r"done: [\d,]+ shots, (not )?converged"]
    monkeypatch.setattr(progress, "HEARTBEAT_SECONDS", 0.02)
    for err, progress_on, heard in ((io.StringIO(), True, True), (io.StringIO(), False, False),
                                    (Terminal(), True, False)):
        monkeypatch.setattr(sys, "stderr", err)
        run(CORNELL, tmp_path / "c.exr", SMALL.replace(tolerance=1e-3), progress=progress_on)
        beats = [x for x in err.getvalue().replace("\r", "\n").splitlines()
                 if re.match(r"daskrad: \d+:\d\d ", x)]
        assert bool(beats) == heard, err.getvalue()
        # each line names a step of the pipeline, in the pipeline's order
        order = []
        for line in beats:
            status = line.split(" ", 2)[2]
            kinds = [k for k, pattern in enumerate(steps) if re.fullmatch(pattern, status)]
            assert kinds, line
            order.append(kinds[0])
        assert order == sorted(order), beats
        if heard:       # the log's last line is how the run ended
            assert re.fullmatch(r"daskrad: \d+:\d\d done: [\d,]+ shots, converged", beats[-1])

    # the solve's status follows its last batch; closed, the heartbeat says no more
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    beat = progress.Heartbeat(True, seconds=0.005)
    beat.shots(Solution(radiosity=None, direct=None, unshot=None, initial_rms=1.0,
                        history=[(4120, 3.14e-3, 9.0)]), 1e-3)
    shooting = " shooting: shot 4,120, relative unshot RMS 3.1e-03 (tolerance 0.001)"
    for _ in range(400):
        if shooting in err.getvalue():
            break
        time.sleep(0.005)
    beat.close()
    said = err.getvalue()
    assert said.splitlines()[-1].endswith(shooting), said
    time.sleep(0.03)
    assert err.getvalue() == said
    # the tolerance as given, not rounded to a power of ten
    beat.shots(Solution(radiosity=None, direct=None, unshot=None, initial_rms=1.0,
                        history=[(8, 0.5, 0.1)]), 2.5e-3)
    assert beat.status.endswith("(tolerance 0.0025)"), beat.status


def test_info_counts_in_words_that_agree(capsys):
    from daskrad import cli

    assert cli.main(["info", str(CORNELL)]) == 0
    out = capsys.readouterr().out
    assert "\nemitters    1 polygon\n" in out, out          # the box's one light


def test_a_terminal_hears_each_long_step_as_it_starts(tmp_path, monkeypatch):
    # the direct pass and the render (tens of seconds in a furnished room) each say they
    # start, on a terminal, before and after the solve's bar; a log file and -q hear nothing
    import io

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    from daskrad import progress as progress_module

    monkeypatch.setattr(progress_module, "HEARTBEAT_SECONDS", 1e6)   # a log's beats: elsewhere
    for tty, progress, heard in ((True, True, True), (False, True, False), (True, False, False)):
        err = Terminal() if tty else io.StringIO()
        monkeypatch.setattr(sys, "stderr", err)
        run(CORNELL, tmp_path / "c.exr", SMALL, progress=progress)
        lines = [x for x in err.getvalue().replace("\r", "\n").splitlines()
                 if x.startswith("daskrad: ") and "replaced" not in x]
        expected = ["daskrad: direct light at", f"daskrad: rendering {SMALL.width} x "
                    f"{SMALL.height}"] if heard else []
        assert [x[:len(e)] for x, e in zip(lines, expected, strict=True)] == expected, lines
        if heard:
            assert lines[0].endswith(" vertices"), lines
    # a resume's note comes before the bar, which draws its line as it is made
    err = Terminal()
    monkeypatch.setattr(sys, "stderr", err)
    run(CORNELL, tmp_path / "c.exr", SMALL, progress=True, resume=True)
    lines = err.getvalue().replace("\r", "\n").splitlines()
    assert [x for x in lines if "resuming" in x][0].startswith("daskrad: resuming from shot ")


def test_a_dashboard_asked_of_an_in_process_run_is_said_to_be_unused(tmp_path, capsys):
    # the Cornell box is below the size a cluster pays for: --dashboard alone was ignored
    # without a word
    from daskrad import cli

    args = ["run", str(CORNELL), "-o", str(tmp_path / "c.exr"), "-q", "--width", "32",
            "--height", "32", "--max-iterations", "40"]
    assert cli.main([*args, "--dashboard", "127.0.0.1:0"]) == 0
    err = capsys.readouterr().err
    assert ("daskrad: warning: --dashboard 127.0.0.1:0 was not used: the run stayed in "
            "this process, with no Dask cluster (give --workers N for one)") \
        in err.splitlines(), err
    assert cli.main(args) == 0 and "--dashboard" not in capsys.readouterr().err
