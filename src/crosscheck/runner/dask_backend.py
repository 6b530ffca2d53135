"""Dask distributed backend (``crosscheck run --scheduler ADDRESS``).

Each task is submitted to the cluster as :func:`crosscheck.runner.isolated.run_isolated`, which
executes the cell in a fresh child interpreter on the worker machine with the cell's wall-time
limit, so an engine segfault or hang costs that cell only (a Dask worker itself never crashes
and its nanny never has to restart it). Should a worker die anyway, Dask's own error for that
future becomes the cell's ``error`` result. Tasks a reference run depends on are submitted first;
cells that need a shared reference are submitted when it is ready (the scheduler in
:mod:`crosscheck.runner` does this for every backend). Reference files are written under the
output folder, so a multi-machine cluster needs that folder on a shared file system.
"""

from __future__ import annotations

import sys
import time
import uuid
from typing import Any

from crosscheck.runner.cell import base_result


def _run_remote(task: dict[str, Any]) -> dict[str, Any]:  # pragma: no cover - runs on a worker
    from crosscheck.runner.isolated import run_isolated

    return run_isolated(task)


class DaskBackend:
    name = "dask"

    def __init__(self, address: str, connect_timeout: float = 30.0):
        from distributed import Client

        self.address = address
        self.client = Client(address, timeout=connect_timeout, set_as_default=False)
        info = self.client.scheduler_info()
        self.workers = sum(w.get("nthreads", 1) for w in info.get("workers", {}).values()) or 1
        self._futures: dict[Any, dict[str, Any]] = {}
        self.peak_rss_total_mb = 0.0
        self._last_sample = 0.0

    def free(self) -> bool:
        return True  # the Dask scheduler queues; results are small

    def busy(self) -> int:
        return len(self._futures)

    def submit(self, task: dict[str, Any]) -> None:
        task = dict(task, sys_path=[p for p in sys.path if p])
        fut = self.client.submit(_run_remote, task, pure=False, retries=0,
                                 key=f"crosscheck-{uuid.uuid4().hex}")
        self._futures[fut] = task

    def poll(self, timeout: float) -> list[tuple[dict[str, Any], dict[str, Any]]]:
        if not self._futures:
            return []
        # Futures report done() from the client's own event loop; a short sleep loop avoids
        # distributed.wait(), which wants a default client (and we do not set one globally).
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and not any(f.done() for f in self._futures):
            time.sleep(0.05)
        done = []
        for fut in [f for f in self._futures if f.done()]:
            task = self._futures.pop(fut)
            try:
                result = fut.result()
            except Exception as exc:  # KilledWorker, cancelled, lost connection...
                result = base_result(task)
                result.update(status="error", reason=f"dask: {type(exc).__name__}: {exc}")
            done.append((task, result))
        self.sample_memory()
        return done

    def sample_memory(self, force: bool = False) -> None:
        """Memory of the cluster's workers as their nannies report it (psutil on each machine).

        Cells run in child processes of the workers, which this does not see; each cell reports
        its own peak (``peak_rss_mb``) and the report shows the largest."""
        now = time.monotonic()
        if not force and now - self._last_sample < 1.0:
            return
        self._last_sample = now
        try:
            info = self.client.scheduler_info()
            total = sum(w.get("metrics", {}).get("memory", 0)
                        for w in info.get("workers", {}).values())
            self.peak_rss_total_mb = max(self.peak_rss_total_mb, total / 2**20)
        except Exception:
            pass

    def shutdown(self, kill: bool = False) -> None:
        if kill and self._futures:
            self.client.cancel(list(self._futures), force=True)
        self._futures.clear()
        self.client.close()
