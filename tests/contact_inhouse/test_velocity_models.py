"""The velocity-level contact models, sequential_impulse and soft_step (docs/inhouse.md,
"Contact"): the solver on hand-filled contact rows, conservation through body-body impacts,
dissipation, stacks and mass ratios, determinism, and the adapter's plumbing (parameters,
effective settings, buffer overflow).

The analytic contact cases run through the cell runner in test_contact_cases.py.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from crosscheck.engines.inhouse import InhouseEngine, InhouseSession
from crosscheck.engines.session import StepFailure
from crosscheck.errors import CaseError
from crosscheck.scene.loader import load_case, load_case_text
from crosscheck.sim.collide import Contacts
from crosscheck.sim.rigid import compile_model, state_from_scene
from crosscheck.sim.rigid.contact_models import CONTACT_KERNELS
from crosscheck.sim.rigid.contact_rows import (
    ROTATION_SPLITTING,
    SEQUENTIAL_IMPULSE,
    SOFT_STEP,
    Settings,
    make_rows,
)

MODELS = ("sequential_impulse", "soft_step")
HERE = Path(__file__).resolve().parent
CASES = str(HERE.parents[1] / "cases" / "contact")


def _session(scene, model: str, integrator: str = "symplectic_euler") -> InhouseSession:
    return InhouseEngine().open(scene, f"{integrator}+{model}", scene.run.dt)


def _momenta(scene, state):
    """Total linear momentum and angular momentum about the origin (3D: vectors; 2D: L scalar)."""
    P = state.P.sum(axis=0)
    if scene.dimension == 3:
        L = np.cross(state.x, state.P).sum(axis=0) + state.L.sum(axis=0)
    else:
        L = (state.x[:, 0] * state.P[:, 1] - state.x[:, 1] * state.P[:, 0]).sum() + state.L.sum()
    return P, np.atleast_1d(L)


def _energy(scene, state, model) -> float:
    """Kinetic plus gravitational potential energy."""
    b = model.bodies
    e = 0.5 * float((state.P ** 2).sum(axis=1) @ b.inv_mass)
    if scene.dimension == 3:
        from crosscheck.rotations import quat_to_matrix

        R = quat_to_matrix(state.rot)
        inv_world = np.einsum("nij,njk,nlk->nil", R, b.inv_inertia, R)
        e += 0.5 * float(np.einsum("ni,nij,nj->", state.L, inv_world, state.L))
    else:
        e += 0.5 * float(state.L ** 2 @ b.inv_moment)
    g = np.asarray(scene.effects.gravity_vector(scene.dimension), float)
    return e - float((b.mass[:, None] * state.x * g).sum())


# -- the registry and the adapter ------------------------------------------------------------------
def test_both_models_are_registered_with_their_parameters():
    assert set(MODELS) <= set(CONTACT_KERNELS)
    si = CONTACT_KERNELS["sequential_impulse"].parameters
    soft = CONTACT_KERNELS["soft_step"].parameters
    assert {"iterations", "tolerance", "position_iterations", "baumgarte", "slop",
            "restitution_threshold", "warm_starting", "margin", "capacity"} == set(si)
    assert {"substeps", "iterations", "relax_iterations", "contact_hertz", "damping_ratio",
            "push_speed", "restitution_threshold", "warm_starting", "margin",
            "capacity"} == set(soft)
    caps = InhouseEngine().capabilities()
    assert "contact" in caps.effects
    for model in MODELS:
        for integ in ("symplectic_euler", "symplectic_euler_exp"):
            assert f"{integ}+{model}" in caps.integrators


_BOX_ON_GROUND = """
[case]
name = "box-on-ground"
dimension = 3
[run]
duration = 0.1
dt = 1e-3
[effects]
gravity = [0.0, 0.0, -9.81]
contact = true
[ground]
[[bodies]]
name = "box"
shape = { box = { size = [0.2, 0.2, 0.2] } }
mass = 1.0
position = [0.0, 0.0, 0.1]
"""


@pytest.mark.parametrize("options, field", [
    ("[engine_options.inhouse]\nsubsteps = 8", "engine_options.inhouse.substeps"),
    ("[engine_options.inhouse.soft_step]\nsubstep = 8", "engine_options.inhouse.soft_step.substep"),
    ("[engine_options.inhouse.soft_step]\nsubsteps = 8.5",
     "engine_options.inhouse.soft_step.substeps"),
    ("[engine_options.inhouse.soft_step]\nsubsteps = 0",
     "engine_options.inhouse.soft_step.substeps"),
    ("[engine_options.inhouse.sequential_impulse]\nbaumgarte = 1.5",
     "engine_options.inhouse.sequential_impulse.baumgarte"),
    ("[engine_options.inhouse.sequential_impulse]\nwarm_starting = 1",
     "engine_options.inhouse.sequential_impulse.warm_starting"),
    ("[engine_options.inhouse]\nsoft_step = 3", "engine_options.inhouse.soft_step"),
    ("[engine_options.inhouse.penalty]\ndamping_law = 3",
     "engine_options.inhouse.penalty.damping_law"),
])
def test_unknown_or_bad_options_are_case_errors_naming_the_field(options, field):
    scene = load_case_text(_BOX_ON_GROUND + options)
    with pytest.raises(CaseError) as err:
        InhouseEngine().not_applicable(scene, "symplectic_euler+soft_step")
    assert err.value.field == field


def test_options_reach_the_model_and_effective_reports_them():
    scene = load_case_text(_BOX_ON_GROUND + """
