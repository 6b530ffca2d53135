"""MuJoCo adapter: a Scene compiled to MJCF, stepped, and read back in crosscheck's frames.

What is mapped how (docs/engines.md has the full table):

* **Bodies, 3D.** One MuJoCo body per scene body, a child of the world body with a free joint. The
  MuJoCo body frame *is* the declared body frame: ``qpos[0:3]``/``qpos[3:7]`` are the declared
  frame's origin and orientation. The inertial is explicit (``mass``, ``pos`` = the centre of mass
  in the body frame, ``quat`` + ``diaginertia`` from NumPy's eigen-decomposition of the full
  tensor), so MuJoCo never derives mass properties from geometry. With the engine option
  ``align_free = true`` the MuJoCo body frame is instead the inertial frame (centre of mass,
  principal axes), what MuJoCo's own ``freejoint align="true"`` does; the adapter converts back.
* **Bodies, 2D.** Planar joints in the x-y plane: a slide along x, a slide along y and a hinge about
  z. The hinge passes through the centre of mass, so the two slides measure the centre of mass and
  the hinge angle is the body angle. Out-of-plane moments equal the in-plane one (any positive
  values satisfying the triangle inequality would do; no out-of-plane motion exists).
* **Gravity** ``m.opt.gravity`` = the scene's, zero when the scene has none (MuJoCo's default is
  -9.81 along z).
* **Contact**, only with ``[effects] contact = true`` (otherwise ``mjDSBL_CONTACT``, no geoms and
  no contact option touched). One massless geom per body (3D shapes as themselves, a mesh
  collided as its convex hull; 2D shapes as prisms along z, the ground line as a plane
  containing z), the ground as a plane and statics as world geoms. Every pair gets exactly its
  values, by material class (``collision_routes``): MuJoCo's own collision (contype /
  conaffinity bits per class, the values on the geoms) where both classes' own values are the
  pair's, so MuJoCo's combination rule returns them; an explicit ``<pair>`` per pair where it
  would not (its rule takes the max friction); no common bit for ``collide = false``. Values:
  condim 1/3/4/6, friction (mu, mu, torsional, rolling, rolling), a non-bouncing solref for
  e = 0 and a direct solref from the unilateral spring-dashpot's zeta(e) for e > 0. Elliptic
  cone, impratio 10, no noslip. docs/engines.md, "Contact", has the measurements behind each
  setting.
* **Springs** are spatial tendons between two sites with ``stiffness``, ``damping`` and
  ``springlength = (L0, L0)``: MuJoCo's tendon force is -k (L - L0) - c dL/dt along the line of
  the sites, exactly the scene's spring, and it is evaluated inside every RK4 stage.
* **Drag** is joint damping where that is exactly the scene's drag: the slides of a 2D body (at its
  centre of mass) and the hinge; the free joint's rotational dofs (isotropic damping of the
  body-local angular velocity is -c w in any frame); its translational dofs only when they carry
  the centre-of-mass velocity (centre of mass at the body origin, or ``align_free``). Linear drag
  of a 3D body whose centre of mass is off its origin has no exact MuJoCo mechanism (the free
  joint's translational dofs are the origin's velocity): it is applied through ``xfrc_applied``,
  recomputed from the state at the start of every step and held over that step (under RK4 that
  force is constant across the four stages: first order in the drag term).
* **Loads** are constant ``xfrc_applied`` rows (force at the centre of mass, torque, world frame),
  set once.
* **A fluid case** (one disc, no free surface: scene/medium_map.py) runs as the disc's long
  cylinder in MuJoCo's medium, the fluid model named by the run ("rk4+ellipsoid",
  "rk4+inertia_box"): planar joints as a 2D body, the cylinder's own mass and moments, the
  fluid's density and dynamic viscosity as ``opt.density`` / ``opt.viscosity``, buoyancy as
  gravcomp (docs/engines.md, "MuJoCo's stateless medium against a resolved fluid").

Stepping (engine option ``stepping``). ``advance(n)`` is ``mj_step(m, d, nstep=n)`` (a Python
loop only when drag is applied per step); after it MuJoCo's warning counters are read, and any
warning (its instability check: NaN, Inf or |value| > 1e10 in qpos, qvel or qacc) ends the run
as a StepFailure. The accuracy pass records ``qpos``/``qvel`` only, converted to centre-of-mass
position and velocity and world angular velocity after the run, vectorised (MuJoCo's derived
arrays, stale after ``mj_step``, are never read):

* ``compiled`` (default): the session's fused fast path, a compiled loop (numba,
  ``engines/_native.py``) calling MuJoCo's C ``mj_step(m, d)`` k times per sample and copying
  ``qpos``/``qvel``, with no Python call per sample. ``mj_step`` is taken from the ``libmujoco``
  the bindings already loaded (``RTLD_NOLOAD``); without it (or without numba) the driver's
  generic loop records. Bit-identical to the generic loop (tests/engines/test_driver.py).
* ``nstep``: the driver's generic loop, ``advance(k)`` then a read per sample.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from crosscheck.engines.base import Capabilities, EngineBase
from crosscheck.engines.session import StepFailure
from crosscheck.errors import CaseError
from crosscheck.names import MEDIUM_MODELS, medium_run_names, rigid_names, split_run
from crosscheck.rotations import matrix_to_quat, quat_conj, quat_mul, quat_to_matrix
from crosscheck.scene.contact import GROUND, ContactPair, material_classes
from crosscheck.scene.medium_map import (
    LENGTH_IN_RADII,
    MappedCylinder,
    mapped_cylinder,
    unmappable,
)
from crosscheck.scene.model import Medium, Scene

try:  # the registry imports this module lazily; a missing mujoco is "not applicable"
    import mujoco
except ImportError:  # pragma: no cover - mujoco is a declared dependency
    mujoco = None

# Integrator names, MuJoCo's default (Euler) first (crosscheck.names holds them).
INTEGRATORS: tuple[str, ...] = rigid_names("mujoco")
_MJ_INTEGRATOR = {"euler": "mjINT_EULER", "rk4": "mjINT_RK4", "implicit": "mjINT_IMPLICIT",
                  "implicitfast": "mjINT_IMPLICITFAST", "discrete": "mjINT_DISCRETE"}

INTEGRATOR_NOTES = {
    "euler": "semi-implicit Euler: v += h a(t), then q += h v(t+h), the quaternion through the "
             "exponential map of the body-local angular velocity; gyroscopic term explicit (a "
             "tumbling body gains energy); joint damping implicit unless eulerdamp = false",
    "rk4": "classic 4-stage Runge-Kutta on (qpos, qvel), quaternion stages by the exponential "
           "map; tendon springs and joint damping are evaluated in every stage, forces set in "
           "xfrc_applied once per step are constant across the stages",
    "implicit": "implicit-in-velocity Euler: the velocity derivatives of all smooth forces "
                "including the gyroscopic term are implicit (a tumbling body loses energy)",
    "implicitfast": "implicit-in-velocity Euler without the Coriolis derivatives, except for "
                    "standalone free bodies where MuJoCo reinstates them (same step as implicit)",
    "discrete": "velocity-stepping: implicit update with damping and stiffness in the effective "
                "inertia M + hD + h^2 K, then q += h v(t+h)",
}

# Engine options a case may pin in [engine_options.mujoco]: name -> (allowed values, default).
OPTIONS: dict[str, tuple[tuple[Any, ...], Any]] = {
    "jacobian": (("auto", "dense", "sparse"), "auto"),
    "eulerdamp": ((True, False), True),
    "align_free": ((True, False), False),
    "drag": (("auto", "per_step"), "auto"),
    "stepping": (("compiled", "nstep"), "compiled"),
    # Contact scenes: the constraint solver. Newton (MuJoCo's default) builds a dense Hessian over
    # all degrees of freedom, so a pile of 1000 free bodies steps 35x slower than with CG, which
    # reaches the same state (CONTACTS.md 3b; benchmarks/results/piles.md).
    "solver": (("newton", "cg", "pgs"), "newton"),
    # [effects] medium: which of MuJoCo's two fluid models acts (docs/engines.md, "Medium").
    "fluid_model": (("inertia_box", "ellipsoid"), "inertia_box"),
}
# The ellipsoid model's five coefficients (blunt drag, slender drag, angular drag, Kutta lift,
# Magnus lift): MuJoCo's defaults unless [engine_options.mujoco] fluidcoef gives five numbers.
FLUIDCOEF_DEFAULT = (0.5, 0.25, 1.5, 1.0, 1.0)
FLUID_OPTIONS = ("fluid_model", "fluidcoef")

# A run fails at the first sample at or after which MuJoCo's own check fired (mj_checkPos,
# mj_checkVel, mj_checkAcc: NaN, Inf or a value beyond mjMAXVAL = 1e10).
_UNSTABLE = "MuJoCo flagged an instability (NaN, Inf or |value| > 1e10 in qpos, qvel or qacc)"
def _native_stepper() -> tuple[Any, int | None, str]:
    """(engines._native, address of the C ``mj_step``, "") or (None, None, why not).

    The address comes from the libmujoco that ``import mujoco`` already loaded (``RTLD_NOLOAD``
    fails rather than load a second copy), so the compiled loop steps the bindings' own model
    and data with their own library. Computed once per process.
    """
    global _NATIVE
    if _NATIVE is None:
        _NATIVE = _find_native_stepper()
    return _NATIVE


_NATIVE: tuple[Any, int | None, str] | None = None


def _find_native_stepper() -> tuple[Any, int | None, str]:
    import ctypes
    import os
    from pathlib import Path

    try:
        from crosscheck.engines import _native
    except Exception as exc:  # pragma: no cover - numba is a dependency
        return None, None, f"numba unavailable ({exc})"
    here = Path(mujoco.__file__).parent
    names = sorted(here.glob("libmujoco.so*")) + sorted(here.glob("libmujoco*.dylib")) + \
        sorted(here.glob("mujoco*.dll"))
    mode = getattr(os, "RTLD_NOLOAD", 0) | getattr(os, "RTLD_LAZY", 0)
    for path in names:
        try:
            lib = ctypes.CDLL(str(path), mode=mode)
            address = ctypes.cast(lib.mj_step, ctypes.c_void_p).value
        except (OSError, AttributeError):
            continue
        if address:
            return _native, int(address), ""
    return None, None, "the libmujoco loaded by the bindings was not found"


_SHAPES_3D = ("sphere", "box", "capsule", "cylinder", "mesh")
_SHAPES_2D = ("circle", "box", "polygon")


def _f(x: float) -> str:
    """Shortest decimal that parses back to exactly the same double."""
    return repr(float(x))


def _v(values) -> str:
    return " ".join(_f(x) for x in np.ravel(values))


def engine_options(scene: Scene) -> dict[str, Any]:
    """The case's [engine_options.mujoco] over the defaults; unknown keys or values refused."""
    given = dict(scene.engine_options.get("mujoco", {}))
    out = {}
    fluid_case = scene.fluid is not None
    for key, value in given.items():
        if key == "fluid_model" and fluid_case:
            # The mapped fluid case runs both models side by side: the run name chooses.
            raise CaseError(scene.source, "engine_options.mujoco.fluid_model",
                            'no fluid_model on a fluid case: the run name chooses the model '
                            '(run.integrators.mujoco = ["rk4+ellipsoid", "rk4+inertia_box"])',
                            value)
        if key in FLUID_OPTIONS and scene.effects.medium is None and not fluid_case:
            raise CaseError(scene.source, f"engine_options.mujoco.{key}",
                            "no fluid option on a scene without [effects] medium (it would "
                            "change nothing)", value)
        if key == "fluidcoef":
            ok = (isinstance(value, list) and len(value) == 5
                  and all(isinstance(x, int | float) and not isinstance(x, bool)
                          and math.isfinite(x) and x >= 0 for x in value))
            if not ok:
                raise CaseError(scene.source, "engine_options.mujoco.fluidcoef",
                                "5 non-negative numbers: blunt drag, slender drag, angular drag, "
                                "Kutta lift, Magnus lift (MuJoCo's geom fluidcoef)", value)
            if given.get("fluid_model") != "ellipsoid" and not fluid_case:
                raise CaseError(scene.source, "engine_options.mujoco.fluidcoef",
                                'fluid_model = "ellipsoid" beside it (the inertia-box model has '
                                "no coefficients)", value)
            out[key] = [float(x) for x in value]
            continue
        if key not in OPTIONS:
            known = sorted({*OPTIONS, "fluidcoef"})
            raise CaseError(scene.source, f"engine_options.mujoco.{key}",
                            f"one of the MuJoCo adapter's options {known}",
                            f"unknown option {key!r}")
        allowed, _ = OPTIONS[key]
        if not any(value == a and type(value) is type(a) for a in allowed):
            raise CaseError(scene.source, f"engine_options.mujoco.{key}", f"one of {list(allowed)}",
                            value)
        out[key] = value
    merged = {key: out.get(key, default) for key, (_, default) in OPTIONS.items()}
    merged["fluidcoef"] = out.get("fluidcoef", list(FLUIDCOEF_DEFAULT))
    return merged


