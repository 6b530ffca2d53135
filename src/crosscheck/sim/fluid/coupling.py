"""Two-way coupling of a rigid body with the fluid: the body's velocity as unknowns of the
pressure solve (Batty, Bertails and Bridson 2007).

Only a fluid case with a dynamic body (``[[bodies]]`` in a case with a ``[fluid]`` section,
``FluidSpec.bodies``) builds a :class:`Coupling`; a fluid without bodies never imports this
module's solver paths (docs/fluid.md, "Rigid bodies in the fluid").

One coupled step (``FluidState.step`` calls the pieces in this order):

1. ``begin_step(dt)``: the body moves with the velocity it ended the last step with (its centre of
   mass by ``dt V``, its angle by ``dt omega``), and the solid boundary is rebuilt at the new pose:
   the body's cut cells (exact face fractions, distances, areas, :mod:`cutcell`, computed in a
   window around the body) joined with the scene's static boundary, with the body's rigid
   velocity on every face and sample it covers or cuts. Redistancing, the face states and
   everything after the advection use this boundary; the advection (a trace's clipping and
   the solid's velocity it reads, the central scheme's term) reads the step's starting field
   on the boundary that field belongs to, ``previous`` (the body's pose and velocity at the
   step's start).
2. ``predict(dt)``: gravity on the body, ``V* = V + g dt``, and the viscous exchange predicted
   from the last step's (taken back in 3, so only the wall's velocity in the viscous step
   changes); with a viscous fluid the previous pressure then acts on fluid and body
   (``pressure.apply_pressure_coupled``, the incremental projection: the solve in 4 is for the
   increment).
3. (viscous fluids) ``viscous_exchange``: the viscous step sees the body as a no-slip wall moving
   at ``V*`` (ghost fluid, viscosity.py, with each face's momentum weighed by its open fraction
   and the slivers, cut faces whose sample is inside the body, as unknowns); the momentum it
   puts into the fluid through that wall is taken from the body (an explicit, partitioned
   exchange: exact momentum balance, stable while ``rho nu dt sum(1/theta) / M`` is well below
   1; the largest value met is in the run's meta). The wall is held at least
   ``viscosity.MOVING_THETA_MIN`` of a cell from the samples.
4. the coupled projection (``pressure.project_coupled``): with ``J`` the body's flux through the
   cells' faces (``J_c = sum_f s_f beta_f (e_f, (r_f x e_f)_z)``, ``beta_f`` the face's solid
   fraction belonging to the body, ``s_f`` +-1 outward, ``r_f`` from the centre of mass to the
   midpoint of the face's solid part: the flux of the rigid motion through it, exactly) and
   ``D = rho dx^2 diag(1/M, 1/M, 1/I)``, the scaled pressure solves

       (A + J D J^T) pt = -div*          (A: the weighted Poisson matrix of pressure.py)

   and the body's velocity is ``(V, omega) = (V*, omega*) + D J^T pt``: the pressure force
   ``F = dx sum_c p_c J_c`` is the discrete ``-(closed integral of p n)`` over the wetted surface
   (cells in the air have p = 0), and ``J`` in the divergence is the discrete flux of the body's
   rigid motion, so the matrix is symmetric positive (semi)definite, the kinetic energy of fluid
   and body is what the projection minimises, and the final fluid velocity is divergence free
   with the body's new velocity on its faces.
5. ``finish()``: the boundary's body velocities are the new ones (the solid faces carry them).

The step is symplectic Euler for the body (position with the old velocity, then the velocity
with the forces at the new position).

Limits, stated: one body; the body must keep clear of the domain's sides and the obstacles by
``CLEARANCE_CELLS`` cells (there is no contact between a body and solids in the fluid; a run in
which it comes closer stops with that reason, as failure data); the viscous exchange is
explicit (above).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from crosscheck.rotations import angle_to_matrix
from crosscheck.scene.shapes import Placed
from crosscheck.sim.fluid import bodygeom
from crosscheck.sim.fluid.boundary import SolidBoundary
from crosscheck.sim.fluid.boundary import SolidStop as CouplingStop
from crosscheck.sim.fluid.pressure import AIR
from crosscheck.sim.fluid.viscosity import DIRECTIONS, sliver_weights

# The body's geometry is computed in a window of its bounding box grown by this many cells
# (distances beyond it are only ever compared with zero: path clipping, ghost-fluid walls).
WINDOW_MARGIN = 4

# The convective exchange balances the momentum of the faces within this many cells of the
# body's wall (and those inside it): where a trace can read the body. MacCormack's step reads
# its field through two bilinear interpolations (one cell each), the backward one from a
# departure point up to the CFL limit (half a cell) away. Inside the band a semi-Lagrangian
# trace's own loss of momentum is not the wall's; measured on a disc held in a Re ~ 14 stream,
# the whole window (4 cells beyond the body) gave the body -0.25 / -0.53 % of the fluid's
# balance at 4 / 8 cells, this band -0.39 / -0.07 % (docs/fluid.md).
CONVECTIVE_BAND_CELLS = 2.5
# Closest the body may come to a closed side or an obstacle, in cells (its cut faces and those
# of the other solid must not share a cell: a face has one solid velocity).
CLEARANCE_CELLS = 1.5
# Distance written where no solid is near (finite: interpolating it must not make NaN).
FAR = 1e6


@dataclass
class BodyState:
    """A rigid 2D body in the fluid: per unit depth (mass kg/m, inertia kg m^2/m)."""

    name: str
    shape: Any            # body-frame shape: Circle, 2D Box, Polygon
    mass: float
    inertia: float        # about the centre of mass
    com_body: np.ndarray  # centre of mass in the body frame
    x: np.ndarray         # centre of mass, world
    angle: float
    v: np.ndarray         # velocity of the centre of mass
    omega: float

    @classmethod
    def from_body(cls, body: Any) -> BodyState:
        com = np.asarray(body.com, float)[:2].copy()
        angle = float(body.orientation[0])
        x = np.asarray(body.position, float)[:2] + angle_to_matrix(angle) @ com
        return cls(body.name, body.shape, float(body.mass),
                   float(np.asarray(body.inertia, float).reshape(-1)[0]), com, x, angle,
                   np.asarray(body.velocity, float)[:2].copy(),
                   float(np.asarray(body.angular_velocity, float).reshape(-1)[0]))

    def placed(self, offset: np.ndarray | None = None) -> Placed:
        """The shape at the body's pose (shifted by ``-offset``: a window's own coordinates)."""
        origin = self.x - angle_to_matrix(self.angle) @ self.com_body
        if offset is not None:
            origin = origin - offset
        return Placed(self.shape, origin, self.angle)

    def kinetic_energy(self) -> float:
        return 0.5 * self.mass * float(self.v @ self.v) + 0.5 * self.inertia * self.omega ** 2

    def potential_energy(self, gravity: np.ndarray) -> float:
        return -self.mass * float(gravity @ self.x)


@dataclass
class BodyGeometry:
    """The body's cut cells in the window ``[i0:i1, j0:j1]`` of cells (faces: ``u`` on
    ``[i0:i1+1, j0:j1]``, ``v`` on ``[i0:i1, j0:j1+1]``)."""

    i0: int
    i1: int
    j0: int
    j1: int
    u_frac: np.ndarray
    v_frac: np.ndarray
    u_dist: np.ndarray
    v_dist: np.ndarray
    c_dist: np.ndarray
    solid_area: np.ndarray   # solid area fraction of each window cell
    jx: np.ndarray           # (wi, wj): the rows of J (see the module docstring)
    jy: np.ndarray
    jw: np.ndarray
    ry_u: np.ndarray         # y of the u faces' solid parts' midpoints from the centre of mass
    rx_v: np.ndarray         # x of the v faces' solid parts' midpoints
    kind: int                # bodygeom.CIRCLE or POLYGON, with the shape's world parameters
    centre: np.ndarray
    radius: float
    verts: np.ndarray

    @property
    def cells(self) -> tuple[slice, slice]:
        return slice(self.i0, self.i1), slice(self.j0, self.j1)

    @property
    def ufaces(self) -> tuple[slice, slice]:
        return slice(self.i0, self.i1 + 1), slice(self.j0, self.j1)

    @property
    def vfaces(self) -> tuple[slice, slice]:
        return slice(self.i0, self.i1), slice(self.j0, self.j1 + 1)


def body_geometry(body: BodyState, nx: int, ny: int, dx: float,
                  margin: int = WINDOW_MARGIN) -> BodyGeometry:
    placed = body.placed()
    lo, hi = placed.bounding_box()
    i0 = max(int(math.floor(lo[0] / dx)) - margin, 0)
    j0 = max(int(math.floor(lo[1] / dx)) - margin, 0)
    i1 = min(int(math.ceil(hi[0] / dx)) + margin, nx)
    j1 = min(int(math.ceil(hi[1] / dx)) + margin, ny)
    if i1 <= i0 or j1 <= j0:
        raise CouplingStop(f"body {body.name!r} left the domain")
    wi, wj = i1 - i0, j1 - j0
    kind, c, r, verts = bodygeom.shape_params(placed)
    u_frac, v_frac, u_mid, v_mid, u_dist, v_dist, c_dist, solid_area = \
        bodygeom.window_geometry(kind, c, r, verts, i0, j0, wi, wj, dx, bodygeom.GAUSS_S,
                                 bodygeom.GAUSS_W)
    # lever arms of the midpoints of the faces' solid parts (world minus the centre of mass):
    # the rigid velocity is linear along a face, so the flux through its solid part is exactly
    # the fraction times the velocity there (a spinning circle moves no water)
    ry_u = (np.arange(j0, j1)[None, :] + u_mid) * dx - body.x[1]
    rx_v = (np.arange(i0, i1)[:, None] + v_mid) * dx - body.x[0]
    jx = u_frac[1:] - u_frac[:-1]
    jy = v_frac[:, 1:] - v_frac[:, :-1]
    jw = -(u_frac[1:] * ry_u[1:] - u_frac[:-1] * ry_u[:-1]) \
        + (v_frac[:, 1:] * rx_v[:, 1:] - v_frac[:, :-1] * rx_v[:, :-1])
    return BodyGeometry(i0, i1, j0, j1, u_frac, v_frac, u_dist, v_dist, c_dist, solid_area,
                        np.ascontiguousarray(jx), np.ascontiguousarray(jy),
                        np.ascontiguousarray(jw), ry_u, rx_v, kind, c, r, verts)


class Coupling:
    """The dynamic body of a fluid case, and what the fluid step needs of it."""

    def __init__(self, bodies: Any, static: SolidBoundary, nx: int, ny: int, dx: float,
                 density: float, gravity: np.ndarray, has_surface: bool = True):
        if len(bodies) != 1:
            raise ValueError("the coupled fluid step has one body's unknowns (got "
                             f"{len(bodies)})")
        self.body = BodyState.from_body(bodies[0])
        self.nx, self.ny, self.dx = nx, ny, dx
        self.rho = density
        self.gravity = np.asarray(gravity, float)[:2]
        # gravity's size and the upward unit vector (straight up without gravity: a free
        # surface's level is then still a height), for the hydrostatic force and the moment
        self.g_mag = float(np.linalg.norm(self.gravity))
        self.up = -self.gravity / self.g_mag if self.g_mag > 0.0 else np.array([0.0, 1.0])
        self.static = static
        self.has_surface = has_surface
        # the static solid's parts a cut boundary needs, once
        self.s_u_dist = static.u_dist if static.cut else np.full(static.u_frac.shape, FAR)
        self.s_v_dist = static.v_dist if static.cut else np.full(static.v_frac.shape, FAR)
        self.s_c_dist = static.c_dist if static.cut else np.full(static.cells.shape, FAR)
        self.s_area = static.fluid_area if static.cut else (~static.cells).astype(float)
        self.geometry: BodyGeometry | None = None
        self.boundary: SolidBoundary | None = None
        self.viscous_number = 0.0       # largest rho nu dt sum(1/theta) / M met
        self.last_force = np.zeros(3)   # fluid force and torque on the body over the last step
        # the viscous exchange's velocity change per unit time, last step (predict), and the
        # part of it put on the body ahead of this step's exchange
        self.exchange_rate = np.zeros(3)
        self.predicted_exchange = np.zeros(3)
        # the boundary of the last step (convective_exchange's "before") and the convective
        # exchange's velocity change, put on the body with gravity (predict)
        self.previous: SolidBoundary | None = None
        self.convective_change = np.zeros(3)
        # steps whose convective exchange was applied, and steps of a viscous coupled run that
        # went without it because the free surface crossed the body's window (window_is_wet):
        # the run's metadata reports both, so a run that lost the exchange says so
        self.convective_steps = 0
        self.surface_skips = 0

    # -- geometry ----------------------------------------------------------------------------
    def build(self) -> SolidBoundary:
        """The boundary of the static solid and the body at its current pose and velocity."""
        g = self.geometry = body_geometry(self.body, self.nx, self.ny, self.dx)
        st = self.static
        su, sv = st.u_frac[g.ufaces], st.v_frac[g.vfaces]
        limit = CLEARANCE_CELLS * self.dx
        near = (np.any((g.u_frac > 0) & (self.s_u_dist[g.ufaces] < limit))
                or np.any((g.v_frac > 0) & (self.s_v_dist[g.vfaces] < limit))
                or np.any((g.u_frac > 0) & (su > 0)) or np.any((g.v_frac > 0) & (sv > 0)))
        if near or self._near_side(g):
            raise CouplingStop(f"body {self.body.name!r} came within {CLEARANCE_CELLS:g} cells "
                               "of a wall or an obstacle (contact between a body and solids in "
                               "the fluid is not modelled)")
        u_frac = st.u_frac.copy()
        v_frac = st.v_frac.copy()
        u_frac[g.ufaces] = np.minimum(su + g.u_frac, 1.0)
        v_frac[g.vfaces] = np.minimum(sv + g.v_frac, 1.0)
        u_dist = self.s_u_dist.copy()
        v_dist = self.s_v_dist.copy()
        c_dist = self.s_c_dist.copy()
        u_dist[g.ufaces] = np.minimum(u_dist[g.ufaces], g.u_dist)
        v_dist[g.vfaces] = np.minimum(v_dist[g.vfaces], g.v_dist)
        c_dist[g.cells] = np.minimum(c_dist[g.cells], g.c_dist)
        area = self.s_area.copy()
        area[g.cells] = np.maximum(area[g.cells] - g.solid_area, 0.0)
        u_solid = st.u_solid.copy()
        v_solid = st.v_solid.copy()
        self.boundary = SolidBoundary(np.ascontiguousarray(c_dist < 0.0), u_frac, v_frac,
                                      u_solid, v_solid, u_dist, v_dist, c_dist, area)
        self.write_velocity()
        return self.boundary

    def _near_side(self, g: BodyGeometry) -> bool:
        lo, hi = self.body.placed().bounding_box()
        limit = CLEARANCE_CELLS * self.dx
        lx, ly = self.nx * self.dx, self.ny * self.dx
        closed = self.static.u_frac[0].min() >= 1.0, self.static.u_frac[-1].min() >= 1.0, \
            self.static.v_frac[:, 0].min() >= 1.0, self.static.v_frac[:, -1].min() >= 1.0
        gaps = (lo[0], lx - hi[0], lo[1], ly - hi[1])
        for is_closed, gap in zip(closed, gaps, strict=True):
            if gap < (limit if is_closed else 0.0):
                return True
        return False

    def write_velocity(self) -> None:
        """The body's rigid velocity on the faces and samples it covers or cuts."""
        g, b, bnd = self.geometry, self.body, self.boundary
        mu = (g.u_frac > 0) | (g.u_dist < 0)
        mv = (g.v_frac > 0) | (g.v_dist < 0)
        uw = bnd.u_solid[g.ufaces]
        vw = bnd.v_solid[g.vfaces]
        uw[mu] = (b.v[0] - b.omega * g.ry_u)[mu]
        vw[mv] = (b.v[1] + b.omega * g.rx_v)[mv]

    # -- the step ----------------------------------------------------------------------------
    def begin_step(self, dt: float) -> SolidBoundary:
        b = self.body
        self.previous = self.boundary
        b.x = b.x + dt * b.v
        b.angle = b.angle + dt * b.omega
        return self.build()

    def predict(self, dt: float) -> None:
        """``V* = V + g dt``, plus the viscous exchange this step is predicted to take (the
        last one's, per unit time): the viscous step then sees the body's wall at about the
        velocity the body ends the step with, not faster by ``dt F_viscous / M``, and
        ``viscous_exchange`` takes the prediction back, so the momentum is the exchange's
        alone. Without it that splitting error was first order in the step: a disc of the
        settling density held at 0.0544 m/s felt 2.8 % more drag than a driven heavy one at
        2 ms, 1.1 % at 0.5 ms (docs/fluid.md, "The settling disc in its own frame")."""
        self.dt = dt
        self.v_start = self.body.v.copy()
        self.omega_start = self.body.omega
        self.predicted_exchange = self.exchange_rate * dt
        self.body.v = (self.body.v + dt * self.gravity + self.predicted_exchange[:2]
                       + self.convective_change[:2])
        self.body.omega = (self.body.omega + float(self.predicted_exchange[2])
                           + float(self.convective_change[2]))
        self.convective_change = np.zeros(3)
        self.write_velocity()

    def rows(self, index: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The rows of J for the pressure unknowns (``index``: the compressed cell numbers, -1
        for no unknown): cell numbers (m,), values (m, 3), and D's diagonal (3,)."""
        g = self.geometry
        idx = index[g.cells]
        use = (idx >= 0) & ((g.jx != 0.0) | (g.jy != 0.0) | (g.jw != 0.0))
        jk = np.ascontiguousarray(idx[use])
        jv = np.ascontiguousarray(np.stack([g.jx[use], g.jy[use], g.jw[use]], axis=1))
        s = self.rho * self.dx * self.dx
        dinv = np.array([s / self.body.mass, s / self.body.mass, s / self.body.inertia])
        ii, jj = np.nonzero(use)
        self._row_centres = np.stack([(ii + g.i0 + 0.5) * self.dx,
                                      (jj + g.j0 + 0.5) * self.dx], axis=1)
        return jk, jv, dinv

    def hydrostatic(self, phi: np.ndarray, jv: np.ndarray, dinv: np.ndarray) -> np.ndarray:
        """The velocity change (vx, vy, omega) that replaces the hydrostatic part of the
        discrete pressure force by Archimedes' exact one.

        The discrete force ``dx J^T p`` applies each cut cell's pressure at the cell's centre,
        not at the wall: the buoyancy of a floating box is then off by ``rho g`` times the
        distance from its bottom to the centre of the cell row the bottom cuts (up to half a
        cell of draft), and its restoring moment (the metacentric ``BM`` term, which comes from
        the pressure varying along the tilted bottom) is lost below a tilt that moves the
        bottom across a grid line: measured, a box stable by its metacentric height rolled over
        from round-off. With the reference hydrostatic pressure ``p0 = rho g (L - y)`` (``L``
        the water level beside the body), the body's force is taken as ``dx J^T (p - p0)`` plus
        the exact force and moment of ``p0``: ``rho g`` times the area of the body below ``L``,
        at that area's centroid (``bodygeom.submerged``). This is a force known before the
        solve (geometry and level only), added to ``V*``; the solve stays symmetric."""
        g = self.geometry
        gmag, up = self.g_mag, self.up
        if gmag == 0.0 or jv.shape[0] == 0:
            return np.zeros(3)
        level = self.level(phi)
        area, centroid = bodygeom.submerged(g.kind, g.centre, g.radius, g.verts, up, level)
        b = self.body
        dt = self.dt
        force = self.rho * gmag * area * up
        r = centroid - b.x
        exact = np.array([dt * force[0] / b.mass, dt * force[1] / b.mass,
                          dt * (r[0] * force[1] - r[1] * force[0]) / b.inertia])
        pt0 = gmag * dt * (level - self._row_centres @ up) / self.dx
        discrete = dinv * (jv.T @ pt0)
        return exact - discrete

    def level(self, phi: np.ndarray) -> float:
        """The water level beside the body: the free surface's height (along -gravity, which
        the loader requires vertical) in the columns just outside the body's window, averaged;
        the top of the domain for a fluid without a free surface."""
        from crosscheck.sim.fluid.levelset import surface_height

        if not self.has_surface:
            return self.ny * self.dx
        g = self.geometry
        cols = [i for i in (g.i0 - 1, g.i1) if 0 <= i < self.nx] or [g.i0, g.i1 - 1]
        return float(np.mean([surface_height(phi, i, 0.0, self.dx) for i in cols]))

    def apply_impulse(self, dvel: np.ndarray) -> None:
        """Add ``(dvx, dvy, domega)`` to the body's velocity (the projection's answer)."""
        self.body.v = self.body.v + dvel[:2]
        self.body.omega = self.body.omega + float(dvel[2])
        self.write_velocity()

    def finish(self, dt: float) -> None:
        """After the projection: the fluid's force and torque on the body over the step (its
        momentum change less gravity's), for the record."""
        b = self.body
        self.last_force = np.array([
            *(b.mass * ((b.v - self.v_start) / dt - self.gravity)),
            b.inertia * (b.omega - self.omega_start) / dt])

    def convective_exchange(self, u_old: np.ndarray, v_old: np.ndarray, u_new: np.ndarray,
                            v_new: np.ndarray, flux_u: np.ndarray, flux_v: np.ndarray,
                            dt: float) -> None:
        """Give the body the momentum the convection made at its wall, so that fluid and body
        together change their momentum by what flows in from outside the body's neighbourhood
        and nothing else.

        Over the faces within ``CONVECTIVE_BAND_CELLS`` of the body's wall and those inside it,
        the fluid's momentum counted as the projection counts it (each face by its open
        fraction) plus the body's part of each face moving at the body's velocity (``frac *
        u_solid``, the fluid the body displaces) must change, over the convection, by the
        momentum that flows in across the band's edge: ``-dt rho dx^2 sum(N_all)``, where
        ``N_all`` (``flux_u``, ``flux_v``) is the central convective term computed on every face
        of the window, those inside the body too, from the same padded velocities (in divergence
        form, its sum over any set of faces telescopes to the set's edge). With the `central`
        scheme it is the step's own Adams-Bashforth combination; after a semi-Lagrangian or
        MacCormack trace it is the term of the field the trace starts from (an estimate of the
        flux the trace carried, to first order in the step). The discretisation at the cut
        cells does not keep that balance (the fluxes between a cut face and the body's samples,
        or a trace reading the body's velocity, carry momentum into or out of the fluid that no
        wall force accounts for); the difference goes to the body, which then feels what the
        fluid's momentum balance gives it. Measured on a disc held in a Re ~ 14 stream at 4
        cells per diameter, the body's force against the fluid's momentum balance around it:
        `central` +2.26 % without this, -0.22 % with it; `maccormack` +2.30 / -0.39 %;
        `semi_lagrangian` -7.95 / -1.54 % (docs/fluid.md, "The convective exchange after a
        trace"). The moment is balanced the same way, about the centre of mass: the change of
        the band's angular momentum plus the moment of the same terms, faces at their
        positions. In the band's interior that sum is not exactly an edge flux (the scheme
        conserves momentum, not angular momentum), but the interior's share is of the scheme's
        truncation; the wall's is not. Measured on a disc spinning in fluid at rest at Re =
        omega a^2 / nu = 200, 128 cells, after 0.4 s: the fluid's gain of angular momentum
        against the body's loss 0.993 (`central` and `maccormack`) with the moment, 1.049 and
        1.025 without (the convection having given the fluid 5.6 and 3.2 % of the body's loss);
        at Re 260 the settling disc then released on the axis (`sedimentation_wachs` at 8
        cells, 2026-11-30) wandered less from it and read -1.25 % of the published speed
        instead of -2.34 % (docs/fluid.md). ``u_old``,
        ``v_old``: the field at the start of the step (on ``previous``, the last step's
        boundary); ``u_new``, ``v_new``: after the convection, the slivers kept."""
        g, bnd, old = self.geometry, self.boundary, self.previous
        if old is None:
            return
        moved = np.zeros(2)
        turned = 0.0
        limit = CONVECTIVE_BAND_CELLS * self.dx
        # the faces' lever arms about the centre of mass (its place for this step): a u face's
        # momentum has the moment -y u, a v face's x v
        arm_u = -((np.arange(g.j0, g.j1) + 0.5) * self.dx - self.body.x[1])[None, :]
        arm_v = ((np.arange(g.i0, g.i1) + 0.5) * self.dx - self.body.x[0])[:, None]
        for comp, (sl, dist, frac_o, sol_o, frac_n, sol_n, qo, qn, flux, arm) in enumerate((
                (g.ufaces, g.u_dist, old.u_frac, old.u_solid, bnd.u_frac, bnd.u_solid, u_old,
                 u_new, flux_u, arm_u),
                (g.vfaces, g.v_dist, old.v_frac, old.v_solid, bnd.v_frac, bnd.v_solid, v_old,
                 v_new, flux_v, arm_v))):
            fo, fn = frac_o[sl], frac_n[sl]
            m = (dist < limit).astype(float)     # the band around the wall, the body inside
            change = (m * ((1.0 - fn) * qn[sl] + fn * sol_n[sl])
                      - m * ((1.0 - fo) * qo[sl] + fo * sol_o[sl]) + dt * m * flux[sl])
            moved[comp] = float(np.sum(change))
            turned += float(np.sum(arm * change))
        made = self.rho * self.dx * self.dx * moved     # momentum made in the band
        made_moment = self.rho * self.dx * self.dx * turned
        self.convective_steps += 1
        self.convective_change = np.array([-made[0] / self.body.mass,
                                           -made[1] / self.body.mass,
                                           -made_moment / self.body.inertia])

    def window_is_wet(self, ustate: np.ndarray, vstate: np.ndarray) -> bool:
        """Whether every face of the body's window is fluid or solid (no air: a free surface
        in the window moves momentum across faces the balance cannot follow)."""
        g = self.geometry
        return bool(np.all(ustate[g.ufaces] != AIR) and np.all(vstate[g.vfaces] != AIR))

    def viscous_exchange(self, u_new: np.ndarray, v_new: np.ndarray,
                         links: tuple[np.ndarray, np.ndarray], nu: float, dt: float,
                         theta_min: float, phi: np.ndarray) -> None:
        """Take from the body the momentum the viscous step put into the fluid through the
        body's no-slip wall (viscosity.diffuse_implicit, whose rows weigh each face's momentum
        by its open fraction, so that this is the fluid's momentum change):

        * at a fluid sample whose neighbour lies inside the body at the fraction theta of the
          way, the wall's term ``nu dt (q_wall - q) / (theta dx^2)`` per unit area, a momentum
          ``rho nu dt (q_wall - q) / theta`` per sample, applied at the wall point; unless that
          neighbour is a sliver linked to the sample (the link replaces the wall);
        * at a sliver, its wall's term ``rho nu dt w (q_wall - q)`` (``w = 2 / f``,
          viscosity.sliver_weights), at the point where the wall crosses its face.

        and, on the body's spin, the moment those terms leave out
        (:meth:`symmetric_stress_moment`).

        ``links``: the u and v slivers' ``viscosity.sliver_links`` the viscous step used;
        ``phi``: the level set (the wetted part of the wall)."""
        g, b, bnd = self.geometry, self.body, self.boundary
        px = np.zeros(3)
        coupling_sum = 0.0
        k = nu * dt / (self.dx * self.dx)
        for comp in (0, 1):
            if comp == 0:
                sl = g.ufaces
                frac, dist = bnd.u_frac[sl], bnd.u_dist[sl]
                q = u_new[sl]
                qs = bnd.u_solid[sl]
                body_in = g.u_dist < 0.0
                xs = (np.arange(g.i0, g.i1 + 1) * self.dx)[:, None] + 0.0 * q
                ys = ((np.arange(g.j0, g.j1) + 0.5) * self.dx)[None, :] + 0.0 * q
            else:
                sl = g.vfaces
                frac, dist = bnd.v_frac[sl], bnd.v_dist[sl]
                q = v_new[sl]
                qs = bnd.v_solid[sl]
                body_in = g.v_dist < 0.0
                xs = ((np.arange(g.i0, g.i1) + 0.5) * self.dx)[:, None] + 0.0 * q
                ys = (np.arange(g.j0, g.j1 + 1) * self.dx)[None, :] + 0.0 * q
            link = links[comp][sl]
            fluid = dist >= 0.0
            n0, n1 = q.shape
            for s, (di, dj) in enumerate(DIRECTIONS):
                a = slice(max(-di, 0), n0 - max(di, 0))
                c = slice(max(-dj, 0), n1 - max(dj, 0))
                an = slice(max(di, 0), n0 - max(-di, 0))
                cn = slice(max(dj, 0), n1 - max(-dj, 0))
                # a linked sliver's link points back along s ^ 1
                pair = fluid[a, c] & body_in[an, cn] & (link[an, cn] != (s ^ 1))
                if not pair.any():
                    continue
                d_here = dist[a, c][pair]
                d_nb = dist[an, cn][pair]
                theta = np.maximum(d_here / (d_here - d_nb), theta_min)
                dq = (qs[an, cn][pair] - q[a, c][pair]) / theta
                mom = self.rho * nu * dt * dq          # into the fluid, per sample
                wx = xs[a, c][pair] + theta * di * self.dx - b.x[0]
                wy = ys[a, c][pair] + theta * dj * self.dx - b.x[1]
                if comp == 0:
                    px[0] += mom.sum()
                    px[2] += float(np.sum(-wy * mom))
                else:
                    px[1] += mom.sum()
                    px[2] += float(np.sum(wx * mom))
                coupling_sum += float(np.sum(1.0 / theta))
            # the slivers' walls
            ii, jj = np.nonzero((link >= 0) & body_in)
            if ii.size:
                f, t, tw = sliver_weights(1.0 - frac[ii, jj])
                mom = self.rho * nu * dt * tw * (qs[ii, jj] - q[ii, jj])
                offset = DIRECTIONS[link[ii, jj]]
                off = 0.5 - f                  # the wall's crossing, from the sample, in cells
                wx = xs[ii, jj] + off * offset[:, 0] * self.dx - b.x[0]
                wy = ys[ii, jj] + off * offset[:, 1] * self.dx - b.x[1]
                if comp == 0:
                    px[0] += float(mom.sum())
                    px[2] += float(np.sum(-wy * mom))
                else:
                    px[1] += float(mom.sum())
                    px[2] += float(np.sum(wx * mom))
                # what the wall's velocity moves through the sliver's solved value
                coupling_sum += float(np.sum(tw * (f / k + t) / (f / k + t + tw)))
        if nu > 0.0:
            self.viscous_number = max(self.viscous_number,
                                      self.rho * nu * dt * coupling_sum / b.mass)
        px[2] += self.symmetric_stress_moment(phi, nu) * dt
        exchange = -px / np.array([b.mass, b.mass, b.inertia])
        self.apply_impulse(exchange - self.predicted_exchange)
        self.predicted_exchange = np.zeros(3)
        self.exchange_rate = exchange / dt

    def symmetric_stress_moment(self, phi: np.ndarray, nu: float) -> float:
        """The moment about the centre of mass, into the fluid, that the viscous wall terms
        leave out: ``rho nu omega W``, ``W`` the integral of ``(x - x_c) . n`` over the wetted
        wall.

        The viscous step diffuses each velocity component (``nu`` times the Laplacian of u), so
        the momentum it moves through the wall is ``mu du/dn``, not the traction of the
        symmetric stress ``mu (grad u + grad u^T) n``. In the fluid both forms are the same
        equation (the divergence of ``grad u^T`` is the gradient of ``div u = 0``); on the
        body's wall, where u is the rigid motion ``V + omega x (x - x_c)`` and (both fields
        divergence-free, equal on the wall) the normal derivative of the difference has no
        normal part, the term left out is ``mu (grad u^T) n = mu n x omega``: it has no force
        (its integral over a closed wall is zero) but the moment ``-mu omega W`` on the body.
        ``W`` is ``2 A`` for a body in the fluid (``div (x - x_c) = 2``) and, for one the free
        surface cuts, ``2 A_sub`` less the waterline's share ``h c`` (``h`` the level's height
        above the centre of mass, ``c`` the chord), the air side carrying no stress.

        Without it the moment is that of ``mu du/dn`` alone, which resists even a rigid
        rotation of the fluid with the body: a disc free to spin in a shear flow spun at the
        full shear rate instead of half of it (measured: 1.986 times half at 8 cells per
        diameter, Re 0.01; tests/fluid/test_coupling.py), and a disc spinning in a fluid at
        rest felt half the wall's stress."""
        g, b = self.geometry, self.body
        wetted = bodygeom.wetted_moment_arm(g.kind, g.centre, g.radius, g.verts, self.up,
                                            self.level(phi), b.x)
        return self.rho * nu * b.omega * wetted

    # -- measurements ------------------------------------------------------------------------
    def measure(self) -> dict[str, float]:
        b = self.body
        n = b.name
        return {
            f"body_x.{n}": float(b.x[0]), f"body_y.{n}": float(b.x[1]),
            f"body_angle.{n}": float(b.angle),
            f"body_vx.{n}": float(b.v[0]), f"body_vy.{n}": float(b.v[1]),
            f"body_omega.{n}": float(b.omega),
            f"body_force_x.{n}": float(self.last_force[0]),
            f"body_force_y.{n}": float(self.last_force[1]),
            f"body_torque.{n}": float(self.last_force[2]),
            "body_energy": b.kinetic_energy() + b.potential_energy(self.gravity),
        }

