"""Dask and Zarr (issue 4): the same bits for any number of workers, a real loopback cluster
started by ``cluster/local.sh``, a worker killed mid-run, the store and its worker cache.

Every comparison is exact (``array_equal`` on float arrays): form factors depend only on
geometry, the client applies batches in shooter order, and which shooters form a batch depends
only on the solution state, so no tolerance is justified — one differing bit is a bug.
"""

from __future__ import annotations

import base64
import json
import os
import re
import signal
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

import numpy as np
import pytest

from daskrad.distributed import worker
from daskrad.distributed.dask_executor import DaskExecutor
from daskrad.distributed.executor import InProcess
from daskrad.distributed.store import Store
from daskrad.output import Outputs
from daskrad.preprocess import preprocess
from daskrad.run import run, solve_scene
from daskrad.scene import load_scene
from daskrad.settings import Settings
from daskrad.testing import stress as sc
from tests.helpers import CORNELL, REPO, assert_same_run, store_arrays

# Small images and a bounded number of shots keep each run to about a second in-process; the
# ≥5,000-element case uses the Cornell box with 25-unit elements (5,839 before subdivision).
CASES = {
    "cornell": Settings(max_iterations=160, width=64, height=64, dashboard="127.0.0.1:0"),
    "5k": Settings(element_size=25.0, max_iterations=64, width=64, height=64,
                   dashboard="127.0.0.1:0"),
}


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> dict[str, Path]:
    """In-process (``--workers 0``) runs of every case: the bits everything must reproduce."""
    out = {}
    for name, settings in CASES.items():
        path = tmp_path_factory.mktemp("ref") / f"{name}.exr"
        run(CORNELL, path, settings, progress=False)
        out[name] = path
    return out


def test_reference_cases_are_what_the_issue_asks(reference):
    counts = {name: json.loads(p.with_suffix(".json").read_text())["counts"]["elements"]
              for name, p in reference.items()}
    assert counts["5k"] >= 5000
    arrays = store_arrays(reference["cornell"].with_suffix(".zarr"))
    assert arrays["elements/radiosity"].dtype == np.float32
    assert arrays["checkpoint/last/radiosity"].dtype == np.float64
    # the public f4 array is the exact state rounded once
    np.testing.assert_array_equal(arrays["elements/radiosity"],
                                  arrays["checkpoint/last/radiosity"].astype(np.float32))


@pytest.mark.parametrize("case, workers, processes", [
    ("cornell", 1, False), ("cornell", 2, True), ("5k", 2, True), ("5k", 2, False),
    ("5k", 4, True)])
def test_same_bits_for_any_number_of_workers(reference, tmp_path, cluster_client, case,
                                             workers, processes):
    out = tmp_path / f"{case}-{workers}-{processes}.exr"
    settings = CASES[case].replace(workers=workers, processes=processes)
    if workers == 2 and processes:  # the session's 2-process cluster; others start their own
        # the executor's store is the one the run solves into (a new run's partial store)
        store = Store(Outputs(out).working_store(resume=False), settings)
        executor = DaskExecutor(cluster_client, store)
        report = run(CORNELL, out, settings, progress=False, executor=executor)
        assert executor.stats["tasks"] > 0
    else:
        report = run(CORNELL, out, settings, progress=False)
    assert report["workers"] == workers
    assert_same_run(reference[case], out)
    # the tiles' counts come back from the workers too
    ref_report = json.loads(reference[case].with_suffix(".json").read_text())
    assert report["image"]["edge_pixels"] == ref_report["image"]["edge_pixels"] > 0
    # the report gives each worker's peak memory and its row cache, within its budget
    memory = report["memory"]
    assert len(memory["workers"]) == workers and memory["client_peak_mib"] > 0
    assert memory["workers_in_client_process"] is not processes
    for w in memory["workers"]:     # a worker may have had no shooter to compute
        assert w["peak_mib"] > 0 and 0 <= w["row_cache_mib"] <= w["row_cache_limit_mib"]
    assert sum(w["row_cache_mib"] for w in memory["workers"]) > 0


