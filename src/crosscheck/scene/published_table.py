"""Load-time checks of ``[reference] table = "..."``: a published data set the case can use.

A table the comparer does not know, or one that does not describe the case, would give a cell
with no reference metric at all, which used to pass. So the loader refuses: an unknown name
(listing the known ones), a table on a case it cannot apply to (a rigid case naming a fluid
table, a dam break without a free surface), and a lid-driven cavity whose Reynolds number is
none of Ghia et al.'s. The catalogue of names lives here, below reference/ (whose
``fluid_data`` loads the data and re-exports the catalogue), so the loader imports nothing above
the scene.
"""

from __future__ import annotations

import math
from typing import Any

from crosscheck.errors import CaseError
from crosscheck.scene.fields import Fields

# The Reynolds numbers of Ghia et al.'s Tables I and II.
GHIA_REYNOLDS = (100, 400, 1000, 3200, 5000, 7500, 10000)
# A case's Reynolds number U L / nu matches a table's to this relative tolerance: the case's
# numbers are exact inputs (1 / 0.01 = 100 up to round-off), so only round-off is forgiven.
REYNOLDS_RTOL = 1e-6

# What ``reference.table`` may name, and what it needs. "ghia_1982" picks the Reynolds number
# from the case; "ghia_1982_re<Re>" insists on one (the case must be at that Re).
CASE_TABLES = {
    "martin_moyce_1952": "surge front of a collapsing water column (a fluid case with gravity "
                         "and a free surface)",
    "ghia_1982": "centreline velocities of the lid-driven cavity at the case's Reynolds number "
                 f"({', '.join(map(str, GHIA_REYNOLDS))})",
}
CASE_TABLES.update({f"ghia_1982_re{_re}": f"lid-driven cavity centrelines at Re = {_re}"
                    for _re in GHIA_REYNOLDS})
# The DFG benchmark (Schafer & Turek 1996): channel flow past a cylinder. The geometry is
# checked in units of the cylinder's diameter D, so a scaled copy of the channel is accepted.
SCHAFER_TUREK = {"schafer_turek_2d1": ("2D-1", 20.0), "schafer_turek_2d2": ("2D-2", 100.0)}
CASE_TABLES.update({
    "schafer_turek_2d1": "DFG benchmark 2D-1, channel flow past a cylinder at Re = 20 (steady): "
                         "drag, lift, pressure difference",
    "schafer_turek_2d2": "DFG benchmark 2D-2, channel flow past a cylinder at Re = 100 "
                         "(periodic): maximum drag and lift, Strouhal number",
})
# Wachs (2009): a disc settling in a closed vertical channel four diameters wide (the published
# terminal Reynolds number and drag coefficient at two density ratios, reference/data/
# wachs2009_disc_channel_sedimentation.csv). With w / d and r = rho_s / rho, the Galileo number
# sqrt((r - 1) g d^3) / nu fixes the terminal state; the benchmark's d = 1, g = 10 and nu =
# 0.008088 give it. The case is accepted in any units with the same groups, to WACHS_RTOL.
WACHS_2009 = {"width_ratio": 4.0, "diameter": 1.0, "g": 10.0, "nu": 0.008088,
              "density_ratios": (1.5, 3.0)}
WACHS_RTOL = 1e-3
CASE_TABLES["wachs_2009"] = ("Wachs (2009): terminal settling speed and drag of a disc in a closed "
                             "vertical channel four diameters wide (rho_s / rho = 1.5 or 3)")
# The DFG channel in cylinder diameters: 22 D long, 4.1 D high, the centre 2 D from the inflow
# side and from the bottom wall. Exact inputs: only round-off is forgiven.
DFG_GEOMETRY_RTOL = 1e-6


def ghia_reynolds(reynolds: float, table: str = "ghia_1982") -> int:
    """The Reynolds number of Ghia et al.'s tables that ``reynolds`` is (to REYNOLDS_RTOL) and that
    the case's ``table`` name allows; ValueError naming the Re found and those available."""
    wanted = GHIA_REYNOLDS if table == "ghia_1982" else (int(table.rsplit("re", 1)[1]),)
    for re in wanted:
        if abs(reynolds - re) <= REYNOLDS_RTOL * re:
            return re
    raise ValueError(f"the case's Reynolds number U L / nu = {reynolds:.10g} matches no table "
                     f"of {table!r} (available: Re = {', '.join(map(str, wanted))}, to a "
                     f"relative {REYNOLDS_RTOL:g})")


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
    if name in SCHAFER_TUREK:
        dfg_cylinder(f, name, fluid)
        return
    if name == "wachs_2009":
        wachs_channel(f, fluid, gravity)
        return
    cavity_reynolds(f, name, fluid)


def galileo_number(density_ratio: float, g: float, diameter: float, nu: float) -> float:
    """sqrt(|r - 1| g d^3) / nu: with r and w / d, what fixes a settling disc's terminal Re."""
    return math.sqrt(abs(density_ratio - 1.0) * g * diameter ** 3) / nu


