"""Validation numbers of a fluid run against the case's ``[reference]``.

All metrics are non-negative magnitudes, compared by the comparer as ``value <= tolerance``:

* ``volume_change``: ``|V(end) - V(0)| / V(0)`` (every free-surface case);
* ``max_spurious_velocity`` (``hydrostatic``): largest fluid speed at any sample, m/s;
* ``surge_front_error`` (table ``martin_moyce_1952``): largest ``|Z - Z_exp| / Z_exp`` over the
  experiment's points with ``T <= max_T`` (default 3), ``Z = front / a``, ``T = t sqrt(2 g / a)``;
  the simulated curve is delayed by ``reference.params.time_shift_T`` (default 0) for the time the
  experiment's gate took to release the column, and ``surge_front_error_unshifted`` is always
  reported beside it;
* ``u_centreline_rms``, ``v_centreline_rms`` (table ``ghia_1982`` or ``ghia_1982_re<Re>``): RMS
  difference from Ghia et al.'s table at the case's Reynolds number U L / nu (the loader refused
  any other) at their interior points, as a fraction of the lid speed, from the final frame;
  ``u_centreline_max``, ``v_centreline_max`` the largest difference;
* ``table_<column>_error_max`` / ``_rms`` (``reference.file``, the case's own table): see
  :mod:`crosscheck.compare.table_metrics`;
* ``period_error`` (``sloshing_period``): ``|P - P_lin| / P_lin`` with ``P`` from the zero
  crossings of the surface height at the probe and ``P_lin`` from ``w^2 = g k tanh(k h)``;
* ``area_change``, ``shape_error`` (``zalesak``): relative area change and area of the symmetric
  difference between the final and the initial region, relative to the initial area;
* ``floating_body`` (a case with one ``[[bodies]]`` entry floating in a rectangular tank, see
  :func:`floating_body`): ``draft_error``, ``heave_period_error``, ``energy_growth``;
* ``channel_sedimentation`` (one circular ``[[bodies]]`` entry settling on the centreline of a
  closed vertical channel without a free surface, see :func:`channel_sedimentation`):
  ``terminal_velocity_error`` against Faxen's low-Reynolds-number wall-corrected drag;
* ``energy_audit`` (a coupled run in a viscous fluid, see :func:`energy_audit`):
  ``viscous_dissipation_ratio``, the energy fluid and body lost against the viscous dissipation
  integral over the same window;
* DFG benchmark (tables ``schafer_turek_2d1``, ``schafer_turek_2d2``, see :func:`dfg_metrics`):
  for each published quantity ``q`` its value ``q``, ``q_error`` (relative difference from the
  FEATFLOW reference value, or from the interval's centre where there is none) and
  ``q_interval_miss`` (how far outside the published interval, relative to it, 0 inside).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from crosscheck.compare.table_metrics import table_metrics
from crosscheck.reference.fluid_data import (
    SCHAFER_TUREK,
    dfg_reference,
    ghia_reynolds,
    load_table,
    sloshing_period,
)


def _ref(scene: Any) -> tuple[str | None, str | None, dict]:
    ref = getattr(scene, "reference", None)
    if ref is None:
        return None, None, {}
    if isinstance(ref, dict):
        return ref.get("kind"), ref.get("table") or ref.get("solution"), ref.get("params", {})
    name = getattr(ref, "table", None) or getattr(ref, "solution", None)
    return getattr(ref, "kind", None), name, dict(getattr(ref, "params", {}) or {})


def _gravity(scene: Any) -> float:
    g = getattr(getattr(scene, "effects", None), "gravity", None)
    return 0.0 if g is None else float(np.linalg.norm(g))


def fluid_metrics(scene: Any, record: Any) -> dict[str, float]:
    """The validation metrics of ``record`` (a FluidRecord) for ``scene``'s reference."""
    spec = scene.fluid
    _, name, params = _ref(scene)
    s = record.series
    out: dict[str, float] = {}
    if spec.has_surface and len(s.get("volume", [])):
        v = s["volume"]
        out["volume_change"] = float(abs(v[-1] - v[0]) / v[0])
    if name == "hydrostatic":
        out["max_spurious_velocity"] = float(np.max(s["max_speed"]))
    elif name == "martin_moyce_1952":
        out.update(surge_front(scene, record, params))
    elif name is not None and name.startswith("ghia_1982"):
        out.update(cavity_centrelines(scene, record, name))
    elif name == "sloshing_period":
        out.update(sloshing(scene, record))
    elif name == "zalesak":
        out.update(zalesak(scene, record))
    elif name in SCHAFER_TUREK:
        out.update(dfg_metrics(scene, record, name, params))
    elif name == "floating_body":
        out.update(floating_body(scene, record, params))
    elif name == "channel_sedimentation":
        out.update(channel_sedimentation(scene, record, params))
    elif name == "disc_settling":
        out.update(disc_settling(scene, record, params))
    elif name == "wachs_2009":
        out.update(published_sedimentation(scene, record, params))
    if "total_energy" in s and "viscous_dissipation" in s:
        out.update(energy_audit(record, float(params.get("audit_start",
                                                         params.get("settle_time", 0.0)))))
    out.update(table_metrics(scene, record))
    return out


