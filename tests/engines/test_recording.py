"""The adapters' fast recorders against their plain Python ones, bit for bit.

To keep recording under 10 % of bare stepping (benchmarks/results/overhead.md) Pymunk steps and
reads in a compiled loop (engines/_native.py, calling Chipmunk's C functions) and PyBullet keeps
its read tuples as returned and flattens them once after the run. Either would be wrong if it
read another body, another field, the wrong order or the state one step early or late, or put a
blow-up at another sample; each is compared here with the straightforward recorder (a Python
step loop and a per-sample ``read_raw``) on scenes where every field moves, so any such slip
changes bits. (MuJoCo's compiled recorder is compared with rollout and nstep in
test_mujoco.py.)
"""

from __future__ import annotations

import numpy as np
import pytest

from crosscheck.engines import get_engine
from crosscheck.engines.base import sampling_plan
from crosscheck.scene.loader import load_case_text

SPRINGS_2D = """
[case]
name = "two-plates"
dimension = 2
[run]
duration = 0.5
dt = 1e-3
sample_every = 0.007
[effects]
gravity = [0.0, -9.81]
[[effects.springs]]
a = "a"
attach_a = [0.05, 0.02]
anchor = [0.0, 2.0]
stiffness = 50.0
damping = 0.3
rest_length = 0.5
[[effects.springs]]
a = "a"
b = "b"
attach_b = [-0.03, 0.01]
stiffness = 30.0
damping = 0.1
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
angular_velocity = -2.0
"""

SPINNERS_3D = """
[case]
name = "two-spinners"
dimension = 3
[run]
duration = 0.5
dt = 1e-3
sample_every = 0.007
[effects]
gravity = [0.0, 0.0, -9.81]
[[bodies]]
name = "a"
shape = { box = { size = [0.3, 0.1, 0.2] } }
mass = 1.5
com = [0.04, -0.03, 0.02]
inertia = [[0.02, 0.001, 0.0], [0.001, 0.03, 0.002], [0.0, 0.002, 0.04]]
position = [0.2, 1.0, 0.5]
orientation = { axis = [1, 2, 3], angle = 0.7 }
velocity = [1.0, -0.5, 0.2]
angular_velocity = [3.0, 1.0, -2.0]
[[bodies]]
name = "b"
shape = { sphere = { radius = 0.1 } }
mass = 0.7
position = [0.6, 0.8, 0.3]
velocity = [0.0, 0.3, 1.0]
angular_velocity = [0.5, 0.0, -2.0]
"""

# A spring far too stiff for the step: the state overflows within the run (Pymunk: sqrt(k/m) h
# = 10 > 2; PyBullet's symplectic Euler: 7 > 2), and the run must end at the same sample.
BLOWUP = """
[case]
name = "blow-up"
dimension = {dim}
[run]
duration = 2.0
dt = 1e-3
sample_every = 0.003
[[effects.springs]]
a = "a"
anchor = {anchor}
stiffness = {k}
[[bodies]]
name = "a"
shape = {{ {shape} = {{ radius = 0.1 }} }}
mass = 2.0
position = {position}
"""


def _pymunk_python_loop(scene):
    """The same run as PymunkEngine.run, through the Python step loop and read_raw."""
    from crosscheck.engines.pymunk import PymunkModel

    model = PymunkModel(scene, scene.run.dt)
    assert model.compiled  # the fast path is the one the adapter uses here
    model.native = None  # now record() steps through cffi and reads through read_raw
    plan = sampling_plan(scene, scene.run.dt)
    (com, angle, vel, omega), count, _ = model.record(plan.n_samples, plan.steps_per_sample)
    return com[:count], angle[:count], vel[:count], omega[:count]


