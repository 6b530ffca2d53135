"""Every engine's integrator names and what the harness needs to know about each, in ONE place.

Plain data, importing nothing of crosscheck's but the standard library: the case loader
(scene/loader.py) and the runner check names against it without importing an adapter, numba,
MuJoCo, PyBullet or Pymunk (slow, and a missing engine must not break loading).

Per engine, ``RIGID`` lists its rigid-body integrators in the adapter's order (the first is the
engine's default) with, for each:

* ``order``: nominal global order of convergence on smooth motion;
* ``scheme``: the discrete update under constant acceleration, which the engine conformance suite
  derives its tolerances from: ``"velocity_first"`` (v += h a, then x += h v_new: the
  semi-implicit Euler family), ``"position_first"`` (x += h v, then v += h a) or ``"exact"``
  (second order or above: exact for constant acceleration);
* ``symplectic``: symplectic for the whole rigid-body system without damping or drag (rotation
  included: a semi-implicit Euler with an explicit gyroscopic term is not);
* ``contact``: whether crosscheck can run it on a scene with contact (the adapter then builds
  collision shapes and programs the pair values: docs/engines.md, each engine's "Contact").

``FLUID`` lists the engines' grid-fluid schemes (the in-house solver's, crosscheck.sim.fluid),
which are never offered as rigid-body integrators. ``INTEGRATOR_NAMES[engine]`` is what the
adapter's ``capabilities().integrators`` lists: its rigid integrators, then its fluid schemes.

Who reads it: the adapters (their ``INTEGRATORS`` tuples are ``rigid_names(engine)``), the
in-house registry (sim/rigid/integrators.py binds a kernel to every in-house name and refuses a
name not listed here; tests/rigid fail when a name has no kernel or a kernel no name), the case
loader and runner (names), and the engine conformance suite (orders and schemes: an integrator
without one fails, it is never skipped). Adding an in-house integrator: one entry here, its
kernels, one ``bind`` call in sim/rigid/integrators.py.
"""

from __future__ import annotations

from typing import NamedTuple

VELOCITY_FIRST = "velocity_first"
POSITION_FIRST = "position_first"
EXACT = "exact"
SCHEMES = (VELOCITY_FIRST, POSITION_FIRST, EXACT)


class IntegratorInfo(NamedTuple):
    name: str
    order: int
    scheme: str  # VELOCITY_FIRST | POSITION_FIRST | EXACT
    symplectic: bool
    contact: bool = False


def _i(name: str, order: int, scheme: str, symplectic: bool, contact: bool = False):
    assert scheme in SCHEMES, scheme
    return IntegratorInfo(name, order, scheme, symplectic, contact)


RIGID: dict[str, tuple[IntegratorInfo, ...]] = {
    # crosscheck.sim.rigid (docs/inhouse.md, "Integrators"). 2D: every scheme is symplectic
    # or not as in 3D except symplectic_euler_exp, which is symplectic_euler there. ``contact``:
    # the integrator pairs with at least one contact model (CONTACT_MODELS below).
    "inhouse": (
        _i("rk4", 4, EXACT, False, contact=True),
        _i("rk4_exp", 4, EXACT, False, contact=True),
        _i("explicit_euler", 1, POSITION_FIRST, False, contact=True),
        _i("midpoint", 2, EXACT, False, contact=True),
        _i("symplectic_euler", 1, VELOCITY_FIRST, True, contact=True),
        _i("symplectic_euler_exp", 1, VELOCITY_FIRST, False, contact=True),
        _i("verlet", 2, EXACT, True, contact=True),
        _i("implicit_euler", 1, VELOCITY_FIRST, False),
    ),
    # MuJoCo, its default (Euler) first: every single-step integrator updates the velocity first
    # and then the position with the new velocity (computation docs, eq_semimplicit /
    # eq_implicit_update / eq_discrete_update); the gyroscopic term is explicit or linearised, so
    # none is symplectic for a tumbling body. RK4 is the classic fourth-order method.
    "mujoco": (
        _i("euler", 1, VELOCITY_FIRST, False, contact=True),
        _i("rk4", 4, EXACT, False, contact=True),
        # Runs with contact, but chaotic on sliding boxes (docs/engines.md, MuJoCo, trap C9).
        _i("implicit", 1, VELOCITY_FIRST, False, contact=True),
        _i("implicitfast", 1, VELOCITY_FIRST, False, contact=True),
        _i("discrete", 1, VELOCITY_FIRST, False, contact=True),
    ),
    # PyBullet's two kinds of body, both semi-implicit Euler (ENGINES.md); the gyroscopic term is
    # explicit (multibody: a tumbling body gains energy) or implicit (maximal: loses).
    "pybullet": (
        _i("multibody", 1, VELOCITY_FIRST, False, contact=True),
        _i("maximal", 1, VELOCITY_FIRST, False, contact=True),
    ),
    # Pymunk (Chipmunk, 2D): positions first with the old velocities, then the velocities with
    # the forces at the new positions (ENGINES.md: 4.900095 m in 1 s at dt = 1e-3); a kick-drift
    # pair in the other order, symplectic in the plane.
    "pymunk": (
        _i("position_first", 1, POSITION_FIRST, True, contact=True),
    ),
}

