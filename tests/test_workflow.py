"""The radiosity workflow through the command line (issue 15) and a store you can trust (issue
13, item 2): continue with other stopping criteria, re-render a finished store, export the baked
lighting, read the store with xarray; every damage or change a resume, render or export meets
is one line and exit code 2, and leaves the store as it was.

The scene is the Cornell box meshed coarsely (1,905 elements, 576 shots to a relative unshot
RMS of 0.01): a run takes about a second once the kernels are compiled. Comparisons of images
and solutions are exact: a continued run applies exactly the shots of a straight one, and a
re-render reads back the very context the run's image was rendered from.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from daskrad import cli
from daskrad.io import read_exr
from tests.helpers import assert_same_run

REPO = Path(__file__).resolve().parent.parent
SCENE = REPO / "scenes" / "cornell_box.obj"
COARSE = ["--element-size", "80", "--patch-size", "160", "--width", "48", "--height", "48",
          "--workers", "0", "-q", "--checkpoint-every", "2"]


def daskrad(capsys, *args) -> tuple[int, str, str]:
    """``daskrad ARGS`` in this process: ``(exit code, stdout, stderr)``."""
    capsys.readouterr()
    code = cli.main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def solve(capsys, out: Path, *extra, scene: Path = SCENE) -> dict:
    code, _, err = daskrad(capsys, "run", scene, "-o", out, *COARSE, *extra)
    assert code == 0, err
    return json.loads(out.with_suffix(".json").read_text())


def tree(path: Path) -> dict[str, bytes]:
    """Every file under ``path`` with its bytes (a store "left as it was" is this, equal)."""
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*"))
            if p.is_file()}


def one_line_error(code: int, err: str, *fragments: str) -> None:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("daskrad: error: "), err
    for f in fragments:
        assert f in lines[0], (f, lines[0])


@pytest.fixture(scope="module")
def straight(tmp_path_factory) -> Path:
    """A straight run to a relative unshot RMS of 0.01 (the bits continued runs must give)."""
    out = tmp_path_factory.mktemp("straight") / "straight.exr"
    assert cli.main(["run", str(SCENE), "-o", str(out), *COARSE, "--tolerance", "0.01"]) == 0
    return out


def copy_run(src: Path, dst_dir: Path, name: str = "copy") -> Path:
    """The run ``src`` (.exr) copied to ``dst_dir/name.*`` (store included)."""
    dst = dst_dir / f"{name}.exr"
    for suffix in (".exr", ".png", ".json"):
        shutil.copy(src.with_suffix(suffix), dst.with_suffix(suffix))
    shutil.copytree(src.with_suffix(".zarr"), dst.with_suffix(".zarr"))
    return dst


def root_attrs(store: Path) -> dict:
    return json.loads((store / "zarr.json").read_text())["attributes"]


# --- 1. continue with other stopping criteria --------------------------------------------------

def test_a_smaller_tolerance_continues_a_finished_store_to_the_straight_runs_bits(
        straight, tmp_path, capsys):
    out = tmp_path / "refined.exr"
    preview = solve(capsys, out, "--tolerance", "0.05")
    assert preview["converged"] and preview["iterations"] < 576
    refined = solve(capsys, out, "--tolerance", "0.01", "--resume")
    assert refined["converged"]
    assert_same_run(straight, out)
    # continued, not started again: the history up to the checkpoint it continued from is the
    # preview's own, wall-clock seconds included
    kept = [h for h in refined["unshot_rms_history"] if h in preview["unshot_rms_history"]]
    assert len(kept) >= len(preview["unshot_rms_history"]) - 2 > 0


def test_a_finished_store_continues_from_the_state_one_batch_before_its_end(tmp_path, capsys):
    # checkpoints are at most one per 5 s, so a short run's last timed one is early; the
    # state before the final batch is kept in memory and written at the end instead
    out = tmp_path / "short.exr"
    report = solve(capsys, out, "--tolerance", "0.05")
    attrs = root_attrs(out.with_suffix(".zarr"))
    slot = json.loads((out.with_suffix(".zarr") / "internal" / "checkpoint"
                       / str(attrs["continue"]) / "zarr.json").read_text())["attributes"]
    history = report["unshot_rms_history"]
    assert len(history) > 3
    assert slot["iteration"] == history[-2]["iteration"] and slot["open"]
    assert attrs["iteration"] == history[-1]["iteration"] == report["iterations"]


def test_more_iterations_continue_to_the_straight_runs_bits(tmp_path, capsys):
    full = tmp_path / "full.exr"
    report = solve(capsys, full, "--max-iterations", "200")
    assert report["iterations"] == 200 and not report["converged"]
    out = tmp_path / "more.exr"
    solve(capsys, out, "--max-iterations", "100")
    more = solve(capsys, out, "--max-iterations", "200", "--resume")
    assert more["iterations"] == 200
    assert_same_run(full, out)


def test_a_looser_stop_or_an_answer_changing_option_is_refused_and_changes_nothing(
        straight, tmp_path, capsys):
    out = copy_run(straight, tmp_path)
    before = tree(out.with_suffix(".zarr"))
    # a straight run with tolerance 0.1 stops before the store's checkpoints
    code, _, err = daskrad(capsys, "run", SCENE, "-o", out, *COARSE, "--tolerance", "0.1",
                           "--resume")
    one_line_error(code, err, "cannot resume with tolerance=0.1", "run without --resume")
    for option, value, named in (("--batch", "4", "batch=8, this run 4"),
                                 ("--area-method", "rays",
                                  "area_method='hemisphere', this run 'rays'"),
                                 ("--subdivide", "0", "subdivide=0.5, this run 0.0")):
        code, _, err = daskrad(capsys, "run", SCENE, "-o", out, *COARSE, "--tolerance", "0.01",
                               option, value, "--resume")
        one_line_error(code, err, "other settings", named)
    assert tree(out.with_suffix(".zarr")) == before


def test_a_changed_scene_with_the_same_mesh_is_refused(tmp_path, capsys):
    for name in ("cornell_box.obj", "cornell_box.mtl", "cornell_box.toml"):
        shutil.copy(REPO / "scenes" / name, tmp_path / name)
    scene = tmp_path / "cornell_box.obj"
    out = tmp_path / "out.exr"
    solve(capsys, out, "--max-iterations", "40", scene=scene)
    mtl = tmp_path / "cornell_box.mtl"
    text = mtl.read_text()
    assert "Ke 17 12 4" in text
    mtl.write_text(text.replace("Ke 17 12 4", "Ke 34 24 8"))    # twice as bright, same mesh
    before = tree(out.with_suffix(".zarr"))
    code, _, err = daskrad(capsys, "run", scene, "-o", out, *COARSE, "--max-iterations", "80",
                           "--resume")
    one_line_error(code, err, "materials changed")
    assert tree(out.with_suffix(".zarr")) == before
    # the camera is not part of the answer: a new view in the sidecar still resumes
    mtl.write_text(text)
    toml = tmp_path / "cornell_box.toml"
    toml.write_text(toml.read_text().replace("-800.0", "-700.0"))
    solve(capsys, out, "--max-iterations", "80", "--resume", scene=scene)


# --- damaged stores ----------------------------------------------------------------------------

def _slot(store: Path) -> Path:
    return store / "internal" / "checkpoint" / str(root_attrs(store)["checkpoint"])


def _delete_chunk(store: Path) -> str:
    (_slot(store) / "radiosity" / "c" / "0" / "0").unlink()
    return "radiosity is damaged"


def _eight_changed_bytes(store: Path) -> str:
    chunk = _slot(store) / "radiosity" / "c" / "0" / "0"
    data = bytearray(chunk.read_bytes())
    data[800:808] = bytes(255 - b for b in data[800:808])
    chunk.write_bytes(bytes(data))
    return "radiosity is damaged"


def _nan_in_unshot(store: Path) -> str:
    chunk = _slot(store) / "unshot" / "c" / "0" / "0"
    data = bytearray(chunk.read_bytes())               # uncompressed float64
    data[16:24] = np.array([np.nan]).tobytes()
    chunk.write_bytes(bytes(data))
    return "unshot is damaged"


def _root_names_a_half_written_slot(store: Path) -> str:
    attrs = root_attrs(store)
    other = next(s for s in range(3) if s not in (attrs["checkpoint"], attrs.get("continue")))
    slot = store / "internal" / "checkpoint" / str(other)
    if not slot.exists():   # give it arrays of the right shape, but not the attributes' state
        shutil.copytree(_slot(store), slot)
    chunk = slot / "radiosity" / "c" / "0" / "0"
    data = bytearray(chunk.read_bytes())
    data[:8] = np.array([1.5]).tobytes()             # a write that stopped half-way
    chunk.write_bytes(bytes(data))
    meta = json.loads((store / "zarr.json").read_text())
    meta["attributes"]["checkpoint"] = other
    (store / "zarr.json").write_text(json.dumps(meta))
    return "damaged"


def _truncated_chunk(store: Path) -> str:
    chunk = _slot(store) / "direct" / "c" / "0" / "0"
    chunk.write_bytes(chunk.read_bytes()[:100])
    return "cannot read internal/checkpoint"


@pytest.mark.parametrize("damage", [_delete_chunk, _eight_changed_bytes, _nan_in_unshot,
                                    _root_names_a_half_written_slot, _truncated_chunk])
def test_a_damaged_checkpoint_is_refused_with_one_line(straight, tmp_path, capsys, damage):
    out = copy_run(straight, tmp_path)
    store = out.with_suffix(".zarr")
    fragment = damage(store)
    before = tree(store)
    code, _, err = daskrad(capsys, "run", SCENE, "-o", out, *COARSE, "--tolerance", "0.01",
                           "--resume")
    one_line_error(code, err, fragment, str(store))
    assert tree(store) == before


def test_a_truncated_chunk_is_one_line_without_traceback_from_the_shell(straight, tmp_path):
    out = copy_run(straight, tmp_path)
    _truncated_chunk(out.with_suffix(".zarr"))
    done = subprocess.run([sys.executable, "-m", "daskrad", "run", str(SCENE), "-o", str(out),
                           *COARSE, "--tolerance", "0.01", "--resume"],
                          capture_output=True, text=True, cwd=REPO, timeout=600)
    one_line_error(done.returncode, done.stderr, "cannot read internal/checkpoint")


def test_a_deleted_public_chunk_is_refused_by_render_and_repaired_by_resume(
        straight, tmp_path, capsys):
    out = copy_run(straight, tmp_path)
    store = out.with_suffix(".zarr")
    chunk = store / "elements" / "vertices" / "c" / "0" / "0"
    chunk.unlink()
    assert root_attrs(store)["complete"] is True
    code, _, err = daskrad(capsys, "render", store, "-o", tmp_path / "view.exr")
    one_line_error(code, err, "elements/vertices is damaged")
    code, _, err = daskrad(capsys, "export", store, tmp_path / "mesh.ply")
    one_line_error(code, err, "elements/vertices is damaged")
    assert not (tmp_path / "view.exr").exists() and not (tmp_path / "mesh.ply").exists()
    solve(capsys, out, "--tolerance", "0.01", "--resume")
    assert chunk.is_file()
    assert daskrad(capsys, "render", store, "-o", tmp_path / "view.exr")[0] == 0
    # changed bytes in a compressed public chunk: refused too, then repaired the same way
    chunk = store / "elements" / "radiosity" / "c" / "0" / "0"
    data = bytearray(chunk.read_bytes())
    data[len(data) // 2] ^= 0xFF
    chunk.write_bytes(bytes(data))
    code, _, err = daskrad(capsys, "render", store, "-o", tmp_path / "view2.exr")
    one_line_error(code, err, "elements/radiosity")
    solve(capsys, out, "--tolerance", "0.01", "--resume")
    assert daskrad(capsys, "render", store, "-o", tmp_path / "view2.exr")[0] == 0
    np.testing.assert_array_equal(read_exr(tmp_path / "view2.exr"), read_exr(straight))


def test_the_store_builds_only_the_types_it_writes(straight, tmp_path, capsys):
    # a crafted store naming any other callable (here one that would write a file) is refused
    out = copy_run(straight, tmp_path)
    store = out.with_suffix(".zarr")
    meta_file = store / "internal" / "context" / "render" / "zarr.json"
    meta = json.loads(meta_file.read_text())
    victim = tmp_path / "written-by-a-crafted-store"
    meta["attributes"]["meta"] = {"type": "daskrad.io.report:write_report", "fields": {
        "path": {"value": str(victim)}, "report": {"value": {}}}}
    meta_file.write_text(json.dumps(meta))
    code, _, err = daskrad(capsys, "render", store, "-o", tmp_path / "view.exr")
    one_line_error(code, err, "refusing to build 'daskrad.io.report:write_report'")
    assert not victim.exists()


# --- 2. render a finished store ------------------------------------------------------------

def test_render_gives_the_runs_bits_and_leaves_the_store_as_it_was(straight, tmp_path, capsys):
    store = straight.with_suffix(".zarr")
    before = tree(store)
    code, out, err = daskrad(capsys, "render", store, "-o", tmp_path / "view.exr")
    assert code == 0, err
    assert f"wrote {tmp_path / 'view.exr'}" in out
    np.testing.assert_array_equal(read_exr(tmp_path / "view.exr"), read_exr(straight))
    assert (tmp_path / "view.png").read_bytes() == straight.with_suffix(".png").read_bytes()
    assert tree(store) == before
    assert "replaced" not in err
    # the same view again replaces the image, and says so, naming the folder
    code, out, err = daskrad(capsys, "render", store, "-o", tmp_path / "view.exr", "-q")
    assert code == 0, err
    assert err == f"daskrad: replaced the earlier results view.exr, view.png in {tmp_path}\n"


def test_a_log_hears_a_render_every_heartbeat(straight, tmp_path, capsys, monkeypatch):
    # a re-render in a batch job's log said nothing until it ended; -q still says nothing
    from daskrad import progress

    monkeypatch.setattr(progress, "HEARTBEAT_SECONDS", 0.01)
    store = straight.with_suffix(".zarr")
    args = ("render", store, "-o", tmp_path / "view.exr", "--width", "200", "--height", "150")
    code, _, err = daskrad(capsys, *args)
    assert code == 0, err
    beats = [x for x in err.splitlines() if x.startswith("daskrad: ")]
    assert beats and all(re.fullmatch(r"daskrad: \d+:\d\d rendering 200 x 150", x)
                         for x in beats), err
    quiet = ("render", store, "-o", tmp_path / "quiet.exr", "--width", "200", "--height", "150")
    code, _, err = daskrad(capsys, *quiet, "-q")       # a new file: no note of a replaced one
    assert code == 0 and not err.strip(), err


def test_render_with_another_camera_gives_the_bits_of_a_full_run_with_it(straight, tmp_path,
                                                                          capsys):
    view = tmp_path / "view.toml"
    view.write_text('[camera]\neye = [100.0, 400.0, -600.0]\nlook_at = [278.0, 200.0, 280.0]\n'
                    'up = [0.0, 1.0, 0.0]\nfov = 50.0\nwidth = 40\nheight = 30\n')
    full = tmp_path / "full.exr"
    solve(capsys, full, "--tolerance", "0.01", "--config", view, "--width", "40", "--height",
          "30", "--spp", "2")
    store = straight.with_suffix(".zarr")
    code, _, err = daskrad(capsys, "render", store, "-o", tmp_path / "a.exr", "--config", view,
                           "--spp", "2")
    assert code == 0, err
    np.testing.assert_array_equal(read_exr(tmp_path / "a.exr"), read_exr(full))
    # the same camera from options instead of a file
    code, _, err = daskrad(capsys, "render", store, "-o", tmp_path / "b.exr", "--eye",
                           "100,400,-600", "--look-at", "278,200,280", "--fov", "50",
                           "--width", "40", "--height", "30", "--spp", "2")
    assert code == 0, err
    np.testing.assert_array_equal(read_exr(tmp_path / "b.exr"), read_exr(full))


def test_render_with_another_edge_spp_gives_the_bits_of_a_full_run_with_it(straight, tmp_path,
                                                                           capsys):
    # the store keeps the edge threshold (edge_step) with the context, so a re-render at
    # another --edge-spp is what a run with it gives; the default's edge pixels differ
    full = tmp_path / "full.exr"
    solve(capsys, full, "--tolerance", "0.01", "--edge-spp", "16")
    store = straight.with_suffix(".zarr")
    code, _, err = daskrad(capsys, "render", store, "-o", tmp_path / "a.exr", "--edge-spp", "16")
    assert code == 0, err
    np.testing.assert_array_equal(read_exr(tmp_path / "a.exr"), read_exr(full))
    assert np.any(read_exr(full) != read_exr(straight))
    code, _, err = daskrad(capsys, "render", store, "-o", tmp_path / "b.exr", "--edge-spp", "5000")
    one_line_error(code, err, "--edge-spp")


@pytest.mark.parametrize("name", ["x.exr", "x.png", "x.json"])
def test_a_file_daskrad_did_not_write_is_refused_not_replaced(tmp_path, capsys, name):
    # earlier results are replaced (the run says so) only when they say daskrad wrote them
    # (the EXR header's and the PNG's software tag, the report's versions): a user's file of
    # the same name is refused with one line before anything is read or written
    foreign = tmp_path / name
    foreign.write_text("a file of the user's")
    code, _, err = daskrad(capsys, "run", SCENE, "-o", tmp_path / "x.exr", *COARSE)
    one_line_error(code, err, name, "not written by daskrad")
    assert foreign.read_text() == "a file of the user's"
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
    code, _, err = daskrad(capsys, "render", tmp_path / "none.zarr", "-o", tmp_path / "x.exr")
    assert code == 2 and foreign.read_text() == "a file of the user's"


def test_earlier_results_and_exports_of_daskrad_are_replaced_foreign_ones_refused(
        straight, tmp_path, capsys):
    out = copy_run(straight, tmp_path)
    code, _, err = daskrad(capsys, "run", SCENE, "-o", out, *COARSE, "--tolerance", "0.01")
    assert code == 0, err
    assert "replaced the earlier results" in err
    for suffix in (".glb", ".ply", ".obj"):
        mesh = tmp_path / f"m{suffix}"
        args = ("export", straight.with_suffix(".zarr"), mesh)
        assert daskrad(capsys, *args)[0] == 0
        assert daskrad(capsys, *args)[0] == 0          # its own export: replaced
        mesh.write_text("a file of the user's")
        code, _, err = daskrad(capsys, *args)
        one_line_error(code, err, mesh.name, "not written by daskrad")
        assert mesh.read_text() == "a file of the user's"


def test_render_refuses_bad_cameras_and_unfinished_stores(straight, tmp_path, capsys):
    store = straight.with_suffix(".zarr")
    views = tmp_path / "views"
    views.mkdir()
    folder = views.stat().st_mtime_ns
    code, _, err = daskrad(capsys, "render", store, "-o", views / "v.exr", "--eye",
                           "278,273,0", "--look-at", "278,273,0")
    one_line_error(code, err, "same point")
    code, _, err = daskrad(capsys, "render", store, "-o", views / "v.exr", "--width", "100000",
                           "--height", "100000")
    one_line_error(code, err, "--width")
    # refused before the outputs' check probed their folder: nothing made there, nor removed
    assert views.stat().st_mtime_ns == folder and not any(views.iterdir())
    for fov in ("200", "0", "180"):       # the same words either side of the range
        with pytest.raises(SystemExit) as stop:     # argparse's: exit 2 after its line
            daskrad(capsys, "render", store, "-o", tmp_path / "v.exr", "--fov", fov)
        one_line_error(stop.value.code, capsys.readouterr().err, "--fov",
                       f"must be a number of degrees in (0, 180), got {fov}")
    code, _, err = daskrad(capsys, "render", store, "-o", store / "inside.exr")
    one_line_error(code, err, "outside the store")
    code, _, err = daskrad(capsys, "render", tmp_path, "-o", tmp_path / "v.exr")
    one_line_error(code, err, "not a solution store")
    out = copy_run(straight, tmp_path)
    meta = json.loads((out.with_suffix(".zarr") / "zarr.json").read_text())
    meta["attributes"]["complete"] = False
    (out.with_suffix(".zarr") / "zarr.json").write_text(json.dumps(meta))
    code, _, err = daskrad(capsys, "render", out.with_suffix(".zarr"), "-o", tmp_path / "v.exr")
    one_line_error(code, err, "no finished solution", "--resume")


# --- 3. export ---------------------------------------------------------------------------------

def test_export_writes_meshes_with_vertex_radiance_that_trimesh_reads(straight, tmp_path,
                                                                      capsys):
    import trimesh
    import zarr

    from daskrad.io.image import display, srgb8

    store = straight.with_suffix(".zarr")
    before = tree(store)
    root = zarr.open_group(str(store), mode="r")
    vertices = root["vertices"][...]
    radiance = root["vertex_radiance"][...]             # float32 of the stored context's
    faces = None
    for suffix in (".ply", ".glb", ".obj"):
        path = tmp_path / f"baked{suffix}"
        code, out, err = daskrad(capsys, "export", store, path)
        assert code == 0, err
        assert f"wrote {path}" in out
        mesh = trimesh.load(path, process=False, force="mesh")
        assert len(mesh.vertices) == len(vertices)
        np.testing.assert_allclose(mesh.vertices, vertices, rtol=1e-6)   # stored as float32
        faces = mesh.faces if faces is None else faces
        np.testing.assert_array_equal(mesh.faces, faces)
        colours = mesh.visual.vertex_colors[:, :3]
        shown = display(radiance.astype(np.float64))
        if suffix == ".ply":
            raw = mesh.metadata["_ply_raw"]["vertex"]["data"]
            got = np.stack([raw[f"radiance_{c}"] for c in range(3)], axis=1)
            np.testing.assert_array_equal(got, radiance)
            # 8-bit sRGB of the display colour (display() of float32 input vs the float64
            # the export used: one step of 255 at most)
            assert np.abs(colours.astype(int) - srgb8(shown).astype(int)).max() <= 1
        elif suffix == ".glb":
            np.testing.assert_array_equal(mesh.vertex_attributes["_RADIANCE"], radiance)
            # glTF vertex colours are linear (COLOR_0 as normalized bytes)
            assert np.abs(colours.astype(int) - np.round(shown * 255).astype(int)).max() <= 1
        # brighter vertices get brighter colours: the colour follows the radiance
        lum = radiance @ [0.2126, 0.7152, 0.0722]
        lo, hi = np.argmin(lum), np.argmax(lum)
        assert colours[hi].sum() > colours[lo].sum()
    # every exported triangle is one the renderer draws, in its winding
    from daskrad.distributed.store import Result

    np.testing.assert_array_equal(faces, Result(store).render_context().tri_verts)
    assert tree(store) == before
    code, _, err = daskrad(capsys, "export", store, tmp_path / "baked.stl")
    one_line_error(code, err, ".ply, .glb, .obj")


# --- 4. the store as data --------------------------------------------------------------------

def test_every_array_has_dimension_names_units_and_a_description(straight):
    import zarr

    root = zarr.open_group(str(straight.with_suffix(".zarr")), mode="r")
    seen = []

    def walk(group):
        for _, member in group.members():
            if isinstance(member, zarr.Array):
                assert member.metadata.dimension_names is not None, member.path
                assert len(member.metadata.dimension_names) == member.ndim, member.path
                assert "units" in member.attrs and member.attrs["description"], member.path
                assert member.attrs["sha256"], member.path
                seen.append(member.path)
            else:
                walk(member)

    walk(root)
    public = {p for p in seen if not p.startswith("internal/")}
    for name in ("vertices", "elements/radiosity", "elements/emission", "materials/diffuse",
                 "materials/emission", "vertex_radiance", "vertex_radiance_direct",
                 "lights/point_intensity"):
        assert name in public
    assert {p.split("/")[1] for p in seen if p.startswith("internal/")} == {"checkpoint",
                                                                             "context"}
    attrs = root.attrs
    assert set(attrs["camera"]) == {"eye", "look_at", "up", "fov", "width", "height"}
    assert attrs["inputs"].keys() == {"geometry", "materials", "lights"}
    assert list(root["materials"].attrs["names"]) == ["white", "light", "green", "red"]


def test_xarray_opens_the_store(straight):
    xr = pytest.importorskip("xarray")
    store = straight.with_suffix(".zarr")
    ds = xr.open_zarr(store, consolidated=False)
    assert ds["vertex_radiance"].dims == ("vertex", "rgb")
    assert ds["vertex_radiance"].attrs["units"] == "W m-2 sr-1"
    tree_ = xr.open_datatree(store, engine="zarr", consolidated=False)
    el = tree_["elements"].to_dataset()
    assert el["radiosity"].dims == ("element", "rgb")
    assert el.sizes["element"] == json.loads(straight.with_suffix(".json").read_text())[
        "counts"]["elements"]
    # the radiosity arrays are the solution rounded once to float32
    np.testing.assert_array_equal(el["radiosity"].values,
                                  tree_[f"internal/checkpoint/{ds.attrs['checkpoint']}"]
                                  ["radiosity"].values.astype(np.float32))
    mats = tree_["materials"].to_dataset()
    assert float(mats["emission"].values.max()) == 17.0


@pytest.mark.parametrize("chunk", [1 << 30, 4096, 100])
def test_a_context_blob_written_chunk_by_chunk_is_the_joined_one(straight, tmp_path,
                                                                  monkeypatch, chunk):
    """The render context written as the store writes it (each chunk filled from the arrays,
    :func:`write_blob`) and joined into one array first (the benchmark's reference arm): the
    same blob, bit for bit, and the same attributes, its sha256 that of its bytes, whether
    the arrays lie within a chunk or across many (100 bytes: most arrays span several)."""
    import zarr

    from daskrad.distributed import store as st

    ctx = st.Result(straight.with_suffix(".zarr")).render_context()
    monkeypatch.setattr(st, "BLOB_CHUNK", chunk)
    written = {}
    for streamed in (True, False):
        monkeypatch.setattr(st, "STREAM_BLOBS", streamed)
        path = tmp_path / f"streamed{streamed}.zarr"
        store = st.Store(path)
        store.group = zarr.open_group(str(path), mode="w")
        token = store.put_context("render", ctx)
        g = zarr.open_group(str(path), mode="r")["internal/context/render"]
        blob = g["blob"]
        assert blob.chunks == (min(chunk, blob.shape[0]),)
        written[streamed] = (token, blob[...], dict(blob.attrs), dict(g.attrs))
        assert blob.attrs["sha256"] == st.sha256(blob[...])
        back = st.load_context(str(path), "render", token)
        np.testing.assert_array_equal(back.tri_verts, ctx.tri_verts)
        np.testing.assert_array_equal(back.vertex_radiance, ctx.vertex_radiance)
    (t1, b1, a1, g1), (t0, b0, a0, g0) = written[True], written[False]
    assert t1 == t0 and a1 == a0 and g1 == g0
    assert b1.dtype == b0.dtype == np.uint8
    np.testing.assert_array_equal(b1, b0)
    assert b1.shape[0] > 100 * 100        # the 100-byte chunks are many


@pytest.mark.parametrize("chunk", [7, 16, 100])
def test_a_blob_with_zeros_before_between_and_after_its_parts(tmp_path, rng, chunk):
    import zarr

    from daskrad.distributed import store as st

    a = rng.integers(1, 255, 13, dtype=np.uint8)
    b = rng.integers(1, 255, 21, dtype=np.uint8)
    joined = np.zeros(70, np.uint8)
    joined[5:18], joined[40:61] = a, b
    g = zarr.open_group(str(tmp_path / "b.zarr"), mode="w")
    st.write_blob(g, "streamed", [(5, a), (40, b)], 70, chunk=chunk, description="d")
    st.write_array(g, "joined", joined, compress=False, dims=("byte",), chunks=(chunk,),
                   description="d")
    np.testing.assert_array_equal(g["streamed"][...], joined)
    assert dict(g["streamed"].attrs) == dict(g["joined"].attrs)
    assert g["streamed"].attrs["sha256"] == st.sha256(joined)
    assert g["streamed"].chunks == (chunk,) and g["streamed"].metadata.dimension_names == (
        "byte",)


def test_a_blob_in_a_store_in_memory_keeps_every_chunk(rng):
    # zarr hands a whole chunk's buffer to the store without a copy, and a store in memory
    # keeps it: each chunk must be an array of its own
    import zarr
    from zarr.storage import MemoryStore

    from daskrad.distributed import store as st

    a = rng.integers(0, 255, 1000, dtype=np.uint8)
    g = zarr.open_group(MemoryStore(), mode="w")
    st.write_blob(g, "b", [(0, a)], 1000, chunk=100)
    np.testing.assert_array_equal(g["b"][...], a)
    assert g["b"].attrs["sha256"] == st.sha256(a)
    st.write_blob(g, "empty", [], 0, chunk=1)
    assert g["empty"].shape == (0,) and g["empty"].attrs["sha256"] == st.sha256(
        np.zeros(0, np.uint8))

# --- 5. feedback ---------------------------------------------------------------------------------

def test_the_report_names_sizes_versions_camera_store_and_every_warning(tmp_path, capsys):
    out = tmp_path / "r.exr"
    code, stdout, err = daskrad(capsys, "run", SCENE, "-o", out, *COARSE, "--max-iterations",
                                "16", "--exposure", "1.5")
    assert code == 0, err
    assert f"the store {out.with_suffix('.zarr')}" in stdout
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["store"] == str(out.with_suffix(".zarr"))
    assert report["sizes"]["patch_size"] == 160 and report["sizes"]["element_size"] == 80
    assert report["sizes"]["min_element_size"] == 20
    assert set(report["versions"]) >= {"daskrad", "numpy", "numba", "dask", "zarr", "python"}
    assert report["seconds"]["total"] >= sum(v for k, v in report["seconds"].items()
                                             if k != "total")
    assert report["camera"]["width"] == 48 and report["camera"]["fov"] == 39.3077
    printed = [line.removeprefix("daskrad: warning: ") for line in err.splitlines()
               if line.startswith("daskrad: warning: ")]
    assert printed and printed == report["warnings"]
    assert report["settings"]["exposure"] == 1.5
    # --exposure brightens the PNG only (+1.5 stops), never the EXR
    solve(capsys, tmp_path / "plain.exr", "--max-iterations", "16")
    np.testing.assert_array_equal(read_exr(out), read_exr(tmp_path / "plain.exr"))
    from PIL import Image

    bright = np.asarray(Image.open(out.with_suffix(".png")), float).mean()
    plain = np.asarray(Image.open(tmp_path / "plain.png"), float).mean()
    assert bright > plain


def test_a_tolerance_of_zero_shoots_max_iterations_times(tmp_path, capsys):
    # the README's "in [0, 1); 0 shoots --max-iterations times": the command line takes 0 too
    report = solve(capsys, tmp_path / "zero.exr", "--tolerance", "0", "--max-iterations", "24")
    assert report["iterations"] == 24 and not report["converged"]


def test_automatic_sizes_are_reported_as_resolved(tmp_path, capsys):
    out = tmp_path / "auto.exr"
    code, _, err = daskrad(capsys, "run", SCENE, "-o", out, "--width", "32", "--height", "32",
                           "--workers", "0", "-q", "--max-iterations", "8")
    assert code == 0, err
    from daskrad.mesh import default_sizes
    from daskrad.scene import load_scene

    patch, element = default_sizes(load_scene(SCENE))
    sizes = json.loads(out.with_suffix(".json").read_text())["sizes"]
    assert sizes["patch_size"] == patch and sizes["element_size"] == element


def test_the_dashboard_shows_each_phase_with_its_progress_from_the_start(tmp_path,
                                                                         cluster_client):
    from daskrad.distributed.dashboard import phase_html
    from daskrad.distributed.dask_executor import DaskExecutor
    from daskrad.distributed.store import Store
    from daskrad.run import run
    from daskrad.settings import Settings

    settings = Settings(element_size=80, patch_size=160, width=48, height=48, workers=2,
                        max_iterations=64, dashboard="127.0.0.1:0")
    out = tmp_path / "d.exr"
    published = []
    original = DaskExecutor.publish

    def spy(self, key, value):
        if key == "phase":
            published.append(value)
        original(self, key, value)

    DaskExecutor.publish = spy
    try:
        executor = DaskExecutor(cluster_client, Store(out.with_suffix(".zarr"), settings))
        assert published and published[0]["phase"] == "preprocessing"   # before any step
        run(SCENE, out, settings, progress=False, executor=executor)
    finally:
        DaskExecutor.publish = original
    names = [p["phase"] for p in published]
    order = ["preprocessing", "direct light", "shooting", "rendering"]
    assert [n for i, n in enumerate(names) if i == 0 or names[i - 1] != n] == order
    assert all(0.0 <= p["fraction"] <= 1.0 for p in published)
    for name in ("direct light", "rendering"):    # each phase ends at 100 %
        assert [p for p in published if p["phase"] == name][-1]["fraction"] == 1.0
    shooting = [p["fraction"] for p in published if p["phase"] == "shooting"]
    assert shooting == sorted(shooting) and shooting[-1] > 0    # the bar only moves forward
    page = phase_html(published[-1])
    assert "phase: rendering" in page and '<progress value="1.0000" max="1"' in page


# --- 6. the design notes live in the repository --------------------------------------------------

def test_every_design_note_the_code_cites_is_in_docs():
    import re

    sections = set(re.findall(r"^## (\d+)\. ", (REPO / "docs" / "design.md").read_text(), re.M))
    files = [*sorted((REPO / "daskrad").rglob("*.py")), *sorted((REPO / "tests").glob("*.py")),
             *sorted((REPO / "benchmarks").glob("*.py")), *sorted((REPO / "docs").glob("*.md")),
             REPO / "README.md", REPO / "Makefile"]
    cited = set()
    for path in files:
        text = path.read_text()
        # the notes outside the repository, and the old names of these ones (spelt in two
        # pieces so that this file does not contain them)
        for gone in ("../" + "shared/", "DESIGN" + " §", "DESIGN" + ".md", "(STACK" + ".md",
                     " STACK" + ".md", " REFERENCES" + ".md", "(REFERENCES" + ".md"):
            assert gone not in text, (path, gone)
        cited |= set(re.findall(r"docs/design\.md\s+§(\d+)", text))
        for name in re.findall(r"docs/([a-z_]+\.(?:md|png))", text):
            assert (REPO / "docs" / name).is_file(), (path, name)
    assert cited and cited <= sections, cited - sections


def test_the_command_is_main_with_the_exit_collection_skipped(capsys, tmp_path):
    # `daskrad` and `python -m daskrad` run cli.entry: main's exit code, then gc.freeze() so
    # that the interpreter's last collection leaves out what the run made (0.2-0.5 s of a
    # 2.5-3.6 s Cornell box command; bench_speed's start-up table). The console script and
    # __main__ must both go through it.
    import gc
    import tomllib

    scripts = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    assert scripts["daskrad"] == "daskrad.cli:entry"
    assert "sys.exit(entry())" in (REPO / "daskrad" / "__main__.py").read_text()
    before = gc.get_freeze_count()
    try:
        assert cli.entry(["info", str(SCENE)]) == 0
        assert gc.get_freeze_count() > before
        gc.unfreeze()
        assert cli.entry(["run", str(tmp_path / "no-such-scene.obj"), "-o",
                          str(tmp_path / "missing.exr")]) == 2
        assert gc.get_freeze_count() > 0
    finally:
        gc.unfreeze()
    err = capsys.readouterr().err
    assert "no-such-scene.obj" in err
    # the process ends as main says (a smoke test: its outputs are read back)
    out = tmp_path / "c.exr"
    done = subprocess.run([sys.executable, "-m", "daskrad", "run", str(SCENE), "-o", str(out),
                           *COARSE, "--tolerance", "0.05"], capture_output=True, text=True,
                          cwd=REPO, timeout=300)
    assert done.returncode == 0, done.stderr
    report = json.loads(out.with_suffix(".json").read_text())
    assert report["iterations"] > 0 and read_exr(out).shape == (48, 48, 3)


@pytest.mark.parametrize("n", [0, 1, 2, 400, 401, 1000])
def test_the_dashboard_curve_keeps_the_first_and_last_points_once_each(n):
    from daskrad.distributed import monitor

    history = [[8 * (k + 1), 1.0 / (k + 1), 0.01 * k] for k in range(n)]
    points = monitor.curve(history)
    assert len(points) <= monitor.CURVE_POINTS + 1
    assert len(points) == min(n, len({tuple(p) for p in points}))     # no point twice
    iterations = [p[0] for p in points]
    assert iterations == sorted(iterations)
    if n:
        assert points[0] == history[0] and points[-1] == history[-1]
    else:
        assert points == []
