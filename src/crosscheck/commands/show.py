"""``crosscheck show FILE``: the scene as crosscheck understood it, with derived mass properties."""

from __future__ import annotations

import argparse
import json
from dataclasses import fields, is_dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from crosscheck.scene.contact import RULES
from crosscheck.scene.loader import load_case
from crosscheck.scene.model import Body, Scene, Static

ORDER = 2  # its place in crosscheck --help


def register(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("show", help="explain how a case file was understood")
    p.add_argument("file", metavar="FILE", help="a case file")
    p.add_argument("--json", action="store_true", help="print the scene as JSON")
    p.set_defaults(func=run)
    return p


def to_plain(value: Any) -> Any:
    """Scene objects as JSON-ready values (arrays to lists, dataclasses to dicts)."""
    if is_dataclass(value) and not isinstance(value, type):
        if hasattr(value, "vertices") and hasattr(value, "faces"):  # meshes: summary, not data
            return {"kind": "mesh", "file": str(value.path), "scale": value.scale,
                    "vertices": len(value.vertices), "faces": len(value.faces)}
        return {f.name: to_plain(getattr(value, f.name)) for f in fields(value)}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, dict):
        return {str(k): to_plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_plain(v) for v in value]
    if isinstance(value, Path):
        return str(value)
    return value


def body_summary(body: Body) -> dict[str, Any]:
    """Derived quantities a user checks a case by: world COM, principal moments and axes."""
    out = {"com_world": body.com_world().tolist()}
    if body.dimension == 3:
        moments, axes = np.linalg.eigh(body.inertia)
        if np.linalg.det(axes) < 0:
            axes[:, 0] *= -1
        out["principal_moments"] = moments.tolist()
        out["principal_axes_body"] = axes.T.tolist()  # rows are the axes
        out["inertia_diagonal_in_body_frame"] = bool(
            np.allclose(body.inertia, np.diag(np.diag(body.inertia)), atol=1e-12 * moments[-1]))
    return out


def static_summary(static: Static) -> dict[str, Any]:
    """Where the static ends up: its tight world bounding box, to check the placement by."""
    lo, hi = static.placed().bounding_box()
    return {"bounding_box_world": [np.asarray(lo).tolist(), np.asarray(hi).tolist()]}


def scene_as_json(scene: Scene) -> dict[str, Any]:
    data = to_plain(scene)
    for b, body in zip(data["bodies"], scene.bodies, strict=True):
        b["derived"] = body_summary(body)
    for s, static in zip(data["statics"], scene.statics, strict=True):
        s["derived"] = static_summary(static)
    # The values every engine will be asked to use, pair by pair (the pair rule applied).
    data["contact_pairs"] = to_plain(list(scene.contact_pairs()))
    return data


def run(args) -> int:
    scene = load_case(args.file)
    if args.json:
        print(json.dumps(scene_as_json(scene), indent=2))
        return 0
    console = Console()
    # Everything the case file wrote is escaped: "[/]" in a description is text, not markup.
    console.print(f"[bold]{escape(scene.name)}[/bold] ({scene.dimension}D) — "
                  f"{escape(scene.description)}")
    console.print(f"tags: {escape(', '.join(scene.tags)) or '-'}    "
                  f"file: {escape(str(scene.source))}")
    r = scene.run
    console.print(f"run: duration {r.duration} s, dt {r.dt} s, sample every {r.sample_every} s; "
                  f"engines {', '.join(r.engines)}")
    for engine, names in r.integrators.items():
        console.print(f"  {engine}: {escape(', '.join(names))}")
    medium = scene.effects.medium
    console.print(f"effects: {', '.join(scene.effects.names()) or 'none'}"
                  + (f"; gravity {scene.effects.gravity.tolist()}"
                     if scene.effects.gravity is not None else "")
                  + (f"; medium: density {medium.density} kg/m^3, viscosity {medium.viscosity} "
                     "Pa s" if medium is not None else ""))
    table = Table(title="bodies")
    for col in ("name", "shape", "mass kg", "com (body)", "com (world)", "principal moments",
                "position", "velocity", "angular velocity"):
        table.add_column(col)
    for body in scene.bodies:
        d = body_summary(body)
        moments = d.get("principal_moments", [body.inertia[0, 0]])
        table.add_row(escape(body.name), body.shape.kind, f"{body.mass:.6g}", _vec(body.com),
                      _vec(d["com_world"]), _vec(moments), _vec(body.position),
                      _vec(body.velocity), _vec(body.angular_velocity))
    console.print(table)
    _print_contact(console, scene)
    ref = scene.reference
    console.print(f"reference: {ref.kind}"
                  + "".join(f" {k}={escape(str(v))}" for k, v in (("solution", ref.solution),
                            ("table", ref.table), ("engine", ref.engine),
                            ("integrator", ref.integrator), ("dt", ref.dt)) if v is not None))
    for name, tol in scene.tolerances.items():
        console.print(f"tolerance {escape(name)}: default {tol.default}"
                      + "".join(f", {escape(k)} {v}" for k, v in tol.overrides.items()))
    return 0


def _vec(v) -> str:
    return "[" + ", ".join(f"{x:.4g}" for x in np.atleast_1d(np.asarray(v, float))) + "]"


def _print_contact(console: Console, scene: Scene) -> None:
    """The ground, the statics and, in a contact case, the values of every pair."""
    if scene.ground is not None:
        g = scene.ground
        console.print(f"ground: normal {_vec(g.normal)}, offset {g.offset} m, "
                      f"material {escape(g.material.name)}")
    if scene.statics:
        table = Table(title="statics")
        for col in ("name", "shape", "position", "orientation", "material",
                    "world bounding box"):
            table.add_column(col, overflow="fold")  # folded, never cut: names are paths
        for st in scene.statics:
            lo, hi = static_summary(st)["bounding_box_world"]
            table.add_row(escape(st.name), st.shape.kind, _vec(st.position),
                          _vec(st.orientation), escape(st.material.name),
                          f"{_vec(lo)} .. {_vec(hi)}")
        console.print(table)
    pairs = scene.contact_pairs()
    if not pairs:
        return
    # One line per pair rather than a table: nothing is cut off at 80 columns.
    rules = {k: v for k, v in RULES.items()
             if scene.dimension == 3 or k != "torsional_friction"}  # no spin about it in 2D
    console.print(escape("contact pairs, the values every engine is given (rule: "
                         + ", ".join(f"{k} {v}" for k, v in rules.items())
                         + "; a [[contact_pairs]] entry overrides it):"))
    for p in pairs:
        console.print(escape(f"  {p.a} - {p.b}: {_pair_values(p.material, scene.dimension)}"))


def _pair_values(m, dimension: int) -> str:
    if not m.collide:
        return f"no contact (collide = false, {m.source})"
    keys = [("friction", ""), ("restitution", ""), ("rolling_friction", " m")]
    if dimension == 3:
        keys.append(("torsional_friction", " m"))
    return ", ".join(f"{k} {getattr(m, k):.6g}{unit}"
                     + (f" ({m.source})" if k in m.overridden else "") for k, unit in keys)
