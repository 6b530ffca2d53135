"""Case file (TOML) -> immutable Scene, refusing bad input with one precise message.

Every refusal is a :class:`crosscheck.errors.CaseError` naming the file, the field path and what
was expected; nothing else escapes :func:`load_case` (a property the tests check with Hypothesis).
The format is documented key by key in docs/cases.md.
"""

from __future__ import annotations

import difflib
import hashlib
import tomllib
from collections.abc import Collection
from pathlib import Path
from typing import Any

import numpy as np

from crosscheck.errors import CaseError
from crosscheck.names import FINE_STEP_ONLY, INTEGRATOR_NAMES, all_integrator_names
from crosscheck.rotations import axis_angle_to_quat
from crosscheck.scene import massprops
from crosscheck.scene.contact_fields import (
    check_contact_sections,
    check_reserved_names,
    material_ref,
    parse_materials,
    parse_pair_overrides,
)
from crosscheck.scene.fields import Fields, check_number, check_vector, one_of
from crosscheck.scene.model import (
    ENGINE_NAMES,
    Body,
    Drag,
    Effects,
    Ground,
    Load,
    Material,
    Medium,
    Reference,
    RunSettings,
    Scene,
    Spring,
    Static,
    Tolerance,
    dividing_step,
    whole_steps,
)
from crosscheck.scene.shapes import (
    Box,
    Capsule,
    Circle,
    Cylinder,
    Mesh,
    Polygon,
    Sphere,
    polygon_area2,
)

REFERENCE_KINDS = ("analytic", "table", "fine-step", "engine", "none")
QUATERNION_UNIT_TOLERANCE = 1e-6  # |q| may differ from 1 by this much (then it is normalised)


