"""Energies and momenta computed by crosscheck from a Trajectory and its Scene.

Never taken from an engine's own figure (Pymunk's ``kinetic_energy`` is twice the kinetic energy;
MuJoCo's leaves out what it does not model): every engine is measured with the same ruler.
All functions are vectorised over time and bodies and return arrays of shape (T,) (system totals)
or (T, d) for vectors.
"""

from __future__ import annotations

import numpy as np

from crosscheck.rotations import quat_to_matrix
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory


def _masses(scene: Scene) -> np.ndarray:
    return scene.masses


def world_inertia(scene: Scene, traj: Trajectory) -> np.ndarray:
    """(T, N, 3, 3) inertia about each centre of mass in world axes: R I_body R^T."""
    r = quat_to_matrix(traj.quat)
    ib = np.stack([b.inertia for b in scene.bodies])  # (N, 3, 3)
    return np.einsum("tnij,njk,tnlk->tnil", r, ib, r)


def translational_kinetic_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    """sum_i 1/2 m_i |v_i|^2."""
    return 0.5 * np.einsum("n,tnd,tnd->t", _masses(scene), traj.vel, traj.vel)


def rotational_kinetic_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    """sum_i 1/2 w_i . I_i(t) w_i with I_i(t) = R I_body R^T (3D); 1/2 I w^2 in 2D."""
    if scene.dimension == 2:
        moments = np.array([b.moment for b in scene.bodies])
        return 0.5 * np.einsum("n,tn,tn->t", moments, traj.omega, traj.omega)
    iw = world_inertia(scene, traj)
    return 0.5 * np.einsum("tni,tnij,tnj->t", traj.omega, iw, traj.omega)


def kinetic_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    return translational_kinetic_energy(scene, traj) + rotational_kinetic_energy(scene, traj)


def gravitational_potential_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    """-sum_i m_i g . x_i (zero at the origin)."""
    if scene.effects.gravity is None:
        return np.zeros(len(traj.t))
    return -np.einsum("n,tnd,d->t", _masses(scene), traj.com, scene.effects.gravity)


def body_volumes(scene: Scene) -> np.ndarray:
    """(N,) volume of each body's shape, m^3 (3D; the mass properties at unit density)."""
    from crosscheck.scene.massprops import shape_mass_properties

    return np.array([shape_mass_properties(b.shape, 1.0).mass for b in scene.bodies])


def buoyancy_forces(scene: Scene) -> np.ndarray:
    """(N, d) buoyancy of a medium on each body, -rho_f V_i g (zero without a medium with
    density, or without gravity). It acts at the centre of buoyancy, the shape's centroid."""
    medium = scene.effects.medium
    n, d = len(scene.bodies), scene.dimension
    if medium is None or medium.density == 0.0 or scene.effects.gravity is None:
        return np.zeros((n, d))
    g = np.asarray(scene.effects.gravity, float)
    return -medium.density * body_volumes(scene)[:, None] * g[None, :]


def buoyancy_potential_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    """sum_i rho_f V_i g . x_i: the potential of the buoyancy, a constant force per body, taken
    at the centre of mass (exact when the centre of buoyancy is the centre of mass, as for every
    body with its shape's centroid as centre of mass; the MuJoCo adapter refuses the others)."""
    forces = buoyancy_forces(scene)
    if not np.any(forces):
        return np.zeros(len(traj.t))
    return -np.einsum("tnd,nd->t", traj.com, forces)


def attachment_points_world(scene: Scene, traj: Trajectory, body: int, local: np.ndarray
                            ) -> np.ndarray:
    """(T, d) world position of a body-frame point: x_com + R (p - com_body)."""
    offset = np.asarray(local, float) - scene.bodies[body].com
    if scene.dimension == 2:
        th = traj.angle[:, body]
        c, s = np.cos(th), np.sin(th)
        rotated = np.stack([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1]], -1)
    else:
        rotated = np.einsum("tij,j->ti", quat_to_matrix(traj.quat[:, body]), offset)
    return traj.com[:, body] + rotated


def spring_potential_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    """sum over springs of 1/2 k (l - l0)^2, l the distance between the attachment points."""
    total = np.zeros(len(traj.t))
    for spring in scene.effects.springs:
        pa = attachment_points_world(scene, traj, spring.body_a, spring.attach_a)
        if spring.body_b is None:
            pb = np.broadcast_to(spring.attach_b, pa.shape)
        else:
            pb = attachment_points_world(scene, traj, spring.body_b, spring.attach_b)
        length = np.linalg.norm(pa - pb, axis=-1)
        total += 0.5 * spring.stiffness * (length - spring.rest_length) ** 2
    return total


def load_potential_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    """Potential of constant loads: -F . x_com; in 2D also -tau * angle (both conservative).

    A constant world torque on a 3D body has no potential; such a scene has no conserved energy
    and should be compared against a reference instead.
    """
    total = np.zeros(len(traj.t))
    for load in scene.effects.loads:
        total -= traj.com[:, load.body] @ load.force
        if scene.dimension == 2:
            total -= load.torque[0] * traj.angle[:, load.body]
    return total


def potential_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    return (gravitational_potential_energy(scene, traj) + spring_potential_energy(scene, traj)
            + load_potential_energy(scene, traj) + buoyancy_potential_energy(scene, traj))


def total_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    return kinetic_energy(scene, traj) + potential_energy(scene, traj)


