"""The in-house contact models' implementations, bound to the names of crosscheck.names.

``crosscheck.names.CONTACT_MODELS`` lists each model's name, level (velocity, force, event), the
integrators it pairs with and a one-line summary; this registry binds a name to its
implementation, as sim/rigid/integrators.py binds integrator names to kernels. A model is
implemented by an ``open`` function::

    open(scene, model: RigidModel, integrator: Integrator, parameters: dict) -> ContactStepper

and the stepper advances the Baraff state with contact in place::

    stepper.advance(state: RigidState, n_steps: int, h: float) -> None
    stepper.describe() -> dict        # the model's effective settings (meta["effective"])
    stepper.contacts                  # the sim.collide.Contacts buffer of the last detection

A stepper raises ValueError (an overflowing contact buffer, a solver that cannot proceed), which
the adapter turns into the run's StepFailure. docs/inhouse.md, "Contact", describes the pipeline
(detect -> solve -> integrate) and every model's formulation and parameters.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

from crosscheck.names import ContactModelInfo, contact_model_info


class ContactStepper(Protocol):
    contacts: Any

    def advance(self, state, n_steps: int, h: float) -> None: ...

    def describe(self) -> dict[str, Any]: ...


@dataclass(frozen=True)
class ContactModel:
    info: ContactModelInfo
    # name -> (default value, "meaning, unit"): what [engine_options.inhouse] may set
    parameters: dict[str, tuple[Any, str]] = field(default_factory=dict)
    open: Callable[..., ContactStepper] | None = None
    # parameters -> [(name, expected)] for values out of range (the adapter's CaseError)
    check: Callable[[dict[str, Any]], list[tuple[str, str]]] | None = None

    @property
    def name(self) -> str:
        return self.info.name


CONTACT_KERNELS: dict[str, ContactModel] = {}


def bind_contact_model(name: str, open: Callable[..., ContactStepper],
                       parameters: dict[str, tuple[Any, str]] | None = None,
                       check: Callable[[dict[str, Any]], list[tuple[str, str]]] | None = None
                       ) -> ContactModel:
    """Register the implementation of the crosscheck.names contact model ``name``: its
    ``open``, its parameters (name -> (default, "meaning, unit"); a case sets them in
    ``[engine_options.inhouse.<name>]``, checked against the defaults' types by the adapter) and
    an optional ``check`` of their ranges."""
    info = contact_model_info("inhouse", name)  # KeyError for a name crosscheck.names lacks
    if name in CONTACT_KERNELS:
        raise ValueError(f"contact model {name!r} is already registered")
    bound = ContactModel(info, dict(parameters or {}), open, check)
    CONTACT_KERNELS[name] = bound
    return bound


def get_contact_model(name: str) -> ContactModel:
    try:
        return CONTACT_KERNELS[name]
    except KeyError:
        raise KeyError(f"the in-house contact model {name!r} is not implemented; implemented: "
                       f"{list(CONTACT_KERNELS)}") from None


def _bind_force_and_event_models() -> None:
    """penalty (force level, penalty.py) and impulse_lcp (event-driven, impulse_lcp.py)."""
    from crosscheck.sim.rigid import impulse_lcp, penalty

    bind_contact_model("penalty", penalty.open_penalty, penalty.PARAMETERS)
    bind_contact_model("impulse_lcp", impulse_lcp.open_impulse_lcp, impulse_lcp.PARAMETERS)


# The implementations register themselves on import (as integrators.py binds its kernels), in
# crosscheck.names' order: the velocity-level models, then penalty and impulse_lcp.
from crosscheck.sim.rigid import velocity_models  # noqa: E402, F401

_bind_force_and_event_models()
