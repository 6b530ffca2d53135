"""``crosscheck inertia MESH``: the inertia of a mesh by three methods, side by side.

The methods are those of the course notes in ``seeds/``: the exact polyhedral mass properties
by the divergence theorem (Mirtich 1996), the solid bounding box, and point sampling. For each:
mass, centre of mass, inertia tensor about the centre of mass (mesh frame), principal moments and
wall time; for the two approximations also their error against the exact result:

* ``mass_rel``: ``|m - m_exact| / m_exact``
* ``com_rel_diag``: ``|com - com_exact| / (bounding-box diagonal)``
* ``inertia_rel_fro``: ``||I - I_exact||_F / ||I_exact||_F``
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from crosscheck.scene import massprops

METHODS = {
    "exact": "divergence theorem (exact)",
    "bounding_box": "bounding box",
    "sampling": "point sampling",
}


ORDER = 3  # its place in crosscheck --help


def register(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "inertia",
        help="mass properties of a mesh: exact, bounding box and point sampling compared",
        description=__doc__.split("\n\n", 1)[0] + " Exact by the divergence theorem, "
        "approximations by the solid bounding box and by point sampling; errors are relative "
        "to the exact result.",
    )
    p.add_argument("mesh", metavar="MESH", help="closed triangle mesh file (OBJ, STL, PLY, OFF)")
    p.add_argument("--density", type=float, default=1000.0,
                   help="uniform density, kg/m^3 (default: 1000)")
    p.add_argument("--samples", type=int, default=100_000,
                   help="number of sample points in the bounding box (default: 100000)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the sampling (default: 0)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.set_defaults(func=run)
    return p


def _timed(fn, *args, **kwargs):
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t0


def _entry(props: massprops.MassProperties3D, seconds: float) -> dict:
    moments, axes = props.principal()
    return {
        "mass": props.mass,
        "com": props.com.tolist(),
        "inertia": props.inertia.tolist(),
        "principal_moments": moments.tolist(),
        "principal_axes": axes.tolist(),
        "wall_time_s": seconds,
    }


def _errors(approx: massprops.MassProperties3D, exact: massprops.MassProperties3D,
            diagonal: float) -> dict:
    return {
        "mass_rel": abs(approx.mass - exact.mass) / exact.mass,
        "com_rel_diag": float(np.linalg.norm(approx.com - exact.com)) / diagonal,
        "inertia_rel_fro": float(np.linalg.norm(approx.inertia - exact.inertia)
                                 / np.linalg.norm(exact.inertia)),
    }


def compute(path, density: float = 1000.0, samples: int = 100_000, seed: int | None = 0) -> dict:
    """The comparison as a JSON-ready dict. Raises :class:`massprops.MeshError`."""
    mesh = massprops.load_mesh(path)
    exact, t_exact = _timed(massprops.mesh_mass_properties, mesh.vertices, mesh.faces, density)
    bbox, t_bbox = _timed(massprops.bounding_box_mass_properties, mesh.vertices, density)
    sampled, t_sampled = _timed(massprops.sampled_mass_properties, mesh, density, samples, seed)
    lo, hi = np.asarray(mesh.bounds, dtype=float)
    diagonal = float(np.linalg.norm(hi - lo))
    methods = {
        "exact": _entry(exact, t_exact),
        "bounding_box": _entry(bbox, t_bbox) | {"error": _errors(bbox, exact, diagonal)},
        "sampling": _entry(sampled, t_sampled) | {"error": _errors(sampled, exact, diagonal)},
    }
    return {
        "mesh": str(path),
        "density": density,
        "samples": samples,
        "seed": seed,
        "vertices": int(len(mesh.vertices)),
        "faces": int(len(mesh.faces)),
        "volume": exact.mass / density,
        "bounding_box": {"min": lo.tolist(), "max": hi.tolist(), "diagonal": diagonal},
        "methods": methods,
    }


def _fmt_vec(v) -> str:
    return "[" + ", ".join(f"{x: .5g}" for x in v) + "]"


def _print_table(result: dict) -> None:
    from rich.console import Console
    from rich.table import Table
    from rich.text import Text

    ms = result["methods"]
    table = Table(
        title=f"Mass properties of {result['mesh']}",
        caption=(f"density {result['density']:g} kg/m^3, {result['faces']} faces, "
                 f"{result['samples']} samples (seed {result['seed']}); inertia about the centre "
                 "of mass, mesh frame; errors relative to the exact result"),
    )
    table.add_column("quantity", style="bold", no_wrap=True)
    for title in METHODS.values():
        table.add_column(title, justify="right", no_wrap=True)

    def row(label, fn):  # Text: no markup, so "[kg]" and vectors print as written
        table.add_row(Text(label), *(Text(fn(ms[k])) for k in METHODS))

    row("mass [kg]", lambda m: f"{m['mass']:.6g}")
    row("com [m]", lambda m: _fmt_vec(m["com"]))
    row("inertia [kg m^2]", lambda m: "\n".join(_fmt_vec(r) for r in m["inertia"]))
    row("principal moments", lambda m: _fmt_vec(m["principal_moments"]))
    row("wall time [s]", lambda m: f"{m['wall_time_s']:.3g}")
    table.add_section()

    def err(name):
        return lambda m: f"{m['error'][name]:.3e}" if "error" in m else "-"

    row("mass error (rel)", err("mass_rel"))
    row("com error (/ bbox diagonal)", err("com_rel_diag"))
    row("inertia error (rel Frobenius)", err("inertia_rel_fro"))
    Console(width=max(150, Console().width)).print(table)


def run(args) -> int:
    try:
        if not args.density > 0:
            raise ValueError(f"--density must be positive, got {args.density}")
        if args.samples < 1:
            raise ValueError(f"--samples must be at least 1, got {args.samples}")
        result = compute(args.mesh, args.density, args.samples, args.seed)
    except massprops.MeshError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except ValueError as exc:
        print(f"error: {args.mesh}: {exc}", file=sys.stderr)
        return 2
    if args.json:
        print(json.dumps(result))
    else:
        _print_table(result)
    return 0