def surge_front(scene: Any, record: Any, params: dict) -> dict[str, float]:
    table = load_table("martin_moyce_1952")
    front = record.series["front"]
    a = float(params.get("column_width", front[0]))
    max_t = float(params.get("max_T", 3.0))
    shift = float(params.get("time_shift_T", 0.0))
    g = _gravity(scene)
    T = record.t * math.sqrt(2 * g / a)
    Z = front / a
    out = {}
    for key, dT in (("surge_front_error", shift), ("surge_front_error_unshifted", 0.0)):
        if key == "surge_front_error_unshifted" and shift == 0.0:
            out[key] = out["surge_front_error"]
            continue
        wanted = table["T"] <= max_t
        sel = wanted & (table["T"] - dT <= T[-1] + 1e-12)
        if not np.any(sel):
            out[key] = math.inf
            continue
        z_sim = np.interp(table["T"][sel] - dT, T, Z)
        rel = np.abs(z_sim - table["Z"][sel]) / table["Z"][sel]
        # a run that stopped before the last point has an error of 100 % there
        worst = float(np.max(rel)) if np.all(sel[wanted]) else max(float(np.max(rel)), 1.0)
        out[key] = worst
        if key == "surge_front_error":
            out["surge_front_rms"] = float(np.sqrt(np.mean(rel**2)))
    out["surge_front_time_shift_T"] = shift
    return out


def centreline_profiles(scene: Any, record: Any):
    """u(y) on the vertical centreline and v(x) on the horizontal one from the final frame,
    normalised by the lid speed, with the wall values appended; positions normalised by the
    domain size."""
    spec = scene.fluid
    nx, ny = spec.resolution
    dx = spec.dx
    lx, ly = spec.domain
    lid = spec.lid.speed if spec.lid is not None else 1.0
    u = np.asarray(record.fields["u"][-1], float)
    v = np.asarray(record.fields["v"][-1], float)
    xi = 0.5 * lx / dx                     # fractional x-face index of the vertical centreline
    i0 = min(int(xi), nx - 1)
    f = xi - i0
    ucol = (1 - f) * u[i0] + f * u[min(i0 + 1, nx)]
    yj = 0.5 * ly / dx
    j0 = min(int(yj), ny - 1)
    g = yj - j0
    vrow = (1 - g) * v[:, j0] + g * v[:, min(j0 + 1, ny)]
    yc = (np.arange(ny) + 0.5) * dx / ly
    xc = (np.arange(nx) + 0.5) * dx / lx
    top = lid if (spec.lid is not None and spec.lid.side == "top") else 0.0
    y_prof = np.concatenate([[0.0], yc, [1.0]])
    u_prof = np.concatenate([[0.0], ucol, [top]]) / lid
    x_prof = np.concatenate([[0.0], xc, [1.0]])
    v_prof = np.concatenate([[0.0], vrow, [0.0]]) / lid
    return y_prof, u_prof, x_prof, v_prof


def cavity_reynolds(scene: Any) -> float:
    """Re = U L / nu: lid speed, side of the (square) cavity, kinematic viscosity."""
    spec = scene.fluid
    return spec.lid.speed * spec.domain[0] / spec.kinematic_viscosity


def cavity_centrelines(scene: Any, record: Any, name: str = "ghia_1982") -> dict[str, float]:
    y, u, x, v = centreline_profiles(scene, record)
    re = ghia_reynolds(cavity_reynolds(scene), name)
    tu = load_table(f"ghia_1982_re{re}_u")
    tv = load_table(f"ghia_1982_re{re}_v")
    # interior points only: the wall values are imposed and would flatter the RMS
    iu = (tu["y"] > 0) & (tu["y"] < 1)
    iv = (tv["x"] > 0) & (tv["x"] < 1)
    du = np.interp(tu["y"][iu], y, u) - tu["u"][iu]
    dv = np.interp(tv["x"][iv], x, v) - tv["v"][iv]
    return {"u_centreline_rms": float(np.sqrt(np.mean(du**2))),
            "v_centreline_rms": float(np.sqrt(np.mean(dv**2))),
            "u_centreline_max": float(np.max(np.abs(du))),
            "v_centreline_max": float(np.max(np.abs(dv)))}


def measured_period(t: np.ndarray, eta: np.ndarray) -> float:
    """Period from the up- and down-crossings of ``eta`` through its mean (linear between
    samples): half the mean spacing of successive crossings is half a period."""
    e = eta - np.mean(eta)
    idx = np.flatnonzero(np.sign(e[1:]) != np.sign(e[:-1]))
    idx = idx[e[idx] != e[idx + 1]]
    if idx.shape[0] < 3:
        return math.nan
    tc = t[idx] - e[idx] * (t[idx + 1] - t[idx]) / (e[idx + 1] - e[idx])
    return float(2.0 * np.mean(np.diff(tc)))


def sloshing(scene: Any, record: Any) -> dict[str, float]:
    spec = scene.fluid
    layer = spec.initial[0].shape
    width = spec.domain[0]
    k = 2 * math.pi / layer.wavelength if math.isfinite(layer.wavelength) else math.pi / width
    mode = max(1, round(k * width / math.pi))
    p_lin = sloshing_period(width, layer.depth, _gravity(scene), mode)
    eta = record.series["surface_height"]
    # the mean of eta over a whole number of periods is the still depth; crossings of the
    # running mean are robust to the slow level drift a level set may have
    p = measured_period(record.t, eta)
    err = abs(p - p_lin) / p_lin if math.isfinite(p) else math.inf
    return {"period_error": float(err), "period": p, "period_linear_theory": p_lin}


