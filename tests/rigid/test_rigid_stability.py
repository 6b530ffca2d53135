"""Stiff spring, k dt^2 / m = 100: implicit Euler stays bounded, every explicit scheme blows up,
and a blow-up is a reported failure with its time, never an exception."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from crosscheck import quantities
from crosscheck.engines import get_engine
from crosscheck.scene.loader import load_case
from crosscheck.sim.rigid import INTEGRATORS

CASE = Path(__file__).resolve().parents[2] / "cases" / "rigid3d" / "stiff_spring.toml"
EXPLICIT = [name for name in INTEGRATORS if name != "implicit_euler"]


def _scene():
    scene = load_case(CASE)
    spring = scene.effects.springs[0]
    m = scene.bodies[0].mass
    assert spring.stiffness * scene.run.dt**2 / m == pytest.approx(100.0)
    return scene


def test_implicit_euler_bounded_on_stiff_spring():
    scene = _scene()
    h = scene.run.dt
    traj = get_engine("inhouse").run(scene, "implicit_euler", h)
    assert traj.failure is None
    assert traj.t[-1] == pytest.approx(scene.run.duration)
    energy = quantities.total_energy(scene, traj)
    # The spring is linear (rest length 0, attached at the centre of mass), so the linearised
    # solve is exact backward Euler, whose map on (x, v) has determinant 1 / (1 + (h w)^2): the
    # energy is divided by exactly 1 + k h^2 / m = 101 every step (one step per sample here).
    # Round-off: a few eps per step.
    np.testing.assert_allclose(energy[1:] / energy[:-1], 1.0 / 101.0, rtol=1e-9)
    assert np.all(np.linalg.norm(traj.com[:, 0], axis=1) <= np.linalg.norm(traj.com[0, 0]))


@pytest.mark.parametrize("integrator", EXPLICIT)
def test_explicit_schemes_blow_up_and_report_it(integrator):
    scene = _scene()
    # w h = 10 is beyond every explicit scheme's stability limit (2 for symplectic Euler and
    # Verlet, 2.83 for RK4, none on the imaginary axis for explicit Euler and midpoint): the
    # energy is multiplied by 1e2 .. 2.5e5 per step. The run must come back, not raise, with
    # the failure's time and reason, and the samples before it finite.
    traj = get_engine("inhouse").run(scene, integrator, scene.run.dt)
    failure = traj.failure
    assert failure is not None, f"{integrator} did not blow up"
    assert 0.0 < failure["time"] <= scene.run.duration
    assert isinstance(failure["reason"], str) and failure["reason"]
    assert len(traj.t) >= 1 and traj.t[-1] < failure["time"]
    assert np.all(np.isfinite(traj.com)) and np.all(np.isfinite(traj.vel))
    # At least two samples were kept (the first step already multiplies the energy by 1e2 or
    # more, and the runaway cut comes after it), so the growth is measured, not assumed.
    energy = quantities.total_energy(scene, traj)
    assert len(energy) >= 2
    assert np.all(energy[1:] > 10.0 * energy[:-1])  # it was growing at every step it kept
