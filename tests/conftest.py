"""Shared fixtures: one seeded RNG per test, one Dask cluster for the whole session."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.helpers import SCENES


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator, so a failing random case fails again the same way."""
    return np.random.default_rng(20261122)


@pytest.fixture(scope="session")
def cluster_client():
    """One 2-worker LocalCluster for every test that needs Dask (started lazily, ~1.5 s)."""
    from distributed import Client, LocalCluster

    cluster = LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        env={"NUMBA_NUM_THREADS": "1"},
    )
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()


@pytest.fixture
def scenes_dir() -> Path:
    return SCENES
