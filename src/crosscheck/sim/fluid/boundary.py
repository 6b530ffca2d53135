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

Two kinds of boundary:

* **staircase** (``SolidBoundary.from_cells``): faces 0 or 1, a face touching a solid cell is
  solid (both checked). What a cell mask gives; the tests' moving blocks use it.
* **cut cells** (``SolidBoundary.from_shapes``, what the scene's obstacles give): faces carry the
  exact solid fraction of the cell edge, and the boundary also holds the solid's signed distance
  at the u samples, v samples and cell centres (``u_dist``, ``v_dist``, ``c_dist``) and the open
  area of every cell (``fluid_area``). The projection weights each face by its open fraction
  (Batty, Bertails and Bridson 2007; Ng, Min and Gibou 2009), the viscous step puts the no-slip
  wall where the distance changes sign between two samples (ghost fluid, Gibou et al. 2002), and
  path clipping stops at the zero of the interpolated distance. ``cells`` are the cells whose
  centre is inside the solid (level set filling, particles, measurements), as before; a cell is a
  pressure unknown when any of its faces is open, wherever its centre is.

A moving solid (two-way coupling) builds a new boundary every step with ``from_shapes`` and its
velocities; the face velocities are then what the solid's rigid motion gives at each face.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from crosscheck.scene.fluid import FluidSpec
from crosscheck.sim.fluid import cutcell
from crosscheck.sim.fluid.pressure import SOLID

SIDES = ("left", "right", "bottom", "top")


class SolidStop(Exception):
    """A moving solid left what the step can handle (a coupled body touching a wall, leaving
    the domain): the run stops there with this reason (failure is data)."""


@dataclass(frozen=True, eq=False)
class SolidBoundary:
    cells: np.ndarray
    u_frac: np.ndarray
    v_frac: np.ndarray
    u_solid: np.ndarray
    v_solid: np.ndarray
    #: cut cells: the solid's signed distance at the u samples, v samples and cell centres (m,
    #: negative inside), and the open (fluid) area fraction of every cell; all None: staircase
    u_dist: np.ndarray | None = None
    v_dist: np.ndarray | None = None
    c_dist: np.ndarray | None = None
    fluid_area: np.ndarray | None = None
    #: whether any cell is solid (path clipping and level-set filling are skipped if not)
    has_cells: bool = field(init=False)
    #: whether the boundary has cut cells (distances and areas)
    cut: bool = field(init=False)

    def __post_init__(self) -> None:
        nx, ny = self.cells.shape
        shapes = {"u_frac": (nx + 1, ny), "v_frac": (nx, ny + 1),
                  "u_solid": (nx + 1, ny), "v_solid": (nx, ny + 1)}
        for name, shape in shapes.items():
            if getattr(self, name).shape != shape:
                raise ValueError(f"SolidBoundary.{name} has shape {getattr(self, name).shape}, "
                                 f"expected {shape} for {nx} x {ny} cells")
        cut_parts = {"u_dist": (nx + 1, ny), "v_dist": (nx, ny + 1), "c_dist": (nx, ny),
                     "fluid_area": (nx, ny)}
        given = [getattr(self, k) is not None for k in cut_parts]
        if any(given) and not all(given):
            raise ValueError("SolidBoundary: cut cells need all of u_dist, v_dist, c_dist and "
                             "fluid_area")
        cut = all(given)
        if cut:
            for name, shape in cut_parts.items():
                if getattr(self, name).shape != shape:
                    raise ValueError(f"SolidBoundary.{name} has shape "
                                     f"{getattr(self, name).shape}, expected {shape}")
        for name in ("u_frac", "v_frac"):
            f = getattr(self, name)
            if cut:
                if not np.all((f >= 0.0) & (f <= 1.0)):
                    raise ValueError(f"SolidBoundary.{name}: fractions outside [0, 1]")
            elif not np.all((f == 0.0) | (f == 1.0)):
                raise ValueError(f"SolidBoundary.{name}: fractions other than 0 and 1 need "
                                 "the cut-cell distances (SolidBoundary.from_shapes)")
        if not cut:
            need_u, need_v = _faces_touching(self.cells)
            if np.any(need_u & (self.u_frac[1:-1] == 0.0)) or \
                    np.any(need_v & (self.v_frac[:, 1:-1] == 0.0)):
                raise ValueError("SolidBoundary: a face next to a solid cell must be solid")
        object.__setattr__(self, "has_cells", bool(self.cells.any()))  # frozen: set once here
        object.__setattr__(self, "cut", cut)

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


    @classmethod
    def from_shapes(cls, shapes: Sequence[Any], nx: int, ny: int, dx: float,
                    open_sides: np.ndarray, u_solid: np.ndarray | None = None,
                    v_solid: np.ndarray | None = None) -> SolidBoundary:
        """Cut-cell boundary of the union of convex 2D ``shapes`` (anything with
        ``signed_distance`` and ``bounding_box`` in world coordinates: the placed circles, boxes
        and polygons of ``scene.shapes``) on an ``nx`` x ``ny`` grid of cell size ``dx``: exact
        face fractions (``cutcell.face_fractions``), distances at the samples, cell areas. The
        closed sides of the domain are solid faces as in ``from_cells``. Velocities default to
        zero (a resting solid); a moving solid gives the normal velocity of its motion on every
        face it covers or cuts and at every sample inside it."""
        u_frac, v_frac = cutcell.face_fractions(shapes, nx, ny, dx)
        u_frac[0] = np.where(open_sides[0], u_frac[0], 1.0)
        u_frac[-1] = np.where(open_sides[1], u_frac[-1], 1.0)
        v_frac[:, 0] = np.where(open_sides[2], v_frac[:, 0], 1.0)
        v_frac[:, -1] = np.where(open_sides[3], v_frac[:, -1], 1.0)
        pu, pv, pc = cutcell.sample_points(nx, ny, dx)
        u_dist = cutcell.union_distance(shapes, pu)
        v_dist = cutcell.union_distance(shapes, pv)
        c_dist = cutcell.union_distance(shapes, pc)
        area = 1.0 - cutcell.cell_solid_fractions(shapes, nx, ny, dx)
        u_solid = np.zeros(u_frac.shape) if u_solid is None else np.asarray(u_solid, float)
        v_solid = np.zeros(v_frac.shape) if v_solid is None else np.asarray(v_solid, float)
        return cls(np.ascontiguousarray(c_dist < 0.0), u_frac, v_frac, u_solid, v_solid,
                   u_dist, v_dist, c_dist, area)


def _faces_touching(cells: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Interior x- and y-faces with a solid cell on either side."""
    return cells[1:] | cells[:-1], cells[:, 1:] | cells[:, :-1]


def open_sides(spec: FluidSpec) -> np.ndarray:
    """Which sides (left, right, bottom, top) are open, as the kernels index them. An inflow
    side is closed: its faces are solid faces moving at the inflow velocity."""
    return np.array([spec.walls.get(s, "solid") == "open" for s in SIDES])


def inflow_velocities(spec: FluidSpec, u_solid: np.ndarray, v_solid: np.ndarray,
                      factor: float = 1.0) -> None:
    """Write the inflow profile (times ``factor``) into the normal velocity of the inflow side's
    faces: u on the left/right side, v on the bottom/top, pointing into the domain; each face
    gets the profile's mean over it, so the inflow rate is exact."""
    inflow = spec.inflow
    if inflow is None:
        return
    nx, ny = spec.resolution
    dx = spec.dx
    lx, ly = spec.domain
    side = inflow.side
    n = ny if side in ("left", "right") else nx
    width = ly if side in ("left", "right") else lx
    s = np.arange(n + 1) * dx
    vel = factor * inflow.face_average(s[:-1], s[1:], width)
    if side == "left":
        u_solid[0] = vel
    elif side == "right":
        u_solid[-1] = -vel
    elif side == "bottom":
        v_solid[:, 0] = vel
    else:
        v_solid[:, -1] = -vel


def static_boundary(spec: FluidSpec, centres: np.ndarray) -> SolidBoundary:
    """The scene's obstacles at rest (cut cells, ``SolidBoundary.from_shapes``), the closed sides,
    and the inflow side moving at the inflow velocity. Without obstacles, the staircase boundary
    of the closed sides (``from_cells`` of no cells), as before cut cells existed."""
    nx, ny = centres.shape[:2]
    u_solid = np.zeros((nx + 1, ny))
    v_solid = np.zeros((nx, ny + 1))
    inflow_velocities(spec, u_solid, v_solid)
    if spec.obstacles:
        return SolidBoundary.from_shapes(spec.obstacles, nx, ny, spec.dx, open_sides(spec),
                                         u_solid, v_solid)
    return SolidBoundary.from_cells(np.zeros((nx, ny), bool), open_sides(spec), u_solid, v_solid)


def impose(u: np.ndarray, v: np.ndarray, ustate: np.ndarray, vstate: np.ndarray,
           bnd: SolidBoundary) -> None:
    """Set the solid faces of ``u``, ``v`` to the solid's velocity: the Neumann data of the
    projection, which leaves these faces as they are (so they keep it after the step). Cut faces
    (partly open) are fluid faces: the projection moves them, and their solid part enters the
    divergence with the solid's velocity."""
    np.copyto(u, bnd.u_solid, where=ustate == SOLID)
    np.copyto(v, bnd.v_solid, where=vstate == SOLID)
