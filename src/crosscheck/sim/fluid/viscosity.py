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


# the neighbour's offset (di, dj) in each direction of a link (0: +i, 1: -i, 2: +j, 3: -j)
DIRECTIONS = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]])


@njit(cache=True)
def _step(s):
    return DIRECTIONS[s, 0], DIRECTIONS[s, 1]


@njit(cache=True)
def sliver_links(state, dist, frac, normal_axis):
    """The slivers of one component and their links: ``(n0, n1)``, -1 for a sample that is not
    a sliver, else the direction (0: +i, 1: -i, 2: +j, 3: -j) of the fluid sample it is linked
    to. A sliver is a face cut by a body's wall whose sample lies inside the solid
    (``dist < 0``) but part of which is open (``frac < 1``); it is linked to the neighbour
    along the face (the tangential axis) on the open side, the one farther from the wall, if
    that neighbour is a fluid sample. Faces on the sides normal to the component and SOLID
    faces are never slivers."""
    n0, n1 = dist.shape
    link = -np.ones((n0, n1), np.int64)
    for i in range(n0):
        for j in range(n1):
            if state[i, j] == SOLID or dist[i, j] >= 0.0 or frac[i, j] >= 1.0:
                continue
            if normal_axis == 0 and (i == 0 or i == n0 - 1):
                continue
            if normal_axis == 1 and (j == 0 or j == n1 - 1):
                continue
            best = -1
            far = 0.0
            for s in range(4):
                if (s < 2) == (normal_axis == 0):
                    continue            # along the face only: +-j for u, +-i for v
                di, dj = _step(s)
                a, c = i + di, j + dj
                if a < 0 or a >= n0 or c < 0 or c >= n1:
                    continue
                if state[a, c] == SOLID or dist[a, c] < 0.0:
                    continue
                if best < 0 or dist[a, c] > far:
                    best = s
                    far = dist[a, c]
            link[i, j] = best
    return link


@njit(cache=True)
def sliver_weights(open_fraction):
    """``(f, link, wall)`` of a sliver (or an array of them): its momentum weight ``f``, the open
    fraction taken into [1e-6, 1/2] (at most 1/2 when the sample is inside), and the weights of
    its link to its fluid neighbour and to the wall, in units of the 5-point stencil's unit
    link. Its value is the mean over its open part, of length ``f dx``: the centroid is
    ``f / 2`` cells from the wall and ``1/2 + f / 2`` from the neighbour's sample."""
    f = np.minimum(np.maximum(open_fraction, 1e-6), 0.5)
    return f, 1.0 / (0.5 + 0.5 * f), 2.0 / f


@njit(cache=True)
def build_viscous(q, state, dist, use_dist, qsolid, frac, link, volume_weighted, k,
                  normal_axis, a_lo, c_lo, a_hi, c_hi, theta_min):
    """System of one component ``q`` ((n0, n1); ``normal_axis`` 0 for u on x-faces, 1 for v on
    y-faces), scaled by ``1/k`` so that every link between whole samples has the coefficient
    -1. Unknowns: samples that are not SOLID faces, not on the sides normal to the component
    (those keep their value: a wall, an inflow or an outflow face), and outside the obstacles
    (``dist >= 0`` when ``use_dist``), and the slivers ``link >= 0`` (:func:`sliver_links`;
    ``link`` all -1 for none). ``volume_weighted``: each face's momentum weighs its open
    fraction ``1 - frac`` (the mass the projection gives it), else 1. ``a_lo, c_lo, a_hi,
    c_hi``: ghost rows ``a q + c`` beyond the low and high sides along the tangential axis;
    ``theta_min`` the closest a wall is taken to be. Returns ``(index, diag, xm, xp, ym, yp,
    wxm, wxp, wym, wyp, b, vol)`` (``vol`` each unknown's weight of ``q / k``)."""
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
            if use_dist and dist[i, j] < 0.0 and link[i, j] < 0:
                continue
            index[i, j] = n
            n += 1
    diag = np.zeros(n)
    # each unknown's neighbour and link weight in the directions of DIRECTIONS (rows 0-3:
    # +i, -i, +j, -j), returned as the solver's xp, xm, yp, ym and their weights
    nb = -np.ones((4, n), np.int64)
    wt = np.ones((4, n))
    b = np.zeros(n)
    vol = np.ones(n)
    inv_k = 1.0 / k
    for i in range(n0):
        for j in range(n1):
            kk = index[i, j]
            if kk < 0:
                continue
            if use_dist and dist[i, j] < 0.0:
                # a sliver: its fluid neighbour and the wall (sliver_weights)
                v, t, tw = sliver_weights(1.0 - frac[i, j])
                vol[kk] = v
                diag[kk] = v * inv_k + t + tw
                b[kk] = v * q[i, j] * inv_k + tw * qsolid[i, j]
                s = link[i, j]
                di, dj = _step(s)
                nb[s, kk] = index[i + di, j + dj]
                wt[s, kk] = t
                continue
            v = 1.0
            if volume_weighted:
                v = max(1.0 - frac[i, j], 0.05)
            vol[kk] = v
            d = v * inv_k
            r = v * q[i, j] * inv_k
            for s in range(4):
                di, dj = _step(s)
                a = i + di
                c = j + dj
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
                wgt = 1.0
                if m >= 0 and use_dist and dist[a, c] < 0.0:
                    if link[a, c] == (s ^ 1):
                        # the sliver linked to this sample: its link replaces the wall
                        wgt = sliver_weights(1.0 - frac[a, c])[1]
                    else:
                        m = -1          # a sliver linked elsewhere: a wall for this sample
                if m >= 0:
                    d += wgt
                    nb[s, kk] = m
                    wt[s, kk] = wgt
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
    return index, diag, nb[1], nb[0], nb[3], nb[2], wt[1], wt[0], wt[3], wt[2], b, vol


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


