"""Published fluid validation data shipped with crosscheck (``reference/data/*.csv``).

Each CSV keeps its source lines as ``#`` comments at the top; :func:`load_table` returns the
columns and those lines, so reports can cite where the numbers come from.

* ``martin_moyce_1952``: surge-front position Z = x/a against T = t sqrt(2 g / a) of a collapsing
  water column of width a = 2.25 in and height 2a (Martin & Moyce 1952, Table 2).
* ``ghia_1982_re<Re>_u``: u along the vertical centreline x = 0.5 of the unit lid-driven cavity;
  ``ghia_1982_re<Re>_v``: v along the horizontal centreline y = 0.5 (Ghia, Ghia & Shin 1982,
  Tables I and II), for every Reynolds number of the paper (:data:`GHIA_REYNOLDS`). Lid speed 1,
  lid at y = 1 moving in +x. Each file's header names its table and column, the public copies it
  was checked against and the points left out (two misprints, in Re = 3200 and 10000).
* ``schafer_turek_1996``: the DFG benchmark, channel flow past a cylinder (Schafer & Turek 1996):
  the published intervals of drag, lift, pressure difference (2D-1, Re = 20) and maximum drag,
  maximum lift, Strouhal number (2D-2, Re = 100), with the FEATFLOW reference values of both
  (2D-2: FEATFLOW's reference computation, whose lift maximum lies below the 1996 interval;
  :func:`dfg_reference`); its header names the copies it was checked against.
* ``ursell_1949``: heave added mass and damping of a half-immersed circular cylinder in deep
  water against ``omega^2 R / g`` (Ursell 1949; a public computation of his method, checked
  against a fit to Faltinsen's graph: the file's header), behind :func:`floating_circle_heave`.

A case names a data set by :data:`CASE_TABLES` (``reference.table``); the loader refuses any
other name, and a cavity case whose Reynolds number is not one of the paper's
(:func:`ghia_reynolds`). Both live in :mod:`crosscheck.scene.published_table`, with the loader's
checks (the scene must not import reference/), and are re-exported here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources

import numpy as np

# The catalogue a case may name lives with the loader's checks, below this module.
from crosscheck.scene.published_table import (  # noqa: F401 - re-exported
    CASE_TABLES,
    GHIA_REYNOLDS,
    REYNOLDS_RTOL,
    SCHAFER_TUREK,
    WACHS_2009,
    galileo_number,
    ghia_reynolds,
)

TABLES = {"martin_moyce_1952": "martin_moyce1952_front_a2.25in.csv",
          "faxen_1946": "faxen1946_cylinder_between_plates.csv",
          "cylinder_drag_steady": "cylinder_drag_steady_low_re.csv",
          "wachs_2009": "wachs2009_disc_channel_sedimentation.csv",
          "wachs_2009_path": "wachs2009_fig5a_path.csv",
          "ursell_1949": "ursell1949_semicircle_heave.csv"}
for _re in GHIA_REYNOLDS:
    TABLES[f"ghia_1982_re{_re}_u"] = f"ghia1982_re{_re}_u_vertical_centreline.csv"
    TABLES[f"ghia_1982_re{_re}_v"] = f"ghia1982_re{_re}_v_horizontal_centreline.csv"

@dataclass(frozen=True)
class Table:
    name: str
    columns: dict[str, np.ndarray]
    source: tuple[str, ...]

    def __getitem__(self, key: str) -> np.ndarray:
        return self.columns[key]


def load_table(name: str) -> Table:
    if name not in TABLES:
        raise KeyError(f"unknown fluid reference table {name!r}; known: {sorted(TABLES)}")
    text = resources.files("crosscheck.reference").joinpath("data", TABLES[name]).read_text()
    source = []
    rows = []
    header = None
    for line in text.splitlines():
        line = line.strip()
        if not line:
            continue
        if line.startswith("#"):
            source.append(line.lstrip("# ").rstrip())
        elif header is None:
            header = [h.strip() for h in line.split(",")]
        else:
            rows.append([float(v) for v in line.split(",")])
    data = np.array(rows)
    return Table(name, {h: data[:, i] for i, h in enumerate(header)}, tuple(source))


@dataclass(frozen=True)
class BenchmarkValue:
    """One published quantity: its interval and, where the source has one, a precise value."""

    lower: float
    upper: float
    reference: float | None

    @property
    def centre(self) -> float:
        return 0.5 * (self.lower + self.upper)

    @property
    def target(self) -> float:
        """The precise value where there is one, else the interval's centre."""
        return self.centre if self.reference is None else self.reference


DFG_FILE = "schafer_turek1996_cylinder.csv"


