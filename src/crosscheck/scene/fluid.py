"""The ``[fluid]`` section of a case file: a free-surface (or enclosed) incompressible fluid domain.

Every key is read through a :class:`~crosscheck.scene.fields.Fields` cursor so that bad input names
the file, the field path (``fluid.obstacles[1].box.size``) and what was expected. The keys, units
and defaults are documented in ``docs/fluid.md``; keep the two in step.

The result is a frozen :class:`FluidSpec`. It is engine-neutral: the in-house MAC-grid solver
(:mod:`crosscheck.sim.fluid`) reads it, the metrics and plots read it, nothing here depends on the
solver.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from crosscheck.errors import CaseError
from crosscheck.scene.fields import Fields
from crosscheck.scene.shapes import Box, Circle, Placed

SIDES_2D = ("left", "right", "bottom", "top")
WALL_KINDS = ("solid", "open", "inflow")
OUTPUT_FIELDS = ("u", "v", "phi", "p")
INFLOW_PROFILES = ("parabolic", "uniform")
VISCOSITY_SOLVERS = ("explicit", "implicit")


# -- shapes ------------------------------------------------------------------------------------
# Obstacles and region parts are shapes of crosscheck.scene.shapes placed at their ``center``
# (an obstacle box may be turned by ``angle``; a polygon's vertices are world points), so the
# solver reads them through the shapes' own signed distances; only the layer, unbounded, is the
# fluid's own.
@dataclass(frozen=True)
class Layer:
    """Fluid below the surface ``y = depth + amplitude * cos(2 pi x / wavelength + phase)``.

    The tank at rest (amplitude 0) and the sloshing tank (cosine perturbation) are layers. The
    function returned is only approximately a distance; the solver redistances it at start.
    """

    depth: float
    amplitude: float = 0.0
    wavelength: float = math.inf
    phase: float = 0.0

    def surface(self, x: np.ndarray) -> np.ndarray:
        if not math.isfinite(self.wavelength):
            return self.depth + self.amplitude * math.cos(self.phase) + 0.0 * x
        return self.depth + self.amplitude * np.cos(2 * math.pi * x / self.wavelength + self.phase)

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """``y - surface(x)`` at points ``(..., 2)``: negative in the fluid, like a shape's."""
        return points[..., 1] - self.surface(points[..., 0])


Shape = Placed | Layer  # a placed Box or Circle, or a layer


@dataclass(frozen=True)
class RegionPart:
    """One entry of the initial fluid region: a shape added to (or subtracted from) the union."""

    shape: Shape
    subtract: bool = False