def diffuse_implicit(q, state, dist, qsolid, k, normal_axis, ghost, q_old=None, frac=None,
                     theta_min=THETA_MIN, link=None):
    """One viscous step of the component ``q`` in place: backward Euler, or with ``q_old`` (the
    component at the start of the step) Crank-Nicolson, ``(I - k/2 L) q = q + k/2 L q_old``,
    the explicit half through the same ghost-fluid stencil. ``dist`` the solid's signed
    distance at the samples (None: staircase walls), ``qsolid`` the solid's velocity component
    there, ``ghost = (a_lo, c_lo, a_hi, c_hi)``, ``theta_min`` the closest a wall is taken to
    be (``MOVING_THETA_MIN`` with a coupled body). Returns the CG iterations.

    Without ``frac`` (the fixed solver) the cut faces whose sample lies inside the solid are
    not unknowns: they take the solid's velocity (the projection then moves them by the
    increment of the pressure, which vanishes in a steady state).

    With ``frac`` (the faces' solid fractions; a coupled body) the step exchanges momentum with
    the body, so it must be the momentum the projection sees (docs/fluid.md, "The body's share
    of the momentum"):

    * each face's momentum weighs its open fraction (the row of a cut face is ``(1 - frac) / k``
      on the diagonal), so that what the wall term puts into the fluid is what the body loses.
      With whole-cell weights a disc held in a Stokes stream received 4.5 % more force than the
      fluid's momentum balance around it measured (2.3 % at twice the resolution);
    * the slivers (cut faces whose sample is inside the body, :func:`sliver_links`) are
      unknowns, their open part's mean velocity between the wall and their fluid neighbour
      (:func:`sliver_weights`). Taking the body's velocity there and then the pressure's
      gradient (``u_body - dt grad p / rho``) gave them a slip proportional to the step: the
      drag on a driven disc changed by 0.4 % with each halving of the step. A sliver with no
      fluid neighbour along its face keeps its value. ``link``: the slivers'
      :func:`sliver_links` of this component, if the caller has them (the coupling's exchange
      needs the same ones)."""
    use_dist = dist is not None
    coupled = frac is not None
    d = dist if use_dist else np.zeros((1, 1))
    if coupled and use_dist:
        if link is None:
            link = sliver_links(state, d, frac, normal_axis)
    elif use_dist:
        link = -np.ones(q.shape, np.int64)
    else:
        link = -np.ones((1, 1), np.int64)
    fr = frac if coupled else np.zeros((1, 1))
    kk = k if q_old is None else 0.5 * k
    index, diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, vol = build_viscous(
        q, state, d, use_dist, qsolid, fr, link, coupled, kk, normal_axis, *ghost, theta_min)
    if diag.shape[0] == 0:
        return 0
    x = np.empty(diag.shape[0])
    # warm start: the advected values
    for_idx = index >= 0
    x[index[for_idx]] = q[for_idx]
    if q_old is not None:
        # A x = b is (V/kk - L) x = V q/kk + D (D: the walls' and known neighbours' part of L,
        # V the momentum weights); Crank-Nicolson adds L q_old = D + V q_old/kk - A q_old
        xo = np.empty_like(x)
        xo[index[for_idx]] = q_old[for_idx]
        axo = np.empty_like(x)
        _matvec(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, xo, axo)
        b = 2.0 * b - vol * x / kk + vol * xo / kk - axo
    bmax = float(np.max(np.abs(b)))
    its = pcg(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, x,
              max(VISCOUS_TOLERANCE * bmax, 1e-300), 1000)
    _scatter_solid(q, index, x, d, use_dist, qsolid, state, not coupled)
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