def linear_momentum(scene: Scene, traj: Trajectory) -> np.ndarray:
    """(T, d): sum_i m_i v_i."""
    return np.einsum("n,tnd->td", _masses(scene), traj.vel)


def system_com(scene: Scene, traj: Trajectory) -> np.ndarray:
    m = _masses(scene)
    return np.einsum("n,tnd->td", m, traj.com) / m.sum()


def _cross2(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def angular_momentum(scene: Scene, traj: Trajectory, about: str | np.ndarray = "origin"
                     ) -> np.ndarray:
    """Total angular momentum: sum_i (x_i - c) x m_i v_i + I_i(t) w_i.

    ``about`` is "origin", "com" (the system's centre of mass at each sample, the quantity
    conserved by an isolated system even when it moves) or a fixed point. 3D: (T, 3); 2D: (T,).
    """
    m = _masses(scene)
    vel = traj.vel
    if isinstance(about, str) and about == "com":
        centre = system_com(scene, traj)[:, None, :]
        # Velocities relative to the centre of mass: the same sum (sum_i m_i (x_i - c) = 0),
        # without the cancellation a fast-moving system would otherwise bring in.
        vel = vel - com_velocity(scene, traj)[:, None, :]
    elif isinstance(about, str) and about == "origin":
        centre = np.zeros(scene.dimension)
    else:
        centre = np.asarray(about, float)
    r = traj.com - centre
    p = m[None, :, None] * vel
    if scene.dimension == 2:
        moments = np.array([b.moment for b in scene.bodies])
        return _cross2(r, p).sum(axis=1) + traj.omega @ moments
    spin = np.einsum("tnij,tnj->ti", world_inertia(scene, traj), traj.omega)
    return np.cross(r, p).sum(axis=1) + spin


# -- the centre-of-mass split (frame-invariant drift, docs/metrics.md) ----------------------------
def com_velocity(scene: Scene, traj: Trajectory) -> np.ndarray:
    """(T, d): the system's centre-of-mass velocity."""
    m = _masses(scene)
    return np.einsum("n,tnd->td", m, traj.vel) / m.sum()


def translational_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    """The centre of mass's share of the energy: 1/2 M |v_c|^2 - M g . c - F_tot . c.

    Uniform gravity and the sum of the constant loads (and of a medium's buoyancies) act on the
    centre of mass c alone; this part changes under a Galilean boost or a shift of the origin,
    the rest does not.
    """
    m = _masses(scene)
    c = system_com(scene, traj)
    vc = com_velocity(scene, traj)
    energy = 0.5 * m.sum() * np.einsum("td,td->t", vc, vc)
    force = np.zeros(scene.dimension)
    if scene.effects.gravity is not None:
        force += m.sum() * np.asarray(scene.effects.gravity, float)
    for load in scene.effects.loads:
        force += np.asarray(load.force, float)
    force += buoyancy_forces(scene).sum(axis=0)
    return energy - c @ force


def internal_energy(scene: Scene, traj: Trajectory) -> np.ndarray:
    """total_energy - translational_energy: the kinetic energy relative to the centre of mass
    (sum 1/2 m_i |v_i - v_c|^2 + 1/2 w.I w), the springs, and the constant loads' potential
    relative to it (-F_i . (x_i - c); 2D also -tau theta). Invariant under a Galilean boost and
    a shift of the origin when no spring is anchored to the world."""
    return total_energy(scene, traj) - translational_energy(scene, traj)


def exchangeable_energy(scene: Scene, first: Trajectory) -> float:
    """A generous upper bound on the energy the scene can exchange in its whole run, from its
    first sample: T(0) + V_springs(0) + sum_i |F_i| (|v_i(0)| D + |F_i| D^2 / (2 m_i))
    + sum_i |tau_i| (|w_i(0)| D + |tau_i| D^2 / (2 I_min,i)), F_i = m_i g + the constant loads,
    tau_i the constant torques, D the duration (the work of the constant forces over the longest
    free-flight distance). A medium's buoyancy counts among the constant forces (a light body
    rises under m g - rho_f V g, which can be many times its weight); its drag only removes
    energy. The run driver's blow-up cut and the comparer's blow-up test both measure against
    it."""
    total = float(kinetic_energy(scene, first)[0] + spring_potential_energy(scene, first)[0])
    duration = scene.run.duration
    d = scene.dimension
    forces = np.zeros((len(scene.bodies), d))
    torques = np.zeros((len(scene.bodies), 3 if d == 3 else 1))
    if scene.effects.gravity is not None:
        forces += scene.masses[:, None] * np.asarray(scene.effects.gravity, float)
    for load in scene.effects.loads:
        forces[load.body] += np.asarray(load.force, float)
        torques[load.body] += np.asarray(load.torque, float).reshape(-1)
    forces += buoyancy_forces(scene)
    for i, body in enumerate(scene.bodies):
        f = float(np.linalg.norm(forces[i]))
        total += f * (float(np.linalg.norm(body.velocity)) * duration
                      + f * duration**2 / (2.0 * body.mass))
        tau = float(np.linalg.norm(torques[i]))
        if tau > 0:
            i_min = float(np.min(np.linalg.eigvalsh(np.atleast_2d(body.inertia))))
            total += tau * (float(np.linalg.norm(body.angular_velocity)) * duration
                            + tau * duration**2 / (2.0 * max(i_min, 1e-300)))
    return total
