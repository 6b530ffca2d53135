"""PyBullet's compiled recorder (Bullet's C API from a numba loop) against PyBullet's Python API.

``engines/_bullet_capi.py`` finds Bullet's client functions and the client handle behind a
``physicsClientId`` inside PyBullet's own library; ``engines/_native.py`` steps and reads through
them with one state request per body and sample instead of two Python calls. It would be wrong
if it used another client, read another body, field or link, swapped position and velocity, read
one step early or late, or lost a blow-up or a failed call. Each test below would catch one of
those: the trajectories of ``run()`` with the compiled loop and with PyBullet's Python functions
must be equal bit for bit on scenes where every field moves.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_recording import SPINNERS_3D as _SPINNERS_3D

from crosscheck.engines import _bullet_capi, _native, get_engine
from crosscheck.engines import pybullet as pb
from crosscheck.engines.base import sampling_plan
from crosscheck.scene.loader import load_case, load_case_text

ROOT = Path(__file__).resolve().parents[2]

# No velocity component of any body is zero (in the shared scene the second body's are).
SPINNERS_3D = _SPINNERS_3D.replace("velocity = [0.0, 0.3, 1.0]", "velocity = [0.2, 0.3, 1.0]"
                                   ).replace("[0.5, 0.0, -2.0]", "[0.5, 0.7, -2.0]")

PLATES_2D = """
[case]
name = "two-plates-free"
dimension = 2
[run]
duration = 0.5
dt = 1e-3
sample_every = 0.007
[effects]
gravity = [0.0, -9.81]
[[bodies]]
name = "a"
shape = { box = { size = [0.3, 0.1] } }
mass = 1.5
com = [0.04, -0.03]
position = [0.2, 1.0]
orientation = 0.4
velocity = [1.0, -0.5]
angular_velocity = 3.0
[[bodies]]
name = "b"
shape = { circle = { radius = 0.1 } }
mass = 0.7
com = [0.01, 0.02]
position = [0.6, 0.8]
velocity = [0.3, 0.2]
angular_velocity = -2.0
"""

# Gravity so strong that the state turns non-finite within the run (dt = 1 s, a sample every 3
# steps). Gravity is Bullet's own: nothing is applied from Python, so these are scenes the
# compiled loop records.
# * multibody, g = 1e152: v_n = n g dt passes sqrt(DBL_MAX) = 1.34e154 at step 135; its square,
#   which btMultiBody forms during the next step, overflows: step 136 is the first non-finite;
# * maximal, g = 1e304: btRigidBody does not square v; the position x_n = g dt^2 n (n + 1) / 2
#   (semi-implicit Euler) passes DBL_MAX = 1.8e308 at step 190.
OVERFLOW_3D = """
[case]
name = "overflow"
dimension = 3
[run]
duration = 900.0
dt = 1.0
sample_every = 3.0
[effects]
gravity = [0.0, 0.0, -{g}]
[[bodies]]
name = "a"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 1.0
position = [0.0, 0.0, 0.0]
angular_velocity = [0.0, 0.0, 0.1]
"""
_BIG = np.finfo(float).max
OVERFLOW_STEP = {"multibody": (1e152, int(np.sqrt(_BIG) / 1e152) + 2),
                 "maximal": (1e304, next(n for n in range(1, 10**4)
                                         if n * (n + 1) // 2 * 1e304 > _BIG))}


def _both(text: str, integrator: str):
    """run() with the compiled loop, then with PyBullet's Python functions."""
    return _both_scene(load_case_text(text), integrator)


def _both_scene(scene, integrator: str):
    engine = get_engine("pybullet")
    fast = engine.run(scene, integrator, scene.run.dt)
    engine.compiled_recording = False
    try:
        slow = engine.run(scene, integrator, scene.run.dt)
    finally:
        engine.compiled_recording = True
    return scene, fast, slow


def _assert_equal(scene, fast, slow) -> None:
    for name in ("t", "com", "vel", "omega", "quat" if scene.dimension == 3 else "angle"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(slow, name), err_msg=name)
    for name, value in slow.extras.items():  # 2D: the out-of-plane drift
        np.testing.assert_array_equal(fast.extras[name], value, err_msg=name)


