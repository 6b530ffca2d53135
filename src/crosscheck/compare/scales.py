"""The yardsticks relative metrics divide by, and which quantities a scene conserves.

Every relative drift in crosscheck is ``max_t |Q(t) - Q(0)| / S`` with a scale ``S`` that is
stated here, is positive whenever anything in the scene moves, and is never taken from the
quantity's own (possibly drifting) value at a single instant. The formulas are repeated in
docs/metrics.md.

Body size
    ``r_i``: the radius of the smallest sphere (circle in 2D) about the body's centre of mass that
    holds its shape: sphere/circle ``r``; box ``|size| / 2`` (offset by the centre of mass);
    capsule ``r + L/2``; cylinder ``sqrt(r^2 + (L/2)^2)``; mesh and polygon the largest vertex
    distance from the centre of mass.

Energy scale
    ``S_E = max(max_t T(t), E_floor)`` with ``T`` the total kinetic energy, taken along the
    *reference* trajectory when the case has one that defines velocities (so a run that gains
    energy does not inflate its own yardstick) and along the run itself otherwise (only its
    samples before a blow-up, if it blew up; a run that gains energy steadily still inflates its
    scale by the gain, a second-order effect: 18 % gain reads as 15 % drift). For a
    conservative system ``max_t T = E - min_t V``: the energy that actually moves between its
    kinetic and potential forms, independent of the potential's datum. ``E_floor = sum_i m_i |g|
    r_i`` (the work to lift each body by its own size; zero without gravity) keeps the scale
    honest for a scene that barely moves under gravity (a body resting on the ground).

Linear momentum scale
    ``S_P = max_t sum_i m_i (|v_i(t)| + |w_i(t)| r_i)``: each body's momentum plus what its rim
    carries, so a pure spin with the centre of mass at rest still has a scale. Like ``S_L`` below
    it is taken along the run's samples before any blow-up.

Angular momentum scale (about the system's centre of mass ``c``)
    ``S_L = max_t sum_i (|I_i(t) w_i(t)| + m_i |x_i - c| |v_i - v_c| + m_i r_i |v_i|)``: the sum of
    the magnitudes of every contribution to ``L`` (so ``|L| <= S_L``) plus a rim term so a body
    that only translates still has a scale.

Available energy (blow-up bound)
    ``E_avail = T(0) + V_springs(0) + sum_i |F_i| (|v_i(0)| D + |F_i| D^2 / (2 m_i))
    + sum_i |tau_i| (|w_i(0)| D + |tau_i| D^2 / (2 I_min,i)) + E_floor``, with ``F_i = m_i g +
    sum of the constant loads on i``, ``tau_i`` the constant torques and ``D`` the duration: a
    generous upper bound on the energy the scene can exchange in the whole run. An energy error
    beyond :data:`BLOWUP_FACTOR` times this bound cannot be physics and marks a blow-up.
"""

from __future__ import annotations

import numpy as np

from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory

# |E(t) - E(0)| > BLOWUP_FACTOR * E_avail marks a blow-up (see the module docstring).
BLOWUP_FACTOR = 10.0


def body_radius(body) -> float:
    """Radius of the smallest sphere about the centre of mass that holds the shape (module doc)."""
    shape = body.shape
    com = np.asarray(body.com, float)
    kind = shape.kind
    if kind in ("sphere", "circle"):
        return float(shape.radius + np.linalg.norm(com))
    if kind == "box":
        half = 0.5 * np.asarray(shape.size, float)
        return float(np.linalg.norm(np.abs(com) + half))
    if kind == "capsule":
        return float(shape.radius + 0.5 * shape.length + np.linalg.norm(com))
    if kind == "cylinder":
        return float(np.hypot(shape.radius, 0.5 * shape.length) + np.linalg.norm(com))
    if kind in ("mesh", "polygon"):
        verts = np.asarray(shape.vertices, float)
        return float(np.max(np.linalg.norm(verts - com, axis=1)))
    return 0.0  # pragma: no cover - unknown shapes contribute no size


def body_radii(scene: Scene) -> np.ndarray:
    return np.array([body_radius(b) for b in scene.bodies])


def energy_floor(scene: Scene) -> float:
    """``sum_i m_i |g| r_i``: the work to lift every body by its own size (0 without gravity)."""
    if scene.effects.gravity is None:
        return 0.0
    g = float(np.linalg.norm(scene.effects.gravity))
    return float(np.sum(scene.masses * g * body_radii(scene)))


def _omega_norm(scene: Scene, traj: Trajectory) -> np.ndarray:
    """(T, N) angular speed."""
    if scene.dimension == 2:
        return np.abs(traj.omega)
    return np.linalg.norm(traj.omega, axis=-1)


