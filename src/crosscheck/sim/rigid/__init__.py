"""In-house contact-free rigid-body simulator (Baraff's state x, q, P, L; planar in 2D).

Public API:

* :func:`compile_model` (Scene -> :class:`RigidModel`), :func:`state_from_scene`
  (-> :class:`RigidState`), :class:`RigidSimulation` (model + integrator: ``advance``,
  ``observe``, ``derivative``); the engine adapter (engines/inhouse.py) opens a session on it
  and the run driver (engines/driver.py) records and times it.
* :func:`step` (model, state_in, state_out, control, contacts, h) and :func:`advance` (model,
  state, control, contacts, n_steps, h), the fused n-step loop; :class:`Control` holds per-body
  external wrenches (None when there are none), ``contacts`` is the contact model's slot (None).
* :data:`INTEGRATORS` / :func:`get_integrator`: the registry (name, order, symplectic, rotation).
* The generic ODE interface: :func:`initial_state` (flat y0), :func:`state_derivative` (f(t, y))
  and :func:`state_to_trajectory`, all on the same kernels. The DOP853 reference does not use
  it (it integrates crosscheck.reference.newton_euler, written apart so the engine is not judged
  against itself); tests compare the two derivatives.

See docs/inhouse.md for the design and the measured numbers.
"""

from __future__ import annotations

import numpy as np

from crosscheck.sim.rigid.integrators import DEFAULT, INTEGRATORS, Integrator, get_integrator
from crosscheck.sim.rigid.model import (
    Control,
    RigidModel,
    RigidState,
    compile_model,
    state_from_scene,
)
from crosscheck.sim.rigid.simulation import RigidSimulation, advance, step

__all__ = [
    "DEFAULT", "INTEGRATORS", "Control", "Integrator", "RigidModel", "RigidSimulation",
    "RigidState", "advance", "compile_model", "get_integrator", "initial_state",
    "state_derivative", "state_from_scene", "state_to_trajectory", "step",
]


def initial_state(scene) -> np.ndarray:
    """The flat state vector (x, q or angle, P, L) at t = 0."""
    return state_from_scene(compile_model(scene), scene).flat()


def state_derivative(scene):
    """f(t, y) of the scene's equations of motion on the flat state (the compiled kernels)."""
    sim = RigidSimulation(compile_model(scene))
    n, d = sim.model.n_bodies, sim.model.dimension

    def f(t: float, y: np.ndarray) -> np.ndarray:
        return sim.derivative(RigidState.from_flat(y, n, d)).flat()

    return f


def state_to_trajectory(scene, t: np.ndarray, Y: np.ndarray):
    """A Trajectory from flat states Y (T, size) at times t (quaternions renormalised)."""
    from crosscheck.state import TrajectoryRecorder

    sim = RigidSimulation(compile_model(scene))
    n, d = sim.model.n_bodies, sim.model.dimension
    t = np.asarray(t, float)
    rec = TrajectoryRecorder(len(t), n, d)
    for ti, y in zip(t, np.asarray(Y, float), strict=True):
        state = RigidState.from_flat(y, n, d)
        if d == 3:
            state.rot /= np.linalg.norm(state.rot, axis=1, keepdims=True)
        if not rec.record(ti, *sim.observe(state)):
            break
    return rec.finish({"case": scene.name, "bodies": list(scene.body_names),
                       "masses": [b.mass for b in scene.bodies]})
