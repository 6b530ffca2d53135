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

import math
import platform
import sys
from collections import namedtuple

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
    chipmunk_read(fns, bodies, cogs, com, angle, vel, omega, 0)
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


# -- Bullet (PyBullet's C API) ------------------------------------------------------------------
# Bullet's client API (PhysicsClientC_API.h) passes opaque handles (pointers), ints, doubles and
# pointers to caller-owned buffers, and returns handles, ints or nothing: one generic caller
# covers it. ``params`` spells the C parameter types, one letter each: "p" pointer (passed as an
# integer address), "i" int, "d" double; ``ret`` is "p", "i" or "v" (void).
_C_TYPES = {"p": _ptr, "i": ir.IntType(32), "d": _f64, "v": ir.VoidType()}
_NB_RETURN = {"p": types.intp, "i": types.int32, "v": types.void}
_NB_PARAM = {"p": types.Integer, "i": types.Integer, "d": types.Float}


def _c_argument(builder, kind: str, value):
    if kind == "p":
        return builder.inttoptr(value, _ptr)
    if kind == "d":
        return value
    width = value.type.width
    return (builder.trunc(value, _C_TYPES["i"]) if width > 32
            else builder.sext(value, _C_TYPES["i"]) if width < 32 else value)


def _c_caller(ret: str, params: str):
    """An intrinsic ``call(fn, (a, b, ...))`` calling the C function at address ``fn``."""

    @intrinsic
    def call(typingctx, fn, args):
        if not (isinstance(fn, types.Integer) and isinstance(args, types.BaseTuple)
                and len(args) == len(params)
                and all(isinstance(a, _NB_PARAM[c]) for a, c in zip(args, params, strict=True))):
            return None

        def codegen(context, builder, sig, llargs):
            fnty = ir.FunctionType(_C_TYPES[ret], [_C_TYPES[c] for c in params])
            f = builder.inttoptr(llargs[0], fnty.as_pointer())
            values = [_c_argument(builder, c, builder.extract_value(llargs[1], j))
                      for j, c in enumerate(params)]
            out = builder.call(f, values)
            if ret == "p":
                return builder.ptrtoint(out, context.get_value_type(types.intp))
            return context.get_dummy_value() if ret == "v" else out

        return _NB_RETURN[ret](fn, args), codegen

    return call


call_p_p = _c_caller("p", "p")           # b3InitStepSimulationCommand(client)
call_p_pp = _c_caller("p", "pp")         # b3SubmitClientCommandAndWaitStatus(client, command)
call_p_pi = _c_caller("p", "pi")         # b3RequestActualStateCommandInit(client, body)
call_i_pi = _c_caller("i", "pi")         # b3RequestActualStateCommandCompute...(command, flag)
call_i_p = _c_caller("i", "p")           # b3GetStatusType(status)
call_i_p8 = _c_caller("i", "pppppppp")   # b3GetStatusActualState(status, 3 int*, 4 double**)
call_i_ppip = _c_caller("i", "ppip")     # b3GetJointState / b3GetLinkState(client, status, i, out)
call_v_piippi = _c_caller("v", "piippi")  # b3ApplyExternalForce(cmd, body, link, f*, at*, frame)
call_v_piipi = _c_caller("v", "piipi")   # b3ApplyExternalTorque(cmd, body, link, t*, frame)
call_p_pii = _c_caller("p", "pii")       # b3JointControlCommandInit2(client, body, mode)
call_i_pid = _c_caller("i", "pid")       # b3JointControlSetDesiredForceTorque(cmd, dof, value)


@intrinsic
def load_f64(typingctx, address, index):
    """``((const double *) address)[index]``: a double from a buffer Bullet owns."""
    if not _ints(address, index):
        return None

    def codegen(context, builder, sig, args):
        base = builder.inttoptr(args[0], _f64.as_pointer())
        return builder.load(builder.gep(base, [args[1]]))

    return types.float64(address, index), codegen


