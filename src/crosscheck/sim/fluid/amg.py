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