def _fractions(phi: np.ndarray, dx: float, sub: int = 4) -> np.ndarray:
    """Supersampled fluid indicator (sub x sub per cell, linear ramp over a sub-cell)."""
    from scipy.ndimage import map_coordinates

    nx, ny = phi.shape
    gx = (np.arange(nx * sub) + 0.5) / sub - 0.5
    gy = (np.arange(ny * sub) + 0.5) / sub - 0.5
    X, Y = np.meshgrid(gx, gy, indexing="ij")
    ps = map_coordinates(np.asarray(phi, float), [X, Y], order=1, mode="nearest")
    return np.clip(0.5 - ps / (dx / sub), 0.0, 1.0) * (dx / sub) ** 2


def zalesak(scene: Any, record: Any) -> dict[str, float]:
    dx = scene.fluid.dx
    phi = record.fields["phi"]
    h0 = _fractions(phi[0], dx)
    h1 = _fractions(phi[-1], dx)
    a0 = float(h0.sum())
    return {"area_change": float(abs(h1.sum() - a0) / a0),
            "shape_error": float(np.abs(h1 - h0).sum() / a0)}


# -- the DFG benchmark -------------------------------------------------------------------------
def dfg_cylinder(spec: Any) -> tuple[Any, str, float, float]:
    """The benchmark's cylinder (placed circle), its name, diameter and the mean inflow speed."""
    (circle, name), = [(o, n) for o, n in zip(spec.obstacles, spec.obstacle_names, strict=True)
                       if getattr(o.shape, "kind", None) == "circle"]
    return circle, name, 2.0 * float(circle.shape.radius), spec.inflow.mean_speed()


def force_coefficients(scene: Any, record: Any) -> tuple[np.ndarray, np.ndarray]:
    """``c_D = 2 F_x / (rho U_mean^2 D)`` and ``c_L`` likewise, per sample, from the forces the
    run measured on the cylinder (``force_x.<name>``, ``force_y.<name>``)."""
    spec = scene.fluid
    _, name, d, u = dfg_cylinder(spec)
    scale = 2.0 / (spec.density * u * u * d)
    return (scale * np.asarray(record.series[f"force_x.{name}"]),
            scale * np.asarray(record.series[f"force_y.{name}"]))


def front_back_pressure(scene: Any, p: np.ndarray) -> float:
    """``p(front) - p(back)``: the pressures at the cylinder's upstream and downstream points
    (``x_c -+ R``, ``y_c``) from the pressure field ``p`` (cell centres), each by a
    least-squares quadratic through the fluid cells within three cells of the point."""
    from crosscheck.sim.fluid.cutcell import sample_points, union_distance
    from crosscheck.sim.fluid.forces import surface_pressure

    spec = scene.fluid
    circle, _, d, _ = dfg_cylinder(spec)
    nx, ny = spec.resolution
    _, _, centres = sample_points(nx, ny, spec.dx)
    dist = union_distance(spec.obstacles, centres)
    cx, cy = (float(c) for c in circle.position)
    p = np.asarray(p, float)
    return (surface_pressure(p, dist, spec.dx, (cx - 0.5 * d, cy))
            - surface_pressure(p, dist, spec.dx, (cx + 0.5 * d, cy)))


def _compare(out: dict[str, float], key: str, value: float, ref: Any) -> None:
    out[key] = float(value)
    target = ref.target
    out[f"{key}_error"] = float(abs(value - target) / abs(target)) if math.isfinite(value) \
        else math.inf
    miss = max(ref.lower - value, value - ref.upper, 0.0) if math.isfinite(value) else math.inf
    out[f"{key}_interval_miss"] = float(miss / abs(target))


def strouhal(t: np.ndarray, lift: np.ndarray, d: float, u: float) -> tuple[float, int]:
    """``St = D f / U_mean`` from the upward zero crossings of the lift (about its mean, linear
    between samples): f = (crossings - 1) / (last - first). Also the number of whole periods."""
    x = np.asarray(lift) - np.mean(lift)
    idx = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    if idx.shape[0] < 2:
        return math.nan, 0
    tc = t[idx] - x[idx] * (t[idx + 1] - t[idx]) / (x[idx + 1] - x[idx])
    periods = idx.shape[0] - 1
    return d * periods / (u * (tc[-1] - tc[0])), periods


def peak(values: np.ndarray) -> float:
    """The largest value of a sampled smooth signal: the largest sample refined by the parabola
    through it and its two neighbours (sampling a sine 30 times a period misses its peak by
    0.5 %; the parabola by 0.002 %)."""
    v = np.asarray(values, float)
    k = int(np.argmax(v))
    if k == 0 or k == v.shape[0] - 1:
        return float(v[k])
    a, b, c = v[k - 1], v[k], v[k + 1]
    den = a - 2 * b + c
    return float(b - 0.125 * (c - a) ** 2 / den) if den < 0 else float(b)


