"""Contact forces inside the force pass: the one call ``evaluate`` makes when it is given a
``contacts`` argument, dispatched at compile time on that argument's type.

``forces3d.evaluate`` and ``forces2d.evaluate`` call :func:`contact_wrench3d` /
:func:`contact_wrench2d` after the smooth forces (gravity, drag, control, springs, loads), with
``F``, ``T`` holding them; each force-level contact model adds its contact forces. A model's
argument type (a NamedTuple class) selects its kernel: numba resolves the overload when it
compiles the step for that type, so a step compiles the code of its own model only, and a
contact-free step (``contacts=None``) none at all (``evaluate`` tests ``is None`` first).

* ``penalty.PenaltyContacts`` -> ``penalty.penalty_wrench3d`` / ``penalty_wrench2d``
* ``impulse_lcp.RestingContacts`` -> the resting-contact forces of the acceleration-level LCP
"""

from __future__ import annotations

from numba.extending import overload

from crosscheck.sim.rigid import impulse_lcp, penalty


def contact_wrench3d(bodies, contacts, x, q, P, L, v, w, F, T):
    """F, T += the contact forces of ``contacts`` at the state (3D); compiled only."""
    raise NotImplementedError("compiled only: called from forces3d.evaluate")


def contact_wrench2d(bodies, contacts, x, angle, P, L, v, w, F, T):
    """F, T += the contact forces of ``contacts`` at the state (2D); compiled only."""
    raise NotImplementedError("compiled only: called from forces2d.evaluate")


def _model(contacts):
    return getattr(contacts, "instance_class", None)


@overload(contact_wrench3d, inline="always")
def _contact_wrench3d(bodies, contacts, x, q, P, L, v, w, F, T):
    model = _model(contacts)
    if model is penalty.PenaltyContacts:
        def impl(bodies, contacts, x, q, P, L, v, w, F, T):
            penalty.penalty_wrench3d(bodies, contacts, x, q, v, w, F, T)
        return impl
    if model is impulse_lcp.RestingContacts:
        def impl(bodies, contacts, x, q, P, L, v, w, F, T):
            impulse_lcp.resting_wrench3d(bodies, contacts, x, q, L, v, w, F, T)
        return impl
    return None


@overload(contact_wrench2d, inline="always")
def _contact_wrench2d(bodies, contacts, x, angle, P, L, v, w, F, T):
    model = _model(contacts)
    if model is penalty.PenaltyContacts:
        def impl(bodies, contacts, x, angle, P, L, v, w, F, T):
            penalty.penalty_wrench2d(bodies, contacts, x, angle, v, w, F, T)
        return impl
    if model is impulse_lcp.RestingContacts:
        def impl(bodies, contacts, x, angle, P, L, v, w, F, T):
            impulse_lcp.resting_wrench2d(bodies, contacts, x, angle, L, v, w, F, T)
        return impl
    return None
