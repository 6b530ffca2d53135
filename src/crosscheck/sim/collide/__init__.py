"""In-house collision detection (compiled): the contact buffer (contacts.py), the scene's colliders
compiled into arrays, broad phase and narrow phase in 2D and 3D. The contact models that read the
buffer live in crosscheck.sim.rigid (docs/inhouse.md, "Contact")."""

from crosscheck.sim.collide.contacts import Contacts

__all__ = ["Contacts"]
