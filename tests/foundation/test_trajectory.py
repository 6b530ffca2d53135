"""Trajectory files and the recorder adapters fill.

The file is the contract with anyone outside crosscheck: it must hold exactly the arrays of
DESIGN.md "Trajectory files" with their shapes, be readable with NumPy alone (no pickles) and
round-trip losslessly. The recorder turns a blow-up into data (failure time, truncated arrays),
makes quaternions sign-continuous and keeps 2D angles as the engine accumulated them.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from crosscheck.rotations import axis_angle_to_quat
from crosscheck.state import FORMAT_VERSION, Trajectory, TrajectoryRecorder

RNG = np.random.default_rng(7)


def make_3d(t_count=11, n=3) -> Trajectory:
    q = RNG.normal(size=(t_count, n, 4))
    return Trajectory(
        t=np.arange(t_count) * 0.01,
        com=RNG.normal(size=(t_count, n, 3)),
        vel=RNG.normal(size=(t_count, n, 3)),
        omega=RNG.normal(size=(t_count, n, 3)),
        quat=q / np.linalg.norm(q, axis=-1, keepdims=True),
        meta={"case": "c", "engine": "inhouse", "integrator": "rk4", "dt": 1e-3,
              "bodies": ["a", "b", "c"], "masses": [1.0, 2.0, 0.1 + 0.2],
              "inertia": np.eye(3)[None].repeat(3, 0).tolist(), "wall_time": 0.123456789,
              "settings": {"nested": [1, 2, {"x": None}]},
              "failure": {"time": 0.07, "reason": "non-finite state"}},
        extras={"energy_engine": RNG.normal(size=t_count),
                "contacts": np.arange(t_count * 2, dtype=np.int32).reshape(t_count, 2)},
    )


def make_2d(t_count=9, n=2) -> Trajectory:
    return Trajectory(
        t=np.linspace(0.0, 1.0, t_count),
        com=RNG.normal(size=(t_count, n, 2)),
        vel=RNG.normal(size=(t_count, n, 2)),
        omega=RNG.normal(size=(t_count, n)),
        angle=np.cumsum(RNG.normal(size=(t_count, n)), axis=0),
        meta={"case": "flat", "failure": None},
        extras={"out_of_plane": RNG.normal(size=(t_count, n))},
    )


def assert_same(a: Trajectory, b: Trajectory) -> None:
    for name in ("t", "com", "vel", "omega", "quat", "angle"):
        x, y = getattr(a, name), getattr(b, name)
        if x is None:
            assert y is None, name
            continue
        assert x.dtype == y.dtype and x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, strict=True)
    assert a.extras.keys() == b.extras.keys()
    for k in a.extras:
        assert a.extras[k].dtype == b.extras[k].dtype
        np.testing.assert_array_equal(a.extras[k], b.extras[k], strict=True)


@pytest.mark.parametrize("make", [make_3d, make_2d])
def test_save_load_is_lossless(tmp_path, make):
    traj = make()
    path = traj.save(tmp_path / "out" / "inhouse-rk4-dt0.001.npz")  # parents are created
    back = Trajectory.load(path)
    assert_same(traj, back)  # bit for bit, dtypes included
    # meta is JSON: the same values, plus the format version
    assert back.meta == {**json.loads(json.dumps(traj.meta)), "format_version": FORMAT_VERSION}
    assert back.failure == traj.meta["failure"]
    assert back.dimension == traj.dimension and back.n_bodies == traj.n_bodies
    # saving what was loaded gives the same file contents again
    again = Trajectory.load(back.save(tmp_path / "again.npz"))
    assert_same(back, again)
    assert again.meta == back.meta
    assert [p.name for p in (tmp_path / "out").iterdir()] == [path.name]  # no temporary left


def test_meta_values_from_numpy_are_written_as_json(tmp_path):
    traj = make_3d()
    traj.meta = {"inertia": np.diag([1.0, 2.0, 3.0]), "dt": np.float64(1e-3),
                 "steps": np.int64(1000), "failure": None}
    back = Trajectory.load(traj.save(tmp_path / "x.npz"))
    assert back.meta["inertia"] == [[1.0, 0, 0], [0, 2.0, 0], [0, 0, 3.0]]
    assert back.meta["dt"] == 1e-3 and back.meta["steps"] == 1000
    assert back.wall_time is None and back.failure is None


def test_3d_file_has_the_documented_arrays_and_needs_only_numpy(tmp_path):
    traj = make_3d(t_count=11, n=3)
    path = traj.save(tmp_path / "x.npz")
    with np.load(path, allow_pickle=False) as data:  # NumPy alone, no pickled objects
        assert set(data.files) == {"t", "com", "quat", "vel", "omega", "meta",
                                   "extra_energy_engine", "extra_contacts"}
        assert data["t"].shape == (11,)
        assert data["com"].shape == (11, 3, 3) and data["vel"].shape == (11, 3, 3)
        assert data["quat"].shape == (11, 3, 4) and data["omega"].shape == (11, 3, 3)
        assert data["meta"].shape == ()
        meta = json.loads(str(data["meta"]))
        np.testing.assert_array_equal(data["quat"], traj.quat)
    assert meta["bodies"] == ["a", "b", "c"] and meta["format_version"] == FORMAT_VERSION
    assert meta["failure"] == {"time": 0.07, "reason": "non-finite state"}


def test_2d_file_has_angle_and_scalar_omega(tmp_path):
    path = make_2d(t_count=9, n=2).save(tmp_path / "x.npz")
    with np.load(path, allow_pickle=False) as data:
        assert set(data.files) == {"t", "com", "angle", "vel", "omega", "meta",
                                   "extra_out_of_plane"}
        assert data["com"].shape == (9, 2, 2) and data["vel"].shape == (9, 2, 2)
        assert data["angle"].shape == (9, 2) and data["omega"].shape == (9, 2)
        assert json.loads(str(data["meta"]))["failure"] is None


def test_empty_trajectory_round_trips(tmp_path):
    # a run that blew up at its first sample has zero samples, and still a failure
    rec = TrajectoryRecorder(5, 2, 3)
    assert rec.record(0.0, np.full((2, 3), np.nan), np.zeros((2, 4)), np.zeros((2, 3)),
                      np.zeros((2, 3))) is False
    traj = rec.finish({"case": "x"})
    assert traj.t.shape == (0,) and traj.com.shape == (0, 2, 3) and traj.quat.shape == (0, 2, 4)
    back = Trajectory.load(traj.save(tmp_path / "e.npz"))
    assert_same(traj, back)
    assert back.failure == {"time": 0.0, "reason": "non-finite state"}


# -- the recorder -----------------------------------------------------------------------------
def _state3(k: int, n: int = 2):
    com = np.full((n, 3), float(k))
    quat = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    return com, quat, com * 2, com * 3


@pytest.mark.parametrize("bad", ["com", "rot", "vel", "omega"])
@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_a_non_finite_sample_stops_the_run_and_records_when(bad, value):
    rec = TrajectoryRecorder(n_samples=10, n_bodies=2, dimension=3)
    for k in range(4):
        assert rec.record(0.1 * k, *_state3(k)) is True
    com, rot, vel, omega = _state3(4)
    arrays = {"com": com, "rot": rot, "vel": vel, "omega": omega}
    arrays[bad] = arrays[bad].copy()
    arrays[bad][1, 0] = value
    assert rec.record(0.4, arrays["com"], arrays["rot"], arrays["vel"], arrays["omega"]) is False
    traj = rec.finish({"case": "blow"}, extras={"e": np.arange(10.0)})
    # truncated at the last finite sample; the failure carries the time of the bad one
    assert traj.failure == {"time": 0.4, "reason": "non-finite state"}
    np.testing.assert_allclose(traj.t, [0.0, 0.1, 0.2, 0.3])
    np.testing.assert_array_equal(traj.com[:, 0, 0], [0.0, 1.0, 2.0, 3.0])
    np.testing.assert_array_equal(traj.omega[-1], np.full((2, 3), 9.0))
    np.testing.assert_array_equal(traj.extras["e"], [0.0, 1.0, 2.0, 3.0])  # cut to match
    assert np.all(np.isfinite(traj.com)) and np.all(np.isfinite(traj.quat))
    assert traj.meta["case"] == "blow"


def test_recorder_without_failure_reports_none_and_copies():
    rec = TrajectoryRecorder(3, 1, 3)
    for k in range(3):
        rec.record(k * 0.5, *_state3(k, n=1))
    traj = rec.finish({"engine": "x"})
    assert traj.failure is None and "failure" in traj.meta
    assert traj.t.shape == (3,) and traj.quat.shape == (3, 1, 4)
    rec.com[:] = -1.0  # the trajectory owns its arrays
    assert traj.com[0, 0, 0] == 0.0


def test_explicit_failure_reason_is_kept():
    rec = TrajectoryRecorder(4, 1, 2)
    rec.record(0.0, np.zeros((1, 2)), np.zeros(1), np.zeros((1, 2)), np.zeros(1))
    rec.fail(0.25, "energy grew 1e6-fold")
    traj = rec.finish({})
    assert traj.failure == {"time": 0.25, "reason": "energy grew 1e6-fold"}
    assert traj.angle.shape == (1, 1)


def test_recorded_quaternions_are_made_sign_continuous():
    # spin about z through 4 pi: the true quaternion changes sign at 2 pi. An engine may
    # report either sign at any sample; the trajectory must come out smooth.
    n_samples = 60
    t = np.linspace(0.0, 4.0, n_samples)
    angles = np.pi * t
    true = np.stack([axis_angle_to_quat(np.array([0.0, 0.0, 1.0]), angles),
                     axis_angle_to_quat(np.array([1.0, 2.0, 2.0]), -0.8 * angles)], axis=1)
    signs = RNG.choice([-1.0, 1.0], size=(n_samples, 2, 1))
    rec = TrajectoryRecorder(n_samples, 2, 3)
    for k in range(n_samples):
        rec.record(t[k], np.zeros((2, 3)), true[k] * signs[k], np.zeros((2, 3)),
                   np.zeros((2, 3)))
    q = rec.finish({}).quat
    assert np.all(np.sum(q[1:] * q[:-1], axis=-1) > 0)  # no jump between samples
    # the same rotation as reported at every sample, with the first sample's sign kept
    np.testing.assert_allclose(q, true * signs[0], atol=1e-15)


def test_recorded_2d_angles_are_kept_continuous():
    # A body spinning at 50 rad/s sampled every 0.1 s turns 5 rad between samples; the recorder
    # must keep the engine's accumulated angle, where np.unwrap would fold 5 rad back to -1.28.
    n_samples = 40
    t = np.arange(n_samples) * 0.1
    true = np.stack([0.3 + 50.0 * t, -1.0 - 2.5 * t], axis=1)
    rec = TrajectoryRecorder(n_samples, 2, 2)
    for k in range(n_samples):
        rec.record(t[k], np.zeros((2, 2)), true[k], np.zeros((2, 2)), np.array([50.0, -2.5]))
    traj = rec.finish({})
    np.testing.assert_array_equal(traj.angle, true)
    assert np.ptp(traj.angle[:, 0]) > 190.0
    assert traj.omega.shape == (n_samples, 2) and traj.quat is None
