"""The solid boundary a fluid step takes: per MAC face, how solid it is and how fast it moves.

The step used to read one mask rasterised at set-up. A rigid body in the fluid (two-way
coupling) moves, so the solid is data handed to every step instead (``FluidState.step(...,
solid=...)``); a scene without moving solids hands it the static one built here once.

* ``cells`` (nx, ny) bool: solid cells. Cells are what the level set, the pressure unknowns, path
  clipping and the measurements need (a cell is fluid only if it is not solid).
* ``u_frac`` (nx+1, ny), ``v_frac`` (nx, ny+1): the solid fraction of each x- and y-face, 0 open,
  1 fully solid. It covers the closed sides of the domain as well as obstacles, so a face is a
  wall because the boundary says so, whatever makes it one.
* ``u_solid``, ``v_solid`` (same shapes): the solid's velocity normal to each face, read only where
  the face is solid. The projection imposes ``u . n = u_solid . n`` there (the face keeps this
  value and enters the divergence with it), viscosity sees it as the wall velocity.

The solver has staircase walls only: faces are 0 or 1, a face touching a solid cell is solid.
Both are checked when a boundary is built, since a fractional face would otherwise be silently
taken as open (cut cells would weight the pressure stencil by the open fraction instead).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from crosscheck.scene.fluid import FluidSpec
from crosscheck.sim.fluid.pressure import SOLID

SIDES = ("left", "right", "bottom", "top")


@dataclass(frozen=True, eq=False)
class SolidBoundary:
    cells: np.ndarray
    u_frac: np.ndarray
    v_frac: np.ndarray
    u_solid: np.ndarray
    v_solid: np.ndarray
    #: whether any cell is solid (path clipping and level-set filling are skipped if not)
    has_cells: bool = field(init=False)

    def __post_init__(self) -> None:
        nx, ny = self.cells.shape
        shapes = {"u_frac": (nx + 1, ny), "v_frac": (nx, ny + 1),
                  "u_solid": (nx + 1, ny), "v_solid": (nx, ny + 1)}
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise ValueError(f"SolidBoundary.{name} has shape {getattr(self, name).shape}, "
                                 f"expected {shape} for {nx} x {ny} cells")
        for name in ("u_frac", "v_frac"):
            f = getattr(self, name)
            if not np.all((f == 0.0) | (f == 1.0)):
                raise ValueError(f"SolidBoundary.{name}: fractions other than 0 and 1 (cut "
                                 "cells) are not implemented")
        need_u, need_v = _faces_touching(self.cells)
        if np.any(need_u & (self.u_frac[1:-1] == 0.0)) or \
                np.any(need_v & (self.v_frac[:, 1:-1] == 0.0)):
            raise ValueError("SolidBoundary: a face next to a solid cell must be solid")
        object.__setattr__(self, "has_cells", bool(self.cells.any()))  # frozen: set once here

    @classmethod
    def from_cells(cls, cells: np.ndarray, open_sides: np.ndarray,
                   u_solid: np.ndarray | None = None,
                   v_solid: np.ndarray | None = None) -> SolidBoundary:
        """Staircase boundary of a cell mask: a face is solid when it touches a solid cell or lies
        on a closed side of the domain (``open_sides``: left, right, bottom, top). Velocities
        default to zero (a resting solid)."""
        cells = np.ascontiguousarray(cells, dtype=bool)
        nx, ny = cells.shape
        u_frac = np.zeros((nx + 1, ny))
        v_frac = np.zeros((nx, ny + 1))
        need_u, need_v = _faces_touching(cells)
        u_frac[1:-1][need_u] = 1.0
        v_frac[:, 1:-1][need_v] = 1.0
        # sides: closed, or open but blocked by a solid cell behind the face
        u_frac[0] = ~open_sides[0] | cells[0]
        u_frac[-1] = ~open_sides[1] | cells[-1]
        v_frac[:, 0] = ~open_sides[2] | cells[:, 0]
        v_frac[:, -1] = ~open_sides[3] | cells[:, -1]
        u_solid = np.zeros(u_frac.shape) if u_solid is None else np.asarray(u_solid, float)
        v_solid = np.zeros(v_frac.shape) if v_solid is None else np.asarray(v_solid, float)
        return cls(cells, u_frac, v_frac, u_solid, v_solid)


def _faces_touching(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Interior x- and y-faces with a solid cell on either side."""
    return cells[1:] | cells[:-1], cells[:, 1:] | cells[:, :-1]


def open_sides(spec: FluidSpec) -> np.ndarray:
    """Which sides (left, right, bottom, top) are open, as the kernels index them."""
    return np.array([spec.walls.get(s, "solid") == "open" for s in SIDES])


def static_boundary(spec: FluidSpec, centres: np.ndarray) -> SolidBoundary:
    """The scene's obstacles at rest: a cell is solid when its centre (``centres``, (nx, ny, 2))
    is strictly inside an obstacle (docs/fluid.md)."""
    cells = np.zeros(centres.shape[:2], bool)
    for obstacle in spec.obstacles:
        cells |= obstacle.contains(centres)
    return SolidBoundary.from_cells(cells, open_sides(spec))


def impose(u: np.ndarray, v: np.ndarray, ustate: np.ndarray, vstate: np.ndarray,
           bnd: SolidBoundary) -> None:
    """Set the solid faces of ``u``, ``v`` to the solid's velocity: the Neumann data of the
    projection, which leaves these faces as they are (so they keep it after the step)."""
    np.copyto(u, bnd.u_solid, where=ustate == SOLID)
    np.copyto(v, bnd.v_solid, where=vstate == SOLID)
