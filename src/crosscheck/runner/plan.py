"""Building the matrix case x engine x integrator x dt, and the shared reference runs it needs."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from crosscheck.errors import CrosscheckError
from crosscheck.runner.cell import cell_id, resolve_engine, safe_name


class UsageError(CrosscheckError):
    """Bad command-line input (unknown engine, bad step): exit status 2."""


@dataclass
class CaseInfo:
    name: str
    file: str
    sha256: str | None
    description: str
    tags: list[str]
    dimension: int
    duration: float
    reference: str
    tolerances: dict[str, Any]
    fluid: bool = False

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass
class Matrix:
    cases: list[CaseInfo] = field(default_factory=list)
    tasks: list[dict[str, Any]] = field(default_factory=list)  # references first, then cells
    engines: list[str] = field(default_factory=list)

    @property
    def cells(self) -> list[dict[str, Any]]:
        return [t for t in self.tasks if t["kind"] == "cell"]

    @property
    def references(self) -> list[dict[str, Any]]:
        return [t for t in self.tasks if t["kind"] == "reference"]


def parse_list(text: str | None) -> list[str] | None:
    if text is None:
        return None
    items = [s.strip() for s in text.split(",") if s.strip()]
    return items or None


def parse_dts(text: str | None) -> list[float] | None:
    items = parse_list(text)
    if items is None:
        return None
    out = []
    for item in items:
        try:
            value = float(item)
        except ValueError:
            raise UsageError(f"--dt: expected positive numbers, got {item!r}") from None
        if not value > 0 or value != value or value == float("inf"):
            raise UsageError(f"--dt: expected positive numbers, got {item!r}")
        out.append(value)
    return out


def check_integrators(requested: list[str] | None, engine_refs: dict[str, str] | None,
                      option: str = "--integrators") -> None:
    """Refuse ``--integrators`` entries no engine knows: a misspelt name would only turn into
    "not applicable" cells and a run that passes without the check it was asked for.

    ``engine.integrator`` needs a known engine with that integrator; a plain name must be an
    integrator of some engine. Engines replaced through ``engine_refs`` (adapters under
    development) bring their own names, so theirs are not checked, nor are plain names then.
    """
    from crosscheck.engines import engine_names
    from crosscheck.names import INTEGRATOR_NAMES, all_integrator_names

    refs = set(engine_refs or {})
    known_engines = sorted(set(engine_names()) | refs)
    for entry in requested or []:
        engine, dot, name = entry.partition(".")
        if dot:
            if engine not in known_engines or not name:
                raise UsageError(f"{option}: {entry!r} is not 'engine.integrator' with a known "
                                 f"engine ({', '.join(known_engines)})")
            if engine not in refs and name not in INTEGRATOR_NAMES.get(engine, ()):
                raise UsageError(f"{option}: {engine} has no integrator {name!r}; its "
                                 f"integrators: {', '.join(INTEGRATOR_NAMES.get(engine, ()))}")
        elif not refs and entry not in all_integrator_names():
            known = "; ".join(f"{e}: {', '.join(n)}" for e, n in INTEGRATOR_NAMES.items())
            raise UsageError(f"{option}: no engine has an integrator {entry!r}; known: {known}")


def _integrators_for(scene, engine_name: str, requested: list[str] | None,
                     engine_refs: dict[str, str] | None) -> list[str]:
    """The run names of one case on one engine; on a contact scene an in-house bare integrator
    carries its contact model ("rk4" -> "rk4+penalty", crosscheck.names.resolve_run)."""
    from crosscheck.names import resolve_run

    contact = bool(scene.effects.contact) and engine_name not in (engine_refs or {})
    return list(dict.fromkeys(resolve_run(engine_name, name, contact) for name in
                              _names_for(scene, engine_name, requested, engine_refs)))


def _names_for(scene, engine_name: str, requested: list[str] | None,
               engine_refs: dict[str, str] | None) -> list[str]:
    if requested:
        own = [r.split(".", 1)[1] for r in requested if r.startswith(engine_name + ".")]
        general = [r for r in requested if "." not in r]
        chosen = own or general
        if chosen:
            return list(dict.fromkeys(chosen))
        # Only other engines' integrators were named: this engine runs its own choice.
    listed = list(scene.integrators_for(engine_name))
    if listed:
        return listed
    from crosscheck.names import default_contact_run

    if (scene.effects.contact and default_contact_run(engine_name)
            and engine_name not in (engine_refs or {})):
        return [default_contact_run(engine_name)]
    try:
        return [resolve_engine(engine_name, engine_refs).capabilities().default_integrator]
    except Exception:
        return ["default"]  # the cell reports the import error as not applicable


def expected_work(scene, dt: float) -> float:
    """A cell's expected work, for the order cells are dispatched in (runner.schedule: the
    heaviest first): a fluid cell's grid cells times steps (its cost grows with both, and its
    run takes seconds to a minute), a rigid or contact cell's bodies times steps (most take well
    under a second; the many-body contact stacks and piles the longest of them, up to 20 s). A
    rough order, not a prediction: the integrator and the contact model are not counted."""
    steps = scene.run.duration / dt
    if scene.fluid is None:
        return float(len(scene.bodies)) * steps
    return float(math.prod(scene.fluid.resolution)) * steps


def build_matrix(scenes: list, *, engines: list[str] | None = None,
                 integrators: list[str] | None = None, dts: list[float] | None = None,
                 out: str | Path | None = None, save_trajectories: bool = False,
                 timeout: float | None = None, engine_refs: dict[str, str] | None = None,
                 reference_dir: str | Path | None = None,
                 cost: bool | dict[str, Any] = True) -> Matrix:
    """Tasks for every scene: shared reference runs first, then one cell per combination.

    ``cost=False`` skips every cell's cost pass (docs/metrics.md, "Cost"): verdicts only; a
    dict sets the cost pass's repetitions (``engines.driver.CostPlan`` fields).

    ``engines`` filters each case's own ``run.engines`` (a case never runs on an engine it does
    not list); ``integrators`` replaces the case's lists (``engine.integrator`` entries apply to
    that engine only); ``dts`` replaces the case's step.
    """
    from crosscheck.engines import engine_names
    from crosscheck.reference.spec import (
        describe,
        needs_run,
        reference_key,
        reference_spec,
    )

    known = set(engine_names()) | set(engine_refs or {})
    for name in engines or []:
        if name not in known:
            raise UsageError(f"--engines: unknown engine {name!r}; known: {sorted(known)}")
    check_integrators(integrators, engine_refs)
    names = {}
    for scene in scenes:
        if scene.name in names:
            raise UsageError(f"two case files define the case {scene.name!r}: "
                             f"{names[scene.name]} and {scene.source}")
        names[scene.name] = scene.source
    out = None if out is None else str(out)
    ref_dir = Path(reference_dir) if reference_dir else (
        Path(out) / "references" if out else None)
    matrix = Matrix()
    refs: dict[str, dict[str, Any]] = {}
    cells: list[dict[str, Any]] = []
    used_engines: list[str] = []
    for scene in scenes:
        case_engines = [e for e in scene.run.engines if engines is None or e in engines]
        step_list = dts or [scene.run.dt]
        if scene.fluid is None:
            from crosscheck.engines.base import whole_steps

            for dt in step_list:
                if whole_steps(scene.run.duration, dt) is None:
                    raise UsageError(
                        f"dt = {dt:g} s does not divide the duration {scene.run.duration:g} s "
                        f"of case {scene.name!r} ({scene.source}) into a whole number of steps "
                        f"({scene.run.duration / dt:.6g}); a run never ends early")
        cell_timeout = float(timeout if timeout is not None else scene.run.timeout)
        matrix.cases.append(CaseInfo(
            name=scene.name, file=str(scene.source), sha256=scene.source_sha256,
            description=scene.description, tags=list(scene.tags), dimension=scene.dimension,
            duration=scene.run.duration,
            reference=describe(reference_spec(scene, scene.run.dt)),
            tolerances={k: {"default": t.default, **t.overrides}
                        for k, t in scene.tolerances.items()},
            fluid=scene.fluid is not None))
        for engine_name in case_engines:
            if engine_name not in used_engines:
                used_engines.append(engine_name)
            for integrator in _integrators_for(scene, engine_name, integrators, engine_refs):
                for dt in step_list:
                    spec = reference_spec(scene, dt)
                    task = {
                        "kind": "cell", "id": cell_id(scene.name, engine_name, integrator, dt),
                        "case": scene.name, "case_file": str(scene.source),
                        "engine": engine_name, "integrator": integrator, "dt": float(dt),
                        "timeout": cell_timeout, "out": out,
                        "save_trajectories": bool(save_trajectories), "reference": spec,
                        "reference_file": None, "reference_error": None,
                        "engine_refs": dict(engine_refs or {}), "depends_on": None,
                        "cost": dict(cost) if isinstance(cost, dict) else bool(cost),
                        "work": expected_work(scene, dt),
                    }
                    if needs_run(spec):
                        if ref_dir is None:
                            raise UsageError("a simulated reference needs an output folder")
                        key = reference_key(scene, spec)
                        if key not in refs:
                            refs[key] = {
                                "kind": "reference", "id": f"reference:{scene.name}:{key}",
                                "case": scene.name, "case_file": str(scene.source),
                                "engine": spec.get("engine", "scipy"),
                                "integrator": spec.get("integrator") or "default",
                                "dt": spec.get("dt"), "spec": spec,
                                "path": str(ref_dir / f"{safe_name(scene.name)}-{key}.npz"),
                                "timeout": cell_timeout, "engine_refs": dict(engine_refs or {}),
                                "depends_on": None,
                            }
                        task["depends_on"] = refs[key]["id"]
                    cells.append(task)
    matrix.tasks = list(refs.values()) + cells
    matrix.engines = used_engines
    return matrix
