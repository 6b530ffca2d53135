"""The in-house integrator registry: binds the kernels to the names of crosscheck.names.

The names, their order (the first is the engine's default), nominal order of convergence,
discrete scheme, symplecticity and contact flag live in :mod:`crosscheck.names` with every other
engine's; this module adds what only the in-house engine has: each integrator's kernels, its
rotation update, its force evaluations per step and a note. ``bind`` refuses a name crosscheck.names
does not list, and tests/rigid/test_integrator_registry.py fails when a listed name has no
kernel. Adding an integrator: its entry in crosscheck.names, one kernel per dimension (in the
module of its family: explicit3d / explicit2d, splitting3d / splitting2d, implicit) and one
``bind`` call here.

Rotation updates (3D; in 2D the angle is a plain coordinate and every scheme is exact
bookkeeping for it):

* ``renormalise``: the quaternion is integrated additively from dq/dt = 1/2 (0, w) q like any
  other state component, then projected back to unit length after the step. The projection
  changes q by O(h^(p+1)) per step, below the scheme's own local error, so the order is kept;
  without it |q| would drift and R(q) would stretch the body.
* ``exp``: the exponential map q <- exp(h w) q keeps |q| = 1 by construction (exact rotation for
  the step's angular velocity). For RK4 the stages are combined in the Lie algebra with the
  dexp^-1 correction (Runge-Kutta-Munthe-Kaas), which keeps order 4; a plain exp of the averaged
  w would only be order 2 when w changes direction.
* ``splitting``: the free rotation (kinetic energy sum Lb_k^2 / 2 I_k) is split into the three
  principal-axis terms, each solved exactly as a rotation about that body axis (Dullweber, Reich
  and Leimkuhler 1997). Every piece is symplectic and keeps |L| exactly, so the whole scheme is
  symplectic for the rigid body, not only for its translation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from crosscheck.names import integrator_info, rigid_names
from crosscheck.sim.rigid import explicit2d, explicit3d, implicit, splitting2d, splitting3d


@dataclass(frozen=True)
class Integrator:
    name: str
    order: int  # nominal global order of convergence (crosscheck.names)
    symplectic: bool  # symplectic for the whole rigid-body system, no damping (crosscheck.names)
    scheme: str  # discrete update under constant acceleration (crosscheck.names)
    contact: bool  # can run with contact (crosscheck.names; none can yet)
    rotation: str  # "renormalise" | "exp" | "splitting" (3D)
    evaluations: int  # force evaluations per step
    note: str  # what it does to rotation and why
    advance3d: Callable  # (model, state, control, contacts, n_steps, h) -> None, in place
    advance2d: Callable

    def advance(self, model, state, control, contacts, n_steps: int, h: float) -> None:
        """n_steps fused steps of size h, in place (one compiled call). ``control``: a
        model.Control held constant over the n steps, or None; ``contacts``: None (the contact
        model's slot)."""
        if contacts is not None and not self.contact:
            raise ValueError(f"integrator {self.name!r} cannot run with contact")
        fn = self.advance3d if model.dimension == 3 else self.advance2d
        fn(model, state, control, contacts, int(n_steps), float(h))

    def step(self, model, state_in, state_out, control, contacts, h: float) -> None:
        """One step from state_in into state_out (state_in unchanged unless it is state_out)."""
        if state_out is not state_in:
            for dst, src in zip(state_out.arrays(), state_in.arrays(), strict=True):
                dst[...] = src
        self.advance(model, state_out, control, contacts, 1, h)

    def describe(self) -> dict:
        return {"integrator": self.name, "order": self.order, "symplectic": self.symplectic,
                "scheme": self.scheme, "rotation_update": self.rotation,
                "force_evaluations_per_step": self.evaluations,
                "rotation_note": self.note}


def _kernel(fn) -> Callable:
    """Wrap a compiled advance kernel as (model, state, control, contacts, n_steps, h)."""

    def advance(model, state, control, contacts, n_steps: int, h: float) -> None:
        fn(*model.kernel_args(), control, contacts, *state.arrays(), n_steps, h)

    advance.__name__ = getattr(fn, "__name__", "advance")
    advance.kernel = fn
    return advance


INTEGRATORS: dict[str, Integrator] = {}


def bind(name: str, rotation: str, evaluations: int, note: str, advance3d: Callable,
         advance2d: Callable) -> Integrator:
    """Register the kernels of the crosscheck.names integrator ``name`` (KeyError if unlisted)."""
    info = integrator_info("inhouse", name)
    if name in INTEGRATORS:
        raise ValueError(f"integrator {name!r} is already registered")
    if not (callable(advance3d) and callable(advance2d)):
        raise TypeError(f"integrator {name!r}: its 3D and 2D kernels must be callables")
    integrator = Integrator(name, info.order, info.symplectic, info.scheme, info.contact,
                            rotation, evaluations, note, advance3d, advance2d)
    INTEGRATORS[name] = integrator
    return integrator


bind(
    "rk4", "renormalise", 4,
    "classical RK4 on (x, q, P, L); the quaternion takes additive stages and is renormalised "
    "once per step (an O(h^5) projection, so order 4 is kept and |q| = 1 to round-off)",
    _kernel(explicit3d.advance_rk4), _kernel(explicit2d.advance_rk4))
bind(
    "rk4_exp", "exp", 4,
    "RK4 with the Runge-Kutta-Munthe-Kaas rotation update: stages and step are exponential maps "
    "q <- exp(theta) q, stage angular velocities pulled back with dexp^-1 (order 4 kept, |q| = 1 "
    "without a projection); 2D: identical to rk4",
    _kernel(explicit3d.advance_rk4_exp), _kernel(explicit2d.advance_rk4))
bind(
    "explicit_euler", "renormalise", 1,
    "q += h/2 (0, w) q with w at the start of the step, then renormalised (as in the seed notes); "
    "the unprojected update would grow |q| by sqrt(1 + (h|w|/2)^2) per step; tumbling energy "
    "grows at O(h)",
    _kernel(explicit3d.advance_explicit_euler), _kernel(explicit2d.advance_explicit_euler))
bind(
    "midpoint", "renormalise", 2,
    "explicit midpoint: additive quaternion stages at h/2 and h, renormalised after the step",
    _kernel(explicit3d.advance_midpoint), _kernel(explicit2d.advance_midpoint))
bind(
    "symplectic_euler", "splitting", 1,
    "kick P, L with the start-of-step forces, drift x with the new P and the orientation by "
    "exact sub-rotations about the principal axes with the new L (Lie-Trotter splitting of the "
    "free rotor): symplectic for rotation as well, |L| kept exactly by the drift",
    _kernel(splitting3d.advance_symplectic_euler),
    _kernel(splitting2d.advance_symplectic_euler))
bind(
    "symplectic_euler_exp", "exp", 1,
    "semi-implicit Euler as game engines do it: kick, then q <- exp(h w) q with "
    "w = I(q_n)^-1 L_(n+1). Symplectic for translation only: w depends on q, so the rotation "
    "update is explicit and a tumbling asymmetric body's energy drifts at O(h); 2D: identical "
    "to symplectic_euler (and symplectic there)",
    _kernel(splitting3d.advance_symplectic_euler_exp),
    _kernel(splitting2d.advance_symplectic_euler))
bind(
    "verlet", "splitting", 2,
    "velocity Verlet: half kick, drift (orientation by the Strang splitting 1-2-3-2-1 of the "
    "free rotor into exact principal-axis rotations), half kick at the new configuration: "
    "second order, symplectic and time-reversible for the rigid body; damping forces in the "
    "closing half kick use momenta extrapolated to the step's end (keeps order 2)",
    _kernel(splitting3d.advance_verlet), _kernel(splitting2d.advance_verlet))
bind(
    "implicit_euler", "exp", 1,
    "linearised backward Euler on the generalised velocities with the spring and drag "
    "Jacobians (stable for stiff springs at any step); the orientation is backward Euler as "
    "well, q1 = exp(h w(q1, L1)) q0 solved by Newton per body, which damps the free rotor's "
    "perturbations instead of amplifying them (|q| = 1 through the exponential map)",
    implicit.advance_implicit_3d, implicit.advance_implicit_2d)

DEFAULT = rigid_names("inhouse")[0]  # tests/rigid check INTEGRATORS lists the same, in order


def get_integrator(name: str) -> Integrator:
    try:
        return INTEGRATORS[name]
    except KeyError:
        raise KeyError(f"unknown in-house integrator {name!r}; known: {list(INTEGRATORS)}") \
            from None
