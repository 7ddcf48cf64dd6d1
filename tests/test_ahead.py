"""The view's junction gather computed ahead, on a core the solve leaves idle
(:func:`daskrad.render.gather_ahead`, :class:`daskrad.distributed.executor.Ahead`): the
image is the same bits whether the gather was computed ahead (all of it, part of it, none)
or in the render, and the render never waits on the idle thread."""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest

from daskrad import render
from daskrad.distributed import executor
from daskrad.distributed.executor import Ahead, InProcess
from tests.helpers import SMALL_RUN as SMALL
from tests.helpers import steps_on


@pytest.fixture(scope="module")
def solved():
    """``(scene, light, sol, image)``: the Cornell box at :data:`SMALL` on 2 threads."""
    return steps_on("cornell_box.obj", 2)


def _image(solved, finish: bool, monkeypatch, threads: int = 2):
    """The image of ``solved`` with its gather started ahead on ``threads`` threads; the
    render asks for it once the idle thread is done (``finish``: then the render may not
    compute any of it) or at once. The thread keeps the normal priority (a test on a busy
    machine must not wait for idle cores)."""
    scene, light, sol, _ = solved
    monkeypatch.setattr(executor, "idle_priority", lambda: True)
    ex = InProcess(threads=threads)
    try:
        cam = render.camera(scene, SMALL)
        ahead = render.gather_ahead(scene, light, SMALL, cam, ex)
        if finish and ahead is not None:
            assert ahead.join(timeout=60)

            def refused(*args, **kwargs):
                raise AssertionError("the render gathered again")
            monkeypatch.setattr(render, "gather_operator_of", refused)
            monkeypatch.setattr(render, "plan_gather", refused)
        return ahead, render.image(scene, light, sol, SMALL, ex, cam, ahead)
    finally:
        ex.close()


@pytest.mark.parametrize("finish", [True, False], ids=["all ahead", "asked at once"])
def test_the_gather_computed_ahead_gives_the_render_the_same_bits(solved, finish,
                                                                   monkeypatch):
    plain = solved[3]
    ahead, image = _image(solved, finish, monkeypatch)
    assert ahead is not None
    plan = ahead.plan()
    assert len(plan.vertices) > 0 and plan.context is not None     # a gather to compute
    assert plan.fits(image.context)                                 # and it was taken
    done, ranges = ahead.progress()
    assert ranges > 1
    if finish:   # every range was the idle thread's
        assert done == ranges
    np.testing.assert_array_equal(image.pixels, plain.pixels)
    # and the gather changed the image: without it the same bits would prove nothing
    no_gather = render.pixels(replace(plain.context, junctions=None))
    assert not np.array_equal(no_gather, plain.pixels)


def test_a_plan_for_another_camera_is_not_taken(solved):
    scene, light, sol, plain = solved
    cam = render.camera(scene, SMALL)
    ex = InProcess(threads=2)
    try:
        ahead = render.gather_ahead(scene, light, SMALL, replace(cam), ex)   # another object
        assert not ahead.plan().fits(render.context(scene, light, sol, SMALL, cam))
        image = render.image(scene, light, sol, SMALL, ex, cam, ahead)
    finally:
        ex.close()
    np.testing.assert_array_equal(image.pixels, plain.pixels)


def test_a_plan_for_other_junctions_is_not_taken(solved):
    # the same mesh and camera, but junctions reaching further (another element size): the
    # plan made with the first settings would gather other vertices
    scene, light, sol, _ = solved
    wider = SMALL.replace(element_size=20.0)
    cam = render.camera(scene, SMALL)
    ex = InProcess(threads=2)
    try:
        ahead = render.gather_ahead(scene, light, SMALL, cam, ex)
        own = render.image(scene, light, sol, wider, ex, cam)
        assert not ahead.plan().fits(own.context)
        image = render.image(scene, light, sol, wider, ex, cam, ahead)
    finally:
        ex.close()
    assert len(render.plan_gather(own.context).vertices) != len(ahead.plan().vertices)
    np.testing.assert_array_equal(image.pixels, own.pixels)


def test_one_thread_starts_nothing_ahead(solved):
    scene, light, _, _ = solved
    ex = InProcess(threads=1)
    try:
        assert render.gather_ahead(scene, light, SMALL, render.camera(scene, SMALL), ex) is None
    finally:
        ex.close()


def _blocking_task(release: threading.Event, started: threading.Event, on: str):
    """A task returning its range, which blocks in thread ``on`` until ``release``."""
    def task(ctx, a, b):
        if threading.current_thread().name == on:
            started.set()
            assert release.wait(timeout=60)
        return (ctx, a, b)
    return task


