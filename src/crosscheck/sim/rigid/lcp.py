"""A direct solver for small linear complementarity problems (numba): find ``lam >= 0`` with
``w = A lam + q >= 0`` and ``lam . w = 0``, for a symmetric positive semi-definite ``A`` (the
normal rows of a contact problem, J M^-1 J^T).

Murty's least-index principal pivoting (a P-matrix LCP ends after finitely many pivots with its
unique solution); each principal block is factored as it is, or, when its Cholesky meets a pivot
below ``PIVOT`` times its diagonal entry (redundant contacts, four corners of a face, make ``A``
singular), as ``A + eps I`` with ``eps`` = ``REGULARISATION`` times the largest diagonal entry,
positive definite: guess the set S of positive ``lam`` (the warm start's), solve
``(A + eps I)_SS lam_S = -q_S`` by Cholesky, and flip the first index that is infeasible (a
negative ``lam`` in S, or a negative ``w`` outside it) until none is. Exact up to round-off and the
regularisation, whatever the conditioning (a 1000:1 mass ratio), where projected Gauss-Seidel
needs thousands of sweeps.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT

REGULARISATION = 1e-10
PIVOT = 1e-9  # a Cholesky pivot below this fraction of its diagonal entry: singular (redundant)


class Dense(NamedTuple):
    """Scratch for problems of up to D rows."""

    A: np.ndarray  # (D, D)
    q: np.ndarray  # (D,)
    lam: np.ndarray  # (D,)
    active: np.ndarray  # (D,) bool
    chol: np.ndarray  # (D, D)
    index: np.ndarray  # (D,) int64
    y: np.ndarray  # (D,)

    @classmethod
    def empty(cls, size: int) -> Dense:
        d = max(int(size), 1)
        return cls(np.zeros((d, d)), np.zeros(d), np.zeros(d), np.zeros(d, np.bool_),
                   np.zeros((d, d)), np.zeros(d, np.int64), np.zeros(d))

    @property
    def size(self) -> int:
        return self.q.shape[0]


@njit(**INLINE)
def _solve_active(dn, m, eps):
    """lam_S = -(A + eps I)_SS^-1 q_S (Cholesky), lam elsewhere 0; False if not positive."""
    A, q, lam, L, idx, y = dn.A, dn.q, dn.lam, dn.chol, dn.index, dn.y
    s = 0
    for i in range(m):
        lam[i] = 0.0
        if dn.active[i]:
            idx[s] = i
            s += 1
    for a in range(s):
        ia = idx[a]
        for b in range(a + 1):
            ib = idx[b]
            v = A[ia, ib] + (eps if a == b else 0.0)
            for k in range(b):
                v -= L[a, k] * L[b, k]
            if a == b:
                if v <= PIVOT * A[ia, ia] or v <= 0.0:
                    return False
                L[a, a] = np.sqrt(v)
            else:
                L[a, b] = v / L[b, b]
    for a in range(s):  # L y = -q_S
        v = -q[idx[a]]
        for k in range(a):
            v -= L[a, k] * y[k]
        y[a] = v / L[a, a]
    for a in range(s - 1, -1, -1):  # L^T x = y
        v = y[a]
        for k in range(a + 1, s):
            v -= L[k, a] * y[k]
        y[a] = v / L[a, a]
        lam[idx[a]] = y[a]
    return True


@njit(**JIT)
def lcp_solve(dn, m, max_pivots):
    """Solve the LCP of dn.A[:m, :m], dn.q[:m] into dn.lam[:m], starting from the set
    dn.active[:m]. Returns the pivots taken (-1: no solution within max_pivots)."""
    A, q, lam = dn.A, dn.q, dn.lam
    big = 0.0
    scale = 0.0
    for i in range(m):
        big = max(big, A[i, i])
        scale = max(scale, abs(q[i]))
    eps_reg = REGULARISATION * big if big > 0.0 else REGULARISATION
    tol = 1e-13 * scale
    for pivots in range(max_pivots):
        # unregularised first (exact for independent contacts: a lone impact to round-off); a
        # singular block (redundant contacts) is solved regularised
        if not _solve_active(dn, m, 0.0):
            if not _solve_active(dn, m, eps_reg):
                return -1
        flip = -1
        for i in range(m):
            if dn.active[i]:
                if lam[i] < 0.0:
                    flip = i
                    break
            else:
                w = q[i]
                for j in range(m):
                    if dn.active[j]:
                        w += A[i, j] * lam[j]
                if w < -tol:
                    flip = i
                    break
        if flip < 0:
            return pivots
        dn.active[flip] = not dn.active[flip]
    return -1