def dfg_metrics(scene: Any, record: Any, name: str, params: dict) -> dict[str, float]:
    """The DFG benchmark's quantities against the published intervals (Schafer & Turek 1996).

    2D-1 (steady): the final sample's ``drag_coefficient`` and ``lift_coefficient`` and the
    final frame's ``pressure_difference``; ``drag_coefficient_drift`` and
    ``lift_coefficient_drift``, the relative changes of c_D and c_L over the last tenth of the
    run, say how steady the run ended (the lift rings down slowly: at 10 cells across, 2 % off
    its final value at t = 6 s, 2e-4 at 11 s).
    2D-2 (periodic): ``drag_coefficient_max``, ``lift_coefficient_max`` and ``strouhal_number``
    over the samples after ``reference.params.settle_time`` (s; default: the second half of the
    run), the maxima refined between samples (:func:`peak`), with ``periods`` the number of
    whole lift periods they span (fewer than 3: the Strouhal number is not measured, it is
    infinite).
    """
    case = SCHAFER_TUREK[name][0]
    refs, _ = dfg_reference(case)
    t = np.asarray(record.t)
    cd, cl = force_coefficients(scene, record)
    out: dict[str, float] = {}
    if case == "2D-1":
        _compare(out, "drag_coefficient", cd[-1], refs["drag_coefficient"])
        _compare(out, "lift_coefficient", cl[-1], refs["lift_coefficient"])
        dp = front_back_pressure(scene, record.fields["p"][-1])
        _compare(out, "pressure_difference", dp, refs["pressure_difference"])
        k = int(np.searchsorted(t, t[-1] - 0.1 * t[-1]))
        out["drag_coefficient_drift"] = float(abs(cd[-1] - cd[k]) / abs(cd[-1]))
        out["lift_coefficient_drift"] = float(abs(cl[-1] - cl[k]) / abs(cl[-1]))
        return out
    settle = float(params.get("settle_time", 0.5 * t[-1]))
    sel = t >= settle
    _compare(out, "drag_coefficient_max", peak(cd[sel]) if sel.any() else math.nan,
             refs["drag_coefficient_max"])
    _compare(out, "lift_coefficient_max", peak(cl[sel]) if sel.any() else math.nan,
             refs["lift_coefficient_max"])
    _, _, d, u = dfg_cylinder(scene.fluid)
    st, periods = strouhal(t[sel], cl[sel], d, u) if sel.sum() > 2 else (math.nan, 0)
    _compare(out, "strouhal_number", st if periods >= 3 else math.inf,
             refs["strouhal_number"])
    out["periods"] = float(periods)
    return out


# -- a floating body (two-way coupling) ----------------------------------------------------------
def heave_added_mass(rho: float, waterline: float) -> float:
    """``rho pi B^2 / 8`` per unit length, ``B`` the waterline width: the heave added mass of a
    flat plate on the free surface and of a half-immersed circular cylinder (``rho pi R^2 / 2``,
    the same number for ``B = 2 R``) in the high-frequency limit (Korotkin, Added Masses of Ship
    Structures, Springer 2009, sec. 5). The added mass of a 2D floating body depends on the
    frequency (Ursell 1949) and on the tank's walls and depth, so this gives an estimate of the
    natural period, not a reference value."""
    return rho * math.pi * waterline ** 2 / 8.0


def _body_series(record: Any, name: str) -> dict[str, np.ndarray]:
    s = record.series
    return {k: s[f"body_{k}.{name}"] for k in ("x", "y", "angle", "vx", "vy", "omega")}


def _placed_at(body: Any, x: float, y: float, angle: float):
    from crosscheck.rotations import angle_to_matrix
    from crosscheck.scene.shapes import Placed

    origin = np.array([x, y]) - angle_to_matrix(angle) @ np.asarray(body.com, float)[:2]
    return Placed(body.shape, origin, angle)


def submerged_area(body: Any, x: float, y: float, angle: float, level: float) -> float:
    """Area of the body at the pose (centre of mass ``x, y``, ``angle``) below ``y = level``."""
    from crosscheck.sim.fluid import bodygeom

    kind, c, r, verts = bodygeom.shape_params(_placed_at(body, x, y, angle))
    return bodygeom.submerged(kind, c, r, verts, np.array([0.0, 1.0]), level)[0]