def test_workers_in_the_clients_process_get_contexts_in_memory_not_from_the_store(tmp_path):
    # --workers N's default LocalCluster is threads of this process: the executor sees it,
    # hands every task context over as the object itself (no store write, no load) and its
    # dashboard link names the loopback address it listens on
    from daskrad.distributed.dask_executor import start_local

    settings = CASES["cornell"].replace(workers=2)
    store = Store(tmp_path / "t.zarr", settings).open()
    executor = start_local(settings, store)
    try:
        assert executor.shared and executor.workers == 2
        assert executor.dashboard_link.startswith("http://127.0.0.1:")
        loads = worker.loads
        solved = solve_scene(load_scene(CORNELL), settings, executor)
        assert solved.solution.iteration > 0 and executor.stats["tasks"] > 0
        assert worker.loads == loads
        assert "internal" not in store.group          # no context went into the store
        assert worker.shared_kinds(store.path) == ["direct", "shoot"]
        # ... and the rows are one cache, the client's, within one budget for the process:
        # each worker reports the client's figures, not a second budget of its own
        memory = executor.memory()
        assert memory["workers_in_client_process"] and memory["row_cache_mib"] > 0
        assert [(w["row_cache_mib"], w["row_cache_limit_mib"]) for w in memory["workers"]] \
            == [(memory["row_cache_mib"], memory["row_cache_limit_mib"])] * 2
    finally:
        executor.close()
    assert worker.shared_kinds(store.path) == []          # forgotten on close


def test_new_rows_are_grouped_into_tasks_by_their_measured_cost():
    # one row a task until one was timed; cheap rows fill a task to TASK_SECONDS, but a batch
    # still makes a task for every worker; dear rows stay one a task; order is kept
    from daskrad.distributed.dask_executor import TASK_SECONDS, row_tasks, rows_per_task

    # a prefetched task (no batch to share among workers) takes rows_per_task rows
    assert [rows_per_task(x) for x in (None, 0.0, 2 * TASK_SECONDS, TASK_SECONDS / 2,
                                       TASK_SECONDS / 100)] == [1, 1, 1, 2, 100]
    new = [0, 2, 3, 5, 6, 7]
    assert row_tasks(new, None, 2) == [[0], [2], [3], [5], [6], [7]]
    assert row_tasks(new, 2 * TASK_SECONDS, 2) == [[0], [2], [3], [5], [6], [7]]
    assert row_tasks(new, TASK_SECONDS / 2, 2) == [[0, 2], [3, 5], [6, 7]]
    assert row_tasks(new, TASK_SECONDS / 100, 2) == [[0, 2, 3], [5, 6, 7]]
    assert row_tasks(new, TASK_SECONDS / 100, 4) == [[0, 2], [3, 5], [6, 7]]
    assert row_tasks([], TASK_SECONDS, 2) == []


def test_worker_cache_loads_each_context_once_per_process(cluster_client, tmp_path):
    settings = CASES["cornell"]
    before = sum(s["loads"] for s in cluster_client.run(worker.state).values())
    store = Store(tmp_path / "c.zarr", settings)
    executor = DaskExecutor(cluster_client, store)
    scene = load_scene(CORNELL)
    store.open()
    solve_scene(scene, settings, executor)
    after = cluster_client.run(worker.state)
    loads = sum(s["loads"] for s in after.values()) - before
    # each of 2 workers reads each context (direct per refinement level, shoot) at most once:
    # far fewer loads than tasks (a cache miss per task would make them equal)
    assert 0 < loads < executor.stats["tasks"] / 2
    assert all(s["cached"] <= worker.CACHE_SIZE for s in after.values())


