"""Metrics: the same formulas for every engine, computed from a Trajectory and the Scene.

Energies and momenta come from :mod:`crosscheck.quantities` (never an engine's own figure); the
scales relative metrics divide by, and the rules deciding whether a quantity is conserved, are in
:mod:`crosscheck.compare.scales`. ``t`` runs over the recorded samples, ``i`` over bodies, ``x_i``
is a centre of mass, ``v_i`` its velocity, ``w_i`` the angular velocity, all in the world frame.
Every formula is repeated in docs/metrics.md.

Conservation (relative, dimensionless)
    ``energy_drift = max_t |E(t) - E(0)| / S_E``, ``E = T + V`` (kinetic, gravity, springs,
    constant loads).
    ``linear_momentum_drift = max_t |B (P(t) - P(0))| / S_P``, ``P = sum_i m_i v_i``, ``B`` the
    projection on the directions no external force acts along (all of them without gravity or
    loads; the horizontal plane under gravity).
    ``angular_momentum_drift = max_t |L(t) - L(0)| / S_L``, ``L`` about the system's centre of mass
    (``sum_i (x_i - c) x m_i v_i + I_i(t) w_i``).
    A quantity the scene does not conserve (energy with drag, momentum under an anchored spring)
    is reported with ``meaningful = False`` and the reason, its value shown for information, and
    never fails a case.

Against the reference (the reference resampled at the run's times, :mod:`.interp`)
    ``position_error_max = max_t max_i |x_i(t) - x_i^ref(t)|`` (m);
    ``position_error_rms = sqrt(mean_t mean_i |x_i - x_i^ref|^2)`` (m);
    ``position_error_rel = position_error_max / L_ref`` with ``L_ref = max_i max(max_t |x_i^ref(t)
    - x_i^ref(0)|, r_i)`` (how far the reference moves, at least a body's size);
    ``orientation_error_max = max_t max_i angle(q_i, q_i^ref)`` (rad), the geodesic angle
    ``2 atan2(|vec(q^* q_ref)|, |w(q^* q_ref)|)``; 2D: ``|wrap(theta - theta^ref)|``;
    ``velocity_error_max = max_t max_i |v_i - v_i^ref|`` (m/s);
    ``angular_velocity_error_max = max_t max_i |w_i - w_i^ref|`` (rad/s);
    ``energy_error = max_t |E(t) - E^ref(t)| / S_E`` (meaningful with drag too: it follows the
    reference's own energy loss).
    Samples where the reference leaves a quantity undefined (NaN) are skipped; a quantity the
    reference never defines gives no metric.

Other
    ``out_of_plane_drift = max_t max_i |z_i(t)|`` (m), the out-of-plane centre-of-mass coordinate
    an adapter that runs a 2D scene in 3D records as ``traj.extras["out_of_plane"]``; likewise
    ``out_of_plane_tilt`` (rad, the body z axis against the world z axis) and
    ``out_of_plane_angular_velocity`` (rad/s, ``|(w_x, w_y)|``) when it records them.
    ``blowup_time``: the first sample time with a non-finite state (the adapter stopped there) or
    with ``|E(t) - E(0)| > 10 E_avail`` (scales.BLOWUP_FACTOR and scales.available_energy);
    absent when the run did not blow up.
    Contact scenes (``effects.contact``): the penetration, energy gain, restitution, sliding,
    rolling and resting metrics of :mod:`crosscheck.compare.contact_metrics`, computed from the
    Trajectory and the scene's geometry, never from an engine's contact report.
    Extra metrics of an analytic solution (``EXTRA_METRICS[name](scene, traj)``, e.g.
    ``flip_period_error``) are added as they come; one the run gives nothing to measure (no
    flip) has value None and ``not_measured`` says why.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from crosscheck.compare import contact_metrics, scales
from crosscheck.rotations import quat_angle_between
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory

# Units shown in reports; metrics not listed are dimensionless.
UNITS = {
    "position_error_max": "m", "position_error_rms": "m", "velocity_error_max": "m/s",
    "orientation_error_max": "rad", "angular_velocity_error_max": "rad/s",
    "out_of_plane_drift": "m", "out_of_plane_tilt": "rad",
    "out_of_plane_angular_velocity": "rad/s", "blowup_time": "s",
    **contact_metrics.UNITS,
}
# Points kept per time series for plots: enough for a smooth curve, bounded memory per cell.
SERIES_POINTS = 400


@dataclass
class Metric:
    name: str
    value: float | None  # None: could not be computed (see note)
    meaningful: bool = True  # False: not conserved in this scene; informational only
    note: str = ""
    unit: str = ""
    not_measured: str = ""  # the run had nothing to measure (e.g. no flip): value None, why


    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"value": _finite_or_none(self.value)}
        if self.value is not None and not np.isfinite(self.value):
            out["value_text"] = str(self.value)
        if not self.meaningful:
            out["meaningful"] = False
        if self.note:
            out["note"] = self.note
        if self.unit:
            out["unit"] = self.unit
        if self.not_measured:
            out["not_measured"] = self.not_measured
        return out


@dataclass
class MetricSet:
    metrics: dict[str, Metric] = field(default_factory=dict)
    series: dict[str, dict[str, list[float]]] = field(default_factory=dict)  # name -> {t, y}
    blowup_time: float | None = None
    blowup_reason: str | None = None

    def add(self, name: str, value: float | None, *, meaningful: bool = True, note: str = "",
            not_measured: str = ""):
        self.metrics[name] = Metric(name, None if value is None else float(value), meaningful,
                                    note or (f"not measured: {not_measured}" if not_measured
                                             else ""), UNITS.get(name, ""), not_measured)

    def add_series(self, name: str, t: np.ndarray, y: np.ndarray):
        self.series[name] = downsample(t, y)


def _finite_or_none(value):
    if value is None:
        return None
    value = float(value)
    return value if np.isfinite(value) else None


def downsample(t: np.ndarray, y: np.ndarray, points: int = SERIES_POINTS) -> dict[str, list]:
    """At most ``points`` samples, keeping the maximum of each bin (drift curves show peaks)."""
    t = np.asarray(t, float)
    y = np.asarray(y, float)
    if len(t) <= points:
        return {"t": t.tolist(), "y": [None if not np.isfinite(v) else float(v) for v in y]}
    edges = np.linspace(0, len(t), points + 1).astype(int)
    tt, yy = [], []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        seg = y[a:b]
        finite = np.isfinite(seg)
        if not finite.any():
            tt.append(float(t[a]))
            yy.append(None)
            continue
        k = a + int(np.nanargmax(np.where(finite, seg, -np.inf)))
        tt.append(float(t[k]))
        yy.append(float(y[k]))
    return {"t": tt, "y": yy}


# -- conservation ----------------------------------------------------------------------------------
def energy_metrics(scene: Scene, traj: Trajectory, ref: Trajectory | None, out: MetricSet,
                   energy: np.ndarray, basis: Trajectory):
    """``basis``: the samples the scale may use when there is no reference (before a blow-up).

    When the centre of mass moves on its own (scales.internal_energy_decouples), the drift is
    that of the internal energy, on the kinetic energy relative to the centre of mass: the same
    in every inertial frame, so a body that also translates fast cannot dilute its rotational
    drift. The centre of mass's share is reported apart as ``translational_energy_drift``.
    Otherwise (a spring to the world, drag, ground contact) the total energy, as one.
    Returns the total-energy scale (for ``energy_error``)."""
    from crosscheck.quantities import internal_energy, translational_energy

    reason = scales.energy_not_conserved(scene)
    total_scale, source = scales.energy_scale(scene, basis, ref)
    if scales.internal_energy_decouples(scene):
        e = internal_energy(scene, traj)
        scale, source = scales.energy_scale(scene, basis, ref, internal=True)
        what = "internal energy (relative to the centre of mass)"
        kinetic = "max kinetic energy relative to the centre of mass"
        _translational_energy(scene, traj, basis, translational_energy(scene, traj), out,
                              reason)
    else:
        e, scale, what, kinetic = energy, total_scale, "total energy", "max kinetic energy"
    if scale <= 0:
        out.add("energy_drift", None, meaningful=False,
                note="no energy scale: " + _still(out) + " and there is no gravity")
        return total_scale
    drift = np.abs(e - e[0]) / scale
    note = f"{what}; scale S_E = {scale:.6g} J ({kinetic}, {source})"
    if reason:
        note = f"not conserved: {reason}; " + note
    out.add("energy_drift", float(np.max(drift)), meaningful=reason is None, note=note)
    out.add_series("energy_drift", traj.t, drift)
    return total_scale


def _translational_energy(scene: Scene, traj: Trajectory, basis: Trajectory,
                          e: np.ndarray, out: MetricSet, reason: str | None):
    """``translational_energy_drift = max_t |E_c(t) - E_c(0)| / S_c``: the centre of mass's
    energy (1/2 M v_c^2 - M g . c - F_tot . c), on the kinetic energy the centre of mass gained
    (1/2 M max_t |v_c(t) - v_c(0)|^2, at least E_floor). Reported when a uniform force (gravity,
    constant loads) moves the centre of mass. Energy is not Galilean-invariant: a boost V adds
    V . (M delta v_c - F_tot t), the run's error in the centre of mass's momentum times V, so
    this figure is frame-invariant only when that momentum is right (as every engine's is for a
    body without an offset centre of mass)."""
    from crosscheck.quantities import com_velocity

    if scene.effects.gravity is None and not any(
            np.any(np.asarray(ld.force) != 0) for ld in scene.effects.loads):
        # No uniform force: the centre of mass moves uniformly and its energy depends on the
        # frame alone; linear_momentum_drift is the frame-invariant check of its motion.
        return
    vc = com_velocity(scene, basis)
    gained = 0.5 * scene.masses.sum() * float(np.max(np.sum((vc - vc[:1]) ** 2, axis=-1)))
    scale = max(gained, scales.energy_floor(scene))
    if scale <= 0:
        out.add("translational_energy_drift", None, meaningful=False,
                note="the centre of mass moves uniformly: its energy has no frame-invariant "
                     "scale (its momentum drift is linear_momentum_drift)")
        return
    drift = np.abs(e - e[0]) / scale
    note = (f"the centre of mass's energy; scale {scale:.6g} J (the kinetic energy it gained, "
            "at least E_floor)")
    if reason:
        note = f"not conserved: {reason}; " + note
    out.add("translational_energy_drift", float(np.max(drift)), meaningful=reason is None,
            note=note)


def linear_momentum_metric(scene: Scene, traj: Trajectory, out: MetricSet,
                           scale_basis: Trajectory):
    from crosscheck.quantities import linear_momentum

    basis, reason = scales.linear_momentum_directions(scene)
    scale = scales.momentum_scale(scene, scale_basis)
    p = linear_momentum(scene, traj)
    dp = p - p[0]
    if scale <= 0:
        out.add("linear_momentum_drift", None, meaningful=False, note=_still(out))
        return
    if basis is None:
        drift = np.linalg.norm(dp, axis=-1) / scale
        out.add("linear_momentum_drift", float(np.max(drift)), meaningful=False,
                note=f"not conserved: {reason}; scale S_P = {scale:.6g} kg m/s")
        out.add_series("linear_momentum_drift", traj.t, drift)
        return
    drift = np.linalg.norm(dp @ basis.T, axis=-1) / scale
    where = "" if len(basis) == scene.dimension else (
        f" (the {len(basis)} direction(s) orthogonal to gravity and loads)")
    out.add("linear_momentum_drift", float(np.max(drift)),
            note=f"scale S_P = {scale:.6g} kg m/s{where}")
    out.add_series("linear_momentum_drift", traj.t, drift)


def angular_momentum_metric(scene: Scene, traj: Trajectory, out: MetricSet,
                            scale_basis: Trajectory):
    from crosscheck.quantities import angular_momentum

    reason = scales.angular_momentum_not_conserved(scene)
    scale = scales.angular_momentum_scale(scene, scale_basis)
    if scale <= 0:
        out.add("angular_momentum_drift", None, meaningful=False, note=_still(out))
        return
    ang = angular_momentum(scene, traj, about="com")
    dl = ang - ang[0]
    drift = (np.abs(dl) if scene.dimension == 2 else np.linalg.norm(dl, axis=-1)) / scale
    note = f"about the system centre of mass; scale S_L = {scale:.6g} kg m^2/s"
    if reason:
        note = f"not conserved: {reason}; " + note
    out.add("angular_momentum_drift", float(np.max(drift)), meaningful=reason is None, note=note)
    out.add_series("angular_momentum_drift", traj.t, drift)


def _still(out: MetricSet) -> str:
    # Drift scales are taken relative to the system's centre of mass (frame-invariant): a body
    # that only translates has nothing to drift by them.
    return ("nothing moves relative to the centre of mass" if out.blowup_time is None
            else "nothing moves relative to the centre of mass before the blow-up")


# -- against the reference -------------------------------------------------------------------------
def _masked_max(values: np.ndarray) -> float | None:
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else None


def reference_metrics(scene: Scene, traj: Trajectory, ref: Trajectory, out: MetricSet,
                      energy: np.ndarray | None, e_scale: float):
    """Trajectory errors against ``ref`` already resampled at ``traj.t`` (same length)."""
    dpos = np.linalg.norm(traj.com - ref.com, axis=-1)  # (T, N)
    pos_max = _masked_max(dpos)
    if pos_max is not None:
        finite = dpos[np.isfinite(dpos)]
        out.add("position_error_max", pos_max)
        out.add("position_error_rms", float(np.sqrt(np.mean(finite**2))))
        reach = np.linalg.norm(ref.com - ref.com[:1], axis=-1)
        reach = np.where(np.isfinite(reach), reach, 0.0).max(axis=0)
        length = float(np.max(np.maximum(reach, scales.body_radii(scene))))
        if length > 0:
            out.add("position_error_rel", pos_max / length,
                    note=f"scale L_ref = {length:.6g} m")
        out.add_series("position_error", traj.t, _row_max(dpos))
    if scene.dimension == 3 and traj.quat is not None and ref.quat is not None:
        dang = quat_angle_between(traj.quat, ref.quat)
    elif traj.angle is not None and ref.angle is not None:
        diff = traj.angle - ref.angle
        dang = np.abs(np.arctan2(np.sin(diff), np.cos(diff)))
    else:
        dang = np.full(dpos.shape, np.nan)
    ang_max = _masked_max(dang)
    if ang_max is not None:
        out.add("orientation_error_max", ang_max)
        out.add_series("orientation_error", traj.t, _row_max(dang))
    dvel = _masked_max(np.linalg.norm(traj.vel - ref.vel, axis=-1))
    if dvel is not None:
        out.add("velocity_error_max", dvel)
    if scene.dimension == 2:
        dom = np.abs(traj.omega - ref.omega)
    else:
        dom = np.linalg.norm(traj.omega - ref.omega, axis=-1)
    dom_max = _masked_max(dom)
    if dom_max is not None:
        out.add("angular_velocity_error_max", dom_max)
    if energy is not None and e_scale > 0 and scales._has_full_state(ref):
        from crosscheck.quantities import total_energy

        de = np.abs(energy - total_energy(scene, ref)) / e_scale
        out.add("energy_error", float(np.max(de)),
                note=f"against the reference's energy; scale S_E = {e_scale:.6g} J")


def _row_max(values: np.ndarray) -> np.ndarray:
    """Max over bodies per sample, NaN where every body is NaN."""
    finite = np.isfinite(values)
    filled = np.where(finite, values, -np.inf).max(axis=1)
    return np.where(finite.any(axis=1), filled, np.nan)


# -- other -----------------------------------------------------------------------------------------
OUT_OF_PLANE = (  # extras key -> metric name (an adapter running a 2D scene in 3D fills them)
    ("out_of_plane", "out_of_plane_drift"),
    ("out_of_plane_tilt", "out_of_plane_tilt"),
    ("out_of_plane_omega", "out_of_plane_angular_velocity"),
)


def out_of_plane_metric(traj: Trajectory, out: MetricSet):
    """``max_t max_i |extras[key]|`` for each out-of-plane record the adapter kept."""
    for key, name in OUT_OF_PLANE:
        if key in traj.extras:
            values = np.abs(np.asarray(traj.extras[key], float))
            worst = _masked_max(values.reshape(len(values), -1)) if values.size else None
            if worst is not None:
                out.add(name, worst, note=f"from the adapter's extras[{key!r}]")


def blowup(scene: Scene, traj: Trajectory, energy: np.ndarray | None, out: MetricSet):
    """First non-finite sample (the adapter's failure) or first runaway-energy sample."""
    failure = traj.failure
    candidates = []
    if failure is not None:
        t_fail = float(failure.get("time", traj.t[-1] if len(traj.t) else 0.0))
        candidates.append((t_fail, str(failure.get("reason", "failure"))))
    if energy is not None and len(energy):
        bound = scales.available_energy(scene, traj)
        if bound > 0:
            over = np.nonzero(np.abs(energy - energy[0]) > scales.BLOWUP_FACTOR * bound)[0]
            if len(over):
                candidates.append((float(traj.t[over[0]]),
                                   f"energy error beyond {scales.BLOWUP_FACTOR:g} x the "
                                   f"available energy bound {bound:.6g} J"))
    if candidates:
        out.blowup_time, out.blowup_reason = min(candidates)
        out.add("blowup_time", out.blowup_time, note=out.blowup_reason)


def _prefix(traj: Trajectory, t_end: float | None) -> Trajectory:
    """The samples strictly before ``t_end`` (at least the first): what a scale may look at."""
    if t_end is None:
        return traj
    n = max(1, int(np.searchsorted(traj.t, t_end, side="left")))
    if n >= len(traj.t):
        return traj
    return Trajectory(t=traj.t[:n], com=traj.com[:n], vel=traj.vel[:n], omega=traj.omega[:n],
                      quat=None if traj.quat is None else traj.quat[:n],
                      angle=None if traj.angle is None else traj.angle[:n], meta=traj.meta)


# -- everything ------------------------------------------------------------------------------------
def compute_metrics(scene: Scene, traj: Trajectory, ref: Trajectory | None = None,
                    extra=None) -> MetricSet:
    """All metrics of one run. ``ref`` is the reference (any sampling; it is resampled here).

    ``extra``: optional callable ``(scene, traj) -> dict[str, float]`` (an analytic solution's
    EXTRA_METRICS entry).
    """
    from crosscheck.compare.interp import resample
    from crosscheck.quantities import total_energy

    out = MetricSet()
    if len(traj.t) == 0:
        blowup(scene, traj, None, out)
        return out
    ref_at = resample(ref, traj.t) if ref is not None else None
    energy = total_energy(scene, traj)
    # Blow-up first: scales taken from the run itself must not include the runaway part,
    # else a blown-up run would shrink its own drift.
    blowup(scene, traj, energy, out)
    basis = _prefix(traj, out.blowup_time)
    e_scale = energy_metrics(scene, traj, ref_at, out, energy, basis)
    linear_momentum_metric(scene, traj, out, basis)
    angular_momentum_metric(scene, traj, out, basis)
    if ref_at is not None:
        reference_metrics(scene, traj, ref_at, out, energy, e_scale)
    out_of_plane_metric(traj, out)
    if scene.effects.contact:
        contact_metrics.contact_metrics(scene, traj, out, energy, basis, ref_at)
    if extra is not None:
        for name, value in extra(scene, traj).items():
            if isinstance(value, tuple):  # (None, reason): the run had nothing to measure
                out.add(name, None, not_measured=value[1] or "not measured")
            else:
                out.add(name, value)
    if "blowup_time" in out.metrics:  # keep it last in reports
        out.metrics["blowup_time"] = out.metrics.pop("blowup_time")
    return out
