"""Pressure projection: boundary-modified Poisson stencil, ghost-fluid free surface, MIC(0)-PCG.

We solve for ``pt = p dt / (rho dx)`` (pressure scaled to a velocity) so that the face update is
simply ``u -= pt[right] - pt[left]``. For every fluid cell the equation is

    sum over non-solid neighbours of (pt_cell - pt_nb) = -(sum of outward face velocities)

which is the seed's stencil: a neighbour across a solid face drops out of both the sum and the
diagonal (the "-3" stencil next to a wall); u . n = u_solid . n is kept by leaving the solid face
at the solid's velocity, which the right-hand side includes (``boundary.py``).
An air neighbour is a Dirichlet neighbour with p = 0 *on the surface*, not at its centre: with the
surface at a fraction ``theta = phi_f / (phi_f - phi_a)`` of the way to the air centre, the ghost
pressure is ``pt_f (1 - 1/theta)`` (Gibou et al. 2002; Enright et al. 2003), so the diagonal gets
``1/theta`` and the surface position enters below cell size. ``theta`` is clamped at 0.01 (as in
Bridson's book) to keep the matrix well conditioned; this loses the subcell position only when the
surface is within a hundredth of a cell of a centre.

The matrix is stored compressed: fluid cells in C order (i outer, j inner) with their diagonal
and the index of each fluid neighbour (-1 if none). C order means the (i-1, j) and (i, j-1)
neighbours come first, which is the ordering the incomplete Cholesky factor needs. The whole
preconditioned conjugate gradient loop runs compiled; the MIC(0) triangular solves, which are
sequential, cost about as much as two matrix-vector products.
"""

from __future__ import annotations

import numpy as np
from numba import njit

THETA_MIN = 0.01

# face states
AIR, FLUID, SOLID = 0, 1, 2


@njit(cache=True)
def classify_faces(phi, u_frac, v_frac, ustate, vstate):
    """Face states: SOLID where the solid boundary closes the face entirely (obstacles and closed
    sides, see ``boundary.py``), FLUID if next to a fluid cell, AIR otherwise (to be filled by
    velocity extension). A cut face (partly open) is FLUID: the projection moves it. A face on an
    open side looks at its one cell."""
    nx, ny = phi.shape
    for i in range(nx + 1):
        for j in range(ny):
            if u_frac[i, j] >= 1.0:
                ustate[i, j] = SOLID
            elif i == 0 or i == nx:
                ustate[i, j] = FLUID if phi[0 if i == 0 else nx - 1, j] < 0.0 else AIR
            elif phi[i - 1, j] < 0.0 or phi[i, j] < 0.0:
                ustate[i, j] = FLUID
            else:
                ustate[i, j] = AIR
    for i in range(nx):
        for j in range(ny + 1):
            if v_frac[i, j] >= 1.0:
                vstate[i, j] = SOLID
            elif j == 0 or j == ny:
                vstate[i, j] = FLUID if phi[i, 0 if j == 0 else ny - 1] < 0.0 else AIR
            elif phi[i, j - 1] < 0.0 or phi[i, j] < 0.0:
                vstate[i, j] = FLUID
            else:
                vstate[i, j] = AIR


@njit(cache=True, inline="always")
def _theta(pf, pa):
    t = pf / (pf - pa)
    return THETA_MIN if t < THETA_MIN else t