# fns: addresses of (b3InitStepSimulationCommand, b3SubmitClientCommandAndWaitStatus,
# b3RequestActualStateCommandInit, b3RequestActualStateCommandComputeLinkVelocity,
# b3RequestActualStateCommandComputeForwardKinematics, b3GetStatusActualState, b3GetJointState,
# b3GetLinkState, b3GetStatusType). kinds: the status types Bullet answers a completed step and
# a completed state request with (learnt from Bullet itself, see _bullet_capi).
BULLET_OK, BULLET_STEP_FAILED, BULLET_READ_FAILED = 0, 1, 2
# Doubles in Bullet's b3JointSensorState (9) and b3LinkState (33), with room to spare: Bullet
# writes the whole struct, whatever this module reads of it.
_JOINT_STATE_DOUBLES, _LINK_STATE_DOUBLES = 32, 64
# b3LinkState: m_worldPosition[3], m_worldOrientation[4], ... m_worldAngularVelocity at 24.
_LINK_ANGULAR_VELOCITY = 24


@njit(cache=True, nogil=True, inline="always")
def _request_state(fns, client, uid, link_flags, read_kind):
    """Bullet's actual-state request for one body, as PyBullet's getters submit it (with link
    velocity and forward kinematics when ``link_flags``, as ``getLinkState(...,
    computeLinkVelocity=1, computeForwardKinematics=1)``). Returns the status handle, or 0 when
    Bullet did not answer with a completed request."""
    command = call_p_pi(fns[2], (client, uid))
    if link_flags:
        call_i_pi(fns[3], (command, 1))
        call_i_pi(fns[4], (command, 1))
    status = call_p_pp(fns[1], (client, command))
    if status != 0 and call_i_p(fns[8], (status,)) != read_kind:
        return 0
    return status


@njit(cache=True, nogil=True, inline="always")
def _copy_base_state(fns, status, scratch, out, o):
    """out[o:o+7] = base position and quaternion x, y, z, w; out[o+7:o+13] = base velocity and
    angular velocity: ``getBasePositionAndOrientation`` + ``getBaseVelocity`` of one answer."""
    pointers = scratch[:2].view(np.intp)
    p = pointers.ctypes.data
    call_i_p8(fns[5], (status, 0, 0, 0, 0, p, p + 8, 0))
    for c in range(7):
        out[o + c] = load_f64(pointers[0], c)
    for c in range(6):
        out[o + 7 + c] = load_f64(pointers[1], c)


@njit(cache=True, nogil=True, inline="always")
def _copy_joint_states(fns, client, status, scratch, out, positions, velocities):
    """out[positions + j], out[velocities + j] = position and velocity of joints 0, 1, 2 (the
    2D multibody's x, y and angle): ``getJointStates``. Returns False if Bullet refuses."""
    buffer = scratch[2:]
    for joint in range(3):
        if call_i_ppip(fns[6], (client, status, joint, buffer.ctypes.data)) == 0:
            return False
        out[positions + joint] = buffer[0]
        out[velocities + joint] = buffer[1]
    return True


@njit(cache=True, nogil=True)
def bullet_step(fns, client, step_kind, nsteps, forces=None):
    """``nsteps`` times what ``pybullet.stepSimulation`` does, each step preceded by the scene's
    springs, drag and loads when ``forces`` (a BulletForces, PybulletModel._force_plan) is
    given. Returns BULLET_OK or the failure code (a step, or a read or apply of the forces,
    without the expected answer)."""
    for _ in range(nsteps):
        if forces is not None:
            code = _bullet_apply_forces(fns, client, forces)
            if code != BULLET_OK:
                return code
        status = call_p_pp(fns[1], (client, call_p_p(fns[0], (client,))))
        if status == 0 or call_i_p(fns[8], (status,)) != step_kind:
            return BULLET_STEP_FAILED
    return BULLET_OK


