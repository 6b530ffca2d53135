"""The contact buffer: what collision detection writes and every contact model reads.

One layout for 2D and 3D (``d`` = 2 or 3) and for every contact model, in the spirit of Newton's
``Contacts``: a structure of arrays with a fixed capacity, allocated once per run and refilled by
``detect`` at every step (or every force evaluation, for the penalty model). A row is one contact
point of one manifold between a body ``a`` and a body or fixed collider ``b``:

* ``a`` (C,) int64: body index, always a body.
* ``b`` (C,) int64: body index, or -1 when b is fixed (a static or the ground plane).
* ``normal`` (C, d): unit, world frame, pointing from a towards b (the direction in which an
  impulse ``+lambda n`` acts on b and ``-lambda n`` on a).
* ``point`` (C, d): world point midway between the two surfaces along the normal.
* ``depth`` (C,): penetration along the normal, positive when the shapes overlap, negative for a
  speculative contact reported within the margin (``geometry.margin``) but not yet touching.
* ``friction``, ``restitution``, ``rolling_friction``, ``torsional_friction`` (C,): the pair's
  values (scene/contact.py's rule and ``[[contact_pairs]]`` overrides), copied at detection so a
  model reads them without a table lookup.
* ``feature`` (C,) int64: a key that stays the same while the same two features stay in contact
  (pair of colliders and feature ids), for warm starting across steps.
* ``impulse`` (C, 3): the contact model's accumulated impulses (normal, tangent 1, tangent 2; in
  2D the third is unused). Detection does not write it; a warm-starting model copies the values
  of the previous step's rows with the same ``feature`` into the new rows.
* ``count`` (1,) int64: rows filled; ``needed`` (1,) int64: rows detection found. ``needed >
  capacity`` is an overflow: the extra contacts are dropped and the step that sees it raises
  (StepFailure through the adapter), never a silent loss of contacts.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Contacts(NamedTuple):
    a: np.ndarray
    b: np.ndarray
    normal: np.ndarray
    point: np.ndarray
    depth: np.ndarray
    friction: np.ndarray
    restitution: np.ndarray
    rolling_friction: np.ndarray
    torsional_friction: np.ndarray
    feature: np.ndarray
    impulse: np.ndarray
    count: np.ndarray
    needed: np.ndarray

    @classmethod
    def empty(cls, capacity: int, dimension: int) -> Contacts:
        c, d = int(capacity), int(dimension)
        if d not in (2, 3) or c < 1:
            raise ValueError(f"contact buffer needs capacity >= 1 and dimension 2 or 3, "
                             f"got {c}, {d}")
        return cls(a=np.zeros(c, np.int64), b=np.zeros(c, np.int64),
                   normal=np.zeros((c, d)), point=np.zeros((c, d)), depth=np.zeros(c),
                   friction=np.zeros(c), restitution=np.zeros(c), rolling_friction=np.zeros(c),
                   torsional_friction=np.zeros(c), feature=np.zeros(c, np.int64),
                   impulse=np.zeros((c, 3)), count=np.zeros(1, np.int64),
                   needed=np.zeros(1, np.int64))

    @property
    def capacity(self) -> int:
        return len(self.a)

    @property
    def n(self) -> int:
        """Rows filled by the last detection."""
        return int(self.count[0])

    def overflowed(self) -> bool:
        return int(self.needed[0]) > self.capacity
