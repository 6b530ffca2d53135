"""Small contact scenes and a stepping helper for the contact-model tests."""

from __future__ import annotations

import hashlib

import numpy as np

from crosscheck.scene.loader import load_case_text
from crosscheck.sim.rigid import compile_model, get_integrator, state_from_scene
from crosscheck.sim.rigid.contact_models import get_contact_model


def scene(body_blocks: str, dim: int = 3, gravity=True, ground: str | None = "",
          statics: str = "", materials: str = "") -> object:
    """A contact case; ``gravity``: True (-9.81 along the last axis), False, or a vector."""
    if gravity is True:
        g = "[0.0, 0.0, -9.81]" if dim == 3 else "[0.0, -9.81]"
    elif gravity is False or gravity is None:
        g = None
    else:
        g = str([float(c) for c in gravity])
    grav = f"gravity = {g}\n" if g else ""
    grd = "" if ground is None else f"[ground]\n{ground}\n"
    return load_case_text(f"""
[case]
name = "contact-model-test"
dimension = {dim}
[run]
duration = 1.0
dt = 1e-3
[effects]
{grav}contact = true
{materials}
{grd}{statics}
{body_blocks}
""")


class Run:
    """A scene stepped by one integrator and one contact model."""

    def __init__(self, sc, integrator: str, model: str, params: dict | None = None):
        self.scene = sc
        self.model = compile_model(sc)
        self.state = state_from_scene(self.model, sc)
        self.stepper = get_contact_model(model).open(sc, self.model, get_integrator(integrator),
                                                     params or {})

    def advance(self, n: int, h: float) -> None:
        self.stepper.advance(self.state, n, h)

    def velocities(self):
        m = self.model
        v = self.state.P / m.bodies.mass[:, None]
        return v

    def energy(self) -> float:
        """Kinetic plus gravitational potential energy (gravity along the last axis)."""
        m = self.model
        b = m.bodies
        st = self.state
        e = 0.5 * float(np.sum(st.P * st.P / b.mass[:, None]))
        if m.dimension == 3:
            from crosscheck.rotations import quat_to_matrix

            for i in range(m.n_bodies):
                r = quat_to_matrix(st.rot[i])
                iinv = r @ b.inv_inertia[i] @ r.T
                e += 0.5 * float(st.L[i] @ iinv @ st.L[i])
        else:
            e += 0.5 * float(np.sum(st.L * st.L * b.inv_moment))
        if m.gravity is not None:
            e -= float(np.sum(b.mass * (st.x @ m.gravity)))
        return e

    def digest(self) -> str:
        h = hashlib.sha256()
        for a in self.state.arrays():
            h.update(np.ascontiguousarray(a).tobytes())
        return h.hexdigest()


def momenta(run: Run):
    """Total linear momentum and angular momentum about the origin (2D: its z component)."""
    st = run.state
    lin = st.P.sum(axis=0)
    if run.model.dimension == 3:
        ang = (np.cross(st.x, st.P) + st.L).sum(axis=0)
    else:
        ang = np.sum(st.x[:, 0] * st.P[:, 1] - st.x[:, 1] * st.P[:, 0] + st.L)
    return lin, ang


def sphere(name: str, pos, radius: float = 0.1, mass: float = 1.0, velocity=None,
           angular=None, material: str | None = None) -> str:
    out = f"""[[bodies]]
name = "{name}"
shape = {{ sphere = {{ radius = {radius} }} }}
mass = {mass}
position = {list(map(float, pos))}
"""
    if velocity is not None:
        out += f"velocity = {list(map(float, velocity))}\n"
    if angular is not None:
        out += f"angular_velocity = {list(map(float, angular))}\n"
    if material:
        out += f"material = {material}\n"
    return out


def circle(name: str, pos, radius: float = 0.1, mass: float = 1.0, velocity=None,
           angular=None, material: str | None = None) -> str:
    out = f"""[[bodies]]
name = "{name}"
shape = {{ circle = {{ radius = {radius} }} }}
mass = {mass}
position = {list(map(float, pos))}
"""
    if velocity is not None:
        out += f"velocity = {list(map(float, velocity))}\n"
    if angular is not None:
        out += f"angular_velocity = {float(angular)}\n"
    if material:
        out += f"material = {material}\n"
    return out


def box(name: str, pos, size, mass: float = 1.0, velocity=None, orientation: str | None = None,
        material: str | None = None) -> str:
    out = f"""[[bodies]]
name = "{name}"
shape = {{ box = {{ size = {list(map(float, size))} }} }}
mass = {mass}
position = {list(map(float, pos))}
"""
    if velocity is not None:
        out += f"velocity = {list(map(float, velocity))}\n"
    if orientation:
        out += f"orientation = {orientation}\n"
    if material:
        out += f"material = {material}\n"
    return out


def oblique_impact_bodies(dim: int, material: str = '"rough"') -> str:
    """An off-centre hit with friction and spin between a sphere (circle) and a turned box, then
    the box on a third body: the momentum tests' scene (no gravity, no ground)."""
    if dim == 3:
        return (sphere("s", [0.0, 0.03, 0.02], velocity=[3.0, 0.0, 0.1], angular=[5, -2, 9],
                       mass=0.7, material=material)
                + box("b", [0.4, 0.0, 0.0], [0.2, 0.3, 0.25], mass=2.0,
                      orientation="{ axis = [1.0, 2.0, 3.0], angle = 0.3 }", material=material)
                + sphere("t", [0.75, -0.05, 0.04], radius=0.08, mass=0.4, material=material))
    return (circle("s", [0.0, 0.03], velocity=[3.0, 0.1], angular=7.0, mass=0.7,
                   material=material)
            + box("b", [0.4, 0.0], [0.2, 0.3], mass=2.0, orientation="0.3", material=material)
            + circle("t", [0.75, -0.05], radius=0.08, mass=0.4, material=material))
