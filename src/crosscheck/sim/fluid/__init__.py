"""In-house incompressible fluid on a staggered MAC grid with a level-set free surface.

Public entry points: :func:`run_fluid` (what the in-house engine adapter calls for scenes with
``scene.fluid``), :data:`INTEGRATORS` (the registered integrator names) and :class:`FluidRecord`.
"""

from crosscheck.sim.fluid.record import FluidRecord
from crosscheck.sim.fluid.solver import DEFAULT_INTEGRATOR, INTEGRATORS, Scheme, run_fluid

__all__ = ["DEFAULT_INTEGRATOR", "INTEGRATORS", "FluidRecord", "Scheme", "run_fluid"]
