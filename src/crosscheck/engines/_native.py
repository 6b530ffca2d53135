"""Compiled (numba) stepping loops that call an engine's own C functions, for the adapters.

Why: between two samples an adapter steps k times and then copies the state. Done from Python,
each engine call costs a fixed ~0.1-1 us of interpreter and binding overhead on top of the C
work, which for a one-body scene is as much as (Chipmunk, ~0.1 us per step) or a large fraction
of (MuJoCo, ~1.5 us per Euler step) the step itself: recording at every tenth step then adds
15-35 % (benchmarks/results/overhead.md). Here the loop over steps and samples runs compiled:
the engine's C functions are called through their addresses with exactly the arguments the
Python bindings pass, so every step is the same computation and the results are bit-identical
to the bindings' (the adapters check this on every build and fall back to Python otherwise).

Only plain C calling conventions are used: pointers and doubles in, ``void`` / ``double`` /
Chipmunk's two-double ``cpVect`` out. A ``cpVect`` argument or result is declared the way clang
lowers ``struct {double x, y;}`` for the x86-64 System V ABI (two doubles in, ``{double, double}``
out); the adapters enable the Chipmunk loop only there (``CHIPMUNK_ABI_OK``). ``mj_step`` takes
two pointers and returns nothing, which is the same on every platform.

Every function is compiled on first use and cached on disk (``cache=True``); ``nogil`` because
nothing here touches Python objects.
"""

from __future__ import annotations

import platform
import sys

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

# cpVect by value is {double, double} in two SSE registers only under the System V x86-64 ABI
# (Windows passes and returns 16-byte structs through memory).
CHIPMUNK_ABI_OK = platform.machine().lower() in ("x86_64", "amd64") and sys.platform != "win32"

_f64 = ir.DoubleType()
_vec2 = ir.LiteralStructType([_f64, _f64])
_ptr = ir.IntType(8).as_pointer()


def _ints(*args) -> bool:
    return all(isinstance(a, types.Integer) for a in args)


def _pair(context, builder, sig, value):
    return context.make_tuple(builder, sig.return_type,
                              [builder.extract_value(value, 0), builder.extract_value(value, 1)])


@intrinsic
def call_v_pp(typingctx, fn, a, b):
    """``void fn(void *a, void *b)``, e.g. ``mj_step(m, d)``."""
    if not _ints(fn, a, b):
        return None

    def codegen(context, builder, sig, args):
        fnty = ir.FunctionType(ir.VoidType(), [_ptr, _ptr])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(args[1], _ptr), builder.inttoptr(args[2], _ptr)])
        return context.get_dummy_value()

    return types.void(fn, a, b), codegen


@intrinsic
def call_v_pd(typingctx, fn, a, x):
    """``void fn(void *a, double x)``, e.g. ``cpSpaceStep(space, dt)``."""
    if not (_ints(fn, a) and isinstance(x, types.Float)):
        return None

    def codegen(context, builder, sig, args):
        fnty = ir.FunctionType(ir.VoidType(), [_ptr, _f64])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(f, [builder.inttoptr(args[1], _ptr), args[2]])
        return context.get_dummy_value()

    return types.void(fn, a, x), codegen


@intrinsic
def call_d_p(typingctx, fn, a):
    """``double fn(void *a)``, e.g. ``cpBodyGetAngle(body)``."""
    if not _ints(fn, a):
        return None

    def codegen(context, builder, sig, args):
        fnty = ir.FunctionType(_f64, [_ptr])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        return builder.call(f, [builder.inttoptr(args[1], _ptr)])

    return types.float64(fn, a), codegen


@intrinsic
def call_v2_p(typingctx, fn, a):
    """``cpVect fn(void *a)``, e.g. ``cpBodyGetVelocity(body)`` (System V x86-64 only)."""
    if not _ints(fn, a):
        return None
    sig = types.UniTuple(types.float64, 2)(fn, a)

    def codegen(context, builder, sig, args):
        fnty = ir.FunctionType(_vec2, [_ptr])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        return _pair(context, builder, sig, builder.call(f, [builder.inttoptr(args[1], _ptr)]))

    return sig, codegen