def medium_limits(scene: Scene) -> str | None:
    """Why MuJoCo cannot give this scene's medium exactly, or None. Buoyancy is given as
    ``gravcomp`` (an upward force at the centre of mass): a body whose centre of mass is not its
    shape's centroid (the centre of buoyancy) would miss the buoyancy's torque."""
    medium = scene.effects.medium
    if medium is None or medium.density == 0.0 or scene.effects.gravity is None:
        return None
    from crosscheck.scene.massprops import shape_mass_properties

    for body in scene.bodies:
        centroid = np.asarray(shape_mass_properties(body.shape, 1.0).com, float)
        off = float(np.linalg.norm(np.asarray(body.com, float) - centroid))
        size = max(float(np.max(np.abs(np.concatenate(body.shape.bounding_box())))), 1e-300)
        if off > 1e-9 * size:
            return (f"body {body.name!r}: its centre of mass is {off:.3g} m from its shape's "
                    "centroid, the centre of buoyancy; MuJoCo's buoyancy route (body gravcomp) "
                    "acts at the centre of mass and would miss the buoyancy's torque")
    return None


# MuJoCo's compiler refuses a moving body whose mass or a principal moment is below mjMINVAL
# (1e-15), and principal moments with A + B < C beyond an absolute slack of about mjMINVAL
# (measured: 1e-16 over passes, 1e-12 over fails). A flat plate sits exactly at A + B = C, and the
# eigen-decomposition lands there only to round-off, which for moments of order 1 kg m^2 and up
# exceeds that absolute slack.
MJ_MINVAL = 1e-15
# A + B may fall short of C by this much relative to C (a few ulps of the decomposition) and is
# then balanced by lowering C to A + B; beyond it the inertia is not MuJoCo's to take.
TRIANGLE_ROUNDOFF = 1e-12


def principal_moments(inertia) -> tuple[np.ndarray, np.ndarray]:
    """(ascending principal moments, axes as a proper rotation), with a moment tensor at the
    triangle-inequality limit balanced to exactly A + B = C when round-off put it past."""
    moments, axes = np.linalg.eigh(np.asarray(inertia, float))
    short = moments[2] - (moments[0] + moments[1])
    if 0 < short <= TRIANGLE_ROUNDOFF * moments[2]:
        moments = moments.copy()
        moments[2] = moments[0] + moments[1]
    return moments, axes


def mujoco_limits(scene: Scene) -> str | None:
    """Why MuJoCo cannot take this scene's bodies (its documented compiler limits), or None."""
    for body in scene.bodies:
        if body.mass < MJ_MINVAL:
            return (f"body {body.name!r}: mass {body.mass:g} kg is below MuJoCo's mjMINVAL "
                    f"({MJ_MINVAL:g}), which its compiler refuses for a moving body")
        if scene.dimension == 3:
            moments, _ = principal_moments(body.inertia)
        else:
            moments = np.full(3, float(body.moment))
        if moments[0] < MJ_MINVAL:
            return (f"body {body.name!r}: principal moment {moments[0]:g} kg m^2 is below "
                    f"MuJoCo's mjMINVAL ({MJ_MINVAL:g})")
        short = moments[2] - (moments[0] + moments[1])
        if short > TRIANGLE_ROUNDOFF * moments[2]:
            return (f"body {body.name!r}: principal moments {moments.tolist()} break the "
                    f"triangle inequality A + B >= C by {short:.3g} kg m^2, which MuJoCo's "
                    "compiler refuses")
    return None


# -- contact ---------------------------------------------------------------------------------------
# Settings of contact scenes (docs/engines.md, "MuJoCo: contact"; the figures behind each are in
# benchmarks/results/contact_mujoco.md, from benchmarks/contact_mujoco.py).
CONTACT_OPTIONS: dict[str, Any] = {
    # Isotropic friction: the pyramidal default slides mu/sqrt(2) at 45 deg to the contact frame
    # (CONTACTS.md trap C3).
    "cone": "mjCONE_ELLIPTIC",
    # Friction rows 10x harder than the normal row: static creep at 25 deg on mu = 0.5 falls from
    # 3 mm to 0.008 mm in 2 s (with the non-bouncing row below; trap C6).
    "impratio": 10.0,
    # No noslip pass: with elliptic cones it spoils kinetic friction (+10 to +86 %), and with
    # pyramidal cones and mu ~ 0 it explodes (trap C5).
    "noslip_iterations": 0,
    "solver": "mjSOL_NEWTON",  # the default of [engine_options.mujoco] solver
    "iterations": 100,
    "tolerance": 1e-8,
    "ls_iterations": 50,
}
# e = 0: recipe M3 of CONTACTS.md. timeconst 5 ms (b ~ 400/s, k ~ 1e4/s^2) with dampratio 2: a
# linear spring-dashpot at dampratio 1 still rebounds (e(1) = exp(-2) = 0.135, trap C1).
SOLREF_INELASTIC = (0.005, 2.0)
SOLIMP = (0.99, 0.99, 0.001, 0.5, 2.0)
# e > 0: a direct-format row whose contact lasts about this many steps.
RESTITUTION_STEPS = 20


def restitution_of_damping(zeta: float) -> float:
    """Coefficient of restitution of a *unilateral* linear spring-dashpot contact.

    x'' + 2 zeta x' + x = 0 from x = 0, x' = 1 (unit natural frequency), and the contact lets go
    when its force k x + b x' reaches zero (a contact cannot pull), i.e. when x'' = 0, not when
    x returns to 0. Then e = -x'(release). Closed forms of Schwager and Poeschel, "Coefficient of
    restitution and linear-dashpot model revisited", Granular Matter 9 (2007) 465, eqs. for the
    under-damped branches; the over-damped branch solves x'' = 0 for the two real exponents
    directly. The textbook exp(-zeta pi / sqrt(1 - zeta^2)) assumes release at x = 0 and asks for
    too little damping (e = 0.5 comes out 0.55; CONTACTS.md trap C2). e(1) = exp(-2).
    """
    z = float(zeta)
    if z <= 0.0:
        return 1.0
    if z < 1.0:
        s = math.sqrt(1.0 - z * z)
        if z < 1.0 / math.sqrt(2.0):
            phase = math.pi - math.atan(2.0 * z * s / (1.0 - 2.0 * z * z))
        elif z == 1.0 / math.sqrt(2.0):
            phase = math.pi / 2.0
        else:
            phase = math.atan(2.0 * z * s / (2.0 * z * z - 1.0))
        return math.exp(-z / s * phase)
    if z == 1.0:
        return math.exp(-2.0)
    s = math.sqrt(z * z - 1.0)
    r1, r2 = -z + s, -z - s  # x = (exp(r1 t) - exp(r2 t)) / (2 s)
    t = math.log(r2 * r2 / (r1 * r1)) / (2.0 * s)  # x'' = 0
    return -(r1 * math.exp(r1 * t) - r2 * math.exp(r2 * t)) / (2.0 * s)