def energy_scale(scene: Scene, traj: Trajectory, reference: Trajectory | None = None,
                 internal: bool = False) -> tuple[float, str]:
    """``S_E`` and where it came from ("reference" or "run"); see the module docstring.

    ``internal``: the kinetic energy relative to the system's centre of mass (the yardstick of
    the internal energy, the same in every inertial frame)."""
    from crosscheck.quantities import com_velocity, kinetic_energy

    source, basis = "run", traj
    if reference is not None and _has_full_state(reference):
        source, basis = "reference", reference
    if not len(basis.t):
        return energy_floor(scene), source
    kinetic = kinetic_energy(scene, basis)
    if internal:
        vc = com_velocity(scene, basis)
        kinetic = kinetic - 0.5 * scene.masses.sum() * np.einsum("td,td->t", vc, vc)
    return max(float(np.max(kinetic)), energy_floor(scene)), source


def internal_energy_decouples(scene: Scene) -> bool:
    """True when the centre of mass moves independently of everything else (no spring anchored
    to the world, no drag, no ground contact): then the internal energy is conserved on its own
    and is what ``energy_drift`` measures."""
    fx = scene.effects
    return not (any(s.body_b is None for s in fx.springs) or fx.drag or fx.fluid
                or fx.medium is not None or (fx.contact and scene.ground is not None))


def _has_full_state(traj: Trajectory) -> bool:
    rot = traj.quat if traj.quat is not None else traj.angle
    if len(traj.t) == 0 or rot is None:
        return False
    return bool(np.all(np.isfinite(traj.vel)) and np.all(np.isfinite(traj.omega))
                and np.all(np.isfinite(rot)))


def momentum_scale(scene: Scene, traj: Trajectory) -> float:
    """``S_P = max_t [sum_i m_i (|v_i - v_c| + |w_i| r_i) + M |v_c(t) - v_c(0)|]``: the same in
    every inertial frame (a uniform velocity added to every body changes nothing)."""
    if not len(traj.t):
        return 0.0
    from crosscheck.quantities import com_velocity

    vc = com_velocity(scene, traj)
    relative = np.linalg.norm(traj.vel - vc[:, None], axis=-1)
    speed = relative + _omega_norm(scene, traj) * body_radii(scene)
    gained = scene.masses.sum() * np.linalg.norm(vc - vc[:1], axis=-1)
    return float(np.max(speed @ scene.masses + gained))


def angular_momentum_scale(scene: Scene, traj: Trajectory) -> float:
    """``S_L = max_t sum_i (|I_i w_i| + m_i |x_i - c| |v_i - v_c| + m_i r_i |v_i - v_c|)``."""
    if not len(traj.t):
        return 0.0
    m = scene.masses
    c = np.einsum("n,tnd->td", m, traj.com) / m.sum()
    vc = np.einsum("n,tnd->td", m, traj.vel) / m.sum()
    if scene.dimension == 2:
        moments = np.array([b.moment for b in scene.bodies])
        spin = np.abs(traj.omega) * moments
    else:
        from crosscheck.quantities import world_inertia

        spin = np.linalg.norm(np.einsum("tnij,tnj->tni", world_inertia(scene, traj), traj.omega),
                              axis=-1)
    relative = np.linalg.norm(traj.vel - vc[:, None], axis=-1)
    orbital = np.linalg.norm(traj.com - c[:, None], axis=-1) * relative
    # The rim term with the velocity relative to the centre of mass: a uniform velocity added to
    # every body must not change the yardstick (it changes nothing about the centre of mass).
    rim = body_radii(scene) * relative
    return float(np.max(spin.sum(1) + orbital @ m + rim @ m))


def available_energy(scene: Scene, traj: Trajectory) -> float:
    """``E_avail``, the generous bound on exchangeable energy used by the blow-up test:
    quantities.exchangeable_energy plus E_floor."""
    from crosscheck.quantities import exchangeable_energy

    first = _first_sample(traj)
    return energy_floor(scene) + (0.0 if first is None else exchangeable_energy(scene, first))


def _first_sample(traj: Trajectory) -> Trajectory | None:
    if not len(traj.t):
        return None
    return Trajectory(t=traj.t[:1], com=traj.com[:1], vel=traj.vel[:1], omega=traj.omega[:1],
                      quat=None if traj.quat is None else traj.quat[:1],
                      angle=None if traj.angle is None else traj.angle[:1], meta=traj.meta)