@pytest.mark.parametrize(("text", "integrator"), [(SPINNERS_3D, "multibody"),
                                                  (SPINNERS_3D, "maximal"),
                                                  (PLATES_2D, "multibody"),
                                                  (PLATES_2D, "maximal")],
                         ids=["3d-multibody", "3d-maximal", "2d-planar-joints", "2d-maximal"])
def test_compiled_recorder_equals_python_functions(text, integrator):
    scene, fast, slow = _both(text, integrator)
    assert fast.meta["effective"]["recording"].startswith("compiled loop")
    assert slow.meta["effective"]["recording"].startswith("python loop")
    assert fast.failure is None and slow.failure is None
    assert len(fast.t) == sampling_plan(scene, scene.run.dt).n_samples
    # Every position and orientation component moves and no velocity is zero, in both bodies,
    # so a swapped body or field, or a sample read a step early, changes bits.
    assert np.all(np.ptp(fast.com, axis=0) > 1e-3)
    assert np.all(fast.vel != 0.0) and np.all(fast.omega != 0.0)
    if scene.dimension == 3:
        assert np.all(np.ptp(fast.quat, axis=0) > 1e-3)
    else:
        assert np.all(np.ptp(fast.angle, axis=0) > 0.5)
    _assert_equal(scene, fast, slow)