def test_the_result_never_waits_for_the_idle_thread():
    release, started = threading.Event(), threading.Event()
    ranges = [(0, 3), (3, 5), (5, 9)]
    ex = InProcess(threads=2)
    got = []
    try:
        task = _blocking_task(release, started, "daskrad-ahead")
        work = Ahead(lambda: "plan", lambda p: p + "-ctx", lambda p: ranges, task,
                     ex.run_ranges(task))
        assert started.wait(timeout=60)        # the idle thread is inside the first range
        asking = threading.Thread(target=lambda: got.append(work.result()))
        asking.start()
        asking.join(timeout=20)                # while the idle thread is still blocked
        assert not release.is_set() and not asking.is_alive()
        # every range, in order, the blocked one computed again on the pool
        assert got == [[("plan-ctx", a, b) for a, b in ranges]]
        assert work.plan() == "plan"
    finally:
        release.set()
        ex.close()
    assert work.join(timeout=60)
    assert work.progress() in ((0, 3), (1, 3))      # it took no range after the result


def test_a_plan_that_fails_raises_where_it_is_read():
    def plan():
        raise ValueError("no plan")

    work = Ahead(plan, lambda p: p, lambda p: [(0, 1)], lambda c, a, b: a, lambda c, x: [])
    with pytest.raises(ValueError, match="no plan"):
        work.plan()
    with pytest.raises(ValueError, match="no plan"):
        work.result()


@pytest.mark.parametrize("how", ["stop", "close the executor", "close a cluster's executor"])
def test_the_work_ahead_ends_after_the_range_it_is_in(monkeypatch, how, request, tmp_path):
    release, started = threading.Event(), threading.Event()
    monkeypatch.setattr(render, "gather_vertices",
                        _blocking_task(release, started, "daskrad-ahead"))
    if how == "close a cluster's executor":
        from daskrad.distributed.dask_executor import DaskExecutor
        from daskrad.distributed.store import Store

        ex = DaskExecutor(request.getfixturevalue("cluster_client"),
                          Store(tmp_path / "a.zarr", SMALL).open())
    else:
        ex = InProcess(threads=2)
    try:
        work = ex.ahead("gather", lambda: 0, lambda p: p,
                        lambda p: [(i, i + 1) for i in range(50)])
        assert started.wait(timeout=60)
        if how == "stop":
            work.stop()
        else:
            ex.close()
        release.set()
        assert work.join(timeout=60)
        assert work.progress() == (1, 50)        # the range it was in, then no other
    finally:
        release.set()
        ex.close()


@pytest.mark.parametrize("finish", [True, False], ids=["all ahead", "asked at once"])
def test_a_cluster_client_computes_the_gather_ahead_with_the_same_bits(
        solved, cluster_client, tmp_path, monkeypatch, finish):
    # the client's thread computes the ranges ahead; those it has not finished when the
    # render asks go to the workers as gather tasks: the same bits either way. Asked at
    # once: without idle priority the thread stops after its first range, so the workers
    # have all the others, merged into fewer tasks (render.gather_merged)
    from daskrad.distributed.dask_executor import DaskExecutor
    from daskrad.distributed.store import Store

    scene, light, sol, plain = solved
    monkeypatch.setattr(executor, "idle_priority", lambda: finish)
    ex = DaskExecutor(cluster_client, Store(tmp_path / "a.zarr", SMALL).open())
    sent = []
    gather = ex.gather
    monkeypatch.setattr(ex, "gather", lambda ctx, ranges: sent.append(ranges) or
                        gather(ctx, ranges))
    try:
        cam = render.camera(scene, SMALL)
        ahead = render.gather_ahead(scene, light, SMALL, cam, ex)
        assert ahead is not None
        assert ahead.join(timeout=60)
        image = render.image(scene, light, sol, SMALL, ex, cam, ahead)
    finally:
        ex.close()
    done, n = ahead.progress()
    ranges = ahead.plan().ranges(batch=render.AHEAD_BATCH)
    assert n == len(ranges) > 2
    if finish:
        assert done == n and not sent          # the workers gathered nothing
    else:
        assert done == 1 and len(sent) == 1
        tasks = sent[0]
        assert len(tasks) < n - 1              # merged
        assert tasks[0][0] == ranges[1][0] and tasks[-1][1] == ranges[-1][1]
        assert all(a[1] == b[0] for a, b in zip(tasks[:-1], tasks[1:], strict=True))
    np.testing.assert_array_equal(image.pixels, plain.pixels)


