"""The velocity-level contact models, ``sequential_impulse`` and ``soft_step``, bound to their
names (sim/rigid/contact_models.py) with their parameters.

Both run inside one compiled call per ``advance`` (velocity3d.advance3d / velocity2d.advance2d):
each step detects at the start-of-step state (sim/collide, speculative margin), solves the
contact rows of contact_rows.py on the velocities and drifts with the integrator's own rotation
update. docs/inhouse.md, "Contact", gives the formulations, the defaults and why, and what each
model measures on the contact cases.
"""

from __future__ import annotations

import math
from typing import Any

from crosscheck.names import contact_model_info
from crosscheck.sim.collide import DEFAULT_MARGIN, compile_geometry, contact_capacity, new_contacts
from crosscheck.sim.rigid.contact_models import bind_contact_model
from crosscheck.sim.rigid.contact_rows import (
    ROTATION_EXP,
    ROTATION_SPLITTING,
    SEQUENTIAL_IMPULSE,
    SOFT_STEP,
    Settings,
    make_rows,
)

_ROTATIONS = {"symplectic_euler": ROTATION_SPLITTING, "symplectic_euler_exp": ROTATION_EXP}

# Parameters shared by both models: name -> (default, "meaning, unit").
_COMMON: dict[str, tuple[Any, str]] = {
    "restitution_threshold": (
        0.1, "m/s: restitution acts only when the normal approach is faster (Box2D's 1 m/s would "
        "end an e = 0.5 bounce after two apexes, CONTACTS.md (d); 0.1 m/s is ten times the "
        "approach g dt a resting body gets in one 1 ms step)"),
    "warm_starting": (True, "start each step from the previous step's impulses (feature keys)"),
    "margin": (DEFAULT_MARGIN, "m: speculative distance: pairs closer than this are contacts "
               "(negative depth); must exceed the approach per step, v dt"),
    "capacity": (0, "contact rows the buffer holds; 0: sim.collide.contact_capacity (16 per "
                 "body in 3D, 8 in 2D); an overflow fails the step"),
}

SEQUENTIAL_IMPULSE_PARAMETERS: dict[str, tuple[Any, str]] = {
    "iterations": (1000, "projected Gauss-Seidel sweeps per step over every row, at most: a "
                   "resting 1000:1 mass ratio needs about as many sweeps as the ratio while "
                   "its impulses build up (30 let the 1000 kg box squeeze the 1 kg box out)"),
    "tolerance": (1e-6, "m/s: the sweeps stop once no row changes its velocity by more (warm "
                  "started resting contacts stop after a few)"),
    "position_iterations": (10, "split-impulse sweeps per step (0: no position correction)"),
    "baumgarte": (0.2, "fraction of the penetration beyond the slop the split impulse removes "
                  "per step (on positions only)"),
    "slop": (1e-5, "m: penetration left uncorrected (the resting depth)"),
    **_COMMON,
}

SOFT_STEP_PARAMETERS: dict[str, tuple[Any, str]] = {
    "substeps": (4, "sub-steps per step (Box2D v3's default)"),
    "iterations": (2, "biased sweeps per sub-step (Box2D v3: 1; with 1 a 1000 kg box on a "
                   "1 kg box slid 12.7 mm in 2 s, with 2 it rests: 0.54 mm, measured)"),
    "relax_iterations": (1, "sweeps without bias after each sub-step's drift (Box2D v3: 1)"),
    "contact_hertz": (0.0, "Hz: contact stiffness as a natural frequency (static contacts "
                      "twice), capped at a quarter of the sub-step rate as in Box2D v3; 0: the "
                      "cap, 1000 Hz at dt = 1 ms with 4 sub-steps. Box2D's 30 Hz suits its 60 Hz "
                      "game steps; here it sinks a resting ball 69 um and a 100 kg box 29 mm "
                      "into the 1 kg box under it (measured)"),
    "damping_ratio": (10.0, "damping ratio of the soft contact (Box2D v3: 10, overdamped)"),
    "push_speed": (3.0, "m/s: the fastest push out of an overlap (Box2D v3's contact speed)"),
    **_COMMON,
}

_AT_LEAST_ONE = ("iterations", "substeps")


def check_parameters(params: dict[str, Any]) -> list[tuple[str, str]]:
    """(key, expected) for every value out of its range."""
    problems = []
    for key, value in params.items():
        if isinstance(value, bool):
            continue
        if not math.isfinite(value) or value < 0:
            problems.append((key, "a finite number >= 0"))
        elif key in _AT_LEAST_ONE and value < 1:
            problems.append((key, "an integer >= 1"))
    if "baumgarte" in params and params["baumgarte"] > 1:
        problems.append(("baumgarte", "a number in [0, 1]"))
    return problems