@pytest.mark.parametrize("integrator", ["multibody", "maximal"])
def test_compiled_recorder_stops_at_the_same_overflow(integrator):
    g, first_bad_step = OVERFLOW_STEP[integrator]
    scene, fast, slow = _both(OVERFLOW_3D.format(g=g), integrator)
    assert fast.meta["effective"]["recording"].startswith("compiled loop")
    plan = sampling_plan(scene, scene.run.dt)
    assert slow.failure is not None and slow.failure["reason"] == "non-finite state"
    assert fast.failure == slow.failure
    assert len(fast.t) == len(slow.t) < plan.n_samples
    # Kept: the samples taken before the first non-finite step (every third step from 0).
    assert len(fast.t) == -(-first_bad_step // 3)
    _assert_equal(scene, fast, slow)


def test_a_failed_bullet_call_is_a_reported_failure_with_its_time(monkeypatch):
    # Bullet answers every step with a status type; the loop requires the one learnt on the
    # scratch client. Requiring another makes the first step "fail": the run must come back as
    # a failure at that sample's time, with the samples before it, not raise.
    real = _bullet_capi.api()
    assert isinstance(real, _bullet_capi.BulletApi)
    wrong = _bullet_capi.BulletApi(real.fns, real.force_fns, real.clients, real.max_clients,
                                   np.array([real.kinds[0] + 1000, real.kinds[1]]))
    monkeypatch.setattr(_bullet_capi, "api", lambda: wrong)
    scene = load_case_text(SPINNERS_3D)
    traj = get_engine("pybullet").run(scene, "multibody", scene.run.dt)
    assert traj.failure is not None
    assert traj.failure["reason"] == "pybullet error: a step command failed in Bullet's C API"
    assert traj.failure["time"] == 0.007 and len(traj.t) == 1


def test_without_the_c_api_the_adapter_records_from_python(monkeypatch):
    monkeypatch.setattr(_bullet_capi, "api", lambda: "no symbol table (test)")
    scene = load_case_text(SPINNERS_3D)
    traj = get_engine("pybullet").run(scene, "maximal", scene.run.dt)
    assert traj.meta["effective"]["recording"] == (
        "python loop over PyBullet's functions (compiled loop unavailable: no symbol table "
        "(test))")
    assert traj.failure is None and len(traj.t) == sampling_plan(scene, scene.run.dt).n_samples


SPRINGS_DRAG_LOADS_3D = _SPINNERS_3D.replace("[[bodies]]", """
[[effects.springs]]
a = "a"
attach_a = [0.05, 0.02, -0.04]
anchor = [0.0, 1.0, 1.5]
stiffness = 50.0
damping = 0.3
rest_length = 0.5
[[effects.springs]]
a = "a"
b = "b"
attach_a = [-0.1, 0.0, 0.03]
attach_b = [0.02, -0.03, 0.01]
stiffness = 30.0
damping = 0.1
[[effects.drag]]
linear = 0.2
angular = 0.01
bodies = ["b"]
[[effects.loads]]
body = "a"
force = [0.5, -0.2, 3.0]
torque = [0.01, 0.02, -0.03]
[[bodies]]""", 1)


@pytest.mark.parametrize(("text", "integrator"), [(SPRINGS_DRAG_LOADS_3D, "multibody"),
                                                  (SPRINGS_DRAG_LOADS_3D, "maximal"),
                                                  ("SPRINGS_2D", "multibody"),
                                                  ("SPRINGS_2D", "maximal")],
                         ids=["3d-multibody", "3d-maximal", "2d-planar-joints", "2d-maximal"])
def test_forces_applied_in_the_compiled_loop_equal_pythons(text, integrator):
    # Springs (to an anchor and between bodies, off the centre of mass, damped), drag and loads
    # are evaluated and applied before every step in the compiled loop: the same state reads,
    # the same terms in the same order, the same commands (2D multibody: joint torques on the
    # joints' velocity indices). A wrong term, frame, sign, body or index changes bits.
    from test_recording import SPRINGS_2D

    text = SPRINGS_2D if text == "SPRINGS_2D" else text
    scene, fast, slow = _both(text, integrator)
    assert fast.meta["effective"]["recording"].startswith("compiled loop")
    assert "springs, drag and loads evaluated in the loop" in fast.meta["effective"]["recording"]
    assert fast.failure is None and slow.failure is None
    assert np.all(np.ptp(fast.com, axis=0) > 1e-3)
    _assert_equal(scene, fast, slow)


@pytest.mark.parametrize("integrator", ["multibody", "maximal"])
def test_compiled_forces_blow_up_where_pythons_do(integrator):
    from test_recording import BLOWUP

    text = BLOWUP.format(dim=3, shape="sphere", anchor="[0.0, 0.0, 0.0]", k="2e8",
                         position="[0.3, 0.0, 0.0]")
    scene, fast, slow = _both(text, integrator)
    assert slow.failure is not None and slow.failure["reason"] == "non-finite state"
    assert fast.failure == slow.failure
    assert 1 < len(fast.t) < sampling_plan(scene, scene.run.dt).n_samples
    _assert_equal(scene, fast, slow)


@pytest.mark.parametrize("path", sorted(p.name for p in (ROOT / "cases").glob("rigid*/*.toml")))
def test_every_committed_rigid_case_records_the_same_both_ways(path):
    scene = load_case(next((ROOT / "cases").glob(f"rigid*/{path}")))
    for integrator in ("multibody", "maximal"):
        _, fast, slow = _both_scene(scene, integrator)
        assert fast.meta["effective"]["recording"].startswith("compiled loop")
        assert (fast.failure is None) == (slow.failure is None)
        _assert_equal(scene, fast, slow)


def test_each_client_id_maps_to_its_own_handle():
    import pybullet as p

    api = _bullet_capi.api()
    assert isinstance(api, _bullet_capi.BulletApi)
    a, b = p.connect(p.DIRECT), p.connect(p.DIRECT)
    try:
        ha, hb = api.handle(a), api.handle(b)
        assert ha and hb and ha != hb
        # The handle holds the client's bodies: one body in b, none in a.
        p.createMultiBody(1.0, physicsClientId=b)
        count = _native_num_bodies()
        assert (count(ha), count(hb)) == (p.getNumBodies(physicsClientId=a),
                                          p.getNumBodies(physicsClientId=b)) == (0, 1)
    finally:
        p.disconnect(physicsClientId=a)
        p.disconnect(physicsClientId=b)
    assert api.handle(b) == 0  # a closed client's slot is cleared
    assert api.handle(-1) == api.handle(api.max_clients) == 0


def _native_num_bodies():
    import ctypes

    import pybullet as p

    lib = ctypes.CDLL(p.__file__)
    fn = lib.b3GetNumBodies
    fn.argtypes, fn.restype = [ctypes.c_void_p], ctypes.c_int
    return fn


def test_a_symbol_table_of_another_build_is_refused(monkeypatch):
    # The library's load address must come out the same from every function the loop calls:
    # a symbol table read from another build than the one loaded would not.
    real = _bullet_capi._symbols

    def shifted(path, names):
        found = real(path, names)
        name = _bullet_capi.FUNCTIONS[3]
        value, size, kind = found[name]
        found[name] = (value + 16, size, kind)
        return found

    monkeypatch.setattr(_bullet_capi, "_symbols", shifted)
    assert _bullet_capi.api.__wrapped__() == (
        "PyBullet's symbol table does not match the loaded library")


def test_a_stripped_library_is_refused(monkeypatch):
    monkeypatch.setattr(_bullet_capi, "_symbols", lambda path, names: {})
    reason = _bullet_capi.api.__wrapped__()
    assert isinstance(reason, str) and "sPhysicsClients1" in reason


def test_the_model_checks_its_reader_against_pythons_before_using_it(monkeypatch):
    # A reader that put the velocity where the position goes must never be used.
    scene = load_case_text(SPINNERS_3D)
    real = _native.bullet_read

    def swapped(fns, client, uids, planar, kind, row, scratch):
        code = real(fns, client, uids, planar, kind, row, scratch)
        row[0:3], row[7:10] = row[7:10].copy(), row[0:3].copy()
        return code

    monkeypatch.setattr(_native, "bullet_read", swapped)
    model = pb.PybulletModel(scene, "multibody", scene.run.dt)
    try:
        poses = model.base_poses()
        model.probe()
        model.set_initial_state(poses)
        assert not model.use_compiled()
        assert model.native_reason == (
            "the compiled reader differs from PyBullet's Python functions")
    finally:
        model.close()


FAST_SPIN_3D = """
[case]
name = "fast-spin"
dimension = 3
[run]
duration = 0.3
dt = 1e-3
sample_every = 0.01
[[bodies]]
name = "a"
shape = { box = { size = [0.3, 0.1, 0.2] } }
mass = 1.5
com = [0.04, -0.03, 0.02]
inertia = [[0.02, 0.001, 0.0], [0.001, 0.03, 0.002], [0.0, 0.002, 0.04]]
position = [0.2, 1.0, 0.5]
orientation = { axis = [1, 2, 3], angle = 0.7 }
velocity = [1.0, -0.5, 0.2]
angular_velocity = [150.0, 20.0, -30.0]
"""


@pytest.mark.parametrize("integrator", ["multibody", "maximal"])
def test_compiled_recorder_keeps_quaternion_signs_continuous(integrator):
    # Bullet rebuilds its quaternion from a matrix at every read, so consecutive raw samples of
    # a fast spin jump sign; the compiled loop undoes each jump as it records (exact negation),
    # and the Trajectory must be the one the Python recorder gives.
    scene = load_case_text(FAST_SPIN_3D)
    plan = sampling_plan(scene, scene.run.dt)
    raw = {}
    for compiled in (True, False):
        model = pb.PybulletModel(scene, integrator, scene.run.dt)
        try:
            poses = model.base_poses()
            model.probe()
            model.set_initial_state(poses)
            assert model.use_compiled(compiled) is compiled
            rows, count, _, error = model.record(plan.n_samples, plan.steps_per_sample)
        finally:
            model.close()
        assert error is None and count == plan.n_samples
        raw[compiled] = rows
    dots = {c: np.sum(r[1:, 3:7] * r[:-1, 3:7], axis=-1) for c, r in raw.items()}
    assert np.sum(dots[False] < 0) >= 3  # the raw reads do jump
    assert np.all(dots[True] > 0)
    flipped = np.sum(raw[True][:, 3:7] * raw[False][:, 3:7], axis=-1) < 0
    np.testing.assert_array_equal(raw[True][:, 3:7], raw[False][:, 3:7] * np.where(
        flipped, -1.0, 1.0)[:, None])
    np.testing.assert_array_equal(np.delete(raw[True], np.s_[3:7], axis=1),
                                  np.delete(raw[False], np.s_[3:7], axis=1))
    _assert_equal(*_both(FAST_SPIN_3D, integrator))
