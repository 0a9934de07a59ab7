"""A local Dask cluster for each batch test module (2 worker processes, one thread each, as ``mimetic
batch`` starts it), so its workers warm up once per module; skipped without the ``[batch]`` extra,
except on CI. Not one for the session: an idle cluster's heartbeats take about a fifth of a core,
and its scheduler shares the test process's interpreter, for the rest of the suite.

``loopback`` starts a cluster as on several machines instead: ``dask scheduler`` and two ``dask
worker`` processes of their own on 127.0.0.1 (``mimetic.testing.cluster``), once per module."""

from __future__ import annotations

import logging
from collections.abc import Iterator

import pytest

from mimetic.testing import require_extra
from mimetic.testing.cluster import Loopback, loopback_cluster


@pytest.fixture(scope="module")
def cluster():
    distributed = require_extra("distributed", "batch")
    from mimetic.batch.jobs import WORKER_THREADS

    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
        env=WORKER_THREADS,
    ) as local:
        yield local


@pytest.fixture(scope="module")
def client(cluster):
    import distributed

    with distributed.Client(cluster) as connected:
        yield connected


@pytest.fixture(scope="module")
def loopback(tmp_path_factory) -> Iterator[Loopback]:
    """A scheduler and two workers as separate processes on 127.0.0.1 (``loopback_cluster``)."""
    require_extra("distributed", "batch")
    with loopback_cluster(tmp_path_factory.mktemp("loopback")) as cluster:
        yield cluster
