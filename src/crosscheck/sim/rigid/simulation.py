"""Driving the compiled step: sampling, blow-up detection, and the generic ODE interface.

:class:`RigidSimulation` binds a compiled model to one registered integrator. :func:`simulate`
runs a Scene at one step size on the sampling plan every engine uses and fills a
TrajectoryRecorder; a blow-up (a non-finite state, or the energy running away far beyond what the
scene's forces can supply) ends the run as a recorded failure with its time, never an exception.
Wall time counts the stepping only: not the compilation, the recording or the energy checks.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from crosscheck.scene.model import Scene
from crosscheck.sim.rigid import kernels2d as k2
from crosscheck.sim.rigid import kernels3d as k3
from crosscheck.sim.rigid.integrators import Integrator, get_integrator
from crosscheck.sim.rigid.model import RigidModel, RigidState, compile_model, state_from_scene
from crosscheck.state import Trajectory, TrajectoryRecorder

# |E(t) - E(0)| > RUNAWAY_FACTOR * E_scale stops a run as a blow-up. E_scale bounds the energy the
# scene can exchange (initial kinetic and spring energy plus the work gravity and the loads can do
# in the run), so no physical run comes near; the comparer flags blow-ups from 10x on, and this
# much larger factor only saves the time of stepping a state that has already exploded.
RUNAWAY_FACTOR = 1e6
ENERGY_CHECK_EVERY = 64  # samples between energy checks (vectorised over the batch)


class RigidSimulation:
    """A compiled model plus one integrator; steps a RigidState in place."""

    def __init__(self, model: RigidModel, integrator: str | Integrator = "rk4"):
        self.model = model
        self.integrator = (integrator if isinstance(integrator, Integrator)
                           else get_integrator(integrator))

    @classmethod
    def from_scene(cls, scene: Scene, integrator: str = "rk4") -> RigidSimulation:
        return cls(compile_model(scene), integrator)

    def advance(self, state: RigidState, n_steps: int, h: float) -> None:
        """Take n_steps steps of size h in place."""
        self.integrator.advance(self.model, state, n_steps, h)

    def warmup(self, state: RigidState, h: float) -> float:
        """Compile (or load from numba's cache) every kernel this run needs; returns seconds."""
        t0 = time.perf_counter()
        scratch = state.copy()
        self.advance(scratch, 1, h)
        self.observe(scratch)
        return time.perf_counter() - t0

    def observe(self, state: RigidState):
        """(com, orientation, com velocity, world angular velocity) arrays of the state."""
        n = self.model.n_bodies
        if self.model.dimension == 3:
            vel = np.empty((n, 3))
            omega = np.empty((n, 3))
            k3.observe(self.model.bodies, state.rot, state.P, state.L, vel, omega)
        else:
            vel = np.empty((n, 2))
            omega = np.empty(n)
            k2.observe(self.model.bodies, state.P, state.L, vel, omega)
        return state.x.copy(), state.rot.copy(), vel, omega

    def derivative(self, state: RigidState) -> RigidState:
        """The state derivative (v, dq/dt, F, tau) from the same kernels the integrators use."""
        dx, drot, dP, dL = (np.empty_like(a) for a in state.arrays())
        kern = k3 if self.model.dimension == 3 else k2
        kern.derivative(*self.model.kernel_args(), *state.arrays(), dx, drot, dP, dL)
        return RigidState(dx, drot, dP, dL)


# -- energy scale for the runaway check -----------------------------------------------------------
def energy_scale(scene: Scene, first: Trajectory) -> float:
    """A generous bound on the energy the scene can exchange in its run (see RUNAWAY_FACTOR)."""
    from crosscheck.quantities import kinetic_energy, spring_potential_energy

    total = float(kinetic_energy(scene, first)[0] + spring_potential_energy(scene, first)[0])
    duration = scene.run.duration
    d = scene.dimension
    forces = np.zeros((len(scene.bodies), d))
    torques = np.zeros((len(scene.bodies), 3 if d == 3 else 1))
    if scene.effects.gravity is not None:
        forces += scene.masses[:, None] * np.asarray(scene.effects.gravity, float)
    for load in scene.effects.loads:
        forces[load.body] += load.force
        torques[load.body] += np.asarray(load.torque, float).reshape(-1)
    for i, body in enumerate(scene.bodies):
        f = float(np.linalg.norm(forces[i]))
        total += f * (float(np.linalg.norm(body.velocity)) * duration
                      + f * duration**2 / (2.0 * body.mass))
        tau = float(np.linalg.norm(torques[i]))
        if tau > 0:
            i_min = float(np.min(np.linalg.eigvalsh(np.atleast_2d(body.inertia))))
            total += tau * (float(np.linalg.norm(body.angular_velocity)) * duration
                            + tau * duration**2 / (2.0 * i_min))
    return max(total, 1e-12)


def _view(rec: TrajectoryRecorder, lo: int, hi: int) -> Trajectory:
    traj = Trajectory(t=rec.t[lo:hi], com=rec.com[lo:hi], vel=rec.vel[lo:hi],
                      omega=rec.omega[lo:hi])
    if rec.dimension == 3:
        traj.quat = rec.rot[lo:hi]
    else:
        traj.angle = rec.rot[lo:hi]
    return traj


@dataclass
class RunInfo:
    wall_time: float = 0.0  # s, stepping only
    compile_time: float = 0.0  # s, first call of the kernels (compile or cache load)
    steps: int = 0
    energy_scale: float = float("nan")
    settings: dict = field(default_factory=dict)


def simulate(scene: Scene, integrator: str, dt: float, *, plan=None,
             runaway_factor: float = RUNAWAY_FACTOR,
             check_every: int = ENERGY_CHECK_EVERY) -> tuple[TrajectoryRecorder, RunInfo]:
    """Run a rigid scene; returns the filled recorder (failure set on a blow-up) and RunInfo."""
    from crosscheck.engines.base import sampling_plan
    from crosscheck.quantities import total_energy

    plan = plan or sampling_plan(scene, dt)
    sim = RigidSimulation.from_scene(scene, integrator)
    model = sim.model
    state = state_from_scene(model, scene)
    rec = TrajectoryRecorder(plan.n_samples, model.n_bodies, model.dimension)
    info = RunInfo()
    info.compile_time = sim.warmup(state, dt)
    info.settings = dict(sim.integrator.describe(), effects_simulated=list(model.effects),
                         steps_per_sample=plan.steps_per_sample,
                         sample_interval=plan.sample_interval, runaway_factor=runaway_factor,
                         energy_check_every_samples=check_every)

    if not rec.record(0.0, *sim.observe(state)):
        return rec, info
    e0 = float(total_energy(scene, _view(rec, 0, 1))[0])
    info.energy_scale = scale = energy_scale(scene, _view(rec, 0, 1))
    checked = 1
    wall = 0.0
    perf = time.perf_counter
    for i in range(1, plan.n_samples):
        t0 = perf()
        try:
            sim.advance(state, plan.steps_per_sample, dt)
        except (ArithmeticError, np.linalg.LinAlgError, ValueError) as exc:
            wall += perf() - t0
            rec.fail(plan.time(i), f"step failed: {type(exc).__name__}: {exc}")
            break
        wall += perf() - t0
        info.steps += plan.steps_per_sample
        if not rec.record(plan.time(i), *sim.observe(state)):
            break
        if rec.count - checked >= check_every or i == plan.n_samples - 1:
            energy = total_energy(scene, _view(rec, checked, rec.count))
            bad = np.flatnonzero(~(np.abs(energy - e0) <= runaway_factor * scale))
            if bad.size:
                j = checked + int(bad[0])
                rec.count = j  # keep the samples before the runaway one
                rec.fail(rec.t[j], f"energy runaway: |E - E0| = {abs(energy[bad[0]] - e0):.3g} J"
                         f" > {runaway_factor:g} x energy scale {scale:.3g} J")
                break
            checked = rec.count
    info.wall_time = wall
    return rec, info