def dfg_reference(case: str) -> tuple[dict[str, BenchmarkValue], tuple[str, ...]]:
    """The DFG benchmark's values for ``case`` (``"2D-1"`` or ``"2D-2"``) by quantity name, and
    the file's source lines."""
    text = resources.files("crosscheck.reference").joinpath("data", DFG_FILE).read_text()
    source, values, header = [], {}, None
    for line in text.splitlines():
        line = line.strip()
        if not line:
            continue
        if line.startswith("#"):
            source.append(line.lstrip("# ").rstrip())
            continue
        cells = [c.strip() for c in line.split(",")]
        if header is None:
            header = cells
            continue
        row = dict(zip(header, cells, strict=True))
        if row["case"] == case:
            ref = float(row["reference"]) if row["reference"] else None
            values[row["quantity"]] = BenchmarkValue(float(row["lower"]), float(row["upper"]), ref)
    if not values:
        raise KeyError(f"no DFG benchmark {case!r} in {DFG_FILE}")
    return values, tuple(source)


def sloshing_period(width: float, depth: float, g: float, mode: int = 1) -> float:
    """Linear (small-amplitude) standing-wave period in a rectangular tank:
    w^2 = g k tanh(k h) with k = mode pi / width."""
    k = mode * math.pi / width
    return 2 * math.pi / math.sqrt(g * k * math.tanh(k * depth))


def ursell_heave(k: float) -> tuple[float, float]:
    """Heave added mass ``a33 / (rho A)`` and damping ``b33 / (rho A) sqrt(R / g)`` of a
    half-immersed circular cylinder in deep water, ``A = pi R^2 / 2``, at ``k = omega^2 R / g``,
    linear between the rows of data/ursell1949_semicircle_heave.csv (k from 0.5 to 1.2; its header
    says where the numbers come from)."""
    return _ursell_at(load_table("ursell_1949"), k)


def _ursell_at(table: Table, k: float) -> tuple[float, float]:
    ks = table["K"]
    if not ks[0] <= k <= ks[-1]:
        raise ValueError(f"k = omega^2 R / g must be in [{ks[0]}, {ks[-1]}], got {k}")
    return (float(np.interp(k, ks, table["added_mass"])),
            float(np.interp(k, ks, table["damping"])))


def floating_circle_heave(radius: float, g: float) -> tuple[float, float]:
    """Natural period (s) and damping ratio of the heave of a circle floating half immersed (a
    body of half the fluid's density) in deep water, from Ursell's added mass and damping at
    its own frequency: ``omega^2 (M + a33(omega)) = C`` with ``M = rho A`` and the waterplane
    stiffness ``C = 2 rho g R``, i.e. ``k = 4 / (pi (1 + a33 / (rho A)))``, solved by fixed point
    (a33 varies by 1 % over the iterations' range); the damping ratio
    ``b33 / (2 sqrt(C (M + a33)))``. Linear theory: small heave, no viscosity, no walls."""
    table = load_table("ursell_1949")
    k = 0.8
    for _ in range(50):
        added, _ = _ursell_at(table, k)
        k_next = 4.0 / (math.pi * (1.0 + added))
        if abs(k_next - k) < 1e-12:
            break
        k = k_next
    added, damping = _ursell_at(table, k)
    omega = math.sqrt(k * g / radius)
    # per unit rho A: M + a = 1 + added, C = 2 g R / A = 4 g / (pi R), b = damping sqrt(g / R)
    stiffness = 4.0 * g / (math.pi * radius)
    ratio = damping * math.sqrt(g / radius) / (2.0 * math.sqrt(stiffness * (1.0 + added)))
    return 2.0 * math.pi / omega, ratio


def faxen_channel_lambda(k: float) -> float:
    """Faxen's (1946) wall factor ``Lambda(k)`` of a circular cylinder of radius ``a`` moving slowly
    along the centreline between plane walls ``2 h`` apart, ``k = a / h``: the Stokes drag per
    unit length is ``4 pi mu U / Lambda(k)`` (data/faxen1946_cylinder_between_plates.csv, with its
    sources: two public copies, the constant and the ``k^2`` coefficient also derived from the
    Stokes equations in tests/reference/test_faxen_table.py; the ``k^6`` and ``k^8`` terms, 0.09 %
    of Lambda at k = 0.25, on one copy). The series is for ``k`` up to about 0.5."""
    if not 0.0 < k < 1.0:
        raise ValueError(f"k = a / h must be in (0, 1), got {k}")
    table = load_table("faxen_1946")
    return math.log(1.0 / k) + float(np.sum(table["coefficient"] * k ** table["power"]))


def faxen_settling_velocity(radius: float, half_width: float, density_solid: float,
                            density: float, kinematic_viscosity: float, g: float) -> float:
    """Stokes settling velocity (m/s, positive down) of a disc on the centreline of a channel:
    ``(rho_s - rho) pi a^2 g Lambda(k) / (4 pi mu)``, Faxen's drag against the reduced weight."""
    lam = faxen_channel_lambda(radius / half_width)
    mu = density * kinematic_viscosity
    return (density_solid - density) * radius ** 2 * g * lam / (4.0 * mu)


