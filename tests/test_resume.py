"""Nothing lost (issue 4, item 7): a client killed or interrupted mid-run leaves its last
checkpoint in ``OUT.zarr``, and ``--resume`` finishes to the same bits as a run never stopped.

Comparisons are exact: the checkpoint holds the solver state in float64 together with the
batches already chosen (``Solution.queued``), so a resumed run applies exactly the shots the
uninterrupted one applied.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from daskrad.distributed.dask_executor import DaskExecutor
from daskrad.distributed.store import FORMAT, Store
from daskrad.errors import OptionError, Terminated
from daskrad.io import read_exr
from daskrad.output import Outputs
from daskrad.run import run
from daskrad.settings import Settings
from tests.helpers import CORNELL, assert_same_run

# Long enough (60 batches of 8) that the client is still shooting when its first checkpoint
# (after batch 8) appears, short enough to keep each run to a few seconds.
SETTINGS = Settings(max_iterations=480, width=64, height=64)
ARGS = ["--max-iterations", "480", "--width", "64", "--height", "64", "-q"]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("full") / "full.exr"
    run(CORNELL, path, SETTINGS, progress=False)
    return path


def _root_attrs(store: Path) -> dict:
    try:  # zarr replaces zarr.json atomically: a read sees the old or the new file
        return json.loads((store / "zarr.json").read_text()).get("attributes", {})
    except (FileNotFoundError, json.JSONDecodeError):
        return {}


def _default_signals() -> None:
    # SIGINT and SIGTERM at their defaults in the child (Python raises KeyboardInterrupt, and
    # the CLI installs its SIGTERM handler, only then), even when the test runner was started
    # with them ignored (a background job of a shell)
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _start_and_stop_after_first_checkpoint(out: Path, sig: int) -> subprocess.CompletedProcess:
    # SIGINT at its default in the child (Python raises KeyboardInterrupt only then), even
    # when the test runner was started with it ignored (a background job of a shell)
    proc = subprocess.Popen([sys.executable, "-m", "daskrad", "run", str(CORNELL), "-o",
                             str(out), "--workers", "0", *ARGS],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=_default_signals)
    store = Outputs(out).partial         # a new run solves beside the earlier results
    end = time.monotonic() + 120
    while "checkpoint" not in _root_attrs(store):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < end, "no checkpoint appeared"
        time.sleep(0.02)
    proc.send_signal(sig)
    stdout, stderr = proc.communicate(timeout=60)
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)


def test_sigkill_then_resume_on_a_cluster_gives_the_same_bits(uninterrupted, tmp_path,
                                                              cluster_client):
    out = tmp_path / "killed.exr"
    killed = _start_and_stop_after_first_checkpoint(out, signal.SIGKILL)
    assert killed.returncode == -signal.SIGKILL
    attrs = _root_attrs(Outputs(out).partial)
    assert 0 < attrs["iteration"] < SETTINGS.max_iterations and "complete" not in attrs
    assert not out.exists()
    # resume with 2 workers where the killed run had none: the bits do not depend on it
    store = Store(Outputs(out).working_store(resume=True), SETTINGS.replace(workers=2),
                  resume=True)
    report = run(CORNELL, out, SETTINGS.replace(workers=2), progress=False, resume=True,
                 executor=DaskExecutor(cluster_client, store))
    assert report["iterations"] == SETTINGS.max_iterations
    # the history continues the killed run's (same batches, same RMS values)
    assert report["unshot_rms_history"][0]["iteration"] == 8
    assert_same_run(uninterrupted, out)


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"),
                                            (signal.SIGTERM, 143, "terminated")],
                         ids=["ctrl-c", "sigterm"])
def test_ctrl_c_or_sigterm_then_resume_from_the_command_line(uninterrupted, tmp_path, sig,
                                                             code, word):
    # SIGTERM (kill, a batch system's stop) stops a run as Ctrl-C does: one line naming the
    # kept checkpoint, the output's lock released, and --resume finishes to the same bits
    out = tmp_path / "interrupted.exr"
    stopped = _start_and_stop_after_first_checkpoint(out, sig)
    assert stopped.returncode == code, stopped.stderr
    shot = _root_attrs(Outputs(out).partial)["iteration"]
    assert stopped.stderr.splitlines()[-1] == (
        f"daskrad: {word}; the last checkpoint (shot {shot:,}) is kept (use --resume)")
    assert "Traceback" not in stopped.stderr
    assert not (tmp_path / ".interrupted.lock").exists()
    resumed = subprocess.run([sys.executable, "-m", "daskrad", "run", str(CORNELL), "-o",
                              str(out), "--workers", "0", "--resume", *ARGS],
                             capture_output=True, text=True, timeout=240)
    assert resumed.returncode == 0, resumed.stderr
    assert_same_run(uninterrupted, out)


@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"),
                                            (signal.SIGTERM, 143, "terminated")],
                         ids=["ctrl-c", "sigterm"])
def test_ctrl_c_in_a_terminal_with_worker_processes_is_one_line(uninterrupted, tmp_path, sig,
                                                                code, word):
    # a terminal's Ctrl-C reaches every process of the group: the worker processes ignore it
    # (no traceback of theirs) and the client says what is kept, once; a batch system's
    # SIGTERM to the group (scancel, systemd) stops it the same way; then --resume on worker
    # processes finishes to the same bits
    out = tmp_path / "group.exr"
    args = [sys.executable, "-m", "daskrad", "run", str(CORNELL), "-o", str(out),
            "--workers", "2", "--processes", "--dashboard", "127.0.0.1:0", *ARGS]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True,
                            preexec_fn=_default_signals)
    store = Outputs(out).partial
    end = time.monotonic() + 180
    while "checkpoint" not in _root_attrs(store):
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < end, "no checkpoint appeared"
        time.sleep(0.02)
    os.killpg(proc.pid, sig)
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == code, stderr
    lines = [line for line in stderr.splitlines() if not line.startswith("daskrad: dashboard")]
    # the line names the shot the kept checkpoint holds
    shot = _root_attrs(store)["iteration"]
    assert lines == [f"daskrad: {word}; the last checkpoint (shot {shot:,}) is kept "
                     "(use --resume)"], stderr
    resumed = subprocess.run([*args, "--resume"], capture_output=True, text=True, timeout=240)
    assert resumed.returncode == 0, resumed.stderr
    assert_same_run(uninterrupted, out)


def test_an_interrupted_run_says_whether_there_is_anything_to_resume(uninterrupted, tmp_path):
    import shutil

    from daskrad.commands import resume_hint

    out = tmp_path / "x.exr"
    assert "store was written: nothing to resume" in resume_hint(str(out))   # before its store
    partial = Outputs(out).partial
    Store(partial, SETTINGS).open()          # a store, but stopped before its first checkpoint
    assert resume_hint(str(out)).endswith("first checkpoint: nothing to resume yet")
    shutil.rmtree(partial)
    shutil.copytree(uninterrupted.with_suffix(".zarr"), partial)     # one with a checkpoint
    assert "--resume" in resume_hint(str(out))


def test_resume_of_a_finished_run_shoots_nothing_more(uninterrupted, tmp_path, capsys):
    import shutil

    out = tmp_path / "again.exr"
    shutil.copytree(uninterrupted.with_suffix(".zarr"), out.with_suffix(".zarr"))
    report = run(CORNELL, out, SETTINGS, progress=True, resume=True)
    assert report["iterations"] == SETTINGS.max_iterations
    # a resume says where it continues from (not under -q, progress=False)
    assert f"daskrad: resuming from shot {SETTINGS.max_iterations:,}\n" in capsys.readouterr().err
    np.testing.assert_array_equal(read_exr(out), read_exr(uninterrupted))


def test_resume_refuses_other_settings_and_a_missing_store(uninterrupted, tmp_path):
    import shutil

    out = tmp_path / "other.exr"
    shutil.copytree(uninterrupted.with_suffix(".zarr"), out.with_suffix(".zarr"))
    with pytest.raises(OptionError, match=r"other settings \(batch=8, this run 4\)"):
        run(CORNELL, out, SETTINGS.replace(batch=4), progress=False, resume=True)
    with pytest.raises(OptionError, match=r"other settings \(relaxation=1\.3, this run 1\.0\)"):
        run(CORNELL, out, SETTINGS.replace(relaxation=1.0), progress=False, resume=True)
    # fewer iterations than the store holds: a straight run would have stopped before it
    with pytest.raises(OptionError, match="cannot resume with .*max_iterations=100"):
        run(CORNELL, out, SETTINGS.replace(max_iterations=100), progress=False, resume=True)
    with pytest.raises(OptionError, match="no solution store"):
        run(CORNELL, tmp_path / "none.exr", SETTINGS, progress=False, resume=True)


def test_looser_criteria_are_refused_before_the_direct_pass(uninterrupted, tmp_path,
                                                            monkeypatch):
    # on a furnished room the refusal came after the direct pass, ~16 s; it needs only the
    # store's last checkpoint and the resolved shot cap
    import shutil

    from daskrad import direct

    def no_direct_pass(*args, **kwargs):
        raise AssertionError("the direct pass ran before the refusal")

    out = tmp_path / "early.exr"
    shutil.copytree(uninterrupted.with_suffix(".zarr"), out.with_suffix(".zarr"))
    before = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*"))
    monkeypatch.setattr(direct, "light", no_direct_pass)
    for looser in (SETTINGS.replace(max_iterations=100), SETTINGS.replace(tolerance=0.5)):
        with pytest.raises(OptionError, match="cannot resume with .* are past where"):
            run(CORNELL, out, looser, progress=False, resume=True)
    assert sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*")) == before


def _older_store(uninterrupted: Path, tmp_path: Path, drop: tuple, fmt: str):
    """``(out, its store's zarr.json)``: a copy of the uninterrupted run's store as an older
    daskrad wrote it, without the settings ``drop`` and marked format ``fmt``."""
    import shutil

    out = tmp_path / "older.exr"
    shutil.copytree(uninterrupted.with_suffix(".zarr"), out.with_suffix(".zarr"))
    meta = out.with_suffix(".zarr") / "zarr.json"
    doc = json.loads(meta.read_text())
    for name in drop:
        del doc["attributes"]["settings"][name]
    doc["attributes"]["format"] = fmt
    meta.write_text(json.dumps(doc))
    return out, meta


def _format(meta: Path) -> str:
    return json.loads(meta.read_text())["attributes"]["format"]


def test_a_store_from_before_sample_share_resumes_with_every_shot_sampled(uninterrupted,
                                                                          tmp_path):
    # a store written before --sample-share (and before --relaxation) was solved with every
    # row sampled (share 0) and plain shots: it resumes with --sample-share 0 --relaxation 1,
    # and another share is refused by name
    out, meta = _older_store(uninterrupted, tmp_path, ("sample_share", "relaxation"),
                             "daskrad-solution/3")          # a format it does not read
    older = SETTINGS.replace(sample_share=0.0, relaxation=1.0)
    with pytest.raises(OptionError, match="format 'daskrad-solution/3', this daskrad reads"):
        run(CORNELL, out, older, progress=False, resume=True)
    doc = json.loads(meta.read_text())
    doc["attributes"]["format"] = "daskrad-solution/4"
    meta.write_text(json.dumps(doc))
    with pytest.raises(OptionError, match=r"other settings \(sample_share=0\.0, this run 0\.03\)"):
        run(CORNELL, out, older.replace(sample_share=0.03), progress=False, resume=True)
    # refused: left as it was, a format-4 store an older daskrad still reads
    assert _format(meta) == "daskrad-solution/4"
    report = run(CORNELL, out, older, progress=False, resume=True)
    assert report["iterations"] == SETTINGS.max_iterations
    # resumed by this daskrad, it may hold one-point rows' keys now: marked format 6
    assert _format(meta) == FORMAT
    np.testing.assert_array_equal(read_exr(out), read_exr(uninterrupted))


def test_a_store_from_before_overshooting_resumes_with_plain_shots(uninterrupted, tmp_path):
    # a format-5 store was solved with plain progressive refinement (relaxation 1): it
    # resumes only with --relaxation 1, and is marked 6 once resumed
    out, meta = _older_store(uninterrupted, tmp_path, ("relaxation",), "daskrad-solution/5")
    with pytest.raises(OptionError, match=r"other settings \(relaxation=1\.0, this run 1\.3\)"):
        run(CORNELL, out, SETTINGS, progress=False, resume=True)
    assert _format(meta) == "daskrad-solution/5"
    report = run(CORNELL, out, SETTINGS.replace(relaxation=1.0), progress=False, resume=True)
    assert report["iterations"] == SETTINGS.max_iterations
    assert _format(meta) == FORMAT == "daskrad-solution/7"
    np.testing.assert_array_equal(read_exr(out), read_exr(uninterrupted))


def _without_row_kind(slot: Path) -> None:
    """Make checkpoint slot ``slot`` (a directory) as format 6 wrote it: no ``row_kind``
    array and no checksum for one, nor for its attributes."""
    import shutil

    shutil.rmtree(slot / "row_kind")
    doc = json.loads((slot / "zarr.json").read_text())
    del doc["attributes"]["sha256"]["row_kind"], doc["attributes"]["state_sha256"]
    (slot / "zarr.json").write_text(json.dumps(doc))


def test_a_store_from_before_row_kinds_continues_and_keeps_them_from_then_on(uninterrupted,
                                                                             tmp_path):
    # a format-6 checkpoint holds no row_kind (the row each patch keeps): a run with more
    # iterations continues from it, choosing the rows of the patches that shot already
    # afresh, and its checkpoints hold row_kind from then on
    out, meta = _older_store(uninterrupted, tmp_path, (), "daskrad-solution/6")
    slots = out.with_suffix(".zarr") / "internal" / "checkpoint"
    for slot in (p for p in slots.iterdir() if p.is_dir()):
        _without_row_kind(slot)
    more = SETTINGS.replace(max_iterations=SETTINGS.max_iterations + 80)
    report = run(CORNELL, out, more, progress=False, resume=True)
    assert report["iterations"] == more.max_iterations
    assert _format(meta) == FORMAT
    last = _root_attrs(out.with_suffix(".zarr"))["checkpoint"]
    import zarr

    kinds = zarr.open_array(slots / str(last) / "row_kind", mode="r")[...]
    assert set(np.unique(kinds)) <= {-1, 0, 1} and (kinds >= 0).sum() > 0


def test_more_iterations_continue_a_finished_run_to_the_straight_runs_bits(uninterrupted,
                                                                            tmp_path):
    # a run stopped at 320 shots and continued to 480 gives the straight run's bits: the
    # continue slot holds each patch's row kind as it was at that state (on this mesh, states
    # from ~230 to ~390 shots continued with only the queued batches' kinds, the others
    # chosen afresh, end with other bits)
    out = tmp_path / "half.exr"
    run(CORNELL, out, SETTINGS.replace(max_iterations=320), progress=False)
    report = run(CORNELL, out, SETTINGS, progress=False, resume=True)
    assert report["iterations"] == SETTINGS.max_iterations
    np.testing.assert_array_equal(read_exr(out), read_exr(uninterrupted))


def test_a_resume_reads_step_2_back_from_the_store_or_computes_it_when_it_is_not_there(
        uninterrupted, tmp_path, monkeypatch):
    # a continued run takes the direct pass and its subdivision from the store (they were
    # most of a furnished room's resume): it computes no vertex's direct light and still ends
    # with the straight run's bits; a store without them (an older daskrad's) has them
    # computed again, to the same bits
    from daskrad import direct

    calls = []
    compute = direct.compute_classes
    monkeypatch.setattr(direct, "compute_classes",
                        lambda *a, **k: calls.append(a[1:3]) or compute(*a, **k))
    for name, kept in (("kept", True), ("gone", False)):
        out = tmp_path / f"{name}.exr"
        run(CORNELL, out, SETTINGS.replace(max_iterations=320), progress=False)
        assert len(calls) > 1          # the vertices, then each level of subdivision
        calls.clear()
        if not kept:
            shutil.rmtree(out.with_suffix(".zarr") / "internal" / "context" / "direct_state")
        report = run(CORNELL, out, SETTINGS, progress=False, resume=True)
        assert 0 < report["resumed_from"] <= 320     # the continue slot
        assert bool(calls) != kept, name
        calls.clear()
        assert_same_run(uninterrupted, out)


def test_a_direct_state_that_does_not_fit_the_mesh_or_this_daskrad_is_computed_again():
    # a state of another mesh (other element sizes), or of a daskrad whose direct pass
    # differs (another STATE_VERSION), is not taken: step 2 runs and gives its own answer
    from daskrad import direct
    from daskrad.preprocess import preprocess
    from daskrad.scene import load_scene

    scene = load_scene(CORNELL)
    settings = Settings(element_size=60.0, patch_size=120.0)
    mesh = preprocess(scene, settings)
    own = direct.light(scene, mesh, settings)
    assert own.levels > 0
    coarse = Settings(element_size=90.0, patch_size=180.0)
    other = direct.state_of(direct.light(scene, preprocess(scene, coarse), coarse))
    older = direct.state_of(own)._replace(version=direct.STATE_VERSION - 1)
    for state in (other, older):
        light = direct.light(scene, mesh, settings, state=state)
        assert light.irradiance is not state.irradiance
        np.testing.assert_array_equal(light.irradiance, own.irradiance)
        np.testing.assert_array_equal(light.mesh.hierarchy.vertices,
                                      own.mesh.hierarchy.vertices)
    taken = direct.light(scene, mesh, settings, state=direct.state_of(own))
    assert taken.irradiance is own.irradiance


def _file_digests(root: Path) -> dict[str, str]:
    import hashlib

    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_continuation_stopped_half_way_leaves_the_finished_results_as_they_were(
        uninterrupted, tmp_path, monkeypatch):
    # a finished 320-shot run continued to 480 and stopped at 400: its store, image and
    # report are untouched, byte for byte, and still read as a finished result (render,
    # export); the continuation's own checkpoint is kept, and --resume finishes it to the
    # straight run's bits
    import daskrad.run as pipeline
    from daskrad.distributed import monitor
    from daskrad.distributed.store import Result

    out = tmp_path / "half.exr"
    run(CORNELL, out, SETTINGS.replace(max_iterations=320), progress=False)
    files = [out, out.with_suffix(".png"), out.with_suffix(".json")]
    before = {p.name: p.read_bytes() for p in files}
    store_before = _file_digests(out.with_suffix(".zarr"))
    radiosity = pipeline.solve.radiosity

    def stopped_at_400(light, settings, ex, begin, on_batch=None):
        def watch(sol):
            on_batch(sol)
            if sol.iteration >= 400:
                raise KeyboardInterrupt
        return radiosity(light, settings, ex, begin, on_batch=watch)

    monkeypatch.setattr(pipeline.solve, "radiosity", stopped_at_400)
    monkeypatch.setattr(monitor, "CHECKPOINT_SECONDS", 0.0)    # every 8th batch (384 shots)
    with pytest.raises(KeyboardInterrupt):
        run(CORNELL, out, SETTINGS, progress=False, resume=True)
    assert {p.name: p.read_bytes() for p in files} == before
    assert _file_digests(out.with_suffix(".zarr")) == store_before
    assert Result(out.with_suffix(".zarr")).attrs["iteration"] == 320
    kept = _root_attrs(Outputs(out).partial)
    assert 320 < kept["iteration"] <= 400 and not kept["complete"]
    monkeypatch.undo()
    run(CORNELL, out, SETTINGS, progress=False, resume=True)
    assert_same_run(uninterrupted, out)
    assert not Outputs(out).partial.exists()


def test_a_refused_continuation_leaves_no_copy_and_names_the_finished_store(uninterrupted,
                                                                            tmp_path):
    import shutil

    out = tmp_path / "done.exr"
    shutil.copytree(uninterrupted.with_suffix(".zarr"), out.with_suffix(".zarr"))
    with pytest.raises(OptionError, match="other settings") as refused:
        run(CORNELL, out, SETTINGS.replace(batch=4), progress=False, resume=True)
    assert refused.value.path == str(out.with_suffix(".zarr"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["done.zarr"]


def _slot_store(tmp_path: Path, row_kind):
    """``(h, store path, solution)``: a store holding one checkpoint of a small box whose
    batch in flight names patch 1's sampled row and patch 2's one-point row."""
    from daskrad.mesh import build_hierarchy
    from daskrad.scene import box_scene
    from daskrad.solve import Solution

    h = build_hierarchy(box_scene(emission_per_face=0.1), 0.5, 0.25)
    E, P = h.n_elements, h.n_patches
    sol = Solution(radiosity=np.ones((E, 3)), direct=np.ones((E, 3)), unshot=np.ones((P, 3)),
                   initial_rms=1.0, iteration=8, history=[(8, 0.5, 1.0)],
                   queued=[[1, 2 + P]], row_kind=row_kind(P))
    store = Store(tmp_path / "t.zarr", Settings()).open()
    store.begin(h, np.full((E, 3), 0.5), sol)
    store.checkpoint(sol)
    return h, tmp_path / "t.zarr", sol


def test_a_format_6_checkpoint_keeps_the_rows_of_the_batches_in_flight(tmp_path):
    # without row_kind (a format-6 slot) the patches of the queued batches keep the rows they
    # were queued with (key p: sampled, P + p: one point); the others are chosen afresh
    h, path, _ = _slot_store(tmp_path, lambda P: np.zeros(P, np.int8))
    _without_row_kind(path / "internal" / "checkpoint" / str(_root_attrs(path)["checkpoint"]))
    back = Store(path, Settings(), resume=True).open().load_checkpoint(h)
    expect = np.full(h.n_patches, -1, np.int8)
    expect[1], expect[2] = 1, 0
    np.testing.assert_array_equal(back.row_kind, expect)


@pytest.mark.parametrize("bad", ["short", "value"])
def test_a_checkpoint_whose_row_kinds_do_not_fit_the_mesh_is_refused(tmp_path, bad):
    # a row_kind of the wrong length, or a kind other than -1, 0, 1, is a StoreError naming
    # the slot (not an IndexError mid-solve)
    from daskrad.errors import StoreError

    def kinds(P):
        return np.zeros(P - 1, np.int8) if bad == "short" else np.full(P, 5, np.int8)

    h, path, _ = _slot_store(tmp_path, kinds)
    with pytest.raises(StoreError, match=r"internal/checkpoint/\d does not hold the state"):
        Store(path, Settings(), resume=True).open().load_checkpoint(h)


@pytest.mark.parametrize("damage", ["queued out of range", "queued text", "iteration text",
                                    "no history", "garbled"])
def test_a_checkpoint_with_damaged_state_attributes_is_refused_in_one_line(tmp_path, damage):
    # the last checkpoint's zarr.json edited or garbled: a StoreError naming it (one line,
    # exit 2 from the CLI), not an IndexError or a JSONDecodeError traceback mid-resume
    from daskrad.errors import StoreError

    h, path, _ = _slot_store(tmp_path, lambda P: np.zeros(P, np.int8))
    meta = path / "internal" / "checkpoint" / str(_root_attrs(path)["checkpoint"]) / "zarr.json"
    if damage == "garbled":
        meta.write_text(meta.read_text()[:40])
    else:
        doc = json.loads(meta.read_text())
        attrs = doc["attributes"]
        del attrs["state_sha256"]      # as a slot of before the seal: its types are checked
        if damage == "queued out of range":
            attrs["queued"] = [[99999]]
        elif damage == "queued text":
            attrs["queued"] = [["a"]]
        elif damage == "iteration text":
            attrs["iteration"] = "x"
        else:
            del attrs["history"]
        meta.write_text(json.dumps(doc))
    with pytest.raises(StoreError, match=r"internal/checkpoint/\d/zarr.json"):
        Store(path, Settings(), resume=True).open().load_checkpoint(h)


@pytest.mark.parametrize("edit", ["iteration", "queued", "history", "row_kind checksum"])
def test_a_checkpoint_whose_state_attributes_were_edited_is_refused(tmp_path, edit):
    # edits that keep every type right (an earlier iteration, no batches in flight, a row
    # kind array no longer listed) would resume to other bits: the slot's own checksum of
    # its attributes refuses them, naming the file
    from daskrad.errors import StoreError

    h, path, sol = _slot_store(tmp_path, lambda P: np.zeros(P, np.int8))
    meta = path / "internal" / "checkpoint" / str(_root_attrs(path)["checkpoint"]) / "zarr.json"
    restored = Store(path, Settings(), resume=True).open().load_checkpoint(h)
    assert restored.iteration == sol.iteration and restored.queued == sol.queued
    doc = json.loads(meta.read_text())
    attrs = doc["attributes"]
    if edit == "iteration":
        attrs["iteration"] = 4
    elif edit == "queued":
        attrs["queued"] = []
    elif edit == "history":
        attrs["history"] = []
    else:
        del attrs["sha256"]["row_kind"]
    meta.write_text(json.dumps(doc))
    with pytest.raises(StoreError, match=r"internal/checkpoint/\d/zarr.json does not match its "
                                         "checksum"):
        Store(path, Settings(), resume=True).open().load_checkpoint(h)


@pytest.mark.parametrize("group", ["internal", "internal/checkpoint", "internal/context",
                                   "elements"])
def test_a_store_with_a_damaged_group_is_refused_before_anything_is_solved(uninterrupted,
                                                                           tmp_path, group):
    # an emptied group zarr.json passed the checks and stopped the resume at its first write
    # below it (a checkpoint, a context) with a JSONDecodeError traceback
    import shutil

    out = tmp_path / "g.exr"
    shutil.copytree(uninterrupted.with_suffix(".zarr"), out.with_suffix(".zarr"))
    (out.with_suffix(".zarr") / group / "zarr.json").write_text("")
    with pytest.raises(OptionError, match=f": {group}/zarr.json cannot be read"):
        run(CORNELL, out, SETTINGS.replace(max_iterations=560), progress=False, resume=True)
    assert not Outputs(out).partial.exists()


def test_a_garbled_free_slot_is_skipped_and_written_anew(uninterrupted, tmp_path):
    # a slot that is neither the last checkpoint nor the one to continue from, its zarr.json
    # garbled: the resume skips it, and its first checkpoint makes the slot anew (zarr's
    # require_group read the garbled metadata and stopped the run with a traceback)
    import shutil

    out = tmp_path / "free.exr"
    shutil.copytree(uninterrupted.with_suffix(".zarr"), out.with_suffix(".zarr"))
    attrs = _root_attrs(out.with_suffix(".zarr"))
    free = min({0, 1, 2} - {attrs["checkpoint"], attrs["continue"]})
    slot = out.with_suffix(".zarr") / "internal" / "checkpoint" / str(free)
    slot.mkdir(parents=True, exist_ok=True)
    (slot / "zarr.json").write_text("{garbled")
    more = SETTINGS.replace(max_iterations=SETTINGS.max_iterations + 80)
    report = run(CORNELL, out, more, progress=False, resume=True)
    assert report["iterations"] == more.max_iterations
    assert json.loads((slot / "zarr.json").read_text())["node_type"] == "group"


def test_a_damaged_slot_to_continue_from_is_named_not_the_stopping_criteria(uninterrupted,
                                                                             tmp_path):
    # more iterations continue from the "continue" slot; when its bytes are damaged the
    # refusal names that array, not "past where a run with these criteria would have stopped"
    out, meta = _older_store(uninterrupted, tmp_path, (), FORMAT)
    slot = _root_attrs(out.with_suffix(".zarr"))["continue"]
    chunks = out.with_suffix(".zarr") / "internal" / "checkpoint" / str(slot) / "radiosity"
    chunk = next(p for p in sorted(chunks.rglob("*")) if p.is_file() and p.name != "zarr.json")
    data = bytearray(chunk.read_bytes())
    data[len(data) // 2] ^= 0xFF
    chunk.write_bytes(bytes(data))
    more = SETTINGS.replace(max_iterations=SETTINGS.max_iterations + 80)
    with pytest.raises(OptionError, match=rf"continue from, internal/checkpoint/{slot}/radiosity "
                                          r"is damaged"):
        run(CORNELL, out, more, progress=False, resume=True)


def test_a_torn_checkpoint_leaves_the_previous_one(tmp_path):
    # A client killed while writing a slot has not yet named it in the root attributes:
    # reading gives the previous checkpoint, bit for bit.
    from daskrad.mesh import build_hierarchy
    from daskrad.scene import box_scene
    from daskrad.solve import Solution

    h = build_hierarchy(box_scene(emission_per_face=0.1), 0.5, 0.25)
    rng = np.random.default_rng(7)
    E, P = h.n_elements, h.n_patches

    def state(i):
        return Solution(radiosity=rng.random((E, 3)), direct=rng.random((E, 3)),
                        unshot=rng.random((P, 3)), initial_rms=0.1 * i, iteration=8 * i,
                        history=[(8 * i, 0.5, 1.0)], seconds=float(i), queued=[[1, 2]],
                        row_kind=rng.integers(-1, 2, P).astype(np.int8))

    store = Store(tmp_path / "t.zarr", Settings()).open()
    store.begin(h, np.full((E, 3), 0.5), state(0))
    store.checkpoint(state(1))
    last = state(2)
    store.checkpoint(last)
    # the older slot, the one the next checkpoint overwrites (the root names the last one)
    slot = 1 - int(_root_attrs(tmp_path / "t.zarr")["checkpoint"])
    torn = state(3)
    g = store.group[f"internal/checkpoint/{slot}"]
    g["radiosity"][...] = torn.radiosity   # the slot's arrays change, its name is never set
    g["unshot"][...] = torn.unshot
    back = Store(tmp_path / "t.zarr", Settings(), resume=True).open().load_checkpoint(h)
    np.testing.assert_array_equal(back.radiosity, last.radiosity)
    np.testing.assert_array_equal(back.unshot, last.unshot)
    np.testing.assert_array_equal(back.direct, last.direct)
    np.testing.assert_array_equal(back.row_kind, last.row_kind)
    assert (back.iteration, back.queued, back.history) == (16, [[1, 2]], [(16, 0.5, 1.0)])
    assert back.initial_rms == last.initial_rms and back.seconds == last.seconds


def _store_at_iteration_8(path: Path):
    """``(h, store, sol)``: a new store for a small emitting box, and a solution claiming 8
    shots (one history entry) to checkpoint into it."""
    from daskrad import solve
    from daskrad.mesh import build_hierarchy
    from daskrad.scene import box_scene

    h = build_hierarchy(box_scene(emission_per_face=1.0), 0.5, 0.5)
    store = Store(path, Settings()).open()
    sol = store.begin(h, np.full((h.n_elements, 3), 0.5),
                      solve.initial_solution(h, np.ones((h.n_elements, 3))))
    sol.iteration, sol.history = 8, [(8, 0.5, 1.0)]
    return h, store, sol


def test_a_checkpoint_names_its_slot_in_one_write_of_the_root_metadata(tmp_path, monkeypatch):
    # the root's zarr.json is replaced exactly once per checkpoint, with the slot's name, the
    # iteration and the history together: zarr 3's attrs.update writes key by key, and a client
    # killed between two writes left "checkpoint" beside the previous iteration (seen 3 times
    # in 42 killed runs under load; 0 in 30 since)
    h, store, sol = _store_at_iteration_8(tmp_path / "s.zarr")
    root = (tmp_path / "s.zarr" / "zarr.json").resolve()
    seen = []
    replace = Path.replace

    def spy(self, target):
        if Path(target).resolve() == root:
            seen.append(json.loads(Path(self).read_text())["attributes"])
        return replace(self, target)

    monkeypatch.setattr(Path, "replace", spy)
    store.checkpoint(sol)
    assert len(seen) == 1
    assert (seen[0]["checkpoint"], seen[0]["iteration"], seen[0]["history"]) == (
        0, 8, [[8, 0.5, 1.0]])


def _raise_terminated(signum, frame):
    raise Terminated("terminated")


@pytest.mark.parametrize("sig, handler, raised", [
    (signal.SIGINT, signal.default_int_handler, KeyboardInterrupt),
    (signal.SIGTERM, _raise_terminated, Terminated)], ids=["ctrl-c", "sigterm"])
def test_ctrl_c_during_a_store_write_waits_for_it_to_finish(tmp_path, monkeypatch, sig,
                                                            handler, raised):
    # SIGINT (or SIGTERM, which the CLI turns into the same stop) arriving while zarr writes
    # (here: at the first file a checkpoint replaces) is held until the checkpoint is
    # complete, then raised: the slot is named, nothing is left half-written and no zarr
    # task is abandoned
    import os

    h, store, sol = _store_at_iteration_8(tmp_path / "s.zarr")
    replace = Path.replace
    sent = []
    # a handler that raises, whatever the runner inherited (ignored in a background job)
    previous = signal.signal(sig, handler)

    def interrupting(self, target):
        if not sent:
            sent.append(True)
            os.kill(os.getpid(), sig)
        return replace(self, target)

    monkeypatch.setattr(Path, "replace", interrupting)
    try:
        with pytest.raises(raised):
            store.checkpoint(sol)
    finally:
        signal.signal(sig, previous)
    assert sent
    monkeypatch.setattr(Path, "replace", replace)
    attrs = _root_attrs(tmp_path / "s.zarr")
    assert (attrs["checkpoint"], attrs["iteration"]) == (0, 8)
    assert store.load_checkpoint(h).iteration == 8
    assert not list((tmp_path / "s.zarr").rglob("*.partial"))


def test_ctrl_c_and_sigterm_held_together_stop_as_a_termination_and_leave_no_hold(
        tmp_path, monkeypatch):
    # both signals during one store write: the checkpoint completes, SIGTERM is delivered
    # first (the stop is a termination, exit 143 in the CLI), and both handlers are the
    # caller's again afterwards (a handler left holding would swallow every later signal)
    import os

    h, store, sol = _store_at_iteration_8(tmp_path / "s.zarr")
    replace = Path.replace
    sent = []
    before = {signal.SIGINT: signal.signal(signal.SIGINT, signal.default_int_handler),
              signal.SIGTERM: signal.signal(signal.SIGTERM, _raise_terminated)}

    def interrupting(self, target):
        if not sent:
            sent.append(True)
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGTERM)
        return replace(self, target)

    monkeypatch.setattr(Path, "replace", interrupting)
    try:
        with pytest.raises(Terminated):
            store.checkpoint(sol)
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        assert signal.getsignal(signal.SIGTERM) is _raise_terminated
        monkeypatch.setattr(Path, "replace", replace)
        store.checkpoint(sol)               # nothing left pending from the first call
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
    assert sent
    assert store.load_checkpoint(h).iteration == 8


def test_ctrl_c_held_by_a_store_call_goes_to_the_handler_that_was_there(tmp_path,
                                                                        monkeypatch):
    # a caller's own SIGINT handler gets the held signal once the store call is done (not a
    # KeyboardInterrupt in its place); with SIGINT ignored nothing is raised at all
    import os

    got, during = [], []
    replace = Path.replace

    def interrupting(self, target):
        if not during:
            os.kill(os.getpid(), signal.SIGINT)
            during.append(list(got))            # what the handler had seen by then
        return replace(self, target)

    previous = signal.signal(signal.SIGINT, lambda signum, frame: got.append(signum))
    try:
        monkeypatch.setattr(Path, "replace", interrupting)
        Store(tmp_path / "a.zarr", Settings()).open()
        assert during == [[]]                   # held while the store call ran ...
        assert got == [signal.SIGINT]           # ... then delivered to the caller's handler
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        during.clear()
        Store(tmp_path / "b.zarr", Settings()).open()   # ignored: no KeyboardInterrupt
        assert during == [[signal.SIGINT]] and got == [signal.SIGINT]
    finally:
        signal.signal(signal.SIGINT, previous)


def test_ctrl_c_before_the_run_starts_claims_no_checkpoint(tmp_path, monkeypatch, capsys):
    # an interrupt while the CLI still checks or compiles (before run() made a store) has
    # nothing to resume, and one outside any run claims nothing at all
    import daskrad.commands
    import daskrad.warmup
    from daskrad import cli

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(daskrad.warmup, "is_warm", interrupt)
    out = tmp_path / "x.exr"
    assert cli.main(["run", str(CORNELL), "-o", str(out), "-q"]) == 130
    assert capsys.readouterr().err == ("daskrad: interrupted; it stopped before its solution "
                                       "store was written: nothing to resume\n")
    monkeypatch.setattr(daskrad.commands, "info_text", interrupt)
    assert cli.main(["info", str(CORNELL)]) == 130
    assert capsys.readouterr().err == "daskrad: interrupted\n"
    assert not out.exists()
