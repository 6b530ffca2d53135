"""Forces of the fluid on an obstacle: a momentum balance over a smoothly weighted control volume.

The force on a body is ``F = - integral over its surface of sigma n`` (``n`` out of the fluid,
``sigma = -p I + tau``). Integrating the momentum equation against a weight ``chi`` that is 1 on
and near the body and falls smoothly to 0 before any other wall turns that surface integral into
a volume integral (the divergence theorem; John 2004 and the FEATFLOW reference values compute
drag and lift this way, and it is what a control-volume momentum balance with a smooth window
is):

    F = integral of [ (p I - tau) grad chi + rho u (u . grad chi) ] dV     (the ring 0 < chi < 1)
        - d/dt integral of rho chi u dV  +  rho g integral of chi dV       (the fluid with chi > 0)

for a body at rest (``u . n = 0`` on its surface; a moving body adds the flux of its surface).
The stresses are needed only in the ring, away from the cut cells, where the MAC fields are
second-order accurate; near the body only the fluid's momentum enters, weighted by the fluid
area of each cut cell, and its weight: ``integral over the fluid of chi = integral over the plane
of chi - the body's area`` (chi = 1 on the body), the first by the midpoint rule on the smooth
``chi``, the second exact (``cutcell.shape_area``; the shape's own area, so a moving body's
weight does not depend on how its cut cells are drawn). The weight is
``chi = S((d - d0) / (d1 - d0))`` of the body's own signed distance ``d``, with ``S`` the C2
quintic step from 1 to 0: ``d0`` and ``d1`` (m from the surface) set the ring. The result does
not depend on the window in the exact solution; the grid-convergence benchmark
(benchmarks/bench_dfg.py) measures how much it does on a grid.

Also here: the pressure on a body's surface at a point, by a least-squares quadratic fit of the
pressure in the fluid cells around it (the DFG pressure difference between the front and back
points of the cylinder).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from crosscheck.sim.fluid.cutcell import shape_area

# finite-difference step of the distance gradient, relative to the cell size
_GRAD_STEP = 1e-4


def smooth_step(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``S(s) = 1 - (6 s^5 - 15 s^4 + 10 s^3)`` on [0, 1] (1 below, 0 above) and ``S'(s)``."""
    c = np.clip(s, 0.0, 1.0)
    val = 1.0 - c ** 3 * (10.0 - 15.0 * c + 6.0 * c * c)
    der = np.where((s > 0.0) & (s < 1.0), -30.0 * c * c * (1.0 - c) ** 2, 0.0)
    return val, der


def default_window(shape: Any, others: Sequence[Any], domain: tuple[float, float],
                   dx: float) -> tuple[float, float]:
    """``(d0, d1)``: ``d1`` is the body's size (largest extent) or 0.9 of its clearance to the
    domain's sides and the other obstacles, whichever is smaller, ``d0 = d1 / 4``."""
    lo, hi = shape.bounding_box()
    size = float(np.max(hi - lo))
    clearance = min(lo[0], lo[1], domain[0] - hi[0], domain[1] - hi[1])
    for other in others:
        olo, ohi = other.bounding_box()
        gap = np.maximum(olo - hi, lo - ohi)
        clearance = min(clearance, float(np.max(gap)))
    d1 = min(size, 0.9 * clearance)
    if d1 <= 2.0 * dx:
        raise ValueError(f"no room for the force window around the obstacle: clearance "
                         f"{clearance:.4g} m on a grid of {dx:.4g} m; give "
                         "fluid.output.force_window")
    return 0.25 * d1, d1


@dataclass
class BodyWindow:
    """The weight of one obstacle on the cells of a sub-box ``[i0:i1, j0:j1]`` of the grid."""

    name: str
    i0: int
    i1: int
    j0: int
    j1: int
    chi: np.ndarray      # (ni, nj), at cell centres
    gx: np.ndarray       # d chi / dx
    gy: np.ndarray
    ring: np.ndarray     # bool: 0 < chi < 1 (where grad chi is not zero)
    weight: np.ndarray   # chi times the cell's fluid area fraction
    window: tuple[float, float]
    fluid_chi: float     # integral of chi over the fluid (m^2): over the plane minus the body


