"""The DFG 2D-2 reference values (src/crosscheck/reference/data/schafer_turek1996_cylinder.csv)
from FEATFLOW's published force series, measured the way crosscheck measures its own runs.

    python benchmarks/featflow_reference.py PATH/bdforces_q2_lv6_dt4
    python benchmarks/featflow_reference.py PATH/bdforces_q2_lv*_dt*     # the level series

The file is FEATFLOW's reference computation of the benchmark (Q2 elements on mesh level 6,
Crank-Nicolson, dt = 1/1600), one line a step: index, time, boundary component, c_D, c_L. A
public copy: redbKIT/redbKIT, Problems/FEM_CFD_Dfg2D/ReferenceValues_Re100Periodic/ (commit
5081083a); FEATFLOW's whole set for 2D-2, levels 2-6 at dt = 1/100, 1/400 and 1/1600 (the
level-6, 1/1600 file byte-identical to redbKIT's, sha256 39208f27...), in LKM-code-base/RotatingMHD,
benchmarks/DFG/20141124_dfg_bench2_official.zip, logs/results_cc2d_bench2_referencenew/ (commit
96e5b0d). Neither is shipped here; this script lets anyone re-derive the numbers the reference
table quotes: the drag and lift extrema refined between samples by
:func:`crosscheck.compare.fluid_metrics.peak` and the Strouhal number from the lift's upward
zero crossings by :func:`crosscheck.compare.fluid_metrics.strouhal` (D = 0.1 m, U_mean = 1 m/s),
as :func:`crosscheck.compare.fluid_metrics.dfg_metrics` reads a run."""

import argparse
from pathlib import Path

import numpy as np

from crosscheck.compare.fluid_metrics import peak, strouhal

D, U_MEAN = 0.1, 1.0


def featflow_values(path: Path) -> dict[str, float]:
    """The sampling step, c_D,max, c_L,max, c_L,min, the mean lift and St of a FEATFLOW
    ``bdforces`` file."""
    try:
        data = np.loadtxt(path)
    except ValueError as exc:
        raise SystemExit(f"{path}: not a FEATFLOW bdforces file (index, time, component, c_D, "
                         f"c_L on each line): {exc}") from exc
    if data.ndim != 2 or data.shape[1] < 5:
        raise SystemExit(f"{path}: expected columns index, time, component, c_D, c_L")
    t, cd, cl = data[:, 1], data[:, 3], data[:, 4]
    st, periods = strouhal(t, cl, D, U_MEAN)
    # the mean lift over the whole periods between the first and the last upward crossing
    x = cl - cl.mean()
    up = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    mean = float(np.mean(cl[up[0]:up[-1]])) if up.shape[0] > 1 else float("nan")
    return {"dt": float(np.median(np.diff(t))),
            "drag_coefficient_max": peak(cd), "lift_coefficient_max": peak(cl),
            "lift_coefficient_min": -peak(-cl), "lift_coefficient_mean": mean,
            "strouhal_number": st, "periods": float(periods), "t0": float(t[0]),
            "t1": float(t[-1])}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("paths", type=Path, nargs="+", metavar="path",
                    help="FEATFLOW bdforces files (2D-2); several: one table row each")
    args = ap.parse_args()
    for path in args.paths:
        if not path.is_file():
            raise SystemExit(f"{path}: no such file")
    if len(args.paths) == 1:
        for k, v in featflow_values(args.paths[0]).items():
            print(f"{k:24s} {v:.6g}")
        return
    # one row a file: how the reference converges over FEATFLOW's levels and steps
    keys = ("drag_coefficient_max", "lift_coefficient_max", "lift_coefficient_min",
            "strouhal_number")
    print("| file | dt | " + " | ".join(keys) + " |")
    print("|---|---|" + "---|" * len(keys))
    for path in args.paths:
        values = featflow_values(path)
        cells = " | ".join(f"{values[k]:.6g}" for k in keys)
        print(f"| {path.name} | 1/{1.0 / values['dt']:.0f} | {cells} |")


if __name__ == "__main__":
    main()
