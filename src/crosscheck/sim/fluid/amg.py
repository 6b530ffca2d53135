"""Algebraic multigrid for a pressure matrix that stays the same from step to step.

MIC(0)-PCG (``pressure.pcg``) needs more iterations the finer the grid (71, 134, 194 and 257
from zero on the DFG channel at 10, 20, 30 and 40 cells across the cylinder: 9, 36, 81 and 143
thousand unknowns); a multigrid preconditioner does not (7 or 8 at each). Its set-up costs about
two of its solves (the first solve at 143 thousand unknowns, set-up included, 556 ms against 200
ms), where MIC(0) needs none and, warm-started in a flow whose matrix changes every step, few
iterations (45 in the dam break at 256^2); so it is used where the matrix is built once and
reused: a flow with no free surface and no moving body (a channel past fixed obstacles, a
cavity), whose matrix depends only on the static solid. ``StaticAMG`` keeps the last matrix and
its hierarchy, and rebuilds both when the matrix changes (which, in a flow it is used for,
happens only when the caller hands it another one: it is never wrong, only slower).
``CoupledAMG`` extends it to a coupled body in such a flow, whose matrix changes every step:
the static domain's hierarchy (the body's cells as fluid) with an exact solve of the body's
window.

The hierarchy is PyAMG's classical (Ruge-Stuben) one, a V-cycle with symmetric Gauss-Seidel, so
the preconditioner is symmetric and CG applies. The CG loop is here, not SciPy's, because it
stops on the same criterion as ``pressure.pcg`` (the largest residual below ``tol``), so both
solvers leave the same divergence behind. Measured (``benchmarks/bench_pressure.py``,
results/pressure.md): per step of the DFG 2D-2 run, the projection takes 12 / 11, 91 / 45, 313 /
93 and 858 / 161 ms (MIC(0) / multigrid) at 9, 36, 81 and 143 thousand unknowns.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from crosscheck.sim.fluid.pressure import _absmax, _dot

#: below this many unknowns MIC(0)-PCG is as fast (measured break-even about 10 thousand)
AMG_MIN_UNKNOWNS = 20000


def assemble(diag, xm, xp, ym, yp, wxm, wxp, wym, wyp) -> sp.csr_matrix:
    """The compressed five-point system of ``pressure.build_system`` as a CSR matrix."""
    n = diag.shape[0]
    rows = [np.arange(n)]
    cols = [np.arange(n)]
    vals = [diag]
    for nb, w in ((xm, wxm), (xp, wxp), (ym, wym), (yp, wyp)):
        has = nb >= 0
        rows.append(np.nonzero(has)[0])
        cols.append(nb[has])
        vals.append(-w[has])
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                         shape=(n, n))


class StaticAMG:
    """Multigrid-preconditioned CG with the hierarchy kept while the matrix does not change."""

    def __init__(self) -> None:
        self._key: tuple[np.ndarray, ...] | None = None
        self._matrix: sp.csr_matrix | None = None
        self._levels: list = []
        self._coarse: np.ndarray | None = None
        self.setups = 0           # how many hierarchies were built (1 in a static flow)

    def _prepare(self, arrays: tuple[np.ndarray, ...]) -> None:
        if self._key is not None and all(a.shape == k.shape and np.array_equal(a, k)
                                         for a, k in zip(arrays, self._key, strict=True)):
            return
        import pyamg  # only flows that use it pay for the import

        self._matrix = assemble(*arrays)
        hierarchy = pyamg.ruge_stuben_solver(self._matrix)
        self._levels = hierarchy.levels
        # the coarsest level (a few unknowns) solved by its pseudo-inverse, as PyAMG's default
        self._coarse = np.linalg.pinv(self._levels[-1].A.toarray())
        self._key = tuple(a.copy() for a in arrays)
        self.setups += 1

    def _vcycle(self, b: np.ndarray, lvl: int = 0) -> np.ndarray:
        """One V-cycle from zero on ``b``: the hierarchy's own smoothers (symmetric Gauss-Seidel)
        and transfers. Written out rather than PyAMG's ``solve``, which also takes the norms of
        the residual, BLAS calls that start threads on the full-length vectors and leave them
        spinning (the run then held both cores for no gain: same time with one BLAS thread)."""
        levels = self._levels
        if lvl == len(levels) - 1:
            return self._coarse @ b
        level = levels[lvl]
        a = level.A
        x = np.zeros_like(b)
        level.presmoother(a, x, b)
        x += level.P @ self._vcycle(level.R @ (b - a @ x), lvl + 1)
        level.postsmoother(a, x, b)
        return x

    def solve(self, diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, x, tol, max_iter) -> int:
        """As ``pressure.pcg``: ``x`` (the warm start) is overwritten with the solution; the
        iteration count, -1 if ``max_iter`` did not bring the largest residual below ``tol``."""
        self._prepare((diag, xm, xp, ym, yp, wxm, wxp, wym, wyp))
        a = self._matrix
        # dot products compiled, not NumPy's: a BLAS dot of this length starts threads that
        # then spin, and took the second core from every other process on the machine
        r = b - a @ x
        if _absmax(r) <= tol:
            return 0
        z = self._vcycle(r)
        s = z.copy()
        sigma = _dot(r, z)
        for it in range(max_iter):
            As = a @ s
            alpha = sigma / _dot(s, As)
            x += alpha * s
            r -= alpha * As
            if _absmax(r) <= tol:
                return it + 1
            z = self._vcycle(r)
            sigma_new = _dot(r, z)
            s = z + (sigma_new / sigma) * s
            sigma = sigma_new
        return -1


class CoupledAMG:
    """Multigrid for the coupled body's pressure solve (``pressure.project_coupled``) in a flow
    with no free surface: the matrix changes every step with the body's cut cells and gains the
    body's rank-3 term ``J D J^T``, so no hierarchy of its own lasts; MIC(0)-PCG needs 113
    iterations at 256^2 where the same domain with the body as a fixed obstacle needs 4 with
    ``StaticAMG`` (benchmarks/results/coupling_submerged.md).

    The preconditioner is a symmetric multiplicative Schwarz of two parts:

    * ``L``: an exact solve of the body's window (its cells and ``WINDOW_MARGIN`` more on each
      side, a few hundred to a few thousand unknowns), the rank-3 term included by
      Sherman-Morrison-Woodbury, so that ``I - L A`` is an A-orthogonal projection: the
      operator's difference from the static domain's lives in the window;
    * ``B``: the V-cycle of the static domain's matrix (the body's cells as fluid, built once,
      ``StaticAMG``) restricted to the coupled unknowns by zero extension.

    ``z = L r; z += B (r - A z); z += L (r - A z)``: symmetric, as CG needs. Measured on the
    submerged disc (0.2 s): 4 iterations at 128^2 and 256^2 (MIC(0) 73 and 124); ``B`` alone
    took 25, ``B + L`` added 9.4. ``B`` is a V-cycle of a nearby matrix, not of the operator, so
    positive definiteness is not guaranteed: a non-positive ``r . z`` or no convergence within
    ``SCHWARZ_MAX_ITER`` hands the solve, from where it stands, to MIC(0) (``fallbacks``)."""

    WINDOW_MARGIN = 2
    SCHWARZ_MAX_ITER = 50

    def __init__(self) -> None:
        self.static = StaticAMG()
        self._phi: np.ndarray | None = None
        self._system: tuple | None = None
        self.fallbacks = 0        # solves handed to MIC(0) (reported in the run's meta)

    @property
    def setups(self) -> int:
        """Hierarchies built (of the static domain: 1 in a flow with no free surface)."""
        return self.static.setups

    def _static_system(self, phi, static) -> tuple:
        """The static domain's compressed system (the body's cells as fluid) and its
        hierarchy, built when ``phi`` changes (never, in a flow with no free surface; checking
        the system's nine arrays every step instead took 0.22 ms of a 68 ms step at 256^2)."""
        if self._phi is None or not np.array_equal(phi, self._phi):
            from crosscheck.sim.fluid.pressure import build_system

            zu, zv = np.zeros(static.u_frac.shape), np.zeros(static.v_frac.shape)
            out = build_system(phi, static.u_frac, static.v_frac, zu, zv, zu, zv)
            diag = out[1].copy()
            if out[-1] == 0:
                diag[0] += 1.0          # enclosed: as the coupled system pins its null space
            self._system = (out[0], (diag, *out[2:10]))
            self.static._prepare(self._system[1])
            self._phi = phi.copy()
        return self._system

    def solve(self, phi, static, index, window, system, jk, jv, dinv, b, x, tol,
              max_iter) -> int:
        """As ``pressure.pcg_lowrank`` on ``system`` = ``(diag, xm, xp, ym, yp, wxm, wxp, wym,
        wyp)`` plus ``J D J^T``: ``x`` (the warm start) is overwritten with the solution;
        ``window`` = ``(i0, i1, j0, j1)``, the body's cells."""
        from scipy.sparse.linalg import splu

        from crosscheck.sim.fluid.pressure import _matvec_lowrank, pcg_lowrank

        n = b.shape[0]
        sindex, ssys = self._static_system(phi, static)
        ns = ssys[0].shape[0]
        # coupled unknown -> static unknown (every coupled unknown is one of the static domain)
        cells = index >= 0
        to_static = np.empty(n, dtype=np.int64)
        to_static[index[cells]] = sindex[cells]
        # the window's unknowns and its block of A, exactly
        i0, i1, j0, j1 = window
        mg = self.WINDOW_MARGIN
        sub = index[max(i0 - mg, 0):i1 + mg, max(j0 - mg, 0):j1 + mg]
        loc = np.sort(sub[sub >= 0])
        pos = np.full(n, -1, dtype=np.int64)
        pos[loc] = np.arange(loc.size)
        diag = system[0]
        rows, cols, vals = [np.arange(loc.size)], [np.arange(loc.size)], [diag[loc]]
        for nb, w in zip(system[1:5], system[5:9], strict=True):
            k = nb[loc]
            inside = k >= 0
            inside[inside] = pos[k[inside]] >= 0
            rows.append(np.nonzero(inside)[0])
            cols.append(pos[k[inside]])
            vals.append(-w[loc][inside])
        block = sp.csc_matrix((np.concatenate(vals), (np.concatenate(rows),
                                                      np.concatenate(cols))),
                              shape=(loc.size, loc.size))
        lu = splu(block)
        # the body's rows inside the block (all of them: J lives in the body's cells)
        jl = pos[jk]
        if np.any(jl < 0):
            self.fallbacks += 1
            return pcg_lowrank(*system, jk, jv, dinv, b, x, tol, max_iter)
        jmat = np.zeros((loc.size, 3))
        np.add.at(jmat, jl, jv)
        w_ = lu.solve(jmat)                                    # A_ww^-1 J
        cap = np.diag(1.0 / dinv) + jmat.T @ w_                # D^-1 + J^T A_ww^-1 J

        def local(r: np.ndarray) -> np.ndarray:
            u = lu.solve(r[loc])
            z = np.zeros(n)
            z[loc] = u - w_ @ np.linalg.solve(cap, jmat.T @ u)
            return z

        def vcycle(r: np.ndarray) -> np.ndarray:
            y = np.zeros(ns)
            y[to_static] = r
            return self.static._vcycle(y)[to_static]

        ax = np.empty(n)

        def apply_a(v: np.ndarray) -> np.ndarray:
            _matvec_lowrank(*system, jk, jv, dinv, v, ax)
            return ax

        def precondition(r: np.ndarray) -> np.ndarray:
            z = local(r)
            z += vcycle(r - apply_a(z))
            z += local(r - apply_a(z))
            return z

        r = b - apply_a(x)
        if _absmax(r) <= tol:
            return 0
        z = precondition(r)
        s = z.copy()
        sigma = _dot(r, z)
        done = 0
        while done < min(max_iter, self.SCHWARZ_MAX_ITER) and sigma > 0.0:
            a_s = apply_a(s).copy()
            alpha = sigma / _dot(s, a_s)
            x += alpha * s
            r -= alpha * a_s
            done += 1
            if _absmax(r) <= tol:
                return done
            z = precondition(r)
            sigma_new = _dot(r, z)
            s = z + (sigma_new / sigma) * s
            sigma = sigma_new
        # not converging as it should: MIC(0) from where the solve stands
        self.fallbacks += 1
        its = pcg_lowrank(*system, jk, jv, dinv, b, x, tol, max_iter)
        return -1 if its < 0 else done + its