[engine_options.inhouse]
runaway_factor = 1e7
[engine_options.inhouse.soft_step]
substeps = 8
contact_hertz = 50
[engine_options.inhouse.sequential_impulse]
iterations = 12
""")
    engine = InhouseEngine()
    assert engine.not_applicable(scene, "symplectic_euler+soft_step") is None
    assert engine.runaway_factor(scene) == 1e7
    s = _session(scene, "soft_step")
    s.advance(5)
    eff = s.effective(())["contact"]
    assert eff["model"] == "soft_step" and eff["level"] == "velocity"
    assert eff["parameters"]["substeps"] == 8 and eff["parameters"]["contact_hertz"] == 50.0
    assert eff["parameters"]["iterations"] == 2  # the default
    assert eff["contact_hertz_effective"] == 50.0 and eff["static_contact_hertz_effective"] == 100.0
    s = _session(scene, "sequential_impulse", "symplectic_euler_exp")
    s.advance(5)
    eff = s.effective(())
    assert eff["integrator"] == "symplectic_euler_exp"
    assert eff["contact"]["parameters"]["iterations"] == 12
    assert eff["contact"]["rotation_update"] == "exp"
    assert 1 <= eff["contact"]["sweeps_per_step_mean"] <= 12


@pytest.mark.parametrize("model", MODELS)
def test_a_contact_buffer_overflow_is_a_step_failure(model):
    scene = load_case_text(_BOX_ON_GROUND + f"[engine_options.inhouse.{model}]\ncapacity = 3\n")
    s = _session(scene, model)
    with pytest.raises(StepFailure, match="contact buffer overflow.*4 contact rows.*holds 3"):
        s.advance(10)


# -- the solver on hand-filled rows ---------------------------------------------------------------
_TWO_BOXES = """
[case]
name = "two-boxes"
dimension = 3
[run]
duration = 0.01
dt = 1e-3
[effects]
contact = true
[[bodies]]
name = "a"
shape = { box = { size = [0.4, 0.2, 0.3] } }
mass = 2.0
position = [0.0, 0.0, 0.0]
velocity = [1.0, 0.3, -0.2]
angular_velocity = [0.5, -1.0, 2.0]
orientation = { axis = [1.0, 2.0, 3.0], angle = 0.4 }
[[bodies]]
name = "b"
shape = { box = { size = [0.1, 0.3, 0.2] } }
mass = 0.7
position = [0.35, 0.1, 0.05]
velocity = [-1.5, 0.1, 0.4]
angular_velocity = [-3.0, 1.0, 0.5]
"""


def _hand_filled(dim, rows_spec):
    c = Contacts.empty(8, dim)
    for r, (a, b, normal, point, depth, mu, e) in enumerate(rows_spec):
        c.a[r], c.b[r] = a, b
        c.normal[r] = np.asarray(normal, float) / np.linalg.norm(normal)
        c.point[r] = point
        c.depth[r] = depth
        c.friction[r] = mu
        c.restitution[r] = e
        c.feature[r] = r
    c.count[0] = c.needed[0] = len(rows_spec)
    return c


def _settings(model, iterations=50):
    return Settings(model=model, rotation=ROTATION_SPLITTING, warm_starting=1,
                    substeps=4 if model == SOFT_STEP else 1, iterations=iterations,
                    relax_iterations=1, position_iterations=10, tolerance=0.0,
                    restitution_threshold=0.1, baumgarte=0.2, slop=1e-5, contact_hertz=0.0,
                    damping_ratio=10.0, push_speed=3.0)


@pytest.mark.parametrize("model", [SEQUENTIAL_IMPULSE, SOFT_STEP])
def test_hand_filled_rows_conserve_momentum_and_stop_the_approach(model):
    from crosscheck.sim.rigid.velocity3d import new_scratch3d, step3d

    scene = load_case_text(_TWO_BOXES)
    m = compile_model(scene)
    state = state_from_scene(m, scene)
    # two points of a face contact between the boxes, normal from a to b, plus one oblique;
    # depths within the slop (a split impulse moves positions, which moves sum x x P: that is
    # position correction, not an impulse)
    contacts = _hand_filled(3, [
        (0, 1, [1.0, 0.2, 0.1], [0.2, 0.05, 0.05], 0.0, 0.6, 0.0),
        (0, 1, [1.0, 0.2, 0.1], [0.2, 0.15, -0.03], 5e-6, 0.6, 0.0),
        (0, 1, [0.8, -0.3, 0.5], [0.18, 0.0, 0.12], 0.0, 0.3, 0.5)])
    rows = make_rows(8)
    P0, L0 = _momenta(scene, state)
    q0 = state.rot.copy()
    step3d(*m.kernel_args(), None, contacts, rows, _settings(model), new_scratch3d(2),
           *state.arrays(), 1e-3)
    P1, L1 = _momenta(scene, state)
    # equal and opposite impulses: conserved to round-off (momenta of order 1)
    np.testing.assert_allclose(P1, P0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(L1, L0, rtol=0, atol=1e-13)
    assert rows.total_normal[:3].sum() > 0.1  # the rows pushed (normal impulse this step)
    if model == SEQUENTIAL_IMPULSE:  # converged rigid rows: no row approaches after the solve
        from crosscheck.rotations import quat_to_matrix

        R = quat_to_matrix(q0)
        w = np.einsum("nij,njk,nlk,nl->ni", R, m.bodies.inv_inertia, R, state.L)
        v = state.P * m.bodies.inv_mass[:, None]
        for c in range(3):
            dv = (v[1] + np.cross(w[1], rows.rb[c])) - (v[0] + np.cross(w[0], rows.ra[c]))
            assert dv @ rows.n[c] >= -1e-9
    # every impulse inside its Coulomb disc
    mu = contacts.friction[:3]
    assert np.all(np.hypot(rows.impulse[:3, 1], rows.impulse[:3, 2])
                  <= mu * rows.impulse[:3, 0] * (1 + 1e-12) + 1e-15)


def test_hand_filled_rows_in_2d_conserve_momentum():
    from crosscheck.sim.rigid.velocity2d import new_scratch2d, step2d

    scene = load_case_text("""
