"""A local Dask cluster for each batch test module (2 worker processes, one thread each, as ``mimetic
batch`` starts it), so its workers warm up once per module; skipped without the ``[batch]`` extra,
except on CI. Not one for the session: an idle cluster's heartbeats take about a fifth of a core,
and its scheduler shares the test process's interpreter, for the rest of the suite."""

from __future__ import annotations

import logging

import pytest

from mimetic.testing import require_extra


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