def damping_for_restitution(e: float) -> float:
    """The damping ratio zeta whose unilateral spring-dashpot gives restitution e in (0, 1]
    (the inverse of :func:`restitution_of_damping`, which decreases monotonically; bisection to
    1e-15). e -> 0 needs zeta -> infinity: e below 1e-9 is refused."""
    if not 1e-9 <= e <= 1.0:
        raise ValueError(f"restitution {e} outside [1e-9, 1]")
    if e == 1.0:
        return 0.0
    lo, hi = 0.0, 1.0
    while restitution_of_damping(hi) > e:
        lo, hi = hi, 2.0 * hi
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if restitution_of_damping(mid) > e:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-15 * hi:
            break
    return 0.5 * (lo + hi)


def solref_for_restitution(e: float, dt: float, nsteps: int = RESTITUTION_STEPS
                           ) -> tuple[float, float]:
    """MuJoCo direct-format ``solref = (-k, -b)`` for restitution ``e`` in (0, 1].

    MuJoCo has no restitution coefficient: a contact is a spring-dashpot on the penetration,
    aref = -b v - k x per unit effective mass, so its restitution is that of the damped
    oscillator (:func:`restitution_of_damping`). The contact is made to last about ``nsteps``
    steps: a nominal frequency w = pi / (nsteps dt), w0 = w / sqrt(1 - zeta^2) so that the
    half-period of the damped oscillation is nsteps dt (w0 = w when over-damped), k = w0^2,
    b = 2 zeta w0. The same construction as ``mj_solref_for_e`` of the contact study
    (shared/contact-measurements/lib.py), written here as crosscheck's own code.
    """
    w = math.pi / (nsteps * dt)
    z = damping_for_restitution(e)
    w0 = w / math.sqrt(1.0 - z * z) if z < 1.0 else w
    return (-w0 * w0, -2.0 * z * w0)


def pair_condim(pm) -> int:
    """MuJoCo's contact dimensionality for a pair's values: 1 frictionless (trap C5: mu = 0 is
    expressed as no friction rows, never as friction 0), 3 sliding, 4 with torsional, 6 with
    rolling friction."""
    if pm.friction == 0.0:
        return 1
    if pm.rolling_friction > 0.0:
        return 6
    if pm.torsional_friction > 0.0:
        return 4
    return 3


def pair_solref(pm, dt: float) -> tuple[float, float]:
    if pm.restitution > 0.0:
        return solref_for_restitution(pm.restitution, dt)
    return SOLREF_INELASTIC


def contact_limits(scene: Scene) -> str | None:
    """Why MuJoCo cannot give this contact scene's pairs their values, or None."""
    classes = material_classes(scene)
    for i, j in classes.class_pairs():
        pm = classes.values[i][j]
        if not pm.collide:
            continue
        a, b = next(classes.pairs_between(i, j))
        if pm.friction == 0.0 and (pm.rolling_friction > 0.0 or pm.torsional_friction > 0.0):
            return (f"pair {a!r}-{b!r}: rolling or torsional friction without sliding "
                    "friction has no MuJoCo contact dimension (condim 1 drops them, and the "
                    "elliptic cone scales every friction row by the sliding one)")
        small = [(k, v) for k, v in (("friction", pm.friction),
                                      ("torsional_friction", pm.torsional_friction),
                                      ("rolling_friction", pm.rolling_friction))
                 if 0.0 < v < MJMINMU]
        if small:
            k, v = small[0]
            return (f"pair {a!r}-{b!r}: {k} {v:g} is below mjMINMU = {MJMINMU:g}, to which "
                    "MuJoCo raises every friction coefficient of a contact")
        if 0.0 < pm.restitution < 1e-9:
            return (f"pair {a!r}-{b!r}: restitution {pm.restitution:g} is neither 0 "
                    "nor reachable by a linear spring-dashpot (below 1e-9)")
    return None


# MuJoCo raises every friction coefficient of a contact to at least mjMINMU (mj_contactParam and
# the explicit pairs alike; measured on 4.0.0): a declared 0 < mu < 1e-5 is refused, and a zero
# torsional coefficient under condim 6 (rolling without torsional friction) acts as 1e-5 m.
MJMINMU = 1e-5


def mujoco_values(pm, dt: float) -> tuple:
    """(condim, friction (mu, mu, torsional, rolling, rolling), solref) MuJoCo needs for a pair's
    values; solimp, margin and gap are the same for every pair."""
    friction = (pm.friction, pm.friction, pm.torsional_friction, pm.rolling_friction,
                pm.rolling_friction)
    return pair_condim(pm), friction, tuple(pair_solref(pm, dt))


# MuJoCo's arena (contacts and constraint arrays) for a contact scene, in bytes: its automatic
# size grows faster than N^1.5 (134 MB at 200 spheres, 1.8 GB at 1000, and the compiler cannot
# allocate it at 5000: "Could not allocate memory"), while a settled pile uses 3-25 kB per
# contact (measured on 4.0.0: 1000 spheres under CG 4.9 MB at 1574 contacts, Newton 37 MB at
# 1458; 200 spheres / boxes under Newton 5.2 / 3.6 MB). So: a 16 MB floor and 256 kB per body
# (room for 16 contacts per body at 16 kB each). Untouched arena pages are never resident.
ARENA_FLOOR = 16 << 20
ARENA_PER_BODY = 256 << 10


def arena_bytes(n_bodies: int) -> int:
    return ARENA_FLOOR + ARENA_PER_BODY * n_bodies


# MuJoCo's contype / conaffinity are 32-bit ints: one bit per material class, up to 31 classes
# (a scene with more gives every pair that can touch an explicit <pair>, the slow route).
MAX_CLASS_BITS = 31


def collision_routes(scene: Scene, dt: float) -> dict[tuple[int, int], str]:
    """How each class pair that can touch (``material_classes``) reaches its values in MuJoCo:

    * "dynamic": MuJoCo's own collision (broad phase, contype / conaffinity) with the values on
      the geoms. Its rule for two geoms (condim and friction the maximum, solref and solimp the
      solmix-weighted mean) returns exactly the pair's values when both geoms carry them, so a
      class pair is dynamic when the pair values are each class's own values (the pair rule on
      one material gives that material);
    * "explicit": one ``<pair>`` per body pair, with exactly its values (MuJoCo's rule would give
      other values, e.g. the max friction where the pair rule asks for the geometric mean);
    * "off": ``collide = false``; the classes' bits keep MuJoCo from colliding them.
    """
    classes = material_classes(scene)
    own = [mujoco_values(classes.values[c][c], dt) for c in range(classes.k)]
    routes = {}
    for i, j in classes.class_pairs():
        pm = classes.values[i][j]
        if not pm.collide:
            routes[(i, j)] = "off"
        elif classes.k <= MAX_CLASS_BITS and mujoco_values(pm, dt) == own[i] == own[j]:
            routes[(i, j)] = "dynamic"
        else:
            routes[(i, j)] = "explicit"
    return routes


def _restitution_model(e: float) -> str:
    if e == 0.0:
        return f"none: non-bouncing row (timeconst, dampratio) = {list(SOLREF_INELASTIC)}"
    return ("direct solref (-k, -b) of a unilateral spring-dashpot with this restitution, "
            f"contact lasting ~{RESTITUTION_STEPS} steps (approximate: docs/engines.md)")


def _contact_pair(classes, a: str, b: str, pm) -> ContactPair:
    """The pair (a, b) as ``Scene.contact_pairs`` lists it: the body first."""
    if a in classes.fixed:
        a, b = b, a
    kind = ("body-ground" if b == GROUND else "body-static" if b in classes.fixed
            else "body-body")
    return ContactPair(a, b, kind, pm)


