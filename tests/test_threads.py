"""Both cores in-process (issue 12, item 1): the thread pool of :class:`InProcess` runs a
batch's shooters, the tiles and the direct-light ranges side by side, with the same bits as one
thread."""

from __future__ import annotations

import numpy as np
import pytest

from daskrad.distributed.executor import InProcess, default_threads
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from tests.helpers import SCENES, steps_on
from tests.helpers import SMALL_RUN as SMALL


def _steps(scene_name: str, threads: int):
    return steps_on(scene_name, threads)[1:]


@pytest.mark.parametrize("scene_name", ["cornell_box.obj", "lit_room.obj"])
def test_one_and_two_threads_give_the_same_bits(scene_name):
    one = _steps(scene_name, 1)
    two = _steps(scene_name, 2)
    assert one[1].iteration == two[1].iteration > 8          # several batches, re-shots
    np.testing.assert_array_equal(one[0].irradiance, two[0].irradiance)
    np.testing.assert_array_equal(one[1].radiosity, two[1].radiosity)
    np.testing.assert_array_equal(one[1].unshot, two[1].unshot)
    assert [h[:2] for h in one[1].history] == [h[:2] for h in two[1].history]
    np.testing.assert_array_equal(one[2].pixels, two[2].pixels)
    assert one[2].context.extras          # the per-pixel pass ran (hard lights, eq. 9)


def test_rows_come_back_in_shooter_order_from_the_pool():
    scene = load_scene(SCENES / "cornell_box.obj")
    mesh = preprocess(scene, SMALL)
    from daskrad.formfactor import shooting

    ctx = shooting.make_context(mesh.hierarchy, "hemisphere", 32, grid=mesh.grid,
                                tri_element=mesh.tri_element)
    ids = np.array([5, 0, 17, 3, 9])
    serial = shooting.shoot_rows(ctx, ids)
    ex = InProcess(threads=3)
    try:
        ex.set_geometry(ctx)
        pooled = ex.shots(0, ids).result()
        again = ex.shots(1, ids[::-1]).result()            # from the row cache now
    finally:
        ex.close()
    for (a_ids, a_f), (b_ids, b_f) in zip(serial, pooled, strict=True):
        np.testing.assert_array_equal(a_ids, b_ids)
        np.testing.assert_array_equal(a_f, b_f)
    for (a_ids, a_f), (b_ids, b_f) in zip(serial[::-1], again, strict=True):
        np.testing.assert_array_equal(a_ids, b_ids)
        np.testing.assert_array_equal(a_f, b_f)
    assert ex.rows.hits == len(ids)


def test_default_is_every_core_this_process_may_use():
    assert InProcess().threads == default_threads() >= 1
    assert InProcess(threads=1).threads == 1


def test_rows_prefetched_on_idle_threads_are_taken_by_the_batch_that_shoots_them():
    # solve's prefetch: an idle pool computes the offered rows ahead (one per idle thread);
    # the batch that shoots those patches takes their futures instead of computing them again,
    # and gets the bits of a serial computation. An offer without a patch lets its row go.
    from daskrad.formfactor import shooting

    scene = load_scene(SCENES / "cornell_box.obj")
    mesh = preprocess(scene, SMALL)
    ctx = shooting.make_context(mesh.hierarchy, "hemisphere", 32, grid=mesh.grid,
                                tri_element=mesh.tri_element)
    serial = shooting.shoot_rows(ctx, np.array([4, 7]))
    ex = InProcess(threads=2)
    try:
        ex.set_geometry(ctx)
        ex.prefetch(np.array([4, 7, 9]))
        assert ex.prefetched >= 2                  # both threads were idle
        for f in list(ex._ahead.values()):
            f.result()
        misses = ex.rows.misses                    # the rows computed ahead
        rows = ex.shots(0, np.array([4, 7])).result()
        assert ex.rows.misses == misses            # nothing computed again
        for a, b in zip(rows, serial, strict=True):
            for x, y in zip(a, b, strict=True):
                np.testing.assert_array_equal(x, y)
        ex.prefetch(np.zeros(0, np.int64))
        assert not ex._ahead
    finally:
        ex.close()