@njit(cache=True)
def build_system(phi, u_frac, v_frac, u, v, u_solid, v_solid):
    """Assemble the compressed matrix and right-hand side. Returns
    ``(index, diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, n_dirichlet)``.

    Unknowns are the fluid cells (``phi < 0``) with at least one face not entirely solid. Each
    face enters with the weight ``W = 1 - solid fraction`` (its open fraction): the coefficient of
    the neighbour across it is ``-W`` (``wxm`` ... ``wyp``, 0 where there is no neighbour unknown)
    and the diagonal gets ``W`` (``W / theta`` towards air, ``2 W`` towards an open side). The
    divergence counts the open part of a face with the fluid's velocity and the solid part with
    the solid's, ``W u + (1 - W) u_solid``: the condition u . n = u_solid . n on the cut faces
    (Batty, Bertails and Bridson 2007; Ng, Min and Gibou 2009). With faces 0 or 1 (staircase) this
    is the seed's stencil: a solid face drops out and enters ``b`` with the velocity it carries,
    the solid's. A non-solid face on a side of the domain is an open side."""
    nx, ny = phi.shape
    index = -np.ones((nx, ny), np.int64)
    n = 0
    for i in range(nx):
        for j in range(ny):
            if phi[i, j] < 0.0 and (u_frac[i, j] < 1.0 or u_frac[i + 1, j] < 1.0
                                    or v_frac[i, j] < 1.0 or v_frac[i, j + 1] < 1.0):
                index[i, j] = n
                n += 1
    diag = np.zeros(n)
    # each unknown's neighbour and face weight in the directions s = 0-3 (+i, -i, +j, -j),
    # returned as xp, xm, yp, ym and their weights
    nb = -np.ones((4, n), np.int64)
    wt = np.zeros((4, n))
    b = np.zeros(n)
    n_dir = 0
    for i in range(nx):
        for j in range(ny):
            k = index[i, j]
            if k < 0:
                continue
            pf = phi[i, j]
            d = 0.0
            for s in range(4):
                a = i + (1 if s == 0 else (-1 if s == 1 else 0))
                c = j + (1 if s == 2 else (-1 if s == 3 else 0))
                if s == 0:
                    frac = u_frac[i + 1, j]
                elif s == 1:
                    frac = u_frac[i, j]
                elif s == 2:
                    frac = v_frac[i, j + 1]
                else:
                    frac = v_frac[i, j]
                if frac >= 1.0:
                    continue  # solid face: Neumann, out of the stencil and the diagonal
                w = 1.0 - frac
                if a < 0 or a >= nx or c < 0 or c >= ny:
                    d += 2.0 * w  # open side: p = 0 on the boundary, half a cell away
                    n_dir += 1
                    continue
                m = index[a, c]
                if m >= 0:
                    d += w
                    nb[s, k] = m
                    wt[s, k] = w
                elif phi[a, c] >= 0.0:
                    d += w / _theta(pf, phi[a, c])
                    n_dir += 1
                # else: a fluid neighbour with every face solid is no unknown; the face between
                # is then closed on the neighbour's side too, nothing flows through it
            diag[k] = d
            f0 = u_frac[i, j]
            f1 = u_frac[i + 1, j]
            g0 = v_frac[i, j]
            g1 = v_frac[i, j + 1]
            b[k] = -(((1.0 - f1) * u[i + 1, j] + f1 * u_solid[i + 1, j])
                     - ((1.0 - f0) * u[i, j] + f0 * u_solid[i, j])
                     + ((1.0 - g1) * v[i, j + 1] + g1 * v_solid[i, j + 1])
                     - ((1.0 - g0) * v[i, j] + g0 * v_solid[i, j]))
    return index, diag, nb[1], nb[0], nb[3], nb[2], wt[1], wt[0], wt[3], wt[2], b, n_dir


@njit(cache=True)
def _dot(a, b):
    # a plain loop, not np.dot: numba's np.dot calls BLAS, whose worker threads spin and stall
    # when the 2 cores are shared with other runs (measured: 35 ms per CG iteration under load)
    s = 0.0
    for k in range(a.shape[0]):
        s += a[k] * b[k]
    return s


@njit(cache=True)
def _absmax(a):
    m = 0.0
    for k in range(a.shape[0]):
        x = abs(a[k])
        if x > m:
            m = x
    return m