def floating_body(scene: Any, record: Any, params: dict) -> dict[str, float]:
    """A body floating in a rectangular tank without obstacles, gravity along -y:

    * ``draft_error``: ``|mean(A_sub) / (M / rho) - 1|`` over ``t >= params.settle_time``
      (default a third of the run), ``A_sub`` the body's area below the still-water level
      ``L(t) = (V(t) + M / rho) / W`` (the measured water volume spread flat over the tank's
      width, with the body at its Archimedes draft; exact for a tank with vertical walls);
      Archimedes: the equilibrium's submerged area is ``M / rho``;
    * ``heave_period``: the natural (undamped) period of the body's vertical motion, from a
      damped sinusoid fitted to it until the waves it radiates come back from the walls
      (:func:`heave_fit`); ``heave_damping`` the fitted damping ratio;
      ``heave_period_estimate`` ``2 pi sqrt((M + a) / (rho g B))`` with the waterline width
      ``B`` at equilibrium and the added mass ``a`` of :func:`heave_added_mass`;
      ``heave_period_error`` their relative difference (an estimate's, see there);
    * ``energy_growth``: the largest rise of the total energy of fluid and body above its initial
      value, relative to ``M g |y(0) - y_eq|``; the level set's volume error puts water at the
      surface or takes it away, whose potential energy ``rho g L dV`` is taken out first.
      ``energy_loss`` (the same scale): how much was dissipated by the end."""
    spec = scene.fluid
    out: dict[str, float] = {}
    if len(spec.bodies) != 1 or spec.obstacles:
        return {"draft_error": math.inf}
    body = spec.bodies[0]
    rho = spec.density
    g = _gravity(scene)
    width = spec.domain[0]
    t = record.t
    s = record.series
    b = _body_series(record, body.name)
    a_eq = body.mass / rho
    vol = s["volume"]
    level = (vol + a_eq) / width
    settle = float(params.get("settle_time", t[-1] / 3.0))
    late = t >= settle - 1e-12
    if not late.any():
        return {"draft_error": math.inf}
    a_sub = np.array([submerged_area(body, b["x"][k], b["y"][k], b["angle"][k], level[k])
                      for k in np.flatnonzero(late)])
    out["draft_error"] = float(abs(np.mean(a_sub) / a_eq - 1.0))
    out["submerged_fraction"] = float(np.mean(a_sub) / a_eq * rho * a_eq / body.mass)
    y_eq = float(np.mean(b["y"][late]))
    out.update(heave_fit(t, b["y"], y_eq, body, spec, level[0], g))
    # the estimate: waterline width at the equilibrium (a horizontal chord at the level)
    from crosscheck.sim.fluid import cutcell

    placed = _placed_at(body, b["x"][-1], y_eq, b["angle"][-1])
    lo, hi = placed.bounding_box()
    lvl = float(level[-1])
    chord = cutcell.solid_length([placed], np.array([[lo[0] - 1.0, lvl]]),
                                 np.array([[hi[0] + 1.0, lvl]]))[0] * (hi[0] - lo[0] + 2.0)
    if g > 0 and chord > 0:
        est = 2 * math.pi * math.sqrt((body.mass + heave_added_mass(rho, chord))
                                      / (rho * g * chord))
        out["heave_period_estimate"] = est
        p = out.get("heave_period", math.nan)
        out["heave_period_error"] = float(abs(p - est) / est) if math.isfinite(p) else math.inf
    if "total_energy" in s:
        e_corr = s["total_energy"] - rho * g * level * (vol - vol[0])
        scale = body.mass * g * abs(b["y"][0] - y_eq)
        if scale > 0:
            out["energy_growth"] = float(max(0.0, np.max(e_corr) - e_corr[0]) / scale)
            out["energy_loss"] = float((e_corr[0] - e_corr[-1]) / scale)
    return out


def heave_fit(t: np.ndarray, y: np.ndarray, y_eq: float, body: Any, spec: Any, level: float,
              g: float) -> dict[str, float]:
    """``y = y_eq + A exp(-z w t) cos(w_d t + phi)`` (``w_d = w sqrt(1 - z^2)``) least-squares
    fitted to the body's height from release until the first wave it radiates can be back from
    the nearer wall (``2 (gap) / sqrt(g L)``, the shallow-water speed; at most the run):
    ``heave_period = 2 pi / w`` (undamped), ``heave_damping = z``. With a 2D body's strong
    radiation damping (z about 0.2 for a box of beam four times its draft) the crossings of one
    or two periods are too few for a period; the fit uses every sample of the clean window."""
    from scipy.optimize import curve_fit

    x0 = float(np.asarray(body.position, float)[0])
    half = 0.5 * float(np.max(_placed_at(body, x0, y_eq, 0.0).bounding_box()[1]
                              - _placed_at(body, x0, y_eq, 0.0).bounding_box()[0]))
    gap = min(x0, spec.domain[0] - x0) - half
    t_end = min(float(t[-1]), 2.0 * gap / math.sqrt(g * level)) if g > 0 else float(t[-1])
    use = t <= t_end
    if np.count_nonzero(use) < 8:
        return {"heave_period": math.nan}
    tt, yy = t[use], y[use]
    a0 = float(yy[0] - y_eq)

    def model(tv, w, z, amp, ph, yc):
        wd = w * math.sqrt(max(1.0 - z * z, 1e-12))
        return yc + amp * np.exp(-z * w * tv) * np.cos(wd * tv + ph)

    # the undamped body's frequency as the start (buoyancy stiffness over mass alone)
    w0 = 2 * math.pi / max(tt[-1], 1e-9) * 2.0
    best = None
    for w_start in (w0, 0.5 * w0, 2.0 * w0, 4.0 * w0):
        try:
            p, _ = curve_fit(model, tt, yy, p0=[w_start, 0.2, a0, 0.0, y_eq], maxfev=5000)
        except (RuntimeError, ValueError):
            continue
        res = float(np.sum((model(tt, *p) - yy) ** 2))
        if p[0] > 0 and 0 <= p[1] < 1 and (best is None or res < best[1]):
            best = (p, res)
    if best is None:
        return {"heave_period": math.nan}
    p = best[0]
    return {"heave_period": float(2 * math.pi / p[0]), "heave_damping": float(p[1]),
            "heave_fit_window": t_end,
            "heave_fit_rms": float(math.sqrt(best[1] / tt.shape[0]) / max(abs(a0), 1e-300))}


