"""Before pytest-xdist starts its workers: fill numba's on-disk cache with the in-house kernels,
the compile work split over two processes (crosscheck.warmup).

Without it both workers compile the same kernels at the same time on a cold cache (numba has no
lock between processes): the 3D contact step's two minutes are paid twice, by both cores. Here
both cores compile different kernels and the workers then load them. Only in the xdist controller
with two or more workers; a plain ``pytest`` (one process) is left as it was. Nothing is checked
here: a warm-up that fails or is killed is reported in the summary and the tests run as they
would have, compiling what is missing. ``CROSSCHECK_WARMUP=0`` turns it off.
"""

from __future__ import annotations

import os
import time

import pytest

_RESULT: list[str] = []


def _wanted(config) -> bool:
    if os.environ.get("CROSSCHECK_WARMUP", "1") == "0" or hasattr(config, "workerinput"):
        return False
    if getattr(config.option, "dist", "no") == "no" or config.option.collectonly:
        return False
    n = getattr(config.option, "numprocesses", None)
    return isinstance(n, int) and n >= 2


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session):
    config = session.config
    if not _wanted(config):
        return
    from crosscheck import warmup

    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line("crosscheck: warming numba's cache in 2 processes "
                            "(crosscheck.warmup; CROSSCHECK_WARMUP=0 skips)")
    t0 = time.perf_counter()
    try:
        results = warmup.warm(parts=2)
    except Exception as exc:  # never in the way of the tests
        _RESULT.append(f"crosscheck: numba warm-up not run: {type(exc).__name__}: {exc}")
        return
    _RESULT.append(f"crosscheck: numba warm-up {time.perf_counter() - t0:.1f} s: " + "; ".join(
        f"part {i} exit {code} after {seconds:.1f} s" for i, (code, seconds, _) in
        enumerate(results)))
    for i, (code, _, err) in enumerate(results):
        if code != 0 and err:
            _RESULT.append(f"crosscheck: warm-up part {i} said:\n{err}")


def pytest_terminal_summary(terminalreporter):
    for line in _RESULT:
        terminalreporter.write_line(line)