# Grid-fluid schemes (crosscheck.sim.fluid.INTEGRATORS, in its order): fluid scenes only.
FLUID: dict[str, tuple[str, ...]] = {
    "inhouse": ("semi_lagrangian", "maccormack", "particle_levelset",
                "particle_levelset_maccormack", "central"),
}

ENGINES: tuple[str, ...] = tuple(RIGID)

# Names a fine-step reference accepts besides its engine's integrators: SciPy's DOP853 on the
# independent Newton-Euler equations (crosscheck.reference.simulated).
FINE_STEP_ONLY: tuple[str, ...] = ("dop853",)


def rigid_names(engine: str) -> tuple[str, ...]:
    """The engine's rigid-body integrators in order (the first is its default)."""
    return tuple(i.name for i in RIGID[engine])


def fluid_names(engine: str) -> tuple[str, ...]:
    return FLUID.get(engine, ())


def integrator_info(engine: str, name: str) -> IntegratorInfo:
    """The entry of one rigid-body integrator; KeyError naming what is known otherwise."""
    for info in RIGID[engine]:
        if info.name == name:
            return info
    raise KeyError(f"{engine} has no rigid-body integrator {name!r}; known: "
                   f"{list(rigid_names(engine))}")


# -- contact models (in-house) -------------------------------------------------------------------
# The in-house engine runs a contact scene with an integrator AND a contact model: the run's name
# is "integrator+model" (e.g. "symplectic_euler+soft_step"), everywhere a name appears (case
# files, --integrators, cell ids, reports). A bare integrator name on a contact scene means that
# integrator with the first model below that pairs with it (resolve_run); the peer engines have
# one contact model each (their own) and never take a "+model".
SEPARATOR = "+"
VELOCITY_LEVEL = "velocity"  # impulses on the velocities inside each step (kick, solve, drift)
FORCE_LEVEL = "force"  # a contact force in every force evaluation, any explicit integrator
EVENT_DRIVEN = "event"  # impulses at the instants of impact, LCP contact forces at rest

_SPLITTING = ("symplectic_euler", "symplectic_euler_exp")
_EXPLICIT = ("rk4", "rk4_exp", "midpoint", "explicit_euler", "verlet", "symplectic_euler",
             "symplectic_euler_exp")


class ContactModelInfo(NamedTuple):
    name: str
    level: str  # VELOCITY_LEVEL | FORCE_LEVEL | EVENT_DRIVEN
    integrators: tuple[str, ...]  # the in-house integrators it pairs with
    summary: str


CONTACT_MODELS: dict[str, tuple[ContactModelInfo, ...]] = {
    # docs/inhouse.md, "Contact": the pipeline, each model's formulation and parameters.
    "inhouse": (
        ContactModelInfo("soft_step", VELOCITY_LEVEL, _SPLITTING,
                         "sub-stepped soft constraints with relaxation (Box2D v3)"),
        ContactModelInfo("sequential_impulse", VELOCITY_LEVEL, _SPLITTING,
                         "projected Gauss-Seidel on velocities with warm starting, restitution "
                         "above a velocity threshold, split-impulse position correction"),
        ContactModelInfo("penalty", FORCE_LEVEL, _EXPLICIT,
                         "Hunt-Crossley spring-damper normal force and Coulomb friction "
                         "(elastic-plastic anchor, or regularised) in every force evaluation"),
        ContactModelInfo("impulse_lcp", EVENT_DRIVEN, _EXPLICIT,
                         "Baraff: impulses with restitution at the time of impact (bisection), "
                         "resting forces from the LCP with Coulomb friction"),
    ),
}


