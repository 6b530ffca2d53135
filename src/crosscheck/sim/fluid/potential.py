"""The discrete potential flow past a scene's obstacles: a uniform stream projected once.

With no viscosity and no time step, one projection of the uniform stream ``U e_x`` (the solid faces
at the obstacles' velocity, zero) is the discrete potential flow past the obstacles: the field of
least kinetic energy that is divergence free with no flow through them. Its disturbance energy ``E =
1/2 integral |u - U e_x|^2 dA`` is, for the exact flow, half the added mass times ``U^2`` (``rho pi
r^2`` for a circle in an unbounded fluid, the classical potential-flow result), and it does not
change when the obstacle moves along a channel. ``benchmarks/cutcell_placement.py`` and
``tests/fluid/test_cutcell.py`` move an obstacle by fractions of a cell and read the spread: of
the whole ``E`` (which counts the cut faces, and so the wall's cells), and of ``E`` in a smooth
window away from the wall (the far field, the dipole the obstacle makes).

:func:`moving_body_added_mass` is the same minimum for a body moving through a closed domain's
resting fluid: the discrete added mass, which the coupled projection's first step from rest
must reproduce (it is the same minimisation with the body's velocity an unknown)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from crosscheck.sim.fluid.boundary import SolidBoundary, impose
from crosscheck.sim.fluid.pressure import project
from crosscheck.sim.fluid.solver import INTEGRATORS, FluidState


def far_window(cx: float, cy: float, inner: float, outer: float
               ) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """A ``weight`` for :func:`stream_energy`: 0 within ``inner`` of the point (cx, cy), 1
    beyond ``outer``, the C2 quintic step between (smooth, so the windowed energy does not jump
    as grid samples cross a circle)."""
    def weight(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        t = np.clip((np.hypot(x - cx, y - cy) - inner) / (outer - inner), 0.0, 1.0)
        return t ** 3 * (10.0 - 15.0 * t + 6.0 * t * t)
    return weight


def projected_stream(spec: Any, speed: float = 1.0, tolerance: float = 1e-12):
    """``(u, v, boundary)``: the stream ``speed`` along x projected once on the fluid ``spec``
    (an enclosed fluid's domain without free surface; the inflow side, if any, should carry the
    same uniform speed)."""
    state = FluidState(spec, np.zeros(3), INTEGRATORS["central"])
    bnd = state.static_boundary
    u = np.full(state.u.shape, float(speed))
    v = np.zeros(state.v.shape)
    state.classify()
    impose(u, v, state.ustate, state.vstate, bnd)
    project(state.phi, bnd, u, v, state.ustate, state.vstate, np.zeros_like(state.p), tolerance)
    return u, v, bnd


def stream_energy(spec: Any, u: np.ndarray, v: np.ndarray, bnd: Any, speed: float = 1.0,
                  weight: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> float:
    """``E`` (m^4/s^2 per metre of depth over density) of a ``projected_stream`` ``(u, v, bnd)``
    of the stream ``speed``. Each face counts with its open fraction, times ``weight(x, y)`` at
    its sample if given (a smooth window that leaves out the cut cells measures the far field
    alone: the faces at the wall carry the open part's mean flux, whose square is not the
    kinetic energy of the part they stand for)."""
    wu, wv = 1.0 - bnd.u_frac, 1.0 - bnd.v_frac
    if weight is not None:
        nx, ny = spec.resolution
        dx = spec.dx
        iu, ju = np.meshgrid(np.arange(nx + 1), np.arange(ny), indexing="ij")
        iv, jv = np.meshgrid(np.arange(nx), np.arange(ny + 1), indexing="ij")
        wu = wu * weight(iu * dx, (ju + 0.5) * dx)
        wv = wv * weight((iv + 0.5) * dx, jv * dx)
    return float(0.5 * (np.sum(wu * (u - speed) ** 2) + np.sum(wv * v ** 2)) * spec.dx ** 2)


def disturbance_energy(spec: Any, speed: float = 1.0, tolerance: float = 1e-12,
                       weight: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
                       ) -> float:
    """``stream_energy`` of the stream ``speed`` projected once on ``spec``."""
    return stream_energy(spec, *projected_stream(spec, speed, tolerance), speed, weight)


def moving_body_added_mass(spec: Any, body: Any, velocity: tuple[float, float],
                           tolerance: float = 1e-12) -> float:
    """The discrete added mass (kg per metre of depth) of the placed shape ``body`` (a
    ``scene.shapes.Placed``) translating at ``velocity`` through the resting fluid of ``spec``
    (a closed domain without free surface or obstacles; its coupled bodies, if any, are left
    out): the fluid at rest, every face the body covers or cuts given its velocity, one
    projection, and ``2 E / |velocity|^2`` with ``E`` the fluid's kinetic energy, each face
    weighted by its open fraction as the projection weighs it. The domain's walls stay at
    rest."""
    if (spec.has_surface or spec.obstacles
            or any(kind != "solid" for kind in spec.walls.values())):
        raise ValueError("moving_body_added_mass needs a closed domain full of fluid, without "
                         "obstacles (solid walls, no free surface)")
    if not np.any(np.asarray(velocity, float)):
        raise ValueError("moving_body_added_mass needs a velocity other than zero")
    nx, ny = spec.resolution
    state = FluidState(dataclasses.replace(spec, bodies=()), np.zeros(2), INTEGRATORS["central"])
    shape_only = SolidBoundary.from_shapes([body], nx, ny, spec.dx, np.zeros(4, bool))
    u_solid = np.where(shape_only.u_frac > 0.0, float(velocity[0]), 0.0)
    v_solid = np.where(shape_only.v_frac > 0.0, float(velocity[1]), 0.0)
    u_solid[[0, -1], :] = 0.0      # the domain's walls
    v_solid[:, [0, -1]] = 0.0
    bnd = dataclasses.replace(shape_only, u_solid=u_solid, v_solid=v_solid)
    state.boundary = bnd
    state.classify()
    u, v = np.zeros(state.u.shape), np.zeros(state.v.shape)
    impose(u, v, state.ustate, state.vstate, bnd)
    project(state.phi, bnd, u, v, state.ustate, state.vstate, np.zeros_like(state.p), tolerance)
    energy = 0.5 * (np.sum((1.0 - bnd.u_frac) * u ** 2) + np.sum((1.0 - bnd.v_frac) * v ** 2))
    return float(2.0 * spec.density * energy * spec.dx ** 2 / np.dot(velocity, velocity))
