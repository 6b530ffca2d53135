"""Local parallel backend: long-lived worker processes (spawned), one cell at a time each.

Why not ``concurrent.futures.ProcessPoolExecutor``: when one of its workers dies (a segfault in an
engine) the whole pool is broken and every pending cell is lost, and it cannot stop one hung
task. Here the parent owns each worker and its pipe, so

* a worker that dies mid-cell (crash, ``os._exit``, signal) gives that cell an ``error`` result
  naming the exit code or signal, and a fresh worker takes the next cell;
* a cell running past its timeout has its worker killed (SIGKILL) and gets ``timeout``;
* Ctrl-C reaches only the parent (workers ignore SIGINT), which stops, kills the workers and lets
  the caller write the report of everything already computed.

Workers are started with the ``spawn`` method (no inherited locks or engine state from the
parent). A worker whose resident memory has grown past ``max_worker_rss_mb`` (default 768 MiB:
compiled kernels and engine state accumulate over hundreds of cells) is replaced after its cell,
so the run's memory is bounded by the number of workers, not the number of cells. The parent
samples the resident memory of itself and all its child processes with psutil about twice a
second and keeps the peak of the sum: the run's peak memory.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import time
from multiprocessing.connection import wait
from typing import Any

from crosscheck.runner.cell import base_result


def _worker_main(conn) -> None:  # pragma: no cover - runs in the child process
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides when to stop
    # Engines print from C (PyBullet's build banner): keep the parent's stdout for progress
    # lines and the tables, send whatever a worker prints to stderr.
    try:
        sys.stdout.flush()
        os.dup2(2, 1)
    except OSError:
        pass
    from crosscheck.runner.cell import execute_task

    while True:
        try:
            task = conn.recv()
        except (EOFError, OSError):
            return
        if task is None:
            return
        conn.send(execute_task(task))


def describe_exit(code: int | None) -> str:
    if code is None:
        return "worker process ended without a result"
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"worker process killed by {name}"
    return f"worker process exited with status {code} before returning a result"


class _Slot:
    def __init__(self):
        self.proc = None
        self.conn = None
        self.task: dict[str, Any] | None = None
        self.deadline = 0.0
        self.started = 0.0
        self.round = 0  # the cost round its process was started for (see submit)


class LocalBackend:
    name = "local"

    def __init__(self, workers: int | None = None, max_worker_rss_mb: float | None = 768.0):
        self.workers = max(1, int(workers or os.cpu_count() or 1))
        # A worker whose resident memory exceeds this after a cell is replaced before its next
        # one: compiled kernels (numba) and engine state accumulate over hundreds of cells.
        self.max_worker_rss_mb = max_worker_rss_mb
        self.recycled = 0
        self.fresh_for_cost = 0  # processes started for a new cost round (submit)
        self._ctx = mp.get_context("spawn")
        self._slots = [_Slot() for _ in range(self.workers)]
        self.peak_rss_total_mb = 0.0
        self._last_sample = 0.0

    # -- lifecycle -----------------------------------------------------------------------------
    def _start(self, slot: _Slot) -> None:
        parent, child = self._ctx.Pipe(duplex=True)
        proc = self._ctx.Process(target=_worker_main, args=(child,), daemon=True,
                                 name="crosscheck-worker")
        proc.start()
        child.close()
        slot.proc, slot.conn = proc, parent

    def _discard(self, slot: _Slot, kill: bool) -> None:
        if slot.proc is not None:
            if kill and slot.proc.is_alive():
                slot.proc.kill()
            slot.proc.join(timeout=5)
        if slot.conn is not None:
            slot.conn.close()
        slot.proc = slot.conn = None
        slot.task = None

    def shutdown(self, kill: bool = False) -> None:
        for slot in self._slots:
            if slot.proc is None:
                continue
            if kill or slot.task is not None:
                self._discard(slot, kill=True)
                continue
            try:
                slot.conn.send(None)
            except (OSError, BrokenPipeError):
                pass
            self._discard(slot, kill=False)

    # -- scheduling ----------------------------------------------------------------------------
    def free(self) -> bool:
        return any(s.task is None for s in self._slots)

    def busy(self) -> int:
        return sum(s.task is not None for s in self._slots)

    def submit(self, task: dict[str, Any]) -> None:
        # A cell's extra cost passes carry their round (runner/cell.py cost_followups): pass r
        # runs in a process started for round r, so that a cell's passes land in as many
        # processes (each with its own code and array placement) as it has passes. A free
        # worker of that round is preferred; another is retired and started afresh.
        rnd = int(task.get("process_round") or 0)
        free = [s for s in self._slots if s.task is None]
        slot = next((s for s in free if s.round == rnd), free[0])
        if rnd and slot.round != rnd:
            if slot.proc is not None and slot.proc.is_alive():
                self._retire(slot)
            self.fresh_for_cost += 1
            slot.round = rnd
        if slot.proc is None or not slot.proc.is_alive():
            self._discard(slot, kill=True)
            self._start(slot)
        try:
            slot.conn.send(task)
        except OSError:  # the idle worker died (e.g. the OOM killer): one fresh try
            self._discard(slot, kill=True)
            self._start(slot)
            slot.conn.send(task)
        slot.task = task
        slot.started = time.monotonic()
        slot.deadline = slot.started + float(task.get("timeout") or 600.0)

    def poll(self, timeout: float) -> list[tuple[dict[str, Any], dict[str, Any]]]:
        busy = [s for s in self._slots if s.task is not None]
        if not busy:
            time.sleep(min(timeout, 0.05))
            return []
        now = time.monotonic()
        nearest = min(s.deadline for s in busy) - now
        handles = [s.conn for s in busy] + [s.proc.sentinel for s in busy]
        wait(handles, timeout=max(0.0, min(timeout, nearest)))
        done = []
        for slot in busy:
            task = slot.task
            if slot.conn.poll():
                try:
                    done.append((task, slot.conn.recv()))
                    slot.task = None
                    self._recycle_if_large(slot)
                    continue
                except (EOFError, OSError):
                    pass  # the pipe closed: the worker died; reported below
            if not slot.proc.is_alive() or slot.conn.closed:
                slot.proc.join(timeout=1)
                result = base_result(task)
                result.update(status="error", reason=describe_exit(slot.proc.exitcode),
                              cell_seconds=time.monotonic() - slot.started)
                done.append((task, result))
                self._discard(slot, kill=True)
            elif time.monotonic() > slot.deadline:
                result = base_result(task)
                limit = float(task.get("timeout") or 600.0)
                result.update(status="timeout",
                              reason=f"no result after {limit:g} s wall time; worker killed",
                              cell_seconds=time.monotonic() - slot.started)
                done.append((task, result))
                self._discard(slot, kill=True)
        self.sample_memory()
        return done

    def _recycle_if_large(self, slot: _Slot) -> None:
        if self.max_worker_rss_mb is None or slot.proc is None:
            return
        self.sample_memory(force=True)  # catch the peak before the worker goes
        if tree_rss_mb(slot.proc.pid) > self.max_worker_rss_mb:
            self._retire(slot)
            self.recycled += 1

    def _retire(self, slot: _Slot) -> None:
        """Ask an idle worker to exit (None ends its loop) and drop its slot's process."""
        try:
            slot.conn.send(None)
        except OSError:
            pass
        self._discard(slot, kill=False)

    def sample_memory(self, force: bool = False) -> None:
        now = time.monotonic()
        if not force and now - self._last_sample < 0.5:
            return
        self._last_sample = now
        self.peak_rss_total_mb = max(self.peak_rss_total_mb, tree_rss_mb())


def tree_rss_mb(pid: int | None = None) -> float:
    """Resident memory of a process and all its descendants, MiB (psutil)."""
    import psutil

    try:
        root = psutil.Process(pid or os.getpid())
        procs = [root] + root.children(recursive=True)
    except psutil.Error:
        return 0.0
    total = 0
    for p in procs:
        try:
            total += p.memory_info().rss
        except psutil.Error:
            pass
    return total / 2**20
