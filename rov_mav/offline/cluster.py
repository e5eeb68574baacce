"""Dask distributed backend for the tuner: batches of closed-loop runs shipped to a cluster as tasks.

`local:N` starts a LocalCluster of N single-threaded worker processes on the loopback interface;
`tcp://HOST:PORT` connects to a running scheduler. The problem (reference, models, scenarios) is sent to every
worker once per tune; each iteration then ships only the gain batches. Runs are seeded and independent, so the
costs equal the in-process backend's bit for bit.
"""

from __future__ import annotations

from collections.abc import Sequence

from rov_mav.config import ConfigError
from rov_mav.offline.tuning import Batch, TuningProblem


def _run(problem: TuningProblem, batch: Batch):
    return problem.run(*batch)


class DaskBackend:
    """A `tuning.Backend` on Dask workers."""

    def __init__(self, address: str):
        try:
            from dask.distributed import (  # optional dependency: imported only when used
                Client,
                LocalCluster,
            )
        except ImportError:
            raise ConfigError("--cluster needs Dask, which is not installed: pip install 'rov-mav[cluster]'") \
                from None

        self._cluster = None
        if address.startswith("local:"):
            workers = int(address.removeprefix("local:"))
            self._cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                         host="127.0.0.1", dashboard_address=None)
            self._client = Client(self._cluster)
        else:
            self._client = Client(address)
        self.workers = max(1, sum(self._client.nthreads().values()))
        self._scattered: tuple[TuningProblem, object] | None = None   # the problem and its future on the workers

    def map_runs(self, problem: TuningProblem, batches: Sequence[Batch]) -> list:
        if self._scattered is None or self._scattered[0] is not problem:
            self._scattered = (problem, self._client.scatter(problem, broadcast=True))
        futures = self._client.map(_run, [self._scattered[1]] * len(batches), batches, pure=False)
        return self._client.gather(futures)

    def close(self) -> None:
        self._client.close()
        if self._cluster is not None:
            self._cluster.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
