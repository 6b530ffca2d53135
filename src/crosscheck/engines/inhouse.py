"""The in-house engine adapter: crosscheck's own simulators behind the adapter protocol.

Rigid scenes (2D and 3D) run on :mod:`crosscheck.sim.rigid`: a session compiles the Scene into
a RigidModel and steps the Baraff state with the named integrator of
``crosscheck.sim.rigid.INTEGRATORS``; a contact scene runs ``integrator+model`` through the
contact model's stepper (``sim/rigid/contact_models.py``), with its parameters from
``[engine_options.inhouse.<model>]``. The run driver (engines/driver.py) samples and times it.
The observed quantities are exactly the Trajectory convention: the state's x *is* the centre of
mass (world), its q the orientation of the declared body frame, P / m the centre-of-mass
velocity and R I_body^-1 R^T L the world angular velocity, so nothing is converted.

Fluid scenes (``scene.fluid``) open a :class:`crosscheck.sim.fluid.FluidRun`, imported
lazily: if that package cannot be imported the scene is "not applicable" with the reason.

A step the kernels cannot take (a singular implicit system) raises StepFailure, which the driver
records as the run's failure with its time, like a non-finite state or an energy runaway.
"""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np

from crosscheck.engines.base import Capabilities, EngineBase
from crosscheck.engines.session import StepFailure
from crosscheck.names import (
    contact_model_info,
    contact_run_names,
    fluid_names,
    rigid_names,
    split_run,
)
from crosscheck.rotations import quat_to_matrix
from crosscheck.scene.model import Scene
from crosscheck.sim.rigid import INTEGRATORS
from crosscheck.sim.rigid.model import RigidState, state_from_scene
from crosscheck.sim.rigid.simulation import RigidSimulation

SHAPES = frozenset({"sphere", "box", "capsule", "cylinder", "mesh", "circle", "polygon"})
RIGID_EFFECTS = frozenset({"gravity", "springs", "drag", "loads"})
OPTIONS = {"runaway_factor": float}  # [engine_options.inhouse] keys a case may pin

def _fluid_module():
    """(module, None) or (None, reason) for the in-house fluid solver."""
    try:
        module = importlib.import_module("crosscheck.sim.fluid")
    except Exception as exc:  # noqa: BLE001 - any import failure makes fluid not applicable
        return None, f"the in-house fluid solver cannot be imported ({type(exc).__name__}: {exc})"
    if not hasattr(module, "FluidRun"):
        return None, "crosscheck.sim.fluid has no FluidRun"
    return module, None


def _fluid_integrators() -> tuple[str, ...]:
    """crosscheck.names' fluid schemes when the fluid solver imports (tests keep them equal to
    crosscheck.sim.fluid.INTEGRATORS), else none."""
    module, _ = _fluid_module()
    return () if module is None else fluid_names("inhouse")


def _contact_reason(integrator: str, model: str) -> str | None:
    """Why the in-house engine cannot run ``integrator+model`` on a contact scene, or None."""
    from crosscheck.sim.rigid.contact_models import CONTACT_KERNELS

    try:
        info = contact_model_info("inhouse", model)
    except KeyError as exc:
        return str(exc.args[0])
    if integrator not in info.integrators:
        return (f"contact model {model!r} does not pair with {integrator!r} (it pairs with "
                f"{list(info.integrators)})")
    if model not in CONTACT_KERNELS:
        return f"the in-house contact model {model!r} is not implemented yet"
    return None


def _model_parameters(source, field: str, model, value) -> dict[str, Any]:
    """A case's table of parameters for one contact model, checked (CaseError otherwise)."""
    from crosscheck.errors import CaseError

    defaults = model.parameters
    if not isinstance(value, dict):
        raise CaseError(source, field, f"a table of {model.name}'s parameters, among "
                        f"{sorted(defaults)}", value)
    out = {}
    for key, given in value.items():
        where = f"{field}.{key}"
        if key not in defaults:
            raise CaseError(source, where, f"a parameter of {model.name}, one of "
                            f"{sorted(defaults)}", f"unknown key {key!r}")
        default = defaults[key][0]
        if isinstance(default, bool):
            ok = isinstance(given, bool)
            kind = "true or false"
        elif isinstance(default, int):
            ok = isinstance(given, int) and not isinstance(given, bool)
            kind = "an integer"
        elif isinstance(default, str):
            ok = isinstance(given, str)
            kind = "a string"
        else:  # a float, or None (a number the model otherwise derives)
            ok = isinstance(given, (int, float)) and not isinstance(given, bool)
            kind = "a number"
            given = float(given) if ok else given
        if not ok:
            raise CaseError(source, where, f"{kind} ({defaults[key][1]})", given)
        out[key] = given
    if model.check is not None:
        for key, expected in model.check(out):
            raise CaseError(source, f"{field}.{key}", expected, out[key])
    return out


