"""Re-export of :mod:`crosscheck.names`, the one table of every engine's integrators (kept for
importers of the old location; new code imports crosscheck.names)."""

from crosscheck.names import (  # noqa: F401
    FINE_STEP_ONLY,
    INTEGRATOR_NAMES,
    all_integrator_names,
)
