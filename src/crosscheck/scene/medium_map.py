"""A 2D fluid case as MuJoCo's stateless medium: what can be mapped, and the mapped cylinder.

docs/engines.md, "MuJoCo's stateless medium against a resolved fluid", derives the mapping: the
in-house fluid is 2D, its body a prism of unit depth (masses per metre, the body's density the
2D mass per unit area, compared directly with the fluid's). A 2D disc of radius R becomes a
MuJoCo **cylinder** of radius R and length L = ``LENGTH_IN_RADII`` R along the out-of-plane axis
(z: the 2D plane stays MuJoCo's x-y plane, gravity along -y), of the same density, in a medium
of the fluid's density and dynamic viscosity. Every MuJoCo force and the mass scale with L, so
velocities compare directly; the end faces add O(R / L) to the viscous term only (MuJoCo's
viscous radius (2 R + L / 2) / 3 of the ellipsoid, (sqrt(3) R + L / 2) / 3 of the inertia box:
per unit length pi mu (1 + 4 R / L) and pi mu (1 + 2 sqrt(3) R / L), 0.4 % and 0.35 % above
pi mu at L = 1000 R); the quadratic terms are exactly those of the infinite cylinder.

What cannot be mapped is refused, by field (:func:`unmappable`): the stateless medium fills all
space, at rest, around one body, so a free surface, obstacles, open or moving sides, and more
than one body or a shape other than a circle have no counterpart. Walls are kept as a known
difference (the medium is unbounded; a closed domain's walls slow the disc), reported, not
refused: every fluid domain has them.

Scene layer: no engine, no numba; the loader and the MuJoCo adapter both call it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

# L / R of the mapped cylinder: long enough that the end faces' share of the viscous term is
# 0.4 % (above), short enough that MuJoCo's out-of-plane moments stay ~1e5 of the in-plane one
# (no out-of-plane dof exists: the joints are planar).
LENGTH_IN_RADII = 1000.0


def unmappable(scene) -> tuple[str, str, Any] | None:
    """(field path, what is expected, what was found) of the first thing of a fluid case that
    MuJoCo's medium cannot stand for, or None when the mapping applies."""
    fluid = scene.fluid
    if fluid is None:
        return ("fluid", "a [fluid] case (MuJoCo maps a 2D fluid case to a medium)", "none")
    if fluid.has_surface:
        return ("fluid.initial", "no free surface (the domain full of fluid): MuJoCo's medium "
                "fills all space, its buoyancy is the whole rho V g wherever the body is",
                f"{len(fluid.initial)} initial region(s)")
    if fluid.obstacles or scene.statics:
        return ("fluid.obstacles", "no obstacles or statics: MuJoCo's medium has no solid "
                "boundaries", f"{len(fluid.obstacles) + len(scene.statics)} solid(s)")
    sides = {k: v for k, v in fluid.walls.items() if v != "solid"}
    if sides or fluid.inflow is not None:
        return ("fluid.walls", "closed solid sides (a fluid at rest: MuJoCo's medium does not "
                "flow)", sides or "inflow")
    if fluid.lids:
        return ("fluid.lid", "no moving side (a fluid at rest: MuJoCo's medium does not flow)",
                ", ".join(lid.side for lid in fluid.lids))
    if len(fluid.bodies) != 1:
        return ("bodies", "exactly one body in the fluid (the disc the mapped cylinder stands "
                "for)", f"{len(fluid.bodies)} bodies")
    body = fluid.bodies[0]
    if body.shape.kind != "circle":
        return ("bodies[0].shape", "a circle (the cross-section of the mapped MuJoCo cylinder; "
                "a box or polygon has no mapping whose drag law is known in closed form)",
                body.shape.kind)
    if np.linalg.norm(np.asarray(body.com, float)) > 1e-12 * body.shape.radius:
        return ("bodies[0].com", "the centre of mass at the disc's centre (the buoyancy acts at "
                "the centroid; MuJoCo's gravcomp acts at the centre of mass)", list(body.com))
    if fluid.density <= 0.0:
        return ("fluid.density", "a positive density", fluid.density)
    return None


@dataclass(frozen=True)
class MappedCylinder:
    """The MuJoCo body standing for a fluid case's disc (3D mass and moments, SI)."""

    radius: float
    length: float
    mass: float  # kg: the disc's mass per metre times the length
    inertia: tuple[float, float, float]  # principal moments about x, y (diameters), z (axis)
    fluid_density: float
    dynamic_viscosity: float
    gravcomp: float  # rho_f V / m: the buoyancy as a fraction of the weight

    @property
    def volume(self) -> float:
        return math.pi * self.radius ** 2 * self.length


def mapped_cylinder(scene) -> MappedCylinder:
    """The cylinder of a mappable fluid case (see :func:`unmappable`)."""
    why = unmappable(scene)
    if why is not None:
        raise ValueError(f"{scene.source}: {why[0]}: expected {why[1]}, got {why[2]}")
    fluid = scene.fluid
    body = fluid.bodies[0]
    r = float(body.shape.radius)
    length = LENGTH_IN_RADII * r
    mass = float(body.mass) * length
    # A solid cylinder about a diameter: M (3 R^2 + L^2) / 12; about its axis the disc's own
    # moment per metre times L (M R^2 / 2 for a uniform disc, or the case's inertia).
    across = mass * (3.0 * r * r + length * length) / 12.0
    axis = float(body.moment) * length
    return MappedCylinder(radius=r, length=length, mass=mass, inertia=(across, across, axis),
                          fluid_density=float(fluid.density),
                          dynamic_viscosity=float(fluid.dynamic_viscosity),
                          gravcomp=float(fluid.density) * math.pi * r * r / float(body.mass))