# -- forces applied before every step (PybulletModel._apply_forces, compiled) -----------------
# PybulletModel._force_plan builds a BulletForces from the model's _Forces, so both evaluate the
# same springs, drag and loads in the same order:
# * fns: addresses of (b3ApplyExternalForceCommandInit, b3ApplyExternalForce,
#   b3ApplyExternalTorque, b3JointControlCommandInit2, b3JointControlSetDesiredForceTorque);
# * uids, planar, read_kind: as for bullet_read; acted: indices of the acted-on bodies;
# * spring_bodies (S, 2): a, b (-1: an anchor); spring_data (S, 12): attachment on a and on b
#   (relative to the centre of mass, in the frame read_raw's quaternion rotates), anchor,
#   stiffness, damping, rest length;
# * drag_bodies (D,), drag_data (D, 2): linear and angular coefficients; base (N, 6): the
#   constant loads, force and torque;
# * dofs (N, 3): 2D multibody joints' velocity indices; modes: (EF_WORLD_FRAME,
#   CONTROL_MODE_TORQUE) as PyBullet defines them;
# * state (N, 13), ft (N, 6), scratch: work arrays (state as read, force and torque).
BulletForces = namedtuple("BulletForces", "fns uids planar read_kind acted spring_bodies "
                          "spring_data drag_bodies drag_data base dofs modes state ft scratch")


