"""Shared machinery of the engine tests.

* Every adapter in ``crosscheck.engines.REGISTRY`` takes part. An adapter whose module is missing
  or fails to import is a failure, not a skip.
* Tests ask for ``engine_name`` (one per adapter) or ``engine_name, integrator`` (one per adapter
  and each rigid-body integrator ``crosscheck.names`` lists for it: fluid schemes are not
  offered), optionally restricted with ``@pytest.mark.dimension(d)`` to adapters that support
  d-dimensional scenes; ``engine`` is the adapter instance.
* ``crosscheck.names`` says which discrete scheme each integrator is (order and update under
  constant acceleration), which is what the suite's tolerances are derived from; an integrator
  without an entry fails.
* ``harness`` (a fixture, so test modules never import this file) bundles ``run`` (run a scene,
  skipping with the adapter's reason when it is not applicable), ``scheme`` (the scheme of an
  integrator applicable to a scene, or a skip) and ``reference``: an engine-independent
  reference Trajectory, the Newton-Euler equations of the scene's bodies (gravity, springs, drag,
  loads; ``crosscheck.reference.newton_euler``, the equations the DOP853 reference integrates)
  solved by SciPy's DOP853 to 1e-12.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from crosscheck import names
from crosscheck.engines import engine_names, get_engine
from crosscheck.reference import newton_euler
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory

VELOCITY_FIRST = names.VELOCITY_FIRST  # v += h a, then x += h v_new (semi-implicit Euler family)
POSITION_FIRST = names.POSITION_FIRST  # x += h v, then v += h a (explicit Euler, Pymunk)
EXACT = names.EXACT  # second order or higher: exact for constant acceleration


@dataclass(frozen=True)
class Scheme:
    order: int  # global order of accuracy on smooth motion
    fall: str  # the discrete form of its update under constant acceleration


def scheme_of(engine, integrator: str) -> Scheme:
    """The integrator's scheme from crosscheck.names; a KeyError (a failure) when it has none."""
    name = engine if isinstance(engine, str) else engine.name
    info = names.integrator_info(name, integrator)
    return Scheme(info.order, info.scheme)


# -- parametrisation over adapters -----------------------------------------------------------
def _adapter_status(name: str) -> tuple[object | None, str | None]:
    """(engine, None); any import error propagates (a missing or broken adapter fails its tests,
    it is never skipped)."""
    return get_engine(name), None


def pytest_configure(config):
    config.addinivalue_line(
        "markers", "dimension(d): run only for adapters whose capabilities include d-D scenes")


def pytest_generate_tests(metafunc):
    if "engine_name" not in metafunc.fixturenames:
        return
    marker = metafunc.definition.get_closest_marker("dimension")
    dimension = marker.args[0] if marker else None
    with_integrator = "integrator" in metafunc.fixturenames
    params = []
    for name in engine_names():
        try:
            engine, reason = _adapter_status(name)
        except Exception as exc:  # noqa: BLE001 - reported by the test itself
            params.append(pytest.param(name, f"<import failed: {exc!r}>", id=f"{name}-broken")
                          if with_integrator else pytest.param(name, id=f"{name}-broken"))
            continue
        if engine is None:
            mark = pytest.mark.skip(reason=reason)
            params.append(pytest.param(name, "-", marks=mark, id=name) if with_integrator
                          else pytest.param(name, marks=mark, id=name))
            continue
        caps = engine.capabilities()
        if dimension is not None and dimension not in caps.dimensions:
            mark = pytest.mark.skip(reason=f"{name} has no {dimension}D scenes")
            params.append(pytest.param(name, "-", marks=mark, id=name) if with_integrator
                          else pytest.param(name, marks=mark, id=name))
            continue
        if with_integrator:
            params += [pytest.param(name, integ, id=f"{name}-{integ}")
                       for integ in names.rigid_names(name)]
        else:
            params.append(pytest.param(name, id=name))
    argnames = ("engine_name", "integrator") if with_integrator else ("engine_name",)
    metafunc.parametrize(argnames, params)


@pytest.fixture
def engine(engine_name):
    """The adapter instance (a broken adapter's import error surfaces here, as a failure)."""
    return get_engine(engine_name)


def require_applicable(engine, scene: Scene, integrator: str) -> None:
    """Skip, with the adapter's own reason, when it cannot run this scene and integrator."""
    reason = engine.not_applicable(scene, integrator)
    if reason is not None:
        pytest.skip(f"{engine.name}/{integrator}: not applicable: {reason}")


def run_scene(engine, scene: Scene, integrator: str, dt: float | None = None):
    """Run (skipping when not applicable); a failed run fails the test."""
    require_applicable(engine, scene, integrator)
    traj = engine.run(scene, integrator, scene.run.dt if dt is None else dt)
    assert traj.failure is None, f"{engine.name}/{integrator} failed: {traj.failure}"
    return traj


def require_scheme(engine, scene: Scene, integrator: str) -> Scheme:
    """The integrator's scheme (crosscheck.names), once it is known to apply to the scene."""
    require_applicable(engine, scene, integrator)
    try:
        return scheme_of(engine, integrator)
    except KeyError as exc:
        pytest.fail(f"no discrete scheme for {engine.name}.{integrator}: add it to "
                    f"crosscheck.names ({exc})")


def with_run(scene: Scene, **changes) -> Scene:
    return replace(scene, run=replace(scene.run, **changes))


# -- independent reference ---------------------------------------------------------------------
def reference(scene: Scene, times: np.ndarray) -> Trajectory:
    """The engine-independent reference at ``times``: the Newton-Euler equations of
    ``crosscheck.reference.newton_euler`` (written apart from every engine, the in-house one
    included) integrated by SciPy's DOP853 to rtol 1e-12, atol 1e-13."""
    return newton_euler.solve(scene, times, rtol=1e-12, atol=1e-13)


class Harness:
    run = staticmethod(run_scene)
    applicable = staticmethod(require_applicable)
    scheme = staticmethod(require_scheme)
    with_run = staticmethod(with_run)
    reference = staticmethod(reference)
    VELOCITY_FIRST = VELOCITY_FIRST
    POSITION_FIRST = POSITION_FIRST
    EXACT = EXACT


@pytest.fixture
def harness() -> type[Harness]:
    return Harness
