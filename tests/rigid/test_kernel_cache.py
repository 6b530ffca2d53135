"""The kernels are split by job across modules that inline each other's helpers (within sim/rigid,
and the contact models of sim/rigid call sim/collide); numba's on-disk cache stamps a function with
its own file only, so sim/_jit.py stamps every kernel of both packages with all of their sources.
These tests check that the stamp is in force."""

from __future__ import annotations

import os

from crosscheck.sim import _jit
from crosscheck.sim.collide import (
    broadphase,
    clip3d,
    convex3d,
    detect,
    gjk,
    manifold,
    narrow2d,
    narrow3d,
    polytope3d,
    pose,
)
from crosscheck.sim.rigid import (
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
                  implicit, pose, manifold, narrow3d, narrow2d, clip3d, polytope3d, gjk, convex3d,
                  broadphase, detect)


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


def test_the_stamp_covers_rigid_and_collide():
    dirs = {os.path.basename(os.path.dirname(p)) for p in _jit.package_sources()}
    assert dirs == {"rigid", "collide"}


def test_the_old_import_path_still_works():
    from crosscheck.sim.rigid import _jit as old

    assert old.JIT is _jit.JIT and old.INLINE is _jit.INLINE


def _copy_packages(tmp_path, monkeypatch):
    dirs = []
    for d in _jit.PACKAGE_DIRS:
        copy = tmp_path / os.path.basename(d)
        copy.mkdir()
        for f in os.listdir(d):
            if f.endswith(".py"):
                (copy / f).write_bytes(open(os.path.join(d, f), "rb").read())
        dirs.append(str(copy))
    monkeypatch.setattr(_jit, "SIM_DIR", str(tmp_path))
    monkeypatch.setattr(_jit, "PACKAGE_DIRS", tuple(dirs))
    return tmp_path


def test_an_edit_to_a_helper_module_changes_every_kernel_stamp(tmp_path, monkeypatch):
    # A copy of the packages with one helper file changed: the stamp (of every kernel) changes.
    root = _copy_packages(tmp_path, monkeypatch)
    before = _jit.package_stamp()
    helper = root / "rigid" / "math3d.py"
    helper.write_text(helper.read_text() + "\n# edited\n")
    assert _jit.package_stamp() != before


def test_an_edit_in_collide_changes_the_rigid_kernels_stamp(tmp_path, monkeypatch):
    # The contact models of sim/rigid inline collision functions: an edit there must recompile.
    root = _copy_packages(tmp_path, monkeypatch)
    before = _jit.package_stamp()
    helper = root / "collide" / "contacts.py"
    helper.write_text(helper.read_text() + "\n# edited\n")
    assert _jit.package_stamp() != before


def test_a_scene_without_gravity_runs_the_compiled_step_of_one_with_it():
    """No gravity is a zero-length array tested at run time (RigidModel.kernel_args), so the two
    scenes share one specialisation of every kernel; and the run-time test must still apply
    gravity when there is some and skip it when there is none: two bodies joined by a spring
    (internal forces only) keep their total momentum without gravity and gain M g t with it."""
    import dataclasses
    from pathlib import Path

    import numba
    import numpy as np

    from crosscheck.scene.loader import load_case
    from crosscheck.sim.rigid import RigidSimulation, compile_model, state_from_scene

    scene = load_case(Path(__file__).resolve().parents[2] / "cases/rigid3d/two_body_spring.toml")
    free = compile_model(scene).without("gravity")
    g = np.array([0.0, 0.0, -9.81])
    heavy = dataclasses.replace(free, gravity=g)
    assert numba.typeof(free.kernel_args()[1]) == numba.typeof(heavy.kernel_args()[1])
    n, h = 200, 1e-3
    mass = float(np.sum(free.bodies.mass))
    for model, expected_gain in ((free, np.zeros(3)), (heavy, mass * g * n * h)):
        state = state_from_scene(model, scene)
        before = state.P.sum(axis=0).copy()
        RigidSimulation(model, "rk4").advance(state, n, h)
        gain = state.P.sum(axis=0) - before
        # the spring's forces cancel in pairs to round-off; gravity adds m g h per body and step
        np.testing.assert_allclose(gain, expected_gain, rtol=1e-12, atol=1e-12 * mass)
