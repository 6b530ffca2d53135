"""Where the suite's tests run under pytest-xdist (`make test`: two workers).

The in-house contact kernels (sim/collide and the contact models of sim/rigid) take most of the
suite's cold numba compile, and numba's on-disk cache only helps a worker that starts a kernel
after another has written it. With xdist's default distribution both workers began with tests
that compile the 3D collision pipeline and compiled it at the same time: 53 signatures, 162 s of
the two workers' 628 s of compiling were done twice (profiled 2026-11-30 on a cold cache: each
worker's numba compile events, exclusive times, by test).

So the files that compile those kernels first run as one unit on one worker, at the start, and
the other tests that use the kernels run last, when the unit has written them to the cache; the
other worker meanwhile takes what never touches them (fluid, engines, reports, runner) one test
at a time. Only placement changes: every test runs, and none depends on another's order.

The unit is made by a scheduler of our own (xdist's ``pytest_xdist_make_scheduler`` hook): its
``loadgroup`` mode, which would read an ``xdist_group`` mark, groups nothing under pytest 9.2
(pytest-xdist issue 1386: the node-id suffix it relies on no longer takes).
"""

from __future__ import annotations

import pytest

# The files that compile the contact kernels (each worker's profile: the first to compile
# detect3d / _pairs3d / gjk / epa / step3d / step2d / the contact effect sets of the integrators).
COMPILE_FIRST = (
    "tests/collide/test_box_box.py",
    "tests/collide/test_broadphase.py",
    "tests/collide/test_collide_pair3d.py",
    "tests/collide/test_detect.py",
    "tests/contact_inhouse/test_velocity_models.py",
    "tests/contact_models/test_case_runs_conservation.py",
)
# The other tests of these directories use the same kernels: after the unit, at the end.
USE_LATER = ("tests/collide/", "tests/contact_inhouse/", "tests/contact_models/")
UNIT = "contact-kernels"


def _place(nodeid: str) -> int:
    path = nodeid.split("::")[0]
    if path in COMPILE_FIRST:
        return 0
    return 2 if path.startswith(USE_LATER) else 1


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    items.sort(key=lambda item: _place(item.nodeid))   # stable: each file keeps its order


@pytest.hookimpl(optionalhook=True)   # xdist's hook: without xdist (-p no:xdist) it is unknown
def pytest_xdist_make_scheduler(config, log):
    if config.getvalue("dist") != "load":
        return None   # an explicit other mode (loadfile, worksteal, ...) is left to xdist
    from xdist.scheduler import LoadScopeScheduling

    class ContactKernelsFirst(LoadScopeScheduling):
        """xdist's scope scheduler with one scope for the unit's tests and one per test
        elsewhere: the unit goes whole to the first worker, the rest test by test to whichever
        worker is free (scopes in collection order)."""

        def _split_scope(self, nodeid: str) -> str:
            return UNIT if _place(nodeid) == 0 else nodeid

    return ContactKernelsFirst(config, log)
