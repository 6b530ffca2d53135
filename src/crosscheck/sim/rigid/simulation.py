"""A compiled model bound to one integrator: stepping, observation and the state derivative.

:class:`RigidSimulation` is all the in-house engine adapter needs to open a session
(engines/inhouse.py); sampling, recording, blow-up detection and timing belong to the one run
driver (engines/driver.py), the same for every engine.
"""

from __future__ import annotations

import time

import numpy as np

from crosscheck.scene.model import Scene
from crosscheck.sim.rigid import forces2d, forces3d
from crosscheck.sim.rigid.integrators import Integrator, get_integrator
from crosscheck.sim.rigid.model import RigidModel, RigidState, compile_model


def step(model: RigidModel, state_in: RigidState, state_out: RigidState, control, contacts,
         h: float, integrator: str | Integrator = "rk4") -> None:
    """One step of the named integrator from state_in into state_out (Newton / warp.sim style).

    ``control``: a model.Control (per-body external wrenches, world frame, at the centres of mass)
    or None; ``contacts``: the contact model's slot, None (no contact code yet)."""
    _integrator(integrator).step(model, state_in, state_out, control, contacts, h)


def advance(model: RigidModel, state: RigidState, control, contacts, n_steps: int, h: float,
            integrator: str | Integrator = "rk4") -> None:
    """n_steps fused steps in place, in one compiled call (what the engine runs between samples);
    ``control`` is held constant over them."""
    _integrator(integrator).advance(model, state, control, contacts, n_steps, h)


def _integrator(integrator: str | Integrator) -> Integrator:
    return integrator if isinstance(integrator, Integrator) else get_integrator(integrator)


class RigidSimulation:
    """A compiled model plus one integrator; steps a RigidState in place."""

    def __init__(self, model: RigidModel, integrator: str | Integrator = "rk4"):
        self.model = model
        self.integrator = (integrator if isinstance(integrator, Integrator)
                           else get_integrator(integrator))

    @classmethod
    def from_scene(cls, scene: Scene, integrator: str = "rk4") -> RigidSimulation:
        return cls(compile_model(scene), integrator)

    def advance(self, state: RigidState, n_steps: int, h: float, control=None,
                contacts=None) -> None:
        """Take n_steps steps of size h in place (control held over them; see ``advance``)."""
        self.integrator.advance(self.model, state, control, contacts, n_steps, h)

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
            forces3d.observe(self.model.bodies, state.rot, state.P, state.L, vel, omega)
        else:
            vel = np.empty((n, 2))
            omega = np.empty(n)
            forces2d.observe(self.model.bodies, state.P, state.L, vel, omega)
        return state.x.copy(), state.rot.copy(), vel, omega

    def derivative(self, state: RigidState) -> RigidState:
        """The state derivative (v, dq/dt, F, tau) from the same kernels the integrators use."""
        dx, drot, dP, dL = (np.empty_like(a) for a in state.arrays())
        kern = forces3d if self.model.dimension == 3 else forces2d
        kern.derivative(*self.model.kernel_args(), None, None, *state.arrays(), dx, drot, dP, dL)
        return RigidState(dx, drot, dP, dL)