@njit(cache=True, nogil=True, inline="always")
def _rotate_xyzw(q, r, out):
    """out = r rotated by the unit quaternion q = (x, y, z, w): pybullet._rotate, same operations
    in the same order (so the same bits)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    rx, ry, rz = r[0], r[1], r[2]
    tx = 2.0 * (y * rz - z * ry)
    ty = 2.0 * (z * rx - x * rz)
    tz = 2.0 * (x * ry - y * rx)
    out[0] = rx + w * tx + y * tz - z * ty
    out[1] = ry + w * ty + z * tx - x * tz
    out[2] = rz + w * tz + x * ty - y * tx


@njit(cache=True, nogil=True, inline="always")
def _cross_into(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True, nogil=True)
def _bullet_force_state(fns, client, uid, planar, read_kind, scratch, st):
    """st = (centre of mass 3, quaternion x, y, z, w, velocity 3, angular velocity 3) of one
    body, read as PybulletModel._state_for_forces reads it (one request, no flags)."""
    status = _request_state(fns, client, uid, False, read_kind)
    if status == 0:
        return BULLET_READ_FAILED
    if not planar:
        _copy_base_state(fns, status, scratch, st, 0)
        return BULLET_OK
    # Joint coordinates first into st[0:3] and st[7:10], then spread as the 3D layout has them.
    if not _copy_joint_states(fns, client, status, scratch, st, 0, 7):
        return BULLET_READ_FAILED
    angle, spin = st[2], st[9]
    st[2] = 0.0
    st[3], st[4], st[5], st[6] = 0.0, 0.0, math.sin(0.5 * angle), math.cos(0.5 * angle)
    st[9], st[10], st[11], st[12] = 0.0, 0.0, 0.0, spin
    return BULLET_OK


@njit(cache=True, nogil=True)
def bullet_evaluate_forces(fns, client, forces):
    """Read the acted-on bodies' states into ``forces``' state array and evaluate the springs,
    drag and loads into its ft array (force 3, torque 3 per body): _Forces.__call__, term by
    term in its order. Returns BULLET_OK or BULLET_READ_FAILED."""
    state, ft = forces.state, forces.ft
    spring_bodies, spring_data = forces.spring_bodies, forces.spring_data
    drag_bodies, drag_data = forces.drag_bodies, forces.drag_data
    for i in forces.acted:
        code = _bullet_force_state(fns, client, forces.uids[i], forces.planar, forces.read_kind,
                                   forces.scratch, state[i])
        if code != BULLET_OK:
            return code
    for i in forces.acted:
        ft[i, :] = forces.base[i, :]
    for n in range(drag_bodies.shape[0]):
        i, c, ca = drag_bodies[n], drag_data[n, 0], drag_data[n, 1]
        for m in range(3):
            ft[i, m] -= c * state[i, 7 + m]
            ft[i, 3 + m] -= ca * state[i, 10 + m]
    work = forces.scratch[2:]
    ra_w, wxr, pa, pva = work[0:3], work[3:6], work[6:9], work[9:12]
    rb_w, pb, pvb, d = work[12:15], work[15:18], work[18:21], work[21:24]
    e, fv, tq = work[24:27], work[27:30], work[30:33]
    for n in range(spring_bodies.shape[0]):
        a, b = spring_bodies[n, 0], spring_bodies[n, 1]
        k, c, l0 = spring_data[n, 9], spring_data[n, 10], spring_data[n, 11]
        sa = state[a]
        _rotate_xyzw(sa[3:7], spring_data[n, 0:3], ra_w)
        _cross_into(sa[10:13], ra_w, wxr)
        for j in range(3):
            pa[j] = sa[j] + ra_w[j]
            pva[j] = sa[7 + j] + wxr[j]
        if b < 0:
            for j in range(3):
                pb[j] = spring_data[n, 6 + j]
                pvb[j] = 0.0
        else:
            sb = state[b]
            _rotate_xyzw(sb[3:7], spring_data[n, 3:6], rb_w)
            _cross_into(sb[10:13], rb_w, wxr)
            for j in range(3):
                pb[j] = sb[j] + rb_w[j]
                pvb[j] = sb[7 + j] + wxr[j]
        for j in range(3):
            d[j] = pa[j] - pb[j]
        length = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if length == 0.0:
            continue
        for j in range(3):
            e[j] = d[j] / length
        rate = ((pva[0] - pvb[0]) * e[0] + (pva[1] - pvb[1]) * e[1]
                + (pva[2] - pvb[2]) * e[2])
        mag = -(k * (length - l0) + c * rate)
        for j in range(3):
            fv[j] = mag * e[j]
        _cross_into(ra_w, fv, tq)
        for j in range(3):
            ft[a, j] += fv[j]
            ft[a, 3 + j] += tq[j]
        if b >= 0:
            _cross_into(rb_w, fv, tq)
            for j in range(3):
                ft[b, j] -= fv[j]
                ft[b, 3 + j] -= tq[j]
    return BULLET_OK


@njit(cache=True, nogil=True)
def _bullet_apply_forces(fns, client, forces):
    """bullet_evaluate_forces, then apply the result as PybulletModel._apply_forces does, one
    command per call it makes."""
    code = bullet_evaluate_forces(fns, client, forces)
    if code != BULLET_OK:
        return code
    ffns, uids, dofs, state, ft = forces.fns, forces.uids, forces.dofs, forces.state, forces.ft
    world, torque_mode = forces.modes[0], forces.modes[1]
    for i in forces.acted:
        if forces.planar:
            command = call_p_pii(ffns[3], (client, uids[i], torque_mode))
            call_i_pid(ffns[4], (command, dofs[i, 0], ft[i, 0]))
            call_i_pid(ffns[4], (command, dofs[i, 1], ft[i, 1]))
            call_i_pid(ffns[4], (command, dofs[i, 2], ft[i, 5]))
            if call_p_pp(fns[1], (client, command)) == 0:
                return BULLET_STEP_FAILED
            continue
        # The force acts at the centre of mass just read (state[i, 0:3]), world frame.
        command = call_p_p(ffns[0], (client,))
        call_v_piippi(ffns[1], (command, uids[i], -1, ft[i, 0:3].ctypes.data,
                                state[i, 0:3].ctypes.data, world))
        if call_p_pp(fns[1], (client, command)) == 0:
            return BULLET_STEP_FAILED
        command = call_p_p(ffns[0], (client,))
        call_v_piipi(ffns[2], (command, uids[i], -1, ft[i, 3:6].ctypes.data, world))
        if call_p_pp(fns[1], (client, command)) == 0:
            return BULLET_STEP_FAILED
    return BULLET_OK


@njit(cache=True, nogil=True)
def bullet_read(fns, client, uids, planar, read_kind, row, scratch):
    """One sample of every body into ``row``, the adapter's raw layout (PybulletModel.read_raw).

    3D and maximal bodies, 13 per body: what ``getBasePositionAndOrientation`` and
    ``getBaseVelocity`` return (the same actual-state request, once instead of twice): centre of
    mass, inertial-frame quaternion x, y, z, w, centre-of-mass velocity, angular velocity.
    2D multibody (``planar``), 16 per body: the three joint positions and velocities
    (``getJointStates``) and link 2's centre of mass, orientation and angular velocity
    (``getLinkState(..., computeLinkVelocity=1, computeForwardKinematics=1)``), from one request
    with both flags set. Returns BULLET_OK or BULLET_READ_FAILED.
    """
    width = 16 if planar else 13
    for j in range(uids.shape[0]):
        status = _request_state(fns, client, uids[j], planar, read_kind)
        if status == 0:
            return BULLET_READ_FAILED
        o = j * width
        if not planar:
            _copy_base_state(fns, status, scratch, row, o)
            continue
        if not _copy_joint_states(fns, client, status, scratch, row, o, o + 3):
            return BULLET_READ_FAILED
        buffer = scratch[2:]
        if call_i_ppip(fns[7], (client, status, 2, buffer.ctypes.data)) == 0:
            return BULLET_READ_FAILED
        for c in range(7):
            row[o + 6 + c] = buffer[c]
        for c in range(3):
            row[o + 13 + c] = buffer[_LINK_ANGULAR_VELOCITY + c]
    return BULLET_OK


@njit(cache=True, nogil=True)
def bullet_record(fns, client, uids, planar, kinds, k, out, scratch, forces=None):
    """Sample 0, then k steps (with ``forces``, see bullet_step) and a sample per row of ``out``
    (n_samples, N * width).

    Returns (count, code): the number of valid samples (a sample with a non-finite value ends
    the run there; sample 0, the state PyBullet was given, is always kept) and BULLET_OK, or
    the failure code of the step or read that stopped the loop. 3D and maximal rows leave with
    sign-continuous quaternions (``_continue_sign``).
    """
    code = bullet_read(fns, client, uids, planar, kinds[1], out[0], scratch)
    if code != BULLET_OK:
        return 0, code
    for i in range(1, out.shape[0]):
        code = bullet_step(fns, client, kinds[0], k, forces)
        if code == BULLET_OK:
            code = bullet_read(fns, client, uids, planar, kinds[1], out[i], scratch)
        if code != BULLET_OK:
            return i, code
        for c in range(out.shape[1]):
            if not np.isfinite(out[i, c]):
                return i, BULLET_OK
        if not planar:
            _continue_sign(out, i, 13)
    return out.shape[0], BULLET_OK


@njit(cache=True, nogil=True, inline="always")
def _continue_sign(out, i, width):
    """Negate sample i's quaternion (x, y, z, w at 3..6 of each body's row) when its dot with
    sample i-1's is negative: the rule of rotations.sign_continuous, applied as the samples
    come. Bullet rebuilds the quaternion from a matrix at every read, so its sign jumps (24
    times in the free-flight case's 100 intervals); left to the conversion, the jumps send
    sign_continuous down its slower path (19 us for 101 samples against 7 us, on 0.87 ms of
    that case's stepping). Negation is exact: the Trajectory is the same either way."""
    for o in range(0, out.shape[1], width):
        dot = 0.0
        for c in range(3, 7):
            dot += out[i, o + c] * out[i - 1, o + c]
        if dot < 0.0:
            for c in range(3, 7):
                out[i, o + c] = -out[i, o + c]


def bullet_scratch() -> np.ndarray:
    """Work buffer for bullet_read and BulletForces: two pointer slots, then room for one
    Bullet struct (or the 33 doubles bullet_evaluate_forces works in)."""
    return np.zeros(2 + max(_JOINT_STATE_DOUBLES, _LINK_STATE_DOUBLES))