def load_case(path: str | Path, *, unchecked_engines: Collection[str] = ()) -> Scene:
    """Read and validate one case file.

    Integrator names are checked against :data:`crosscheck.names.INTEGRATOR_NAMES`,
    except those of ``unchecked_engines``: engines an adapter under development stands in for
    (``--engine-ref``), which brings integrator names of its own; a name it does not know is then
    "not applicable" when the case runs.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise CaseError(path, "", "a readable case file", exc.strerror or str(exc)) from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise CaseError(path, "", "a UTF-8 text file") from None
    return _load(text, path, path.parent, hashlib.sha256(data).hexdigest(),
                 frozenset(unchecked_engines))


def load_case_text(text: str, name: str = "<text>", base_dir: str | Path = ".", *,
                   unchecked_engines: Collection[str] = ()) -> Scene:
    """Load a case from a TOML string (tests, generated cases); mesh paths resolve in base_dir.
    ``unchecked_engines`` as in :func:`load_case`."""
    digest = hashlib.sha256(text.encode("utf-8")).hexdigest()
    return _load(text, Path(name), Path(base_dir), digest, frozenset(unchecked_engines))


def is_case_file(path: str | Path) -> bool:
    """A TOML file with a top-level [case] table (so pyproject.toml is never taken for a case)."""
    path = Path(path)
    if path.suffix != ".toml":
        return False
    try:
        return "case" in tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return True  # let load_case report what is wrong with it


def find_cases(paths: list[str | Path]) -> list[Path]:
    """Case files under the given files and folders, sorted, folders searched recursively."""
    found: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found.extend(f for f in sorted(p.rglob("*.toml")) if is_case_file(f))
        else:
            found.append(p)
    return found


# -- the whole file -------------------------------------------------------------------------------
def _load(text: str, file: Path, base_dir: Path, digest: str,
          unchecked: frozenset[str] = frozenset()) -> Scene:
    try:
        raw = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(file, "", f"valid TOML ({exc})") from None
    top = Fields(raw, "", file)

    case = top.sub("case")
    name = case.string("name")
    if not name.strip():
        raise case.error("name", "a non-empty name")
    description = case.string("description", "")
    tags = case.string_list("tags", [])
    dimension = case.integer("dimension")
    if dimension not in (2, 3):
        raise case.error("dimension", "2 or 3", dimension)
    case.done()

    run = _run(top.sub("run"), unchecked, fluid=top.has("fluid"))
    materials = parse_materials(top.sub("materials", {}), dimension)
    has_fluid = top.has("fluid")

    body_tables = top.table_list("bodies", [])
    if not body_tables and not has_fluid:
        raise CaseError(file, "bodies", "at least one [[bodies]] entry")
    bodies = tuple(_body(b, dimension, materials, base_dir) for b in body_tables)
    names = [b.name for b in bodies]
    for i, n in enumerate(names):
        if names.index(n) != i:
            raise CaseError(file, f"bodies[{i}].name", "a name no other body has", n)

    effects = _effects(top.sub("effects", {}), dimension, names, has_fluid)
    ground = _ground(top.sub("ground"), dimension, materials) if top.has("ground") else None
    check_contact_sections(top, effects.contact, has_fluid)
    check_reserved_names(names, file, effects.contact)
    statics = tuple(_static(s, dimension, materials, base_dir)
                    for s in top.table_list("statics", []))
    static_names = [s.name for s in statics]
    for i, n in enumerate(static_names):
        if n == "ground":
            raise CaseError(file, f"statics[{i}].name",
                            "a name other than 'ground' (it names the [ground] plane)", n)
        if n in names or static_names.index(n) != i:
            raise CaseError(file, f"statics[{i}].name", "a name no body or other static has", n)
    fluid = None
    if has_fluid:
        # after the statics: in a fluid case they are obstacles in the fluid
        fluid = _fluid(top.sub("fluid"), dimension, statics, bodies)
        if bodies:
            _check_fluid_effects(file, effects)
    pair_overrides = parse_pair_overrides(top.table_list("contact_pairs", []), names,
                                          static_names, ground is not None, dimension)
    reference = _reference(top.sub("reference", {}), unchecked, base_dir, dimension=dimension,
                           run=run, names=tuple(names), fluid=fluid, gravity=effects.gravity)
    tolerances = _tolerances(top.sub("tolerances", {}), unchecked)
    engine_options = _engine_options(top.sub("engine_options", {}))
    top.done()

    scene = Scene(
        name=name, description=description, tags=tags, dimension=dimension, run=run,
        effects=effects, bodies=bodies, ground=ground, materials=materials, reference=reference,
        tolerances=tolerances, engine_options=engine_options, fluid=fluid, statics=statics,
        pair_overrides=pair_overrides, source=file, source_sha256=digest,
    )
    _check_medium_runs(scene, unchecked)
    return scene


def _check_medium_runs(scene: Scene, unchecked: frozenset[str]) -> None:
    """A fluid case that names medium-model runs for an engine ("rk4+ellipsoid": MuJoCo runs
    the disc as a long cylinder in its stateless medium, scene/medium_map.py) must be one the
    mapping applies to: what cannot be mapped is refused at its own field. (Whether a known name
    applies to a scene otherwise stays a run-time verdict, as for every integrator name: a
    medium run on a rigid case, or a bare MuJoCo integrator on a fluid case, is "not
    applicable" with the reason.)"""
    from crosscheck.names import MEDIUM_MODELS, split_run
    from crosscheck.scene.medium_map import unmappable

    if scene.fluid is None:
        return
    for engine, models in MEDIUM_MODELS.items():
        runs = scene.run.integrators.get(engine, ())
        if engine in unchecked or not any(split_run(n)[1] in models for n in runs):
            continue
        why = unmappable(scene)
        if why is not None:
            raise CaseError(scene.source, why[0],
                            f"{why[1]} (run.integrators.{engine} asks {engine} to run this "
                            "fluid case as a body in its stateless medium)", why[2])


def _fluid(fields: Fields, dimension: int, statics: tuple = (), bodies: tuple = ()) -> Any:
    # The fluid section has its own parser beside the solver that understands it.
    from crosscheck.scene.fluid import parse_fluid

    return parse_fluid(fields, dimension, statics, bodies)


def _check_fluid_effects(file: Path, effects: Effects) -> None:
    """A body in a fluid moves under gravity and the fluid's forces only: the coupled fluid step
    applies no springs, drag or loads (and has no contact), so a case must not declare them."""
    for key, present in (("springs", effects.springs), ("drag", effects.drag),
                         ("loads", effects.loads), ("contact", effects.contact)):
        if present:
            raise CaseError(file, f"effects.{key}", "none in a fluid case with [[bodies]] (the "
                            "body moves under gravity and the fluid's forces only)", key)
    g = effects.gravity
    if g is not None and g[0] != 0.0:
        # the hydrostatic part of the body's force is taken at the water level beside the body,
        # measured up the grid's columns (sim/fluid/coupling.py)
        raise CaseError(file, "effects.gravity", "gravity along -y (or none) in a fluid case "
                        "with [[bodies]]", g.tolist())


# -- sections -------------------------------------------------------------------------------------
def _run(f: Fields, unchecked: frozenset[str], fluid: bool = False) -> RunSettings:
    duration = f.number("duration", positive=True, unit="s")
    dt = f.number("dt", positive=True, unit="s")
    if dt > duration:
        raise f.error("dt", f"a step no longer than run.duration ({duration} s)", dt)
    # A rigid run takes exactly duration / dt steps (a fluid's adaptive steps land on the
    # duration by themselves): a step that does not divide it would end the run early.
    if not fluid:
        if whole_steps(duration, dt) is None:
            raise f.error("dt", f"a step that divides run.duration ({duration} s) into a whole "
                                f"number of steps (here {duration / dt:.6g}; e.g. "
                                f"{dividing_step(duration, dt):.6g})", dt)
    sample_every = f.number("sample_every", dt, positive=True, unit="s")
    if sample_every > duration:
        raise f.error("sample_every", f"an interval no longer than run.duration ({duration} s)",
                      sample_every)
    engines = f.string_list("engines", list(ENGINE_NAMES))
    for i, e in enumerate(engines):
        if e not in ENGINE_NAMES:
            raise CaseError(f.file, f"{f.field('engines')}[{i}]", f"one of {list(ENGINE_NAMES)}", e)
    integrators: dict[str, tuple[str, ...]] = {}
    if f.has("integrators"):
        table = f.sub("integrators")
        for engine in list(table.table):
            if engine not in ENGINE_NAMES:
                raise table.error(engine, f"an engine name, one of {list(ENGINE_NAMES)}",
                                  f"unknown key {engine!r}")
            names = table.string_list(engine)
            if not names:
                raise table.error(engine, "at least one integrator name")
            if engine not in unchecked:
                # A misspelt name would only show up as a "not applicable" cell, and a
                # regression gate would pass without the check it was asked for.
                known = INTEGRATOR_NAMES[engine]
                for i, name in enumerate(names):
                    if name not in known:
                        raise CaseError(f.file, f"{table.field(engine)}[{i}]",
                                        f"an integrator of {engine}, one of {list(known)}", name)
            integrators[engine] = names
        table.done()
    timeout = f.number("timeout", 600.0, positive=True, unit="s")
    f.done()
    return RunSettings(duration=duration, dt=dt, sample_every=sample_every, engines=engines,
                       integrators=integrators, timeout=timeout)


# -- bodies ---------------------------------------------------------------------------------------
def _shape(f: Fields, dimension: int, base_dir: Path) -> Any:
    def size(n: int):
        return lambda s: _done(s, Box(size=s.vector("size", n, positive=True, unit="m")))

    def radius_only(cls):
        return lambda s: _done(s, cls(radius=s.number("radius", positive=True, unit="m")))

    def radius_length(cls):
        return lambda s: _done(s, cls(radius=s.number("radius", positive=True, unit="m"),
                                      length=s.number("length", positive=True, unit="m")))

    if dimension == 3:
        options = {
            "sphere": radius_only(Sphere),
            "box": size(3),
            "capsule": radius_length(Capsule),
            "cylinder": radius_length(Cylinder),
            "mesh": lambda s: _mesh(s, base_dir),
        }
    else:
        options = {"circle": radius_only(Circle), "box": size(2), "polygon": _polygon}
    return one_of(f, "shape", options)[1]


def _done(f: Fields, value: Any) -> Any:
    f.done()
    return value


def _mesh(f: Fields, base_dir: Path) -> Mesh:
    rel = f.string("file")
    scale = f.number("scale", 1.0, positive=True)
    f.done()
    try:
        path = (base_dir / rel).resolve()
    except (OSError, ValueError):  # e.g. an embedded NUL character
        raise f.error("file", "a file path (relative to the case file)", rel) from None
    try:
        mesh = massprops.load_mesh(path)
        massprops.check_closed_volume(mesh)
    except massprops.MeshError as exc:
        reason = exc.message.split(", expected")[0]  # the expectation is stated once, below
        raise f.error("file", f"a mesh file that is {massprops.CLOSED_MESH_EXPECTED}",
                      f"{path}: {reason}") from None
    vertices = np.asarray(mesh.vertices, float) * scale
    faces = np.asarray(mesh.faces, dtype=np.int64)
    vertices.setflags(write=False)
    faces.setflags(write=False)
    return Mesh(path=path, vertices=vertices, faces=faces, scale=scale)


def _polygon(f: Fields) -> Polygon:
    raw = f.raw("vertices")
    field = f.field("vertices")
    if not isinstance(raw, list) or len(raw) < 3:
        raise CaseError(f.file, field, "an array of at least 3 [x, y] points", raw)
    pts = np.array([check_vector(p, 2, f.file, f"{field}[{i}]", unit="m")
                    for i, p in enumerate(raw)])
    f.done()
    with np.errstate(all="ignore"):  # overflowing sizes are refused with the mass properties
        return _convex_polygon(f, field, raw, pts)


def _convex_polygon(f: Fields, field: str, raw: Any, pts: np.ndarray) -> Polygon:
    edges = np.roll(pts, -1, axis=0) - pts
    area2 = polygon_area2(pts)
    if abs(area2) < 1e-12:
        raise CaseError(f.file, field, "a polygon with non-zero area", raw)
    if area2 < 0:  # clockwise: store counter-clockwise, the convention of the 2D engines
        pts = pts[::-1].copy()
        edges = np.roll(pts, -1, axis=0) - pts
    turns = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
    if np.any(turns < -1e-12 * np.max(np.abs(pts)) ** 2):
        raise CaseError(f.file, field, "a convex polygon", raw)
    pts.setflags(write=False)
    return Polygon(vertices=pts)


def _checked_mass_properties(f: Fields, shape: Any, density: float, mass: float | None = None
                             ) -> Any:
    """Mass properties of the shape (scaled to ``mass`` if given), refused when floating point
    cannot represent them: a size so large or small that the volume overflows or underflows."""
    try:
        with np.errstate(all="ignore"):
            props = massprops.shape_mass_properties(shape, density)
            if mass is not None:
                props = massprops.with_mass(props, mass)
            second = props.inertia if hasattr(props, "inertia") else props.moment
            ok = (props.mass > 0 and np.all(np.isfinite([props.mass, *np.ravel(props.com),
                                                          *np.ravel(second)])))
    except (ValueError, ArithmeticError):
        ok = False
    if not ok:
        raise f.error("shape", "a shape whose mass, centre of mass and inertia are finite and "
                      "non-zero in floating point (sizes that neither overflow nor underflow)",
                      f.table.get("shape"))
    return props


def _body(f: Fields, dimension: int, materials: dict[str, Material], base_dir: Path) -> Body:
    name = f.string("name")
    shape = _shape(f, dimension, base_dir)

    if f.has("mass") == f.has("density"):
        got = "both" if f.has("mass") else "neither"
        near = difflib.get_close_matches("mass", list(f.table), n=1, cutoff=0.75) \
            + difflib.get_close_matches("density", list(f.table), n=1, cutoff=0.75)
        if got == "neither" and near:  # 'masss = 10' is a typo, not a missing mass
            got = f"neither (is {near[0]!r} a typo?)"
        raise CaseError(f.file, f.field("mass"), "exactly one of mass (kg) or density", got)
    if f.has("mass"):
        mass = f.number("mass", positive=True, unit="kg")
        props = _checked_mass_properties(f, shape, 1.0, mass)
        mass_source = "given"
    else:
        density = f.number("density", positive=True,
                           unit="kg/m^3" if dimension == 3 else "kg/m^2")
        props = _checked_mass_properties(f, shape, density)
        mass = float(props.mass)
        mass_source = "density"

    com = f.vector("com", dimension, None, unit="m")
    if com is None:
        com = np.asarray(props.com, float)

    inertia_source = "shape"
    if f.has("inertia"):
        inertia = _inertia(f, dimension)
        inertia_source = "given"
    elif dimension == 3:
        # A com offset moves the mass distribution, not its shape about the com: the inertia
        # about the centre of mass stays the shape's own about its centroid.
        inertia = np.asarray(props.inertia, float)
    else:
        inertia = np.array([[float(props.moment)]])

    position, orientation = _pose(f, dimension)
    if dimension == 3:
        velocity = f.vector("velocity", 3, [0, 0, 0], unit="m/s")
        angular_velocity = f.vector("angular_velocity", 3, [0, 0, 0], unit="rad/s")
    else:
        velocity = f.vector("velocity", 2, [0, 0], unit="m/s")
        angular_velocity = np.array([f.number("angular_velocity", 0.0, unit="rad/s")])
    material = material_ref(f, materials, dimension)
    f.done()
    for arr in (com, inertia, angular_velocity):
        arr.setflags(write=False)
    return Body(name=name, shape=shape, mass=mass, com=com, inertia=inertia, position=position,
                orientation=orientation, velocity=velocity, angular_velocity=angular_velocity,
                material=material, mass_source=mass_source, inertia_source=inertia_source)


def _pose(f: Fields, dimension: int) -> tuple[np.ndarray, np.ndarray]:
    """``position`` and ``orientation`` of a body frame (bodies and statics alike)."""
    position = f.vector("position", dimension, unit="m")
    if dimension == 3:
        orientation = _orientation(f)
    else:
        orientation = np.array([f.number("orientation", 0.0, unit="rad")])
    orientation.setflags(write=False)
    return position, orientation


def _static(f: Fields, dimension: int, materials: dict[str, Material], base_dir: Path) -> Static:
    """Fixed geometry: a shape of the body vocabulary placed like a body frame; no mass, no
    velocity (the parser of body shapes, so meshes and polygons are checked the same way)."""
    name = f.string("name")
    shape = _shape(f, dimension, base_dir)
    position, orientation = _pose(f, dimension)
    material = material_ref(f, materials, dimension)
    f.done()
    return Static(name=name, shape=shape, position=position, orientation=orientation,
                  material=material)


def _inertia(f: Fields, dimension: int) -> np.ndarray:
    field = f.field("inertia")
    raw = f.raw("inertia")
    if dimension == 2:
        return np.array([[check_number(raw, f.file, field, positive=True, unit="kg m^2")]])
    if isinstance(raw, list) and len(raw) == 3 and all(isinstance(r, list) for r in raw):
        tensor = np.array([check_vector(r, 3, f.file, f"{field}[{i}]", unit="kg m^2")
                           for i, r in enumerate(raw)])
        scale = np.max(np.abs(tensor))
        with np.errstate(over="ignore"):  # |a - b| of huge entries overflows: not symmetric
            symmetric = np.allclose(tensor, tensor.T, rtol=0, atol=1e-12 * max(scale, 1e-300))
        if not symmetric:
            raise CaseError(f.file, field, "a symmetric 3x3 tensor", raw)
        tensor = 0.5 * tensor + 0.5 * tensor.T  # (a + b) / 2 would overflow near 1e308
    else:
        diag = check_vector(raw, 3, f.file, field, positive=True, unit="kg m^2")
        tensor = np.diag(diag)
    scale = np.max(np.abs(tensor))
    if scale == 0:
        raise CaseError(f.file, field, "a positive definite inertia tensor", raw)
    # Eigenvalues of the tensor scaled to order one: LAPACK does not converge on entries near
    # the overflow limit. The checks below are scale-free.
    moments = np.linalg.eigvalsh(tensor / scale)
    if moments[0] <= 0:
        raise CaseError(f.file, field, "a positive definite inertia tensor", raw)
    # A rigid body's principal moments satisfy the triangle inequality I1 + I2 >= I3.
    if moments[0] + moments[1] < moments[2] * (1 - 1e-9):
        raise CaseError(f.file, field,
                        "principal moments satisfying the triangle inequality I1 + I2 >= I3",
                        raw)
    return tensor


def _orientation(f: Fields) -> np.ndarray:
    field = f.field("orientation")
    raw = f.raw("orientation", [1.0, 0.0, 0.0, 0.0])
    if isinstance(raw, dict):
        sub = Fields(raw, field, f.file)
        axis = sub.vector("axis", 3)
        angle = sub.number("angle", unit="rad")
        sub.done()
        if _safe_norm(axis) < 1e-12:
            raise CaseError(f.file, f"{field}.axis", "a non-zero axis", axis.tolist())
        return axis_angle_to_quat(axis / np.max(np.abs(axis)), angle)
    q = check_vector(raw, 4, f.file, field)
    norm = _safe_norm(q)
    if abs(norm - 1.0) > QUATERNION_UNIT_TOLERANCE:
        raise CaseError(f.file, field,
                        f"a unit quaternion [w, x, y, z] (|q| within {QUATERNION_UNIT_TOLERANCE}"
                        " of 1) or { axis = [...], angle = radians }", f"|q| = {norm:.6g}")
    return q / norm


def _safe_norm(v: np.ndarray) -> float:
    """Euclidean norm without overflow (|v|^2 of components near 1e300 is inf)."""
    biggest = float(np.max(np.abs(v)))
    return 0.0 if biggest == 0 else biggest * float(np.linalg.norm(v / biggest))


# -- effects, ground, reference, tolerances -------------------------------------------------------
def _body_name(f: Fields, key: str, names: list[str]) -> int:
    name = f.string(key)
    if name not in names:
        raise f.error(key, f"the name of a body ({names})", name)
    return names.index(name)


def _effects(f: Fields, dimension: int, names: list[str], has_fluid: bool) -> Effects:
    gravity = f.vector("gravity", dimension, None, unit="m/s^2")
    contact = f.boolean("contact", False)
    springs = []
    for s in f.table_list("springs", []):
        a = _body_name(s, "a", names)
        attach_a = s.vector("attach_a", dimension, [0.0] * dimension, unit="m")
        if s.has("b") == s.has("anchor"):
            raise CaseError(s.file, s.field("b"), "exactly one of b (a body) or anchor (a point)",
                            "both" if s.has("b") else "neither")
        if s.has("b"):
            b = _body_name(s, "b", names)
            if b == a:
                raise s.error("b", "a body other than a", names[b])
            attach_b = s.vector("attach_b", dimension, [0.0] * dimension, unit="m")
        else:
            b = None
            attach_b = s.vector("anchor", dimension, unit="m")
        springs.append(Spring(
            body_a=a, attach_a=attach_a, body_b=b, attach_b=attach_b,
            stiffness=s.number("stiffness", positive=True, unit="N/m"),
            damping=s.number("damping", 0.0, nonnegative=True, unit="N s/m"),
            rest_length=s.number("rest_length", 0.0, nonnegative=True, unit="m"),
        ))
        s.done()
    drags = []
    for d in f.table_list("drag", []):
        if d.has("bodies"):
            listed = d.string_list("bodies")
            for i, n in enumerate(listed):
                if n not in names:
                    raise CaseError(d.file, f"{d.field('bodies')}[{i}]",
                                    f"the name of a body ({names})", n)
            idx = tuple(names.index(n) for n in listed)
        else:
            idx = tuple(range(len(names)))
        drags.append(Drag(linear=d.number("linear", 0.0, nonnegative=True, unit="N s/m"),
                          angular=d.number("angular", 0.0, nonnegative=True, unit="N m s"),
                          bodies=idx))
        d.done()
    loads = []
    for ld in f.table_list("loads", []):
        body = _body_name(ld, "body", names)
        force = ld.vector("force", dimension, [0.0] * dimension, unit="N")
        if dimension == 3:
            torque = ld.vector("torque", 3, [0.0, 0.0, 0.0], unit="N m")
        else:
            torque = np.array([ld.number("torque", 0.0, unit="N m")])
            torque.setflags(write=False)
        loads.append(Load(body=body, force=force, torque=torque))
        ld.done()
    medium = _medium(f, dimension, has_fluid) if f.has("medium") else None
    f.done()
    return Effects(gravity=gravity, springs=tuple(springs), drag=tuple(drags), loads=tuple(loads),
                   contact=contact, fluid=has_fluid, medium=medium)


def _medium(f: Fields, dimension: int, has_fluid: bool) -> Medium:
    """``[effects] medium = { density = kg/m^3, viscosity = Pa s }``: a quiescent medium (3D rigid
    scenes; docs/cases.md). Each key defaults to 0; at least one must be positive."""
    if has_fluid:
        raise f.error("medium", "no medium in a [fluid] case (the resolved fluid is the medium "
                      "its bodies move through)", f.raw("medium"))
    if dimension != 3:
        raise f.error("medium", "no medium in a 2D case (the engines' medium models act on "
                      "finite 3D bodies; a 2D body in a fluid is a [fluid] case)",
                      f.raw("medium"))
    m = f.sub("medium")
    medium = Medium(density=m.number("density", 0.0, nonnegative=True, unit="kg/m^3"),
                    viscosity=m.number("viscosity", 0.0, nonnegative=True, unit="Pa s"))
    m.done()
    if medium.density == 0.0 and medium.viscosity == 0.0:
        raise f.error("medium", "a density or a viscosity above zero (a medium of neither "
                      "changes nothing)", f.raw("medium"))
    return medium


def _ground(f: Fields, dimension: int, materials: dict[str, Material]) -> Ground:
    up = [0.0, 0.0, 1.0] if dimension == 3 else [0.0, 1.0]
    normal = f.vector("normal", dimension, up)
    if _safe_norm(normal) < 1e-12:
        raise f.error("normal", "a non-zero normal vector", normal.tolist())
    unit = normal / np.max(np.abs(normal))
    unit = unit / np.linalg.norm(unit)
    unit.setflags(write=False)
    ground = Ground(normal=unit, offset=f.number("offset", 0.0, unit="m"),
                    material=material_ref(f, materials, len(normal)))
    f.done()
    return ground


def _reference(f: Fields, unchecked: frozenset[str], base_dir: Path, *, dimension: int,
               run: RunSettings, names: tuple[str, ...], fluid: Any, gravity: Any) -> Reference:
    kind = f.string("kind", "none", choices=REFERENCE_KINDS)
    ref = Reference(
        kind=kind,
        solution=f.string("solution", None) if f.has("solution") else None,
        table=f.string("table", None) if f.has("table") else None,
        file=f.string("file", None) if f.has("file") else None,
        engine=f.string("engine", None, choices=ENGINE_NAMES) if f.has("engine") else None,
        integrator=f.string("integrator", None) if f.has("integrator") else None,
        dt=f.number("dt", positive=True, unit="s") if f.has("dt") else None,
        params=_free_form(f, "params") if f.has("params") else {},
    )
    # fine-step may omit dt: the comparer then uses run.dt / 100 (docs/metrics.md).
    required = {"analytic": "solution", "engine": "engine"}
    if kind in required and getattr(ref, required[kind]) is None:
        raise CaseError(f.file, f.field(required[kind]),
                        f"this field, required when reference.kind = {kind!r}")
    if ref.integrator is not None:
        _check_reference_integrator(f, ref, unchecked)
    if kind == "table":
        ref = _table_reference(f, ref, base_dir, dimension, run, names, fluid, gravity)
    else:
        for key in ("table", "file"):
            if f.has(key):  # a table the comparer would never read
                raise f.error(key, f"no {key} unless reference.kind = \"table\"", kind)
    f.done()
    return ref


def _table_reference(f: Fields, ref: Reference, base_dir: Path, dimension: int,
                     run: RunSettings, names: tuple[str, ...], fluid: Any,
                     gravity: Any) -> Reference:
    """Published (``table``) or the case's own (``file``): exactly one, checked against the case
    now, so a table the comparer cannot use never reaches a cell (it would measure nothing)."""
    from dataclasses import replace

    from crosscheck.scene.published_table import check_published_table
    from crosscheck.scene.user_table import read_user_table

    if ref.table is None and ref.file is None:
        raise CaseError(f.file, f.field("table"), "this field (a published data set), or file = "
                        "\"your.csv\" (your own data), required when reference.kind = \"table\"")
    if ref.table is not None and ref.file is not None:
        raise f.error("file", "only one of table (a published data set) and file (your own CSV)",
                      ref.file)
    if ref.table is not None:
        check_published_table(f, ref.table, fluid, gravity)
        return ref
    data = read_user_table(f, base_dir, dimension=dimension, duration=run.duration,
                           body_names=names, fluid=fluid)
    return replace(ref, data=data)


def _check_reference_integrator(f: Fields, ref: Reference, unchecked: frozenset[str]) -> None:
    """The integrator must be one the reference's engine has (fine-step: also 'dop853'). Kinds
    that run no engine (analytic, table, none) ignore it; there it must merely be a name some
    engine knows, unless reference.engine names the engine."""
    engine = ref.engine or ("inhouse" if ref.kind == "fine-step" else None)
    if engine in unchecked or (engine is None and unchecked):
        return  # a stand-in adapter brings names of its own
    if engine is None:
        known = all_integrator_names()
        expected = f"an integrator name of some engine, one of {list(known)}"
    else:
        known = INTEGRATOR_NAMES[engine]
        expected = f"an integrator of {engine}, one of {list(known)}"
    name = ref.integrator
    if ref.kind == "fine-step":
        # crosscheck.reference.spec runs the fine-step integrator by its lower-case name.
        name = name.lower()
        known = known + FINE_STEP_ONLY
        expected += f", or {' or '.join(map(repr, FINE_STEP_ONLY))} (SciPy's DOP853)"
    if name not in known:
        raise f.error("integrator", expected, ref.integrator)


def _free_form(f: Fields, key: str) -> dict[str, Any]:
    """A table whose keys belong to someone else (solution parameters, engine options): its keys
    are not checked here, but its values must still be finite numbers, strings, booleans, arrays
    or tables (a NaN or a TOML date would only fail later, inside an engine or a JSON report)."""
    table = f.sub(key).table
    _check_plain(table, f.file, f.field(key))
    return table


def _check_plain(value: Any, file: Path, field: str) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _check_plain(v, file, f"{field}.{k}")
    elif isinstance(value, list):
        for i, v in enumerate(value):
            _check_plain(v, file, f"{field}[{i}]")
    elif isinstance(value, float):
        check_number(value, file, field)
    elif not isinstance(value, str | int):  # bool is an int; dates and times are the rest
        raise CaseError(file, field, "a number, string, boolean, array or table", value)


def _tolerances(f: Fields, unchecked: frozenset[str]) -> dict[str, Tolerance]:
    out = {}
    for metric in list(f.table):
        value = f.raw(metric)
        field = f.field(metric)
        if isinstance(value, dict):
            sub = Fields(value, field, f.file)
            default = sub.number("default", None, nonnegative=True)
            overrides = {k: sub.number(k, nonnegative=True) for k in value if k != "default"}
            for key in overrides:
                _check_override_key(sub, key, unchecked)
            sub.done()
            if default is None and not overrides:
                raise CaseError(f.file, field, "a limit, or a table with default and overrides")
            out[metric] = Tolerance(metric=metric, default=default, overrides=overrides)
        else:
            limit = check_number(value, f.file, field, nonnegative=True)
            out[metric] = Tolerance(metric=metric, default=limit)
    f.done()
    return out


def _check_override_key(sub: Fields, key: str, unchecked: frozenset[str]) -> None:
    """An override names an engine, an integrator some engine has, or 'engine.integrator' with
    an integrator of that engine: a misspelt key would silently never apply."""
    engine, dot, integrator = key.partition(".")
    if dot:
        if engine not in ENGINE_NAMES or not integrator:
            raise sub.error(key, "default, an engine name, an integrator name or "
                            f"'engine.integrator' with an engine in {list(ENGINE_NAMES)}",
                            f"unknown key {key!r}")
        if engine not in unchecked and integrator not in INTEGRATOR_NAMES[engine]:
            raise sub.error(key, f"'{engine}.integrator' with an integrator of {engine}, one of "
                            f"{list(INTEGRATOR_NAMES[engine])}", f"unknown key {key!r}")
    elif key not in ENGINE_NAMES and key not in all_integrator_names() and not unchecked:
        # (With an engine unchecked, its stand-in adapter may know the name.)
        raise sub.error(key, f"default, an engine name {list(ENGINE_NAMES)}, an integrator name "
                        f"of some engine {list(all_integrator_names())} or 'engine.integrator'",
                        f"unknown key {key!r}")


def _engine_options(f: Fields) -> dict[str, dict[str, Any]]:
    out = {}
    for engine in list(f.table):
        if engine not in ENGINE_NAMES:
            raise f.error(engine, f"an engine name, one of {list(ENGINE_NAMES)}",
                          f"unknown key {engine!r}")
        out[engine] = dict(_free_form(f, engine))
    f.done()
    return out
