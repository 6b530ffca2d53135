"""Where the suite's tests run under pytest-xdist (`make test`: two workers).

Compiling takes about half of the suite's CPU time on a cold numba cache, and numba's on-disk
cache only helps a worker that starts a kernel after another has written it. Two workers that
meet the same kernel at the same time both compile it. With xdist's default distribution that
happened to 53 signatures of the 3D collision pipeline (162 s of the two workers' 628 s of
compiling; profiled 2026-11-30 on a cold cache: each worker's numba compile events, exclusive
times, by test), and, once those were placed, to the rigid integrators' specialisations (one per
integrator and effect set), which tests/rigid/test_control.py's parameters and the other rigid
files' compiled on both workers at once (67 s).

So the suite runs in four groups, in this order:

1. the files that first compile the contact kernels (sim/collide and the contact models of
   sim/rigid), as one unit on one worker;
2. the files that first compile the integrators' specialisations, as a second unit on the
   other worker;
3. the tests that touch neither, one file at a time, on whichever worker is free: a file's tests
   share compiled specialisations and expensive runs (each worker of tests/fluid kept its own
   copy of a run its tests share); test_validation.py and test_solver.py share the fluid runs
   of tests/fluid/conftest.py and go together;
4. the other tests of the contact directories, which use the first unit's kernels, last and one
   test at a time (which balances the two workers' ends).

Only placement changes: every test runs, and none depends on another's order.

The units are made by a scheduler of our own (xdist's ``pytest_xdist_make_scheduler`` hook): its
``loadgroup`` mode, which would read an ``xdist_group`` mark, groups nothing under pytest 9.2
(pytest-xdist issue 1386: the node-id suffix it relies on no longer takes).
"""

from __future__ import annotations

import pytest

# The files that compile the contact kernels (each worker's profile: the first to compile
# detect3d / _pairs3d / gjk / epa / step3d / step2d / the contact effect sets of the integrators).
CONTACT_UNIT = (
    "tests/collide/test_box_box.py",
    "tests/collide/test_broadphase.py",
    "tests/collide/test_collide_pair3d.py",
    "tests/collide/test_detect.py",
    "tests/contact_inhouse/test_velocity_models.py",
    "tests/contact_models/test_case_runs_conservation.py",
)
# The files that compile the integrators' specialisations of the contact-free effect sets.
RIGID_UNIT = ("tests/rigid/", "tests/reference/test_newton_euler.py")
# The other tests of these directories use the contact unit's kernels: at the end.
USE_LATER = ("tests/collide/", "tests/contact_inhouse/", "tests/contact_models/")
# Files whose tests share the session's fluid runs (tests/fluid/conftest.py: run_case).
SHARED_RUNS = ("tests/fluid/test_validation.py", "tests/fluid/test_solver.py")


def _place(nodeid: str) -> int:
    """The test's group: 0 and 1 the units, 2 the middle, 3 the end."""
    path = nodeid.split("::")[0]
    if path in CONTACT_UNIT:
        return 0
    if path.startswith(RIGID_UNIT):
        return 1
    return 3 if path.startswith(USE_LATER) else 2


def _scope(nodeid: str) -> str:
    """The scope xdist hands to one worker whole."""
    place = _place(nodeid)
    if place == 0:
        return "contact-kernels"
    if place == 1:
        return "rigid-kernels"
    if place == 3:
        return nodeid
    path = nodeid.split("::")[0]
    return "shared-fluid-runs" if path in SHARED_RUNS else path


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    items.sort(key=lambda item: _place(item.nodeid))   # stable: each file keeps its order


@pytest.hookimpl(optionalhook=True)   # xdist's hook: without xdist (-p no:xdist) it is unknown
def pytest_xdist_make_scheduler(config, log):
    if config.getvalue("dist") != "load":
        return None   # an explicit other mode (loadfile, worksteal, ...) is left to xdist
    from xdist.scheduler import LoadScopeScheduling

    class KernelsFirst(LoadScopeScheduling):
        """xdist's scope scheduler on our scopes (:func:`_scope`). Each scope goes whole to
        whichever worker is free, in collection order: xdist's reordering of scopes by their
        number of tests is switched off, since it would put a file with more tests than a unit
        ahead of it."""

        def __init__(self, config, log=None):
            config.option.loadscopereorder = False
            super().__init__(config, log)

        def _split_scope(self, nodeid: str) -> str:
            return _scope(nodeid)

    return KernelsFirst(config, log)