def channel_sedimentation(scene: Any, record: Any, params: dict) -> dict[str, float]:
    """A disc settling on the centreline of a vertical channel (the walls at x = 0 and the
    domain's width), gravity along -y, at a low Reynolds number:

    * ``terminal_velocity``: the mean settling speed over the last whole number of cells of
      travel after ``params.settle_time`` (default half the run): the speed varies periodically as
      the disc crosses the grid lines (+-1.5 % at dx = a / 4), so a mean over part of a cell is
      biased by up to that much; less than a cell of travel: the mean over the window;
    * ``terminal_velocity_reference``: Faxen's Stokes settling velocity in the channel
      (:func:`crosscheck.reference.fluid_data.faxen_settling_velocity`), ``terminal_reynolds``
      ``2 a U / nu`` of the measured speed (Faxen's drag neglects inertia: keep it well below 1);
    * ``terminal_velocity_error``: their relative difference;
    * ``centreline_offset``: the largest ``|x - W / 2|`` over the run, m (the disc should not
      drift off the axis; the formula is for the centreline)."""
    from crosscheck.reference.fluid_data import faxen_settling_velocity
    from crosscheck.scene.shapes import Circle

    spec = scene.fluid
    if len(spec.bodies) != 1 or spec.obstacles or not isinstance(spec.bodies[0].shape, Circle):
        return {"terminal_velocity_error": math.inf}
    body = spec.bodies[0]
    a = float(body.shape.radius)
    rho = spec.density
    rho_s = body.mass / (math.pi * a * a)
    nu = spec.kinematic_viscosity
    width = spec.domain[0]
    b = _body_series(record, body.name)
    t = record.t
    settle = float(params.get("settle_time", t[-1] / 2.0))
    late = t >= settle - 1e-12
    if not late.any() or not nu:
        return {"terminal_velocity_error": math.inf}
    u_sim = _whole_cells_speed(t[late], b["y"][late], spec.dx)
    u_ref = faxen_settling_velocity(a, width / 2.0, rho_s, rho, nu, _gravity(scene))
    return {"terminal_velocity": u_sim, "terminal_velocity_reference": u_ref,
            "terminal_velocity_error": float(abs(u_sim / u_ref - 1.0)),
            "terminal_reynolds": 2.0 * a * u_sim / nu,
            "centreline_offset": float(np.max(np.abs(b["x"] - width / 2.0)))}


def published_sedimentation(scene: Any, record: Any, params: dict) -> dict[str, float]:
    """A disc settling in a vertical channel against a published benchmark's terminal state
    (``reference.table = "wachs_2009"``: reference/data/wachs2009_...csv, Wachs 2009, the channel
    four diameters wide, at the scene's density ratio 1.5 or 3). The loader refuses a case that is
    not the benchmark (``scene.published_table.wachs_channel``); a scene built otherwise that is
    not (one circle, no obstacles, the width w / d and the Galileo number sqrt((r - 1) g d^3) / nu
    the published ones to 1e-3) gets an infinite ``terminal_velocity_error`` (a failure, never a
    quiet pass).

    * ``terminal_velocity``: the mean settling speed over the last whole cells of travel after
      ``params.settle_time`` (default half the run), as in ``channel_sedimentation``;
      ``terminal_velocity_reference`` the published Re nu / d; ``terminal_velocity_error`` their
      relative difference (the Reynolds number's, too: ``terminal_reynolds`` and
      ``terminal_reynolds_reference``);
    * ``drag_coefficient``, the C_D that balances the reduced weight at the measured speed,
      against the published ``drag_coefficient_reference`` as ``drag_coefficient_error``;
    * ``terminal_velocity_unsteadiness``: |U(second half) / U(first half) - 1| of the window,
      each half's speed over its whole cells: how far from terminal the disc still is;
    * ``window_travel``: diameters travelled in the window; ``bottom_clearance``: the gap below
      the disc at the end, in diameters (the bottom brakes it within about one);
    * ``centreline_offset`` and ``centreline_offset_mean``: the largest and the mean |x - w / 2|
      in the window, in diameters (the symmetric state on the axis is unstable at this Reynolds
      number: the disc wanders across the axis, docs/fluid.md);
    * where the disc was released as the benchmark releases it (1 d off the axis, to 1e-3 d),
      ``centreline_offset_reference`` and ``centreline_offset_mean_reference``: the same two of
      Wachs's published path (fig. 5a, digitised; :func:`wachs_path_offsets`) over the same
      stretch of the fall, the window's start and end measured in diameters below the release.
      Reported beside the run's, not judged: the digitisation scatters by about 0.01 d, the
      largest offset depends on aligning the figure's release with the run's (the gate case's
      0.220 d is 0.299 with the stretch begun 1 d earlier; the mean 0.073 and 0.080), and the
      swing is what a coarse grid resolves least (docs/fluid.md)."""
    from crosscheck.reference.fluid_data import (
        galileo_number,
        settling_drag_coefficient,
        wachs_path_offsets,
        wachs_sedimentation,
    )
    from crosscheck.scene.shapes import Circle

    fail = {"terminal_velocity_error": math.inf}
    spec = scene.fluid
    if len(spec.bodies) != 1 or spec.obstacles or not isinstance(spec.bodies[0].shape, Circle):
        return fail
    body = spec.bodies[0]
    d = 2.0 * float(body.shape.radius)
    ratio = body.mass / (math.pi * d * d / 4.0) / spec.density
    nu, g = spec.kinematic_viscosity, _gravity(scene)
    try:
        bench = wachs_sedimentation(round(ratio, 9))
    except KeyError:
        return fail
    width = spec.domain[0]
    if (not nu or abs(width / d / bench.width_ratio - 1.0) > 1e-3
            or abs(galileo_number(ratio, g, d, nu) / bench.galileo - 1.0) > 1e-3):
        return fail
    b = _body_series(record, body.name)
    t = np.asarray(record.t, float)
    settle = float(params.get("settle_time", t[-1] / 2.0)) if len(t) else 0.0
    late = t >= settle - 1e-12
    if late.sum() < 4:
        return fail
    tl, yl = t[late], b["y"][late]
    u = _whole_cells_speed(tl, yl, spec.dx)
    half = tl >= 0.5 * (tl[0] + tl[-1])
    u1 = _whole_cells_speed(tl[~half], yl[~half], spec.dx)
    u2 = _whole_cells_speed(tl[half], yl[half], spec.dx)
    u_ref = bench.reynolds * nu / d
    cd = settling_drag_coefficient(ratio, g, d, u)
    out = {"terminal_velocity": u, "terminal_velocity_reference": u_ref,
           "terminal_velocity_error": float(abs(u / u_ref - 1.0)),
           "terminal_reynolds": u * d / nu, "terminal_reynolds_reference": bench.reynolds,
           "drag_coefficient": cd, "drag_coefficient_reference": bench.drag_coefficient,
           "drag_coefficient_error": float(abs(cd / bench.drag_coefficient - 1.0)),
           "terminal_velocity_unsteadiness": float(abs(u2 / u1 - 1.0)),
           "window_travel": float((yl[0] - yl[-1]) / d),
           "bottom_clearance": float((b["y"][-1] - d / 2.0) / d),
           "centreline_offset": float(np.max(np.abs(b["x"][late] - width / 2.0)) / d),
           "centreline_offset_mean": float(np.mean(np.abs(b["x"][late] - width / 2.0)) / d)}
    if abs(abs(b["x"][0] - width / 2.0) / d - 1.0) < 1e-3:
        path = wachs_path_offsets(bench.density_ratio, (b["y"][0] - yl[0]) / d,
                                  (b["y"][0] - yl[-1]) / d)
        if path is not None:
            out["centreline_offset_reference"], out["centreline_offset_mean_reference"] = path
    return out