# -- what the scene conserves --------------------------------------------------------------------
def _dissipative_contact(scene: Scene) -> bool:
    """Whether a pair that touches has restitution below 1 or any friction: the pair values, not
    the materials, decide (a pair of e = 1 and e = 0 surfaces bounces with e = 1).

    Decided per class of material rather than per pair: a pile of 1000 bodies has 500 500 body
    pairs but a handful of materials (listing every pair took 10 to 25 s)."""
    from crosscheck.scene.contact import GROUND, combine, pair_material

    def dissipates(m) -> bool:
        return m.collide and (m.restitution < 1.0 or m.friction > 0.0
                              or m.rolling_friction > 0.0 or m.torsional_friction > 0.0)

    if not scene.effects.contact:
        return False
    overridden = {frozenset((o.a, o.b)) for o in scene.pair_overrides}
    if any(dissipates(pair_material(scene, o.a, o.b)) for o in scene.pair_overrides):
        return True
    groups: dict = {}
    for body in scene.bodies:
        groups.setdefault(body.material, []).append(body.name)
    others = [(s.name, s.material) for s in scene.statics]
    if scene.ground is not None:
        others.append((GROUND, scene.ground.material))
    classes = list(groups)
    for i, ma in enumerate(classes):
        for mb in classes[i:]:
            a, b = groups[ma], groups[mb]
            pairs = {frozenset((x, y)) for x in a for y in b if x != y} if len(a) * len(b) \
                <= 4 * len(overridden) + 4 else None
            if pairs is not None and pairs <= overridden:
                continue  # every pair of these two classes has its own values (checked above)
            if (ma is not mb or len(a) > 1) and dissipates(combine(ma, mb)):
                return True
        for name, mo in others:
            if any(frozenset((x, name)) not in overridden for x in groups[ma]) \
                    and dissipates(combine(ma, mo)):
                return True
    return False


def _fixed_contact(scene: Scene) -> bool:
    """Contact with the ground or a static: an external force on the bodies."""
    return scene.effects.contact and (scene.ground is not None or bool(scene.statics))


def energy_not_conserved(scene: Scene) -> str | None:
    """Why total mechanical energy is not conserved in this scene, or None if it is.

    Energy is conserved unless the scene has drag, a damped spring, a constant torque on a 3D body
    (no potential), or contact in a pair that is not perfectly elastic and frictionless.
    """
    fx = scene.effects
    if fx.fluid:
        return "fluid scene"
    if fx.drag:
        return "the scene has drag"
    if fx.medium is not None:
        return "the medium's drag dissipates energy"
    if any(s.damping > 0 for s in fx.springs):
        return "a spring is damped"
    if scene.dimension == 3 and any(np.any(np.asarray(ld.torque) != 0) for ld in fx.loads):
        return "a constant torque on a 3D body has no potential"
    if fx.contact and _dissipative_contact(scene):
        return "contact with restitution < 1 or friction dissipates energy"
    return None


def linear_momentum_directions(scene: Scene) -> tuple[np.ndarray | None, str | None]:
    """Orthonormal basis (rows) of the directions in which linear momentum is conserved.

    External forces along fixed directions (gravity, constant loads) remove those directions;
    forces in arbitrary directions (drag, springs to world anchors, contact with the ground)
    remove everything. Returns (basis, None), or (None, reason) when nothing is conserved.
    """
    fx = scene.effects
    d = scene.dimension
    if fx.fluid:
        return None, "fluid scene"
    if any(dr.linear > 0 for dr in fx.drag):
        return None, "the scene has linear drag (an external force)"
    if fx.medium is not None:
        return None, "the medium's drag is an external force"
    if any(s.body_b is None for s in fx.springs):
        return None, "a spring is anchored to the world (an external force)"
    if _fixed_contact(scene):
        return None, "contact with the ground or a static is an external force"
    fixed = []
    if fx.gravity is not None and np.linalg.norm(fx.gravity) > 0:
        fixed.append(np.asarray(fx.gravity, float))
    fixed += [np.asarray(ld.force, float) for ld in fx.loads if np.linalg.norm(ld.force) > 0]
    if not fixed:
        return np.eye(d), None
    # Directions orthogonal to every fixed external force: the null space of their span.
    _, sv, vt = np.linalg.svd(np.array(fixed))
    rank = int(np.sum(sv > 1e-12 * sv.max()))
    basis = vt[rank:]
    if len(basis) == 0:
        return None, "external forces (gravity, loads) act in every direction"
    return basis, None


def angular_momentum_not_conserved(scene: Scene) -> str | None:
    """Why angular momentum about the system's centre of mass is not conserved, or None.

    Uniform gravity exerts no torque about the centre of mass, and springs between bodies act
    along the line joining their attachment points, so both keep it. Drag, springs to world
    anchors, ground contact, constant torques, and constant forces on a scene of several bodies
    (which give a torque about the common centre of mass) do not.
    """
    fx = scene.effects
    if fx.fluid:
        return "fluid scene"
    if fx.drag:
        return "the scene has drag"
    if fx.medium is not None:
        return "the medium's drag exerts torques"
    if any(s.body_b is None for s in fx.springs):
        return "a spring is anchored to the world (an external torque)"
    if _fixed_contact(scene):
        return "contact with the ground or a static is an external force"
    if any(np.any(np.asarray(ld.torque) != 0) for ld in fx.loads):
        return "a constant torque is applied"
    if len(scene.bodies) > 1 and any(np.any(np.asarray(ld.force) != 0) for ld in fx.loads):
        return "constant loads on one of several bodies give a torque about their centre of mass"
    return None
