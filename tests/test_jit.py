"""The leaves' contract (daskrad/kernels/_jit.py): kernels compiled without reference counts
allocate nothing, return no array and call only leaves."""

from __future__ import annotations

import importlib.util
import types

import numba
import pytest

from daskrad.kernels import array_returns, direct, grid, is_leaf
from daskrad.warmup import leaf_violations


def test_the_kernels_keep_the_contract():
    # statically, every leaf's callees; and the result types of every leaf compiled here
    assert leaf_violations() == []


def test_the_shadow_rays_path_is_leaves():
    # what the per-pixel pass and the vertex pass run per shadow ray: the measured reason for
    # the leaves (benchmarks/bench_leaves.py)
    for fn in (grid.intersect, grid.any_hit_cached, grid.any_hit_fan, grid.any_hit_one,
               grid.closest_hit_one, grid.locate_hit, direct.hash01):
        assert is_leaf(fn), fn.__name__
    # kernels that allocate stay counted
    assert not is_leaf(grid.new_fan)
    assert not is_leaf(direct.irradiance_one)


def _kernels(tmp_path, source: str) -> types.ModuleType:
    """A module of kernels made from ``source`` (a file, for numba's cache to have a place;
    none is compiled here)."""
    path = tmp_path / "fake.py"
    path.write_text("import numpy as np\nfrom daskrad.kernels import jit, jit_leaf\n\n"
                    + source)
    spec = importlib.util.spec_from_file_location("daskrad.kernels.fake", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_leaf_calling_a_counted_kernel_is_found(tmp_path):
    module = _kernels(
        tmp_path,
        "@jit\ndef counted(n):\n    return np.zeros(n)\n\n"
        "@jit_leaf\ndef leaf(n):\n    return counted(n)[0]\n")
    assert leaf_violations([module]) == ["fake.leaf calls the counted kernel counted"]


def test_a_leaf_calling_leaves_only_passes(tmp_path):
    module = _kernels(
        tmp_path,
        "@jit_leaf\ndef inner(a, i):\n    return a[i] * 2.0\n\n"
        "@jit_leaf\ndef outer(a):\n    return inner(a, 0) + inner(a, 1)\n")
    assert is_leaf(module.outer)
    assert leaf_violations([module]) == []


@pytest.mark.parametrize("returns, bad", [("a", True), ("(a, 1.0)", True), ("a[0]", False),
                                         ("(a[0], a.shape[0])", False)])
def test_an_array_result_is_found(returns, bad):
    # compiled, never called: returned from a leaf, the array would be freed under its owner
    ns = {}
    exec(f"def f(a):\n    return {returns}\n", ns)
    d = numba.njit(_nrt=False)(ns["f"])
    d.compile((numba.float64[:],))
    assert bool(array_returns(d)) is bad
