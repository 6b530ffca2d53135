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

from crosscheck.scene.loader import load_case
from crosscheck.scene.model import Body, Scene

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


def scene_as_json(scene: Scene) -> dict[str, Any]:
    data = to_plain(scene)
    for b, body in zip(data["bodies"], scene.bodies, strict=True):
        b["derived"] = body_summary(body)
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
    console.print(f"effects: {', '.join(scene.effects.names()) or 'none'}"
                  + (f"; gravity {scene.effects.gravity.tolist()}"
                     if scene.effects.gravity is not None else ""))
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