def test_merged_gather_tasks_are_cut_back_into_their_ranges(solved):
    # gather_merged runs adjacent ranges as one task and cuts its operator back: the same
    # rows, bit for bit, as each range computed alone, across a gap between ranges too
    scene, light, _, _ = solved
    ex = InProcess(threads=2)
    try:
        plan = render.gather_ahead(scene, light, SMALL, render.camera(scene, SMALL), ex).plan()
        ranges = plan.ranges(batch=7)
        assert len(ranges) > 6
        asked = ranges[:2] + ranges[3:]            # range 2 done elsewhere: a gap
        got = render.gather_merged(plan.context, asked, ex)
    finally:
        ex.close()
    assert len(got) == len(asked)
    for (a, b), part in zip(asked, got, strict=True):
        alone = render.gather_vertices(plan.context, a, b)
        assert len(part.indptr) == b - a + 1
        for x, y in zip(part, alone, strict=True):
            np.testing.assert_array_equal(x, y)


def test_without_idle_priority_the_thread_stops_after_its_first_range(monkeypatch):
    # the first range runs at the normal priority (it loads the kernel); without SCHED_IDLE
    # the thread must not go on competing with the solve: the render computes the rest
    monkeypatch.setattr(executor, "idle_priority", lambda: False)
    ex = InProcess(threads=2)
    try:
        def task(ctx, a, b):
            return (a, b)
        work = Ahead(lambda: 0, lambda p: p, lambda p: [(i, i + 1) for i in range(20)],
                     task, ex.run_ranges(task))
        assert work.join(timeout=60)
        assert work.progress() == (1, 20)
        assert work.result() == [(i, i + 1) for i in range(20)]
    finally:
        ex.close()


def test_a_plan_made_under_other_module_settings_is_not_taken(solved, monkeypatch):
    # the disc's side (and the other settings plan_gather reads) at the render, not at the
    # plan, decide: a plan made before they changed gathers along other directions
    scene, light, sol, _ = solved
    cam = render.camera(scene, SMALL)
    ex = InProcess(threads=2)
    try:
        ahead = render.gather_ahead(scene, light, SMALL, cam, ex)
        ahead.plan()
        monkeypatch.setattr(render, "DISC_SIDE_SIMPLE", render.DISC_SIDE_SIMPLE + 2)
        own = render.image(scene, light, sol, SMALL, ex, cam)
        assert not ahead.plan().fits(own.context)
        image = render.image(scene, light, sol, SMALL, ex, cam, ahead)
    finally:
        ex.close()
    np.testing.assert_array_equal(image.pixels, own.pixels)
    assert not np.array_equal(image.pixels, solved[3].pixels)     # the side changed the image


def test_a_plan_for_other_polygons_is_not_taken(solved):
    scene, light, sol, plain = solved
    cam = render.camera(scene, SMALL)
    ex = InProcess(threads=2)
    try:
        ahead = render.gather_ahead(scene, light, SMALL, cam, ex)
        ctx = render.context(scene, light, sol, SMALL, cam)
        assert ahead.plan().fits(ctx)
        other = replace(ctx, occluders=ctx.occluders._replace())    # equal, another object
        assert not ahead.plan().fits(other)
    finally:
        ex.close()


def test_the_operator_in_blocks_gives_the_bits_of_one_operator_of_every_row(solved, rng):
    # the render applies the tasks' blocks one after the other (render.GatherBlocks) instead
    # of joining them: each row is summed in its stored order either way
    scene, light, _, _ = solved
    plan = render.plan_gather(render.geometry_context(scene, light, SMALL,
                                                      render.camera(scene, SMALL)))
    n = len(plan.vertices)
    assert n > 20
    whole = render.gather_vertices(plan.context, 0, n)
    cuts = [0, 1, 7, n // 2, n]                   # a block of one row, and uneven ones
    blocks = render.GatherBlocks([render.gather_vertices(plan.context, a, b)
                                  for a, b in zip(cuts[:-1], cuts[1:], strict=True)])
    radiance = rng.random((plan.context.n_vertices, 3))
    np.testing.assert_array_equal(blocks.mean_radiance(radiance),
                                  whole.mean_radiance(radiance))
    np.testing.assert_array_equal(blocks.excluded, whole.excluded)
    assert blocks.mean_radiance(radiance).shape == (n, 3)
    assert render.GatherBlocks([]).mean_radiance(radiance).shape == (0, 3)