def body_window(name: str, shape: Any, window: tuple[float, float], nx: int, ny: int, dx: float,
                fluid_area: np.ndarray) -> BodyWindow:
    d0, d1 = window
    lo, hi = shape.bounding_box()
    i0 = max(int(math.floor((lo[0] - d1) / dx)) - 1, 0)
    j0 = max(int(math.floor((lo[1] - d1) / dx)) - 1, 0)
    i1 = min(int(math.ceil((hi[0] + d1) / dx)) + 2, nx)
    j1 = min(int(math.ceil((hi[1] + d1) / dx)) + 2, ny)
    x = (np.arange(i0, i1) + 0.5) * dx
    y = (np.arange(j0, j1) + 0.5) * dx
    X, Y = np.meshgrid(x, y, indexing="ij")
    pts = np.stack([X, Y], axis=-1)
    dist = shape.signed_distance(pts)
    s = (dist - d0) / (d1 - d0)
    chi, dchi = smooth_step(s)
    # gradient of the distance by central differences (the distance of a convex shape is C1
    # outside it, where the ring is)
    h = _GRAD_STEP * dx
    ex = np.array([h, 0.0])
    ey = np.array([0.0, h])
    ddx = (shape.signed_distance(pts + ex) - shape.signed_distance(pts - ex)) / (2 * h)
    ddy = (shape.signed_distance(pts + ey) - shape.signed_distance(pts - ey)) / (2 * h)
    g = dchi / (d1 - d0)
    ring = (s > 0.0) & (s < 1.0)
    fluid_chi = float(np.sum(chi)) * dx * dx - shape_area(shape)
    return BodyWindow(name, i0, i1, j0, j1, chi, g * ddx, g * ddy, ring,
                      chi * fluid_area[i0:i1, j0:j1], (d0, d1), fluid_chi)


class ForceProbe:
    """Force on each obstacle from the state after a step (``FluidState`` calls it)."""

    def __init__(self, shapes: Sequence[Any], names: Sequence[str], windows: Sequence[Any],
                 nx: int, ny: int, dx: float, domain: tuple[float, float],
                 fluid_area: np.ndarray):
        self.dx = dx
        self.bodies = []
        for k, (shape, name) in enumerate(zip(shapes, names, strict=True)):
            win = windows[k] if windows[k] is not None else default_window(
                shape, [s for m, s in enumerate(shapes) if m != k], domain, dx)
            self.bodies.append(body_window(name, shape, win, nx, ny, dx, fluid_area))
        self.momentum = [np.zeros(2) for _ in self.bodies]
        self.rate = [np.zeros(2) for _ in self.bodies]

    def body_momentum(self, b: BodyWindow, uc: np.ndarray, vc: np.ndarray,
                      rho: float) -> np.ndarray:
        sl = (slice(b.i0, b.i1), slice(b.j0, b.j1))
        da = self.dx * self.dx
        return rho * da * np.array([np.sum(b.weight * uc[sl]), np.sum(b.weight * vc[sl])])

    def advance(self, u: np.ndarray, v: np.ndarray, rho: float, dt: float) -> None:
        """After every step of ``dt``: the momentum in each window and its rate of change over the
        step (the ``d/dt`` term of the balance)."""
        uc = 0.5 * (u[1:] + u[:-1])
        vc = 0.5 * (v[:, 1:] + v[:, :-1])
        for k, b in enumerate(self.bodies):
            m_new = self.body_momentum(b, uc, vc, rho)
            self.rate[k] = (m_new - self.momentum[k]) / dt if dt > 0 else np.zeros(2)
            self.momentum[k] = m_new

    def forces(self, u: np.ndarray, v: np.ndarray, p: np.ndarray, rho: float, mu: float,
               gravity: np.ndarray) -> dict[str, tuple[float, float]]:
        """Forces (N per unit depth) on each obstacle, by name, in the state ``u, v, p`` reached
        by the last ``advance``."""
        uc = 0.5 * (u[1:] + u[:-1])
        vc = 0.5 * (v[:, 1:] + v[:, :-1])
        out = {}
        for k, b in enumerate(self.bodies):
            fx, fy = self._ring(b, u, v, uc, vc, p, rho, mu)
            fx += -self.rate[k][0] + rho * gravity[0] * b.fluid_chi
            fy += -self.rate[k][1] + rho * gravity[1] * b.fluid_chi
            out[b.name] = (fx, fy)
        return out

    def _ring(self, b: BodyWindow, u, v, uc, vc, p, rho, mu) -> tuple[float, float]:
        dx = self.dx
        ii, jj = np.nonzero(b.ring)
        gx = b.gx[ii, jj]
        gy = b.gy[ii, jj]
        i = ii + b.i0
        j = jj + b.j0
        nx, ny = p.shape
        ip = np.minimum(i + 1, nx - 1)
        im = np.maximum(i - 1, 0)
        jp = np.minimum(j + 1, ny - 1)
        jm = np.maximum(j - 1, 0)
        dudx = (u[i + 1, j] - u[i, j]) / dx
        dvdy = (v[i, j + 1] - v[i, j]) / dx
        dudy = (uc[i, jp] - uc[i, jm]) / ((jp - jm) * dx)
        dvdx = (vc[ip, j] - vc[im, j]) / ((ip - im) * dx)
        txx = 2.0 * mu * dudx
        tyy = 2.0 * mu * dvdy
        txy = mu * (dudy + dvdx)
        ucc = uc[i, j]
        vcc = vc[i, j]
        pc = p[i, j]
        flux = rho * (ucc * gx + vcc * gy)
        da = dx * dx
        fx = float(np.sum((pc - txx) * gx - txy * gy + ucc * flux) * da)
        fy = float(np.sum(-txy * gx + (pc - tyy) * gy + vcc * flux) * da)
        return fx, fy


