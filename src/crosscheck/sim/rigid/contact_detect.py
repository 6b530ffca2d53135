"""The contact models' door to collision detection (crosscheck.sim.collide): the scene's colliders,
a contact buffer, and a compiled ``detect`` that a hand-filled buffer can stand in for.

``geometry`` is the collide package's compiled colliders, or ``None``: then ``detect3d`` /
``detect2d`` leave the buffer as it is, so a model's kernels can be tested on hand-filled rows
(numba prunes the detection for a ``None`` geometry).
"""

from __future__ import annotations

from numba import njit

from crosscheck.sim._jit import INLINE
from crosscheck.sim.collide.contacts import Contacts
from crosscheck.sim.collide.detect import detect2d as _collide2d
from crosscheck.sim.collide.detect import detect3d as _collide3d


def compile_colliders(scene, margin: float, capacity: int = 0):
    """(geometry, scratch, capacity) of a contact scene for the given speculative margin (m);
    ``capacity`` 0: collide's estimate for the scene."""
    from crosscheck.sim.collide.detect import contact_capacity
    from crosscheck.sim.collide.geometry import compile_geometry

    geometry = compile_geometry(scene, margin=margin)
    cap = int(capacity) if capacity and capacity > 0 else contact_capacity(geometry)
    return geometry, None, cap


def new_contacts(capacity: int, dimension: int) -> Contacts:
    return Contacts.empty(capacity, dimension)


def pair_restitutions(scene) -> list[float]:
    """Every restitution a contact row of the scene can carry (the pair rule and overrides)."""
    from crosscheck.scene.contact import material_classes

    classes = material_classes(scene)
    return sorted({float(classes.values[i][j].restitution) for i, j in classes.class_pairs()
                   if classes.values[i][j].collide} or {0.0})


@njit(**INLINE)
def detect3d(geometry, x, q, buf):
    """Refill ``buf`` from the 3D state; a ``None`` geometry leaves a hand-filled buffer."""
    if geometry is not None:
        _collide3d(geometry, x, q, buf)
        if buf.needed[0] > buf.a.shape[0]:
            raise ValueError("contact buffer overflow: more contacts than its capacity")


@njit(**INLINE)
def detect2d(geometry, x, angle, buf):
    """Refill ``buf`` from the 2D state; a ``None`` geometry leaves a hand-filled buffer."""
    if geometry is not None:
        _collide2d(geometry, x, angle, buf)
        if buf.needed[0] > buf.a.shape[0]:
            raise ValueError("contact buffer overflow: more contacts than its capacity")