class VelocityStepper:
    """A scene's geometry, contact buffer and solver rows, stepped by one compiled call."""

    def __init__(self, model_name: str, scene, model, integrator, parameters: dict[str, Any]):
        from crosscheck.sim.rigid import velocity2d, velocity3d

        defaults = (SOFT_STEP_PARAMETERS if model_name == "soft_step"
                    else SEQUENTIAL_IMPULSE_PARAMETERS)
        unknown = sorted(set(parameters) - set(defaults))
        if unknown:
            raise ValueError(f"{model_name}: unknown parameters {unknown}; known "
                             f"{sorted(defaults)}")
        self.name = model_name
        self.parameters = {k: parameters.get(k, d) for k, (d, _) in defaults.items()}
        problems = check_parameters(self.parameters)
        if problems:
            raise ValueError("; ".join(f"{model_name}.{k}: expected {e}" for k, e in problems))
        if integrator.name not in _ROTATIONS:
            raise ValueError(f"{model_name} pairs with {sorted(_ROTATIONS)}, not "
                             f"{integrator.name!r}")
        p = self.parameters
        self.model = model
        self.integrator = integrator
        self.geometry = compile_geometry(scene, float(p["margin"]))
        capacity = int(p["capacity"]) or contact_capacity(self.geometry)
        self.contacts = new_contacts(self.geometry, capacity)
        self.rows = make_rows(capacity)
        soft = model_name == "soft_step"
        self.settings = Settings(
            model=SOFT_STEP if soft else SEQUENTIAL_IMPULSE,
            rotation=_ROTATIONS[integrator.name],
            warm_starting=int(bool(p["warm_starting"])),
            substeps=int(p["substeps"]) if soft else 1,
            iterations=int(p["iterations"]),
            relax_iterations=int(p["relax_iterations"]) if soft else 0,
            position_iterations=0 if soft else int(p["position_iterations"]),
            tolerance=0.0 if soft else float(p["tolerance"]),
            restitution_threshold=float(p["restitution_threshold"]),
            baumgarte=0.0 if soft else float(p["baumgarte"]),
            slop=0.0 if soft else float(p["slop"]),
            contact_hertz=float(p["contact_hertz"]) if soft else 0.0,
            damping_ratio=float(p["damping_ratio"]) if soft else 0.0,
            push_speed=float(p["push_speed"]) if soft else 0.0)
        self.h: float | None = None
        self._kernel = velocity3d.advance3d if model.dimension == 3 else velocity2d.advance2d

    def advance(self, state, n_steps: int, h: float) -> None:
        self.h = float(h)
        n = int(n_steps)
        done = self._kernel(*self.model.kernel_args(), None, self.geometry, self.contacts,
                            self.rows, self.settings, *state.arrays(), n, float(h))
        if done < n:
            raise ValueError(
                f"contact buffer overflow: detection found {int(self.contacts.needed[0])} "
                f"contact rows, the buffer holds {self.contacts.capacity} (raise "
                f"[engine_options.inhouse.{self.name}] capacity); {done} of {n} steps taken")

    def describe(self) -> dict[str, Any]:
        info = contact_model_info("inhouse", self.name)
        out = {"model": self.name, "level": info.level, "parameters": dict(self.parameters),
               "contact_capacity": self.contacts.capacity,
               "friction_cone": "isotropic (Coulomb disc per contact point)",
               "rotation_update": self.integrator.rotation}
        stats = self.rows.stats
        if self.name == "sequential_impulse" and stats[0] > 0:
            out["sweeps_per_step_mean"] = float(stats[1]) / float(stats[0])
            out["sweeps_per_step_max"] = int(stats[2])
        if self.name == "soft_step":
            if self.h is not None:
                cap = 0.25 * self.settings.substeps / self.h
                hz = self.settings.contact_hertz
                out["contact_hertz_effective"] = min(hz, cap) if hz > 0 else cap
                out["static_contact_hertz_effective"] = 2 * out["contact_hertz_effective"]
            out["formulation"] = (
                "Box2D v3 soft step: per step detect once, then per sub-step kick, warm start, "
                "soft biased sweeps, drift, relax sweeps; restitution after the sub-steps")
        else:
            out["formulation"] = (
                "kick, detect, warm start, projected Gauss-Seidel (restitution bias from the "
                "pre-solve velocity, speculative gaps), drift, split-impulse position "
                "correction")
        return out


def _open(model_name: str):
    def open_model(scene, model, integrator, parameters):
        return VelocityStepper(model_name, scene, model, integrator, dict(parameters))

    open_model.__name__ = f"open_{model_name}"
    return open_model


bind_contact_model("soft_step", _open("soft_step"), SOFT_STEP_PARAMETERS,
                   check=check_parameters)
bind_contact_model("sequential_impulse", _open("sequential_impulse"),
                   SEQUENTIAL_IMPULSE_PARAMETERS, check=check_parameters)