def test_worker_killed_mid_run_is_replaced_and_bits_are_the_same(reference, cluster_client,
                                                                 tmp_path):
    settings = CASES["cornell"]
    killed = []

    def kill_a_worker(sol):
        if len(sol.history) == 3 and not killed:
            pids = cluster_client.run(os.getpid)
            victim = sorted(pids)[0]
            os.kill(pids[victim], signal.SIGKILL)
            killed.append(victim)

    store = Store(tmp_path / "k.zarr", settings)
    executor = DaskExecutor(cluster_client, store)
    scene = load_scene(CORNELL)
    store.open()
    try:
        _, _, sol, _ = solve_scene(scene, settings, executor, on_batch=kill_a_worker)
    finally:
        cluster_client.wait_for_workers(2, timeout=60)  # the nanny restarts it
    assert killed
    expected = store_arrays(reference["cornell"].with_suffix(".zarr"))
    np.testing.assert_array_equal(sol.radiosity, expected["checkpoint/last/radiosity"])
    np.testing.assert_array_equal(sol.unshot, expected["checkpoint/last/unshot"])


def _wait_for(predicate, timeout: float, what: str):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


def test_a_scheduler_nothing_listens_on_is_refused_before_any_work(tmp_path):
    # Dask's connect retries a refused address for connect_timeout (30 s), after the scene is
    # loaded and meshed (and the kernels compiled on a first run); a plain socket says at once
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"      # closed: nothing listens there now
    out = tmp_path / "out" / "x.exr"
    out.parent.mkdir()
    r = subprocess.run([sys.executable, "-m", "daskrad", "run", str(CORNELL), "-o", str(out),
                        "-q", "--scheduler", address], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2
    assert r.stderr.strip() == (f"daskrad: error: cannot reach the Dask scheduler {address}: "
                                "connection refused")
    assert list(out.parent.iterdir()) == []   # not even the lock file


def test_loopback_cluster_script_and_scheduler_option(reference, tmp_path):
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}"
           f"{os.environ.get('PATH', '')}"}
    cluster_dir = tmp_path / "cluster"
    proc = subprocess.Popen(["bash", str(REPO / "cluster" / "local.sh"), str(cluster_dir), "2"],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            start_new_session=True)
    try:
        sched = cluster_dir / "scheduler.json"
        _wait_for(lambda: sched.is_file() and sched.stat().st_size > 0, 60, "the scheduler")
        address = json.loads(sched.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        from distributed import Client

        with Client(address, timeout=60) as client:   # both worker processes have joined
            client.wait_for_workers(2, timeout=60)
        settings = CASES["cornell"]
        args = ["--max-iterations", str(settings.max_iterations), "--width", "64",
                "--height", "64", "-q", "--scheduler", address]

        # a relative output cannot be found by workers elsewhere: one clear line, exit 2
        bad = subprocess.run([sys.executable, "-m", "daskrad", "run", str(CORNELL), "-o",
                              "relative.exr", *args], cwd=tmp_path, env=env,
                             capture_output=True, text=True, timeout=120)
        assert bad.returncode == 2
        assert "shared file system" in bad.stderr and "Traceback" not in bad.stderr

        out = tmp_path / "sched.exr"
        done = subprocess.run([sys.executable, "-m", "daskrad", "run", str(CORNELL), "-o",
                               str(out), *args], env=env, capture_output=True, text=True,
                              timeout=240)
        assert done.returncode == 0, done.stderr
        assert_same_run(reference["cornell"], out)

        # the dashboard link is printed, and /daskrad serves the progress of the run
        link = re.search(r"dashboard (http://127\.0\.0\.1:\d+)/status", done.stderr)
        assert link, done.stderr
        with urllib.request.urlopen(link.group(1) + "/daskrad/json", timeout=10) as r:
            meta = json.load(r)
        assert meta["progress"]["iteration"] == settings.max_iterations
        assert meta["progress"]["workers"] == 2
        assert base64.b64decode(meta["preview"]).startswith(b"\x89PNG")
        with urllib.request.urlopen(link.group(1) + "/daskrad", timeout=10) as r:
            page = r.read().decode()
        assert "relative unshot RMS" in page and "<svg" in page
        # the phase with its progress bar (the last one: the tiles, all done)
        assert "phase: rendering" in page and '<progress value="1.0000"' in page
    finally:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_without_workers_option_a_run_stays_in_process():
    # docs/design.md §4: on one machine the threads beat a LocalCluster at every size
    # measured (bench_speed), so a run without --workers or --scheduler is in-process
    from daskrad.cli import build_parser
    from daskrad.commands import settings_from_args
    from daskrad.distributed import auto_workers

    args = build_parser().parse_args(["run", str(CORNELL)])
    assert settings_from_args(args).workers is None          # decided by run() from the scene
    scene = load_scene(CORNELL)
    assert auto_workers(scene, Settings()) == 0              # ~3,700 elements
    assert auto_workers(scene, Settings(element_size=5.0)) == 0   # ~119,000 elements
    explicit = build_parser().parse_args(["run", str(CORNELL), "--workers", "0"])
    assert settings_from_args(explicit).workers == 0


def test_lit_room_direct_pass_same_bits_in_process_and_on_two_workers(tmp_path, cluster_client):
    # the two-pass pipeline with point, directional and area lights, adaptive subdivision and
    # the per-pixel pass: direct-light futures, form factors and tiles all on the 2 workers
    room = REPO / "scenes" / "lit_room.obj"
    settings = Settings(max_iterations=64, width=48, height=48, dashboard="127.0.0.1:0")
    a, b = tmp_path / "in-process.exr", tmp_path / "two-workers.exr"
    run(room, a, settings.replace(workers=0), progress=False)
    store = Store(Outputs(b).working_store(resume=False), settings.replace(workers=2))
    executor = DaskExecutor(cluster_client, store)
    direct_batches = []
    submit_direct = executor.direct
    executor.direct = lambda ctx, ranges: (direct_batches.append(len(ranges)),
                                           submit_direct(ctx, ranges))[1]
    report = run(room, b, settings.replace(workers=2), progress=False, executor=executor)
    assert report["counts"]["point_lights"] and report["counts"]["directional_lights"]
    assert report["counts"]["emitters"] > 0
    assert direct_batches and sum(direct_batches) > 0  # direct light ran as futures
    assert_same_run(a, b)


def _cornell_rows_executor(client, tmp_path):
    """The Cornell box's shoot context and a Dask executor on ``client`` set to it."""
    from daskrad.formfactor import shooting

    settings = CASES["cornell"]
    h = preprocess(load_scene(CORNELL), settings).hierarchy
    ctx = shooting.make_context(h, settings.method, settings.resolution)
    executor = DaskExecutor(client, Store(tmp_path / "rows.zarr", settings).open())
    executor.set_geometry(ctx, h.generation)
    return ctx, executor


def test_a_patch_shoots_again_from_the_row_the_client_or_its_worker_kept(cluster_client,
                                                                         tmp_path):
    # issue 12: the client keeps the rows it received, so a re-shot is no task at all; a row
    # the client dropped goes back to the worker that computed it, which kept it. Either way
    # the rows are the bits of the first time (and of the in-process executor)
    from daskrad.distributed.executor import InProcess
    from daskrad.formfactor import shooting

    ctx, executor = _cornell_rows_executor(cluster_client, tmp_path)
    cluster_client.run(worker.forget_rows)
    ids = np.arange(12)
    first = executor.shots(0, ids).result()
    before = cluster_client.run(worker.state)
    tasks = executor.stats["tasks"]
    again = executor.shots(1, ids[::-1]).result()
    assert executor.stats["tasks"] == tasks                 # all from the client's rows
    # the new rows of the first batch were shared out: both workers computed some
    assert all(before[w]["row_misses"] > 0 for w in before)
    # a client that kept no row sends each re-shot to the worker that computed it
    executor.rows = shooting.RowCache(max_bytes=0)
    third = executor.shots(2, ids).result()
    after = cluster_client.run(worker.state)
    hits = sum(after[w]["row_hits"] - before[w]["row_hits"] for w in after)
    misses = sum(after[w]["row_misses"] - before[w]["row_misses"] for w in after)
    assert (hits, misses) == (12, 0)
    for a, b in zip(first, third, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)
    local = InProcess(ctx).shots(0, ids).result()
    for a, b, c in zip(first, again[::-1], local, strict=True):
        for x, y, z in zip(a, b, c, strict=True):
            np.testing.assert_array_equal(x, y)
            np.testing.assert_array_equal(x, z)


def test_rows_prefetched_on_idle_workers_leave_the_solution_unchanged(cluster_client,
                                                                     tmp_path):
    # issue 12: between batches the workers compute rows of the patches ranked next (solve's
    # prefetch); a batch takes a prefetched row's future. The solution is the bits of one
    # thread in-process, which never prefetches
    from daskrad import direct, solve
    from daskrad.distributed.executor import InProcess

    scene = load_scene(CORNELL)
    settings = CASES["cornell"]
    light = direct.light(scene, preprocess(scene, settings), settings, InProcess(threads=1))
    local = solve.radiosity(light, settings, InProcess(threads=1))
    store = Store(tmp_path / "ahead.zarr", settings).open()
    executor = DaskExecutor(cluster_client, store)
    cluster_client.run(worker.forget_rows)
    remote = solve.radiosity(light, settings, executor)
    assert executor.stats["ahead"] > 0
    assert remote.iteration == local.iteration > 2 * settings.batch
    np.testing.assert_array_equal(remote.radiosity, local.radiosity)
    np.testing.assert_array_equal(remote.unshot, local.unshot)


def test_a_patch_offered_again_while_its_first_prefetch_lives_gets_its_own_rows(
        cluster_client, tmp_path):
    # a prefetched task of rows (1, 2, 3) lives on while 2 and 3 are still offered; 1 drops
    # out and comes back at the head of a new task (1, 5, 6). That task must not be handed the
    # first one's future (Client.submit answers a key it already has with its live future):
    # the batch shooting 1, 5, 6 gets exactly the rows of 1, 5, 6
    from daskrad.distributed.dask_executor import TASK_SECONDS
    from daskrad.distributed.executor import InProcess

    ctx, executor = _cornell_rows_executor(cluster_client, tmp_path)
    executor.row_seconds = TASK_SECONDS / 3             # three rows a prefetched task
    executor.prefetch(np.array([1, 2, 3]))
    executor.prefetch(np.array([2, 3]))
    executor.prefetch(np.array([1, 5, 6, 2, 3]))
    assert executor.stats["ahead"] == 2
    ids = np.array([1, 5, 6])
    rows = executor.shots(0, ids).result()
    local = InProcess(ctx).shots(0, ids).result()
    for a, b in zip(rows, local, strict=True):
        for x, y in zip(a, b, strict=True):
            np.testing.assert_array_equal(x, y)


def test_a_cluster_started_while_the_scene_loads_is_closed_when_the_scene_is_bad(
        tmp_path, monkeypatch):
    # --workers N starts its LocalCluster of threads beside the loading and meshing; a scene
    # that fails to load must not leave it running (its event loop, its workers, the port of
    # its dashboard), and the error is the loader's own
    import threading

    import daskrad.run
    from daskrad.errors import SceneError

    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    before = {t.ident for t in threading.enumerate()}
    started = []
    early = daskrad.run.start_early

    def start(settings):
        started.append(early(settings))
        return started[-1]

    def load(*args, **kwargs):
        time.sleep(1.0)                     # a scene that takes a while: the cluster starts
        return load_scene(*args, **kwargs)

    monkeypatch.setattr(daskrad.run, "start_early", start)
    monkeypatch.setattr(daskrad.run, "load_scene", load)
    with pytest.raises(SceneError, match="bad.obj"):
        run(bad, tmp_path / "o.exr", CASES["cornell"].replace(workers=2,
                                                              dashboard="127.0.0.1:0"),
            progress=False)
    # (its threads may all have been started by earlier tests' clusters, and its starting
    # thread ends within the second: so the cluster is followed, not the threads)
    assert started and started[0] is not None, "no cluster was started beside the loading"
    assert started[0].get().client.status == "closed"
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        left = [t.name for t in threading.enumerate() if t.ident not in before and t.is_alive()]
        if not left:
            break
        time.sleep(0.1)
    assert left == []
    assert not (tmp_path / "o.exr").exists()


def test_only_a_local_cluster_of_threads_starts_beside_the_loading():
    # worker processes must start from the main thread (they inherit its ignored SIGINT) and
    # a --scheduler is connected to once the scene is known good
    from daskrad.distributed import start_early

    base = CASES["cornell"]
    for settings in (base.replace(workers=0), base.replace(workers=None),
                     base.replace(workers=2, processes=True),
                     base.replace(workers=2, scheduler="tcp://127.0.0.1:1")):
        assert start_early(settings) is None
    early = start_early(base.replace(workers=1, dashboard="127.0.0.1:0"))
    try:
        assert early.get().workers == 1
    finally:
        early.close()


def test_one_point_rows_give_the_same_bits_on_any_executor_and_stay_within_the_furnace_bound(
        cluster_client):
    # the fin furnace with a share at which some shooters leave from one point (solve.row_keys,
    # keyed apart from their sampled rows): the cluster, one thread and the thread pool apply
    # the same rows in the same order; the answer is still E / (1 − ρ) within the furnace's
    # 1 %. Every patch of a furnace starts as bright as the brightest, so only a share above 1
    # sends any from one point: those first chosen before their light grew past the gate, and
    # they keep that row (1.1: 24 of 108 patches, 0.73 %; every row sampled: 0.35 %; 1.5, every
    # patch from one point: 1.28 %)
    scene = sc.degenerate_scenes()["non-manifold edge (fin)"]
    settings = sc.BOX.replace(sample_share=1.1)
    results = []
    for executor in (InProcess(threads=1), InProcess(threads=2), DaskExecutor(cluster_client)):
        keys = []
        shots = executor.shots

        def recorded(n, k, shots=shots, keys=keys):
            keys.extend(np.asarray(k).tolist())
            return shots(n, k)

        executor.shots = recorded
        try:
            h, _, sol, _ = solve_scene(scene, settings, executor)
        finally:
            executor.close()
        assert (np.array(keys) >= h.n_patches).sum() > 0
        results.append(sol)
    for sol in results[1:]:
        np.testing.assert_array_equal(sol.radiosity, results[0].radiosity)
        np.testing.assert_array_equal(sol.unshot, results[0].unshot)
    assert np.abs(results[0].radiosity * (1.0 - sc.RHO) - 1.0).max() < 0.01


def test_a_spawned_process_reports_its_own_peak_memory_not_its_parents():
    # Linux keeps getrusage's ru_maxrss across execve, so a worker started by spawn reported
    # the client's peak (both `--processes` workers showed the benchmark's 827 MiB). A parent
    # that touched 400 MiB starts a fresh interpreter: the child's peak must be far below it.
    code = (
        "import subprocess, sys\n"
        "from daskrad.distributed.memory import peak_mib\n"
        "block = bytearray(400 * 2**20)\n"
        "block[::4096] = b'x' * len(block[::4096])\n"
        "child = subprocess.run([sys.executable, '-c', 'from daskrad.distributed.memory import "
        "peak_mib; print(peak_mib())'], capture_output=True, text=True, check=True)\n"
        "print(peak_mib(), float(child.stdout))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=REPO, timeout=120).stdout
    parent, child = map(float, out.split())
    assert parent > 400 and child < parent - 300


def test_a_ctrl_c_as_a_dask_call_starts_prints_no_tornado_traceback(monkeypatch):
    # distributed's sync() adds a cancel callback when the waiting thread is interrupted; if
    # that happens before the call created its future, cancel reads an unassigned variable
    # and tornado logs the NameError with a traceback (seen once in CI above daskrad's one
    # line). Made deterministic here: the loop is held until the call was interrupted, so it
    # runs the call's first step, then the cancel, then the step that makes the future.
    import logging
    import threading

    import distributed.utils as du

    from daskrad.distributed import dask_executor

    class InterruptedWait(threading.Event):
        def wait(self, timeout=None):
            raise KeyboardInterrupt

    class Threading:            # sync()'s threading module with an Event whose wait raises
        Event = InterruptedWait

        def __getattr__(self, name):
            return getattr(threading, name)

    class Records(logging.Handler):
        def __init__(self):
            super().__init__()
            self.seen = []

        def emit(self, record):
            # this test's records only (a cluster of another test may log here too)
            exc = record.exc_info[1] if record.exc_info else None
            if isinstance(exc, NameError) or record.getMessage() == "another error":
                self.seen.append(record)

    async def work():
        return 1

    def interrupt_a_call(runner):
        gate = threading.Event()
        runner.loop.add_callback(gate.wait, 30)      # the loop waits until the call is stopped
        try:
            with monkeypatch.context() as m:
                m.setattr(du, "threading", Threading())
                with pytest.raises(KeyboardInterrupt):
                    du.sync(runner.loop, work)
        finally:
            gate.set()
        du.sync(runner.loop, work)      # the loop has run the cancel callback after this

    log = logging.getLogger("tornado.application")
    records = Records()
    log.addHandler(records)
    had = dask_executor.CANCEL_RACE in log.filters
    log.removeFilter(dask_executor.CANCEL_RACE)
    runner = du.LoopRunner(asynchronous=False)
    runner.start()
    try:
        interrupt_a_call(runner)
        unfiltered = [r.exc_info[1] for r in records.seen]
        records.seen.clear()
        dask_executor.hush_cancel_race()
        interrupt_a_call(runner)
        logging.getLogger("tornado.application").error("another error")
    finally:
        runner.stop()
        log.removeHandler(records)
        (log.addFilter if had else log.removeFilter)(dask_executor.CANCEL_RACE)
    assert len(unfiltered) == 1 and isinstance(unfiltered[0], NameError), unfiltered
    assert [r.getMessage() for r in records.seen] == ["another error"]


def test_the_publisher_sends_the_latest_of_each_key_in_order_and_everything_before_close():
    # the solve's client hands its progress to a thread and never waits for the scheduler
    import threading

    from daskrad.distributed.dask_executor import Publisher

    sent, entered, gate = [], threading.Event(), threading.Event()

    def send(key, value):
        if key == "bad":
            raise OSError("the scheduler is gone")
        if key == "first":
            entered.set()
            assert gate.wait(10)
        sent.append((key, value))

    pub = Publisher(send)
    pub.put("first", 0)
    assert entered.wait(10)                 # the thread is sending it, held at the gate
    pub.put("progress", 1)
    pub.put("preview", lambda: threading.current_thread().name)
    pub.put("bad", 2)                       # the scheduler refuses it: dropped
    pub.put("phase", 3)
    pub.put("progress", 4)                  # replaces 1, in 1's place
    gate.set()
    pub.close()                             # returns once everything pending was sent
    pub.put("late", 5)                      # after close: never sent
    assert sent == [("first", 0), ("progress", 4), ("preview", "daskrad-publish"),
                    ("phase", 3)]

    # a preview that fails is daskrad's bug: the next messages still go, close raises it
    sent.clear()
    pub = Publisher(send)
    pub.put("preview", lambda: 1 / 0)
    pub.put("phase", 6)
    with pytest.raises(ZeroDivisionError):
        pub.close()
    assert sent == [("phase", 6)]

    # idle, the thread ends (an executor never closed leaves none) and starts again
    senders = []
    Publisher.IDLE_SECONDS, idle = 0.01, Publisher.IDLE_SECONDS
    try:
        pub = Publisher(lambda key, value: senders.append(threading.current_thread()))
        pub.put("phase", 7)
        for _ in range(500):
            if senders and not senders[0].is_alive():
                break
            time.sleep(0.01)
        assert senders and not senders[0].is_alive()
        pub.put("phase", 8)
        pub.close()
    finally:
        Publisher.IDLE_SECONDS = idle
    assert len(senders) == 2 and senders[1] is not senders[0]

    # without its thread (the benchmark's reference arm) each message goes at once, in line
    inline = []
    pub = Publisher(lambda key, value: inline.append((key, value)), thread=False)
    pub.put("preview", lambda: threading.current_thread().name)
    assert inline == [("preview", threading.current_thread().name)]
    pub.close()
