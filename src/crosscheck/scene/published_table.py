"""Load-time checks of ``[reference] table = "..."``: a published data set the case can use.

A table the comparer does not know, or one that does not describe the case, would give a cell
with no reference metric at all, which used to pass. So the loader refuses: an unknown name
(listing the known ones), a table on a case it cannot apply to (a rigid case naming a fluid
table, a dam break without a free surface), and a lid-driven cavity whose Reynolds number is
none of Ghia et al.'s. The catalogue lives in :mod:`crosscheck.reference.fluid_data`, a module
that imports nothing of crosscheck (so this import does not point up).
"""

from __future__ import annotations

from typing import Any

from crosscheck.reference.fluid_data import CASE_TABLES, ghia_reynolds
from crosscheck.scene.fields import Fields

# Relative difference allowed between the sides of a "square" cavity (exact inputs: round-off).
SQUARE_RTOL = 1e-9


def check_published_table(f: Fields, name: str, fluid: Any, gravity: Any) -> None:
    """Refuse ``reference.table = name`` unless the comparer knows it and it fits the case."""
    if name not in CASE_TABLES:
        known = "; ".join(f"{k}: {v}" for k, v in CASE_TABLES.items())
        raise f.error("table", f"a published table crosscheck ships ({known}); or "
                      "file = \"your.csv\" for your own data", name)
    if fluid is None:
        raise f.error("table", f"a table that applies to this rigid case: {name!r} is fluid "
                      "data (for your own rigid data, give file = \"your.csv\")", name)
    if name == "martin_moyce_1952":
        if not fluid.has_surface or gravity is None or not any(gravity):
            raise f.error("table", "a case it describes: martin_moyce_1952 is a collapsing "
                          "water column, which needs a free surface (fluid.initial) and "
                          "effects.gravity", name)
        return
    cavity_reynolds(f, name, fluid)


def cavity_reynolds(f: Fields, name: str, fluid: Any) -> int:
    """The Reynolds number of Ghia et al.'s table for this cavity: Re = U L / nu with U the lid
    speed, L the side of the square cavity and nu the kinematic viscosity (as fluid_metrics
    normalises the profiles: by the lid speed and the domain size)."""
    lid = fluid.lid
    lx, ly = fluid.domain
    if lid is None or lid.side != "top" or lid.speed <= 0:
        raise f.error("table", f"a case {name} describes: a lid on the top side moving in +x "
                      "(fluid.lid = { side = \"top\", speed > 0 })",
                      None if lid is None else f"lid {lid.side} at {lid.speed} m/s")
    if abs(lx - ly) > SQUARE_RTOL * max(lx, ly):
        raise f.error("table", f"a case {name} describes: a square cavity", f"domain {lx} x {ly}")
    if fluid.kinematic_viscosity <= 0:
        raise f.error("table", f"a case {name} describes: a viscous fluid "
                      "(fluid.kinematic_viscosity > 0)", fluid.kinematic_viscosity)
    reynolds = lid.speed * lx / fluid.kinematic_viscosity
    try:
        return ghia_reynolds(reynolds, name)
    except ValueError as exc:
        raise f.error("table", f"a case at a Reynolds number the table has: {exc}",
                      name) from None
