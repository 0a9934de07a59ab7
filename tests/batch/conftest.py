"""One local Dask cluster for the batch tests (2 worker processes, one thread each, as ``mimetic batch``
starts it), so its workers warm up once; skipped without the ``[batch]`` extra, except on CI."""

from __future__ import annotations

import logging

import pytest

from mimetic.testing import require_extra


@pytest.fixture(scope="session")
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


@pytest.fixture(scope="session")
def client(cluster):
    import distributed

    with distributed.Client(cluster) as connected:
        yield connected
