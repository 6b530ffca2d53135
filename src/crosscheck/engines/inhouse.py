"""The in-house engine adapter: crosscheck's own simulators behind the adapter protocol.

Rigid scenes (2D and 3D, no contact) run on :mod:`crosscheck.sim.rigid`: the Scene is compiled
once into a RigidModel, the Baraff state is stepped by the named integrator of
``crosscheck.sim.rigid.INTEGRATORS`` and sampled on the common sampling plan. The recorded
quantities are exactly the Trajectory convention: the state's x *is* the centre of mass (world),
its q the orientation of the declared body frame, P / m the centre-of-mass velocity and
R I_body^-1 R^T L the world angular velocity, so nothing is converted.

Fluid scenes (``scene.fluid``) are delegated to :func:`crosscheck.sim.fluid.run_fluid`, imported
lazily: if that package cannot be imported the scene is "not applicable" with the reason.

A blow-up (non-finite state, or energy running away beyond RUNAWAY_FACTOR times what the scene's
forces can supply) ends the run early and is reported through ``meta["failure"]`` with its time;
the adapter never raises for it.
"""

from __future__ import annotations

import importlib
from typing import Any

from crosscheck.engines.base import Capabilities, EngineBase, sampling_plan
from crosscheck.scene.model import Scene
from crosscheck.sim.rigid import INTEGRATORS
from crosscheck.sim.rigid.simulation import RUNAWAY_FACTOR, simulate
from crosscheck.state import Trajectory

SHAPES = frozenset({"sphere", "box", "capsule", "cylinder", "mesh", "circle", "polygon"})
RIGID_EFFECTS = frozenset({"gravity", "springs", "drag", "loads"})
OPTIONS = {"runaway_factor": float}  # [engine_options.inhouse] keys a case may pin

# The discrete update each integrator applies under constant acceleration and its order, for the
# engine conformance suite (tests/engines/conftest.py): "velocity_first" v += h a then x += h v,
# "position_first" x += h v then v += h a, "exact" second order or above.
INTEGRATOR_SCHEMES = {
    "rk4": (4, "exact"),
    "rk4_exp": (4, "exact"),
    "explicit_euler": (1, "position_first"),
    "midpoint": (2, "exact"),
    "symplectic_euler": (1, "velocity_first"),
    "symplectic_euler_exp": (1, "velocity_first"),
    "verlet": (2, "exact"),
    "implicit_euler": (1, "velocity_first"),
}


def _fluid_module():
    """(module, None) or (None, reason) for the in-house fluid solver."""
    try:
        module = importlib.import_module("crosscheck.sim.fluid")
    except Exception as exc:  # noqa: BLE001 - any import failure makes fluid not applicable
        return None, f"the in-house fluid solver cannot be imported ({type(exc).__name__}: {exc})"
    if not hasattr(module, "run_fluid"):
        return None, "crosscheck.sim.fluid has no run_fluid yet"
    return module, None


def _fluid_integrators() -> tuple[str, ...]:
    module, _ = _fluid_module()
    if module is None:
        return ()
    return tuple(getattr(module, "INTEGRATORS", ()) or ())


class InhouseEngine(EngineBase):
    name = "inhouse"
    integrator_schemes = INTEGRATOR_SCHEMES

    def capabilities(self) -> Capabilities:
        rigid = tuple(INTEGRATORS)  # rk4 first: the default
        fluid = tuple(n for n in _fluid_integrators() if n not in INTEGRATORS)
        notes = {name: integ.note for name, integ in INTEGRATORS.items()}
        notes.update({name: "fluid scenes only (crosscheck.sim.fluid)" for name in fluid})
        effects = set(RIGID_EFFECTS)
        if _fluid_module()[0] is not None:
            effects.add("fluid")
        return Capabilities(dimensions=frozenset({2, 3}), shapes=SHAPES,
                            effects=frozenset(effects), integrators=rigid + fluid, notes=notes)

    def version(self) -> str:
        import numba

        import crosscheck

        return f"crosscheck {crosscheck.__version__} (numba {numba.__version__})"

    def not_applicable(self, scene: Scene, integrator: str) -> str | None:
        if scene.fluid is not None or scene.effects.fluid:
            module, reason = _fluid_module()
            if module is None:
                return reason
            names = tuple(getattr(module, "INTEGRATORS", ()) or ())
            if names and integrator not in names:
                return (f"{integrator!r} is not a fluid integrator "
                        f"(fluid integrators: {list(names)})")
            return None
        if scene.effects.contact:
            return "the in-house rigid simulator has no contact yet"
        if integrator not in INTEGRATORS:
            return (f"inhouse has no rigid-body integrator {integrator!r} "
                    f"(it has {list(INTEGRATORS)})")
        return super().not_applicable(scene, integrator)

    def check_options(self, scene: Scene) -> None:
        self._options(scene)  # raises CaseError on an unknown key

    def _options(self, scene: Scene) -> dict[str, Any]:
        from crosscheck.errors import CaseError

        raw = dict(scene.engine_options.get(self.name, {}))
        unknown = sorted(set(raw) - set(OPTIONS))
        if unknown:
            raise CaseError(scene.source or scene.name, f"engine_options.{self.name}",
                            f"options among {sorted(OPTIONS)}", unknown)
        return {k: OPTIONS[k](v) for k, v in raw.items()}

    def run(self, scene: Scene, integrator: str, dt: float) -> Trajectory | Any:
        reason = self.not_applicable(scene, integrator)
        if reason is not None:
            from crosscheck.errors import EngineUnavailable

            raise EngineUnavailable(f"inhouse: {reason}")
        if scene.fluid is not None or scene.effects.fluid:
            return self._run_fluid(scene, integrator, dt)
        options = self._options(scene)
        plan = sampling_plan(scene, dt)
        rec, info = simulate(scene, integrator, dt, plan=plan,
                             runaway_factor=options.get("runaway_factor", RUNAWAY_FACTOR))
        meta = self.base_meta(scene, integrator, dt)
        meta.update({
            "wall_time": info.wall_time,
            "compile_time": info.compile_time,
            "steps": info.steps,
            "effective": dict(info.settings, energy_scale=info.energy_scale,
                              gravity=None if scene.effects.gravity is None
                              else list(map(float, scene.effects.gravity)),
                              damping="only the declared drag and spring damping",
                              contact=False),
        })
        return rec.finish(meta)

    def _run_fluid(self, scene: Scene, integrator: str, dt: float):
        module, reason = _fluid_module()
        if module is None:  # pragma: no cover - not_applicable said so already
            from crosscheck.errors import EngineUnavailable

            raise EngineUnavailable(f"inhouse: {reason}")
        record = module.run_fluid(scene, integrator, dt)
        meta = getattr(record, "meta", None)
        if isinstance(meta, dict):
            for key, value in self.base_meta(scene, integrator, dt).items():
                meta.setdefault(key, value)
        return record
