"""Ahead-of-time compiling (issue 12, item 4): the marker says when a run would compile, the
command line says so in one line, and a warm cache is really warm."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from daskrad import cli, warmup
from tests.helpers import SCENES

CORNELL = SCENES / "cornell_box.obj"


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """A copy of a marked cache directory the warmup module looks at instead of numba's."""
    d = tmp_path / "cache"
    d.mkdir()
    for name in ("a-1.py311.nbi", "a-1.py311.1.nbc", "b-7.py311.nbi"):
        (d / name).write_bytes(b"x")
    (d / warmup.MARKER).write_text(json.dumps({
        "environment": warmup.environment(), "index": ["a-1.py311.nbi", "b-7.py311.nbi"],
        "seconds": 12.3}))
    monkeypatch.setattr(warmup, "cache_dir", lambda: d)
    return d


def test_marker_matching_the_sources_and_the_cache_is_warm(cache):
    assert warmup.is_warm()
    assert warmup.expected_seconds() == 12


def test_a_missing_cache_file_makes_it_cold(cache):
    (cache / "b-7.py311.nbi").unlink()           # the Makefile's find drops them all
    assert not warmup.is_warm()


def test_an_edited_kernel_source_makes_it_cold(cache, monkeypatch):
    stamps = warmup.kernel_stamps()
    name = sorted(stamps)[0]
    stamps[name] = [stamps[name][0] + 1, stamps[name][1]]     # touched: numba recompiles it
    monkeypatch.setattr(warmup, "kernel_stamps", lambda: stamps)
    assert not warmup.is_warm()


def test_no_marker_is_cold_and_drop_cache_removes_code_and_marker(cache):
    assert warmup.drop_cache(cache) == 4
    assert sorted(os.listdir(cache)) == []
    assert not warmup.is_warm()


def test_a_cold_run_says_so_in_one_line_then_runs(tmp_path, monkeypatch, capsys):
    calls = []
    monkeypatch.setattr(warmup, "is_warm", lambda: False)
    monkeypatch.setattr(warmup, "warmup", lambda verbose=True: calls.append(verbose))
    monkeypatch.setattr(warmup, "expected_seconds", lambda: 37)
    out = tmp_path / "c.exr"
    code = cli.main(["run", str(CORNELL), "-o", str(out), "-q", "--max-iterations", "8",
                     "--width", "16", "--height", "16", "--workers", "0"])
    assert code == 0 and calls == [False] and out.exists()
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "daskrad: compiling kernels (first run, ~37 s)..."
    assert not any("compiling" in line for line in err[1:])


def test_bad_input_on_a_cold_cache_is_still_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(warmup, "is_warm", lambda: False)
    monkeypatch.setattr(warmup, "warmup", lambda verbose=True: pytest.fail("compiled"))
    code = cli.main(["run", str(CORNELL), "-o", str(tmp_path / "missing" / "c.exr"), "-q"])
    assert code == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("daskrad: error:")


@pytest.mark.slow
def test_warmup_leaves_nothing_to_compile_for_a_default_run(tmp_path):
    # after `daskrad warmup` into an empty cache (a minute of compiling: slow), the Cornell
    # box at default settings (small image) writes no new compiled code: every kernel it
    # calls was compiled for the types it passes
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"))
    done = subprocess.run([sys.executable, "-m", "daskrad", "warmup"], env=env,
                          capture_output=True, text=True, timeout=1200)
    assert done.returncode == 0, done.stderr
    before = {p: p.stat().st_mtime_ns for p in (tmp_path / "numba").rglob("*.nb*")}
    assert before
    run = subprocess.run([sys.executable, "-m", "daskrad", "run", str(CORNELL), "-o",
                          str(tmp_path / "c.exr"), "-q", "--width", "32", "--height", "32"],
                         env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert "compiling" not in run.stderr
    after = {p: p.stat().st_mtime_ns for p in (tmp_path / "numba").rglob("*.nb*")}
    assert after == before


_MISSES = """
import gc, sys
from numba.core.registry import CPUDispatcher
from daskrad.run import run
from daskrad.settings import Settings
run(sys.argv[1], sys.argv[2], Settings(workers=0, width=64, height=64), progress=False)
print(sorted(d.py_func.__qualname__ for d in gc.get_objects()
             if isinstance(d, CPUDispatcher) and d.py_func.__module__.startswith("daskrad")
             and sum(d.stats.cache_misses.values())))
"""


@pytest.mark.skipif(not warmup.is_warm(), reason="the kernel cache is not warm (make install "
                    "warms it)")
def test_a_run_on_the_warm_cache_compiles_no_kernel(tmp_path):
    # the fast twin of the slow test above, on the cache `make install` warmed: a default run
    # of the Cornell box (its blocks hide the light from per-pixel elements: the hidden-light
    # proof runs) misses numba's cache for no kernel. The kernels of that proof were once left
    # out of the warmup and compiled silently in the first run
    done = subprocess.run([sys.executable, "-c", _MISSES, str(CORNELL), str(tmp_path / "c.exr")],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "[]"
