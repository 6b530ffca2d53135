"""MuJoCo's medium ([effects] medium): the force terms of its two fluid models measured against
their stated formulas, the buoyancy route (gravcomp), the cases against their closed forms, the
inertia-box sphere that differs by construction, and the invariances a medium at rest keeps
(translation of the origin, rotation of the scene) and the one it breaks (a Galilean boost).

Figures are MuJoCo 4.0.0's; docs/engines.md, "Medium", records them.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from crosscheck.engines.mujoco import MujocoEngine
from crosscheck.reference.analytic import SOLUTIONS
from crosscheck.reference.medium_analytic import law
from crosscheck.rotations import axis_angle_to_quat, quat_to_matrix
from crosscheck.scene.loader import load_case

CASES = Path(__file__).resolve().parents[2] / "cases" / "medium"
ENGINE = MujocoEngine()
R, M = 0.1, 2.0  # the raw-MuJoCo probe sphere


def _probe(rho: float, mu: float, geom: str = "", gravcomp: float = 0.0):
    inertia = 0.4 * M * R * R
    xml = (f'<mujoco><compiler inertiafromgeom="false"/>'
           f'<option density="{rho}" viscosity="{mu}" gravity="0 0 -9.81"/><worldbody>'
           f'<body name="b" gravcomp="{gravcomp}"><freejoint/><inertial pos="0 0 0" mass="{M}" '
           f'diaginertia="{inertia} {inertia} {inertia}"/>{geom}</body></worldbody></mujoco>')
    model = mujoco.MjModel.from_xml_string(xml)
    return model, mujoco.MjData(model)


def _fluid_force(model, data, v, w=(0.0, 0.0, 0.0)) -> np.ndarray:
    data.qvel[:3], data.qvel[3:] = v, w
    mujoco.mj_forward(model, data)
    return data.qfrc_fluid.copy()


SPHERE_ELLIPSOID = (f'<geom type="sphere" size="{R}" fluidshape="ellipsoid" contype="0" '
                    'conaffinity="0"/>')


# -- MuJoCo's two models, term by term ------------------------------------------------------------
def test_neither_fluid_model_applies_buoyancy_or_the_added_mass_acceleration():
    # A sphere of volume 4.19e-3 m^3 at rest in a medium of density 1000: buoyancy would be
    # 41 N on a 2 kg body, and an added mass rho V / 2 would slow the start to g M / (M + 2.09).
    # MuJoCo accelerates it at exactly g in both models: neither term exists.
    for geom in ("", SPHERE_ELLIPSOID):
        model, data = _probe(1000.0, 1.0, geom)
        mujoco.mj_forward(model, data)
        np.testing.assert_allclose(data.qacc[:3], [0.0, 0.0, -9.81], rtol=0, atol=1e-12)
    # The ellipsoid model does compute the added masses (geom_fluid[6:9] = V kappa / (2 - kappa),
    # 1/2 V for a sphere; kappa by MuJoCo's quadrature: 5.9e-7 relative), and uses them only in
    # the velocity terms (m_A v) x w (below).
    model, _ = _probe(1000.0, 0.0, SPHERE_ELLIPSOID)
    np.testing.assert_allclose(model.geom_fluid[0, 6:9], 0.5 * 4 / 3 * math.pi * R**3,
                               rtol=2e-6)


def test_inertia_box_terms_on_a_sphere():
    # Equivalent inertia box of a uniform sphere: r_i = sqrt(3 (I_j + I_k - I_i) / (2 M))
    # = sqrt(3/5) r = 0.7746 r; viscous -6 pi mu r_eq v_i, r_eq = mean(r_i); quadratic
    # -2 rho r_j r_k |v_i| v_i per body axis.
    r_box = math.sqrt(0.6) * R
    model, data = _probe(0.0, 1.0)
    f = _fluid_force(model, data, [0.0, 0.0, -1.0])
    assert f[2] == pytest.approx(6 * math.pi * r_box, rel=1e-12)
    t = _fluid_force(model, data, [0.0, 0.0, 0.0], [0.0, 0.0, 1.0])
    assert -t[5] == pytest.approx(8 * math.pi * r_box**3, rel=1e-12)
    model, data = _probe(1000.0, 0.0)
    f = _fluid_force(model, data, [0.0, 0.0, -2.0])
    assert f[2] == pytest.approx(2 * 1000.0 * r_box**2 * 4.0, rel=1e-12)  # 48 N
    # Per axis, not along v: at v = (1, 1, 1) each component is 2 rho r^2 (12 N), so the drag's
    # magnitude is 1/sqrt(3) of what |v| v would give along an axis (a cube's anisotropy).
    f = _fluid_force(model, data, [1.0, 1.0, 1.0])
    np.testing.assert_allclose(f[:3], -2 * 1000.0 * r_box**2, rtol=1e-12)


def test_ellipsoid_terms_on_a_sphere_and_a_box():
    # Sphere: viscous -6 pi mu r v exactly (its equivalent sphere is the sphere), rotational
    # -8 pi mu r^3 w; quadratic -C_blunt rho pi r^2 |v| v and no slender term (A_max = A_proj).
    model, data = _probe(0.0, 1.0, SPHERE_ELLIPSOID)
    assert _fluid_force(model, data, [0.0, 0.0, -1.0])[2] == pytest.approx(6 * math.pi * R,
                                                                          rel=1e-12)
    assert -_fluid_force(model, data, [0.0] * 3, [0, 0, 1.0])[5] == pytest.approx(
        8 * math.pi * R**3, rel=1e-12)
    model, data = _probe(1000.0, 0.0, SPHERE_ELLIPSOID)
    f = _fluid_force(model, data, [1.0, 1.0, 1.0])
    np.testing.assert_allclose(f[:3], -0.5 * 1000.0 * math.pi * R * R * math.sqrt(3), rtol=1e-12)
    # Spinning: Magnus C_M rho V w x v plus the added mass's (m_A v) x w = -1/2 rho V w x v for
    # a sphere: net +1/2 rho V w x v.
    f = _fluid_force(model, data, [1.0, 0.0, 0.0], [0.0, 0.0, 10.0])
    assert f[1] == pytest.approx(0.5 * 1000.0 * 4 / 3 * math.pi * R**3 * 10.0, rel=2e-6)
    # Slender term alone on a box geom (semi-axes 0.1, 0.2, 0.05): rho (A_max - A_proj) v^2 with
    # A_max = pi r_max r_mid (MuJoCo's code), not the 4 pi r_max r_min of its documentation.
    geom = ('<geom type="box" size="0.1 0.2 0.05" fluidshape="ellipsoid" fluidcoef="0 1 0 0 0" '
            'contype="0" conaffinity="0"/>')
    model, data = _probe(1000.0, 0.0, geom)
    a_max = math.pi * 0.2 * 0.1
    for axis, a_proj in enumerate((math.pi * 0.2 * 0.05, math.pi * 0.1 * 0.05,
                                   math.pi * 0.1 * 0.2)):
        v = np.zeros(3)
        v[axis] = 1.0
        assert -_fluid_force(model, data, v)[axis] == pytest.approx(1000.0 * (a_max - a_proj),
                                                                     abs=1e-9)


# -- the adapter ---------------------------------------------------------------------------------
def _case(name: str):
    return load_case(CASES / f"{name}.toml")


def test_buoyancy_is_gravcomp_with_the_shapes_volume():
    scene = _case("rising_sphere")  # 500 kg/m^3 in 1000: buoyancy twice the weight
    sim = ENGINE.build(scene, "rk4", 1e-3)
    mujoco.mj_forward(sim.model, sim.data)
    assert sim.model.body_gravcomp[1] == pytest.approx(2.0, rel=1e-12)
    assert sim.data.qacc[2] == pytest.approx(9.81, rel=1e-12)  # g (rho_f / rho_s - 1), up
    eff = sim.effective()["medium"]
    assert eff["model"] == "ellipsoid" and eff["density"] == 1000.0
    body = eff["bodies"][0]
    assert body["buoyancy_N"] == pytest.approx(1000.0 * 4 / 3 * math.pi * 0.1**3 * 9.81)
    assert body["viscous_force_coefficient"] == pytest.approx(6 * math.pi * 100.0 * 0.1)


def test_the_inertia_box_of_a_sphere_is_read_back():
    scene = _case("stokes_settling")
    scene = replace(scene, engine_options={"mujoco": {"fluid_model": "inertia_box"}})
    body = ENGINE.build(scene, "rk4", 1e-3).effective()["medium"]["bodies"][0]
    np.testing.assert_allclose(body["box_half_sizes"], math.sqrt(0.6) * 0.05, rtol=1e-12)
    # the box's volume is 8 (3/5)^(3/2) r^3 = 3.718 r^3, 0.888 of the sphere's 4.189 r^3
    assert body["box_to_shape_volume"] == pytest.approx(6 * 0.6**1.5 / math.pi, rel=1e-12)


@pytest.mark.parametrize("name", ["stokes_settling", "rising_sphere", "quadratic_sphere",
                                  "quadratic_cube"])
def test_cases_follow_their_closed_forms_under_rk4(name):
    scene = _case(name)
    traj = ENGINE.run(scene, "rk4", scene.run.dt)
    ref = SOLUTIONS["medium_settling"](scene, traj.t)
    lw = law(scene, 0)
    # RK4 at h k <= 0.09: velocity within 5e-8 m/s of the closed form (measured 1e-11 to
    # 2.4e-8); the last sample (17.6 to 19.1 time constants in) is within e^(-kT) ~ 5e-8 of the
    # terminal velocity itself
    assert np.max(np.abs(traj.vel - ref.vel)) < 5e-8
    assert np.max(np.abs(traj.com - ref.com)) < 1e-9
    assert abs(traj.vel[-1, 0] @ lw["n"] - lw["u_t"]) < 1e-7 * lw["u_t"]


def test_buoyancy_sign_light_rises_heavy_sinks_neutral_stays():
    rising, settling = _case("rising_sphere"), _case("stokes_settling")
    assert ENGINE.run(rising, "implicitfast", 1e-3).vel[-1, 0, 2] == pytest.approx(
        0.108028, rel=1e-5)
    assert ENGINE.run(settling, "implicitfast", 1e-3).vel[-1, 0, 2] == pytest.approx(
        -0.0545, rel=1e-6)
    neutral = replace(settling, bodies=(replace(settling.bodies[0],
                                                mass=1000.0 * 4 / 3 * math.pi * 0.05**3),))
    traj = ENGINE.run(neutral, "rk4", 1e-3)
    assert np.max(np.abs(traj.com)) < 1e-12 and np.max(np.abs(traj.vel)) < 1e-12


def test_inertia_box_sphere_differs_from_the_closed_form_by_construction():
    # Stokes: the inertia box's equivalent sphere has r_eq = sqrt(3/5) r, so its viscous drag is
    # 0.7746 of Stokes'; the model has no coefficients, so its quadratic term 1.2 rho r^2 u^2
    # (3.3 % of the drag here) comes with it: terminal velocity (-b + sqrt(b^2 + 4 c F)) / (2 c)
    # with b = 6 pi mu sqrt(3/5) r, c = 1.2 rho r^2, 1.2873 times Stokes' 0.0545 m/s (the viscous
    # term alone would give 1/sqrt(3/5) = 1.2910).
    scene = _case("stokes_settling")
    box = replace(scene, engine_options={"mujoco": {"fluid_model": "inertia_box"}})
    u_box = -ENGINE.run(box, "rk4", 1e-3).vel[-1, 0, 2]
    lw = law(scene, 0)
    b, c = 6 * math.pi * 100.0 * math.sqrt(0.6) * 0.05, 1.2 * 1000.0 * 0.05**2
    u_expected = (-b + math.sqrt(b * b + 4 * c * lw["force"])) / (2 * c)
    # (0.2 s is 14 of the box's longer time constants: e^-14 = 8e-7 of the approach is left)
    assert u_box == pytest.approx(u_expected, rel=3e-6)
    assert u_box / lw["u_t"] == pytest.approx(1.2873, abs=1e-4)
    # Quadratic, face-on: c_box = 2 rho (3/5) r^2 = 1.2 rho r^2 against rho C_D pi r^2 / 2 with
    # C_D = 0.47: terminal velocity sqrt(0.47 pi / 2.4) = 0.7844 of the case's.
    quad = _case("quadratic_sphere")
    box = replace(quad, engine_options={"mujoco": {"fluid_model": "inertia_box"}})
    u_face = -ENGINE.run(box, "rk4", 1e-3).vel[-1, 0, 2]
    assert u_face / law(quad, 0)["u_t"] == pytest.approx(math.sqrt(0.47 * math.pi / 2.4),
                                                         rel=1e-6)
    # The same sphere turned so that it falls along its body diagonal: per-axis drag, each
    # component 1.2 rho r^2 u^2 / 3, so the terminal velocity is 3^(1/4) = 1.316 times larger.
    # The ellipsoid model (|v| v) does not care how a sphere is turned.
    q = axis_angle_to_quat(np.cross([1.0, 1.0, 1.0], [0.0, 0.0, 1.0]),
                           math.acos(1 / math.sqrt(3)))
    assert quat_to_matrix(q) @ (np.ones(3) / math.sqrt(3)) == pytest.approx([0, 0, 1])
    turned = replace(box, bodies=(replace(box.bodies[0], orientation=q),))
    u_diag = -ENGINE.run(turned, "rk4", 1e-3).vel[-1, 0, 2]
    assert u_diag / u_face == pytest.approx(3 ** 0.25, rel=1e-6)
    ellipsoid_turned = replace(quad, bodies=(replace(quad.bodies[0], orientation=q),))
    upright = ENGINE.run(quad, "rk4", 1e-3).vel[:, 0, 2]
    np.testing.assert_allclose(ENGINE.run(ellipsoid_turned, "rk4", 1e-3).vel[:, 0, 2], upright,
                               rtol=1e-12, atol=0)


# -- invariance ----------------------------------------------------------------------------------
def _moved(scene, rot: np.ndarray, shift: np.ndarray, boost: np.ndarray):
    """The scene turned by rot about the origin (gravity and the body with it), moved by shift
    and boosted by boost (world frame, after turning)."""
    from crosscheck.rotations import matrix_to_quat, quat_mul

    body = scene.bodies[0]
    q = quat_mul(matrix_to_quat(rot), body.orientation)
    moved = replace(body, position=rot @ body.position + shift, orientation=q,
                    velocity=rot @ body.velocity + boost)
    effects = replace(scene.effects, gravity=rot @ scene.effects.gravity)
    return replace(scene, bodies=(moved,), effects=effects)


@pytest.mark.parametrize("name,model", [("quadratic_sphere", "ellipsoid"),
                                        ("quadratic_sphere", "inertia_box"),
                                        ("stokes_settling", "ellipsoid")])
def test_translating_and_turning_the_scene_changes_nothing_relative(name, model):
    scene = _case(name)
    options = dict(scene.engine_options.get("mujoco", {}), fluid_model=model)
    if model == "inertia_box":
        options.pop("fluidcoef", None)
    scene = replace(scene, engine_options={"mujoco": options})
    rot = quat_to_matrix(axis_angle_to_quat([0.3, -1.0, 0.5], 0.9))
    shift = np.array([2000.0, -1500.0, 700.0])
    base = ENGINE.run(scene, "rk4", scene.run.dt)
    moved = ENGINE.run(_moved(scene, rot, shift, np.zeros(3)), "rk4", scene.run.dt)
    rel = np.einsum("ij,tj->ti", rot.T, moved.com[:, 0] - moved.com[0, 0])
    scale = np.max(np.abs(base.com[:, 0] - base.com[0, 0]))
    # round-off of positions 2.5 km from the origin (eps x 2.5e3 ~ 6e-13 m per step)
    np.testing.assert_allclose(rel, base.com[:, 0] - base.com[0, 0], rtol=0, atol=1e-9 * scale
                               + 1e-10)
    np.testing.assert_allclose(np.einsum("ij,tj->ti", rot.T, moved.vel[:, 0]), base.vel[:, 0],
                               rtol=0, atol=1e-9 * np.max(np.abs(base.vel)))


def test_a_boost_is_not_a_symmetry_of_a_medium_at_rest():
    # The medium defines a rest frame: a body boosted sideways by V feels the drag of its
    # velocity relative to the medium. Under Stokes' law alone (the stokes_settling case) the
    # components decouple: the sideways velocity decays as V exp(-k t), k = 6 pi mu r / m, and
    # the vertical motion is unchanged.
    scene = _case("stokes_settling")
    boost = np.array([0.5, 0.0, 0.0])
    base = ENGINE.run(scene, "rk4", 1e-3)
    boosted = ENGINE.run(_moved(scene, np.eye(3), np.zeros(3), boost), "rk4", 1e-3)
    k = law(scene, 0)["k"]
    # RK4 at h k = 0.09: ~ V (h k)^4 / 120 / e = 9e-8 m/s (measured 1.1e-7)
    np.testing.assert_allclose(boosted.vel[:, 0, 0], 0.5 * np.exp(-k * boosted.t), rtol=0,
                               atol=3e-7)
    np.testing.assert_allclose(boosted.vel[:, 0, 2], base.vel[:, 0, 2], rtol=0, atol=1e-12)
    # a Galilean-invariant law would have kept V: after 18 time constants it is gone
    assert abs(boosted.vel[-1, 0, 0]) < 1e-6 * 0.5


def test_fused_and_generic_stepping_are_bit_identical_with_a_medium():
    scene = _case("quadratic_sphere")
    generic = replace(scene, engine_options={"mujoco": dict(scene.engine_options["mujoco"],
                                                            stepping="nstep")})
    a, b = ENGINE.run(scene, "euler", 1e-3), ENGINE.run(generic, "euler", 1e-3)
    assert a.meta["effective"]["stepping"].startswith("compiled loop")
    np.testing.assert_array_equal(a.com, b.com)
    np.testing.assert_array_equal(a.vel, b.vel)


def test_engines_without_a_medium_model_say_why():
    from crosscheck.engines import get_engine

    scene = _case("stokes_settling")
    reasons = {name: get_engine(name).not_applicable(scene, get_engine(name).capabilities()
                                                     .default_integrator)
               for name in ("inhouse", "pybullet", "pymunk")}
    assert "no fluid model" in reasons["pybullet"] and "no fluid model" in reasons["pymunk"]
    assert "no stateless medium model" in reasons["inhouse"]
    assert "coupled [fluid] case" in reasons["inhouse"]
    assert ENGINE.not_applicable(scene, "rk4") is None


def test_an_offset_centre_of_mass_is_not_applicable_in_a_dense_medium():
    scene = _case("stokes_settling")
    off = replace(scene, bodies=(replace(scene.bodies[0], com=np.array([0.01, 0.0, 0.0])),))
    reason = ENGINE.not_applicable(off, "rk4")
    assert reason is not None and "centre of buoyancy" in reason


def test_a_long_cylinder_per_unit_length_the_2d_mapping():
    # docs/engines.md, "MuJoCo's stateless medium against a resolved fluid": a 2D disc of radius R
    # maps to a cylinder of length L >> R. Across its axis, per unit length: quadratic drag
    # rho C_D R v^2 with C_D = sqrt(3)/2 (inertia box) or pi/2 C_blunt (ellipsoid); viscous
    # 6 pi mu (r_x + r_y + r_z) / 3 / L -> pi mu as L grows.
    r, length = 0.05, 2.0
    m = 2000.0 * math.pi * r * r * length
    ix, iz = m * (3 * r * r + length**2) / 12, m * r * r / 2
    geom = (f'<geom type="cylinder" size="{r} {length / 2}" fluidshape="ellipsoid" '
            'contype="0" conaffinity="0"/>')
    per_length = {}
    for name, g in (("box", ""), ("ellipsoid", geom)):
        for rho, mu in ((1000.0, 0.0), (0.0, 1.0)):
            xml = (f'<mujoco><compiler inertiafromgeom="false"/><option density="{rho}" '
                   f'viscosity="{mu}"/><worldbody><body><freejoint/><inertial pos="0 0 0" '
                   f'mass="{m}" diaginertia="{ix} {ix} {iz}"/>{g}</body></worldbody></mujoco>')
            model = mujoco.MjModel.from_xml_string(xml)
            data = mujoco.MjData(model)
            per_length[name, rho > 0] = -_fluid_force(model, data, [1.0, 0.0, 0.0])[0] / length
    assert per_length["box", True] / (1000.0 * r) == pytest.approx(math.sqrt(3) / 2, rel=1e-12)
    assert per_length["ellipsoid", True] / (1000.0 * r) == pytest.approx(math.pi / 2 * 0.5,
                                                                         rel=1e-12)
    half = math.sqrt(3) / 2 * r
    assert per_length["box", False] == pytest.approx(
        6 * math.pi * (2 * half + length / 2) / 3 / length, rel=1e-12)  # 1.087 pi here
    assert per_length["ellipsoid", False] == pytest.approx(
        6 * math.pi * (2 * r + length / 2) / 3 / length, rel=1e-12)  # 1.1 pi here