def _quat_z_to(n: np.ndarray) -> np.ndarray:
    """The shortest rotation taking +z to the unit vector n, (w, x, y, z)."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    c = float(n[2])
    if c < -1.0 + 1e-15:
        return np.array([0.0, 1.0, 0.0, 0.0])
    q = np.array([1.0 + c, -n[1], n[0], 0.0])  # (1 + z.n, z x n)
    return q / np.linalg.norm(q)


def extrusion_half_depth(scene: Scene) -> float:
    """2D: half the z extent of the prisms standing in for circles, boxes and polygons: the
    largest in-plane half extent of any shape (bodies and statics), so prisms are about as deep as
    they are wide (a plate far thinner than wide would make the convex collision search of two
    prisms ill-conditioned, and no 2D quantity depends on the depth)."""
    half = 0.0
    for thing in (*scene.bodies, *scene.statics):
        lo, hi = thing.shape.bounding_box()
        half = max(half, float(np.max(np.abs(np.concatenate([lo, hi])))))
    return half if half > 0 else 1.0


@dataclass
class _BodyMap:
    """How one scene body sits in the MuJoCo model."""

    body_id: int
    qadr: int
    vadr: int
    # MuJoCo body frame relative to the declared frame: x_mj = x_decl + R_decl t, R_mj = R_decl P.
    t: np.ndarray  # (3,) or (2,)
    q_p: np.ndarray  # (4,) quaternion of P (identity unless aligned)
    com_mj: np.ndarray  # centre of mass in the MuJoCo body frame (3D) / in the body frame (2D)
    drag_linear: float  # total coefficients of all drag entries naming the body
    drag_angular: float
    linear_drag_per_step: bool
    angular_drag_per_step: bool


class MujocoModel:
    """One compiled MuJoCo model of one Scene, integrator and step: a session (session.py).

    ``set_initial_state()`` writes the scene's t = 0 state into ``data``; ``advance(n)`` steps;
    ``read_raw()`` is (qpos, qvel); ``convert(rows, t)`` turns such rows into crosscheck's
    convention; ``record(n, k, rows)`` is the fused fast path; ``settings()`` reads the settings
    back from the compiled model.
    """

    def __init__(self, scene: Scene, integrator: str, dt: float,
                 options: dict[str, Any] | None = None):
        if mujoco is None:  # pragma: no cover
            raise ImportError("mujoco is not installed")
        self.run_name = integrator
        # A fluid case runs as the mapped cylinder in a medium (scene/medium_map.py), its fluid
        # model named by the run: "rk4+ellipsoid".
        self.mapped: MappedCylinder | None = None
        model_name = None
        if scene.fluid is not None:
            integrator, model_name = split_run(integrator)
            if model_name not in MEDIUM_MODELS["mujoco"]:
                raise ValueError(f"a fluid case runs in MuJoCo as integrator+model, model one of "
                                 f"{list(MEDIUM_MODELS['mujoco'])}; got {self.run_name!r}")
            self.mapped = mapped_cylinder(scene)
        if integrator not in INTEGRATORS:
            raise ValueError(f"unknown MuJoCo integrator {integrator!r}; known: {INTEGRATORS}")
        self.scene = scene
        self.integrator = integrator
        self.dt = float(dt)
        self.options = engine_options(scene) if options is None else options
        if model_name is not None:
            self.options = dict(self.options, fluid_model=model_name)
        self.dim = scene.dimension
        self.aligned = bool(self.options["align_free"]) and self.dim == 3
        self.contact = bool(scene.effects.contact)
        self.medium = scene.effects.medium
        if self.mapped is not None:
            self.medium = Medium(density=self.mapped.fluid_density,
                                 viscosity=self.mapped.dynamic_viscosity)
        # The ellipsoid model acts on geoms (fluidshape="ellipsoid"), the inertia-box model on
        # the body's inertia alone.
        self.ellipsoid = self.medium is not None and self.options.get("fluid_model") == "ellipsoid"
        self._depth = extrusion_half_depth(scene) if self.contact and self.dim == 2 else 0.0
        self._pairs = []
        self.mjcf = self._mjcf()
        self.model = mujoco.MjModel.from_xml_string(self.mjcf)
        self.data = mujoco.MjData(self.model)
        self._configure()
        self._map_bodies()
        self._set_damping_and_loads()

    # -- model ----------------------------------------------------------------------------
    def _frame(self, body) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(t, q_P, inertial quaternion in the MuJoCo frame, principal moments) of a 3D body."""
        moments, axes = principal_moments(body.inertia)
        if np.linalg.det(axes) < 0:  # a proper rotation: flip one principal axis
            axes[:, 2] *= -1.0
        q_axes = matrix_to_quat(axes)
        if self.aligned:
            return np.asarray(body.com, float), q_axes, np.array([1.0, 0, 0, 0]), moments
        return np.zeros(3), np.array([1.0, 0, 0, 0]), q_axes, moments

    def _site_pos(self, body_index: int, local: np.ndarray) -> np.ndarray:
        """A declared body-frame point in its MuJoCo body frame."""
        body = self.scene.bodies[body_index]
        if self.dim == 2:
            return np.array([local[0], local[1], 0.0])
        t, q_p, _, _ = self._frame(body)
        return quat_to_matrix(q_p).T @ (np.asarray(local, float) - t)

    # -- contact geometry -----------------------------------------------------------------------
    def _geom(self, name: str, shape, pos, quat, assets: list[str],
              collision: str = 'contype="0" conaffinity="0"') -> str:
        """A geom (no mass: the compiler ignores geoms for inertia, inertiafromgeom is false) for
        a shape at (pos, quat) in its parent's frame, with ``collision``: its contype /
        conaffinity and contact values (the default collides with nothing)."""
        frame = f'pos="{_v(pos)}" quat="{_v(quat)}" {collision}'
        kind = shape.kind
        if self.dim == 3:
            if kind == "sphere":
                return f'<geom name="{name}" type="sphere" size="{_f(shape.radius)}" {frame}/>'
            if kind == "box":
                half = np.asarray(shape.size, float) / 2
                return f'<geom name="{name}" type="box" size="{_v(half)}" {frame}/>'
            if kind in ("capsule", "cylinder"):
                return (f'<geom name="{name}" type="{kind}" '
                        f'size="{_f(shape.radius)} {_f(shape.length / 2)}" {frame}/>')
            if kind == "mesh":
                # MuJoCo collides a mesh by its convex hull (qhull, computed by the compiler).
                assets.append(f'<mesh name="m_{name}" vertex="{_v(shape.vertices)}" '
                              f'face="{" ".join(str(int(i)) for i in np.ravel(shape.faces))}"/>')
                return f'<geom name="{name}" type="mesh" mesh="m_{name}" {frame}/>'
        else:
            depth = self._depth
            if kind == "circle":
                return (f'<geom name="{name}" type="cylinder" '
                        f'size="{_f(shape.radius)} {_f(depth)}" {frame}/>')
            if kind == "box":
                w, h = np.asarray(shape.size, float) / 2
                return f'<geom name="{name}" type="box" size="{_v([w, h, depth])}" {frame}/>'
            if kind == "polygon":
                v = np.asarray(shape.vertices, float)
                prism = np.concatenate([np.column_stack([v, np.full(len(v), -depth)]),
                                        np.column_stack([v, np.full(len(v), depth)])])
                # No faces: MuJoCo takes the convex hull of the vertices, here the prism itself.
                assets.append(f'<mesh name="m_{name}" vertex="{_v(prism)}"/>')
                return f'<geom name="{name}" type="mesh" mesh="m_{name}" {frame}/>'
        raise CaseError(self.scene.source, "shape", "a shape MuJoCo can collide", kind)

    def _contact_xml(self) -> tuple[dict[int, str], str, str, str]:
        """(geom per body index, world geoms, assets, <contact> section) of a contact scene.

        Every geom carries its material class's values and one contype bit per class, its
        conaffinity the bits of the classes it meets by MuJoCo's own collision
        (``collision_routes``): MuJoCo's broad phase finds those contacts and its geom rule gives
        them the pair values. Class pairs whose values MuJoCo's rule cannot give get one explicit
        ``<pair>`` per pair (an explicit pair also replaces MuJoCo's own contact of the same two
        geoms, measured on 4.0.0), and ``collide = false`` class pairs no bits in common.
        """
        scene = self.scene
        classes = material_classes(scene)
        routes = collision_routes(scene, self.dt)
        self._classes, self._routes = classes, routes
        bits = classes.k <= MAX_CLASS_BITS
        affinity = [0] * classes.k
        for (i, j), route in routes.items():
            if route == "dynamic":
                affinity[i] |= 1 << j
                affinity[j] |= 1 << i

        def collision(name: str) -> str:
            c = classes.of[name]
            condim, friction, solref = mujoco_values(classes.values[c][c], self.dt)
            ct, ca = (1 << c, affinity[c]) if bits else (0, 0)
            return (f'contype="{ct}" conaffinity="{ca}" condim="{condim}" '
                    f'friction="{_v([friction[0], friction[2], friction[3]])}" '
                    f'solref="{_v(solref)}" solimp="{_v(SOLIMP)}" margin="0" gap="0"')

        assets: list[str] = []
        body_geoms: dict[int, str] = {}
        ident = np.array([1.0, 0.0, 0.0, 0.0])
        self._geom_of: dict[str, str] = {}
        for i, body in enumerate(scene.bodies):
            if self.dim == 3:
                t, q_p, _, _ = self._frame(body)
                pos = -(quat_to_matrix(q_p).T @ t)
                quat = quat_conj(q_p)
            else:
                # The 2D MuJoCo body frame coincides with the declared body frame in the plane.
                pos, quat = np.zeros(3), ident
            body_geoms[i] = self._geom(f"g{i}", body.shape, pos, quat, assets,
                                       collision(body.name))
            self._geom_of[body.name] = f"g{i}"
        world: list[str] = []
        for k, static in enumerate(scene.statics):
            if self.dim == 3:
                pos, quat = np.asarray(static.position, float), np.asarray(static.orientation,
                                                                             float)
            else:
                pos = np.array([static.position[0], static.position[1], 0.0])
                a = float(np.ravel(static.orientation)[0])
                quat = np.array([math.cos(a / 2), 0.0, 0.0, math.sin(a / 2)])
            world.append(self._geom(f"s{k}", static.shape, pos, quat, assets,
                                    collision(static.name)))
            self._geom_of[static.name] = f"s{k}"
        if scene.ground is not None:
            n = np.asarray(scene.ground.normal, float)
            if self.dim == 2:
                n = np.array([n[0], n[1], 0.0])  # the ground line: a plane containing z
            n = n / np.linalg.norm(n)
            # A plane geom is its frame's x-y plane, its normal the frame's +z.
            world.append(f'<geom name="ground" type="plane" size="0 0 1" '
                         f'pos="{_v(n * scene.ground.offset)}" quat="{_v(_quat_z_to(n))}" '
                         f'{collision(GROUND)}/>')
            self._geom_of[GROUND] = "ground"
        pairs = []
        self._pairs = []
        for (i, j), route in routes.items():
            if route != "explicit":
                continue
            pm = classes.values[i][j]
            condim, friction, solref = mujoco_values(pm, self.dt)
            for a, b in classes.pairs_between(i, j):
                pair = _contact_pair(classes, a, b, pm)
                g1, g2 = self._geom_of[pair.a], self._geom_of[pair.b]
                pairs.append(f'<pair name="p{len(self._pairs)}" geom1="{g1}" geom2="{g2}" '
                             f'condim="{condim}" friction="{_v(friction)}" '
                             f'solref="{_v(solref)}" solimp="{_v(SOLIMP)}" margin="0" '
                             'gap="0"/>')
                self._pairs.append(pair)
        contact = f"<contact>{''.join(pairs)}</contact>" if pairs else ""
        asset = f"<asset>{''.join(assets)}</asset>" if assets else ""
        return body_geoms, "".join(world), asset, contact

    def _mjcf(self) -> str:
        scene = self.scene
        sites: dict[int, list[str]] = {i: [] for i in range(len(scene.bodies))}
        world_sites: list[str] = []
        tendons: list[str] = []
        for k, spring in enumerate(scene.effects.springs):
            pa = self._site_pos(spring.body_a, spring.attach_a)
            sites[spring.body_a].append(f'<site name="sa{k}" pos="{_v(pa)}"/>')
            if spring.body_b is None:
                anchor = np.asarray(spring.attach_b, float)
                if self.dim == 2:
                    anchor = np.array([anchor[0], anchor[1], 0.0])
                world_sites.append(f'<site name="sb{k}" pos="{_v(anchor)}"/>')
            else:
                pb = self._site_pos(spring.body_b, spring.attach_b)
                sites[spring.body_b].append(f'<site name="sb{k}" pos="{_v(pb)}"/>')
            # Two equal springlength values: no dead band, rest length exactly L0 (a single -1
            # would make the compiler take the length at qpos0).
            tendons.append(
                f'<spatial name="t{k}" stiffness="{_f(spring.stiffness)}" '
                f'damping="{_f(spring.damping)}" '
                f'springlength="{_f(spring.rest_length)} {_f(spring.rest_length)}">'
                f'<site site="sa{k}"/><site site="sb{k}"/></spatial>')
        body_geoms: dict[int, str] = {}
        world_geoms = asset = contact = ""
        if self.contact:
            body_geoms, world_geoms, asset, contact = self._contact_xml()
        elif self.ellipsoid:
            body_geoms, asset = self._fluid_geoms()
        if self.ellipsoid:
            coef = _v(self.options.get("fluidcoef", FLUIDCOEF_DEFAULT))
            fluid = f'<geom fluidshape="ellipsoid" fluidcoef="{coef}" '
            body_geoms = {i: g.replace("<geom ", fluid, 1) for i, g in body_geoms.items()}
        gravcomp = self._gravcomp()
        bodies = []
        for i, body in enumerate(scene.bodies):
            if self.dim == 3:
                _, _, q_in, moments = self._frame(body)
                com_mj = np.zeros(3) if self.aligned else np.asarray(body.com, float)
                joints = f'<freejoint name="j{i}"/>'
                inertial = (f'<inertial pos="{_v(com_mj)}" quat="{_v(q_in)}" '
                            f'mass="{_f(body.mass)}" diaginertia="{_v(moments)}"/>')
            else:
                c = np.array([body.com[0], body.com[1], 0.0])
                moment = body.moment
                joints = (f'<joint name="j{i}x" type="slide" axis="1 0 0"/>'
                          f'<joint name="j{i}y" type="slide" axis="0 1 0"/>'
                          f'<joint name="j{i}r" type="hinge" axis="0 0 1" pos="{_v(c)}"/>')
                mass, moments = body.mass, [moment, moment, moment]
                if self.mapped is not None:
                    # The cylinder's own mass and moments: the inertia-box model reads its box
                    # from them (half sizes sqrt(3) R / 2, sqrt(3) R / 2, L / 2).
                    mass, moments = self.mapped.mass, list(self.mapped.inertia)
                inertial = (f'<inertial pos="{_v(c)}" mass="{_f(mass)}" '
                            f'diaginertia="{_v(moments)}"/>')
            buoy = f' gravcomp="{_f(gravcomp[i])}"' if gravcomp[i] != 0.0 else ""
            bodies.append(f'<body name="b{i}"{buoy}>{joints}{inertial}{body_geoms.get(i, "")}'
                          f'{"".join(sites[i])}</body>')
        tendon_xml = f"<tendon>{''.join(tendons)}</tendon>" if tendons else ""
        size = (f'<size memory="{arena_bytes(len(scene.bodies))}"/>' if self.contact else "")
        # inertiafromgeom false and no bounds: the inertial is used exactly as written.
        return (
            '<mujoco model="crosscheck">'
            '<compiler angle="radian" inertiafromgeom="false" boundmass="0" boundinertia="0" '
            'balanceinertia="false" alignfree="false"/>'
            f'{size}{asset}<worldbody>{world_geoms}{"".join(world_sites)}{"".join(bodies)}</worldbody>'
            f"{contact}{tendon_xml}</mujoco>"
        )

    def _fluid_geoms(self) -> tuple[dict[int, str], str]:
        """One massless, non-colliding geom per body, its shape at its place in the MuJoCo body
        frame: what the ellipsoid fluid model acts on (scenes without contact have no geoms)."""
        assets: list[str] = []
        geoms = {}
        if self.mapped is not None:  # the cylinder along z, at the disc's centre
            cyl = self.mapped
            return {0: (f'<geom name="g0" type="cylinder" size="{_f(cyl.radius)} '
                        f'{_f(cyl.length / 2)}" pos="0 0 0" contype="0" conaffinity="0"/>')}, ""
        for i, body in enumerate(self.scene.bodies):
            t, q_p, _, _ = self._frame(body)
            geoms[i] = self._geom(f"g{i}", body.shape, -(quat_to_matrix(q_p).T @ t),
                                  quat_conj(q_p), assets)
        return geoms, (f"<asset>{''.join(assets)}</asset>" if assets else "")

    def _gravcomp(self) -> np.ndarray:
        """Per body, the buoyancy as MuJoCo's gravity compensation: gravcomp = rho_f V / m (an
        upward force rho_f V |g| at the centre of mass). MuJoCo's fluid models apply no buoyancy
        (measured: a body at rest in a medium of density 1000 accelerates at exactly g)."""
        out = np.zeros(len(self.scene.bodies))
        if self.medium is None or self.medium.density == 0.0:
            return out
        if self.mapped is not None:
            return np.array([self.mapped.gravcomp])
        from crosscheck.quantities import body_volumes

        return self.medium.density * body_volumes(self.scene) / self.scene.masses

    def _configure(self) -> None:
        m = self.model
        opt = m.opt
        opt.timestep = self.dt
        opt.integrator = int(getattr(mujoco.mjtIntegrator, _MJ_INTEGRATOR[self.integrator]))
        g = self.scene.effects.gravity_vector(self.dim)
        opt.gravity[:] = [g[0], g[1], g[2] if self.dim == 3 else 0.0]
        # Explicitly zero what could add forces the scene did not ask for.
        opt.wind[:] = 0.0
        opt.magnetic[:] = 0.0
        # The medium, if any: MuJoCo's fluid forces (the inertia-box model, or the ellipsoid
        # model on the geoms that carry fluidshape="ellipsoid").
        opt.density = self.medium.density if self.medium is not None else 0.0
        opt.viscosity = self.medium.viscosity if self.medium is not None else 0.0
        opt.jacobian = int(getattr(mujoco.mjtJacobian,
                                   f"mjJAC_{self.options['jacobian'].upper()}"))
        dis = mujoco.mjtDisableBit
        flags = int(opt.disableflags)
        if self.contact:
            # Contacts: the geoms' contype / conaffinity bits and the explicit pairs.
            flags &= ~int(dis.mjDSBL_CONTACT)
            c = CONTACT_OPTIONS
            opt.cone = int(getattr(mujoco.mjtCone, c["cone"]))
            opt.impratio = c["impratio"]
            opt.noslip_iterations = c["noslip_iterations"]
            opt.solver = int(getattr(mujoco.mjtSolver,
                                     f"mjSOL_{self.options['solver'].upper()}"))
            opt.iterations = c["iterations"]
            opt.tolerance = c["tolerance"]
            opt.ls_iterations = c["ls_iterations"]
        else:
            flags |= int(dis.mjDSBL_CONTACT)
        # A blow-up must stay a blow-up (NaN reaches the recorder), not a silent reset to qpos0.
        flags |= int(dis.mjDSBL_AUTORESET)
        if not self.options["eulerdamp"]:
            flags |= int(dis.mjDSBL_EULERDAMP)
        # Springs and dampers are how tendons and joint damping act: keep them on.
        flags &= ~(int(dis.mjDSBL_SPRING) | int(dis.mjDSBL_DAMPER) | int(dis.mjDSBL_GRAVITY))
        opt.disableflags = flags

    def _map_bodies(self) -> None:
        m = self.model
        scene = self.scene
        lin = np.zeros(len(scene.bodies))
        ang = np.zeros(len(scene.bodies))
        for drag in scene.effects.drag:
            for b in drag.bodies:
                lin[b] += drag.linear
                ang[b] += drag.angular
        per_step_all = self.options["drag"] == "per_step"
        self.bodies: list[_BodyMap] = []
        for i, body in enumerate(scene.bodies):
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"b{i}")
            if self.dim == 3:
                jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"j{i}")
                t, q_p, _, _ = self._frame(body)
                com_mj = np.zeros(3) if self.aligned else np.asarray(body.com, float)
                # Joint damping on the translational dofs damps the origin's velocity: exact only
                # when the origin is the centre of mass.
                lin_step = lin[i] > 0 and (per_step_all or bool(np.any(com_mj != 0.0)))
            else:
                jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"j{i}x")
                t, q_p = np.zeros(2), np.array([1.0, 0, 0, 0])
                com_mj = np.asarray(body.com, float)
                lin_step = lin[i] > 0 and per_step_all
            self.bodies.append(_BodyMap(
                body_id=bid, qadr=int(m.jnt_qposadr[jid]), vadr=int(m.jnt_dofadr[jid]), t=t,
                q_p=q_p, com_mj=com_mj, drag_linear=float(lin[i]), drag_angular=float(ang[i]),
                linear_drag_per_step=bool(lin_step),
                angular_drag_per_step=bool(ang[i] > 0 and per_step_all)))
        nb = len(self.bodies)
        if self.dim == 3:
            self._qidx = np.array([[b.qadr + k for k in range(7)] for b in self.bodies]).reshape(
                nb, 7)
            self._vidx = np.array([[b.vadr + k for k in range(6)] for b in self.bodies]).reshape(
                nb, 6)
        else:
            self._qidx = np.array([[b.qadr + k for k in range(3)] for b in self.bodies]).reshape(
                nb, 3)
            self._vidx = np.array([[b.vadr + k for k in range(3)] for b in self.bodies]).reshape(
                nb, 3)
        self._com_mj = np.array([b.com_mj for b in self.bodies]).reshape(nb, self.dim)
        self._q_p = np.array([b.q_p for b in self.bodies]).reshape(nb, 4)
        self._t = np.array([b.t for b in self.bodies]).reshape(nb, self.dim)

    def _set_damping_and_loads(self) -> None:
        m, d = self.model, self.data
        # Joint damping is set on the compiled model, per dof (a free joint's XML damping is one
        # value for all six dofs). MuJoCo reads dof_damping at run time.
        m.dof_damping[:] = 0.0
        m.dof_frictionloss[:] = 0.0
        m.dof_armature[:] = 0.0
        for b in self.bodies:
            if self.dim == 3:
                if not b.linear_drag_per_step:
                    m.dof_damping[b.vadr:b.vadr + 3] = b.drag_linear
                if not b.angular_drag_per_step:
                    m.dof_damping[b.vadr + 3:b.vadr + 6] = b.drag_angular
            else:
                if not b.linear_drag_per_step:
                    m.dof_damping[b.vadr:b.vadr + 2] = b.drag_linear
                if not b.angular_drag_per_step:
                    m.dof_damping[b.vadr + 2] = b.drag_angular
        # Constant loads: one xfrc_applied row per body, force at the centre of mass (xipos) and
        # torque, both world frame. mj_step never clears xfrc_applied, so setting it once is enough.
        self._loads = np.zeros((m.nbody, 6))
        for load in self.scene.effects.loads:
            bid = self.bodies[load.body].body_id
            if self.dim == 3:
                self._loads[bid, :3] += load.force
                self._loads[bid, 3:] += load.torque
            else:
                self._loads[bid, :2] += load.force
                self._loads[bid, 5] += load.torque[0]
        d.xfrc_applied[:] = self._loads
        self._has_loads = bool(np.any(self._loads))
        self._step_bodies = [i for i, b in enumerate(self.bodies)
                             if b.linear_drag_per_step or b.angular_drag_per_step]
        self.per_step_forces = bool(self._step_bodies)
        if self.per_step_forces:
            sb = self._step_bodies
            self._sb_ids = np.array([self.bodies[i].body_id for i in sb])
            self._sb_lin = np.array([self.bodies[i].drag_linear
                                     * self.bodies[i].linear_drag_per_step for i in sb])[:, None]
            self._sb_ang = np.array([self.bodies[i].drag_angular
                                     * self.bodies[i].angular_drag_per_step for i in sb])[:, None]
            self._sb_q = self._qidx[sb]
            self._sb_v = self._vidx[sb]
            self._sb_c = self._com_mj[sb]

    # -- state ----------------------------------------------------------------------------
    def set_initial_state(self) -> None:
        """Write the scene's t = 0 state (declared frames, COM velocity, world omega) to data."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.xfrc_applied[:] = self._loads
        for b, body in zip(self.bodies, self.scene.bodies, strict=True):
            w = np.asarray(body.angular_velocity, float)
            if self.dim == 3:
                r = quat_to_matrix(body.orientation)
                q_mj = quat_mul(body.orientation, b.q_p) if self.aligned else np.asarray(
                    body.orientation, float)
                r_mj = quat_to_matrix(q_mj)
                x_mj = np.asarray(body.position, float) + r @ b.t
                rc = r_mj @ b.com_mj  # centre of mass relative to the MuJoCo origin, world
                d.qpos[b.qadr:b.qadr + 3] = x_mj
                d.qpos[b.qadr + 3:b.qadr + 7] = q_mj
                # qvel[0:3] is the MuJoCo origin's velocity, qvel[3:6] the body-local omega.
                d.qvel[b.vadr:b.vadr + 3] = np.asarray(body.velocity, float) - np.cross(w, rc)
                d.qvel[b.vadr + 3:b.vadr + 6] = r_mj.T @ w
            else:
                # Slides carry the centre of mass minus its body-frame offset; the hinge, through
                # the centre of mass, the angle.
                d.qpos[b.qadr:b.qadr + 2] = body.com_world() - b.com_mj
                d.qpos[b.qadr + 2] = body.angle
                d.qvel[b.vadr:b.vadr + 2] = body.velocity
                d.qvel[b.vadr + 2] = w[0]
        # Derived arrays consistent with the state (not needed by the reader, which uses qpos and
        # qvel only, but anyone inspecting data sees the set state).
        mujoco.mj_forward(m, d)

    def convert_q(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, ...]:
        """(T, nq), (T, nv) samples -> com (T,N,d), rot (T,N,4)|(T,N), vel (T,N,d), omega."""
        qpos = np.asarray(qpos, float).reshape(-1, self.model.nq)
        qvel = np.asarray(qvel, float).reshape(-1, self.model.nv)
        q = qpos[:, self._qidx]  # (T, N, 7) or (T, N, 3)
        v = qvel[:, self._vidx]
        if self.dim == 2:
            com = q[..., :2] + self._com_mj
            return com, q[..., 2], v[..., :2].copy(), v[..., 2].copy()
        quat = q[..., 3:7] / np.linalg.norm(q[..., 3:7], axis=-1, keepdims=True)
        r_mj = quat_to_matrix(quat)  # (T, N, 3, 3), MuJoCo frame to world
        omega = np.einsum("tnij,tnj->tni", r_mj, v[..., 3:6])  # body-local -> world
        rc = np.einsum("tnij,nj->tni", r_mj, self._com_mj)
        com = q[..., 0:3] + rc
        vel = v[..., 0:3] + np.cross(omega, rc)  # origin velocity -> centre-of-mass velocity
        if self.aligned:
            quat = quat_mul(quat, quat_conj(self._q_p)[None])
        return com, quat, vel, omega

    def state(self) -> tuple[np.ndarray, ...]:
        """The current state of data, (N, ...) arrays in crosscheck's convention."""
        com, rot, vel, omega = self.convert_q(self.data.qpos[None], self.data.qvel[None])
        return com[0], rot[0], vel[0], omega[0]

    # -- session -------------------------------------------------------------------------
    @property
    def row_width(self) -> int:
        return self.model.nq + self.model.nv

    def read_raw(self) -> np.ndarray:
        return np.concatenate([self.data.qpos, self.data.qvel])

    def convert(self, rows, t=None):
        """(T, nq + nv) rows -> ((com, rot, vel, omega), no extras)."""
        rows = np.asarray(rows, float).reshape(-1, self.row_width)
        return self.convert_q(rows[:, :self.model.nq], rows[:, self.model.nq:]), {}

    def set_state(self, com, rot, vel, omega) -> None:
        """Place a normalised state: the inverse of convert for one sample."""
        d = self.data
        for i, b in enumerate(self.bodies):
            w = np.asarray(omega[i], float)
            if self.dim == 3:
                q_decl = np.asarray(rot[i], float)
                q_mj = quat_mul(q_decl, b.q_p) if self.aligned else q_decl
                r_mj = quat_to_matrix(q_mj)
                rc = r_mj @ b.com_mj
                d.qpos[b.qadr:b.qadr + 3] = np.asarray(com[i], float) - rc
                d.qpos[b.qadr + 3:b.qadr + 7] = q_mj
                d.qvel[b.vadr:b.vadr + 3] = np.asarray(vel[i], float) - np.cross(w, rc)
                d.qvel[b.vadr + 3:b.vadr + 6] = r_mj.T @ w
            else:
                d.qpos[b.qadr:b.qadr + 2] = np.asarray(com[i], float) - b.com_mj
                d.qpos[b.qadr + 2] = float(rot[i])
                d.qvel[b.vadr:b.vadr + 2] = vel[i]
                d.qvel[b.vadr + 2] = float(omega[i])
        mujoco.mj_forward(self.model, d)

    def check(self) -> list[str]:
        return []

    def close(self) -> None:
        pass

    def _apply_step_forces(self) -> None:
        """Drag with no exact MuJoCo mechanism, from the state at the start of the step."""
        d = self.data
        q = d.qpos[self._sb_q]
        v = d.qvel[self._sb_v]
        force = self._loads[self._sb_ids].copy()
        if self.dim == 3:
            r = quat_to_matrix(q[:, 3:7])
            w = np.einsum("nij,nj->ni", r, v[:, 3:6])
            vcom = v[:, 0:3] + np.cross(w, np.einsum("nij,nj->ni", r, self._sb_c))
            force[:, :3] -= self._sb_lin * vcom
            force[:, 3:] -= self._sb_ang * w
        else:
            force[:, :2] -= self._sb_lin * v[:, 0:2]
            force[:, 5] -= self._sb_ang[:, 0] * v[:, 2]
        d.xfrc_applied[self._sb_ids] = force

    def advance(self, nsteps: int) -> None:
        """nsteps steps: one mj_step call when no force is recomputed per step. Raises
        StepFailure once any of MuJoCo's warning counters is set (they start at zero)."""
        if nsteps <= 0:
            return
        m, d = self.model, self.data
        if not self.per_step_forces:
            mujoco.mj_step(m, d, nsteps)
        else:
            step, apply = mujoco.mj_step, self._apply_step_forces
            for _ in range(nsteps):
                apply()
                step(m, d)
        if d.warning.number.any():
            raise StepFailure(_UNSTABLE)

    @property
    def fused(self) -> bool:
        """True when ``record`` (the compiled loop) is used by the driver."""
        return (not self.per_step_forces and self.options["stepping"] == "compiled"
                and _native_stepper()[0] is not None)

    @property
    def stepping_mode(self) -> str:
        if self.per_step_forces:
            return "python loop: per-step xfrc_applied drag, mj_step"
        if self.fused:
            return ("compiled loop (numba) calling mj_step(m, d) steps_per_sample times per "
                    "sample and copying qpos, qvel; cost timed on mj_step(m, d, nstep)")
        fallback = "" if self.options["stepping"] == "nstep" else (
            f" (compiled loop unavailable: {_native_stepper()[2]})")
        return "mj_step(m, d, nstep=steps_per_sample) per sample" + fallback

    def record(self, n: int, k: int, rows: np.ndarray) -> tuple[int, str | None]:
        """The fused fast path: the rows the generic loop would fill, from a compiled loop.

        Stops at the first sample after whose steps one of MuJoCo's warning counters is set,
        as ``advance`` does; returns (valid rows, failure reason or None).
        """
        m, d = self.model, self.data
        native, step, _ = _native_stepper()
        qpos = np.empty((n, m.nq))
        qvel = np.empty((n, m.nv))
        qpos[0], qvel[0] = d.qpos, d.qvel
        # d.qpos, d.qvel and d.warning.number are views of data's own memory.
        count = native.mujoco_record(step, m._address, d._address, d.qpos, d.qvel,
                                     d.warning.number, k, qpos, qvel)
        rows[:, :m.nq] = qpos
        rows[:, m.nq:] = qvel
        if count == n:
            return n, None
        return count, _UNSTABLE

    # -- read back ------------------------------------------------------------------------
    def contact_settings(self) -> dict[str, Any]:
        """Contact settings read back from the compiled model: global options, every geom, every
        pair (the scene's names and values next to what MuJoCo holds)."""
        m = self.model
        opt = m.opt
        gtypes = {int(v): k.replace("mjGEOM_", "").lower()
                  for k, v in mujoco.mjtGeom.__members__.items()}
        geoms = []
        for g in range(m.ngeom):
            entry = {
                "name": _name(m, mujoco.mjtObj.mjOBJ_GEOM, g),
                "type": gtypes.get(int(m.geom_type[g]), str(int(m.geom_type[g]))),
                "body": _name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g])),
                "size": np.array(m.geom_size[g]).tolist(),
                "contype": int(m.geom_contype[g]),
                "conaffinity": int(m.geom_conaffinity[g]),
            }
            if int(m.geom_type[g]) == int(mujoco.mjtGeom.mjGEOM_MESH):
                mid = int(m.geom_dataid[g])
                entry["collision"] = (
                    f"convex hull of the mesh: {int(m.mesh_graph[m.mesh_graphadr[mid]])} hull "
                    f"vertices of {int(m.mesh_vertnum[mid])}" if m.mesh_graphadr[mid] >= 0
                    else "convex hull of the mesh")
            geoms.append(entry)
        gid = {_name(m, mujoco.mjtObj.mjOBJ_GEOM, g): g for g in range(m.ngeom)}
        first_pair = {}
        for k, pair in enumerate(self._pairs):
            first_pair.setdefault((pair.a, pair.b), k)
        pairs = []
        classes = self._classes
        # One entry per class pair: its route, how many pairs it holds, one of them by name, and
        # the values MuJoCo holds for it (an explicit pair's row, or the two geoms' values).
        for (i, j), route in self._routes.items():
            pair = _contact_pair(classes, *next(classes.pairs_between(i, j)),
                                 classes.values[i][j])
            entry = {"a": pair.a, "b": pair.b, "kind": pair.kind, "count": classes.count(i, j),
                     "route": {"dynamic": "MuJoCo's collision (contype / conaffinity), the "
                                          "values on both geoms",
                               "explicit": "one explicit <pair> each",
                               "off": "collide = false: no contype / conaffinity bit in "
                                      "common"}[route],
                     "source": pair.material.source, "restitution": pair.material.restitution,
                     "restitution_model": _restitution_model(pair.material.restitution)}
            g1, g2 = gid[self._geom_of[pair.a]], gid[self._geom_of[pair.b]]
            entry["geoms"] = [self._geom_of[pair.a], self._geom_of[pair.b]]
            if route == "explicit":
                k = first_pair[(pair.a, pair.b)]
                entry.update(
                    condim=int(m.pair_dim[k]), friction=np.array(m.pair_friction[k]).tolist(),
                    solref=np.array(m.pair_solref[k]).tolist(),
                    solreffriction=np.array(m.pair_solreffriction[k]).tolist(),
                    solimp=np.array(m.pair_solimp[k]).tolist(), margin=float(m.pair_margin[k]),
                    gap=float(m.pair_gap[k]))
            elif route == "dynamic":
                # Both geoms hold the same values (collision_routes), so MuJoCo's combination
                # is those values; read them from the model, and refuse to report a mismatch.
                held = [(int(m.geom_condim[g]), tuple(m.geom_friction[g]),
                         tuple(m.geom_solref[g]), tuple(m.geom_solimp[g]),
                         float(m.geom_margin[g]), float(m.geom_gap[g])) for g in (g1, g2)]
                if held[0] != held[1]:
                    raise RuntimeError(f"MuJoCo geoms {entry['geoms']} hold different contact "
                                       f"values {held}: the dynamic route is wrong")
                condim, fr, solref, solimp, margin, gap = held[0]
                entry.update(condim=condim, friction=[fr[0], fr[0], fr[1], fr[2], fr[2]],
                             solref=list(solref), solreffriction=[0.0, 0.0],
                             solimp=list(solimp), margin=margin, gap=gap)
            pairs.append(entry)
        disabled = [[p["a"], p["b"]] for p, r in zip(pairs, self._routes.values(), strict=True)
                    if r == "off"]
        timeconst = SOLREF_INELASTIC[0]
        return {
            "cone": mujoco.mjtCone(int(opt.cone)).name,
            "impratio": float(opt.impratio),
            "noslip_iterations": int(opt.noslip_iterations),
            "solver": mujoco.mjtSolver(int(opt.solver)).name,
            "iterations": int(opt.iterations),
            "tolerance": float(opt.tolerance),
            "ls_iterations": int(opt.ls_iterations),
            "refsafe": not (int(opt.disableflags) & int(mujoco.mjtDisableBit.mjDSBL_REFSAFE)),
            "inelastic_timeconst_in_force": max(timeconst, 2.0 * float(opt.timestep)),
            "npair": int(m.npair),
            "arena_bytes": int(m.narena),
            "material_classes": [list(c) if len(c) <= 8 else [*c[:8], f"... {len(c)} in all"]
                                 for c in classes.members],
            "geoms": geoms,
            "pairs": pairs,
            "collide_false": disabled,
            "extrusion_half_depth_2d": self._depth if self.dim == 2 else None,
        }

    def medium_settings(self) -> dict[str, Any]:
        """The fluid model as compiled: per body the geometry MuJoCo derives and the force terms
        it applies (docs/engines.md, "Medium"), the buoyancy route read back."""
        from crosscheck.quantities import body_volumes

        m = self.model
        rho, mu = float(m.opt.density), float(m.opt.viscosity)
        volumes = (np.array([self.mapped.volume]) if self.mapped is not None
                   else body_volumes(self.scene))
        bodies = []
        for k, (b, body) in enumerate(zip(self.bodies, self.scene.bodies, strict=True)):
            bid = b.body_id
            entry: dict[str, Any] = {
                "name": body.name,
                "shape_volume": float(volumes[k]),
                "gravcomp": float(m.body_gravcomp[bid]),
                "buoyancy_N": float(m.body_gravcomp[bid] * m.body_mass[bid]
                                    * np.linalg.norm(m.opt.gravity)),
            }
            if self.ellipsoid:
                gid = int(m.body_geomadr[bid])
                fl = np.array(m.geom_fluid[gid])
                semi = _geom_semi_axes(m, gid)
                entry.update({
                    "model": "ellipsoid",
                    "fluidcoef": fl[1:6].tolist(),
                    "semi_axes": semi.tolist(),
                    "ellipsoid_volume": float(4.0 / 3.0 * np.pi * np.prod(semi)),
                    "viscous_force_coefficient": float(6 * np.pi * mu * np.mean(semi)),
                    "viscous_torque_coefficient": float(8 * np.pi * mu * np.mean(semi) ** 3),
                    "added_mass_per_density": fl[6:9].tolist(),
                    "added_inertia_per_density": fl[9:12].tolist(),
                })
            else:
                r = _inertia_box_half_sizes(float(m.body_mass[bid]), np.array(m.body_inertia[bid]))
                r_eq = float(np.mean(r))
                entry.update({
                    "model": "inertia_box",
                    "box_half_sizes": r.tolist(),
                    "box_volume": float(8.0 * np.prod(r)),
                    "box_to_shape_volume": float(8.0 * np.prod(r) / volumes[k]),
                    "r_eq": r_eq,
                    "viscous_force_coefficient": float(6 * np.pi * mu * r_eq),
                    "viscous_torque_coefficient": float(8 * np.pi * mu * r_eq ** 3),
                    "quadratic_force_coefficients": [float(2 * rho * r[(i + 1) % 3]
                                                           * r[(i + 2) % 3]) for i in range(3)],
                })
            bodies.append(entry)
        terms = ("ellipsoid: f = -rho [C_blunt A_proj + C_slender (pi r_max r_mid - A_proj)] |v| v"
                 " - 6 pi mu r_D v + C_M rho V w x v + (m_A v) x w + Kutta lift; torque -8 pi mu "
                 "r_D^3 w and the angular drag; no -m_A dv/dt" if self.ellipsoid else
                 "inertia box: f_i = -2 rho r_j r_k |v_i| v_i - 6 pi mu r_eq v_i, torque_i = "
                 "-rho r_i (r_j^4 + r_k^4) |w_i| w_i / 2 - 8 pi mu r_eq^3 w_i (body inertial axes)")
        return {"model": "ellipsoid" if self.ellipsoid else "inertia_box",
                "density": rho, "viscosity": mu, "terms": terms,
                "buoyancy": "body gravcomp = rho V / m, V the shape's volume (MuJoCo's fluid "
                            "models apply none)",
                "added_mass": "none applied (no -m_A dv/dt term in either model)",
                "wind": np.array(m.opt.wind).tolist(), "bodies": bodies}

    def _mapping(self) -> dict[str, Any]:
        cyl = self.mapped
        return {"mapping": _mapping_text(), "model": self.options["fluid_model"],
                "radius": cyl.radius, "length": cyl.length,
                "length_in_radii": cyl.length / cyl.radius, "mass": cyl.mass,
                "principal_moments": list(cyl.inertia), "gravcomp": cyl.gravcomp,
                "density": cyl.fluid_density, "viscosity": cyl.dynamic_viscosity,
                "not_modelled": "added mass in the acceleration, walls, wake, Reynolds-number "
                                "dependence of the drag (docs/engines.md)"}

    def effective(self, arrays=None) -> dict[str, Any]:
        """Settings read back from the compiled model, not from what was asked for."""
        m, d = self.model, self.data
        opt = m.opt
        dis = [name for name, bit in mujoco.mjtDisableBit.__members__.items()
               if name != "mjNDISABLE" and int(opt.disableflags) & int(bit)]
        ena = [name for name, bit in mujoco.mjtEnableBit.__members__.items()
               if name != "mjNENABLE" and int(opt.enableflags) & int(bit)]
        integ = mujoco.mjtIntegrator(int(opt.integrator)).name
        bodies = []
        for b, body in zip(self.bodies, self.scene.bodies, strict=True):
            bid = b.body_id
            moments = np.array(m.body_inertia[bid])
            r_i = quat_to_matrix(np.array(m.body_iquat[bid]))
            inertia_mj = r_i @ np.diag(moments) @ r_i.T  # about the COM, MuJoCo body axes
            dofs = slice(b.vadr, b.vadr + (6 if self.dim == 3 else 3))
            entry: dict[str, Any] = {
                "name": body.name,
                "mass": float(m.body_mass[bid]),
                "com_mujoco_frame": np.array(m.body_ipos[bid]).tolist(),
                "principal_moments": moments.tolist(),
                "dof_damping": np.array(m.dof_damping[dofs]).tolist(),
                "linear_drag": ("per-step xfrc_applied" if b.linear_drag_per_step
                                else "joint damping" if b.drag_linear > 0 else "none"),
                "angular_drag": ("per-step xfrc_applied" if b.angular_drag_per_step
                                 else "joint damping" if b.drag_angular > 0 else "none"),
            }
            if self.dim == 3:
                p = quat_to_matrix(b.q_p)
                declared = p @ inertia_mj @ p.T  # back to declared body axes
                ref = np.asarray(body.inertia, float)
                entry["joint"] = "free"
                entry["frame"] = "aligned (centre of mass, principal axes)" if self.aligned \
                    else "declared body frame"
                entry["inertia_rel_error"] = float(np.max(np.abs(declared - ref))
                                                   / np.max(np.abs(ref)))
            else:
                entry["joint"] = "planar: slide x, slide y, hinge z through the centre of mass"
                want = self.mapped.inertia[2] if self.mapped is not None else body.moment
                entry["inertia_rel_error"] = float(abs(moments[2] - want) / want)
            bodies.append(entry)
        springs = [{
            "mechanism": "spatial tendon",
            "stiffness": float(np.ravel(m.tendon_stiffness[k])[0]),
            "damping": float(m.tendon_damping[k]),
            "springlength": np.array(m.tendon_lengthspring[k]).tolist(),
        } for k in range(m.ntendon)]
        warnings = {mujoco.mjtWarning(k).name: int(d.warning[k].number)
                    for k in range(int(mujoco.mjtWarning.mjNWARNING)) if d.warning[k].number}
        return {
            "timestep": float(opt.timestep),
            "integrator": integ,
            "gravity": np.array(opt.gravity).tolist(),
            "wind": np.array(opt.wind).tolist(),
            "magnetic": np.array(opt.magnetic).tolist(),
            "density": float(opt.density),
            "viscosity": float(opt.viscosity),
            "jacobian": mujoco.mjtJacobian(int(opt.jacobian)).name,
            "disableflags": dis,
            "enableflags": ena,
            "ngeom": int(m.ngeom),
            "bodies": bodies,
            "springs": springs,
            "loads": "constant xfrc_applied (force at the centre of mass, world torque)"
                     if self.scene.effects.loads else "none",
            "stepping": self.stepping_mode,
            "contact": self.contact_settings() if self.contact else "disabled (mjDSBL_CONTACT)",
            "medium": self.medium_settings() if self.medium is not None else "none",
            "fluid_case": self._mapping() if self.mapped is not None else "none",
            "warnings": warnings,
            "options": dict(self.options),
        }