@njit(cache=True)
def _matvec(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, x, out):
    for k in range(diag.shape[0]):
        s = diag[k] * x[k]
        if xm[k] >= 0:
            s -= wxm[k] * x[xm[k]]
        if xp[k] >= 0:
            s -= wxp[k] * x[xp[k]]
        if ym[k] >= 0:
            s -= wym[k] * x[ym[k]]
        if yp[k] >= 0:
            s -= wyp[k] * x[yp[k]]
        out[k] = s


@njit(cache=True)
def mic0(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, tau=0.97, sigma=0.25):
    """Modified incomplete Cholesky MIC(0) of the 5-point matrix with off-diagonal entries
    ``-w`` (Bridson, Fluid Simulation for Computer Graphics, 2nd ed., sec. 5.3.3): tau = 0.97
    blends towards the row-sum-preserving modification, sigma = 0.25 guards against tiny pivots.
    With unit weights the operations are those of the unweighted factor, bit for bit."""
    n = diag.shape[0]
    prec = np.empty(n)
    for k in range(n):
        e = diag[k]
        a = xm[k]
        if a >= 0:
            w = wxm[k]
            pa = prec[a] * prec[a]
            e -= w * w * pa
            if yp[a] >= 0:
                e -= tau * (w * wyp[a] * pa)
        c = ym[k]
        if c >= 0:
            w = wym[k]
            pc = prec[c] * prec[c]
            e -= w * w * pc
            if xp[c] >= 0:
                e -= tau * (w * wxp[c] * pc)
        if e < sigma * diag[k]:
            e = diag[k]
        prec[k] = 1.0 / np.sqrt(e)
    return prec


@njit(cache=True)
def _apply_mic(prec, xm, xp, ym, yp, wxm, wxp, wym, wyp, r, q, z):
    n = r.shape[0]
    for k in range(n):
        t = r[k]
        a = xm[k]
        if a >= 0:
            t += wxm[k] * prec[a] * q[a]
        c = ym[k]
        if c >= 0:
            t += wym[k] * prec[c] * q[c]
        q[k] = t * prec[k]
    for k in range(n - 1, -1, -1):
        t = q[k]
        a = xp[k]
        if a >= 0:
            t += wxp[k] * prec[k] * z[a]
        c = yp[k]
        if c >= 0:
            t += wyp[k] * prec[k] * z[c]
        z[k] = t * prec[k]


@njit(cache=True)
def pcg(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, x, tol, max_iter):
    """MIC(0)-preconditioned conjugate gradient, warm-started from ``x`` (overwritten). Stops when
    the largest residual is below ``tol``. Returns the iteration count (-1 if it did not
    converge)."""
    n = b.shape[0]
    if n == 0:
        return 0
    r = np.empty(n)
    _matvec(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, x, r)
    for k in range(n):
        r[k] = b[k] - r[k]
    if _absmax(r) <= tol:
        return 0
    prec = mic0(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp)
    q = np.empty(n)
    z = np.empty(n)
    _apply_mic(prec, xm, xp, ym, yp, wxm, wxp, wym, wyp, r, q, z)
    s = z.copy()
    sigma = _dot(r, z)
    As = np.empty(n)
    for it in range(max_iter):
        _matvec(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, s, As)
        alpha = sigma / _dot(s, As)
        for k in range(n):
            x[k] += alpha * s[k]
            r[k] -= alpha * As[k]
        if _absmax(r) <= tol:
            return it + 1
        _apply_mic(prec, xm, xp, ym, yp, wxm, wxp, wym, wyp, r, q, z)
        sigma_new = _dot(r, z)
        beta = sigma_new / sigma
        sigma = sigma_new
        for k in range(n):
            s[k] = z[k] + beta * s[k]
    return -1