@dataclass(frozen=True)
class Rotation:
    """Prescribed rigid rotation velocity field ``u = omega x (x - center)`` (rad/s, m)."""

    center: tuple[float, ...]
    angular_velocity: float

    def velocity(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        w = self.angular_velocity
        return -w * (y - self.center[1]), w * (x - self.center[0])


@dataclass(frozen=True)
class Lid:
    """A solid side moving tangentially (lid-driven cavity). ``speed`` in m/s, positive along +x
    for the bottom/top sides and +y for the left/right sides."""

    side: str
    speed: float


@dataclass(frozen=True)
class Inflow:
    """Velocity imposed on an ``"inflow"`` side, normal to it and into the domain (m/s).

    ``parabolic``: ``U(s) = 4 speed s (W - s) / W^2`` across the side of width W (``speed`` is the
    centre-line maximum, the mean is 2/3 of it), the Poiseuille profile of a channel;
    ``uniform``: ``speed`` everywhere. ``ramp_time`` > 0 scales it by ``sin(pi t / (2 ramp))``
    until ``t = ramp_time``. The tangential velocity on the side is zero."""

    side: str
    profile: str
    speed: float
    ramp_time: float = 0.0

    def mean_speed(self) -> float:
        return self.speed * (2.0 / 3.0 if self.profile == "parabolic" else 1.0)

    def factor(self, t: float) -> float:
        if self.ramp_time <= 0.0 or t >= self.ramp_time:
            return 1.0
        return math.sin(0.5 * math.pi * t / self.ramp_time)

    def face_average(self, s0: np.ndarray, s1: np.ndarray, width: float) -> np.ndarray:
        """Mean of the profile over each face ``[s0, s1]`` along the side: the face's flux is
        exact, so the channel carries exactly ``width * mean_speed()``."""
        if self.profile == "uniform":
            return np.full(np.shape(s0), self.speed)

        def primitive(s):  # integral of 4 U s (W - s) / W^2
            return 4.0 * self.speed * (0.5 * width * s * s - s ** 3 / 3.0) / width ** 2

        return (primitive(s1) - primitive(s0)) / (s1 - s0)


@dataclass(frozen=True)
class ForceOutput:
    """Force measurement on the obstacles (docs/fluid.md, "Forces on a body"). ``window``:
    ``(d0, d1)`` in m, the distances from each obstacle's surface where the smooth weight of the
    momentum balance starts to fall from 1 and where it reaches 0; ``None``: chosen from the
    obstacle's size and clearance."""

    enabled: bool = False
    window: tuple[float, float] | None = None


@dataclass(frozen=True)
class ParticleSpec:
    """Particle level set (Enright et al. 2002) parameters."""

    enabled: bool = False
    per_cell: int = 16
    band: float = 3.0           # seeding band half-width, cells
    reseed_every: int = 20      # steps between reseeding
    seed: int = 12345           # random seed of particle placement (runs are reproducible)


@dataclass(frozen=True)
class OutputSpec:
    fields: tuple[str, ...] = ("u", "v", "phi")
    field_every: float | None = None   # s; None: the run decides (about 40 frames)
    probe_x: float | None = None       # m; x of the surface-height probe; None: first column
    forces: ForceOutput = ForceOutput()


@dataclass(frozen=True)
class FluidSpec:
    """A 2D incompressible fluid domain with optional free surface. SI units throughout."""

    domain: tuple[float, ...]
    resolution: tuple[int, ...]
    walls: dict[str, str] = field(default_factory=dict)
    no_slip: bool = False
    lids: tuple[Lid, ...] = ()  # solid sides moving tangentially, each side at most once
    inflow: Inflow | None = None
    obstacles: tuple[Placed, ...] = ()  # a placed Box, Circle or Polygon each
    obstacle_names: tuple[str, ...] = ()  # one per obstacle: its name, or "obstacle<k>"
    viscosity_solver: str = "explicit"
    initial: tuple[RegionPart, ...] = ()   # empty: the domain is full of fluid (no free surface)
    density: float = 1000.0
    kinematic_viscosity: float = 0.0
    cfl: float = 1.0
    cfl_limit: float = 2.0
    time_step: str = "cfl"               # "cfl": adaptive, capped by the given dt; "fixed"
    redistance_every: int = 1
    redistancing: str = "fast_sweeping"
    pressure_tolerance: float = 1e-6
    #: "auto": multigrid-preconditioned CG for a large matrix that does not change (no free
    #: surface, no moving body), MIC(0)-PCG otherwise; "mic0" or "amg" to choose (sim/fluid/amg.py)
    pressure_solver: str = "auto"
    min_volume_fraction: float = 0.5
    prescribed_velocity: Rotation | None = None
    particles: ParticleSpec = ParticleSpec()
    output: OutputSpec = OutputSpec()
    #: dynamic bodies coupled with the fluid: the case's ``[[bodies]]`` (``scene.model.Body``,
    #: per unit depth); empty: no coupling (docs/fluid.md, "Rigid bodies in the fluid")
    bodies: tuple = ()

    @property
    def lid(self) -> Lid | None:
        """The one moving side of a lid-driven cavity; None with no moving side or several."""
        return self.lids[0] if len(self.lids) == 1 else None

    def wall_speed(self, side: str) -> float:
        """Tangential speed of a solid side (m/s; 0 unless it moves)."""
        return next((lid.speed for lid in self.lids if lid.side == side), 0.0)

    @property
    def dimension(self) -> int:
        return len(self.domain)

    @property
    def dx(self) -> float:
        return self.domain[0] / self.resolution[0]

    @property
    def has_surface(self) -> bool:
        return len(self.initial) > 0

    @property
    def dynamic_viscosity(self) -> float:
        return self.kinematic_viscosity * self.density


# -- parsing ----------------------------------------------------------------------------------
def _point(f: Fields, key: str, dim: int, default: Any = None) -> tuple[float, ...]:
    if default is None:
        return tuple(float(v) for v in f.vector(key, dim, unit="m"))
    v = f.vector(key, dim, default=None, unit="m")
    return tuple(default) if v is None else tuple(float(x) for x in v)


def _shape(f: Fields, dim: int, *, allow_layer: bool, obstacle: bool = False) -> Shape:
    kinds = ["box", "circle"] + (["polygon"] if obstacle else []) + (["layer"] if allow_layer
                                                                     else [])
    present = [k for k in kinds if f.has(k)]
    if len(present) != 1:
        raise CaseError(f.file, f.path, f"exactly one shape key of {kinds}",
                        sorted(k for k in f.table if k != "name"))
    kind = present[0]
    s = f.sub(kind)
    if kind == "box":
        center = _point(s, "center", dim)
        size = tuple(float(v) for v in s.vector("size", dim, positive=True, unit="m"))
        angle = s.number("angle", 0.0, unit="rad") if obstacle else 0.0
        # no angle: the pure translation the fluid always had (bit for bit the same distances)
        shape: Shape = Placed(Box(size=size), center, None if angle == 0.0 else angle)
    elif kind == "circle":
        if dim != 2:
            raise s.error("", "a circle only in 2D cases")
        center = _point(s, "center", dim)
        shape = Placed(Circle(radius=s.number("radius", positive=True, unit="m")), center)
    elif kind == "polygon":
        # the body parser's checks (at least 3 points, non-zero area, convex; stored CCW), with
        # the vertices in world coordinates
        from crosscheck.scene.loader import _polygon

        shape = Placed(_polygon(s), (0.0, 0.0))
    else:
        amplitude = s.number("amplitude", 0.0, unit="m")
        wavelength = s.number("wavelength", None, positive=True, unit="m")
        wavelength = math.inf if wavelength is None else wavelength
        shape = Layer(s.number("depth", positive=True, unit="m"), amplitude, wavelength,
                      s.number("phase", 0.0, unit="rad"))
    s.done()
    return shape


def _lids(f: Fields, walls: dict[str, str]) -> tuple[Lid, ...]:
    """``lid``: one table (the cavity's lid) or an array of them (several sides moving, e.g. both
    side walls of a channel at the speed of the flow far upstream: a settling body's frame).
    Each side at most once, each a solid side."""
    raw = f.raw("lid", None)
    if raw is None:
        return ()
    if isinstance(raw, dict):
        entries = [f.sub("lid")]
    elif isinstance(raw, list) and raw and all(isinstance(v, dict) for v in raw):
        entries = f.table_list("lid")
    else:
        raise f.error("lid", "a table { side, speed } or an array of such tables", raw)
    lids: list[Lid] = []
    for lf in entries:
        side = lf.string("side", "top", choices=SIDES_2D)
        if walls[side] != "solid":
            raise lf.error("side", f"a solid side (fluid.walls.{side} is {walls[side]!r})", side)
        if any(lid.side == side for lid in lids):
            raise lf.error("side", "each side at most once", side)
        lids.append(Lid(side, lf.number("speed", unit="m/s")))
        lf.done()
    return tuple(lids)


def _obstacles(f: Fields, dim: int) -> tuple[tuple[Placed, ...], tuple[str, ...]]:
    shapes, names = [], []
    for k, o in enumerate(f.table_list("obstacles", [])):
        name = o.string("name", f"obstacle{k}")
        if not name.strip() or name in names:
            raise o.error("name", "a non-empty name no other obstacle has", name)
        shapes.append(_shape(o, dim, allow_layer=False, obstacle=True))
        names.append(name)
        o.done()
    return tuple(shapes), tuple(names)


def parse_fluid(fields: Fields, dimension: int, statics: tuple = (),
                bodies: tuple = ()) -> FluidSpec:
    """Read the ``[fluid]`` table of a case (see docs/fluid.md for every key). ``statics``: the
    case's ``[[statics]]`` (``scene.model.Static``), which are obstacles in the fluid after the
    section's own, under their names. ``bodies``: the case's ``[[bodies]]``
    (``scene.model.Body``), dynamic bodies coupled with the fluid (checked here: one, inside the
    domain, clear of its sides and the obstacles)."""
    f = fields
    if dimension != 2:
        raise CaseError(f.file, "case.dimension",
                        "2 for a case with a [fluid] section (the fluid solver is 2D for now)",
                        dimension)
    domain = tuple(float(v) for v in f.vector("domain", dimension, positive=True, unit="m"))
    res_raw = f.raw("resolution")
    if (not isinstance(res_raw, list) or len(res_raw) != dimension
            or not all(isinstance(r, int) and not isinstance(r, bool) and r >= 4
                       for r in res_raw)):
        raise f.error("resolution", f"an array of {dimension} integers >= 4 (cells per axis)",
                      res_raw)
    resolution = tuple(int(r) for r in res_raw)
    dxs = [d / n for d, n in zip(domain, resolution, strict=True)]
    if max(dxs) - min(dxs) > 1e-9 * max(dxs):
        raise f.error("resolution", "square cells: domain[i] / resolution[i] equal on every axis "
                      f"(cell sizes here {dxs})", res_raw)

    walls = {s: "solid" for s in SIDES_2D}
    wf = f.sub("walls", None)
    if wf is not None:
        for side in SIDES_2D:
            walls[side] = wf.string(side, "solid", choices=WALL_KINDS)
        wf.done()
    inflow_sides = [s for s in SIDES_2D if walls[s] == "inflow"]
    if len(inflow_sides) > 1:
        raise wf.error(inflow_sides[1], "at most one \"inflow\" side",
                       walls[inflow_sides[1]])
    inflow = None
    inf = f.sub("inflow", None)
    if inf is not None and not inflow_sides:
        raise f.error("inflow", "a side with fluid.walls.<side> = \"inflow\" for this table",
                      dict(inf.table))
    if inflow_sides:
        if inf is None:
            raise CaseError(f.file, f.field("inflow"), "this table (profile, speed), required "
                            f"when fluid.walls.{inflow_sides[0]} = \"inflow\"")
        inflow = Inflow(side=inflow_sides[0],
                        profile=inf.string("profile", "parabolic", choices=INFLOW_PROFILES),
                        speed=inf.number("speed", positive=True, unit="m/s"),
                        ramp_time=inf.number("ramp_time", 0.0, nonnegative=True, unit="s"))
        inf.done()

    lids = _lids(f, walls)

    density = f.number("density", 1000.0, positive=True, unit="kg/m^3")
    if f.has("kinematic_viscosity") and f.has("dynamic_viscosity"):
        raise f.error("dynamic_viscosity", "only one of kinematic_viscosity and dynamic_viscosity",
                      f.table["dynamic_viscosity"])
    nu = f.number("kinematic_viscosity", 0.0, nonnegative=True, unit="m^2/s")
    if f.has("dynamic_viscosity"):
        nu = f.number("dynamic_viscosity", nonnegative=True, unit="Pa s") / density
    no_slip = f.boolean("no_slip", nu > 0)

    obstacles, obstacle_names = _obstacles(f, dimension)
    for st in statics:
        if st.name in obstacle_names:
            raise f.error("obstacles", f"obstacle names other than the static {st.name!r}",
                          list(obstacle_names))
    obstacles += tuple(st.placed() for st in statics)
    obstacle_names += tuple(st.name for st in statics)

    parts = []
    for entry in f.table_list("initial", []):
        subtract = entry.boolean("subtract", False)
        parts.append(RegionPart(_shape(entry, dimension, allow_layer=True), subtract))
        entry.done()
    if parts and parts[0].subtract:
        raise f.error("initial[0].subtract", "false for the first region part (nothing to "
                      "subtract from)", True)

    cfl = f.number("cfl", 1.0, positive=True)
    cfl_limit = f.number("cfl_limit", max(2.0 * cfl, cfl + 1.0), positive=True)
    if cfl_limit < cfl:
        raise f.error("cfl_limit", f"a number >= fluid.cfl ({cfl})", cfl_limit)
    time_step = f.string("time_step", "cfl", choices=("cfl", "fixed"))
    redistance_every = f.integer("redistance_every", 1, minimum=1)
    redistancing = f.string("redistancing", "fast_sweeping",
                            choices=("fast_sweeping", "fast_marching"))
    ptol = f.number("pressure_tolerance", 1e-6, positive=True)
    psolver = f.string("pressure_solver", "auto", choices=("auto", "mic0", "amg"))
    if psolver == "amg" and bodies and parts:
        raise f.error("pressure_solver", '"auto" or "mic0" (the coupled solve with a body and a '
                      "free surface has no multigrid)", psolver)
    min_vol = f.number("min_volume_fraction", 0.5, nonnegative=True)

    prescribed = None
    pf = f.sub("prescribed_velocity", None)
    if pf is not None:
        rf = pf.sub("rotation")
        prescribed = Rotation(_point(rf, "center", dimension),
                              rf.number("angular_velocity", unit="rad/s"))
        rf.done()
        pf.done()

    particles = ParticleSpec()
    pls = f.sub("particles", None)
    if pls is not None:
        particles = ParticleSpec(
            enabled=pls.boolean("enabled", True),
            per_cell=pls.integer("per_cell", 16, minimum=1),
            band=pls.number("band", 3.0, positive=True, unit="cells"),
            reseed_every=pls.integer("reseed_every", 20, minimum=1),
            seed=pls.integer("seed", 12345, minimum=0),
        )
        pls.done()

    output = OutputSpec()
    of = f.sub("output", None)
    if of is not None:
        names = of.string_list("fields", ["u", "v", "phi"])
        for i, name in enumerate(names):
            if name not in OUTPUT_FIELDS:
                raise CaseError(of.file, f"{of.field('fields')}[{i}]",
                                f"one of {list(OUTPUT_FIELDS)}", name)
        forces = ForceOutput(of.boolean("forces", False))
        if of.has("force_window"):
            win = of.vector("force_window", 2, unit="m")
            if not 0.0 <= win[0] < win[1]:
                raise of.error("force_window", "[d0, d1] with 0 <= d0 < d1 (m from the surface)",
                               list(win))
            forces = ForceOutput(forces.enabled, (float(win[0]), float(win[1])))
        output = OutputSpec(tuple(names), of.number("field_every", None, positive=True, unit="s"),
                            of.number("probe_x", None, nonnegative=True, unit="m"), forces)
        of.done()
    if output.forces.enabled and not obstacles:
        raise of.error("forces", "obstacles to measure forces on (fluid.obstacles or "
                       "[[statics]])", True)
    # Cut-cell walls and an inflow need the implicit viscous step: the ghost-fluid Dirichlet
    # condition of a wall a small fraction theta of a cell away has a 1/theta coefficient, which
    # an explicit step would pay for with steps theta times shorter.
    default_visc = "implicit" if (obstacles or bodies or inflow is not None) else "explicit"
    viscosity_solver = f.string("viscosity_solver", default_visc, choices=VISCOSITY_SOLVERS)
    if viscosity_solver == "explicit" and (obstacles or bodies) and nu > 0 and no_slip:
        raise f.error("viscosity_solver", "\"implicit\" for a viscous no-slip fluid with "
                      "obstacles or bodies (their cut-cell walls need the implicit ghost-fluid "
                      "stencil)", viscosity_solver)
    if bodies:
        _check_bodies(f, bodies, domain, resolution, walls, obstacles, nu, no_slip, prescribed)
    f.done()
    return FluidSpec(domain=domain, resolution=resolution, walls=walls, no_slip=no_slip, lids=lids,
                     inflow=inflow, obstacles=obstacles, obstacle_names=obstacle_names,
                     viscosity_solver=viscosity_solver, initial=tuple(parts), density=density,
                     kinematic_viscosity=nu, cfl=cfl, cfl_limit=cfl_limit, time_step=time_step,
                     redistance_every=redistance_every, redistancing=redistancing,
                     pressure_tolerance=ptol, pressure_solver=psolver,
                     min_volume_fraction=min_vol, prescribed_velocity=prescribed,
                     particles=particles, output=output, bodies=tuple(bodies))


#: closest a body may start to a closed side or an obstacle, in cells (the coupled step stops a
#: run whose body comes within 1.5 cells: there is no contact in the fluid)
BODY_CLEARANCE_CELLS = 2.0


def _check_bodies(f: Fields, bodies: tuple, domain: tuple, resolution: tuple, walls: dict,
                  obstacles: tuple, nu: float, no_slip: bool, prescribed: Any) -> None:
    """A fluid case's ``[[bodies]]`` are coupled with the fluid: refuse what the coupled step
    does not do, naming the body's field."""
    if len(bodies) > 1:
        raise CaseError(f.file, "bodies[1]", "at most one [[bodies]] entry in a fluid case (the "
                        "coupled pressure solve has one body's unknowns for now)",
                        bodies[1].name)
    if prescribed is not None:
        raise f.error("prescribed_velocity", "no prescribed velocity in a case with [[bodies]] "
                      "(the body needs the fluid's forces)", "a rotation")
    if nu > 0 and not no_slip:
        raise f.error("no_slip", "true for a viscous fluid with [[bodies]] (the viscous momentum "
                      "is exchanged with the body through its no-slip wall)", no_slip)
    dx = domain[0] / resolution[0]
    gap = BODY_CLEARANCE_CELLS * dx
    for k, body in enumerate(bodies):
        placed = Placed(body.shape, body.position, body.orientation)
        lo, hi = placed.bounding_box()
        margins = {"left": lo[0], "right": domain[0] - hi[0], "bottom": lo[1],
                   "top": domain[1] - hi[1]}
        for side, m in margins.items():
            need = gap if walls[side] != "open" else 0.0
            if m < need:
                rule = (f"at least {BODY_CLEARANCE_CELLS:g} cells ({need:.4g} m) from its {side} "
                        f"side (there is no contact between a body and solids in the fluid)"
                        if need > 0 else f"within its open {side} side")
                raise CaseError(f.file, f"bodies[{k}].position",
                                f"a pose that keeps the body inside fluid.domain, {rule}; its "
                                f"{side} edge is {abs(m):.4g} m {'away' if m >= 0 else 'outside'}",
                                [float(v) for v in body.position])
        for name_k, obstacle in enumerate(obstacles):
            olo, ohi = obstacle.bounding_box()
            sep = float(np.max(np.maximum(olo - hi, lo - ohi)))
            if sep < gap:
                raise CaseError(f.file, f"bodies[{k}].position",
                                f"a pose at least {BODY_CLEARANCE_CELLS:g} cells ({gap:.4g} m) "
                                f"from every obstacle (bounding boxes; there is no contact in "
                                f"the fluid); obstacle {name_k} is {sep:.4g} m away",
                                [float(v) for v in body.position])