# Why the cross-engine figures of a settling disc are reported and not judged (attached to the
# metrics by compare/evaluate.py, so a reader of the report sees the reason beside the number).
DISC_SETTLING_NOTES = {
    "terminal_velocity_vs_mujoco_ellipsoid":
        "reported, not judged: MuJoCo's ellipsoid drag is C_D = pi C_blunt / 2 (0.785) plus "
        "pi mu U per length whatever the Reynolds number; a cylinder's published C_D is "
        "1.5-2.1 at Re 40-20",
    "terminal_velocity_vs_mujoco_inertia_box":
        "reported, not judged: MuJoCo's inertia-box drag is C_D = sqrt(3) / 2 (0.866) plus pi mu "
        "U per length whatever the Reynolds number",
    "startup_acceleration_stateless":
        "MuJoCo's g (1 - rho_f / rho_s): its medium has no added mass (-m_A dv/dt)",
    "blockage": "2 R / W: the closed box's walls slow the disc; MuJoCo's medium is unbounded",
}


def disc_settling(scene: Any, record: Any, params: dict) -> dict[str, float]:
    """A disc released from rest in a closed domain full of fluid (no free surface), settling
    far from the walls: the in-house cell of the comparison with MuJoCo's stateless medium
    (docs/engines.md, "MuJoCo's stateless medium against a resolved fluid").

    What both claim to model, judged where the case sets limits:

    * ``terminal_velocity`` (m/s along the net force: down for a heavy disc, up for a light
      one; the mean over the last whole cells of travel after ``params.settle_time``, default
      half the run), ``terminal_reynolds`` 2 R U / nu and ``drag_coefficient`` the C_D on the
      diameter that balances the reduced weight at that speed, |rho_s / rho - 1| pi R g / U^2;
      ``drag_coefficient_published_low`` / ``_high``, the published band of a cylinder in
      unbounded steady flow at that Reynolds number (reference/fluid_data.cylinder_drag_band;
      None outside Re 20-40), and ``drag_coefficient_error``, how far C_D lies outside the band
      relative to the nearer edge (0 inside; None when there is no band);
    * ``terminal_force_balance_error``: |mean fluid force / weight - 1| over the same window (the
      fluid carries the whole weight at terminal speed: buoyancy plus drag);
    * ``startup_acceleration`` (m/s^2 along gravity, negative rising, from the first three
      samples) against ``startup_acceleration_reference`` g (rho_s - rho) / (rho_s + rho), the
      potential-flow
      added mass of a cylinder (rho pi R^2 per unit length); ``startup_acceleration_error``;
      ``added_mass_coefficient`` the C_a the measured acceleration implies.

    What the report sets beside MuJoCo's cells (reported, not judged here: MuJoCo's constant
    coefficients are not a cylinder's at this Reynolds number, and it has no added mass):
    ``terminal_velocity_mujoco_<model>`` the closed form of MuJoCo's mapped cylinder
    (reference/medium_analytic.mapped_law, with the case's ``engine_options.mujoco.fluidcoef``),
    ``terminal_velocity_vs_mujoco_<model>`` = U / U_mujoco - 1, ``startup_acceleration_stateless``
    g (1 - rho / rho_s), MuJoCo's; ``blockage`` 2 R / W (the walls MuJoCo does not have) and
    ``centreline_offset`` the largest sideways drift, m."""
    from crosscheck.reference.fluid_data import cylinder_drag_band
    from crosscheck.reference.medium_analytic import (
        FLUIDCOEF_DEFAULT,
        MEDIUM_MODELS,
        mapped_law,
        settling_accelerations,
        startup_acceleration,
    )
    from crosscheck.scene.medium_map import unmappable

    spec = scene.fluid
    why = unmappable(scene)
    if why is not None:
        return {"terminal_velocity": None, "startup_acceleration_error": None,
                "drag_coefficient_error": None}
    body = spec.bodies[0]
    r = float(body.shape.radius)
    rho = spec.density
    rho_s = body.mass / (math.pi * r * r)
    nu = spec.kinematic_viscosity
    g = _gravity(scene)
    b = _body_series(record, body.name)
    t = np.asarray(record.t, float)
    out: dict[str, float] = {"blockage": 2.0 * r / spec.domain[0],
                             "centreline_offset": float(np.max(np.abs(b["x"] - b["x"][0])))}
    acc = settling_accelerations(scene)
    if len(t) >= 3:
        a0 = -startup_acceleration(t, b["vy"])
        out["startup_acceleration"] = a0
        out["startup_acceleration_reference"] = acc["added_mass"]
        out["startup_acceleration_error"] = float(abs(a0 / acc["added_mass"] - 1.0))
        out["startup_acceleration_stateless"] = acc["stateless"]
        out["added_mass_coefficient"] = float(((rho_s - rho) * g / a0 - rho_s) / rho)
    settle = float(params.get("settle_time", t[-1] / 2.0)) if len(t) else 0.0
    late = t >= settle - 1e-12
    if late.sum() < 2 or g == 0.0:
        out["terminal_velocity"] = None
        return out
    # along the net force: down for a heavy disc, up for a light one (its -y falls)
    sign = 1.0 if rho_s >= rho else -1.0
    u = _whole_cells_speed(t[late], sign * b["y"][late], spec.dx)
    out["terminal_velocity"] = u
    if nu > 0:
        out["terminal_reynolds"] = 2.0 * r * u / nu
    cd = abs(rho_s / rho - 1.0) * math.pi * r * g / (u * u)
    out["drag_coefficient"] = cd
    band = cylinder_drag_band(out.get("terminal_reynolds", math.nan))
    if band is None:
        out["drag_coefficient_error"] = None
    else:
        lo, hi = band
        out["drag_coefficient_published_low"], out["drag_coefficient_published_high"] = lo, hi
        out["drag_coefficient_error"] = float(max(lo - cd, cd - hi, 0.0)
                                              / (lo if cd < lo else hi))
    weight = body.mass * g
    fy = np.asarray(record.series.get(f"body_force_y.{body.name}", []), float)
    if len(fy) == len(t):
        out["terminal_force_balance_error"] = float(abs(np.mean(fy[late]) / weight - 1.0))
    coef = (scene.engine_options.get("mujoco", {}) or {}).get("fluidcoef", FLUIDCOEF_DEFAULT)
    for model in MEDIUM_MODELS:
        try:
            u_mj = mapped_law(scene, model, coef)["u_t"]
        except ValueError:
            continue
        out[f"terminal_velocity_mujoco_{model}"] = u_mj
        out[f"terminal_velocity_vs_mujoco_{model}"] = u / u_mj - 1.0
    return out


