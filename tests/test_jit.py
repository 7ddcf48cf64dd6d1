"""The leaves' contract (daskrad/kernels/_jit.py): kernels compiled without reference counts
allocate nothing, return no array and call only leaves."""

from __future__ import annotations

import importlib.util
import types

import numba
import numpy as np
import pytest

from daskrad.kernels import LEAF_REFCOUNTS, direct, grid, is_leaf, leaf_faults
from daskrad.warmup import leaf_violations


def test_the_kernels_keep_the_contract():
    # statically, every leaf's callees; and the result types of every leaf compiled here
    # (all of them, with their code, when `daskrad warmup` fills an empty cache: make install)
    assert leaf_violations() == []


@pytest.mark.skipif(LEAF_REFCOUNTS, reason="the leaves are counted: nothing to check")
def test_shadow_ray_leaves_compile_without_reference_counts():
    # fresh copies of two leaves of the shadow rays' path, compiled here (the cache's copies
    # cannot be read): their code and their callees' hold no reference count
    from daskrad.kernels.grid import build_grid

    g = build_grid(np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]]))
    v = numba.float64
    for fn, sig in ((grid.intersect, (numba.typeof(g.triangles), numba.int64) + (v,) * 9),
                    (grid.any_hit_one, (numba.typeof(g), v[::1], v[::1], v, v))):
        fresh = numba.njit(_nrt=False)(fn.py_func)
        fresh.compile(sig)
        assert leaf_faults(fresh) == []


def test_the_shadow_rays_path_is_leaves():
    # what the per-pixel pass and the vertex pass run per shadow ray: the measured reason for
    # the leaves (benchmarks/bench_leaves.py)
    for fn in (grid.intersect, grid.any_hit_cached, grid.any_hit_fan, grid.any_hit_one,
               grid.closest_hit_one, grid.locate_hit, direct.hash01, direct.irradiance_one):
        assert is_leaf(fn), fn.__name__
    # kernels that allocate stay counted
    assert not is_leaf(grid.new_fan)
    assert not is_leaf(direct.new_scratch)
    assert not is_leaf(direct.irradiance_points)


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


@pytest.mark.parametrize("returns, bad", [("a", True), ("(a, 1.0)", True),
                                         ("a if a[0] > 0 else None", True), ("a[0]", False),
                                         ("(a[0], a.shape[0])", False)])
def test_an_array_result_is_found(returns, bad):
    # compiled, never called: returned from a leaf, the array would be freed under its owner
    ns = {}
    exec(f"def f(a):\n    return {returns}\n", ns)
    d = numba.njit(_nrt=False)(ns["f"])
    d.compile((numba.float64[:],))
    assert any("holds an array" in f for f in leaf_faults(d)) is bad


@pytest.mark.skipif(LEAF_REFCOUNTS, reason="the leaves are counted: nothing to find")
def test_reference_counts_in_a_leaf_are_found():
    # a view of an argument, bound and passed on: counted under numba's defaults, not in a
    # leaf (compiled here, so its code can be read)
    ns = {}
    exec("def f(a, i):\n    row = a[i]\n    return g(row)\n", ns)
    ns["g"] = numba.njit(_nrt=False)(lambda r: r[0] + r[1])     # a leaf, as the rule asks
    counted = numba.njit(_nrt=True)(ns["f"])
    counted.compile((numba.float64[:, :], numba.int64))
    leaf = numba.njit(_nrt=False)(ns["f"])
    leaf.compile((numba.float64[:, :], numba.int64))
    assert any("counts references" in f for f in leaf_faults(counted))
    assert leaf_faults(leaf) == []


def test_a_leaf_calling_through_a_module_or_a_tuple_is_found(tmp_path):
    module = _kernels(
        tmp_path,
        "import daskrad.kernels.direct as D\n\n"
        "PAIR = (D.irradiance_points, D.hash01)\n\n"
        "@jit_leaf\ndef by_module(a):\n    return D.irradiance_points(a)\n\n"
        "@jit_leaf\ndef by_tuple(a):\n    return PAIR[0](a)\n\n"
        "@jit_leaf\ndef nested(a):\n    return [D.irradiance_points(x) for x in a]\n")
    found = leaf_violations([module])
    assert "fake.by_module calls the counted kernel D.irradiance_points" in found
    assert "fake.by_tuple calls the counted kernel PAIR[0]" in found
    assert "fake.nested calls the counted kernel D.irradiance_points" in found
    assert not any("hash01" in f for f in found)       # a leaf in the tuple
