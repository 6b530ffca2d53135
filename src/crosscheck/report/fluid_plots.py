"""Figures of a fluid run for the HTML report: free-surface frames, the validation plot against
the case's reference, and a short animation of the surface where it moves.

Files in the run's plot folder, palette PNGs (crosscheck.report.figure.png). The page embeds the
validation plot (the one that answers "does it match the reference?", or the frames when the
case has none) and links the frames and the animation: they are the heavy part and a reader
who wants them clicks. The animation is made only where the surface moves by at least
:data:`MOVES_CELLS` cells: a tank at rest, or a 5 mm sloshing wave on a 16 mm grid, animates
into a still picture that would only add weight.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from crosscheck.compare import fluid_metrics as FM  # noqa: E402
from crosscheck.reference.fluid_data import (  # noqa: E402
    SCHAFER_TUREK,
    dfg_reference,
    load_table,
    sloshing_period,
)
from crosscheck.report.atomic import write_bytes  # noqa: E402
from crosscheck.report.figure import png  # noqa: E402
from crosscheck.sim.fluid.levelset import surface_lines  # noqa: E402

DPI = 90
MOVES_CELLS = 2.0
# The figure the page embeds (the rest are linked): the validation plot, else the frames.
EMBED_ORDER = ("-validation.png", "-body.png", "-frames.png")


def embedded(paths: list[str]) -> str | None:
    """Of a fluid run's plot files, the one the page shows inline (the others are linked)."""
    for suffix in EMBED_ORDER:
        for p in paths:
            if str(p).endswith(suffix):
                return p
    return None


def _stem(scene: Any, record: Any) -> str:
    integ = record.meta.get("integrator", "fluid")
    return f"{scene.name}-{integ}"


def _extent(spec) -> list[float]:
    return [0.0, spec.domain[0], 0.0, spec.domain[1]]


def _draw_frame(ax, scene, record, k: int) -> None:
    spec = scene.fluid
    dx = spec.dx
    if "phi" in record.fields and spec.has_surface:
        phi = np.asarray(record.fields["phi"][k], float)
        ax.imshow((phi < 0).T, origin="lower", extent=_extent(spec), cmap="Blues", vmin=0,
                  vmax=1.6, interpolation="nearest")
        for line in surface_lines(phi, dx):
            ax.plot(line[:, 0], line[:, 1], color="navy", lw=1.0)
    elif "u" in record.fields and "v" in record.fields:
        u = np.asarray(record.fields["u"][k], float)
        v = np.asarray(record.fields["v"][k], float)
        uc = 0.5 * (u[1:] + u[:-1])
        vc = 0.5 * (v[:, 1:] + v[:, :-1])
        speed = np.hypot(uc, vc)
        ax.imshow(speed.T, origin="lower", extent=_extent(spec), cmap="viridis")
        nx, ny = spec.resolution
        x = (np.arange(nx) + 0.5) * dx
        y = (np.arange(ny) + 0.5) * dx
        if np.any(speed > 0):
            ax.streamplot(x, y, uc.T, vc.T, color="white", density=1.0, linewidth=0.5)
    _draw_obstacles(ax, spec)
    ax.set_xlim(0, spec.domain[0])
    ax.set_ylim(0, spec.domain[1])
    ax.set_aspect("equal")
    ax.set_title(f"t = {record.field_t[k]:.3g} s", fontsize=8)
    ax.tick_params(labelsize=6)


def _draw_obstacles(ax, spec) -> None:
    """The obstacles' outlines: the zero contour of their signed distance on a grid four times
    finer than the fluid's (any shape, turned or not)."""
    if not spec.obstacles:
        return
    from crosscheck.sim.fluid.cutcell import union_distance

    nx, ny = spec.resolution
    h = spec.dx / 4
    x = (np.arange(4 * nx) + 0.5) * h
    y = (np.arange(4 * ny) + 0.5) * h
    X, Y = np.meshgrid(x, y, indexing="ij")
    d = union_distance(spec.obstacles, np.stack([X, Y], axis=-1))
    ax.contourf(x, y, d.T, levels=[-np.inf, 0.0], colors=["0.55"])
    ax.contour(x, y, d.T, levels=[0.0], colors=["k"], linewidths=0.6)


