"""The integrator names of every engine, without importing any engine.

The case loader refuses a name no engine knows (``run.integrators``, ``reference.integrator``,
tolerance keys) and the runner refuses one given to ``--integrators``. Both must work without
importing the adapters, which import numba kernels, MuJoCo, PyBullet and Pymunk (slow, and a
missing engine must not break loading). The adapters' own tuples stay the source of truth for
what they run; tests/foundation/test_integrator_names.py fails when this table and an adapter's
``capabilities().integrators`` (or the in-house rigid and fluid registries) disagree.

Each tuple is in the adapter's order: the first entry is the engine's default integrator.
Whether an integrator applies to a scene (a fluid scheme on a rigid case, Pymunk on a 3D case)
is not decided here: the adapter reports that at run time as "not applicable".
"""

from __future__ import annotations

INTEGRATOR_NAMES: dict[str, tuple[str, ...]] = {
    # crosscheck.sim.rigid.INTEGRATORS (registration order), then the fluid schemes of
    # crosscheck.sim.fluid.INTEGRATORS, as InhouseEngine.capabilities() lists them.
    "inhouse": ("rk4", "rk4_exp", "explicit_euler", "midpoint", "symplectic_euler",
                "symplectic_euler_exp", "verlet", "implicit_euler",
                "semi_lagrangian", "maccormack", "particle_levelset",
                "particle_levelset_maccormack"),
    # crosscheck.engines.mujoco.INTEGRATORS
    "mujoco": ("euler", "rk4", "implicit", "implicitfast", "discrete"),
    # crosscheck.engines.pybullet.INTEGRATORS
    "pybullet": ("multibody", "maximal"),
    # crosscheck.engines.pymunk.INTEGRATORS
    "pymunk": ("position_first",),
}

# Names a fine-step reference accepts besides its engine's integrators: SciPy's DOP853 on the
# independent Newton-Euler equations (crosscheck.reference.simulated).
FINE_STEP_ONLY: tuple[str, ...] = ("dop853",)


def all_integrator_names() -> tuple[str, ...]:
    """Every name some engine knows, each once, in engine order."""
    return tuple(dict.fromkeys(n for names in INTEGRATOR_NAMES.values() for n in names))