def wachs_channel(f: Fields, fluid: Any, gravity: Any) -> float:
    """The density ratio of a case that is Wachs's (2009) benchmark, after checking it is: one
    coupled circle, no obstacles, no free surface, a viscous fluid under gravity, the channel
    four diameters wide, a published density ratio and the benchmark's Galileo number."""

    def refuse(expected: str, got: Any) -> CaseError:
        return f.error("table", f"a case wachs_2009 describes: {expected}", got)

    bodies = fluid.bodies
    if len(bodies) != 1 or getattr(bodies[0].shape, "kind", None) != "circle":
        raise refuse("exactly one [[bodies]] entry, a circle (the settling disc)",
                     f"{len(bodies)} bodies" if len(bodies) != 1 else bodies[0].shape.kind)
    if fluid.obstacles:
        raise refuse("a channel with no obstacles", f"{len(fluid.obstacles)} obstacles")
    if fluid.has_surface:
        raise refuse("a closed channel full of fluid (no fluid.initial)", "a free surface")
    g = 0.0 if gravity is None else math.sqrt(sum(float(c) ** 2 for c in gravity))
    nu = fluid.kinematic_viscosity
    if g == 0.0 or not nu:
        raise refuse("effects.gravity and a viscous fluid", f"gravity {g:g}, nu {nu!r}")
    disc = bodies[0]
    d = 2.0 * float(disc.shape.radius)
    ratio = float(disc.mass) / (math.pi * d * d / 4.0) / fluid.density
    known = WACHS_2009["density_ratios"]
    if not any(abs(ratio / r - 1.0) <= WACHS_RTOL for r in known):
        raise refuse(f"a disc of density ratio rho_s / rho in {list(known)}", f"{ratio:.6g}")
    width = fluid.domain[0] / d
    if abs(width / WACHS_2009["width_ratio"] - 1.0) > WACHS_RTOL:
        raise refuse(f"a channel {WACHS_2009['width_ratio']:g} diameters wide "
                     "(fluid.domain[0] / the disc's diameter)", f"{width:.6g}")
    ga = galileo_number(ratio, g, d, nu)
    want = galileo_number(ratio, WACHS_2009["g"], WACHS_2009["diameter"], WACHS_2009["nu"])
    if abs(ga / want - 1.0) > WACHS_RTOL:
        raise refuse(f"the benchmark's Galileo number sqrt((r - 1) g d^3) / nu = {want:.6g} "
                     "(d = 1, g = 10, nu = 0.008088)", f"{ga:.6g}")
    return ratio


def dfg_cylinder(f: Fields, name: str, fluid: Any) -> tuple[Any, str, float]:
    """The DFG case's cylinder (the placed circle, its name) and its Reynolds number
    ``U_mean D / nu``, after checking the case is the benchmark: one circular obstacle, a
    parabolic inflow on the left, an open right side, solid top and bottom, no free surface, a
    viscous fluid, the forces measured (and, for 2D-1, the pressure saved for the pressure
    difference), the channel's proportions, and the table's Reynolds number."""
    label, re_table = SCHAFER_TUREK[name]

    def refuse(expected: str, got: Any) -> CaseError:
        return f.error("table", f"a case {name} describes: {expected}", got)

    if fluid.has_surface:
        raise refuse("a channel full of fluid (no fluid.initial)", "a free surface")
    circles = [(o, n) for o, n in zip(fluid.obstacles, fluid.obstacle_names, strict=True)
               if getattr(o.shape, "kind", None) == "circle"]
    if len(fluid.obstacles) != 1 or len(circles) != 1:
        raise refuse("exactly one obstacle, a circle (the cylinder)",
                     f"{len(fluid.obstacles)} obstacles, {len(circles)} circles")
    walls = dict(fluid.walls)
    want = {"left": "inflow", "right": "open", "bottom": "solid", "top": "solid"}
    if walls != want:
        raise refuse(f"fluid.walls = {want}", walls)
    if fluid.inflow.profile != "parabolic":
        raise refuse("a parabolic inflow (fluid.inflow.profile)", fluid.inflow.profile)
    if fluid.kinematic_viscosity <= 0 or not fluid.no_slip:
        raise refuse("a viscous fluid with no-slip walls", fluid.kinematic_viscosity)
    if not fluid.output.forces.enabled:
        raise refuse("the forces on the cylinder measured (fluid.output.forces = true)", False)
    if label == "2D-1" and "p" not in fluid.output.fields:
        raise refuse("the pressure saved for the pressure difference (\"p\" in "
                     "fluid.output.fields)", list(fluid.output.fields))
    circle, cname = circles[0]
    d = 2.0 * float(circle.shape.radius)
    cx, cy = (float(c) for c in circle.position)
    lx, ly = fluid.domain
    for what, value, expected in (("length", lx, 22.0 * d), ("height", ly, 4.1 * d),
                                  ("centre x", cx, 2.0 * d), ("centre y", cy, 2.0 * d)):
        if abs(value - expected) > DFG_GEOMETRY_RTOL * expected:
            raise refuse(f"the DFG channel: {what} {expected:.6g} m for a cylinder of "
                         f"diameter {d:.6g} m (22 D long, 4.1 D high, centre at (2 D, 2 D))",
                         value)
    reynolds = fluid.inflow.mean_speed() * d / fluid.kinematic_viscosity
    if abs(reynolds - re_table) > REYNOLDS_RTOL * re_table:
        raise refuse(f"Re = U_mean D / nu = {re_table:g} (U_mean = 2/3 of inflow.speed)",
                     f"Re = {reynolds:.10g}")
    return circle, cname, reynolds


def cavity_reynolds(f: Fields, name: str, fluid: Any) -> int:
    """The Reynolds number of Ghia et al.'s table for this cavity: Re = U L / nu with U the lid
    speed, L the side of the square cavity and nu the kinematic viscosity (as fluid_metrics
    normalises the profiles: by the lid speed and the domain size)."""
    lid = fluid.lid
    lx, ly = fluid.domain
    if lid is None or lid.side != "top" or lid.speed <= 0:
        raise f.error("table", f"a case {name} describes: a lid on the top side moving in +x "
                      "(fluid.lid = { side = \"top\", speed > 0 })",
                      f"lid {lid.side} at {lid.speed} m/s" if lid is not None
                      else f"{len(fluid.lids)} moving sides")
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