def _mapping_text() -> str:
    return (f"the fluid case's disc as a cylinder of the same radius and density along z, "
            f"{LENGTH_IN_RADII:g} radii long, in a medium of the fluid's density and dynamic "
            "viscosity (scene/medium_map.py); masses and forces scale with the length, "
            "velocities compare directly")


def _inertia_box_half_sizes(mass: float, moments: np.ndarray) -> np.ndarray:
    """MuJoCo's equivalent inertia box: r_i = sqrt(3 (I_j + I_k - I_i) / (2 M)), principal
    axes (the box whose uniform mass has these moments; docs/engines.md, "Medium")."""
    i = np.asarray(moments, float)
    return np.sqrt(np.maximum(1.5 * (i.sum() - 2.0 * i) / mass, 0.0))


def _geom_semi_axes(m, gid: int) -> np.ndarray:
    """The ellipsoid semi-axes MuJoCo's fluid model uses for a geom (mju_geomSemiAxes): sphere
    (r, r, r), capsule (r, r, h + r), cylinder (r, r, h), box and ellipsoid their half sizes; a
    mesh its size as compiled."""
    size = np.array(m.geom_size[gid], float)
    kind = int(m.geom_type[gid])
    g = mujoco.mjtGeom
    if kind == int(g.mjGEOM_SPHERE):
        return np.full(3, size[0])
    if kind == int(g.mjGEOM_CAPSULE):
        return np.array([size[0], size[0], size[1] + size[0]])
    if kind == int(g.mjGEOM_CYLINDER):
        return np.array([size[0], size[0], size[1]])
    return size


