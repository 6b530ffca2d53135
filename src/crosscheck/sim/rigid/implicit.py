"""Implicit (backward) Euler, linearised: one Newton step on the coupled system per time step.

Unknowns are the generalised velocities u = (v_i, w_i) of every body (6 per body in 3D, 3 in 2D).
Backward Euler asks for M (u1 - u0) = h f(X1, u1) with X1 = X0 + h u1 (X: centre of mass and a
small world rotation vector). Linearising f about the start of the step,

    f(X1, u1) ~ f0 + K h u1 + D (u1 - u0),    K = df/dX,  D = df/du,

gives one sparse linear system per step,

    (M - h D - h^2 K) du = h (f0 + h K u0),    u1 = u0 + du,

with M = blockdiag(m_i 1, I_i(q_n)) and K, D the spring Jacobians (12 x 12 per body-body spring,
6 x 6 per anchored spring, analytic: axial stiffness, the geometric stiffness of a stretched
spring, the torque arms and the damping along the axis) plus the drag terms. For linear springs
(rest length 0, attachments at the centres of mass) this *is* backward Euler; otherwise it is the
linearly implicit (Rosenbrock-Euler) form, first order, and stable for stiff springs at any step
(k h^2 / m = 100 in the tests) where every explicit scheme blows up.

Momenta follow exactly from the solve: P1 = P0 + m dv, L1 = L0 + I(q_n) dw (so a torque-free
body keeps L to round-off); then x1 = x0 + h P1 / m and the orientation is backward Euler too:
q1 = exp(phi) q0 with phi = h w(q1, L1), the angular velocity at the *end* of the step, solved by
Newton per body (:func:`backward_rotation`). Backward Euler dissipates the free rotor's
perturbations instead of amplifying them (explicit rotation updates grow round-off off a
principal axis by exp(n (h |w|)^2 / 2)); it is first order.

Scenes without springs have a block-diagonal system solved body by body inside one compiled
loop; scenes with springs assemble the sparse matrix in a compiled kernel and solve it with
SciPy once per step (a Python loop over *steps*, never over bodies).

The compiled pieces live in kernels3d.py and kernels2d.py (each kernel file is self-contained,
so numba's per-file cache can never pair a kernel with a stale copy of a helper from another
file); this module holds the drivers.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse
import scipy.sparse.linalg

from crosscheck.sim.rigid import kernels2d as k2
from crosscheck.sim.rigid import kernels3d as k3

DENSE_LIMIT = 96  # unknowns up to which a dense LAPACK solve beats SciPy's sparse overhead


# -- Python drivers (the registry's entry points) --------------------------------------------------
def _solve(rows, cols, vals, rhs, nnz):
    n = rhs.shape[0]
    with warnings.catch_warnings():
        # A singular system is a blow-up: the NaNs it produces are reported by the driver.
        warnings.simplefilter("ignore")
        if n <= DENSE_LIMIT:
            A = np.zeros((n, n))
            np.add.at(A, (rows[:nnz], cols[:nnz]), vals[:nnz])
            try:
                return np.linalg.solve(A, rhs)
            except np.linalg.LinAlgError:
                return np.full(n, np.nan)
        A = scipy.sparse.csc_matrix((vals[:nnz], (rows[:nnz], cols[:nnz])), shape=(n, n))
        return scipy.sparse.linalg.spsolve(A, rhs)


def _coupled_steps(n_steps, n_unknowns, nnz_max, assemble, assemble_args, finish, finish_args):
    """Steps with springs: assemble the sparse system into triplet buffers reused every step
    (``assemble(*assemble_args, rows, cols, vals, rhs) -> nnz``), solve it, and apply the velocity
    increment (``finish(*finish_args, du)``)."""
    coo = (np.empty(nnz_max, dtype=np.int64), np.empty(nnz_max, dtype=np.int64),
           np.empty(nnz_max), np.empty(n_unknowns))
    assemble_args = (*assemble_args, *coo)
    for _ in range(n_steps):
        nnz = assemble(*assemble_args)
        finish(*finish_args, _solve(*coo, nnz))


def advance_implicit_3d(model, state, control, contacts, n_steps: int, h: float) -> None:
    args = (*model.kernel_args(), control, contacts, *state.arrays())
    if model.springs is None:
        k3.advance_local_3d(*args, n_steps, h)
        return
    x, q, P, L = state.arrays()
    n = x.shape[0]
    R, v, w, F, T, Iw = (np.empty((n, *s)) for s in ((3, 3), (3,), (3,), (3,), (3,), (3, 3)))
    # entries: per body 3 (mass) + 9 (world inertia), per spring one 12 x 12 block
    _coupled_steps(n_steps, 6 * n, 12 * n + 144 * len(model.springs.a),
                   k3.assemble_3d, (*args, h, R, v, w, F, T, Iw),
                   k3.finish_3d, (model.bodies, x, q, P, L, Iw, np.empty((5, 3, 3)), h))


def advance_implicit_2d(model, state, control, contacts, n_steps: int, h: float) -> None:
    args = (*model.kernel_args(), control, contacts, *state.arrays())
    if model.springs is None:
        k2.advance_local_2d(*args, n_steps, h)
        return
    x, angle, P, L = state.arrays()
    n = x.shape[0]
    v, w, F, T = np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n)
    # entries: per body 2 (mass) + 1 (moment), per spring one 6 x 6 block
    _coupled_steps(n_steps, 3 * n, 3 * n + 36 * len(model.springs.a),
                   k2.assemble_2d, (*args, h, v, w, F, T),
                   k2.finish_2d, (model.bodies, x, angle, P, L, w, h))
