"""The end-state table ``crosscheck run`` prints: per case, each cell's final state against the
reference's (or, without a reference, against the case's first cell).

|dx|: largest centre-of-mass distance (m); dangle: largest orientation difference (rad,
geodesic); |dv|: largest velocity difference (m/s); over bodies, at the last common sample.

Every column is filled or says why not. A reference may lack a quantity (the tennis racket's
analytic solution gives the flip period, not the orientation): that column is then compared
with the case's most accurate other run (lowest worst metric / limit) at the same end time and
marked ``*``, with a note under the table naming it. A row with no end state (not applicable,
an error, a fluid run without bodies) says why in the ``vs`` column and shows ``-``, and so does
the run the others are compared with when there is no reference. A fluid run with a coupled body
has its body's end state (2D: +y up, angle counter-clockwise) like a rigid run.
"""

from __future__ import annotations

import math

import numpy as np

HEAD = ("case", "engine-integrator", "dt", "status", "t_end", "vs", "|dx| m", "dangle rad",
        "|dv| m/s")
QUANTITIES = ("centre of mass", "orientation", "velocity")
MARK = "*"


def diff(a: dict, b: dict) -> tuple[float, float, float]:
    """(max |dx|, max orientation angle, max |dv|) over bodies between two end states; NaN
    where either lacks the quantity."""
    from crosscheck.rotations import quat_angle_between

    def arr(state, key):
        value = state.get(key)
        return None if value is None else np.asarray(
            [[math.nan if v is None else v for v in np.atleast_1d(row)]
             for row in value], float)

    def largest(x):
        return float(np.max(x)) if x.size and np.all(np.isfinite(x)) else math.nan

    out = []
    for key in ("com", "rot", "vel"):
        x, y = arr(a, key), arr(b, key)
        if x is None or y is None or x.shape != y.shape:
            out.append(math.nan)
        elif key == "rot" and a.get("rot_kind") == "quat":
            out.append(largest(quat_angle_between(x, y)) if np.all(np.isfinite(y)) else math.nan)
        elif key == "rot":
            d = x - y
            out.append(largest(np.abs(np.arctan2(np.sin(d), np.cos(d)))))
        else:
            out.append(largest(np.linalg.norm(x - y, axis=-1)))
    return tuple(out)


def _label(c: dict) -> str:
    return f"{c['engine']}-{c['integrator']}"


def _accuracy_rank(c: dict) -> tuple[int, float]:
    ratio = (c.get("worst") or {}).get("ratio")
    ok = c.get("status") == "pass" and isinstance(ratio, int | float) and math.isfinite(ratio)
    return (0, ratio) if ok else (1, math.inf)


def _same_time(a: dict, b: dict) -> bool:
    return abs(a["t"] - b["t"]) <= 1e-9 * max(1.0, abs(a["t"]))


def _rows_of_case(case: str, group: list[dict], notes: dict[str, None]) -> list[tuple]:
    group = sorted(group, key=lambda c: (c["engine"], c["integrator"], c["dt"]))
    with_end = [c for c in group if c.get("end_state")]
    first = with_end[0] if with_end else None
    ranked = sorted(with_end, key=_accuracy_rank)
    rows = []
    for c in group:
        end = c.get("end_state")
        base = (case, _label(c), f"{c['dt']:g}", c["status"])
        if not end:
            why = ("a fluid run: no bodies" if c.get("fluid") else
                   f"no end state: {c['status'].replace('_', ' ')}")
            rows.append((*base, "-", why, "-", "-", "-"))
            continue
        t_end = f"{end['t']:.4g}"
        other, vs = c.get("reference_end"), "reference"
        if not other:
            if c is first:
                rows.append((*base, t_end, "(the base of this case's rows)", "-", "-", "-"))
                continue
            other, vs = first["end_state"], _label(first)
            if not _same_time(other, end):
                rows.append((*base, t_end, f"{vs} ended at t={other['t']:.4g}: not comparable",
                             "-", "-", "-"))
                continue
        values = list(diff(end, other))
        texts = []
        for k, v in enumerate(values):
            if math.isfinite(v):
                texts.append(f"{v:.3g}")
                continue
            # The reference lacks this quantity: compare it with the case's most accurate
            # other run (lowest worst metric / limit) that ended at the same time.
            peer = next((p for p in ranked if p is not c and _same_time(p["end_state"], end)),
                        None)
            pv = diff(end, peer["end_state"])[k] if peer is not None else math.nan
            if vs == "reference" and math.isfinite(pv):
                texts.append(f"{pv:.3g}{MARK}")
                notes[f"{MARK} {case}: the reference has no {QUANTITIES[k]} at the end; "
                      f"compared with {_label(peer)} instead"] = None
            else:
                texts.append("-")
                notes[f"- {case}: no {QUANTITIES[k]} to compare with (neither the {vs} nor "
                      "another run of the case at the same end time has it)"] = None
        rows.append((*base, t_end, vs, *texts))
    return rows


def end_state_table(cells: list[dict]) -> str:
    """The table as text (columns padded), with its notes under it."""
    by_case: dict[str, list[dict]] = {}
    for c in cells:
        by_case.setdefault(c["case"], []).append(c)
    notes: dict[str, None] = {}
    rows = [HEAD]
    for case, group in by_case.items():
        rows += _rows_of_case(case, group, notes)
    widths = [max(len(r[i]) for r in rows) for i in range(len(HEAD))]
    lines = ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip()
             for r in rows]
    return "\n".join(lines + list(notes))
