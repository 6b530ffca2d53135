"""Implicit viscosity with no-slip walls where they really are (ghost fluid on cut cells).

Backward Euler for each velocity component, ``(I - k L) q = q_adv`` with ``k = nu dt / dx^2``,
on the 5-point Laplacian of the MAC samples. Where the segment from a sample to its neighbour
crosses an obstacle's wall (the solid's signed distance changes sign between them, at the
fraction ``theta`` of the way), the neighbour is replaced by the ghost value that makes the
linear interpolant equal the wall velocity on the wall: ``q_g = q_b / theta + (1 - 1/theta) q``
(Gibou, Fedkiw, Cheng and Kang 2002, the same device the pressure uses at the free surface). The
matrix stays symmetric (the wall only adds ``1/theta`` to the diagonal), so the MIC(0)-CG of the
pressure solves it. Samples inside an obstacle take the obstacle's velocity (Ng, Min and Gibou
2009). Grid-aligned walls of the domain enter through the ghost rows as in the explicit step
(no-slip ``2 U - q``: the wall half a cell away).

An explicit step would need ``k <= theta / 4``: a wall a hundredth of a cell from a sample would
cut the step a hundredfold. The implicit step has no such limit, and its two solves converge in
a few iterations (the matrix is ``1/k`` plus a Laplacian).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim.fluid.pressure import SOLID, _matvec, pcg

# closest a wall may be to a sample, in cells (the diagonal grows as 1/theta)
THETA_MIN = 1e-2
# the same with a coupled body, whose wall sweeps across the samples: each sample it approaches
# passes through every theta, and one whose velocity still differs from the wall's by a finite
# amount then gives a wall term (q_wall - q) / theta whose sum over the steps grows as
# log(1 / max(theta_min, k)), k = nu dt / dx^2: the viscous force on a body driven at a constant
# speed rose as the step shrank (+0.7 / +2.0 / +3.7 % against its frame's drag at 4 cells and
# 2 / 1 / 0.5 ms), almost all of the rise from samples within 0.1 cell of the wall at the
# body's front. With the walls held at least 0.1 cell from the samples it is -0.6 / -0.5 % at
# 2 / 0.5 ms (+1.8 / +2.1 % at 8 cells, where it was +2.2 / +3.4 %), and a fixed obstacle's
# drag is unchanged (its samples keep their distances, and those close to the wall keep the
# wall's velocity): docs/fluid.md, "The settling disc in its own frame"
MOVING_THETA_MIN = 0.1
VISCOUS_TOLERANCE = 1e-10


@njit(cache=True)
def build_viscous(q, state, dist, use_dist, qsolid, k, normal_axis,
                  a_lo, c_lo, a_hi, c_hi, theta_min):
    """System of one component ``q`` ((n0, n1); ``normal_axis`` 0 for u on x-faces, 1 for v on
    y-faces), scaled by ``1/k`` so that every link has the coefficient -1. Unknowns: samples that
    are not SOLID faces, not on the sides normal to the component (those keep their value: a wall,
    an inflow or an outflow face), and outside the obstacles (``dist >= 0`` when ``use_dist``).
    ``a_lo, c_lo, a_hi, c_hi``: ghost rows ``a q + c`` beyond the low and high sides along the
    tangential axis; ``theta_min`` the closest a wall is taken to be. Returns
    ``(index, diag, xm, xp, ym, yp, w, b)``."""
    n0, n1 = q.shape
    index = -np.ones((n0, n1), np.int64)
    n = 0
    for i in range(n0):
        for j in range(n1):
            if state[i, j] == SOLID:
                continue
            if normal_axis == 0 and (i == 0 or i == n0 - 1):
                continue
            if normal_axis == 1 and (j == 0 or j == n1 - 1):
                continue
            if use_dist and dist[i, j] < 0.0:
                continue
            index[i, j] = n
            n += 1
    diag = np.zeros(n)
    xm = -np.ones(n, np.int64)
    xp = -np.ones(n, np.int64)
    ym = -np.ones(n, np.int64)
    yp = -np.ones(n, np.int64)
    w = np.ones(n)
    b = np.zeros(n)
    inv_k = 1.0 / k
    for i in range(n0):
        for j in range(n1):
            kk = index[i, j]
            if kk < 0:
                continue
            d = inv_k
            r = q[i, j] * inv_k
            for s in range(4):
                a = i + (1 if s == 0 else (-1 if s == 1 else 0))
                c = j + (1 if s == 2 else (-1 if s == 3 else 0))
                if a < 0 or a >= n0 or c < 0 or c >= n1:
                    # beyond a side tangential to the component: the wall's ghost row
                    if (a < 0) or (c < 0):
                        d += 1.0 - a_lo
                        r += c_lo
                    else:
                        d += 1.0 - a_hi
                        r += c_hi
                    continue
                m = index[a, c]
                if m >= 0:
                    d += 1.0
                    if s == 0:
                        xp[kk] = m
                    elif s == 1:
                        xm[kk] = m
                    elif s == 2:
                        yp[kk] = m
                    else:
                        ym[kk] = m
                elif use_dist and dist[a, c] < 0.0:
                    # the wall lies between the sample and this neighbour, at theta
                    theta = dist[i, j] / (dist[i, j] - dist[a, c])
                    if theta < theta_min:
                        theta = theta_min
                    d += 1.0 / theta
                    r += qsolid[a, c] / theta
                else:
                    # a known value one cell away: a wall, inflow or outflow face, air
                    d += 1.0
                    r += q[a, c]
            diag[kk] = d
            b[kk] = r
    return index, diag, xm, xp, ym, yp, w, b


@njit(cache=True)
def _scatter_solid(q, index, x, dist, use_dist, qsolid, state, write_inside):
    n0, n1 = q.shape
    for i in range(n0):
        for j in range(n1):
            kk = index[i, j]
            if kk >= 0:
                q[i, j] = x[kk]
            elif write_inside and use_dist and dist[i, j] < 0.0 and state[i, j] != SOLID:
                q[i, j] = qsolid[i, j]


def diffuse_implicit(q, state, dist, qsolid, k, normal_axis, ghost, q_old=None,
                     keep_cut_inside=False, theta_min=THETA_MIN):
    """One viscous step of the component ``q`` in place: backward Euler, or with ``q_old`` (the
    component at the start of the step) Crank-Nicolson, ``(I - k/2 L) q = q + k/2 L q_old``,
    the explicit half through the same ghost-fluid stencil. ``dist`` the solid's signed
    distance at the samples (None: staircase walls), ``qsolid`` the solid's velocity component
    there, ``ghost = (a_lo, c_lo, a_hi, c_hi)``, ``theta_min`` the closest a wall is taken to
    be (``MOVING_THETA_MIN`` with a coupled body). Returns the CG iterations.

    The cut faces whose sample lies inside the solid are not unknowns; they take the solid's
    velocity, unless ``keep_cut_inside``: then they keep their value. The coupled incremental
    step needs that: it has put the previous pressure's gradient on them (the open part's flux,
    which the projection moves), and writing the body's velocity over it made each increment put
    it back, so the carried pressure drifted with the number of steps (a disc in Stokes flow
    settled 27 % too fast, 50 % with half the step; docs/fluid.md)."""
    use_dist = dist is not None
    d = dist if use_dist else np.zeros((1, 1))
    kk = k if q_old is None else 0.5 * k
    index, diag, xm, xp, ym, yp, w, b = build_viscous(q, state, d, use_dist, qsolid, kk,
                                                      normal_axis, *ghost, theta_min)
    if diag.shape[0] == 0:
        return 0
    x = np.empty(diag.shape[0])
    # warm start: the advected values
    for_idx = index >= 0
    x[index[for_idx]] = q[for_idx]
    if q_old is not None:
        # A x = b is (I/kk - L) x = q/kk + D (D: the walls' and known neighbours' part of L);
        # Crank-Nicolson adds L q_old = D + q_old/kk - A q_old to the right-hand side
        xo = np.empty_like(x)
        xo[index[for_idx]] = q_old[for_idx]
        axo = np.empty_like(x)
        _matvec(diag, xm, xp, ym, yp, w, w, w, w, xo, axo)
        b = 2.0 * b - x / kk + xo / kk - axo
    bmax = float(np.max(np.abs(b)))
    its = pcg(diag, xm, xp, ym, yp, w, w, w, w, b, x, max(VISCOUS_TOLERANCE * bmax, 1e-300),
              1000)
    _scatter_solid(q, index, x, d, use_dist, qsolid, state, not keep_cut_inside)
    return its


def viscous_dissipation(u: np.ndarray, v: np.ndarray, weight: np.ndarray, dx: float, mu: float,
                        ghosts: dict[str, tuple[float, float]]) -> float:
    """``2 mu integral of D:D dA`` (W per metre of depth) of the MAC field: the rate at which
    viscosity turns the flow's kinetic energy into heat, ``D = (grad u + grad u^T) / 2``.

    ``D11 = du/dx`` and ``D22 = dv/dy`` at the cell centres, weighted by ``weight`` (nx, ny), the
    open liquid fraction of each cell; ``D12`` at the cell corners, weighted by the mean of the
    four cells around the corner (cells beyond the domain weigh 0, so a corner on a wall counts
    half). The tangential component beyond a side takes the ghost ``a q + c`` of
    ``ghosts[side] = (a, c)``: ``(-1, 0)`` a no-slip wall at rest (the wall half a cell from the
    samples, as the viscous step has it), ``(-1, 2 U)`` a lid moving at U, ``(1, 0)`` a free-slip
    or open side. Samples inside a solid carry its rigid velocity (whose D is zero), so a cut
    cell's gradients span the wall with the rigid velocity a fraction of a cell inside: first
    order at the wall, where the viscous step itself is second order (ghost fluid)."""
    nx, ny = weight.shape
    d11 = (u[1:, :] - u[:-1, :]) / dx
    d22 = (v[:, 1:] - v[:, :-1]) / dx
    cells = float(np.sum(weight * (d11 * d11 + d22 * d22)))
    # du/dy at the corners (nx + 1, ny + 1): ghost rows below and above
    ab, cb = ghosts.get("bottom", (-1.0, 0.0))
    at, ct = ghosts.get("top", (-1.0, 0.0))
    ue = np.empty((nx + 1, ny + 2))
    ue[:, 1:-1] = u
    ue[:, 0] = ab * u[:, 0] + cb
    ue[:, -1] = at * u[:, -1] + ct
    dudy = (ue[:, 1:] - ue[:, :-1]) / dx
    al, cl = ghosts.get("left", (-1.0, 0.0))
    ar, cr = ghosts.get("right", (-1.0, 0.0))
    ve = np.empty((nx + 2, ny + 1))
    ve[1:-1, :] = v
    ve[0, :] = al * v[0, :] + cl
    ve[-1, :] = ar * v[-1, :] + cr
    dvdx = (ve[1:, :] - ve[:-1, :]) / dx
    d12 = 0.5 * (dudy + dvdx)
    wp = np.zeros((nx + 2, ny + 2))
    wp[1:-1, 1:-1] = weight
    wc = 0.25 * (wp[1:, 1:] + wp[:-1, 1:] + wp[1:, :-1] + wp[:-1, :-1])
    corners = float(np.sum(wc * 2.0 * d12 * d12))
    return 2.0 * mu * (cells + corners) * dx * dx