def _name(m, obj, i: int) -> str:
    return mujoco.mj_id2name(m, obj, i) or str(i)


class MujocoEngine(EngineBase):
    name = "mujoco"
    effect_reasons = {**EngineBase.effect_reasons,
                      "fluid": "MuJoCo has no grid fluid (its fluid forces are a drag model)"}

    def check_options(self, scene: Scene) -> None:
        engine_options(scene)  # raises CaseError on an unknown key

    def capabilities(self) -> Capabilities:
        return Capabilities(
            dimensions=frozenset({2, 3}),
            shapes=frozenset(_SHAPES_3D + _SHAPES_2D),
            effects=frozenset({"gravity", "springs", "drag", "loads", "contact", "medium"}),
            integrators=INTEGRATORS + medium_run_names("mujoco"),
            notes=dict(INTEGRATOR_NOTES),
        )

    def version(self) -> str:
        return mujoco.__version__ if mujoco is not None else "not installed"

    def maps_fluid(self, scene: Scene) -> bool:
        """True for a fluid case MuJoCo runs as a cylinder in its medium (the driver then runs
        it as a rigid scene through ``open``)."""
        return scene.fluid is not None and unmappable(scene) is None

    def not_applicable(self, scene: Scene, integrator: str) -> str | None:
        if mujoco is None:  # pragma: no cover
            return "the mujoco package is not installed"
        if scene.fluid is not None:
            why = unmappable(scene)
            if why is not None:
                return (f"MuJoCo has no grid fluid; its medium stands for a fluid case only "
                        f"with {why[1]} ({why[0]}: {why[2]})")
            base, model = split_run(integrator)
            if model not in MEDIUM_MODELS["mujoco"] or base not in INTEGRATORS:
                return (f"a fluid case runs in MuJoCo as the mapped cylinder with a named fluid "
                        f"model: integrator+model, one of {list(medium_run_names('mujoco'))} "
                        f"(got {integrator!r})")
            self.check_options(scene)
            return mujoco_limits(scene)
        base, model = split_run(integrator)
        if model is not None and model in MEDIUM_MODELS["mujoco"]:
            return (f"{integrator!r} names a fluid model, which only a mapped fluid case takes; "
                    "an [effects] medium case chooses it with engine_options.mujoco.fluid_model")
        return (super().not_applicable(scene, integrator) or mujoco_limits(scene)
                or contact_limits(scene) or medium_limits(scene))

    def build(self, scene: Scene, integrator: str, dt: float) -> MujocoModel:
        """The compiled model with the scene's initial state set (also used by benchmarks)."""
        model = MujocoModel(scene, integrator, dt)
        model.set_initial_state()
        return model

    def open(self, scene: Scene, integrator: str, dt: float) -> MujocoModel:
        return self.build(scene, integrator, dt)