@njit(cache=True)
def apply_pressure(pt, phi, u, v, ustate, vstate):
    """``u -= grad pt`` on fluid faces, with ghost-fluid pressures across the free surface and
    ``p = 0`` half a cell beyond an open side. ``pt`` is on the full grid (0 outside fluid)."""
    nx, ny = phi.shape
    for i in range(nx + 1):
        for j in range(ny):
            if ustate[i, j] != FLUID:
                continue
            if i == 0:
                u[i, j] -= pt[0, j] - (-pt[0, j])
                continue
            if i == nx:
                u[i, j] -= (-pt[nx - 1, j]) - pt[nx - 1, j]
                continue
            fl = phi[i - 1, j] < 0.0
            fr = phi[i, j] < 0.0
            pl = pt[i - 1, j]
            pr = pt[i, j]
            if not fl:
                pl = pr * (1.0 - 1.0 / _theta(phi[i, j], phi[i - 1, j]))
            if not fr:
                pr = pl * (1.0 - 1.0 / _theta(phi[i - 1, j], phi[i, j]))
            u[i, j] -= pr - pl
    for i in range(nx):
        for j in range(ny + 1):
            if vstate[i, j] != FLUID:
                continue
            if j == 0:
                v[i, j] -= pt[i, 0] - (-pt[i, 0])
                continue
            if j == ny:
                v[i, j] -= (-pt[i, ny - 1]) - pt[i, ny - 1]
                continue
            fb = phi[i, j - 1] < 0.0
            ft = phi[i, j] < 0.0
            pb = pt[i, j - 1]
            ptop = pt[i, j]
            if not fb:
                pb = ptop * (1.0 - 1.0 / _theta(phi[i, j], phi[i, j - 1]))
            if not ft:
                ptop = pb * (1.0 - 1.0 / _theta(phi[i, j - 1], phi[i, j]))
            v[i, j] -= ptop - pb


@njit(cache=True)
def scatter(index, x, out):
    nx, ny = index.shape
    for i in range(nx):
        for j in range(ny):
            k = index[i, j]
            out[i, j] = x[k] if k >= 0 else 0.0


@njit(cache=True)
def gather(index, grid, n):
    x = np.zeros(n)
    nx, ny = index.shape
    for i in range(nx):
        for j in range(ny):
            k = index[i, j]
            if k >= 0:
                x[k] = grid[i, j]
    return x


def project(phi, bnd, u, v, ustate, vstate, p_guess, tol, max_iter=2000, amg=None,
            amg_min=0):
    """Make ``u, v`` discretely divergence free in the fluid with the solid boundary ``bnd``
    (``boundary.SolidBoundary``), whose velocity the solid faces of ``u, v`` must already carry
    (``boundary.impose``). ``p_guess`` (scaled pressure on the grid) warm-starts the solve and
    receives the new scaled pressure. ``amg`` (``amg.StaticAMG``, kept by the caller across
    steps): solve with it when the system has at least ``amg_min`` unknowns, else MIC(0)-PCG.
    Returns (iterations, fluid cell count, largest |divergence| residual before the solve)."""
    (index, diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b,
     n_dir) = build_system(phi, bnd.u_frac, bnd.v_frac, u, v, bnd.u_solid, bnd.v_solid)
    n = diag.shape[0]
    if n == 0:
        p_guess[:] = 0.0
        return 0, 0, 0.0
    if n_dir == 0:
        # Enclosed fluid without free surface: the matrix is singular (pressure up to a
        # constant). Adding 1 to one diagonal entry pins that cell to p = 0; because the
        # right-hand side of an enclosed flow sums to zero (the solid faces around it carry no
        # net flux: walls at rest, or solids moving rigidly), the modified system's solution
        # satisfies the original equations exactly.
        diag[0] += 1.0
    x = gather(index, p_guess, n)
    bmax = float(np.max(np.abs(b)))
    stop = max(tol * bmax, 1e-13)
    if amg is not None and n >= amg_min:
        its = amg.solve(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, x, stop, max_iter)
    else:
        its = pcg(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, x, stop, max_iter)
    scatter(index, x, p_guess)
    apply_pressure(p_guess, phi, u, v, ustate, vstate)
    return its, n, bmax


