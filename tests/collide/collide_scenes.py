"""Scenes for the collision tests, built directly (no case file): bodies of given shapes at given
poses, statics, an optional ground plane, one material unless told otherwise."""

from __future__ import annotations

import numpy as np

from crosscheck.scene.model import (
    Body,
    Effects,
    Ground,
    Material,
    PairOverride,
    Reference,
    RunSettings,
    Scene,
    Static,
)

STEEL = Material("steel", friction=0.5, restitution=0.25, rolling_friction=0.01,
                 torsional_friction=0.02)


def body(name, shape, position, orientation=None, material=STEEL, com=None):
    d = len(position)
    if orientation is None:
        orientation = [1.0, 0.0, 0.0, 0.0] if d == 3 else [0.0]
    return Body(name=name, shape=shape, mass=1.0,
                com=np.zeros(d) if com is None else np.asarray(com, float),
                inertia=np.eye(3) if d == 3 else np.eye(1),
                position=np.asarray(position, float), orientation=np.asarray(orientation, float),
                velocity=np.zeros(d), angular_velocity=np.zeros(3 if d == 3 else 1),
                material=material)


def static(name, shape, position, orientation=None, material=STEEL):
    d = len(position)
    if orientation is None:
        orientation = [1.0, 0.0, 0.0, 0.0] if d == 3 else [0.0]
    return Static(name=name, shape=shape, position=np.asarray(position, float),
                  orientation=np.asarray(orientation, float), material=material)


def scene(bodies, statics=(), ground=None, dimension=3, overrides=(), ground_material=STEEL):
    """``ground``: None, or (normal, offset)."""
    g = None
    if ground is not None:
        g = Ground(np.asarray(ground[0], float), float(ground[1]), ground_material)
    pair_overrides = tuple(PairOverride(i, *o[:2], **o[2]) for i, o in enumerate(overrides))
    return Scene(name="collide-test", description="", tags=(), dimension=dimension,
                 run=RunSettings(1.0, 1e-3, 0.1, ("inhouse",), {}),
                 effects=Effects(contact=True), bodies=tuple(bodies), ground=g,
                 materials={}, reference=Reference(), tolerances={}, engine_options={},
                 statics=tuple(statics), pair_overrides=pair_overrides)


def state3d(sc):
    """x (centres of mass) and q of the scene's bodies at t = 0."""
    x = np.array([b.com_world() for b in sc.bodies], float).reshape(-1, 3)
    q = np.array([b.orientation for b in sc.bodies], float).reshape(-1, 4)
    return x, q


def state2d(sc):
    x = np.array([b.com_world() for b in sc.bodies], float).reshape(-1, 2)
    a = np.array([b.orientation[0] for b in sc.bodies], float).reshape(-1)
    return x, a