class InhouseEngine(EngineBase):
    name = "inhouse"
    effect_reasons = {
        **EngineBase.effect_reasons,
        "medium": "the in-house rigid engine has no stateless medium model; the in-house body in "
                  "a resolved fluid is the coupled [fluid] case (2D, docs/fluid.md)",
    }

    def capabilities(self) -> Capabilities:
        rigid = rigid_names("inhouse")  # rk4 first: the default
        fluid = _fluid_integrators()
        notes = {name: integ.note for name, integ in INTEGRATORS.items()}
        notes.update({name: "fluid scenes only (crosscheck.sim.fluid)" for name in fluid})
        effects = set(RIGID_EFFECTS)
        if _fluid_module()[0] is not None:
            effects.add("fluid")
        from crosscheck.sim.rigid.contact_models import CONTACT_KERNELS

        if CONTACT_KERNELS:
            effects.add("contact")
        contact_runs = contact_run_names("inhouse")
        return Capabilities(dimensions=frozenset({2, 3}), shapes=SHAPES,
                            effects=frozenset(effects), integrators=rigid + contact_runs + fluid,
                            notes=notes)

    def version(self) -> str:
        import numba

        import crosscheck

        return f"crosscheck {crosscheck.__version__} (numba {numba.__version__})"

    def not_applicable(self, scene: Scene, integrator: str) -> str | None:
        if scene.fluid is not None or scene.effects.fluid:
            module, reason = _fluid_module()
            if module is None:
                return reason
            names = fluid_names("inhouse")
            if integrator not in names:
                return (f"{integrator!r} is not a fluid integrator "
                        f"(fluid integrators: {list(names)})")
            return None
        base, model = split_run(integrator)
        if base not in INTEGRATORS:
            return (f"inhouse has no rigid-body integrator {base!r} "
                    f"(it has {list(INTEGRATORS)})")
        if model is not None:
            if not scene.effects.contact:
                return f"contact model {model!r} named on a scene without contact"
            reason = _contact_reason(base, model)
            if reason:
                return reason
            return super().not_applicable(scene, base)
        if scene.effects.contact:
            return (f"{base!r} pairs with no in-house contact model "
                    f"(crosscheck.names.CONTACT_MODELS)")
        return super().not_applicable(scene, integrator)

    def check_options(self, scene: Scene) -> None:
        self._options(scene)  # raises CaseError on an unknown key

    def _options(self, scene: Scene) -> dict[str, Any]:
        """The case's [engine_options.inhouse]: ``runaway_factor`` and one table per contact
        model, ``[engine_options.inhouse.<model>]``, with that model's parameters (the registry's
        names, values of the defaults' types, ranges by the model's check). Anything else is a
        CaseError naming the field and what was expected."""
        from crosscheck.errors import CaseError
        from crosscheck.sim.rigid.contact_models import CONTACT_KERNELS

        source = scene.source or scene.name
        raw = dict(scene.engine_options.get(self.name, {}))
        known = sorted(set(OPTIONS) | set(CONTACT_KERNELS))
        unknown = sorted(set(raw) - set(known))
        if unknown:
            raise CaseError(source, f"engine_options.{self.name}.{unknown[0]}",
                            f"one of the options {known} (contact models take a table of their "
                            f"parameters)", f"unknown key {unknown[0]!r}")
        out: dict[str, Any] = {}
        for key, value in raw.items():
            if key in OPTIONS:
                out[key] = OPTIONS[key](value)
                continue
            out[key] = _model_parameters(source, f"engine_options.{self.name}.{key}",
                                         CONTACT_KERNELS[key], value)
        return out

    def contact_parameters(self, scene: Scene, model: str) -> dict[str, Any]:
        """The parameters a case sets for one contact model (the rest take their defaults)."""
        return dict(self._options(scene).get(model, {}))

    def runaway_factor(self, scene: Scene) -> float:
        return self._options(scene).get("runaway_factor", super().runaway_factor(scene))

    def open(self, scene: Scene, integrator: str, dt: float) -> InhouseSession:
        return InhouseSession(scene, integrator, dt)

    def open_fluid(self, scene: Scene, integrator: str, dt: float):
        module, reason = _fluid_module()
        if module is None:  # pragma: no cover - not_applicable said so already
            from crosscheck.errors import EngineUnavailable

            raise EngineUnavailable(f"inhouse: {reason}")
        return module.FluidRun(scene, integrator, dt)


