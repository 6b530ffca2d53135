"""In-house collision detection (compiled): the contact buffer (contacts.py), the scene's colliders
compiled into arrays (geometry.py), broad phase and narrow phase in 2D and 3D, and the detection
that fills the buffer (detect.py). The contact models that read the buffer live in
crosscheck.sim.rigid (docs/inhouse.md, "Contact" and "Collision detection").

Public API: ``compile_geometry(scene, margin) -> Geometry3D | Geometry2D``;
``detect3d(geometry, x, q, contacts)`` / ``detect2d(geometry, x, angle, contacts)`` (compiled,
return the rows needed); ``new_contacts(geometry, capacity=None) -> Contacts``.
"""

from crosscheck.sim.collide.contacts import Contacts
from crosscheck.sim.collide.detect import contact_capacity, detect2d, detect3d, new_contacts
from crosscheck.sim.collide.geometry import (
    DEFAULT_MARGIN,
    Geometry2D,
    Geometry3D,
    compile_geometry,
)

__all__ = ["DEFAULT_MARGIN", "Contacts", "Geometry2D", "Geometry3D", "compile_geometry",
           "contact_capacity", "detect2d", "detect3d", "new_contacts"]