def balance_after_each_step(state: Any, places: Any) -> list[tuple[float, dict]]:
    """Measure the fluid's momentum balance around the obstacles of ``places`` (a
    ``FluidSpec`` with forces output: their shapes, names and window) on ``state`` (a
    ``FluidState``) after each of its steps from now on: the list returned fills with ``(time,
    forces by name)``. For a state whose solver does not measure those places itself: a
    coupled body's place, whose fluid balance is checked against the body's momentum change
    (Newton's third law, benchmarks/bench_faxen_frame.py and bench_sedimentation_frame.py)."""
    probe = ForceProbe(places.obstacles, places.obstacle_names, [places.output.forces.window],
                       state.nx, state.ny, state.dx, (state.lx, state.ly),
                       state.boundary.fluid_area)
    out: list[tuple[float, dict]] = []
    step = state.step

    def step_and_measure(dt, timers, solid=None):
        result = step(dt, timers, solid)
        probe.advance(state.u, state.v, state.spec.density, dt)
        out.append((state.time, probe.forces(state.u, state.v, state.p, state.spec.density,
                                             state.spec.dynamic_viscosity, state.gravity)))
        return result

    state.step = step_and_measure
    return out


def surface_pressure(p: np.ndarray, c_dist: np.ndarray, dx: float, point: Sequence[float],
                     radius_cells: float = 3.0) -> float:
    """Pressure at ``point`` (on or near an obstacle's surface): the least-squares quadratic
    ``a + b x + c y + d x^2 + e x y + f y^2`` through the cell-centred pressures of the cells
    whose centres lie outside the obstacles (``c_dist > 0``) within ``radius_cells`` cells of the
    point, evaluated at the point. Second-order accurate; ValueError with fewer than 10 cells."""
    nx, ny = p.shape
    px, py = float(point[0]), float(point[1])
    r = radius_cells * dx
    i0 = max(int((px - r) / dx) - 1, 0)
    i1 = min(int((px + r) / dx) + 2, nx)
    j0 = max(int((py - r) / dx) - 1, 0)
    j1 = min(int((py + r) / dx) + 2, ny)
    ii, jj = np.meshgrid(np.arange(i0, i1), np.arange(j0, j1), indexing="ij")
    X = ((ii + 0.5) * dx - px) / dx
    Y = ((jj + 0.5) * dx - py) / dx
    use = (X * X + Y * Y <= radius_cells ** 2) & (c_dist[ii, jj] > 0.0)
    if np.count_nonzero(use) < 10:
        raise ValueError(f"too few fluid cells around {tuple(point)} for the surface pressure")
    x, y = X[use], Y[use]
    A = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)
    coef, *_ = np.linalg.lstsq(A, np.asarray(p, float)[ii[use], jj[use]], rcond=None)
    return float(coef[0])