def contact_model_names(engine: str) -> tuple[str, ...]:
    return tuple(m.name for m in CONTACT_MODELS.get(engine, ()))


def contact_model_info(engine: str, name: str) -> ContactModelInfo:
    for info in CONTACT_MODELS.get(engine, ()):
        if info.name == name:
            return info
    raise KeyError(f"{engine} has no contact model {name!r}; known: "
                   f"{list(contact_model_names(engine))}")


def contact_run_names(engine: str) -> tuple[str, ...]:
    """Every "integrator+model" an engine accepts, model by model."""
    return tuple(f"{i}{SEPARATOR}{m.name}" for m in CONTACT_MODELS.get(engine, ())
                 for i in m.integrators)


def split_run(name: str) -> tuple[str, str | None]:
    """("integrator", "model") of a run name; the model is None for a bare integrator."""
    integrator, sep, model = name.partition(SEPARATOR)
    return integrator, (model if sep else None)


def default_model(engine: str, integrator: str) -> str | None:
    """The first contact model that pairs with the integrator, or None."""
    for info in CONTACT_MODELS.get(engine, ()):
        if integrator in info.integrators:
            return info.name
    return None


def resolve_run(engine: str, name: str, contact: bool) -> str:
    """The run name a cell carries: on a contact scene, an in-house bare integrator becomes
    "integrator+its default model" so reports always show both; otherwise unchanged."""
    integrator, model = split_run(name)
    if contact and model is None:
        chosen = default_model(engine, integrator)
        if chosen is not None:
            return f"{integrator}{SEPARATOR}{chosen}"
    return name


def default_contact_run(engine: str) -> str | None:
    """What an engine runs on a contact scene when nothing is asked: the first contact model
    with its first partner integrator (None for an engine without contact models)."""
    models = CONTACT_MODELS.get(engine, ())
    return f"{models[0].integrators[0]}{SEPARATOR}{models[0].name}" if models else None


# -- medium models (MuJoCo) on a fluid case ------------------------------------------------------
# MuJoCo runs a 2D fluid case with one coupled disc and no free surface as a long cylinder in its
# stateless medium (docs/engines.md, "MuJoCo's stateless medium against a resolved fluid"). Its two
# fluid models are two approximations of the same truth (the resolved fluid), as the in-house
# contact models are of one contact, so each is a run: "integrator+model" (e.g. "rk4+ellipsoid"),
# and the runner puts both beside the in-house cell. On a 3D ``[effects] medium`` case the model
# stays the engine option ``fluid_model`` (there the case's truth is exact for one model only).
MEDIUM_MODELS: dict[str, tuple[str, ...]] = {"mujoco": ("inertia_box", "ellipsoid")}


def medium_run_names(engine: str) -> tuple[str, ...]:
    """Every "integrator+model" an engine accepts on a fluid case it maps to a medium."""
    return tuple(f"{i}{SEPARATOR}{m}" for m in MEDIUM_MODELS.get(engine, ())
                 for i in rigid_names(engine))


INTEGRATOR_NAMES: dict[str, tuple[str, ...]] = {
    engine: (rigid_names(engine) + contact_run_names(engine) + medium_run_names(engine)
             + fluid_names(engine))
    for engine in ENGINES}


def all_integrator_names() -> tuple[str, ...]:
    """Every name some engine knows, each once, in engine order."""
    return tuple(dict.fromkeys(n for names in INTEGRATOR_NAMES.values() for n in names))


for _engine, _infos in RIGID.items():  # a name is one thing per engine
    _names = [i.name for i in _infos] + list(FLUID.get(_engine, ()))
    assert len(set(_names)) == len(_names), (_engine, _names)
    assert not any(SEPARATOR in n for n in _names), (_engine, _names)
    for _model in CONTACT_MODELS.get(_engine, ()):  # a model pairs with integrators that exist
        assert set(_model.integrators) <= set(_names), (_engine, _model)
del _engine, _infos, _names
