"""In-house incompressible fluid on a staggered MAC grid with a level-set free surface.

Public entry points: :class:`FluidRun` (what the in-house engine adapter opens for scenes with
``scene.fluid``; the run driver records and times it), :func:`run_fluid` (its accuracy pass
alone), :data:`INTEGRATORS` (the registered integrator names) and :class:`FluidRecord`.
"""

from crosscheck.sim.fluid.record import FluidRecord
from crosscheck.sim.fluid.run import FluidRun, run_fluid
from crosscheck.sim.fluid.solver import DEFAULT_INTEGRATOR, INTEGRATORS, Scheme

__all__ = ["DEFAULT_INTEGRATOR", "INTEGRATORS", "FluidRecord", "FluidRun", "Scheme", "run_fluid"]