def test_pymunk_compiled_recorder_equals_python_loop():
    scene = load_case_text(SPRINGS_2D)
    traj = get_engine("pymunk").run(scene, "position_first", scene.run.dt)
    assert traj.meta["effective"]["recording"].startswith("compiled loop")
    com, angle, vel, omega = _pymunk_python_loop(scene)
    assert np.ptp(traj.angle[:, 1]) > 0.5 and np.ptp(traj.com[:, 0, 1]) > 0.01  # all moves
    np.testing.assert_array_equal(traj.com, com)
    np.testing.assert_array_equal(traj.angle, angle)
    np.testing.assert_array_equal(traj.vel, vel)
    np.testing.assert_array_equal(traj.omega, omega)
    plan = sampling_plan(scene, scene.run.dt)
    np.testing.assert_array_equal(traj.t, np.arange(plan.n_samples) * plan.steps_per_sample
                                  * scene.run.dt)


def test_pymunk_compiled_recorder_stops_at_the_same_blow_up():
    scene = load_case_text(BLOWUP.format(dim=2, shape="circle", anchor="[0.0, 0.0]", k="2e8",
                                         position="[0.3, 0.0]"))
    traj = get_engine("pymunk").run(scene, "position_first", scene.run.dt)
    com, *_ = _pymunk_python_loop(scene)
    assert traj.failure is not None and traj.failure["reason"] == "non-finite state"
    assert len(traj.t) == len(com) < sampling_plan(scene, scene.run.dt).n_samples
    assert traj.failure["time"] == pytest.approx(len(com) * 3e-3, rel=1e-12)
    np.testing.assert_array_equal(traj.com, com)


# 2D multibody records through read_raw already (joint and link states): not compared.
@pytest.mark.parametrize(("text", "integrator"), [(SPINNERS_3D, "multibody"),
                                                  (SPINNERS_3D, "maximal"),
                                                  (SPRINGS_2D, "maximal")],
                         ids=["3d-multibody", "3d-maximal", "2d-maximal-springs"])
def test_pybullet_recorder_equals_per_sample_read_raw(text, integrator):
    from crosscheck.engines.pybullet import PybulletModel

    scene = load_case_text(text)
    plan = sampling_plan(scene, scene.run.dt)
    rows = {}
    for name in ("record", "_record_rows"):
        model = PybulletModel(scene, integrator, scene.run.dt)
        try:
            poses = model.base_poses()
            model.probe()
            model.set_initial_state(poses)
            raw, count, _, error = getattr(model, name)(plan.n_samples, plan.steps_per_sample)
        finally:
            model.close()
        assert error is None and count == plan.n_samples
        rows[name] = raw
    assert np.ptp(rows["record"][:, 0]) > 0.01  # it moves
    np.testing.assert_array_equal(rows["record"], rows["_record_rows"])


@pytest.mark.parametrize("integrator", ["multibody", "maximal"])
def test_pybullet_recorder_finds_the_exact_first_non_finite_sample(integrator):
    # Finiteness is checked every 64 samples while recording and located exactly afterwards:
    # the run must end where a per-sample check ends it.
    from crosscheck.engines.pybullet import PybulletModel

    scene = load_case_text(BLOWUP.format(dim=3, shape="sphere", anchor="[0.0, 0.0, 0.0]", k="2e8",
                                         position="[0.3, 0.0, 0.0]"))
    plan = sampling_plan(scene, scene.run.dt)
    out = {}
    for name in ("record", "_record_rows"):
        model = PybulletModel(scene, integrator, scene.run.dt)
        try:
            poses = model.base_poses()
            model.probe()
            model.set_initial_state(poses)
            out[name] = getattr(model, name)(plan.n_samples, plan.steps_per_sample)
        finally:
            model.close()
    (fast, count, _, _), (slow, slow_count, _, _) = out["record"], out["_record_rows"]
    assert 1 < count < plan.n_samples and count % 64 != 0
    assert count == slow_count
    np.testing.assert_array_equal(fast, slow)
    traj = get_engine("pybullet").run(scene, integrator, scene.run.dt)
    assert traj.failure == {"time": plan.time(count), "reason": "non-finite state"}