@intrinsic
def call_v2_pv2(typingctx, fn, a, x, y):
    """``cpVect fn(void *a, cpVect p)``, e.g. ``cpBodyLocalToWorld(body, point)`` (System V)."""
    if not (_ints(fn, a) and isinstance(x, types.Float) and isinstance(y, types.Float)):
        return None
    sig = types.UniTuple(types.float64, 2)(fn, a, x, y)

    def codegen(context, builder, sig, args):
        fnty = ir.FunctionType(_vec2, [_ptr, _f64, _f64])
        f = builder.inttoptr(args[0], fnty.as_pointer())
        value = builder.call(f, [builder.inttoptr(args[1], _ptr), args[2], args[3]])
        return _pair(context, builder, sig, value)

    return sig, codegen


# -- Chipmunk (Pymunk) ---------------------------------------------------------------------------
# fns = (cpSpaceStep, cpBodyLocalToWorld, cpBodyGetVelocity, cpBodyGetAngle,
#        cpBodyGetAngularVelocity) addresses.

@njit(cache=True, nogil=True)
def chipmunk_step(step, space, dt, nsteps):
    """``nsteps`` times ``cpSpaceStep(space, dt)``: the bare stepping loop."""
    for _ in range(nsteps):
        call_v_pd(step, space, dt)


@njit(cache=True, nogil=True)
def chipmunk_read(fns, bodies, cogs, com, angle, vel, omega, i):
    """Sample i of every body j: com[i, j] (centre of mass), angle[i, j], vel[i, j] (centre of
    mass velocity), omega[i, j]: the getters ``PymunkModel.read_raw`` calls, in its order."""
    _, to_world, velocity, get_angle, spin = fns
    for j in range(bodies.shape[0]):
        b = bodies[j]
        cx, cy = call_v2_pv2(to_world, b, cogs[j, 0], cogs[j, 1])
        vx, vy = call_v2_p(velocity, b)
        com[i, j, 0] = cx
        com[i, j, 1] = cy
        angle[i, j] = call_d_p(get_angle, b)
        vel[i, j, 0] = vx
        vel[i, j, 1] = vy
        omega[i, j] = call_d_p(spin, b)


@njit(cache=True, nogil=True)
def chipmunk_record(fns, space, dt, k, bodies, cogs, com, angle, vel, omega):
    """Sample 0 is read; then k steps and a read per sample, straight into the Trajectory's
    arrays. Returns the number of samples before the first one holding a non-finite value."""
    step = fns[0]
    # np.int64: a literal 0 would compile chipmunk_read a second time (sim/_jit.py, "Literal
    # arguments")
    chipmunk_read(fns, bodies, cogs, com, angle, vel, omega, np.int64(0))
    for i in range(1, com.shape[0]):
        for _ in range(k):
            call_v_pd(step, space, dt)
        chipmunk_read(fns, bodies, cogs, com, angle, vel, omega, i)
        for j in range(bodies.shape[0]):
            if not (np.isfinite(com[i, j, 0]) and np.isfinite(com[i, j, 1])
                    and np.isfinite(angle[i, j]) and np.isfinite(vel[i, j, 0])
                    and np.isfinite(vel[i, j, 1]) and np.isfinite(omega[i, j])):
                return i
    return com.shape[0]


# -- MuJoCo -------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def mujoco_record(step, m, d, qpos, qvel, warnings, k, out_q, out_v):
    """From sample 1 on: k ``mj_step(m, d)`` calls, then copy ``qpos``/``qvel`` (views of d).

    Returns the index of the first sample after whose steps one of MuJoCo's warning counters
    (``d.warning.number``, zero at the start) is non-zero, or ``len(out_q)``: the samples before
    it are valid, as with ``mujoco.rollout``, which stops at the first warning.
    """
    for i in range(1, out_q.shape[0]):
        for _ in range(k):
            call_v_pp(step, m, d)
        out_q[i] = qpos
        out_v[i] = qvel
        for w in range(warnings.shape[0]):
            if warnings[w] != 0:
                return i
    return out_q.shape[0]
