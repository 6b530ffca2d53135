"""The in-house MAC-grid free-surface solver and its integrator registry.

One step (Bridson's splitting; every piece follows the Treuille seed):

1. time step from the CFL number (or the fixed step a sweep asks for);
2. semi-Lagrangian advection of the level set and of both velocity components with the
   velocity of the start of the step, second-order (midpoint) backtrace, path clipping at walls
   and obstacles; MacCormack correction on top for the ``maccormack`` integrator;
3. particle level set correction (``particle_levelset``), redistancing (fast sweeping);
4. body forces (gravity) and explicit viscosity sub-steps;
5. pressure projection with solid walls and the ghost-fluid free surface (``pressure.py``);
6. extension of the new fluid velocity into an air band wide enough for the next step's trace.

A run never raises for a physical failure: exceeding the CFL bound, losing the fluid or
producing non-finite values stops it and is reported in ``FluidRecord.failure``.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from crosscheck.scene.fluid import FluidSpec, Layer
from crosscheck.sim.fluid import kernels as K
from crosscheck.sim.fluid import levelset as LS
from crosscheck.sim.fluid.amg import AMG_MIN_UNKNOWNS, CoupledAMG, StaticAMG
from crosscheck.sim.fluid.boundary import (
    SolidBoundary,
    impose,
    inflow_velocities,
    static_boundary,
)
from crosscheck.sim.fluid.forces import ForceProbe
from crosscheck.sim.fluid.particles import Particles
from crosscheck.sim.fluid.pressure import (
    FLUID,
    apply_pressure,
    apply_pressure_coupled,
    classify_faces,
    fill_new_cells,
    project,
    project_coupled,
    unknown_cells,
)
from crosscheck.sim.fluid.viscosity import (
    MOVING_THETA_MIN,
    THETA_MIN,
    diffuse_implicit,
    sliver_links,
    viscous_dissipation,
)


@dataclass(frozen=True)
class Scheme:
    """An in-house fluid integrator: how fields are advected and whether particles correct the
    level set."""

    name: str
    advection: str      # "linear" semi-Lagrangian or "maccormack"
    particles: bool
    description: str


#: The one place where fluid integrator names are registered.
INTEGRATORS: dict[str, Scheme] = {
    s.name: s for s in (
        Scheme("semi_lagrangian", "linear", False,
               "semi-Lagrangian, midpoint backtrace, bilinear interpolation, plain level set"),
        Scheme("maccormack", "maccormack", False,
               "semi-Lagrangian + MacCormack correction with extrema limiter (Selle et al. 2008)"),
        Scheme("particle_levelset", "linear", True,
               "semi-Lagrangian with the particle level set correction (Enright et al. 2002)"),
        Scheme("particle_levelset_maccormack", "maccormack", True,
               "MacCormack advection with the particle level set correction"),
        Scheme("central", "central", False,
               "second-order central convection (divergence form on the MAC grid), "
               "Adams-Bashforth 2; flows without a free surface"),
    )
}
DEFAULT_INTEGRATOR = "semi_lagrangian"

# Explicit viscosity is stable for nu dt/dx^2 <= 1/4 in 2D (forward Euler on the 5-point
# Laplacian); 0.2 keeps a margin. Sub-stepping the cheap stencil is far cheaper than an implicit
# solve per component at the Reynolds numbers the cases use (cavity: 5 sub-steps of 20 us).
VISCOUS_SUBSTEP_LIMIT = 0.2

PHASES = ("advection", "redistancing", "particles", "forces", "projection", "extension")


class FluidState:
    """Grid, fields and the compiled model of one run (built once from the FluidSpec)."""

    def __init__(self, spec: FluidSpec, gravity: np.ndarray, scheme: Scheme):
        self.spec = spec
        self.scheme = scheme
        self.nx, self.ny = spec.resolution
        self.dx = spec.dx
        self.lx, self.ly = spec.domain
        self.gravity = np.zeros(2) if gravity is None else np.asarray(gravity, float)[:2]
        xc = (np.arange(self.nx) + 0.5) * self.dx
        yc = (np.arange(self.ny) + 0.5) * self.dx
        self.xc, self.yc = np.meshgrid(xc, yc, indexing="ij")
        self.centres = np.stack([self.xc, self.yc], axis=-1)  # (nx, ny, 2): shape query points

        # the scene's obstacles at rest; step() takes another boundary when the solid moves
        self.static_boundary = static_boundary(spec, self.centres)
        self.boundary = self.static_boundary   # the one of the last step (measurements read it)
        # a dynamic body (two-way coupling): only built when the case declares one, so a fluid
        # without bodies runs none of it (issue 14, point 5)
        self.coupling = None
        if spec.bodies:
            from crosscheck.sim.fluid.coupling import Coupling

            if spec.kinematic_viscosity > 0.0 and not spec.no_slip:
                # the case loader refuses it too; a spec built in code must not run it silently
                # (no wall, so no viscous exchange: the body would feel no viscous force)
                raise ValueError("a viscous fluid with a body needs no_slip = true: the viscous "
                                 "momentum is exchanged through the body's no-slip wall")
            self.coupling = Coupling(spec.bodies, self.static_boundary, self.nx, self.ny,
                                     self.dx, spec.density, self.gravity,
                                     spec.has_surface)
            self.boundary = self.coupling.build()

        # ghost-row coefficients (ghost = a * interior + c) for tangential velocity at each side
        def ghost(side: str) -> tuple[float, float]:
            if spec.walls.get(side, "solid") == "inflow":
                return -1.0, 0.0   # the inflow is normal to its side: no tangential velocity
            if spec.walls.get(side, "solid") == "open" or not spec.no_slip:
                return 1.0, 0.0
            return -1.0, 2.0 * spec.wall_speed(side)

        self.gu = (*ghost("bottom"), *ghost("top"))
        self.gv = (*ghost("left"), *ghost("right"))
        if spec.lids and not spec.no_slip:
            # a free-slip lid cannot drive anything: the case is inconsistent, say so by meta
            self.lid_warning = "lid on a free-slip wall has no effect; set fluid.no_slip = true"
        else:
            self.lid_warning = None

        self.has_surface = spec.has_surface
        # the pressure matrix changes every step with a free surface or a moving body; without
        # them it is built once, and a large one is solved by multigrid (sim/fluid/amg.py); with
        # a moving body and no free surface, by the static domain's multigrid and an exact solve
        # of the body's window
        self.amg = None
        self.amg_min = AMG_MIN_UNKNOWNS if spec.pressure_solver == "auto" else 0
        if spec.pressure_solver != "mic0" and not self.has_surface:
            # a coupled body's matrix changes every step: the static domain's hierarchy with an
            # exact solve of the body's window (amg.CoupledAMG)
            self.amg = CoupledAMG() if spec.bodies else StaticAMG()
        elif spec.pressure_solver == "amg" and not spec.bodies:
            self.amg = StaticAMG()
        # band of extended velocity: the backtrace goes at most cfl_limit cells, the midpoint
        # evaluation and the bilinear stencil need up to two more cells beyond it
        self.band_cells = math.ceil(spec.cfl_limit) + 3
        self.redist_cells = self.band_cells + 2
        self.phi = self._initial_phi()
        self.u = np.zeros((self.nx + 1, self.ny))
        self.v = np.zeros((self.nx, self.ny + 1))
        self.up = K.empty_like_padded_u(self.u)
        self.vp = K.empty_like_padded_v(self.v)
        self.zero_u = np.zeros(self.u.shape)
        self.zero_v = np.zeros(self.v.shape)
        self.all_active = np.ones((self.nx + 1, self.ny + 1), bool)
        self.ustate = np.zeros(self.u.shape, np.int8)
        self.vstate = np.zeros(self.v.shape, np.int8)
        self.p = np.zeros((self.nx, self.ny))   # physical pressure (Pa), warm start of the solve
        self.prescribed = spec.prescribed_velocity
        if self.prescribed is not None:
            xu = np.arange(self.nx + 1)[:, None] * self.dx + 0 * yc[None, :]
            yu = (np.arange(self.ny)[None, :] + 0.5) * self.dx + 0 * xu
            self.u = np.ascontiguousarray(self.prescribed.velocity(xu, yu)[0])
            xv = (np.arange(self.nx)[:, None] + 0.5) * self.dx + 0 * np.arange(self.ny + 1)[None]
            yv = np.arange(self.ny + 1)[None, :] * self.dx + 0 * xv
            self.v = np.ascontiguousarray(self.prescribed.velocity(xv, yv)[1])
        self.particles = None
        if scheme.particles or spec.particles.enabled:
            ps = spec.particles
            self.particles = Particles(ps.per_cell, ps.band, ps.reseed_every, ps.seed)
            self.particles.seed(self.phi, self.dx, self.boundary.cells)
        self.classify()
        if self.prescribed is None:
            impose(self.u, self.v, self.ustate, self.vstate, self.boundary)
        self.step_index = 0
        self.time = 0.0
        self.last_iterations = 0
        self.last_viscous_iterations = 0
        self.fluid_cells0 = self.fluid_cells()
        # implicit viscosity with the incremental pressure correction (Van Kan 1986): the step
        # starts from the previous pressure gradient and projects with the increment, so a steady
        # state does not depend on the step and the no-slip walls hold after the projection
        self.implicit = spec.viscosity_solver == "implicit"
        # With a coupled body the previous pressure acts on the body too, on the new step's
        # geometry (pressure.apply_pressure_coupled). Without it the projection's tangential
        # slip dt dp/ds at the body's wall made the coupled step first order with a large
        # constant: a disc settling at Re ~ 14 fell 11.6 % too fast at CFL 0.2; 2.5 % too slowly
        # with it (benchmarks/results/sedimentation_frame.md).
        self.incremental = self.implicit and spec.kinematic_viscosity > 0.0
        self.pressure_cells = None   # the last solve's unknowns (a coupled body uncovers cells)
        self.p_increment = np.zeros((self.nx, self.ny))
        self.no_dist = np.zeros((1, 1))
        # the central scheme: Eulerian convection, Adams-Bashforth 2 with the previous step's term
        self.conv_prev: tuple | None = None   # (N_u, N_v, faces it was computed on)
        # with a coupled body: the term on every face of its window too, and its combination
        # this step (Coupling.convective_exchange)
        self.conv_all_prev: tuple | None = None
        self.conv_all: tuple | None = None
        self.dt_prev = 0.0
        self.unsupported = None
        if scheme.advection == "central" and self.has_surface:
            self.unsupported = ("the central scheme has no free surface (it convects the "
                                "velocity only); use semi_lagrangian or maccormack")
        self.forces = None
        if spec.output.forces.enabled:
            b = self.static_boundary
            area = b.fluid_area if b.fluid_area is not None else np.ones((self.nx, self.ny))
            self.forces = ForceProbe(spec.obstacles, spec.obstacle_names,
                                     [spec.output.forces.window] * len(spec.obstacles),
                                     self.nx, self.ny, self.dx, (self.lx, self.ly), area)

    # -- set-up --------------------------------------------------------------------------
    def _initial_phi(self) -> np.ndarray:
        spec = self.spec
        if not spec.initial:
            # enclosed flow: everything is fluid, no surface to track
            return np.full((self.nx, self.ny), -1e3 * (self.lx + self.ly))
        phi = None
        for part in spec.initial:
            d = part.shape.signed_distance(self.centres)
            if phi is None:
                phi = d
            elif part.subtract:
                phi = np.maximum(phi, -d)
            else:
                phi = np.minimum(phi, d)
        phi = np.ascontiguousarray(phi, dtype=float)
        if any(isinstance(p.shape, Layer) for p in spec.initial) or len(spec.initial) > 1:
            # unions, differences and wavy layers are not exact distances: redistance once
            phi = LS.redistance(phi, self.dx, max(self.nx, self.ny), self.spec.redistancing)
        return phi

    def classify(self) -> None:
        b = self.boundary
        classify_faces(self.phi, b.u_frac, b.v_frac, self.ustate, self.vstate)

    def fluid_cells(self) -> int:
        return int(np.count_nonzero((self.phi < 0) & ~self.boundary.cells))

    def pad(self, u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        K.pad_u(u, self.up, *self.gu)
        K.pad_v(v, self.vp, *self.gv)
        return self.up, self.vp

    def max_speed_faces(self) -> float:
        """Largest face velocity component the next trace will see (fluid and extended faces)."""
        m = max(float(np.max(np.abs(self.u))), float(np.max(np.abs(self.v))))
        for lid in self.spec.lids:
            m = max(m, abs(lid.speed))
        return m

    # -- one step ------------------------------------------------------------------------
    def step(self, dt: float, timers: dict[str, float],
             solid: SolidBoundary | None = None) -> dict[str, Any]:
        """Advance by ``dt`` with the solid boundary ``solid`` (None: the scene's static
        obstacles). A moving solid passes its boundary every step; it is the solid for the whole
        step (path clipping, face states, the projection's Neumann data) and for the
        measurements after it."""
        spec = self.spec
        dx = self.dx
        coupling = self.coupling
        if solid is None and coupling is not None:
            tc = time.perf_counter()
            solid = coupling.begin_step(dt)     # the body moves, its boundary is rebuilt
            # a phase of its own, in coupled runs only (the others' timers are unchanged)
            timers["coupling"] = timers.get("coupling", 0.0) + time.perf_counter() - tc
        elif solid is None:
            solid = self._ramped(self.static_boundary, self.time + dt)
        start_bnd = self.boundary     # the solid of the step's start, which the field obeys
        bnd = self.boundary = solid
        t0 = time.perf_counter()
        # The advection reads the field at the step's start, so it reads it on the solid that
        # field belongs to: a coupled body's pose and velocity at the start of the step, not
        # where begin_step has just moved it. A trace (semi-Lagrangian, MacCormack) clips its
        # paths against that body and reads its velocity inside it (a face the body uncovers
        # then reads the body's velocity, as the fluid there had it); the central scheme's
        # term div(u u) is the start field's on the faces it had then. Measured on the disc
        # driven at Re ~ 260, 12 cells per diameter: `maccormack` C_D 1.741 / 1.702 / 1.687 at
        # the steps 0.02 / 0.01 / 0.005 against 1.825 / 1.737 / 1.703 with the moved pose (the
        # motion's error in the step halved); `central` 1.575 / 1.577 at 0.02 / 0.01 against
        # 1.679 / 1.630 (the motion's error gone; benchmarks/results/sedimentation_motion.md,
        # docs/fluid.md, "The advection on the pose its field belongs to"). Everything after
        # the advection uses the moved pose.
        advect_bnd = start_bnd if coupling is not None else bnd
        if advect_bnd.cut:
            # advection reads the solid's velocity at the samples inside it (the projection
            # moves a cut face whose sample is inside; that value is the open part's mean
            # flux, not a velocity to carry the fluid with: measured on the dam break over a
            # block, it doubled the volume error, 1.5 % against 0.6 %)
            up, vp = self.pad(np.where(advect_bnd.u_dist < 0.0, advect_bnd.u_solid, self.u),
                              np.where(advect_bnd.v_dist < 0.0, advect_bnd.v_solid, self.v))
        else:
            up, vp = self.pad(self.u, self.v)
        dist = advect_bnd.c_dist if advect_bnd.cut else self.no_dist
        args = (up, vp, dt, dx, self.lx, self.ly, advect_bnd.cells, advect_bnd.has_cells, dist,
                advect_bnd.cut)
        mac = self.scheme.advection == "maccormack"
        if self.has_surface:
            # only the band can change sign or be read by the next steps (|u| dt <= cfl_limit dx)
            band = self.band_cells * dx
            act_phi = np.abs(self.phi) < band
            act_u = LS.face_phi(self.phi, 0) < band
            act_v = LS.face_phi(self.phi, 1) < band
        else:
            act_phi = act_u = act_v = self.all_active
        if self.has_surface:
            self.phi = self._advect(self.phi, K.OFF_PHI, (0.5, 0.5), args, mac, None,
                                    act_phi, self.phi)
        if self.prescribed is None and self.scheme.advection == "central":
            un, vn = self._convect(up, vp, dt, advect_bnd)
        elif self.prescribed is None:
            un = self._advect(up, K.OFF_UPAD, (0.0, 0.5), args, mac, "u", act_u, self.zero_u)
            vn = self._advect(vp, K.OFF_VPAD, (0.5, 0.0), args, mac, "v", act_v, self.zero_v)
        else:
            un, vn = self.u, self.v
        if coupling is not None and self.incremental and self.prescribed is None and bnd.cut:
            # a coupled body's slivers (cut faces whose sample is inside it) keep their value:
            # the trace from a sample inside the body reads the body's velocity, which the
            # viscous step, where a sliver is an unknown tied to the wall, would then have to
            # undo (viscosity.diffuse_implicit; traced in the projection's field instead, the
            # driven disc at Re ~ 14 read 0.3 % more drag, the settling one 0.2 % slower)
            keep = (bnd.u_dist < 0.0) & (bnd.u_frac < 1.0)
            un[keep] = self.u[keep]
            keep = (bnd.v_dist < 0.0) & (bnd.v_frac < 1.0)
            vn[keep] = self.v[keep]
        if self.conv_all is not None:
            # the momentum the convection made at the body's wall goes to the body
            coupling.convective_exchange(self.u, self.v, un, vn, *self.conv_all, dt)
            self.conv_all = None
        elif (coupling is not None and self.incremental and self.prescribed is None
              and bnd.cut):
            # the same balance after a trace, whose flux across the band's edge is estimated
            # by the central term of the field it starts from. Not with a free surface in the
            # window (air faces carry extrapolated velocities, not momentum; counted, and
            # reported in the run's metadata), nor in an inviscid fluid, whose slivers the trace
            # resets to the body's velocity every step (above: they are kept with viscosity), a
            # change the balance would charge to the body (the impulsively started disc of
            # test_coupling.py kept 0.4773 of its speed so, 0.4828 without, against about 0.495
            # from the added mass)
            if coupling.window_is_wet(self.ustate, self.vstate):
                na, nb = self._convection_all(up, vp, bnd)
                coupling.convective_exchange(self.u, self.v, un, vn, na, nb, dt)
            else:
                coupling.surface_skips += 1
        if self.particles is not None:
            self.particles.advect(up, vp, dt, dx, self.lx, self.ly, bnd.cells, bnd.has_cells)
        t1 = time.perf_counter()
        timers["advection"] += t1 - t0

        escaped = 0
        if self.has_surface:
            if self.particles is not None:
                escaped = self.particles.correct(self.phi, dx)
                t1b = time.perf_counter()
                timers["particles"] += t1b - t1
                t1 = t1b
            if (self.step_index + 1) % spec.redistance_every == 0:
                if bnd.has_cells:
                    K.fill_solid(self.phi, bnd.cells, self.band_cells)
                self.phi = LS.redistance(self.phi, dx, self.redist_cells, spec.redistancing,
                                         bnd.cells if bnd.has_cells else None)
            t2 = time.perf_counter()
            timers["redistancing"] += t2 - t1
            if self.particles is not None:
                self.particles.correct(self.phi, dx)
                self.particles.adjust_radii(self.phi, dx)
                if (self.step_index + 1) % self.particles.reseed_every == 0:
                    self.particles.seed(self.phi, dx, bnd.cells)
                timers["particles"] += time.perf_counter() - t2
        t2 = time.perf_counter()

        its = 0
        if self.prescribed is None:
            g = self.gravity
            if g[0] != 0.0:
                un += g[0] * dt
            if g[1] != 0.0:
                vn += g[1] * dt
            if coupling is not None:
                coupling.predict(dt)            # gravity on the body: V* on its faces
            self.classify()
            impose(un, vn, self.ustate, self.vstate, bnd)   # before viscosity: its wall velocity
            nu = spec.kinematic_viscosity
            scale = dt / (spec.density * dx)
            if self.incremental and coupling is not None:
                cells = unknown_cells(self.phi, bnd.u_frac, bnd.v_frac)
                if self.pressure_cells is not None:
                    self.p = fill_new_cells(self.p, cells, self.pressure_cells)
                self.pressure_cells = cells
                apply_pressure_coupled(self.p * scale, self.phi, un, vn, self.ustate,
                                       self.vstate, coupling, cells)
                impose(un, vn, self.ustate, self.vstate, bnd)   # the body's velocity after it
            elif self.incremental:
                apply_pressure(self.p * scale, self.phi, un, vn, self.ustate, self.vstate)
            if nu > 0.0:
                k_total = nu * dt / (dx * dx)
                if self.implicit:
                    walls = bnd.cut and spec.no_slip
                    # Crank-Nicolson with the Eulerian convection (second order in time with
                    # Adams-Bashforth 2); backward Euler after a semi-Lagrangian trace, whose
                    # explicit half would belong at the departure points
                    cn = self.scheme.advection == "central"
                    # with a coupled body: momentum weighted by the open fractions, the
                    # slivers as unknowns (viscosity.diffuse_implicit)
                    coupled = coupling is not None and self.incremental
                    # a moving wall sweeps across the samples (viscosity.MOVING_THETA_MIN)
                    theta_min = THETA_MIN if coupling is None else MOVING_THETA_MIN
                    # the slivers, found once for the viscous step and the exchange
                    links = ((sliver_links(self.ustate, bnd.u_dist, bnd.u_frac, 0),
                              sliver_links(self.vstate, bnd.v_dist, bnd.v_frac, 1))
                             if coupled and walls else (None, None))
                    self.last_viscous_iterations = (
                        diffuse_implicit(un, self.ustate, bnd.u_dist if walls else None,
                                         bnd.u_solid, k_total, 0, self.gu,
                                         self.u if cn else None,
                                         bnd.u_frac if coupled else None, theta_min, links[0])
                        + diffuse_implicit(vn, self.vstate, bnd.v_dist if walls else None,
                                           bnd.v_solid, k_total, 1, self.gv,
                                           self.v if cn else None,
                                           bnd.v_frac if coupled else None, theta_min,
                                           links[1]))
                    if coupling is not None and walls:
                        # Crank-Nicolson's wall terms are the mean of the old and the new
                        # field's (both against the body's present velocity; linear in q)
                        coupling.viscous_exchange(0.5 * (un + self.u) if cn else un,
                                                  0.5 * (vn + self.v) if cn else vn,
                                                  links, nu, dt, theta_min, self.phi)
                else:
                    n_sub = max(1, math.ceil(k_total / VISCOUS_SUBSTEP_LIMIT))
                    for _ in range(n_sub):
                        upv, vpv = self.pad(un, vn)
                        K.diffuse_u(upv, un, self.ustate, k_total / n_sub)
                        K.diffuse_v(vpv, vn, self.vstate, k_total / n_sub)
            t3 = time.perf_counter()
            timers["forces"] += t3 - t2

            if coupling is not None:
                # the increment with a viscous fluid (warm-started from the last one), else the
                # pressure itself
                pt = (self.p_increment if self.incremental else self.p) * scale
                its, _, _ = project_coupled(self.phi, bnd, un, vn, self.ustate, self.vstate, pt,
                                            spec.pressure_tolerance, coupling, amg=self.amg,
                                            amg_min=self.amg_min)
                if self.incremental:
                    self.p_increment = pt / scale
                    self.p = self.p + self.p_increment
                else:
                    self.p = pt / scale
                impose(un, vn, self.ustate, self.vstate, bnd)   # the body's new velocity
                coupling.finish(dt)
            elif self.incremental:
                # the increment (it vanishes in a steady state), warm-started from the last one
                pt = self.p_increment * scale
                its, _, _ = project(self.phi, bnd, un, vn, self.ustate, self.vstate, pt,
                                    spec.pressure_tolerance, amg=self.amg,
                                    amg_min=self.amg_min)
                self.p_increment = pt / scale
                self.p = self.p + self.p_increment
            else:
                pt = self.p * scale
                its, _, _ = project(self.phi, bnd, un, vn, self.ustate, self.vstate, pt,
                                    spec.pressure_tolerance, amg=self.amg,
                                    amg_min=self.amg_min)
                self.p = pt / scale
            t4 = time.perf_counter()
            timers["projection"] += t4 - t3

            if self.has_surface:
                band = self.band_cells * dx
                LS.extend_velocity(un, self.ustate, LS.face_phi(self.phi, 0), band)
                LS.extend_velocity(vn, self.vstate, LS.face_phi(self.phi, 1), band)
            timers["extension"] += time.perf_counter() - t4
            self.u, self.v = un, vn
            if self.forces is not None:
                self.forces.advance(un, vn, spec.density, dt)
        self.step_index += 1
        self.time += dt
        self.last_iterations = its
        return {"iterations": its, "escaped": escaped}

    def _convect(self, up: np.ndarray, vp: np.ndarray, dt: float, start: SolidBoundary):
        """``u - dt div(u u)`` by Adams-Bashforth 2 with variable steps (forward Euler on the
        first step): ``(1 + r/2) N^n - (r/2) N^(n-1)``, ``r = dt / dt_prev``. A steady state is
        then exactly the discrete steady equations, whatever the step.

        With a coupled body the term is computed on the faces inside it too (from the body's
        velocity at its samples, as ``up``, ``vp`` have it): that is the flux into the body's
        window whose balance ``Coupling.convective_exchange`` keeps (``self.conv_all``). A
        fluid face's term does not depend on its neighbours' states, so the fluid's term is
        the same array with the other faces zeroed. A face the body uncovers has no previous
        term: forward Euler there."""
        coupled = self.coupling is not None
        if coupled:
            na, nb = self._convection_all(up, vp, start)
        else:
            na = np.empty(self.u.shape)
            nb = np.empty(self.v.shape)
            K.convection(up, vp, self.ustate, self.vstate, self.dx, na, nb)
        r = None if self.conv_prev is None else dt / self.dt_prev
        prev = self.conv_prev or (None, None, None)
        if coupled:
            # the faces the fluid's term is computed on (FLUID in the last classification)
            fluid = (self.ustate == FLUID, self.vstate == FLUID)
            nu_, nv_ = np.where(fluid[0], na, 0.0), np.where(fluid[1], nb, 0.0)
            all_prev = self.conv_all_prev or (None, None)
            self.conv_all = (_ab2(na, all_prev[0], r), _ab2(nb, all_prev[1], r))
            self.conv_all_prev = (na, nb)
        else:
            fluid = None
            nu_, nv_ = na, nb
        cu, cv = _ab2(nu_, prev[0], r), _ab2(nv_, prev[1], r)
        if coupled and r is not None:
            cu = np.where(prev[2][0], cu, nu_)
            cv = np.where(prev[2][1], cv, nv_)
        self.conv_prev = (nu_, nv_, fluid)
        self.dt_prev = dt
        return self.u - dt * cu, self.v - dt * cv

    def _convection_all(self, up: np.ndarray, vp: np.ndarray,
                        bnd: SolidBoundary) -> tuple[np.ndarray, np.ndarray]:
        """The central convective term on the fluid's faces and on those inside the coupled
        body at its pose in ``bnd`` (from the body's velocity at its samples, as ``up``, ``vp``
        have it): summed over any set of faces that all have a term (the band
        ``Coupling.convective_exchange`` balances) it telescopes to the momentum flux across
        the set's edge. The central scheme's own term marks the body at the step's start; the
        estimate after a trace at the moved pose (as measured in docs/fluid.md)."""
        us = np.where(bnd.u_dist < 0.0, FLUID, self.ustate).astype(self.ustate.dtype)
        vs = np.where(bnd.v_dist < 0.0, FLUID, self.vstate).astype(self.vstate.dtype)
        na = np.empty(self.u.shape)
        nb = np.empty(self.v.shape)
        K.convection(up, vp, us, vs, self.dx, na, nb)
        return na, nb

    def _ramped(self, bnd: SolidBoundary, t: float) -> SolidBoundary:
        """The static boundary with the inflow scaled by its ramp at time ``t``."""
        inflow = self.spec.inflow
        if inflow is None or inflow.ramp_time <= 0.0 or t >= inflow.ramp_time:
            return bnd
        u_solid = bnd.u_solid.copy()
        v_solid = bnd.v_solid.copy()
        inflow_velocities(self.spec, u_solid, v_solid, inflow.factor(t))
        return dataclasses.replace(bnd, u_solid=u_solid, v_solid=v_solid)

    def _advect(self, q, qoff, toff, args, mac, comp, active, fallback):
        out = np.empty(self._target_shape(comp))
        lo = np.empty_like(out)
        hi = np.empty_like(out)
        K.advect(q, qoff[0], qoff[1], toff[0], toff[1], out, lo, hi, active, fallback, *args)
        if not mac:
            return out
        # MacCormack: trace the result forward again and correct by half the round-trip error
        up, vp, dt = args[0], args[1], args[2]
        if comp == "u":
            fwdp = np.empty_like(up)
            K.pad_u(out, fwdp, *self.gu)
            q0 = q[:, 1:-1]
        elif comp == "v":
            fwdp = np.empty_like(vp)
            K.pad_v(out, fwdp, *self.gv)
            q0 = q[1:-1, :]
        else:
            fwdp = out
            q0 = q
        back = np.empty_like(out)
        lo2 = np.empty_like(out)
        hi2 = np.empty_like(out)
        K.advect(fwdp, qoff[0], qoff[1], toff[0], toff[1], back, lo2, hi2, active, fallback,
                 up, vp, -dt, *args[3:])
        res = np.empty_like(out)
        K.maccormack_combine(np.ascontiguousarray(q0), out, back, lo, hi, res)
        return res

    def _target_shape(self, comp):
        if comp == "u":
            return (self.nx + 1, self.ny)
        if comp == "v":
            return (self.nx, self.ny + 1)
        return (self.nx, self.ny)

    # -- measurements --------------------------------------------------------------------
    def centre_velocity(self) -> tuple[np.ndarray, np.ndarray]:
        return 0.5 * (self.u[1:] + self.u[:-1]), 0.5 * (self.v[:, 1:] + self.v[:, :-1])

    def viscous_dissipation(self, solid: np.ndarray) -> float:
        """``2 mu integral of D:D dA`` of the current velocity, W/m (viscosity.viscous_dissipation:
        cells weighted by their open liquid fraction, the domain's sides by their ghosts)."""
        spec = self.spec
        frac = (self.boundary.fluid_area if self.boundary.fluid_area is not None
                else (~solid).astype(float))
        weight = frac * ((self.phi < 0) if self.has_surface else 1.0)
        ghosts = {}
        for side in ("left", "right", "bottom", "top"):
            kind = spec.walls.get(side, "solid")
            if spec.wall_speed(side) != 0.0:
                ghosts[side] = (-1.0, 2.0 * spec.wall_speed(side))
            elif kind == "open" or (kind == "solid" and not spec.no_slip):
                ghosts[side] = (1.0, 0.0)
            else:  # a no-slip wall at rest; an inflow side has no tangential velocity
                ghosts[side] = (-1.0, 0.0)
        return viscous_dissipation(self.u, self.v, np.asarray(weight, float), self.dx,
                                   spec.dynamic_viscosity, ghosts)

    def measure(self) -> dict[str, float]:
        dx = self.dx
        solid = self.boundary.cells
        fluid = (self.phi < 0) & ~solid
        uc, vc = self.centre_velocity()
        speed2 = uc * uc + vc * vc
        out = {
            "kinetic_energy": float(0.5 * self.spec.density * np.sum(speed2[fluid]) * dx * dx),
            "max_speed": float(np.sqrt(np.max(speed2[fluid]))) if fluid.any() else 0.0,
            "fluid_cells": float(np.count_nonzero(fluid)),
        }
        if self.has_surface:
            out["volume"] = LS.fluid_area(self.phi, solid, dx, self.boundary.fluid_area)
            out["front"] = float(LS.front_position(self.phi, 0, dx))
            px = self.spec.output.probe_x
            gx = 0.0 if px is None else min(max(px / dx - 0.5, 0.0), self.nx - 1.0)
            i0 = min(int(gx), self.nx - 2)
            out["surface_height"] = float(LS.surface_height(self.phi, i0, gx - i0, dx))
        elif self.boundary.cut:
            out["volume"] = float(np.sum(self.boundary.fluid_area)) * dx * dx
        else:
            out["volume"] = float(np.count_nonzero(~solid)) * dx * dx
        if self.particles is not None:
            out["particles"] = float(self.particles.count)
        if self.coupling is not None:
            out.update(self.coupling.measure())
            # the audit of fluid plus body: the fluid's potential energy, -rho g . integral of x
            area, mx, my = K.fluid_moments(self.phi, self.boundary.fluid_area, dx, 4)
            g = self.gravity
            out["potential_energy"] = float(-self.spec.density * (g[0] * mx + g[1] * my))
            out["total_energy"] = (out["kinetic_energy"] + out["potential_energy"]
                                   + out["body_energy"])
        if self.spec.kinematic_viscosity > 0.0:
            out["viscous_dissipation"] = self.viscous_dissipation(solid)
        if self.forces is not None:
            spec = self.spec
            for name, (fx, fy) in self.forces.forces(self.u, self.v, self.p, spec.density,
                                                     spec.dynamic_viscosity,
                                                     self.gravity).items():
                out[f"force_x.{name}"] = fx
                out[f"force_y.{name}"] = fy
        return out

    def snapshot(self, names: tuple[str, ...]) -> dict[str, np.ndarray]:
        table = {"u": self.u, "v": self.v, "phi": self.phi, "p": self.p}
        return {k: table[k].astype(np.float32) for k in names}


def _scene_gravity(scene: Any, dim: int) -> np.ndarray:
    effects = getattr(scene, "effects", None)
    g = getattr(effects, "gravity", None) if effects is not None else None
    if g is None and isinstance(effects, dict):
        g = effects.get("gravity")
    return np.zeros(dim) if g is None else np.asarray(g, float)


def fluid_threads() -> int:
    """Threads of the parallel kernels: ``CROSSCHECK_FLUID_THREADS`` (default 1).

    One by default: on the project's 2-core machine other runs (pytest-xdist workers, other
    engines) share the cores, and numba's parallel loops then wait on each other at every
    barrier; measured on the cavity, a contended 2-thread run was 6x slower than a serial one.
    The benchmark reports both.
    """
    try:
        n = int(os.environ.get("CROSSCHECK_FLUID_THREADS", "1"))
    except ValueError:
        n = 1
    return max(1, min(n, numba.config.NUMBA_NUM_THREADS))


def _ab2(n: np.ndarray, prev: np.ndarray | None, r: float | None) -> np.ndarray:
    """Adams-Bashforth 2 with the step ratio ``r = dt / dt_prev``: ``(1 + r/2) n - (r/2)
    prev``; forward Euler (``n``) with no previous term."""
    if prev is None or r is None:
        return n
    return (1.0 + 0.5 * r) * n - 0.5 * r * prev