[case]
name = "two-boxes-2d"
dimension = 2
[run]
duration = 0.01
dt = 1e-3
[effects]
contact = true
[[bodies]]
name = "a"
shape = { box = { size = [0.4, 0.2] } }
mass = 2.0
position = [0.0, 0.0]
velocity = [1.0, 0.3]
angular_velocity = 2.0
orientation = 0.3
[[bodies]]
name = "b"
shape = { box = { size = [0.1, 0.3] } }
mass = 0.7
position = [0.3, 0.1]
velocity = [-1.5, 0.1]
angular_velocity = -3.0
""")
    m = compile_model(scene)
    for model in (SEQUENTIAL_IMPULSE, SOFT_STEP):
        state = state_from_scene(m, scene)
        contacts = _hand_filled(2, [(0, 1, [1.0, 0.2], [0.2, 0.05], 0.0, 0.6, 0.5),
                                    (0, 1, [1.0, 0.2], [0.18, 0.15], 5e-6, 0.6, 0.5)])
        P0, L0 = _momenta(scene, state)
        step2d(*m.kernel_args(), None, contacts, make_rows(8), _settings(model),
               new_scratch2d(m.bodies, 2), *state.arrays(), 1e-3)
        P1, L1 = _momenta(scene, state)
        np.testing.assert_allclose(P1, P0, rtol=0, atol=1e-14)
        np.testing.assert_allclose(L1, L0, rtol=0, atol=1e-14)


# -- conservation and dissipation through detection ---------------------------------------------
_ZERO_G_IMPACTS = """
[case]
name = "zero-g-impacts"
dimension = 3
[run]
duration = 0.6
dt = 1e-3
[effects]
contact = true
[materials.rubber]
friction = 0.6
restitution = 0.4
[[bodies]]
name = "box"
shape = { box = { size = [0.3, 0.2, 0.1] } }
mass = 1.5
position = [0.0, 0.0, 0.0]
velocity = [0.8, 0.05, 0.0]
angular_velocity = [1.0, 2.0, -3.0]
material = "rubber"
[[bodies]]
name = "ball"
shape = { sphere = { radius = 0.1 } }
mass = 0.5
position = [0.45, 0.06, 0.03]
velocity = [-0.6, 0.0, 0.1]
angular_velocity = [0.0, 5.0, 0.0]
material = "rubber"
[[bodies]]
name = "slab"
shape = { box = { size = [0.1, 0.4, 0.4] } }
mass = 3.0
position = [-0.45, 0.0, 0.0]
velocity = [0.3, 0.0, 0.0]
orientation = { axis = [0.0, 0.0, 1.0], angle = 0.3 }
material = "rubber"
"""


@pytest.mark.parametrize("integrator", ["symplectic_euler", "symplectic_euler_exp"])
@pytest.mark.parametrize("model", MODELS)
def test_body_body_impacts_without_gravity_conserve_momentum(model, integrator):
    scene = load_case_text(_ZERO_G_IMPACTS)
    s = _session(scene, model, integrator)
    P0, L0 = _momenta(scene, s.state)
    v0 = s.state.P.copy()
    touched = 0
    for _ in range(60):
        s.advance(10)
        touched = max(touched, s.contact.contacts.n)
        P, L = _momenta(scene, s.state)
        np.testing.assert_allclose(P, P0, rtol=0, atol=1e-13)
        np.testing.assert_allclose(L, L0, rtol=0, atol=1e-12)
    assert touched > 0 and not np.allclose(s.state.P, v0, atol=0.05)  # they did collide


_DISSIPATIVE = """
[case]
name = "dissipative"
dimension = 3
[run]
duration = 1.5
dt = 1e-3
[effects]
gravity = [0.0, 0.0, -9.81]
contact = true
[materials.clay]
friction = 0.5
restitution = 0.3
[ground]
material = "clay"
[[bodies]]
name = "box"
shape = { box = { size = [0.3, 0.2, 0.1] } }
mass = 1.5
position = [0.0, 0.0, 0.4]
velocity = [0.8, 0.0, 0.0]
angular_velocity = [2.0, 3.0, -1.0]
orientation = { axis = [1.0, 1.0, 0.0], angle = 0.5 }
material = "clay"
[[bodies]]
name = "ball"
shape = { sphere = { radius = 0.08 } }
mass = 0.5
position = [0.05, 0.02, 0.8]
velocity = [-0.3, 0.0, 0.0]
material = "clay"
[[bodies]]
name = "capsule"
shape = { capsule = { radius = 0.05, length = 0.2 } }
mass = 0.4
position = [-0.3, 0.1, 0.3]
orientation = { axis = [0.0, 1.0, 0.0], angle = 1.0 }
angular_velocity = [0.0, 0.0, 4.0]
material = "clay"
"""


@pytest.mark.parametrize("integrator", ["symplectic_euler", "symplectic_euler_exp"])
@pytest.mark.parametrize("model", MODELS)
def test_no_energy_gain_in_a_dissipative_scene(model, integrator):
    """Friction and e < 1: the energy may only fall. Between two contact-free steps symplectic
    Euler's own energy error is 1/2 m g^2 dt^2 per step (and splitting's rotational error), so
    the bound is checked on the running maximum with that allowance."""
    scene = load_case_text(_DISSIPATIVE)
    s = _session(scene, model, integrator)
    m = s.sim.model
    e0 = _energy(scene, s.state, m)
    allowance = 0.5 * float(m.bodies.mass.sum()) * 9.81 ** 2 * 1e-6 * 1500  # m g^2 dt^2 / 2 n
    energies = []
    for _ in range(150):
        s.advance(10)
        energies.append(_energy(scene, s.state, m))
    assert max(energies) <= e0 + allowance
    assert energies[-1] < 0.5 * e0  # and it did dissipate


# -- stacks and mass ratios ---------------------------------------------------------------------
@pytest.mark.slow
@pytest.mark.parametrize("model", MODELS)
def test_a_stack_of_ten_boxes_stands_ten_seconds(model):
    scene = load_case(f"{CASES}/stack_10.toml")
    s = _session(scene, model)
    x0 = s.state.x.copy()
    drift = 0.0
    for _ in range(100):
        s.advance(100)
        drift = max(drift, float(np.linalg.norm(s.state.x - x0, axis=1).max()))
    # measured: sequential_impulse 8.9e-7 m, soft_step 2.5e-5 m (its soft contacts' depth)
    assert drift < 1e-3


@pytest.mark.parametrize("ratio", [100, 1000])
@pytest.mark.parametrize("model", MODELS)
def test_mass_ratios_rest_without_sinking(model, ratio):
    scene = load_case(f"{CASES}/mass_ratio_{ratio}.toml")
    s = _session(scene, model)
    x0 = s.state.x.copy()
    worst = 0.0
    for _ in range(200):
        s.advance(10)
        worst = max(worst, float(np.abs(s.state.x - x0).max()))
    # sequential_impulse: rigid rows, measured 2.2e-7 m (100:1) and 1.2e-5 m (1000:1);
    # soft_step: its soft contact's static depth M g / (m_light w^2) at w = 2 pi 1000 Hz,
    # 0.25 mm at 1000:1: measured 3.7e-5 m (100:1), 5.5e-4 m at worst (1000:1, transient)
    assert worst < (1e-4 if model == "sequential_impulse" or ratio == 100 else 1e-3)


# -- determinism ----------------------------------------------------------------------------------
def _final_hash(path: str, model: str, steps: int) -> str:
    scene = load_case(path)
    s = _session(scene, model)
    s.advance(steps)
    digest = hashlib.sha256()
    for a in s.state.arrays():
        digest.update(np.ascontiguousarray(a).tobytes())
    return digest.hexdigest()


@pytest.mark.parametrize("model", MODELS)
def test_the_final_state_is_bit_identical_run_to_run(model):
    """Box2D-style determinism: the same state's hash twice in this process and once in a
    fresh one (no parallel reduction anywhere in the step)."""
    import subprocess
    import sys

    path = f"{CASES}/sphere_pile.toml"
    first = _final_hash(path, model, 400)
    assert _final_hash(path, model, 400) == first
    code = (f"import sys; sys.path.insert(0, {str(HERE)!r}); "
            "from test_velocity_models import _final_hash; "
            f"print(_final_hash({path!r}, {model!r}, 400))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=900, check=True)
    assert out.stdout.strip().splitlines()[-1] == first


@pytest.mark.slow
def test_end_states_are_identical_across_worker_counts(tmp_path):
    import json
    import subprocess
    import sys

    ends = []
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        subprocess.run([sys.executable, "-m", "crosscheck.cli", "run",
                        f"{CASES}/sphere_pile.toml", f"{CASES}/pyramid_2d.toml", "--engines",
                        "inhouse", "--integrators",
                        "symplectic_euler+soft_step,symplectic_euler+sequential_impulse",
                        "--out", str(out), "--no-cost", "--workers", str(workers),
                        "--progress", "none"], check=True, capture_output=True, timeout=1800)
        cells = [json.loads(line) for line in (out / "cells.jsonl").read_text().splitlines()]
        ends.append({c["id"]: c["end_state"] for c in cells if c.get("kind") == "cell"})
    assert len(ends[0]) == 4 and ends[0] == ends[1]


# -- what a contact leaves alone -----------------------------------------------------------------
@pytest.mark.parametrize("integrator", ["symplectic_euler", "symplectic_euler_exp"])
@pytest.mark.parametrize("model", MODELS)
def test_a_body_no_contact_touches_steps_as_the_contact_free_integrator(model, integrator):
    scene = load_case_text(_DISSIPATIVE.replace('position = [-0.3, 0.1, 0.3]',
                                                'position = [5.0, 0.1, 3.0]'))
    s = _session(scene, model, integrator)
    from crosscheck.sim.rigid import INTEGRATORS

    free = state_from_scene(s.sim.model, scene)
    k = 4 if model == "soft_step" else 1  # soft_step sub-steps every body (Box2D v3)
    for _ in range(20):
        s.advance(25)
        INTEGRATORS[integrator].advance(s.sim.model, free, None, None, 25 * k, scene.run.dt / k)
    for got, want in zip(s.state.arrays(), free.arrays(), strict=True):
        np.testing.assert_array_equal(got[2], want[2])  # the capsule, bit for bit
    assert not np.array_equal(s.state.x[1], free.x[1])  # the ball did hit something
