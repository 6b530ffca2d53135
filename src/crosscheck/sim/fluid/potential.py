"""The discrete potential flow past a scene's obstacles: a uniform stream projected once.

With no viscosity and no time step, one projection of the uniform stream ``U e_x`` (the solid faces
at the obstacles' velocity, zero) is the discrete potential flow past the obstacles: the field of
least kinetic energy that is divergence free with no flow through them. Its disturbance energy ``E =
1/2 integral |u - U e_x|^2 dA`` is, for the exact flow, half the added mass times ``U^2`` (``rho pi
r^2`` for a circle in an unbounded fluid, the classical potential-flow result). It measures the
projection at the wall alone: ``benchmarks/cutcell_placement.py`` and
``tests/fluid/test_cutcell.py`` move an obstacle by fractions of a cell, which leaves the exact
``E`` unchanged, and read the spread.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from crosscheck.sim.fluid.boundary import impose
from crosscheck.sim.fluid.pressure import project
from crosscheck.sim.fluid.solver import INTEGRATORS, FluidState


def disturbance_energy(spec: Any, speed: float = 1.0, tolerance: float = 1e-12) -> float:
    """``E`` (m^4/s^2 per metre of depth over density) of the stream ``speed`` along x projected
    once on the fluid ``spec`` (an enclosed fluid's domain without free surface; the inflow side,
    if any, should carry the same uniform speed). Each face counts with its open fraction."""
    state = FluidState(spec, np.zeros(3), INTEGRATORS["central"])
    bnd = state.static_boundary
    u = np.full(state.u.shape, float(speed))
    v = np.zeros(state.v.shape)
    state.classify()
    impose(u, v, state.ustate, state.vstate, bnd)
    project(state.phi, bnd, u, v, state.ustate, state.vstate, np.zeros_like(state.p), tolerance)
    return float(0.5 * (np.sum((1.0 - bnd.u_frac) * (u - speed) ** 2)
                        + np.sum((1.0 - bnd.v_frac) * v ** 2)) * spec.dx ** 2)
