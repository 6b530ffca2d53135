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
  integrator applicable to a scene, or a skip) and ``reference``: ``newton_euler``, an
  engine-independent reference, the Newton-Euler equations of the scene's bodies (gravity,
  springs, drag, loads) integrated by SciPy's DOP853 to 1e-12.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from crosscheck import names
from crosscheck.engines import engine_names, get_engine
from crosscheck.rotations import quat_mul, quat_normalize, quat_to_matrix
from crosscheck.scene.model import Scene

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


class Harness:
    run = staticmethod(run_scene)
    applicable = staticmethod(require_applicable)
    scheme = staticmethod(require_scheme)
    with_run = staticmethod(with_run)
    reference = staticmethod(lambda scene, times: newton_euler(scene, times))
    VELOCITY_FIRST = VELOCITY_FIRST
    POSITION_FIRST = POSITION_FIRST
    EXACT = EXACT


@pytest.fixture
def harness() -> type[Harness]:
    return Harness


# -- independent reference ---------------------------------------------------------------------
def _embed(scene: Scene):
    """Per-body 3D arrays (a 2D scene embedded in the z = 0 plane, rotating about z)."""
    out = []
    for b in scene.bodies:
        if scene.dimension == 3:
            out.append(dict(m=b.mass, c=np.asarray(b.com, float), I=np.asarray(b.inertia, float),
                            x=b.com_world(), q=np.asarray(b.orientation, float),
                            v=np.asarray(b.velocity, float),
                            w=np.asarray(b.angular_velocity, float)))
        else:
            th = b.angle
            out.append(dict(m=b.mass, c=np.array([*b.com, 0.0]), I=np.eye(3) * b.moment,
                            x=np.array([*b.com_world(), 0.0]),
                            q=np.array([np.cos(th / 2), 0.0, 0.0, np.sin(th / 2)]),
                            v=np.array([*b.velocity, 0.0]),
                            w=np.array([0.0, 0.0, b.angular_velocity[0]])))
    return out


def _to3(v) -> np.ndarray:
    """A 2D point or vector in the z = 0 plane (3D ones unchanged)."""
    v = np.asarray(v, float)
    return v if v.size == 3 else np.array([v[0], v[1], 0.0])


def newton_euler(scene: Scene, times: np.ndarray, rtol: float = 1e-12, atol: float = 1e-13):
    """Reference state at ``times``: (com, quat, vel, omega) arrays of shape (T, N, 3|4).

    State per body: centre of mass x, orientation q of the declared body frame, velocity v of the
    centre of mass, world angular momentum about the centre of mass L. Forces: gravity on the
    centre of mass; each spring at its attachment points, -(k (l - l0) + c dl/dt) e on a; drag
    -c v and -c_a w; loads at the centre of mass. dL/dt = sum of torques about the centre of mass
    (world), w = I_world^-1 L with I_world = R I_body R^T.
    """
    from scipy.integrate import solve_ivp

    dim = scene.dimension
    bodies = _embed(scene)
    n = len(bodies)
    g = _to3(scene.effects.gravity_vector(dim))
    lin = np.zeros(n)
    ang = np.zeros(n)
    for d in scene.effects.drag:
        for i in d.bodies:
            lin[i] += d.linear
            ang[i] += d.angular
    loads_f = np.zeros((n, 3))
    loads_t = np.zeros((n, 3))
    for ld in scene.effects.loads:
        loads_f[ld.body] += _to3(ld.force)
        loads_t[ld.body] += ld.torque if dim == 3 else [0.0, 0.0, ld.torque[0]]
    springs = []
    for s in scene.effects.springs:
        springs.append((s.body_a, _to3(s.attach_a), s.body_b, _to3(s.attach_b), s.stiffness,
                        s.damping, s.rest_length))
    mass = np.array([b["m"] for b in bodies])
    ibody = np.array([b["I"] for b in bodies])
    cbody = np.array([b["c"] for b in bodies])

    def unpack(y):
        y = y.reshape(n, 13)
        return y[:, 0:3], y[:, 3:7], y[:, 7:10], y[:, 10:13]

    def omega_of(q, L):
        r = quat_to_matrix(q)
        iw = np.einsum("nij,njk,nlk->nil", r, ibody, r)
        return np.linalg.solve(iw, L[..., None])[..., 0], r

    def rhs(_t, y):
        x, q, v, L = unpack(y)
        w, r = omega_of(q, L)
        force = mass[:, None] * g + loads_f - lin[:, None] * v
        torque = loads_t - ang[:, None] * w
        for a, pa, b, pb, k, c, l0 in springs:
            ra = r[a] @ (pa - cbody[a])
            wa = x[a] + ra
            va = v[a] + np.cross(w[a], ra)
            if b is None:
                wb, vb = pb, np.zeros(3)
            else:
                rb = r[b] @ (pb - cbody[b])
                wb = x[b] + rb
                vb = v[b] + np.cross(w[b], rb)
            d = wa - wb
            length = np.linalg.norm(d)
            e = d / length if length > 0 else np.zeros(3)
            f = -(k * (length - l0) + c * (e @ (va - vb))) * e
            force[a] += f
            torque[a] += np.cross(ra, f)
            if b is not None:
                force[b] -= f
                torque[b] -= np.cross(rb, f)
        qdot = 0.5 * quat_mul(np.concatenate([np.zeros((n, 1)), w], axis=1), q)
        return np.concatenate([v, qdot, force / mass[:, None], torque], axis=1).ravel()

    y0 = []
    for b in bodies:
        r = quat_to_matrix(b["q"])
        y0.append(np.concatenate([b["x"], b["q"], b["v"], r @ b["I"] @ r.T @ b["w"]]))
    sol = solve_ivp(rhs, (0.0, float(times[-1])), np.concatenate(y0), method="DOP853",
                    t_eval=times, rtol=rtol, atol=atol)
    assert sol.success, sol.message
    ys = sol.y.T.reshape(len(times), n, 13)
    x, q, v, L = ys[..., 0:3], quat_normalize(ys[..., 3:7]), ys[..., 7:10], ys[..., 10:13]
    w = np.stack([omega_of(q[i], L[i])[0] for i in range(len(times))])
    return x, q, v, w