def _plot_dfg(ax, scene, record, name) -> None:
    """The DFG benchmark: drag and lift coefficients against time with the published intervals
    (2D-1: of the values; 2D-2: of the maxima) and, dashed, the reference computations' values
    (FEATFLOW's; for the 2D-2 lift maximum it lies below the interval)."""
    case = SCHAFER_TUREK[name][0]
    refs, _ = dfg_reference(case)
    cd, cl = FM.force_coefficients(scene, record)
    key_d, key_l = (("drag_coefficient", "lift_coefficient") if case == "2D-1"
                    else ("drag_coefficient_max", "lift_coefficient_max"))
    ax.plot(record.t, cd, color="C0", label="c_D")
    ax.axhspan(refs[key_d].lower, refs[key_d].upper, color="C0", alpha=0.3,
               label=f"{key_d} published")
    if refs[key_d].reference is not None:
        ax.axhline(refs[key_d].reference, color="C0", ls="--", lw=0.8)
    lo, hi = refs[key_d].lower, refs[key_d].upper
    ax.set_ylim(min(lo, np.min(cd[len(cd) // 4:])) - 0.1, max(hi, np.max(cd[len(cd) // 4:])) + 0.1)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("drag coefficient", color="C0")
    ax2 = ax.twinx()
    ax2.plot(record.t, cl, color="C1", lw=0.8, label="c_L")
    ax2.axhspan(refs[key_l].lower, refs[key_l].upper, color="C1", alpha=0.3)
    if refs[key_l].reference is not None:
        ax2.axhline(refs[key_l].reference, color="C1", ls="--", lw=0.8)
    ax2.set_ylabel("lift coefficient", color="C1")
    if case == "2D-1":
        span = max(0.01, 2 * np.max(np.abs(cl[len(cl) // 2:] - refs[key_l].target)))
        ax2.set_ylim(refs[key_l].target - span, refs[key_l].target + span)


def plot_frames(scene: Any, record: Any, outdir: Path, n: int = 6) -> Path:
    nf = len(record.field_t)
    picks = sorted(set(np.linspace(0, nf - 1, min(n, nf)).round().astype(int).tolist()))
    cols = min(3, len(picks))
    rows = math.ceil(len(picks) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 3.0 * rows), squeeze=False)
    for ax, k in zip(axes.ravel(), picks, strict=False):
        _draw_frame(ax, scene, record, k)
    for ax in axes.ravel()[len(picks):]:
        ax.axis("off")
    fig.suptitle(f"{scene.name} ({record.meta.get('integrator')})", fontsize=9)
    fig.tight_layout()
    path = write_bytes(outdir / f"{_stem(scene, record)}-frames.png", png(fig, DPI))
    plt.close(fig)
    return path


def plot_validation(scene: Any, record: Any, outdir: Path) -> Path | None:
    _, name, params = FM._ref(scene)
    spec = scene.fluid
    g = FM._gravity(scene)
    fig, ax = plt.subplots(1, 2 if name == "ghia_1982_re100" else 1,
                           figsize=(9, 3.6) if name == "ghia_1982_re100" else (5.5, 3.6),
                           squeeze=False)
    ax = ax.ravel()
    metrics = FM.fluid_metrics(scene, record)
    if name == "martin_moyce_1952":
        tb = load_table("martin_moyce_1952")
        a = float(params.get("column_width", record.series["front"][0]))
        shift = float(params.get("time_shift_T", 0.0))
        T = record.t * math.sqrt(2 * g / a)
        Z = record.series["front"] / a
        ax[0].plot(T, Z, label="simulation")
        if shift:
            ax[0].plot(T + shift, Z, "--", label=f"simulation, delayed {shift:g} in T")
        ax[0].plot(tb["T"], tb["Z"], "ko", ms=4, label="Martin & Moyce 1952")
        ax[0].set_xlabel("T = t sqrt(2g/a)")
        ax[0].set_ylabel("Z = front / a")
        ax[0].set_xlim(0, 3.5)
    elif name == "ghia_1982_re100":
        y, u, x, v = FM.centreline_profiles(scene, record)
        tu, tv = load_table("ghia_1982_re100_u"), load_table("ghia_1982_re100_v")
        ax[0].plot(u, y, label="simulation")
        ax[0].plot(tu["u"], tu["y"], "ko", ms=4, label="Ghia et al. 1982")
        ax[0].set_xlabel("u / U on x = 0.5")
        ax[0].set_ylabel("y / L")
        ax[1].plot(x, v, label="simulation")
        ax[1].plot(tv["x"], tv["v"], "ko", ms=4, label="Ghia et al. 1982")
        ax[1].set_xlabel("x / L")
        ax[1].set_ylabel("v / U on y = 0.5")
        ax[1].legend(fontsize=7)
    elif name == "sloshing_period":
        eta = record.series["surface_height"]
        layer = spec.initial[0].shape
        p = sloshing_period(spec.domain[0], layer.depth, g)
        ax[0].plot(record.t, eta - layer.depth, label="simulation (at the probe)")
        ax[0].plot(record.t, layer.amplitude * np.cos(2 * math.pi * record.t / p), "k--",
                   label=f"linear theory, period {p:.4g} s (undamped)")
        ax[0].set_xlabel("t (s)")
        ax[0].set_ylabel("surface elevation (m)")
    elif name == "zalesak":
        dx = spec.dx
        for k, style, lab in ((0, "k-", "initial (exact after one turn)"), (-1, "r-", "final")):
            for i, line in enumerate(surface_lines(np.asarray(record.fields["phi"][k]), dx)):
                ax[0].plot(line[:, 0], line[:, 1], style, lw=1, label=lab if i == 0 else None)
        ax[0].set_aspect("equal")
    elif name == "hydrostatic":
        ax[0].semilogy(record.t, np.maximum(record.series["max_speed"], 1e-16),
                       label="max speed in the fluid")
        ax[0].axhline(1e-4, color="r", ls="--", label="1e-4 m/s")
        ax[0].set_xlabel("t (s)")
        ax[0].set_ylabel("m/s")
    elif name in ("channel_sedimentation", "wachs_2009"):
        body = spec.bodies[0]
        vy = record.series[f"body_vy.{body.name}"]
        ax[0].plot(record.t, -vy, label="simulation: settling speed")
        ref = metrics.get("terminal_velocity_reference")
        source = ("Faxen (1946), Stokes" if name == "channel_sedimentation"
                  else "Wachs (2009), U = Re nu / d")
        if ref is not None:
            ax[0].axhline(ref, color="k", ls="--", label=f"{source}: {ref:.4g} m/s")
        ax[0].set_xlabel("t (s)")
        ax[0].set_ylabel("m/s")
    elif name in SCHAFER_TUREK:
        _plot_dfg(ax[0], scene, record, name)
    else:
        plt.close(fig)
        return None
    text = ", ".join(f"{k} = {v:.3g}" for k, v in metrics.items()
                     if k.endswith(("error", "rms", "change", "velocity")))
    ax[0].set_title(text, fontsize=7)
    ax[0].legend(fontsize=7)
    fig.tight_layout()
    path = write_bytes(outdir / f"{_stem(scene, record)}-validation.png", png(fig, DPI))
    plt.close(fig)
    return path


def surface_motion(record: Any) -> float:
    """How far the free surface moved, in cells: the largest number of cells whose wet state
    differs from the first frame, over the frames, divided by the grid's width in cells (a
    surface displaced by h cells across the whole width changes h cells per column)."""
    phi = record.fields["phi"]
    wet0 = np.asarray(phi[0], float) < 0
    changed = max(int(np.count_nonzero((np.asarray(f, float) < 0) != wet0)) for f in phi)
    return changed / wet0.shape[0]


def animate(scene: Any, record: Any, outdir: Path, max_frames: int = 40) -> Path | None:
    """A short GIF of the free surface: free-surface cases with enough frames whose surface
    moves by at least MOVES_CELLS cells."""
    if not scene.fluid.has_surface or len(record.field_t) < 5 or "phi" not in record.fields:
        return None
    if surface_motion(record) < MOVES_CELLS:
        return None
    from matplotlib.animation import FuncAnimation, PillowWriter

    nf = len(record.field_t)
    picks = np.unique(np.linspace(0, nf - 1, min(nf, max_frames)).round().astype(int))
    fig, ax = plt.subplots(figsize=(3.6, 3.4))

    def draw(k):
        ax.clear()
        _draw_frame(ax, scene, record, int(k))

    anim = FuncAnimation(fig, draw, frames=picks)
    path = outdir / f"{_stem(scene, record)}-surface.gif"
    anim.save(path, writer=PillowWriter(fps=8), dpi=60)
    plt.close(fig)
    return path


def plot_body(scene: Any, record: Any, body: Any, outdir: Path) -> Path | None:
    """The coupled body's motion (its Trajectory, engines/driver.body_trajectory): the height of
    its centre of mass and its angle over time."""
    if body is None or not len(body.t):
        return None
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.2))
    names = body.meta.get("bodies") or [f"body {k}" for k in range(body.n_bodies)]
    for k, n in enumerate(names):
        ax[0].plot(body.t, body.com[:, k, 1], label=f"{n}: y of the centre of mass")
        ax[1].plot(body.t, body.angle[:, k], label=f"{n}")
    ax[0].set_xlabel("t (s)")
    ax[0].set_ylabel("y (m)")
    ax[1].set_xlabel("t (s)")
    ax[1].set_ylabel("angle (rad, ccw)")
    ax[0].legend(fontsize=7)
    ax[1].legend(fontsize=7)
    fig.tight_layout()
    path = write_bytes(outdir / f"{_stem(scene, record)}-body.png", png(fig, DPI))
    plt.close(fig)
    return path


def plot_fluid(scene: Any, record: Any, outdir: str | Path, animation: bool = True,
               body: Any = None) -> list[Path]:
    """Write the PNG (and GIF) figures of one fluid run into ``outdir``; return their paths.
    ``body``: the coupled body's Trajectory, drawn in a ``-body.png`` of its own."""
    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    out: list[Path] = []
    if len(record.field_t):
        out.append(plot_frames(scene, record, outdir))
    v = plot_validation(scene, record, outdir)
    if v is not None:
        out.append(v)
    b = plot_body(scene, record, body, outdir)
    if b is not None:
        out.append(b)
    if animation:
        a = animate(scene, record, outdir)
        if a is not None:
            out.append(a)
    return out