def cylinder_drag_band(reynolds: float) -> tuple[float, float] | None:
    """The published band (low, high) of the steady drag coefficient of a circular cylinder in
    unbounded flow at ``reynolds`` (on the diameter), linear in log Re between the tabulated
    Reynolds numbers (data/cylinder_drag_steady_low_re.csv: Re 20 and 40, with its sources and
    caveats); None outside them (no extrapolation: C_D changes steeply with Re there, and above
    Re ~ 47 the flow sheds vortices)."""
    table = load_table("cylinder_drag_steady")
    re = table["re"]
    if not (math.isfinite(reynolds) and re[0] <= reynolds <= re[-1]):
        return None
    x = math.log(reynolds)
    xs = np.log(re)
    return (float(np.interp(x, xs, table["cd_low"])), float(np.interp(x, xs, table["cd_high"])))


@dataclass(frozen=True)
class SedimentationBenchmark:
    """A published disc settling in a vertical channel (data/wachs2009_...csv): the groups
    that fix it and its terminal state."""

    density_ratio: float
    width_ratio: float      # channel width / diameter
    galileo: float          # sqrt((r - 1) g d^3) / nu
    reynolds: float         # U d / nu at terminal speed
    drag_coefficient: float  # reduced weight / (0.5 rho U^2 d)
    source: tuple[str, ...]


def settling_drag_coefficient(density_ratio: float, g: float, diameter: float,
                              speed: float) -> float:
    """The C_D on the diameter that balances the reduced weight of a disc at ``speed``:
    (r - 1) g pi d / (2 U^2)."""
    return abs(density_ratio - 1.0) * g * math.pi * diameter / (2.0 * speed * speed)


def wachs_sedimentation(density_ratio: float) -> SedimentationBenchmark:
    """Wachs's (2009) disc in a channel four diameters wide at ``density_ratio`` (1.5 or 3)."""
    table = load_table("wachs_2009")
    hit = np.flatnonzero(np.isclose(table["density_ratio"], density_ratio, rtol=0, atol=1e-9))
    if hit.size != 1:
        raise KeyError(f"no Wachs (2009) sedimentation value at rho_s / rho = {density_ratio}; "
                       f"known: {table['density_ratio'].tolist()}")
    i = int(hit[0])
    return SedimentationBenchmark(
        density_ratio=float(density_ratio), width_ratio=WACHS_2009["width_ratio"],
        galileo=galileo_number(density_ratio, WACHS_2009["g"], WACHS_2009["diameter"],
                               WACHS_2009["nu"]),
        reynolds=float(table["reynolds"][i]), drag_coefficient=float(table["drag_coefficient"][i]),
        source=table.source)


# Where Wachs's fig. 5a releases the disc, in its coordinates (d; the channel's axis at x = 2):
# wachs2009_fig5a_path.csv's header says how this is known.
WACHS_PATH_RELEASE = (1.0, 40.0)
WACHS_PATH_AXIS = 2.0


def wachs_path(density_ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """Wachs's (2009, fig. 5a) path of the settling disc at ``density_ratio`` (1.5 or 3), as
    ``(x, y)`` in diameters, ``y`` decreasing, points digitised at the same height merged (their
    mean x): a function x(y) to interpolate."""
    table = load_table("wachs_2009_path")
    pick = np.isclose(table["density_ratio"], density_ratio, rtol=0, atol=1e-9)
    if not pick.any():
        raise KeyError(f"no Wachs (2009) path at rho_s / rho = {density_ratio}; known: "
                       f"{sorted(set(table['density_ratio'].tolist()))}")
    y, inverse = np.unique(table["y"][pick], return_inverse=True)
    x = np.bincount(inverse, weights=table["x"][pick]) / np.bincount(inverse)
    return x[::-1], y[::-1]


def wachs_path_offsets(density_ratio: float, fall_start: float, fall_end: float,
                       samples: int = 4001) -> tuple[float, float] | None:
    """The largest and the mean |x - axis| (diameters) of Wachs's path while the disc falls from
    ``fall_start`` to ``fall_end`` diameters below its release, the path interpolated linearly
    at ``samples`` heights evenly spaced (a mean over the distance fallen, which at a steady
    speed is the mean over time). None where that stretch leaves the digitised path."""
    x, y = wachs_path(density_ratio)
    top, bottom = WACHS_PATH_RELEASE[1] - fall_start, WACHS_PATH_RELEASE[1] - fall_end
    if not (fall_start < fall_end and bottom >= y[-1] and top <= y[0]):
        return None
    heights = np.linspace(top, bottom, samples)
    off = np.abs(np.interp(heights, y[::-1], x[::-1]) - WACHS_PATH_AXIS)
    return float(off.max()), float(off.mean())