class InhouseSession:
    """The Baraff state of a scene stepped by one compiled integrator (engines/session.py)."""

    fused = False  # advance(k) is one compiled call already: the generic loop is the fast path

    def __init__(self, scene: Scene, integrator: str, dt: float):
        self.scene = scene
        self.dt = float(dt)
        base, model = split_run(integrator)
        self.sim = RigidSimulation.from_scene(scene, base)
        self.state = state_from_scene(self.sim.model, scene)
        # A contact scene steps through its contact model's stepper (sim/rigid/contact_models.py);
        # a contact-free one through the integrator's kernels alone.
        self.contact = None
        if model is not None:
            from crosscheck.sim.rigid.contact_models import get_contact_model

            parameters = InhouseEngine().contact_parameters(scene, model)
            self.contact = get_contact_model(model).open(scene, self.sim.model,
                                                         self.sim.integrator, parameters)
        n, d = self.sim.model.n_bodies, self.sim.model.dimension
        r, w = (4, 3) if d == 3 else (1, 1)
        # Row layout: com (N d), orientation (N r), velocity (N d), angular velocity (N w).
        self._sizes = (n * d, n * r, n * d, n * w)
        self._shapes = ((n, d), (n, 4) if d == 3 else (n,), (n, d), (n, 3) if d == 3 else (n,))
        self.row_width = sum(self._sizes)

    def advance(self, n: int) -> None:
        try:
            if self.contact is not None:
                self.contact.advance(self.state, n, self.dt)
            else:
                self.sim.advance(self.state, n, self.dt)
        except (ArithmeticError, np.linalg.LinAlgError, ValueError) as exc:
            raise StepFailure(f"step failed: {type(exc).__name__}: {exc}") from exc

    def read_raw(self) -> np.ndarray:
        return np.concatenate([a.ravel() for a in self.sim.observe(self.state)])

    def convert(self, rows, t):
        rows = np.asarray(rows, float)
        parts = np.split(rows, np.cumsum(self._sizes)[:-1], axis=1)
        return tuple(p.reshape((len(rows), *shape))
                     for p, shape in zip(parts, self._shapes, strict=True)), {}

    def set_state(self, com, rot, vel, omega) -> None:
        model = self.sim.model
        bodies = model.bodies
        x = np.array(com, float)
        P = bodies.mass[:, None] * np.asarray(vel, float)
        if model.dimension == 3:
            q = np.array(rot, float)
            r = quat_to_matrix(q)
            inertia_world = np.einsum("nij,njk,nlk->nil", r, bodies.inertia, r)
            L = np.einsum("nij,nj->ni", inertia_world, np.asarray(omega, float))
        else:
            q = np.array(rot, float)
            L = bodies.moment * np.asarray(omega, float)
        self.state = RigidState(x, q, P, L)

    def check(self) -> list[str]:
        return []

    def effective(self, arrays) -> dict[str, Any]:
        scene = self.scene
        return dict(self.sim.integrator.describe(),
                    effects_simulated=list(self.sim.model.effects),
                    gravity=None if scene.effects.gravity is None
                    else list(map(float, scene.effects.gravity)),
                    damping="only the declared drag and spring damping",
                    contact=False if self.contact is None else self.contact.describe())

    def close(self) -> None:
        pass