# -- two-way coupling with a rigid body (coupling.py) ------------------------------------------
@njit(cache=True)
def _matvec_lowrank(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, jk, jv, dinv, x, out):
    """``(A + J D J^T) x``: the weighted Poisson matrix plus the body's rank-3 term (``jk`` the
    unknowns the body's rows touch, ``jv`` their rows of J, ``dinv`` D's diagonal)."""
    _matvec(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, x, out)
    y0 = 0.0
    y1 = 0.0
    y2 = 0.0
    for m in range(jk.shape[0]):
        xv = x[jk[m]]
        y0 += jv[m, 0] * xv
        y1 += jv[m, 1] * xv
        y2 += jv[m, 2] * xv
    y0 *= dinv[0]
    y1 *= dinv[1]
    y2 *= dinv[2]
    for m in range(jk.shape[0]):
        out[jk[m]] += jv[m, 0] * y0 + jv[m, 1] * y1 + jv[m, 2] * y2


@njit(cache=True)
def pcg_lowrank(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, jk, jv, dinv, b, x, tol, max_iter):
    """``pcg`` on ``A + J D J^T`` (symmetric positive (semi)definite), preconditioned by the
    MIC(0) factor of ``A`` alone: the body's term has rank 3, which costs CG at most three
    iterations more in exact arithmetic."""
    n = b.shape[0]
    if n == 0:
        return 0
    r = np.empty(n)
    _matvec_lowrank(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, jk, jv, dinv, x, r)
    for k in range(n):
        r[k] = b[k] - r[k]
    if _absmax(r) <= tol:
        return 0
    prec = mic0(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp)
    q = np.empty(n)
    z = np.empty(n)
    _apply_mic(prec, xm, xp, ym, yp, wxm, wxp, wym, wyp, r, q, z)
    s = z.copy()
    sigma = _dot(r, z)
    As = np.empty(n)
    for it in range(max_iter):
        _matvec_lowrank(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, jk, jv, dinv, s, As)
        alpha = sigma / _dot(s, As)
        for k in range(n):
            x[k] += alpha * s[k]
            r[k] -= alpha * As[k]
        if _absmax(r) <= tol:
            return it + 1
        _apply_mic(prec, xm, xp, ym, yp, wxm, wxp, wym, wyp, r, q, z)
        sigma_new = _dot(r, z)
        beta = sigma_new / sigma
        sigma = sigma_new
        for k in range(n):
            s[k] = z[k] + beta * s[k]
    return -1


@njit(cache=True)
def _body_response(jk, jv, dinv, x):
    """``D J^T x``: the change of the body's (vx, vy, omega) the pressure ``x`` makes."""
    out = np.zeros(3)
    for m in range(jk.shape[0]):
        xv = x[jk[m]]
        out[0] += jv[m, 0] * xv
        out[1] += jv[m, 1] * xv
        out[2] += jv[m, 2] * xv
    for c in range(3):
        out[c] *= dinv[c]
    return out


def unknown_cells(phi: np.ndarray, u_frac: np.ndarray, v_frac: np.ndarray) -> np.ndarray:
    """The cells ``build_system`` makes unknowns (bool (nx, ny)): fluid (``phi < 0``) with at
    least one face not entirely solid."""
    open_face = ((u_frac[:-1] < 1.0) | (u_frac[1:] < 1.0)
                 | (v_frac[:, :-1] < 1.0) | (v_frac[:, 1:] < 1.0))
    return (phi < 0.0) & open_face