def _whole_cells_speed(t: np.ndarray, y: np.ndarray, dx: float) -> float:
    """Mean downward speed over the last whole number of cells ``dx`` of travel in ``y(t)``
    (which falls), or over the whole window when it is shorter than a cell."""
    travel = float(y[0] - y[-1])
    cells = math.floor(travel / dx) if dx > 0 else 0
    if cells < 1:
        return travel / float(t[-1] - t[0]) if t[-1] > t[0] else math.nan
    target = y[-1] + cells * dx  # y fell through it: the time it passed, interpolated
    k = int(np.flatnonzero(y >= target)[-1])
    if k + 1 < len(y) and y[k] != y[k + 1]:
        t0 = t[k] + (t[k + 1] - t[k]) * (y[k] - target) / (y[k] - y[k + 1])
    else:
        t0 = t[k]
    return cells * dx / float(t[-1] - t0)


def energy_audit(record: Any, start: float = 0.0) -> dict[str, float]:
    """The energy of fluid plus body lost over ``t >= start`` against what viscosity dissipated:

    * ``energy_lost``: ``E(start) - E(end)`` of ``total_energy`` (kinetic and potential energy of
      fluid and body), J/m;
    * ``viscous_dissipation_integral``: the trapezoidal time integral of the measured
      ``viscous_dissipation`` series (``2 mu integral of D:D dA`` at every sample, W/m);
    * ``viscous_dissipation_ratio``: their ratio. 1 when viscosity accounts for all the loss;
      above 1 the scheme dissipates by itself as well (the semi-Lagrangian trace's interpolation,
      the first-order exchange with the body), below 1 the field's quadrature of ``D:D`` (first
      order at a moving wall) over-counts or the scheme gains energy;
    * ``energy_rise_max``: the largest rise of ``total_energy`` above its value at ``start``,
      relative to ``energy_lost`` (what never should be positive beyond the quadrature of the
      potential energy of cut cells)."""
    t = np.asarray(record.t, float)
    e = np.asarray(record.series["total_energy"], float)
    phi = np.asarray(record.series["viscous_dissipation"], float)
    sel = t >= start - 1e-12
    if np.count_nonzero(sel) < 2:
        return {}
    t, e, phi = t[sel], e[sel], phi[sel]
    lost = float(e[0] - e[-1])
    integral = float(np.sum(0.5 * (phi[1:] + phi[:-1]) * np.diff(t)))
    out = {"energy_lost": lost, "viscous_dissipation_integral": integral,
           "viscous_dissipation_ratio": lost / integral if integral > 0 else math.inf}
    if lost > 0:
        out["energy_rise_max"] = float(max(0.0, np.max(e - e[0])) / lost)
    return out
