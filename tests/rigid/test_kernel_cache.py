"""The kernels are split by job across modules that inline each other's helpers; numba's on-disk
cache stamps a function with its own file only, so sim/rigid/_jit.py stamps every kernel of the
package with all of the package's sources. These tests check that the stamp is in force."""

from __future__ import annotations

import os

from crosscheck.sim.rigid import (
    _jit,
    explicit2d,
    explicit3d,
    forces2d,
    forces3d,
    implicit,
    math3d,
    splitting2d,
    splitting3d,
)

KERNEL_MODULES = (math3d, forces3d, forces2d, explicit3d, explicit2d, splitting3d, splitting2d,
                  implicit)


def _kernels(module):
    return [obj for obj in vars(module).values()
            if getattr(obj, "_cache", None) is not None and getattr(obj, "py_func", None)
            is not None and obj.py_func.__module__ == module.__name__]


def test_every_kernel_is_stamped_with_the_whole_package():
    assert _jit.LOCATORS_REGISTERED
    stamp = _jit.package_stamp()
    for module in KERNEL_MODULES:
        kernels = _kernels(module)
        assert kernels, module.__name__
        for fn in kernels:
            locator = fn._cache._impl.locator
            assert type(locator).__name__.startswith("Package"), (fn, type(locator))
            assert locator.get_source_stamp() == stamp, fn


def test_the_stamp_covers_every_kernel_module():
    names = {os.path.basename(p) for p in _jit.package_sources()}
    for module in KERNEL_MODULES:
        assert os.path.basename(module.__file__) in names


def test_an_edit_to_a_helper_module_changes_every_kernel_stamp(tmp_path, monkeypatch):
    # A copy of the package with one helper file changed: the stamp (of every kernel) changes.
    for path in _jit.package_sources():
        (tmp_path / os.path.basename(path)).write_bytes(open(path, "rb").read())
    monkeypatch.setattr(_jit, "PACKAGE_DIR", str(tmp_path))
    before = _jit.package_stamp()
    helper = tmp_path / "math3d.py"
    helper.write_text(helper.read_text() + "\n# edited\n")
    assert _jit.package_stamp() != before