def fill_new_cells(p: np.ndarray, now: np.ndarray, before: np.ndarray) -> np.ndarray:
    """The pressure with a value for each cell that is an unknown ``now`` and was not
    ``before`` (a cell a moving body uncovered, whose pressure the last solve wrote as 0): the
    mean of its neighbours that were unknowns, 0 with none. Applying the previous pressure's
    gradient (the incremental projection) across such a cell's faces would otherwise throw the
    whole previous pressure at them. Measured on the disc settling at Re ~ 14 (4 cells per
    diameter): without it the mean speed is 0.6-0.8 % lower (-4.4 / -4.8 % against the frame at
    the steps 2 / 0.5 ms, -3.8 / -4.0 % with it); before the cut faces were kept through the
    viscous step (viscosity.diffuse_implicit) the velocity jumped there."""
    new = now & ~before
    if not new.any():
        return p
    known = np.pad(np.where(before, p, 0.0), 1)
    count = np.pad(before.astype(float), 1)
    total = known[:-2, 1:-1] + known[2:, 1:-1] + known[1:-1, :-2] + known[1:-1, 2:]
    n = count[:-2, 1:-1] + count[2:, 1:-1] + count[1:-1, :-2] + count[1:-1, 2:]
    out = p.copy()
    out[new] = np.where(n[new] > 0.0, total[new] / np.maximum(n[new], 1.0), 0.0)
    return out


def apply_pressure_coupled(pt, phi, u, v, ustate, vstate, coupling, unknown) -> None:
    """The scaled pressure ``pt``'s gradient on the fluid's faces and its force on the coupled
    body (``D J^T pt``, the same discrete force as the coupled solve's), both on the step's
    geometry (``unknown``: its ``unknown_cells``): the incremental projection's start with a
    coupled body."""
    index = -np.ones(unknown.shape, np.int64)
    n = int(np.count_nonzero(unknown))
    index[unknown] = np.arange(n)
    jk, jv, dinv = coupling.rows(index)
    apply_pressure(pt, phi, u, v, ustate, vstate)
    coupling.apply_impulse(_body_response(jk, jv, dinv, gather(index, pt, n)))


def project_coupled(phi, bnd, u, v, ustate, vstate, p_guess, tol, coupling, max_iter=2000,
                    amg=None, amg_min=0):
    """``project`` with the coupled body's velocity as unknowns (Batty, Bertails and Bridson
    2007; coupling.py): the solid faces and samples of the body carry its predicted velocity
    ``V*`` (so the right-hand side is ``-div*``), the matrix gains ``J D J^T``, and after the
    solve the body's velocity gains ``D J^T pt`` (``coupling.apply_impulse``). ``amg``
    (``amg.CoupledAMG``, kept by the caller; a flow with no free surface): solve with it when
    the system has at least ``amg_min`` unknowns, else MIC(0)-PCG. Returns (iterations, fluid
    cell count, largest |divergence| residual before the solve)."""
    (index, diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b,
     n_dir) = build_system(phi, bnd.u_frac, bnd.v_frac, u, v, bnd.u_solid, bnd.v_solid)
    n = diag.shape[0]
    if n == 0:
        p_guess[:] = 0.0
        return 0, 0, 0.0
    if n_dir == 0:
        # enclosed: as in project (the body's term keeps the constant in the null space: the
        # body's flux through a closed surface sums to zero, J^T 1 = 0)
        diag[0] += 1.0
    jk, jv, dinv = coupling.rows(index)
    # the hydrostatic part of the body's force, exactly (coupling.hydrostatic): a known change
    # of V*, so the divergence the solve removes changes by J dv
    dv = coupling.hydrostatic(phi, jv, dinv)
    coupling.apply_impulse(dv)
    b[jk] -= jv @ dv
    x = gather(index, p_guess, n)
    bmax = float(np.max(np.abs(b)))
    stop = max(tol * bmax, 1e-13)
    if amg is not None and n >= amg_min:
        g = coupling.geometry
        its = amg.solve(phi, coupling.static, index, (g.i0, g.i1, g.j0, g.j1),
                        (diag, xm, xp, ym, yp, wxm, wxp, wym, wyp), jk, jv, dinv, b, x, stop,
                        max_iter)
    else:
        its = pcg_lowrank(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, jk, jv, dinv, b, x, stop,
                          max_iter)
    scatter(index, x, p_guess)
    apply_pressure(p_guess, phi, u, v, ustate, vstate)
    coupling.apply_impulse(_body_response(jk, jv, dinv, x))
    return its, n, bmax
